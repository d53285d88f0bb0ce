//! The subcommands of the `rths` binary, one module each, and their printing to standard output.

pub mod analyze;
pub mod benchmark;
pub mod check_model;
pub mod cli;
pub mod faults;
pub mod identify;
pub mod import;
pub mod link;
pub mod nonlinear_study;
pub mod plant;
pub mod report;
pub mod reproduce;
pub mod robustness;
pub mod simulate;
pub mod simulate_args;
pub mod simulate_imported;
pub mod simulate_imported_online;
pub mod simulate_nl_floors;
pub mod site;
pub mod train;

// Standard output (what `outln!` and `out!` write through) is the machinery's, shared with the
// site's messages: re-exported for the commands and `main`.
pub use crate::machinery::output::{write_stdout, EXIT_STDOUT_CLOSED, EXIT_STDOUT_FAILED};

/// Exit status of a command that ran one test and reported it, when the supervisor stopped that
/// run (safely: the figures up to the stop are printed and written): 3, told apart from a run to
/// its end (0), an error (1) and a usage error (2, the argument parser's). Studies of many runs
/// (`reproduce`, `robustness`, `nonlinear-study`, `faults`, the benchmark grid) count their stopped
/// runs in their tables and exit 0.
pub const EXIT_RUN_STOPPED: u8 = 3;

/// What a command returns, once it has reported its run, when the supervisor stopped it: `main`
/// prints it and exits with [`EXIT_RUN_STOPPED`].
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct RunStopped(pub String);

impl RunStopped {
    /// `Err(RunStopped)` when `report` says the supervisor stopped its run, else `Ok`.
    pub fn check(report: &crate::studies::scenario::ScenarioReport) -> anyhow::Result<()> {
        match (&report.stop_reason, report.stop_time_s) {
            (Some(why), Some(t)) => {
                Err(RunStopped(format!("the supervisor stopped the run: {why} at {t:.3} s")).into())
            }
            (Some(why), None) => {
                Err(RunStopped(format!("the supervisor stopped the run: {why}")).into())
            }
            _ => Ok(()),
        }
    }
}

/// An error as one line, `error: ` excluded: each context and cause once. A cause whose text its
/// context already quotes (`cannot read x: Is a directory (os error 21)` over the io error itself)
/// is left out, so no cause is printed twice.
pub fn error_text(e: &anyhow::Error) -> String {
    let mut text = String::new();
    for cause in e.chain() {
        let s = cause.to_string();
        if s.is_empty() || text.contains(&s) {
            continue;
        }
        if !text.is_empty() {
            text.push_str(": ");
        }
        text.push_str(&s);
    }
    text
}
