//! `rths identify`: characterize a rig from measured signals only and write its rig file and
//! figure.

use std::path::{Path, PathBuf};

use anyhow::Context;
use rths_hal_sim::{BoucWen, FaultPlan, Preset, Specimen};

use crate::cmd::plant::{PresetArg, SpecimenArg};
use crate::machinery::identify::estimate::compensated;
use crate::machinery::identify::excitation::MAX_AMPLITUDE_MM;
use crate::machinery::identify::rig_file::{
    iso8601_utc, ActuatorInfo, CompensationInfo, ExcitationInfo, Provenance, QualityInfo, RigFile,
    RIG_FORMAT, SCHEMA_VERSION,
};
use crate::machinery::identify::{self, IdentifyConfig, Outcome};

/// Arguments of `rths identify`.
#[derive(Debug, Clone, clap::Args)]
pub struct Args {
    /// Plant preset of the virtual rig.
    #[arg(long, value_enum, default_value = "unr-compact")]
    pub preset: PresetArg,
    /// Seed of the sensor noise (and of the parameters with --uncertainty).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Draw the plant parameters from the benchmark's uncertainty with the seed.
    #[arg(long)]
    pub uncertainty: bool,
    /// Specimen model.
    #[arg(long, value_enum, default_value = "linear")]
    pub specimen: SpecimenArg,
    /// Scales the specimen's stiffness.
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub specimen_stiffness_factor: f64,
    /// Peak excitation, mm (at most 2.54, 10% of the stroke).
    #[arg(long, default_value_t = 2.0, value_name = "MM")]
    pub amplitude_mm: f64,
    /// Lead-filter tap spacing, ticks (1..=8).
    #[arg(long, default_value_t = 8)]
    pub lead_stride: usize,
    /// The rig file to write (only if every check passed).
    #[arg(long, value_name = "RIG.json")]
    pub out: PathBuf,
    /// The figure (default: the rig file's name with `.png`).
    #[arg(long, value_name = "PATH")]
    pub plot: Option<PathBuf>,
}

fn preset(a: PresetArg) -> Preset {
    match a {
        PresetArg::Benchmark => Preset::Benchmark,
        PresetArg::UnrCompact => Preset::UnrCompact,
    }
}

fn specimen(a: SpecimenArg) -> Specimen {
    match a {
        SpecimenArg::Linear => Specimen::Linear,
        SpecimenArg::BoucWen => Specimen::BoucWen(BoucWen::default()),
    }
}

/// The figure's path: `--plot`, or the rig file's name with `.png`.
fn plot_path(args: &Args) -> PathBuf {
    args.plot
        .clone()
        .unwrap_or_else(|| args.out.with_extension("png"))
}

/// The identification settings of the arguments, once the rig file and the figure are known to be
/// writable (before the identification's work).
pub fn config(args: &Args) -> anyhow::Result<IdentifyConfig> {
    let mut cfg = IdentifyConfig::default();
    if !(args.amplitude_mm > 0.0 && args.amplitude_mm <= MAX_AMPLITUDE_MM) {
        anyhow::bail!(
            "--amplitude-mm must be in (0, {MAX_AMPLITUDE_MM}] (10% of the stroke), got {}",
            rths_files::readable(args.amplitude_mm)
        );
    }
    crate::machinery::output::writable_file(&args.out)?;
    crate::machinery::output::writable_file(&plot_path(args))?;
    cfg.excitation.amplitude_mm = args.amplitude_mm;
    cfg.lead_stride = args.lead_stride;
    Ok(cfg)
}

/// The rig file of an outcome.
pub fn rig_file(args: &Args, cfg: &IdentifyConfig, o: &Outcome) -> RigFile {
    let id = &o.identification;
    let e = &o.excitation;
    let x = &e.config;
    RigFile {
        format: RIG_FORMAT.into(),
        schema_version: SCHEMA_VERSION,
        preset: preset(args.preset).name().into(),
        board: crate::machinery::identify::rig_file::VIRTUAL_BOARD.into(),
        specimen: specimen(args.specimen).name().into(),
        specimen_stiffness_factor: args.specimen_stiffness_factor,
        seed: args.seed,
        uncertainty: args.uncertainty,
        date_utc: iso8601_utc(std::time::SystemTime::now()),
        excitation: ExcitationInfo {
            amplitude_mm: x.amplitude_mm,
            peak_command_mm: e.peak_mm,
            band_hz: [x.band_lo_hz, x.band_hi_hz],
            corner_hz: x.corner_hz,
            duration_s: x.duration_s(),
            rate_limit_mm_s: x.rate_limit_mm_s,
            peak_velocity_mm_s: e.peak_velocity_mm_s,
            period_s: e.period_ticks as f64 * x.dt_s,
            periods: x.periods,
            lines: e.lines.len(),
        },
        actuator: ActuatorInfo {
            dt_s: x.dt_s,
            delay_ms: id.delay_s * 1e3,
            dead_time_ms: id.model.dead_time_s * 1e3,
            lag_ms: id.model.lag_s * 1e3,
            gain: id.model.gain,
            frf: id.frf.clone(),
        },
        compensation: CompensationInfo {
            lead_weights: id.lead_weights.to_vec(),
            lead_stride: cfg.lead_stride,
            ats_initial: id.ats_initial,
        },
        specimen_fit: id.specimen,
        quality: QualityInfo {
            min_coherence: id.min_coherence,
            mean_coherence: id.mean_coherence,
            good_line_fraction: id.good_line_fraction,
            frf_fit_error_pct: id.model.fit_error_pct,
            lead_fit_nrmse_pct: id.lead_fit_nrmse_pct,
            lead_residual_pct: id.lead_residual_pct,
            stiffness_r2: id.specimen.r2,
        },
        provenance: Provenance {
            rths_version: env!("CARGO_PKG_VERSION").into(),
            command_line: std::env::args().collect::<Vec<_>>().join(" "),
            device: None,
        },
    }
}

