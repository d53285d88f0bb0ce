//! One vRTHS benchmark run: the numerical substructure of a case integrated by Chang's method
//! ([`ChangN`]) at 4096 Hz, the benchmark plant and specimen (`rths-hal-sim`, `--preset benchmark`)
//! behind the benchmark's sensors and 18-bit converters, a controller, and the reference (the whole
//! structure, linear, Newmark average acceleration, same record and intensity). The controller is
//! `rths_core::control::Controller` (the firmware's, with its supervisor at the benchmark
//! actuator's limits, [`actuator_limits`]) driven by the host's one control step
//! ([`crate::machinery::drive::run`]).
//!
//! What the controller sees: the ground acceleration, the measured (noisy, quantized) actuator
//! displacement and load-cell force, and the nominal plant model the benchmark hands its
//! participants (the ATS starts from its phase delay). It never sees the drawn plant, the specimen's
//! true force or the reference: only the evaluation ([`BenchmarkRun::criteria`]) does.

use std::ops::ControlFlow;
use std::sync::OnceLock;

use anyhow::Context;
use rths_core::compensator::{Ats, AtsConfig, AtsParams, Compensator, Lead};
use rths_core::control::{
    self as core_control, Analytical, ControlConfig, Controller, FeedbackSource,
};
use rths_core::integrator::Newmark;
use rths_core::metamodel::{DeltaArx, DeltaArxParams};
use rths_core::metrics::{benchmark_criteria, normalized_std_error_pct, BenchmarkCriteria};
use rths_core::params::{Prototype, SpecimenScale};
use rths_core::structure::{LinearStructure, Mat};
use rths_core::structure_n::{ChangN, MAX_DOF};
use rths_core::supervisor::{Limits, State};
use rths_files::structure_file::{Structure, SI_TO_MM_KN};
use rths_hal_sim::{PlantParams, VirtualRig};

use crate::machinery::motion::GroundMotion;

use super::ident::Converters;
use super::meta::META_FORCE_CORRECTION;
use super::plant::{plant_params, PlantDraw};
use super::{
    noise_sigma, BenchmarkRecord, ACTUATOR_CAPACITY_N, BENCHMARK_DT_S, DISP_NOISE_POWER_M2,
};
use crate::machinery::drive;

/// The controllers the benchmark can run.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum ControllerKind {
    /// Chang's method on the numerical substructure, no delay compensation.
    Fe,
    /// Chang's method with the adaptive time-series compensator (ATS).
    FeAts,
    /// The fixed-order metamodel of the numerical substructure (docs/benchmark.md), force
    /// correction, ATS.
    MetaAts,
    /// Chang's method with the rig's identified lead filter and its online gain-and-delay
    /// correction, identified through the converters (docs/benchmark.md).
    FeId,
    /// The metamodel with the force correction from the identified specimen, the identified lead
    /// filter and its online correction.
    MetaId,
}

impl ControllerKind {
    /// The CLI name.
    pub fn name(self) -> &'static str {
        match self {
            ControllerKind::Fe => "fe",
            ControllerKind::FeAts => "fe-ats",
            ControllerKind::MetaAts => "meta-ats",
            ControllerKind::FeId => "fe-id",
            ControllerKind::MetaId => "meta-id",
        }
    }

    /// Whether it runs on the metamodel (else on Chang's method).
    pub fn uses_metamodel(self) -> bool {
        matches!(self, ControllerKind::MetaAts | ControllerKind::MetaId)
    }

    /// Whether it identifies the rig before the run.
    pub fn identifies(self) -> bool {
        matches!(self, ControllerKind::FeId | ControllerKind::MetaId)
    }
}

/// One run's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunConfig {
    /// Partitioning case, 1..=4.
    pub case: u8,
    /// Record.
    pub record: BenchmarkRecord,
    /// Factor on the ground acceleration.
    pub intensity: f64,
    /// Plant.
    pub plant: PlantDraw,
    /// Controller.
    pub controller: ControllerKind,
}

