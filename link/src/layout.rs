//! The values of a model as the link carries them, for every kind: the one home of the layout. The
//! host lays a lab's model files out with [`lay_out`] (what it uploads), the firmware's build script
//! lays out its compiled-in default the same way, and the device reads values back into core's
//! [`ModelSpec`] with [`with_spec`] (an upload's commit, and the default at boot), so that the
//! three agree by construction.
//!
//! Every value is an f64, sent bit-exact. A count, an index or a flag is a whole number stored as
//! an f64. Matrices are row-major. By kind ([`ModelKind`]):
//!
//! | kind | values |
//! |---|---|
//! | `Lr` | θ0..θ5 (6; `LR_FEATURE_NAMES` order) |
//! | `Lrx` | [`lrx_values`]: 9 frame coefficients, k_corr, k_adapt_ticks, 8 lead weights, the lead stride (20) |
//! | `Rnn` | [`rnn_value_count`]: `w_ih` (H×2), `w_hh` (H×H), `b_h`, `w_ho`, `b_o`, input means (2) and standard deviations (2), output mean and standard deviation |
//! | `FeAts` | the delay the ATS starts from, s (1; the finite elements are the device's prototype) |
//! | `StructureFe`, `StructureNl` | N, the specimen's DOF, L (0, or N story laws), mass, damping, stiffness, initial stiffness (N×N each), `M·ι` (N), then L laws of 7: k0, yield force, post-yield ratio, Bouc–Wen flag (0 bilinear, 1 Bouc–Wen), n, β, γ |
//! | `StructureMeta` | θ ([`DELTA_ARX_COEFFS`]), k_corr (19) |
//! | `StructureModal` | M modes, F floors, S springs, the specimen's DOF, its stiffness; M modes of 3 (ω, ζ, Γ); the shapes (F×M); S laws of 7; the springs' drifts (S×M) |
//! | `StructureReduced` | M modes, O outputs, the specimen's stiffness, the interface's static correction (h, g); M modes of 4 (ω, ζ, Γ, interface shape); the outputs' shapes (O×M); O static corrections (h, g) |
//! | `StructureHysteron` | F floors, D directions, H hysterons, the specimen's floor, its stiffness, the operator (0 play, 1 Menegotto–Pinto) and its R₀, c_R1, c_R2 (0 for the play); mass, damping, stiffness (F×F each), `M·ι` (F); the directions (D×F); H hysterons of 3 (direction, threshold, weight) |

use rths_core::compensator::LEAD_TAPS;
use rths_core::control::{
    FloorHysteronSpec, ModalSpec, ReducedSpec, StoryLawSpec, StructureSpec, HYSTERON_VALUES,
};
use rths_core::metamodel::{
    FloorStructure, HysteronOperator, ModalMode, MpShape, ReducedMode, RnnScaling, RnnWeights,
    StaticCorrection, DELTA_ARX_COEFFS, HYST_MAX_DIRECTIONS, HYST_MAX_HYSTERONS, HYST_MAX_MP,
    MODAL_MAX_FLOORS, MODAL_MAX_MODES, MODAL_MAX_SPRINGS, REDUCED_MAX_MODES, REDUCED_MAX_OUTPUTS,
    RNN_INPUTS, RNN_MAX_HIDDEN,
};
use rths_core::model::ModelSpec;
use rths_core::structure_n::MAX_DOF;

use crate::{ModelKind, LR_COEFFS};

/// Values of an LRX model ([`lrx_values`]): 9 frame coefficients, the correction stiffness, the
/// adaptation time constant, 8 lead-filter weights, the lead stride.
pub const LRX_VALUES: usize = 20;

/// Values of an FE + ATS model ([`ModelKind::FeAts`]): the delay the ATS starts from, s. The finite
/// elements are the device's own prototype (the paper's frame, compiled in).
pub const FE_ATS_VALUES: usize = 1;

/// The largest RNN hidden size a model may have: the controller's RNN capacity.
pub const RNN_UPLOAD_MAX_HIDDEN: usize = RNN_MAX_HIDDEN;

/// Values of a structure-metamodel (delta ARX) model: θ and k_corr.
pub const STRUCTURE_META_VALUES: usize = DELTA_ARX_COEFFS + 1;

/// Values of one story or spring law: k0, yield force, post-yield ratio, Bouc–Wen flag, n, β, γ.
pub const LAW_VALUES: usize = 7;

/// Values of an N-DOF structure's finite elements with `laws` story laws (0: linear; N: yielding).
pub const fn structure_value_count(dofs: usize, laws: usize) -> usize {
    3 + 4 * dofs * dofs + dofs + LAW_VALUES * laws
}

/// Values of a modal-hysteretic model of `modes` modes, `floors` floors and `springs` springs.
pub const fn modal_value_count(modes: usize, floors: usize, springs: usize) -> usize {
    5 + 3 * modes + floors * modes + LAW_VALUES * springs + springs * modes
}

