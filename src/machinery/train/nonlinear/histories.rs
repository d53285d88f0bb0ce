//! Training runs from the time histories a lab's FE program wrote (`rths train nonlinear
//! --histories`, [`rths_files::history`]) instead of rths's own FE runs of the structure file.
//!
//! A story structure's history carries every floor (`out_<FLOOR>_1_mm`) and the stand-in
//! specimen's force. Stage 1 needs each story's force against its drift, which no FE program
//! writes as such: it is recovered from the floors by equilibrium with the structure file's
//! *elastic* mass and damping (what the lab's numerical model has), `R = −M·(ẍ + ι·ü_g) − C·ẋ −
//! e·F_E`, the floors' restoring forces `R_j = f_j − f_{j+1}` summed from the roof down. The
//! accelerations and velocities are central differences of the recorded floors (second-order in
//! the step; at 2048 Hz the error is far below the laws' own).

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use rths_files::history::{OutputDof, RecorderUnits, TimeHistory};
use rths_files::structure_file::{Structure, Units};

use super::runs::FeRun;
use crate::machinery::structure::{NlResponse, RESIDUAL_WINDOW_S};
use crate::machinery::train::TrainError;

/// The floor outputs a story structure's history must carry, `out_<FLOOR>_1_mm`, floor 1 first.
pub fn floor_outputs(floors: usize) -> Vec<OutputDof> {
    (1..=floors)
        .map(|f| OutputDof {
            node: f as u32,
            dof: 1,
        })
        .collect()
}

fn source(h: &TimeHistory) -> String {
    h.source.display().to_string()
}

/// The interface is the specimen's floor: `h`'s interface column must be that floor's
/// (`floor_mm`, its column `column`), or a mislabelled output would train the model on the wrong
/// DOF. The refusal names the first row that differs.
pub fn interface_is_floor(
    h: &TimeHistory,
    floor_mm: &[f64],
    column: &str,
) -> Result<(), TrainError> {
    let peak = floor_mm.iter().fold(0.0_f64, |m, v| m.max(v.abs()));
    match floor_mm
        .iter()
        .zip(&h.interface_mm)
        .position(|(a, b)| (*a - *b).abs() > 1e-6 * peak.max(1e-9))
    {
        Some(k) => Err(TrainError::Setting(format!(
            "{}: interface_mm is not {column} (the specimen's floor)",
            h.row_at(k)
        ))),
        None => Ok(()),
    }
}

/// A training run from the history `h` of the story structure `s`.
pub fn run_from_history(s: &Structure, h: &TimeHistory) -> Result<FeRun, TrainError> {
    let n = s.dofs();
    let steps = h.len();
    if steps < 3 {
        return Err(TrainError::Setting(format!(
            "{}: {steps} rows; training needs at least 3",
            source(h)
        )));
    }
    let mut floors = Vec::with_capacity(n);
    for d in floor_outputs(n) {
        let v = h.output(d).ok_or_else(|| {
            TrainError::Setting(format!(
                "{}: no column {} (a history of the {n}-floor structure {} carries every floor, \
                 out_1_1_mm to out_{n}_1_mm)",
                source(h),
                d.column(),
                s.name()
            ))
        })?;
        floors.push(v.to_vec());
    }
    let sd = s.specimen_dof();
    interface_is_floor(h, &floors[sd], &floor_outputs(n)[sd].column())?;
    let dt = h.dt_s;
    let m = s.mass();
    let c = s.damping();
    let mi = s.ground_mass();
    let at = |f: &[f64], k: usize| {
        let k = k.clamp(1, steps - 2);
        (
            (f[k + 1] - f[k - 1]) / (2.0 * dt),
            (f[k + 1] - 2.0 * f[k] + f[k - 1]) / (dt * dt),
        )
    };
    let mut story_force_kn = vec![Vec::with_capacity(steps); n];
    let mut story_drift_mm = vec![Vec::with_capacity(steps); n];
    let mut vel = vec![0.0; n];
    let mut acc = vec![0.0; n];
    let mut r = vec![0.0; n];
    for k in 0..steps {
        for j in 0..n {
            (vel[j], acc[j]) = at(&floors[j], k);
        }
        for j in 0..n {
            let mut v = -mi[j] * h.ground_accel_mm_s2[k];
            for i in 0..n {
                v -= m[(j, i)] * acc[i] + c[(j, i)] * vel[i];
            }
            if j == sd {
                v -= h.specimen_force_kn[k];
            }
            r[j] = v;
        }
        let mut above = 0.0;
        for j in (0..n).rev() {
            above += r[j];
            story_force_kn[j].push(above);
        }
        for j in 0..n {
            let below = if j == 0 { 0.0 } else { floors[j - 1][k] };
            story_drift_mm[j].push(floors[j][k] - below);
        }
    }
    let w = ((RESIDUAL_WINDOW_S / dt) as usize).clamp(1, steps);
    let residual_drift_mm = story_drift_mm
        .iter()
        .map(|d| d[steps - w..].iter().sum::<f64>() / w as f64)
        .collect();
    let label = h
        .source
        .file_name()
        .map_or_else(|| source(h), |f| f.to_string_lossy().into_owned());
    Ok(FeRun {
        label,
        record: source(h),
        scale: f64::NAN,
        // No law is known for a lab's run: the ductility is not defined here.
        ductility: f64::NAN,
        ground_accel_mm_s2: h.ground_accel_mm_s2.clone(),
        floor_disp_mm: floors,
        record_steps: steps,
        residual_drift_mm,
        story_drift_mm,
        story_force_kn,
    })
}