/// The time histories of a run, one value per tick (mm).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BenchmarkHistory {
    /// Time, s.
    pub time_s: Vec<f64>,
    /// Measured first-floor (actuator) displacement.
    pub measured_mm: Vec<f64>,
    /// Target first-floor displacement (the numerical substructure's).
    pub target_mm: Vec<f64>,
    /// Numerical floors, `floors_mm[j][k]` (floor j+1).
    pub floors_mm: Vec<Vec<f64>>,
    /// Reference floors, `reference_mm[j][k]`.
    pub reference_mm: Vec<Vec<f64>>,
    /// The actuator's true (noise-free) displacement: evaluation only.
    pub true_disp_mm: Vec<f64>,
}

/// The outcome of a run.
#[derive(Debug, Clone, PartialEq)]
pub struct BenchmarkRun {
    /// Its settings.
    pub config: RunConfig,
    /// J1-J9 (`None` if the run went unstable).
    pub criteria: Option<BenchmarkCriteria>,
    /// Why the run was stopped, if it was (divergence, stroke).
    pub unstable: Option<String>,
    /// The histories (up to where the run stopped).
    pub history: BenchmarkHistory,
    /// The ATS coefficients at the end `[a0, a1 (s), a2 (s²)]` (fe-ats).
    pub ats_coefficients: Option<[f64; 3]>,
    /// The rig's identification (the `*-id` controllers).
    pub identification: Option<std::sync::Arc<super::ident::RigIdentification>>,
    /// The lead's online correction at the end `[gain, delay (s)]` (the `*-id` controllers).
    pub lead_adaptation: Option<[f64; 2]>,
    /// The force-correction stiffness used, kN/mm (metamodel controllers).
    pub force_correction_kn_per_mm: Option<f64>,
    /// The drawn specimen stiffness, N/m (evaluation only).
    pub specimen_stiffness_n_per_m: f64,
    /// The structure's name (the case file's or the `--structure` file's).
    pub structure_name: String,
    /// The specimen's DOF, 0-based.
    pub specimen_dof: usize,
    /// Ticks at which the load cell read at the end of its ±8900 N range (clipped: the force fed
    /// back is wrong there; a structure file whose specimen moves more than ~7.5 mm does this).
    pub clipped_force_ticks: usize,
    /// The record's name.
    pub record_name: String,
    /// J2 of the true (noise-free) displacement, %: how much of J2 is sensor noise (evaluation only).
    pub j2_noise_free_pct: Option<f64>,
}

/// The ATS's starting delay: the nominal plant's phase delay at the structure's second mode (the
/// first for one DOF). The benchmark gives its participants the nominal plant model; the drawn plant
/// stays unseen. Why not the first mode: the ATS starts from `[1, τ, τ²/2]`, whose `τ²/2·s²` term
/// grows with frequency; from the first mode's 23.5 ms, case 1's loop grows from sensor noise
/// before the adaptation latches (J2 15 % on El Centro), while from the second mode's shorter delay
/// it stays quiet and the ATS adapts to the same coefficients (a1 ≈ 23 ms) (`docs/benchmark.md`).
pub fn nominal_delay_s(structure: &Structure) -> anyhow::Result<f64> {
    let f = structure.natural_frequencies_hz();
    let f_hz = f
        .get(1)
        .or(f.first())
        .copied()
        .context("the structure has no natural frequency")?;
    Ok(plant_params(PlantDraw::Nominal, structure.specimen().1)?.phase_delay_s(f_hz))
}