/// Values of a reduced model of `modes` modes and `outputs` outputs.
pub const fn reduced_value_count(modes: usize, outputs: usize) -> usize {
    5 + 4 * modes + outputs * modes + 2 * outputs
}

/// Header values of a floor-hysteron model: F, D, H, the specimen's floor, its stiffness, the
/// operator flag and its three shape values.
const HYSTERON_HEADER: usize = 9;

/// Values of a floor-hysteron model of `floors` floors, `directions` directions and `hysterons`
/// hysterons.
pub const fn hysteron_value_count(floors: usize, directions: usize, hysterons: usize) -> usize {
    HYSTERON_HEADER
        + 3 * floors * floors
        + floors
        + directions * floors
        + HYSTERON_VALUES * hysterons
}

/// Values of an RNN model of `hidden` units ([`ModelKind::Rnn`]), in this order: `w_ih` (hidden ×
/// 2, row-major), `w_hh` (hidden × hidden, row-major), `b_h` (hidden), `w_ho` (hidden), `b_o`, the
/// input means (2) and standard deviations (2), the output mean and standard deviation.
pub const fn rnn_value_count(hidden: usize) -> usize {
    hidden * 2 + hidden * hidden + hidden + hidden + 1 + 2 + 2 + 2
}

/// Most values a model of any kind has: the device's staging area (an RNN of
/// [`RNN_UPLOAD_MAX_HIDDEN`] units, 1,159 values, 9,272 bytes; the largest structure model, a
/// reduced model of 32 modes and 16 outputs, has 677).
pub const MODEL_MAX_VALUES: usize = rnn_value_count(RNN_UPLOAD_MAX_HIDDEN);

const fn max(a: usize, b: usize) -> usize {
    if a > b {
        a
    } else {
        b
    }
}

/// The largest model of each kind fits the staging area.
const _: () = assert!(
    max(
        max(
            structure_value_count(MAX_DOF, MAX_DOF),
            modal_value_count(MODAL_MAX_MODES, MODAL_MAX_FLOORS, MODAL_MAX_SPRINGS),
        ),
        max(
            reduced_value_count(REDUCED_MAX_MODES, REDUCED_MAX_OUTPUTS),
            max(
                max(LRX_VALUES, STRUCTURE_META_VALUES),
                hysteron_value_count(MAX_DOF, HYST_MAX_DIRECTIONS, HYST_MAX_HYSTERONS),
            ),
        ),
    ) <= MODEL_MAX_VALUES
);

/// Why values are not a model of their kind.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LayoutError {
    /// The count, or a size the values announce, is not one of the kind's (or past its capacity).
    Shape,
    /// A value that must be a whole number (a stride, a flag) is not one in its range.
    Value,
    /// The model has no layout: plain finite elements, which no upload carries.
    Kind,
}

/// The sizes of a model, read from its values: what its cost per tick depends on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Dims {
    /// An RNN's hidden units.
    pub rnn_hidden: usize,
    /// A structure's DOFs (its finite elements).
    pub dofs: usize,
    /// Modes (the modal-hysteretic and the reduced model).
    pub modes: usize,
    /// Latent springs (the modal-hysteretic model), or yielding stories (the structure's FE).
    pub springs: usize,
    /// Read-outs (the reduced model).
    pub outputs: usize,
    /// Of the laws (yielding stories or latent springs), those of Bouc–Wen's (the costlier law);
    /// of a floor-hysteron model's hysterons, the Menegotto–Pinto ones (the costlier operator).
    pub bouc_wen: usize,
    /// The directions a floor-hysteron model's hysterons act along.
    pub directions: usize,
    /// A floor-hysteron model's hysterons.
    pub hysterons: usize,
}

/// The hidden size of an RNN model of `values` values ([`rnn_value_count`]'s inverse), if any.
pub fn rnn_hidden_of(values: usize) -> Option<usize> {
    // values = h² + 4h + 7: the positive root, checked exactly.
    (1..=64).find(|h| rnn_value_count(*h) == values)
}

/// A count of `values` values may be a `kind` model (the sizes its values announce are checked
/// by [`dims`]): `Err(Shape)` otherwise.
pub fn count_fits(kind: ModelKind, values: usize) -> Result<(), LayoutError> {
    let ok = match kind {
        ModelKind::Lr => values == LR_COEFFS,
        ModelKind::Lrx => values == LRX_VALUES,
        ModelKind::FeAts => values == FE_ATS_VALUES,
        ModelKind::Rnn => rnn_hidden_of(values).is_some_and(|h| h <= RNN_UPLOAD_MAX_HIDDEN),
        ModelKind::StructureFe => (1..=MAX_DOF).any(|n| structure_value_count(n, 0) == values),
        ModelKind::StructureNl => (1..=MAX_DOF).any(|n| structure_value_count(n, n) == values),
        ModelKind::StructureMeta => values == STRUCTURE_META_VALUES,
        ModelKind::StructureModal => {
            values >= modal_value_count(1, 1, 1)
                && values <= modal_value_count(MODAL_MAX_MODES, MODAL_MAX_FLOORS, MODAL_MAX_SPRINGS)
        }
        ModelKind::StructureReduced => {
            values >= reduced_value_count(1, 0)
                && values <= reduced_value_count(REDUCED_MAX_MODES, REDUCED_MAX_OUTPUTS)
        }
        ModelKind::StructureHysteron => {
            values >= hysteron_value_count(1, 1, 1)
                && values <= hysteron_value_count(MAX_DOF, HYST_MAX_DIRECTIONS, HYST_MAX_HYSTERONS)
        }
    };
    if ok {
        Ok(())
    } else {
        Err(LayoutError::Shape)
    }
}

