//! An imported structure in the hybrid loop on the virtual rig (`rths simulate --structure S.json
//! --scenario meta-online|fe-online-ats`, docs/opensees.md "In the loop"): its analytical part in
//! core's controller (`rths_core::control::Controller`, the firmware's tick) driven by the host's
//! one control step ([`crate::machinery::drive::run`]) against the virtual plant carrying the structure's
//! specimen, with the rig's identified compensation; and the run's score against the whole model
//! with the specimen the rig really has.
//!
//! What the controller sees: the ground acceleration, the measured (noisy, quantized)
//! displacement and force, and what was identified of the rig (its lead filter and specimen, a
//! rig file's or identified on this virtual plant before the run). The specimen the plant really
//! has (a draw of the benchmark's uncertainty) reaches the reference alone ([`reference`]).

use std::ops::ControlFlow;

use anyhow::Context;
use rths_core::compensator::Compensator;
use rths_core::control::{
    Analytical, CompensatorTarget, ControlConfig, Controller, FeedbackSource, ForceCorrection,
};
use rths_core::metrics;
use rths_core::params::{Prototype, SpecimenScale, DISP_SCALE, DT_S};
use rths_core::supervisor::Limits;
use rths_hal_sim::{Preset, RigConfig, Specimen, VirtualRig};
use serde::Serialize;

use crate::machinery::drive::{self, Stop};
use crate::machinery::imported::fe::{self, FeHistory};
use crate::machinery::imported::ImportedStructure;
use crate::machinery::reference::DrawnPlant;
use crate::studies::scenario::{self, ScenarioReport};

/// The virtual plant an imported structure's specimen is tested on: `preset` with the paper's
/// brace as the rig's specimen (the rig `rths identify` characterizes by default), sensor noise
/// `seed`, the benchmark's uncertainty drawn with `seed` if `uncertainty`; and its specimen
/// stiffness factor over the paper's brace (1).
///
/// The structure's specimen reaches the rig through [`specimen_scale`], not through a softer rig
/// specimen: at force scale 1000 the shipped frames' 50 kN/mm brace would be a 0.05 kN/mm spring
/// on the rig, whose own moving mass then resonates at 6.6 Hz (benchmark preset), inside the
/// structure's band, and whose load cell's noise is 25 times larger against its force.
pub fn rig_of(preset: Preset, seed: u64, uncertainty: bool) -> (RigConfig, f64) {
    let factor = 1.0;
    let mut rig = crate::machinery::reference::rig_config(preset, Specimen::Linear, factor, seed);
    rig.uncertainty = uncertainty;
    (rig, factor)
}

/// The prototype ↔ rig conversion of an imported structure's hybrid run (the one home of its
/// scale): displacement scale 1 (the rig imposes the interface's displacement), force scale such
/// that the rig's nominal specimen ([`rig_of`]) stands for the structure's
/// `--specimen-stiffness`: `k_E = k_rig · force / disp`.
pub fn specimen_scale(structure: &ImportedStructure) -> anyhow::Result<SpecimenScale> {
    let rig_k = RigConfig::new(Preset::Benchmark).specimen_stiffness_kn_per_mm;
    SpecimenScale::new(
        DISP_SCALE,
        structure.specimen_stiffness_kn_per_mm() * DISP_SCALE / rig_k,
    )
    .map_err(|e| anyhow::anyhow!("the specimen scale of {}: {e:?}", structure.name()))
}

/// The reference of a hybrid run on `rig` (configured with specimen stiffness factor `factor`):
/// the host FE of the whole model with the specimen the plant really has (drawn, with the
/// uncertainty) under `ag_mm_s2`, and what was drawn. Evaluation only: the controller never sees
/// it.
pub fn reference(
    structure: &ImportedStructure,
    rig: &RigConfig,
    factor: f64,
    ag_mm_s2: &[f64],
) -> anyhow::Result<(FeHistory, DrawnPlant)> {
    let draw = DrawnPlant::of(rig, factor)?;
    let k_true = structure.specimen_stiffness_kn_per_mm() * draw.specimen_stiffness_factor / factor;
    let h = fe::run_with_specimen(structure, k_true, ag_mm_s2, DT_S, |_| {})
        .context("the reference (the whole model with the rig's specimen)")?;
    Ok((h, draw))
}