/// The reference: the whole structure with the specimen the plant actually holds (its drawn
/// stiffness and damping in place of the nominal ones the numerical part subtracted), linear,
/// Newmark average acceleration; one history per floor. Evaluation only: the controller never sees
/// this. Any N in 1..=[`MAX_DOF`] (the core's integrator is sized at compile time: one instance per N).
pub fn reference(
    structure: &Structure,
    plant: &PlantParams,
    ag_mm_s2: &[f64],
) -> anyhow::Result<Vec<Vec<f64>>> {
    match structure.dofs() {
        1 => reference_n::<1>(structure, plant, ag_mm_s2),
        2 => reference_n::<2>(structure, plant, ag_mm_s2),
        3 => reference_n::<3>(structure, plant, ag_mm_s2),
        4 => reference_n::<4>(structure, plant, ag_mm_s2),
        5 => reference_n::<5>(structure, plant, ag_mm_s2),
        6 => reference_n::<6>(structure, plant, ag_mm_s2),
        7 => reference_n::<7>(structure, plant, ag_mm_s2),
        8 => reference_n::<8>(structure, plant, ag_mm_s2),
        n => anyhow::bail!(
            "the benchmark's reference takes 1..={MAX_DOF} DOFs; {} has {n}",
            structure.name()
        ),
    }
}

fn reference_n<const N: usize>(
    structure: &Structure,
    plant: &PlantParams,
    ag_mm_s2: &[f64],
) -> anyhow::Result<Vec<Vec<f64>>> {
    let m = |a: &nalgebra::DMatrix<f64>| Mat::<N>::from_fn(|i, j| a[(i, j)]);
    let (_, k_e, c_e) = structure.specimen();
    let d = structure.specimen_dof();
    let (mut k, mut c) = (m(structure.stiffness()), m(structure.damping()));
    // N/m and N·s/m → kN/mm and kN·s/mm.
    k[(d, d)] += plant.specimen_stiffness_n_per_m() * SI_TO_MM_KN - k_e;
    c[(d, d)] += plant.specimen_damping_n_s_per_m() * SI_TO_MM_KN - c_e;
    let model =
        LinearStructure::new(m(structure.mass()), c, k, k).context("reference structure")?;
    let mut nm = Newmark::new(model, BENCHMARK_DT_S).context("reference integrator")?;
    let mut out: Vec<Vec<f64>> = (0..N).map(|_| Vec::with_capacity(ag_mm_s2.len())).collect();
    for (k, &ag) in ag_mm_s2.iter().enumerate() {
        let d = if k == 0 {
            nm.reset(ag);
            nm.state().disp
        } else {
            nm.step(ag).disp
        };
        for (o, x) in out.iter_mut().zip(d.iter()) {
            o.push(*x);
        }
    }
    Ok(out)
}

/// The benchmark actuator's interlock limits for its runs: the nominal actuator's stroke and
/// velocity with the 95 % margins of `Limits::paper_actuator`, its force capacity (the load
/// cell's full scale, [`ACTUATOR_CAPACITY_N`]) without one (the benchmark's case 3 on Kobe asks
/// more than 95 % of it: that margin stops the run at 10.1 s), its sensor timeout, overrun count
/// and ramps, at the benchmark's 4096 Hz; the per-tick plausibility check knows the displacement
/// sensor's noise (at 4096 Hz the velocity limit's step alone is within a few σ of two
/// readings' difference, docs/benchmark.md).
pub fn actuator_limits(specimen_kn_per_mm: f64) -> anyhow::Result<Limits> {
    let nominal = plant_params(PlantDraw::Nominal, specimen_kn_per_mm)?;
    Limits::new(
        0.95 * nominal.stroke_mm(),
        0.95 * nominal.velocity_limit_mm_s(),
        ACTUATOR_CAPACITY_N * 1e-3,
        8,
        4,
        20.0,
        10.0,
        BENCHMARK_DT_S,
    )
    .and_then(|l| l.with_sensor_noise_mm(noise_sigma(DISP_NOISE_POWER_M2, BENCHMARK_DT_S) * 1e3))
    .map_err(|e| anyhow::anyhow!("the benchmark actuator's limits: {e}"))
}