/// A whole number in `lo..=hi` stored as an f64.
fn whole(x: f64, lo: usize, hi: usize) -> Result<usize, LayoutError> {
    // In range first: then the cast is exact, and a fraction does not survive it.
    if x >= lo as f64 && x <= hi as f64 && (x as usize) as f64 == x {
        Ok(x as usize)
    } else {
        Err(LayoutError::Shape)
    }
}

/// A cursor over a model's values: each read is checked, none can panic.
struct Reader<'a> {
    rest: &'a [f64],
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [f64], LayoutError> {
        let (head, rest) = self.rest.split_at_checked(n).ok_or(LayoutError::Shape)?;
        self.rest = rest;
        Ok(head)
    }
    fn one(&mut self) -> Result<f64, LayoutError> {
        self.take(1)?.first().copied().ok_or(LayoutError::Shape)
    }
    fn count(&mut self, lo: usize, hi: usize) -> Result<usize, LayoutError> {
        whole(self.one()?, lo, hi)
    }
    /// Every value was read.
    fn end(&self) -> Result<(), LayoutError> {
        if self.rest.is_empty() {
            Ok(())
        } else {
            Err(LayoutError::Shape)
        }
    }
}

/// A law from its 7 values.
fn law(v: &[f64]) -> Result<StoryLawSpec, LayoutError> {
    let &[k0, fy, ratio, flag, n, beta, gamma] = v else {
        return Err(LayoutError::Shape);
    };
    let bouc_wen = match whole(flag, 0, 1).map_err(|_| LayoutError::Value)? {
        0 => None,
        _ => Some([n, beta, gamma]),
    };
    Ok(StoryLawSpec {
        k0_kn_per_mm: k0,
        yield_force_kn: fy,
        post_yield_ratio: ratio,
        bouc_wen,
    })
}

/// How many of the laws (7 values each) are Bouc–Wen's (their flag is 1).
fn bouc_wen_laws(laws: &[f64]) -> usize {
    laws.chunks_exact(LAW_VALUES)
        .filter(|l| l.get(3).copied() == Some(1.0))
        .count()
}

/// The structure header (N, the specimen's DOF, L) of a `StructureFe`/`StructureNl` model.
fn structure_dims(
    kind: ModelKind,
    r: &mut Reader<'_>,
) -> Result<(usize, usize, usize), LayoutError> {
    let n = r.count(1, MAX_DOF)?;
    let dof = r.count(0, n - 1)?;
    let laws = r.count(0, MAX_DOF)?;
    let want = if kind == ModelKind::StructureNl { n } else { 0 };
    if laws != want {
        return Err(LayoutError::Shape);
    }
    Ok((n, dof, laws))
}

/// A floor-hysteron model's header, read.
struct HysteronHeader {
    floors: usize,
    directions: usize,
    hysterons: usize,
    specimen_floor: usize,
    specimen_k: f64,
    operator: HysteronOperator,
}

/// The header of a `StructureHysteron` model (its sizes in the controller's capacities; its
/// operator flag whole, its shape checked by core: `Value` for a shape out of range).
fn hysteron_header(r: &mut Reader<'_>) -> Result<HysteronHeader, LayoutError> {
    let floors = r.count(1, MAX_DOF)?;
    let directions = r.count(1, HYST_MAX_DIRECTIONS)?;
    let hysterons = r.count(1, HYST_MAX_HYSTERONS)?;
    let specimen_floor = r.count(0, floors - 1)?;
    let specimen_k = r.one()?;
    let flag = whole(r.one()?, 0, 1).map_err(|_| LayoutError::Value)?;
    let (r0, cr1, cr2) = (r.one()?, r.one()?, r.one()?);
    let operator = if flag == 0 {
        // The play has no shape: its three values are 0, never read.
        if [r0, cr1, cr2] != [0.0; 3] {
            return Err(LayoutError::Value);
        }
        HysteronOperator::Play
    } else {
        if hysterons > HYST_MAX_MP {
            return Err(LayoutError::Shape);
        }
        HysteronOperator::MenegottoPinto(
            MpShape::new(r0, cr1, cr2).map_err(|_| LayoutError::Value)?,
        )
    };
    Ok(HysteronHeader {
        floors,
        directions,
        hysterons,
        specimen_floor,
        specimen_k,
        operator,
    })
}

