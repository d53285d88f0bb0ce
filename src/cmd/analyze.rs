//! `rths analyze`: pure analysis of the prototype frame under a ground motion (the `fe-pure`
//! reference), with a summary, a CSV of the response and the paper's Figure 2.

use std::path::{Path, PathBuf};

use anyhow::Context;
use rths_core::params::{
    Prototype, ACTUATOR_CAPACITY_KN, ACTUATOR_STROKE_MM, ACTUATOR_VELOCITY_MM_S, DT_S, FORCE_SCALE,
    G_MM_S2,
};

use crate::machinery::motion::{GroundMotion, MotionError};
use crate::machinery::plot::{self, Panel};
use crate::studies::analysis::{pure_response, write_csv, Method, Summary};

/// Arguments of `rths analyze`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Ground motion: an AT2 or CSV (time_s, accel_g) file, or an embedded record name
    /// (el-centro, northridge, loma-prieta, kobe). Default: the embedded 1940 El Centro NS.
    #[arg(long, value_name = "PATH|NAME")]
    pub motion: Option<String>,
    /// Scale factor on the ground acceleration (positive; the scaled record must stay within
    /// ±20 g).
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub scale: f64,
    /// Integration method.
    #[arg(long, value_enum, default_value_t = Method::Chang)]
    pub method: Method,
    /// Write the response (one row per 1/2048 s step) to this CSV file.
    #[arg(long, value_name = "FILE.csv")]
    pub out: Option<PathBuf>,
    /// Draw ground acceleration, brace displacement and brace force (the paper's Figure 2) to this PNG;
    /// with `--structure`, the hysteresis (story force against drift) of every story.
    #[arg(long, value_name = "FILE.png")]
    pub plot: Option<PathBuf>,
    /// Analyze this yielding structure file (one with a `hysteresis` section; a linear one is
    /// refused) instead of the prototype: the nonlinear FE response (peak ductility, residual
    /// drift; docs/nonlinear.md).
    #[arg(long, value_name = "FILE.json")]
    pub structure: Option<PathBuf>,
    /// With `--structure`: write the run as a training time history (the layout `rths train
    /// nonlinear --histories` reads: every floor an output, the linear specimen the stand-in).
    #[arg(long, value_name = "FILE.csv", requires = "structure")]
    pub history: Option<PathBuf>,
    /// With `--structure`: seconds of free vibration after the record, so the frame comes to rest
    /// and its residual drift is defined (a held-out history's residual is judged only at rest).
    #[arg(long, value_name = "S", requires = "structure", default_value_t = crate::machinery::structure::FREE_VIBRATION_S)]
    pub free_s: f64,
}

/// The record named by `--motion`: an existing file first, then an embedded name.
pub fn load_motion(spec: Option<&str>) -> anyhow::Result<GroundMotion> {
    let Some(spec) = spec else {
        return GroundMotion::try_el_centro().context("embedded El Centro record");
    };
    let path = Path::new(spec);
    if path.exists() {
        return GroundMotion::from_path(path)
            .with_context(|| format!("reading ground motion {}", path.display()));
    }
    match GroundMotion::try_embedded(spec) {
        Ok(m) => Ok(m),
        Err(MotionError::UnknownRecord { known, .. }) => Err(anyhow::anyhow!(
            "--motion {spec}: no such file, and not an embedded record ({known})"
        )),
        Err(e) => Err(e).with_context(|| format!("embedded record {spec}")),
    }
}

/// Run `rths analyze`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !(args.scale.is_finite() && args.scale > 0.0) {
        anyhow::bail!(
            "--scale must be a positive number, got {}",
            rths_files::readable(args.scale)
        );
    }
    let motion = load_motion(args.motion.as_deref())?.scaled(args.scale);
    motion.validate().context("ground motion")?;
    if let Some(path) = &args.structure {
        return nonlinear(&args, path, &motion);
    }
    let proto = Prototype::paper();
    let ag = motion.resample_mm_s2(DT_S);
    let r = pure_response(&proto, &ag, DT_S, args.method).context("analysis")?;
    let summary = Summary::new(&proto, &r, DT_S);

    crate::outln!(
        "ground motion          {}: {} points at {} s ({:.3} s), PGA {:.4} g",
        motion.name,
        motion.accel_g.len(),
        motion.dt_s,
        motion.duration_s(),
        motion.pga_g()
    );
    crate::outln!("method                 {}", args.method);
    crate::outln!("{summary}");
    for warning in actuator_warnings(&summary, args.scale) {
        crate::outln!("note: {warning}");
    }

    if let Some(out) = &args.out {
        write_csv(&r, out)?;
        crate::outln!("wrote {} ({} rows)", out.display(), r.len());
    }
    if let Some(png) = &args.plot {
        let ag_g: Vec<f64> = r.ground_accel_mm_s2.iter().map(|a| a / G_MM_S2).collect();
        let title = format!(
            "Pure analysis, {} ({}): peak brace disp. {:.2} mm, force {:.0} kN",
            motion.name, args.method, summary.peak_brace_disp_mm, summary.peak_brace_force_kn
        );
        plot::stacked_time_series(
            png,
            &title,
            &[
                Panel::single("Ground accel. (g)", &r.time_s, &ag_g),
                Panel::single("Brace disp. (mm)", &r.time_s, &r.brace_disp_mm),
                Panel::single("Brace force (kN)", &r.time_s, &r.brace_force_kn),
            ],
        )?;
        crate::outln!("wrote {}", png.display());
    }
    Ok(())
}