/// The metamodel of case `case` (1..=4), trained once per process.
fn trained(case: u8, structure: &Structure) -> anyhow::Result<super::meta::Meta> {
    static TRAINED: [OnceLock<super::meta::Meta>; 4] = [
        OnceLock::new(),
        OnceLock::new(),
        OnceLock::new(),
        OnceLock::new(),
    ];
    // Case 0 (a structure file): trained for it, not cached.
    let Some(slot) = TRAINED.get(usize::from(case).wrapping_sub(1)) else {
        return super::meta::train(structure, super::DEFAULT_INTENSITY);
    };
    if let Some(m) = slot.get() {
        return Ok(m.clone());
    }
    let m = super::meta::train(structure, super::DEFAULT_INTENSITY)?;
    Ok(slot.get_or_init(|| m).clone())
}

/// Run one benchmark case.
pub fn run(cfg: &RunConfig) -> anyhow::Result<BenchmarkRun> {
    check_intensity(cfg.intensity)?;
    let structure = super::case_structure(cfg.case)?;
    if structure.dofs() != 3 || structure.specimen_dof() != 0 {
        anyhow::bail!(
            "benchmark case {} is not a 3-story frame with the specimen at DOF 1",
            cfg.case
        );
    }
    run_on(&structure, &cfg.record.motion()?, cfg)
}

fn check_intensity(intensity: f64) -> anyhow::Result<()> {
    if !(intensity.is_finite() && intensity > 0.0) {
        anyhow::bail!(
            "--intensity must be a positive number, got {}",
            rths_files::readable(intensity)
        );
    }
    Ok(())
}

/// Shortest record the benchmark runs, s: the J's are standard deviations over the run, and the
/// compensators adapt over their ~1 s windows.
pub const MIN_RECORD_S: f64 = 2.0;

/// Longest record the benchmark runs, s (the histories of one run are kept in memory).
pub const MAX_RECORD_S: f64 = rths_files::motion::MAX_RECORD_DURATION_S;

/// Whether a ground-motion record matches the benchmark: a uniform step (the CSV reader refuses
/// any other, with its line) no finer than the benchmark's 4096 Hz tick (a finer record would be
/// decimated by the linear interpolation, its content above 2048 Hz lost unseen), and a duration
/// in [[`MIN_RECORD_S`], [`MAX_RECORD_S`]].
pub fn check_record(motion: &GroundMotion) -> anyhow::Result<()> {
    motion
        .validate()
        .with_context(|| format!("record {}", motion.name))?;
    let rate_hz = 1.0 / motion.dt_s;
    if motion.dt_s < BENCHMARK_DT_S * (1.0 - 1e-9) {
        anyhow::bail!(
            "record {}: sampled at {rate_hz:.1} Hz, above the benchmark's {} Hz: the 4096 Hz \
             interpolation would drop samples (resample it to 4096 Hz or below)",
            motion.name,
            super::BENCHMARK_RATE_HZ
        );
    }
    let duration_s = motion.duration_s();
    if !(MIN_RECORD_S..=MAX_RECORD_S).contains(&duration_s) {
        anyhow::bail!(
            "record {}: {duration_s:.3} s long; the benchmark runs records of \
             {MIN_RECORD_S}..={MAX_RECORD_S} s",
            motion.name
        );
    }
    Ok(())
}

