//! `rths plant`: the virtual servo-hydraulic plant's parameters, delay, gain and phase, Bode plot.

use std::path::PathBuf;

use anyhow::Context;
use plotters::prelude::*;
use rths_core::hal::{Actuator, Daq};
use rths_core::metrics::{self, Tracking};
use rths_core::params::Prototype;
use rths_hal_sim::{BoucWen, PlantParams, Preset, RigConfig, Specimen, VirtualRig};

use crate::machinery::motion::GroundMotion;
use crate::studies::analysis::{pure_response, Method};

/// Largest lag searched for J1, steps (0.1 s).
pub const MAX_LAG_STEPS: usize = 205;

/// The plant tracking El Centro with no compensation: the target is the brace deformation of the
/// pure prototype (Chang, 1/2048 s); each tick reads the sensors, commands the target and advances.
/// Returns the benchmark criteria of the measured displacement against the target (the reference
/// is the target too, so J4/J5 equal J2/J3) and the target.
pub fn el_centro_tracking(params: PlantParams) -> anyhow::Result<Tracking> {
    let dt_s = params.dt_s();
    let ag = GroundMotion::el_centro().resample_mm_s2(dt_s);
    let target = pure_response(&Prototype::paper(), &ag, dt_s, Method::Chang)?.brace_disp_mm;
    let mut rig = VirtualRig::new(params);
    let mut measured = Vec::with_capacity(target.len());
    for &t in &target {
        let s = rig
            .read()
            .map_err(|e| anyhow::anyhow!("sensor read failed: {e}"))?;
        measured.push(s.disp_mm);
        rig.command(t)
            .map_err(|e| anyhow::anyhow!("command failed: {e}"))?;
        rig.advance_tick();
    }
    metrics::tracking(&measured, &target, &target, MAX_LAG_STEPS)
        .map_err(|e| anyhow::anyhow!("tracking metrics: {e:?}"))
}

/// Plant preset names on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum PresetArg {
    /// The RTHS benchmark plant (Silva et al. 2020).
    Benchmark,
    /// The benchmark time-scaled to the UNR actuator's 13.7 ms (28 steps).
    UnrCompact,
}

/// Specimen names on the command line.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum SpecimenArg {
    /// Linear spring, the paper's brace at force scale 1000 (1.2241 kN/mm).
    Linear,
    /// Bouc–Wen hysteretic brace (linearized at its initial stiffness for the frequency response).
    BoucWen,
}

/// Arguments of `rths plant`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Plant preset.
    #[arg(long, value_enum, default_value = "unr-compact")]
    pub preset: PresetArg,
    /// Specimen model.
    #[arg(long, value_enum, default_value = "linear")]
    pub specimen: SpecimenArg,
    /// Draw the parameters from the benchmark's uncertainty with this seed (nominal if absent).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write a Bode plot (magnitude and phase, 0.1–50 Hz) to this PNG file.
    #[arg(long)]
    pub bode: Option<PathBuf>,
}

/// The plant configuration of the arguments.
pub fn config(args: &Args) -> RigConfig {
    let mut c = RigConfig::new(match args.preset {
        PresetArg::Benchmark => Preset::Benchmark,
        PresetArg::UnrCompact => Preset::UnrCompact,
    });
    c.specimen = match args.specimen {
        SpecimenArg::Linear => Specimen::Linear,
        SpecimenArg::BoucWen => Specimen::BoucWen(BoucWen::default()),
    };
    if let Some(seed) = args.seed {
        c.seed = seed;
        c.uncertainty = true;
    }
    c
}

/// The validated plant of the arguments.
pub fn params(args: &Args) -> anyhow::Result<PlantParams> {
    config(args)
        .build()
        .map_err(|e| anyhow::anyhow!("invalid plant configuration: {e}"))
}

/// Low frequency at which the phase slope gives the delay, Hz.
const DELAY_FREQ_HZ: f64 = 0.5;