/// The recorder files' units of a structure file of `units` (the lab's model is in the same).
pub fn recorder_units(units: Units) -> RecorderUnits {
    match units {
        Units::Si => RecorderUnits::SI,
        Units::MmKn => RecorderUnits::MM_KN,
    }
}

/// The histories `paths` in the order of their file names (byte order; the whole path breaks a
/// tie), refusing a history given twice and one that is not there.
///
/// Every third history is held out of the fit, so the order decides the model: taken by name, the
/// same files give the same model however a shell lists `*.csv` (its order follows the locale),
/// and a run given twice cannot be both fitted and held out.
pub fn in_name_order(paths: &[PathBuf]) -> Result<Vec<PathBuf>, TrainError> {
    let mut seen = BTreeSet::new();
    for p in paths {
        // The same file by two spellings (a name, and the same name by way of a parent folder) is
        // one history.
        let key = std::fs::canonicalize(p)
            .map_err(|e| TrainError::Setting(format!("{}: cannot read: {e}", p.display())))?;
        if !seen.insert(key) {
            return Err(TrainError::Setting(format!(
                "{}: history given twice (each run counts once: fitted, held out or scored)",
                p.display()
            )));
        }
    }
    let mut ordered = paths.to_vec();
    ordered.sort_by(|a, b| {
        let name = |p: &Path| p.file_name().map(|n| n.as_encoded_bytes().to_vec());
        name(a).cmp(&name(b)).then_with(|| a.cmp(b))
    });
    Ok(ordered)
}

/// Read every history (a CSV file, or a recorder directory in `units`) of the story structure `s`.
pub fn read_runs(
    s: &Structure,
    paths: &[&Path],
    units: RecorderUnits,
    dt_s: f64,
) -> Result<Vec<FeRun>, TrainError> {
    paths
        .iter()
        .map(|p| {
            let h = rths_files::history::read(p, units, dt_s)
                .map_err(|e| TrainError::Setting(e.to_string()))?;
            run_from_history(s, &h)
        })
        .collect()
}

/// The history of the FE run `run` of `s` (its linear specimen as the stand-in), every floor an
/// output.
pub fn history_of_run(s: &Structure, run: &FeRun, dt_s: f64, source: &Path) -> TimeHistory {
    history_of_floors(s, &run.ground_accel_mm_s2, &run.floor_disp_mm, dt_s, source)
}

/// The history of rths's FE response `r` of `s`: what `rths analyze --structure --history` writes.
pub fn history_of_response(s: &Structure, r: &NlResponse, dt_s: f64, source: &Path) -> TimeHistory {
    let floors: Vec<Vec<f64>> = (0..r.story_drift_mm.len())
        .map(|j| {
            (0..r.time_s.len())
                .map(|k| r.story_drift_mm[..=j].iter().map(|d| d[k]).sum())
                .collect()
        })
        .collect();
    history_of_floors(s, &r.ground_accel_mm_s2, &floors, dt_s, source)
}

fn history_of_floors(
    s: &Structure,
    ground_accel_mm_s2: &[f64],
    floor_disp_mm: &[Vec<f64>],
    dt_s: f64,
    source: &Path,
) -> TimeHistory {
    let sd = s.specimen_dof();
    let k_e = s.specimen().1;
    let interface_mm = floor_disp_mm[sd].clone();
    TimeHistory {
        source: source.to_path_buf(),
        dt_s,
        ground_accel_mm_s2: ground_accel_mm_s2.to_vec(),
        specimen_force_kn: interface_mm.iter().map(|x| k_e * x).collect(),
        interface_mm,
        outputs: floor_outputs(s.dofs())
            .into_iter()
            .zip(floor_disp_mm)
            .map(|(d, v)| (d, v.clone()))
            .collect(),
        row_line: Vec::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machinery::motion::GroundMotion;

    /// The story forces recovered from the floors by equilibrium are the FE's own to a small
    /// fraction of their peak.
    #[test]
    fn story_forces_from_the_floors_are_the_fe_forces() {
        let s = Structure::load(Path::new("data/structures/shear3-yielding.json")).unwrap();
        let dt = rths_core::params::DT_S;
        let mut m = GroundMotion::try_embedded("northridge").unwrap();
        m.accel_g.truncate(600);
        let run = super::super::runs::fe_run(&s, &m, 1.0, dt).unwrap();
        let h = history_of_run(&s, &run, dt, Path::new("h.csv"));
        let back = run_from_history(&s, &h).unwrap();
        for j in 0..3 {
            let peak = run.story_force_kn[j]
                .iter()
                .fold(0.0_f64, |a, v| a.max(v.abs()));
            let worst = run.story_force_kn[j]
                .iter()
                .zip(&back.story_force_kn[j])
                .skip(1)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(worst < 0.02 * peak, "story {}: {worst} of {peak}", j + 1);
            assert_eq!(back.story_drift_mm[j].len(), run.story_drift_mm[j].len());
        }
        // A history without a floor, or whose interface is not the specimen's floor, is refused.
        let mut no_floor = h.clone();
        no_floor.outputs.pop();
        let e = run_from_history(&s, &no_floor).unwrap_err().to_string();
        assert!(e.contains("h.csv: no column out_3_1_mm"), "{e}");
        let mut wrong = h.clone();
        wrong.interface_mm[10] += 1.0;
        let e = run_from_history(&s, &wrong).unwrap_err().to_string();
        assert!(e.contains("h.csv: data row 11: interface_mm"), "{e}");
    }
}