/// What a hybrid test of this response would ask beyond the paper's actuator (displacement scale 1,
/// force scale [`FORCE_SCALE`]), with the largest `--scale` that would fit (`scale` is the one used).
pub fn actuator_warnings(s: &Summary, scale: f64) -> Vec<String> {
    let checks = [
        (
            "brace deformation",
            s.peak_brace_disp_mm,
            ACTUATOR_STROKE_MM,
            "mm stroke",
        ),
        (
            "brace velocity",
            s.peak_brace_vel_mm_s,
            ACTUATOR_VELOCITY_MM_S,
            "mm/s velocity",
        ),
        (
            "brace force",
            s.peak_brace_force_kn / FORCE_SCALE,
            ACTUATOR_CAPACITY_KN,
            "kN capacity (specimen force)",
        ),
    ];
    checks
        .iter()
        .filter(|(_, peak, limit, _)| peak > limit)
        .map(|(what, peak, limit, unit)| {
            format!(
                "peak {what} {peak:.2} exceeds the actuator's {limit} {unit}: \
                 a hybrid test needs --scale <= {:.3}",
                scale.abs() * limit / peak
            )
        })
        .collect()
}

/// `rths analyze --structure FILE`: the nonlinear FE response of a yielding structure file.
fn nonlinear(args: &Args, path: &Path, motion: &GroundMotion) -> anyhow::Result<()> {
    if args.method != Method::Chang {
        anyhow::bail!("--structure is integrated by Chang's explicit method only (drop --method)");
    }
    let structure = rths_files::structure_file::Structure::load(path)?;
    let ag = motion.resample_mm_s2(DT_S);
    if !(args.free_s.is_finite() && (0.0..=600.0).contains(&args.free_s)) {
        anyhow::bail!(
            "--free-s {}: the free vibration must be between 0 and 600 s",
            args.free_s
        );
    }
    let r = crate::machinery::structure::fe_reference_free(&structure, &ag, DT_S, args.free_s)?;
    crate::outln!(
        "ground motion          {}: PGA {:.4} g, {:.3} s (+{} s free vibration)",
        motion.name,
        motion.pga_g(),
        motion.duration_s(),
        args.free_s
    );
    crate::outln!(
        "structure              {} ({} DOFs, Chang explicit at {} Hz)",
        structure.name(),
        structure.dofs(),
        1.0 / DT_S
    );
    crate::outln!("peak ductility         {:.3}", r.peak_ductility());
    let residual = r.residual_drift_mm(DT_S);
    let peaks = r.peak_story_force_kn();
    for (j, uy) in r.yield_drift_mm.iter().enumerate() {
        let peak_drift = r.story_drift_mm[j]
            .iter()
            .fold(0.0_f64, |m, v| m.max(v.abs()));
        crate::outln!(
            "story {}                yield drift {:.3} mm, peak drift {:.3} mm (ductility {:.2}), \
             peak force {:.1} kN, residual drift {:.3} mm",
            j + 1,
            uy,
            peak_drift,
            peak_drift / uy,
            peaks[j],
            residual[j]
        );
    }
    let elastic = crate::machinery::structure::elastic_drifts(&structure, &r, DT_S)?;
    let err = crate::machinery::structure::drift_nrmse_pct(&elastic, &r)?;
    let residual_lin = crate::machinery::structure::NlResponse {
        story_drift_mm: elastic,
        ..Default::default()
    }
    .residual_drift_mm(DT_S);
    for (j, (e, res)) in err.iter().zip(&residual_lin).enumerate() {
        crate::outln!(
            "elastic path, story {}  drift NRMSE {e:.2} % against the nonlinear reference, \
             residual drift {res:.3} mm",
            j + 1
        );
    }
    if let Some(out) = &args.out {
        use std::io::Write;
        let file = std::fs::File::create(out).with_context(|| format!("{}", out.display()))?;
        let mut w = std::io::BufWriter::new(file);
        let n = r.story_drift_mm.len();
        write!(w, "time_s,ground_accel_mm_s2")?;
        for j in 1..=n {
            write!(w, ",drift{j}_mm,force{j}_kn")?;
        }
        writeln!(w)?;
        for (i, (t, a)) in r.time_s.iter().zip(&r.ground_accel_mm_s2).enumerate() {
            write!(w, "{t},{a}")?;
            for (d, f) in r.story_drift_mm.iter().zip(&r.story_force_kn) {
                write!(w, ",{},{}", d[i], f[i])?;
            }
            writeln!(w)?;
        }
        w.flush()?;
        crate::outln!("wrote {} ({} rows)", out.display(), r.time_s.len());
    }
    if let Some(out) = &args.history {
        let h = crate::machinery::train::nonlinear::histories::history_of_response(
            &structure, &r, DT_S, out,
        );
        std::fs::write(out, rths_files::history::to_csv(&h))
            .with_context(|| format!("writing {}", out.display()))?;
        crate::outln!(
            "wrote {} ({} rows, training history)",
            out.display(),
            h.len()
        );
    }
    if let Some(png) = &args.plot {
        let title = format!(
            "{} under {}: peak ductility {:.2}",
            structure.name(),
            motion.name,
            r.peak_ductility()
        );
        crate::machinery::structure::plot::hysteresis(png, &title, &r)?;
        crate::outln!("wrote {}", png.display());
    }
    Ok(())
}