/// Run `rths plant`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let p = params(&args)?;
    if let Some(path) = &args.bode {
        crate::machinery::output::writable_file(path)?;
    }
    crate::outln!(
        "plant: preset {}, specimen {}, {}",
        p.preset().name(),
        p.specimen().name(),
        match args.seed {
            Some(s) => format!("uncertain parameters drawn with seed {s}"),
            None => "nominal parameters".to_string(),
        }
    );
    crate::outln!("  time scale r      {:.4} (s -> s/r)", p.time_scale());
    crate::outln!("  gain              {:.4}", p.gain());
    crate::outln!("  a1*b0             {:.5e}", p.a1_beta0());
    crate::outln!("  a2                {:.5e} N/m", p.a2());
    crate::outln!("  b1                {:.3} 1/s", p.beta1());
    crate::outln!("  b2                {:.5e} 1/s^2", p.beta2());
    crate::outln!("  a3                {:.4} 1/s", p.a3());
    crate::outln!("  specimen mass     {:.3} kg", p.specimen_mass_kg());
    // What a run's fair reference would use: the structure with this brace.
    let draw = crate::studies::study::DrawnPlant::of(&config(&args), 1.0)?;
    crate::outln!(
        "  specimen k        {:.4} kN/mm ({:.1} N/m, F = {:.4} of the paper's brace)",
        p.specimen_stiffness_kn_per_mm(),
        draw.specimen_stiffness_n_per_m,
        draw.specimen_stiffness_factor
    );
    crate::outln!(
        "  specimen c        {:.1} N*s/m",
        p.specimen_damping_n_s_per_m()
    );
    crate::outln!(
        "  limits            stroke +/-{} mm, velocity {} mm/s, force {} kN",
        p.stroke_mm(),
        p.velocity_limit_mm_s(),
        p.capacity_kn()
    );
    crate::outln!(
        "  RK4 sub-steps     {} per {:.1} us tick",
        p.substeps(),
        p.dt_s() * 1e6
    );
    let delay_s = p.phase_delay_s(DELAY_FREQ_HZ);
    crate::outln!(
        "delay (phase slope at {DELAY_FREQ_HZ} Hz): {:.2} ms = {:.1} controller steps",
        delay_s * 1e3,
        delay_s / p.dt_s()
    );
    let tr = el_centro_tracking(p)?;
    crate::outln!(
        "El Centro brace deformation, no compensation: J1 = {} steps ({:.2} ms), J2 = {:.2}%, J3 = {:.2}%",
        tr.j1_steps,
        tr.j1_steps as f64 * p.dt_s() * 1e3,
        tr.j2_pct,
        tr.j3_pct
    );
    crate::outln!("frequency response x/u:");
    for f in [1.0, 5.0, 10.0] {
        let r = p.frequency_response(f);
        crate::outln!(
            "  {f:>4} Hz  gain {:.4}  phase {:8.2} deg  (delay {:.2} ms)",
            r.gain,
            r.phase_deg,
            p.phase_delay_s(f) * 1e3
        );
    }
    if let Some(path) = &args.bode {
        bode(&p, path).with_context(|| format!("drawing {}", path.display()))?;
        crate::outln!("Bode plot written to {}", path.display());
    }
    Ok(())
}

/// Draw magnitude (dB) and phase (deg) against log frequency, 0.1–50 Hz.
fn bode(p: &PlantParams, path: &std::path::Path) -> anyhow::Result<()> {
    crate::machinery::plot::init_fonts()?;
    let n = 400;
    let pts: Vec<(f64, f64, f64)> = (0..=n)
        .map(|i| {
            let f = 0.1 * 500f64.powf(i as f64 / n as f64);
            let r = p.frequency_response(f);
            (f, 20.0 * r.gain.log10(), r.phase_deg)
        })
        .collect();
    let root = crate::machinery::plot::bitmap(path, (900, 700))?;
    root.fill(&WHITE)?;
    let title = format!(
        "Plant x/u: {} preset, {} specimen",
        p.preset().name(),
        p.specimen().name()
    );
    let (top, bottom) = root
        .titled(&title, ("sans-serif", 22))?
        .split_vertically(330);
    let (mag_lo, mag_hi) = pts
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), q| {
            (lo.min(q.1), hi.max(q.1))
        });
    let mut mag = ChartBuilder::on(&top)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (0.1f64..50f64).log_scale(),
            (mag_lo - 2.0).floor()..(mag_hi + 2.0).ceil(),
        )?;
    mag.configure_mesh()
        .x_desc("frequency (Hz)")
        .y_desc("magnitude (dB)")
        .label_style(("sans-serif", 14))
        .draw()?;
    mag.draw_series(LineSeries::new(
        pts.iter().map(|q| (q.0, q.1)),
        BLUE.stroke_width(2),
    ))?;
    let phase_lo = pts.iter().fold(0.0f64, |lo, q| lo.min(q.2));
    let mut ph = ChartBuilder::on(&bottom)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(
            (0.1f64..50f64).log_scale(),
            ((phase_lo / 45.0).floor() * 45.0)..0.0,
        )?;
    ph.configure_mesh()
        .x_desc("frequency (Hz)")
        .y_desc("phase (deg)")
        .label_style(("sans-serif", 14))
        .draw()?;
    ph.draw_series(LineSeries::new(
        pts.iter().map(|q| (q.0, q.2)),
        RED.stroke_width(2),
    ))?;
    root.present()?;
    Ok(())
}