/// Run the benchmark on any structure file (N ≤ 8 DOFs, the specimen on its DOF, validated by
/// `rths-files`) under the benchmark plant, with `motion` as the record (`cfg.record` and
/// `cfg.case` only label the run; case 0: not one of the four cases, the metamodel is trained for
/// this structure and not cached).
pub fn run_on(
    structure: &Structure,
    motion: &GroundMotion,
    cfg: &RunConfig,
) -> anyhow::Result<BenchmarkRun> {
    check_intensity(cfg.intensity)?;
    check_record(motion)?;
    let ag = motion.scaled(cfg.intensity).resample_mm_s2(BENCHMARK_DT_S);
    // The rig holds the file's specimen (for the four cases, the benchmark's own).
    let (_, k_e_file, _) = structure.specimen();
    let params = plant_params(cfg.plant, k_e_file)?;
    let reference = reference(structure, &params, &ag)?;
    let mut rig = Converters::new(VirtualRig::new(params));
    let mut meta = match cfg.controller.uses_metamodel() {
        true => Some(trained(cfg.case, structure)?),
        false => None,
    };
    let identification = match cfg.controller.identifies() {
        true => Some(super::ident::identified(cfg.plant, k_e_file)?),
        false => None,
    };
    let (_, k_e_nominal, _) = structure.specimen();
    // The force correction's stiffness: the identified specimen's for meta-id (measured data
    // only; why the full one, docs/benchmark.md "The force correction"), the disclosed half of
    // the nominal for meta-ats (trained in).
    let k_corr = match &identification {
        Some(id) => id.specimen.stiffness_kn_per_mm,
        None => META_FORCE_CORRECTION * k_e_nominal,
    };
    if let (Some(m), Some(_)) = (meta.as_mut(), &identification) {
        let params = DeltaArxParams::from_slice(m.params().theta(), k_corr)
            .context("the metamodel with the identified force correction")?;
        *m = DeltaArx::new(params);
    }
    let compensator = match cfg.controller {
        ControllerKind::Fe => Compensator::None,
        ControllerKind::FeAts | ControllerKind::MetaAts => Compensator::Ats(Ats::new(
            AtsParams::new(AtsConfig::paper(
                BENCHMARK_DT_S,
                nominal_delay_s(structure)?,
            ))
            .context("ATS parameters")?,
        )),
        ControllerKind::FeId | ControllerKind::MetaId => Compensator::Lead(Lead::new(
            identification.as_ref().context("the identified lead")?.lead,
        )),
    };
    let dof = structure.specimen_dof();
    // The numerical part in the controller: Chang's method, or the metamodel (its force
    // correction in its parameters). For the metamodel the other floors are the numerical model
    // under the measured force, a reconstruction beside the loop (not the command's path).
    let (analytical, mut beside) = match meta {
        Some(m) => (
            Analytical::StructureMeta(m),
            Some(
                ChangN::new(structure.numerical()?, BENCHMARK_DT_S)
                    .context("numerical substructure")?,
            ),
        ),
        None => (
            Analytical::StructureFe(
                core_control::StructureFe::new(structure.numerical()?, dof, BENCHMARK_DT_S)
                    .context("numerical substructure")?,
            ),
            None,
        ),
    };
    let limits = actuator_limits(k_e_file)?;
    // The benchmark's quantities are the rig's own (full scale): a unit specimen scale.
    let config = ControlConfig::new(
        Prototype::paper(),
        SpecimenScale::new(1.0, 1.0)?,
        FeedbackSource::Measured,
        limits,
    )?;
    let mut ctl = Controller::new(config, analytical, compensator);
    let dofs = structure.dofs();
    let n = ag.len();
    let mut h = BenchmarkHistory {
        floors_mm: (0..dofs).map(|_| Vec::with_capacity(n)).collect(),
        ..BenchmarkHistory::default()
    };
    let mut unstable = None;
    let mut clipped_force_ticks = 0;
    drive::run(
        &mut ctl,
        Some(&mut rig),
        &ag,
        None,
        BENCHMARK_DT_S,
        |st, ctl, rig| {
            if rig.is_some_and(Converters::force_clipped) {
                clipped_force_ticks += 1;
            }
            h.time_s.push(st.k as f64 * BENCHMARK_DT_S);
            h.measured_mm.push(st.measured_mm);
            h.true_disp_mm.push(st.true_disp_mm);
            h.target_mm.push(st.target_mm);
            let floors = match (beside.as_mut(), ctl.analytical()) {
                (Some(integ), _) => {
                    if st.k == 0 {
                        integ.reset(st.ground_accel_mm_s2);
                    } else {
                        let mut r = [0.0; MAX_DOF];
                        if let Some(ri) = r.get_mut(dof) {
                            *ri = st.measured_force_kn;
                        }
                        integ.advance(st.ground_accel_mm_s2, &r);
                    }
                    *integ.disp()
                }
                (None, Analytical::StructureFe(m)) => *m.chang().disp(),
                (None, _) => [f64::NAN; MAX_DOF],
            };
            for (f, x) in h.floors_mm.iter_mut().zip(floors) {
                f.push(x);
            }
            if let State::Fault(reason) = st.out.state {
                unstable = Some(format!(
                "the supervisor stopped the run at t = {:.3} s: {reason:?} (requested {:.3} mm, \
                 measured {:.3} mm; stroke ±{:.2} mm, {:.1} mm/s, ±{:.2} kN)",
                st.k as f64 * BENCHMARK_DT_S,
                st.out.requested_mm,
                st.measured_mm,
                limits.stroke_mm(),
                limits.velocity_mm_s(),
                limits.force_kn(),
            ));
                return ControlFlow::Break(());
            }
            ControlFlow::Continue(())
        },
    );
    let (ats_coefficients, lead_adaptation) = match ctl.compensator() {
        Compensator::Ats(a) => (Some(a.coefficients()), None),
        Compensator::Lead(l) => {
            let st = l.adaptation_state();
            (
                None,
                Some([
                    f64::from(st.gain),
                    f64::from(st.delay_ticks) * BENCHMARK_DT_S,
                ]),
            )
        }
        _ => (None, None),
    };
    let ticks = h.time_s.len();
    h.reference_mm = reference
        .into_iter()
        .map(|mut r| {
            r.truncate(ticks);
            r
        })
        .collect();
    let criteria = if unstable.is_none() {
        Some(criteria(&h, dof)?)
    } else {
        None
    };
    let j2_noise_free_pct = match criteria {
        Some(_) => Some(
            normalized_std_error_pct(&h.true_disp_mm, &h.target_mm)
                .map_err(|e| anyhow::anyhow!("J2 (noise-free): {e}"))?,
        ),
        None => None,
    };
    Ok(BenchmarkRun {
        config: *cfg,
        j2_noise_free_pct,
        criteria,
        unstable,
        history: h,
        ats_coefficients,
        lead_adaptation,
        identification,
        force_correction_kn_per_mm: cfg.controller.uses_metamodel().then_some(k_corr),
        specimen_stiffness_n_per_m: params.specimen_stiffness_n_per_m(),
        structure_name: structure.name().to_string(),
        specimen_dof: dof,
        clipped_force_ticks,
        record_name: motion.name.clone(),
    })
}

/// J1-J9: J1-J5 on the specimen's DOF, J6-J9 on the first two other floors in order (floors 2 and
/// 3 of the benchmark's frame); NaN where the structure has fewer.
fn criteria(h: &BenchmarkHistory, dof: usize) -> anyhow::Result<BenchmarkCriteria> {
    let others: Vec<usize> = (0..h.floors_mm.len()).filter(|&j| j != dof).collect();
    let pick = |i: usize| others.get(i).copied().unwrap_or(dof);
    let (a, b) = (pick(0), pick(1));
    let mut j = benchmark_criteria(
        &h.measured_mm,
        &h.target_mm,
        [&h.floors_mm[a], &h.floors_mm[b]],
        [&h.reference_mm[dof], &h.reference_mm[a], &h.reference_mm[b]],
        BENCHMARK_DT_S,
    )
    .map_err(|e| anyhow::anyhow!("J1-J9: {e}"))?;
    if others.is_empty() {
        (j.j6_pct, j.j8_pct) = (f64::NAN, f64::NAN);
    }
    if others.len() < 2 {
        (j.j7_pct, j.j9_pct) = (f64::NAN, f64::NAN);
    }
    Ok(j)
}
