//! One rule for every file made at a controller rate (model files of every kind, rig files): the
//! file's `dt_s` must be the running controller's, else it is refused with the command that makes
//! one at the right rate. A model or a lead filter fitted at another step predicts the wrong thing
//! at every tick (its coefficients are per step), so running it would be silently wrong.

/// Relative tolerance on a file's `dt_s` against the controller's (a hand-edited `0.000488281`
/// for 1/2048 s passes; another rate never does: the rates differ by 2×).
pub const DT_TOLERANCE: f64 = 1e-6;

/// A file made at another controller rate than the run's.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error(
    "{what} was made at {} Hz (dt_s = {file_dt_s:e} s), this controller runs at \
     {run_hz:.0} Hz (dt_s = {run_dt_s:e} s): make one at {run_hz:.0} Hz with `{remedy}`",
    crate::readable(*file_hz)
)]
pub struct OtherRate {
    /// What the file is (`LR model`, `rig file`, ...).
    pub what: String,
    /// The file's step, s.
    pub file_dt_s: f64,
    /// Its rate, Hz.
    pub file_hz: f64,
    /// The controller's step, s.
    pub run_dt_s: f64,
    /// The controller's rate, Hz.
    pub run_hz: f64,
    /// The command that makes one at the controller's rate.
    pub remedy: String,
}

/// Refuse `file_dt_s` unless it is `run_dt_s` within [`DT_TOLERANCE`]; `what` names the file,
/// `remedy` is the command that makes one at the run's rate.
pub fn check_dt(what: &str, file_dt_s: f64, run_dt_s: f64, remedy: &str) -> Result<(), OtherRate> {
    if (file_dt_s - run_dt_s).abs() <= DT_TOLERANCE * run_dt_s {
        return Ok(());
    }
    Err(OtherRate {
        what: what.to_string(),
        file_dt_s,
        file_hz: 1.0 / file_dt_s,
        run_dt_s,
        run_hz: 1.0 / run_dt_s,
        remedy: remedy.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn same_rate_passes_other_refused_with_the_command() {
        let dt = 1.0 / 2048.0;
        check_dt("LR model", dt, dt, "x").unwrap();
        check_dt("LR model", 0.000488281, dt, "x").unwrap();
        let e = check_dt("LR model", 1.0 / 4096.0, dt, "rths train lr --out lr.json").unwrap_err();
        let s = e.to_string();
        assert!(
            s.contains("made at 4096 Hz") && s.contains("runs at 2048 Hz"),
            "{s}"
        );
        assert!(s.contains("`rths train lr --out lr.json`"), "{s}");
        assert!(check_dt("x", f64::NAN, dt, "x").is_err());
        assert!(check_dt("x", 0.0, dt, "x").is_err());
    }
}