/// Run `rths identify`.
pub fn run(args: Args) -> anyhow::Result<()> {
    run_with_faults(&args, FaultPlan::none()).map(|_| ())
}

/// `rths identify` on a virtual rig with injected faults (the tests' bad rigs). Writes the rig file
/// and its figure only after every check passed; returns the file written.
pub fn run_with_faults(args: &Args, faults: FaultPlan) -> anyhow::Result<RigFile> {
    let f = args.specimen_stiffness_factor;
    if !(f.is_finite() && f > 0.0) {
        anyhow::bail!(
            "--specimen-stiffness-factor must be a positive number, got {}",
            rths_files::readable(f)
        );
    }
    let cfg = config(args)?;
    let mut rig = crate::machinery::reference::rig_config(
        preset(args.preset),
        specimen(args.specimen),
        f,
        args.seed,
    );
    rig.uncertainty = args.uncertainty;
    let o = identify::identify_virtual(&rig, faults, &cfg)
        .context("identification refused, nothing written")?;
    write_outputs(args, &cfg, &o, rig_file(args, &cfg, &o))
}

/// Validate and write the rig file `file` of outcome `o` and its figure (`args.out`, `args.plot`),
/// the file last; print the summary. Shared by `rths identify` and `rths link ... identify`.
pub fn write_outputs(
    args: &Args,
    cfg: &IdentifyConfig,
    o: &Outcome,
    file: RigFile,
) -> anyhow::Result<RigFile> {
    let f = args.specimen_stiffness_factor;
    // Validate (and serialize) before touching the disk: a file that exists passed every check.
    let text = file.to_json().context("rig file")?;
    let plot = plot_path(args);
    let id = &o.identification;
    let comp = compensated(
        &id.frf,
        &id.lead_weights,
        cfg.lead_stride,
        cfg.excitation.dt_s,
    );
    let title = format!(
        "Rig identification: {} ({} specimen ×{f}, seed {}{})",
        file.preset,
        file.specimen,
        args.seed,
        if args.uncertainty { ", uncertain" } else { "" }
    );
    // The figure first: the rig file, written last and atomically, exists only if all went well.
    identify::figure::draw(&plot, &title, &id.frf, id.delay_s, &id.model, &comp)
        .with_context(|| format!("drawing {}", plot.display()))?;
    write_atomically(&args.out, &(text + "\n"))?;
    print_summary(&file, &args.out, &plot);
    Ok(file)
}

fn write_atomically(path: &Path, text: &str) -> anyhow::Result<()> {
    let tmp = path.with_extension("json.tmp");
    std::fs::write(&tmp, text).with_context(|| format!("writing {}", tmp.display()))?;
    std::fs::rename(&tmp, path).with_context(|| format!("writing {}", path.display()))
}

fn print_summary(r: &RigFile, out: &Path, plot: &Path) {
    let a = &r.actuator;
    let q = &r.quality;
    let s = &r.specimen_fit;
    crate::outln!(
        "identified {} ({} specimen) in {:.1} s of rig time, peak {:.2} mm, {:.0} mm/s",
        r.preset,
        r.specimen,
        r.excitation.duration_s,
        r.excitation.peak_command_mm,
        r.excitation.peak_velocity_mm_s
    );
    crate::outln!(
        "  actuator: delay {:.2} ms (model: dead time {:.2} ms, lag {:.2} ms), gain {:.4}; coherence min {:.4} mean {:.4}; model error {:.2}%",
        a.delay_ms, a.dead_time_ms, a.lag_ms, a.gain, q.min_coherence, q.mean_coherence, q.frf_fit_error_pct
    );
    for f in [1.0, 5.0, 10.0, 20.0] {
        if let Some(l) = a
            .frf
            .iter()
            .min_by(|x, y| (x.freq_hz - f).abs().total_cmp(&(y.freq_hz - f).abs()))
        {
            crate::outln!(
                "    {:>5.1} Hz  gain {:.4}  phase {:8.2} deg  coherence {:.4}",
                l.freq_hz,
                l.gain,
                l.phase_deg,
                l.coherence
            );
        }
    }
    crate::outln!(
        "  lead (stride {}): fit NRMSE {:.3}%, compensated residual {:.2}%; ATS a0 {:.4} a1 {:.5} s a2 {:.3e} s²",
        r.compensation.lead_stride,
        q.lead_fit_nrmse_pct,
        q.lead_residual_pct,
        r.compensation.ats_initial[0],
        r.compensation.ats_initial[1],
        r.compensation.ats_initial[2]
    );
    crate::outln!(
        "  specimen: k {:.4} kN/mm (R² {:.4}), c {:.3e} kN·s/mm, m {:.3e} kN·s²/mm",
        s.stiffness_kn_per_mm,
        s.r2,
        s.damping_kn_s_per_mm,
        s.mass_kn_s2_per_mm
    );
    crate::outln!("rig file {}, figure {}", out.display(), plot.display());
}