/// What a hybrid run's controller is given of the rig: its compensator and the force correction.
pub struct Compensation {
    /// The compensator (the identified lead, or the ATS).
    pub compensator: Compensator,
    /// The measured force brought to the target displacement with the identified specimen
    /// ([`ForceCorrection::NONE`]: as measured).
    pub correction: ForceCorrection,
}

/// A hybrid run, one row per tick.
#[derive(Debug, Clone)]
pub struct OnlineRun {
    /// The target in force at each tick (the analytical part's), mm.
    pub target_mm: Vec<f64>,
    /// The command in force at each tick, mm (prototype).
    pub command_mm: Vec<f64>,
    /// The measured displacement, mm (prototype; NaN on a DAQ error).
    pub measured_mm: Vec<f64>,
    /// The measured force, kN (rig).
    pub measured_force_kn: Vec<f64>,
    /// The analytical part's own interface and outputs at its last completed step.
    pub model: FeHistory,
}

/// A hybrid run's analytical part as the history reads it: its interface displacement and its
/// outputs (in the structure's order) at the last completed step, mm.
pub trait ReadOut {
    /// `(interface, outputs)` of `analytical` (pushed into `outputs`).
    fn read(&self, analytical: &Analytical, outputs: &mut Vec<f64>) -> f64;
}

/// The reduced model's read-outs (`meta-online`).
pub struct ReducedReadOut;

impl ReadOut for ReducedReadOut {
    fn read(&self, analytical: &Analytical, outputs: &mut Vec<f64>) -> f64 {
        match analytical {
            Analytical::StructureReduced(m) => {
                let m = m.model();
                outputs.extend((0..m.params().outputs()).map(|o| m.output_mm(o)));
                m.interface_mm()
            }
            _ => f64::NAN,
        }
    }
}

/// Run `analytical` in core's controller on the virtual plant `rig` over `ag_mm_s2` (one sample
/// per tick) at specimen scale `scale` ([`specimen_scale`]), with `compensation`, the compensator given the target in force (the rig is at the
/// displacement whose force the model reads, as every structure's hybrid run), the paper
/// actuator's supervisor. `output_columns` names the outputs `read` gives.
pub fn run_online(
    scale: SpecimenScale,
    analytical: Analytical,
    compensation: Compensation,
    rig: &RigConfig,
    ag_mm_s2: &[f64],
    output_columns: Vec<String>,
    read: &dyn ReadOut,
) -> anyhow::Result<(OnlineRun, Stop)> {
    let config = ControlConfig::new(
        Prototype::paper(),
        scale,
        FeedbackSource::Measured,
        Limits::paper_actuator(),
    )
    .context("the controller of the imported structure's hybrid run")?
    .with_force_correction(compensation.correction)
    .with_compensator_target(CompensatorTarget::Current);
    let mut ctl = Controller::new(config, analytical, compensation.compensator);
    let mut plant = VirtualRig::new(rig.build().context("the virtual plant")?);
    let n = ag_mm_s2.len();
    let mut run = OnlineRun {
        target_mm: Vec::with_capacity(n),
        command_mm: Vec::with_capacity(n),
        measured_mm: Vec::with_capacity(n),
        measured_force_kn: Vec::with_capacity(n),
        model: FeHistory {
            dt_s: DT_S,
            output_columns,
            interface_mm: Vec::with_capacity(n),
            outputs_mm: Vec::with_capacity(n),
        },
    };
    let stop = drive::run(
        &mut ctl,
        Some(&mut plant),
        ag_mm_s2,
        None,
        DT_S,
        |st, ctl, _| {
            run.target_mm.push(st.target_mm);
            run.command_mm.push(scale.prototype_disp_mm(st.command_mm));
            run.measured_mm
                .push(scale.prototype_disp_mm(st.measured_mm));
            run.measured_force_kn.push(st.measured_force_kn);
            let mut outs = Vec::with_capacity(run.model.output_columns.len());
            run.model
                .interface_mm
                .push(read.read(ctl.analytical(), &mut outs));
            run.model.outputs_mm.push(outs);
            ControlFlow::Continue(())
        },
    );
    Ok((run, stop))
}