/// The sizes of a `kind` model of `values` (every size it announces checked against its count and
/// the controller's capacities): `Err(Shape)` for values that are no model of the kind.
pub fn dims(kind: ModelKind, values: &[f64]) -> Result<Dims, LayoutError> {
    count_fits(kind, values.len())?;
    let mut r = Reader { rest: values };
    let d = match kind {
        ModelKind::Lr | ModelKind::Lrx | ModelKind::FeAts | ModelKind::StructureMeta => {
            Dims::default()
        }
        ModelKind::Rnn => Dims {
            rnn_hidden: rnn_hidden_of(values.len()).ok_or(LayoutError::Shape)?,
            ..Dims::default()
        },
        ModelKind::StructureFe | ModelKind::StructureNl => {
            let (n, _, laws) = structure_dims(kind, &mut r)?;
            r.take(4 * n * n + n)?;
            let bouc_wen = bouc_wen_laws(r.take(LAW_VALUES * laws)?);
            r.end()?;
            Dims {
                dofs: n,
                springs: laws,
                bouc_wen,
                ..Dims::default()
            }
        }
        ModelKind::StructureModal => {
            let m = r.count(1, MODAL_MAX_MODES)?;
            let f = r.count(1, MODAL_MAX_FLOORS)?;
            let s = r.count(1, MODAL_MAX_SPRINGS)?;
            r.take(2 + 3 * m + f * m)?;
            let bouc_wen = bouc_wen_laws(r.take(LAW_VALUES * s)?);
            r.take(s * m)?;
            r.end()?;
            Dims {
                dofs: f,
                modes: m,
                springs: s,
                bouc_wen,
                ..Dims::default()
            }
        }
        ModelKind::StructureReduced => {
            let m = r.count(1, REDUCED_MAX_MODES)?;
            let o = r.count(0, REDUCED_MAX_OUTPUTS)?;
            r.take(reduced_value_count(m, o) - 2)?;
            r.end()?;
            Dims {
                modes: m,
                outputs: o,
                ..Dims::default()
            }
        }
        ModelKind::StructureHysteron => {
            let h = hysteron_header(&mut r)?;
            r.take(hysteron_value_count(h.floors, h.directions, h.hysterons) - HYSTERON_HEADER)?;
            r.end()?;
            Dims {
                dofs: h.floors,
                directions: h.directions,
                hysterons: h.hysterons,
                bouc_wen: if h.operator == HysteronOperator::Play {
                    0
                } else {
                    h.hysterons
                },
                ..Dims::default()
            }
        }
    };
    Ok(d)
}

/// Read `values` of a `kind` model as core's [`ModelSpec`] and give it to `f` (the spec borrows
/// `values` and a few small arrays of this call's frame: the modes, laws and corrections, at most
/// 1.3 KiB). Refused (`f` not called): values that are no model of the kind ([`dims`]), or a
/// stride or flag that is not a whole number in its range (`Value`). The spec's own values are
/// checked by core when it is validated or assembled.
pub fn with_spec<R>(
    kind: ModelKind,
    values: &[f64],
    f: impl FnOnce(&ModelSpec<'_>) -> R,
) -> Result<R, LayoutError> {
    dims(kind, values)?;
    let mut r = Reader { rest: values };
    match kind {
        ModelKind::Lr => Ok(f(&ModelSpec::Lr { theta: values })),
        ModelKind::Lrx => {
            let coeffs = r.take(9)?;
            let (k_corr, k_adapt) = (r.one()?, r.one()?);
            let lead_weights = r.take(LEAD_TAPS)?;
            let stride = whole(r.one()?, 1, 64).map_err(|_| LayoutError::Value)?;
            Ok(f(&ModelSpec::Lrx {
                coeffs,
                k_corr_kn_per_mm: k_corr,
                k_adapt_ticks: k_adapt,
                lead_weights,
                lead_stride: stride,
                lead_adapt_ticks: 0.0,
                specimen_dynamics: [0.0, 0.0],
            }))
        }
        ModelKind::Rnn => {
            let h = rnn_hidden_of(values.len()).ok_or(LayoutError::Shape)?;
            let w_ih = r.take(h * RNN_INPUTS)?;
            let w_hh = r.take(h * h)?;
            let b_h = r.take(h)?;
            let w_ho = r.take(h)?;
            let &[b_o, m0, m1, s0, s1, output_mean, output_std] = r.take(7)? else {
                return Err(LayoutError::Shape);
            };
            Ok(f(&ModelSpec::Rnn {
                weights: RnnWeights {
                    w_ih,
                    w_hh,
                    b_h,
                    w_ho,
                    b_o,
                },
                scaling: RnnScaling {
                    input_mean: [m0, m1],
                    input_std: [s0, s1],
                    output_mean,
                    output_std,
                },
            }))
        }
        ModelKind::FeAts => Ok(f(&ModelSpec::FeAts {
            expected_delay_s: r.one()?,
        })),
        ModelKind::StructureFe | ModelKind::StructureNl => {
            let (n, specimen_dof, nlaws) = structure_dims(kind, &mut r)?;
            let (mass, damping) = (r.take(n * n)?, r.take(n * n)?);
            let (stiffness, initial_stiffness) = (r.take(n * n)?, r.take(n * n)?);
            let ground_mass = r.take(n)?;
            let mut laws = [StoryLawSpec {
                k0_kn_per_mm: 0.0,
                yield_force_kn: 0.0,
                post_yield_ratio: 0.0,
                bouc_wen: None,
            }; MAX_DOF];
            for l in laws.iter_mut().take(nlaws) {
                *l = law(r.take(LAW_VALUES)?)?;
            }
            let structure = StructureSpec {
                dofs: n,
                mass,
                damping,
                stiffness,
                initial_stiffness,
                ground_mass,
                specimen_dof,
                laws: laws.get(..nlaws).ok_or(LayoutError::Shape)?,
            };
            Ok(f(&if kind == ModelKind::StructureNl {
                ModelSpec::StructureNl { structure }
            } else {
                ModelSpec::StructureFe { structure }
            }))
        }
        ModelKind::StructureMeta => {
            let theta = r.take(DELTA_ARX_COEFFS)?;
            Ok(f(&ModelSpec::StructureMeta {
                theta,
                k_corr_kn_per_mm: r.one()?,
            }))
        }
        ModelKind::StructureModal => {
            let m = r.count(1, MODAL_MAX_MODES)?;
            let fl = r.count(1, MODAL_MAX_FLOORS)?;
            let s = r.count(1, MODAL_MAX_SPRINGS)?;
            let specimen_dof = r.count(0, fl - 1)?;
            let specimen_k = r.one()?;
            let mut modes = [ModalMode {
                omega_rad_s: 0.0,
                damping_ratio: 0.0,
                ground_participation: 0.0,
            }; MODAL_MAX_MODES];
            for mode in modes.iter_mut().take(m) {
                let &[omega_rad_s, damping_ratio, ground_participation] = r.take(3)? else {
                    return Err(LayoutError::Shape);
                };
                *mode = ModalMode {
                    omega_rad_s,
                    damping_ratio,
                    ground_participation,
                };
            }
            let shape = r.take(fl * m)?;
            let mut laws = [StoryLawSpec {
                k0_kn_per_mm: 0.0,
                yield_force_kn: 0.0,
                post_yield_ratio: 0.0,
                bouc_wen: None,
            }; MODAL_MAX_SPRINGS];
            for l in laws.iter_mut().take(s) {
                *l = law(r.take(LAW_VALUES)?)?;
            }
            let drift = r.take(s * m)?;
            Ok(f(&ModelSpec::StructureModal {
                model: ModalSpec {
                    modes: modes.get(..m).ok_or(LayoutError::Shape)?,
                    shape,
                    specimen_dof,
                    specimen_k_kn_per_mm: specimen_k,
                    laws: laws.get(..s).ok_or(LayoutError::Shape)?,
                    drift,
                },
            }))
        }
        ModelKind::StructureReduced => {
            let m = r.count(1, REDUCED_MAX_MODES)?;
            let o = r.count(0, REDUCED_MAX_OUTPUTS)?;
            let specimen_k = r.one()?;
            let interface_static = StaticCorrection {
                ground_mm_per_mm_s2: r.one()?,
                force_mm_per_kn: r.one()?,
            };
            let mut modes = [ReducedMode {
                omega_rad_s: 0.0,
                damping_ratio: 0.0,
                ground_participation: 0.0,
                interface_shape: 0.0,
            }; REDUCED_MAX_MODES];
            for mode in modes.iter_mut().take(m) {
                let &[omega_rad_s, damping_ratio, ground_participation, interface_shape] =
                    r.take(4)?
                else {
                    return Err(LayoutError::Shape);
                };
                *mode = ReducedMode {
                    omega_rad_s,
                    damping_ratio,
                    ground_participation,
                    interface_shape,
                };
            }
            let output_shape = r.take(o * m)?;
            let mut statics = [StaticCorrection::default(); REDUCED_MAX_OUTPUTS];
            for c in statics.iter_mut().take(o) {
                let &[ground_mm_per_mm_s2, force_mm_per_kn] = r.take(2)? else {
                    return Err(LayoutError::Shape);
                };
                *c = StaticCorrection {
                    ground_mm_per_mm_s2,
                    force_mm_per_kn,
                };
            }
            Ok(f(&ModelSpec::StructureReduced {
                model: ReducedSpec {
                    modes: modes.get(..m).ok_or(LayoutError::Shape)?,
                    output_shape,
                    interface_static,
                    output_static: statics.get(..o).ok_or(LayoutError::Shape)?,
                    specimen_k_kn_per_mm: specimen_k,
                },
            }))
        }
        ModelKind::StructureHysteron => {
            let h = hysteron_header(&mut r)?;
            let n = h.floors;
            let (mass, damping, stiffness) = (r.take(n * n)?, r.take(n * n)?, r.take(n * n)?);
            let ground_mass = r.take(n)?;
            let directions = r.take(h.directions * n)?;
            let hysterons = r.take(HYSTERON_VALUES * h.hysterons)?;
            Ok(f(&ModelSpec::StructureHysteron {
                model: FloorHysteronSpec {
                    floors: FloorStructure {
                        floors: n,
                        mass,
                        damping,
                        stiffness,
                        ground_mass,
                        specimen_floor: h.specimen_floor,
                        specimen_k_kn_per_mm: h.specimen_k,
                    },
                    directions,
                    hysterons,
                    operator: h.operator,
                },
            }))
        }
    }
}

/// The kind of `spec` on the link (`Err(Kind)`: plain finite elements, which no upload carries).
pub fn kind_of(spec: &ModelSpec<'_>) -> Result<ModelKind, LayoutError> {
    Ok(match spec {
        ModelSpec::Lr { .. } => ModelKind::Lr,
        ModelSpec::Rnn { .. } => ModelKind::Rnn,
        ModelSpec::Lrx { .. } => ModelKind::Lrx,
        ModelSpec::Fe => return Err(LayoutError::Kind),
        ModelSpec::FeAts { .. } => ModelKind::FeAts,
        ModelSpec::StructureFe { .. } => ModelKind::StructureFe,
        ModelSpec::StructureNl { .. } => ModelKind::StructureNl,
        ModelSpec::StructureMeta { .. } => ModelKind::StructureMeta,
        ModelSpec::StructureModal { .. } => ModelKind::StructureModal,
        ModelSpec::StructureReduced { .. } => ModelKind::StructureReduced,
        ModelSpec::StructureHysteron { .. } => ModelKind::StructureHysteron,
    })
}

/// A writer of a model's values into a caller's slice: every write checked.
struct Writer<'a> {
    out: &'a mut [f64],
    n: usize,
}