/// One output's error in a hybrid run against the reference, %.
#[derive(Debug, Clone, Serialize)]
pub struct OutputScore {
    /// The column (`out_<NODE>_<DOF>_mm`).
    pub column: String,
    /// NRMSE of the model's output against the reference's.
    pub nrmse_pct: Option<f64>,
    /// J4's form (the benchmark's J6, J7 for its floors): `100·std(x − x_r)/std(x_r)`.
    pub std_error_pct: Option<f64>,
    /// J5's form (the benchmark's J8, J9): `100·peak(x − x_r)/peak(x_r)`.
    pub peak_error_pct: Option<f64>,
}

/// A hybrid run's score.
#[derive(Debug, Clone, Serialize)]
pub struct OnlineScore {
    /// The study's figures at the interface: NRMSE of the target and of the measured displacement
    /// against the reference, J1-J5 (J4: the measured interface against the reference).
    #[serde(flatten)]
    pub report: ScenarioReport,
    /// NRMSE of the model's own interface displacement against the reference, %.
    pub interface_model_nrmse_pct: Option<f64>,
    /// Each output against the reference.
    pub outputs: Vec<OutputScore>,
}

/// Score `run` (stopped by `stop`, if it was) against `reference` (evaluation: the only place
/// the reference is read). A stopped run has the reason and no figures.
pub fn score(name: &str, run: &OnlineRun, reference: &FeHistory, stop: Stop) -> OnlineScore {
    let n = run.target_mm.len().min(reference.interface_mm.len());
    let stopped = stop.is_some();
    let report = scenario::figures_of_series(
        name,
        true,
        &run.target_mm[..n],
        &run.command_mm[..n],
        &run.measured_mm[..n],
        &reference.interface_mm[..n],
        stop,
    );
    let column = |h: &FeHistory, o: usize| -> Vec<f64> {
        h.outputs_mm
            .iter()
            .take(n)
            .map(|r| r.get(o).copied().unwrap_or(f64::NAN))
            .collect()
    };
    let outputs = reference
        .output_columns
        .iter()
        .enumerate()
        .map(|(o, c)| {
            let (x, r) = (column(&run.model, o), column(reference, o));
            let ok = |v: Result<f64, metrics::MetricError>| v.ok().filter(|_| !stopped);
            OutputScore {
                column: c.clone(),
                nrmse_pct: ok(metrics::nrmse_pct(&x, &r)),
                std_error_pct: ok(metrics::normalized_std_error_pct(&x, &r)),
                peak_error_pct: ok(metrics::normalized_peak_error_pct(&x, &r)),
            }
        })
        .collect();
    let interface_model_nrmse_pct = metrics::nrmse_pct(
        &run.model.interface_mm[..n.min(run.model.interface_mm.len())],
        &reference.interface_mm[..n.min(run.model.interface_mm.len())],
    )
    .ok()
    .filter(|_| !stopped);
    OnlineScore {
        report,
        interface_model_nrmse_pct,
        outputs,
    }
}

impl OnlineRun {
    /// Write `time_s,interface_mm,out_<NODE>_<DOF>_mm...` (the model's, as the pure scenarios
    /// write them), then `target_mm,command_mm,measured_mm,measured_force_kn` of the rig.
    pub fn write_csv(&self, path: &std::path::Path) -> std::io::Result<()> {
        use std::io::Write;
        let h = &self.model;
        let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
        write!(w, "time_s,interface_mm")?;
        for c in &h.output_columns {
            write!(w, ",{c}")?;
        }
        writeln!(w, ",target_mm,command_mm,measured_mm,measured_force_kn")?;
        for (k, (x, outs)) in h.interface_mm.iter().zip(&h.outputs_mm).enumerate() {
            write!(w, "{},{x}", k as f64 * h.dt_s)?;
            for o in outs {
                write!(w, ",{o}")?;
            }
            let at = |v: &[f64]| v.get(k).copied().unwrap_or(f64::NAN);
            writeln!(
                w,
                ",{},{},{},{}",
                at(&self.target_mm),
                at(&self.command_mm),
                at(&self.measured_mm),
                at(&self.measured_force_kn)
            )?;
        }
        w.flush()
    }
}