impl Writer<'_> {
    fn one(&mut self, x: f64) -> Result<(), LayoutError> {
        *self.out.get_mut(self.n).ok_or(LayoutError::Shape)? = x;
        self.n += 1;
        Ok(())
    }
    fn all(&mut self, xs: &[f64]) -> Result<(), LayoutError> {
        xs.iter().try_for_each(|x| self.one(*x))
    }
    fn law(&mut self, l: &StoryLawSpec) -> Result<(), LayoutError> {
        let (flag, [n, beta, gamma]) = match l.bouc_wen {
            Some(s) => (1.0, s),
            None => (0.0, [0.0; 3]),
        };
        self.all(&[
            l.k0_kn_per_mm,
            l.yield_force_kn,
            l.post_yield_ratio,
            flag,
            n,
            beta,
            gamma,
        ])
    }
}

/// Lay `spec` out into `out`: its kind and the values written (the first of `out`). `Err(Shape)`
/// if `out` is too short or the spec's arrays do not have its sizes; `Err(Kind)` for plain finite
/// elements. An LRX spec's lead adaptation and specimen dynamics are its rig compensation's
/// ([`lrx_rig_values`]), not its model's. The inverse of [`with_spec`].
pub fn lay_out(spec: &ModelSpec<'_>, out: &mut [f64]) -> Result<(ModelKind, usize), LayoutError> {
    let kind = kind_of(spec)?;
    let mut w = Writer { out, n: 0 };
    match *spec {
        ModelSpec::Lr { theta } => {
            if theta.len() != LR_COEFFS {
                return Err(LayoutError::Shape);
            }
            w.all(theta)?;
        }
        ModelSpec::Lrx {
            coeffs,
            k_corr_kn_per_mm,
            k_adapt_ticks,
            lead_weights,
            lead_stride,
            ..
        } => w.all(
            &lrx_values(
                coeffs,
                k_corr_kn_per_mm,
                k_adapt_ticks,
                lead_weights,
                lead_stride,
            )
            .ok_or(LayoutError::Shape)?,
        )?,
        ModelSpec::Rnn { weights, scaling } => {
            let h = weights.b_h.len();
            if weights.w_ih.len() != h * RNN_INPUTS
                || weights.w_hh.len() != h * h
                || weights.w_ho.len() != h
            {
                return Err(LayoutError::Shape);
            }
            let ([m0, m1], [s0, s1]) = (scaling.input_mean, scaling.input_std);
            w.all(weights.w_ih)?;
            w.all(weights.w_hh)?;
            w.all(weights.b_h)?;
            w.all(weights.w_ho)?;
            w.all(&[
                weights.b_o,
                m0,
                m1,
                s0,
                s1,
                scaling.output_mean,
                scaling.output_std,
            ])?;
        }
        ModelSpec::Fe => return Err(LayoutError::Kind),
        ModelSpec::FeAts { expected_delay_s } => w.one(expected_delay_s)?,
        ModelSpec::StructureFe { structure } | ModelSpec::StructureNl { structure } => {
            let n = structure.dofs;
            let sq = n * n;
            if [
                structure.mass.len(),
                structure.damping.len(),
                structure.stiffness.len(),
                structure.initial_stiffness.len(),
            ] != [sq; 4]
                || structure.ground_mass.len() != n
            {
                return Err(LayoutError::Shape);
            }
            w.all(&[
                n as f64,
                structure.specimen_dof as f64,
                structure.laws.len() as f64,
            ])?;
            w.all(structure.mass)?;
            w.all(structure.damping)?;
            w.all(structure.stiffness)?;
            w.all(structure.initial_stiffness)?;
            w.all(structure.ground_mass)?;
            structure.laws.iter().try_for_each(|l| w.law(l))?;
        }
        ModelSpec::StructureMeta {
            theta,
            k_corr_kn_per_mm,
        } => {
            if theta.len() != DELTA_ARX_COEFFS {
                return Err(LayoutError::Shape);
            }
            w.all(theta)?;
            w.one(k_corr_kn_per_mm)?;
        }
        ModelSpec::StructureModal { model } => {
            let m = model.modes.len();
            let s = model.laws.len();
            if m == 0 || model.shape.len() % m != 0 || model.drift.len() != s * m {
                return Err(LayoutError::Shape);
            }
            let floors = model.shape.len() / m;
            w.all(&[
                m as f64,
                floors as f64,
                s as f64,
                model.specimen_dof as f64,
                model.specimen_k_kn_per_mm,
            ])?;
            for mode in model.modes {
                w.all(&[
                    mode.omega_rad_s,
                    mode.damping_ratio,
                    mode.ground_participation,
                ])?;
            }
            w.all(model.shape)?;
            model.laws.iter().try_for_each(|l| w.law(l))?;
            w.all(model.drift)?;
        }
        ModelSpec::StructureReduced { model } => {
            let m = model.modes.len();
            let o = model.output_static.len();
            if model.output_shape.len() != o * m {
                return Err(LayoutError::Shape);
            }
            w.all(&[
                m as f64,
                o as f64,
                model.specimen_k_kn_per_mm,
                model.interface_static.ground_mm_per_mm_s2,
                model.interface_static.force_mm_per_kn,
            ])?;
            for mode in model.modes {
                w.all(&[
                    mode.omega_rad_s,
                    mode.damping_ratio,
                    mode.ground_participation,
                    mode.interface_shape,
                ])?;
            }
            w.all(model.output_shape)?;
            for c in model.output_static {
                w.all(&[c.ground_mm_per_mm_s2, c.force_mm_per_kn])?;
            }
        }
        ModelSpec::StructureHysteron { model } => {
            let fl = &model.floors;
            let n = fl.floors;
            let sq = n * n;
            if [fl.mass.len(), fl.damping.len(), fl.stiffness.len()] != [sq; 3]
                || fl.ground_mass.len() != n
                || n == 0
                || model.directions.len() % n != 0
                || model.hysterons.len() % HYSTERON_VALUES != 0
            {
                return Err(LayoutError::Shape);
            }
            let (flag, [r0, cr1, cr2]) = match model.operator {
                HysteronOperator::Play => (0.0, [0.0; 3]),
                HysteronOperator::MenegottoPinto(m) => (1.0, [m.r0(), m.cr1(), m.cr2()]),
            };
            w.all(&[
                n as f64,
                (model.directions.len() / n) as f64,
                (model.hysterons.len() / HYSTERON_VALUES) as f64,
                fl.specimen_floor as f64,
                fl.specimen_k_kn_per_mm,
                flag,
                r0,
                cr1,
                cr2,
            ])?;
            w.all(fl.mass)?;
            w.all(fl.damping)?;
            w.all(fl.stiffness)?;
            w.all(fl.ground_mass)?;
            w.all(model.directions)?;
            w.all(model.hysterons)?;
        }
    }
    let n = w.n;
    // What the device will read back: the same sizes, or the spec does not fit its kind.
    dims(kind, out.get(..n).ok_or(LayoutError::Shape)?)?;
    Ok((kind, n))
}

/// An LRX model as the flat list of values a chunked upload sends, in this order: `coeffs` (9),
/// `k_corr_kn_per_mm`, `k_adapt_ticks`, `lead_weights` (8), `lead_stride` (as f64). `None` if a
/// slice has the wrong length.
pub fn lrx_values(
    coeffs: &[f64],
    k_corr_kn_per_mm: f64,
    k_adapt_ticks: f64,
    lead_weights: &[f64],
    lead_stride: usize,
) -> Option<[f64; LRX_VALUES]> {
    let mut v = [0.0; LRX_VALUES];
    v.get_mut(..9)?
        .copy_from_slice(coeffs.get(..9).filter(|_| coeffs.len() == 9)?);
    *v.get_mut(9)? = k_corr_kn_per_mm;
    *v.get_mut(10)? = k_adapt_ticks;
    v.get_mut(11..19)?
        .copy_from_slice(lead_weights.get(..8).filter(|_| lead_weights.len() == 8)?);
    *v.get_mut(19)? = lead_stride as f64;
    Some(v)
}

// ---- rig compensations ----

/// Most values a rig compensation has, of any kind (a structure part's, [`STRUCTURE_RIG_VALUES`]);
/// more than one frame's [`RIG_MAX_VALUES`]: such a compensation goes in chunks
/// ([`crate::HostMsg::RigBegin`]).
pub const RIG_UPLOAD_MAX_VALUES: usize = STRUCTURE_RIG_VALUES;

/// Most values a rig compensation sent in one frame ([`crate::HostMsg::UploadRig`]) has.
pub const RIG_MAX_VALUES: usize = crate::RECORD_CHUNK;

/// Values of a structure part's rig compensation ([`structure_rig_values`]).
pub const STRUCTURE_RIG_VALUES: usize = 15;

/// Values of the rig compensation of an analytical `kind` (`None`: its controller has none):
/// [`ModelKind::FeAts`]: the ATS's initial [a0, a1 (s), a2 (s²)] (3); [`ModelKind::Lrx`]: the 8
/// lead-filter weights, the lead stride (ticks, as f64), the lead's adaptation time constant
/// (ticks, 0: fixed), the specimen's moving mass (kN·s²/mm) and damping (kN·s/mm) (12); a
/// structure part: [`structure_rig_values`] (15).
pub fn rig_value_count(kind: ModelKind) -> Option<usize> {
    match kind {
        ModelKind::FeAts => Some(3),
        ModelKind::Lrx => Some(12),
        ModelKind::Lr | ModelKind::Rnn => None,
        ModelKind::StructureFe
        | ModelKind::StructureNl
        | ModelKind::StructureMeta
        | ModelKind::StructureModal
        | ModelKind::StructureReduced
        | ModelKind::StructureHysteron => Some(STRUCTURE_RIG_VALUES),
    }
}

/// The LRX rig compensation as the flat values of [`rig_value_count`]'s layout; `None` if the lead
/// has not 8 weights.
pub fn rig_values(
    lead_weights: &[f64],
    lead_stride: usize,
    lead_adapt_ticks: f64,
    specimen_dynamics: [f64; 2],
) -> Option<[f64; RIG_MAX_VALUES]> {
    let mut v = [0.0; RIG_MAX_VALUES];
    v.get_mut(..8)?
        .copy_from_slice(lead_weights.get(..8).filter(|_| lead_weights.len() == 8)?);
    *v.get_mut(8)? = lead_stride as f64;
    *v.get_mut(9)? = lead_adapt_ticks;
    v.get_mut(10..12)?.copy_from_slice(&specimen_dynamics);
    Some(v)
}

/// The rig compensation an LRX spec carries (its lead's adaptation and the specimen's dynamics, in
/// [`rig_values`]' layout), or `None` if it has neither (the model's own lead is the rig's).
pub fn lrx_rig_values(spec: &ModelSpec<'_>) -> Option<[f64; RIG_MAX_VALUES]> {
    let ModelSpec::Lrx {
        lead_weights,
        lead_stride,
        lead_adapt_ticks,
        specimen_dynamics,
        ..
    } = *spec
    else {
        return None;
    };
    if lead_adapt_ticks == 0.0 && specimen_dynamics == [0.0, 0.0] {
        return None;
    }
    rig_values(
        lead_weights,
        lead_stride,
        lead_adapt_ticks,
        specimen_dynamics,
    )
}

/// A structure part's rig compensation (`nl-online`, `meta-online`, `fe-online-lead`), in this
/// order: the identified lead's 8 weights, its stride (ticks, as f64) and its adaptation time
/// constant (ticks, 0: fixed); the identified specimen at the rig, stiffness (kN/mm), damping
/// (kN·s/mm) and moving mass (kN·s²/mm), which correct the measured force; the specimen scale
/// (prototype over rig), displacement and force. `None` if the lead has not 8 weights.
pub fn structure_rig_values(
    lead_weights: &[f64],
    lead_stride: usize,
    lead_adapt_ticks: f64,
    specimen: [f64; 3],
    scale: [f64; 2],
) -> Option<[f64; STRUCTURE_RIG_VALUES]> {
    let mut v = [0.0; STRUCTURE_RIG_VALUES];
    v.get_mut(..8)?
        .copy_from_slice(lead_weights.get(..8).filter(|_| lead_weights.len() == 8)?);
    *v.get_mut(8)? = lead_stride as f64;
    *v.get_mut(9)? = lead_adapt_ticks;
    v.get_mut(10..13)?.copy_from_slice(&specimen);
    v.get_mut(13..15)?.copy_from_slice(&scale);
    Some(v)
}

#[cfg(test)]
mod tests;
