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
pub mod simulate_imported;
pub mod simulate_imported_nl;
pub mod simulate_imported_online;
pub mod site;
pub mod train;

/// Exit status of a command whose standard output was closed by its reader (`rths … | head -1`):
/// 0, the reader took what it wanted; the command ends quietly at its next line of output.
pub const EXIT_STDOUT_CLOSED: i32 = 0;

/// Exit status when standard output cannot be written for another reason (a full disk): 1, as any
/// error.
pub const EXIT_STDOUT_FAILED: i32 = 1;

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
    pub fn check(report: &crate::scenario::ScenarioReport) -> anyhow::Result<()> {
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

/// Write `args` to standard output (what [`crate::outln!`] and [`crate::out!`] call). A closed
/// pipe ends the process quietly with [`EXIT_STDOUT_CLOSED`]; any other write error is printed to
/// standard error and ends it with [`EXIT_STDOUT_FAILED`]. Never a panic (`println!` panics).
pub fn write_stdout(args: std::fmt::Arguments<'_>) {
    use std::io::Write as _;
    let mut out = std::io::stdout().lock();
    if let Err(e) = out.write_fmt(args).and_then(|()| out.flush()) {
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::process::exit(EXIT_STDOUT_CLOSED);
        }
        eprintln!("error: writing to standard output: {e}");
        std::process::exit(EXIT_STDOUT_FAILED);
    }
}

/// `println!` for the commands' output: a closed standard output ends the command quietly
/// ([`cmd::write_stdout`](crate::cmd::write_stdout)).
#[macro_export]
macro_rules! outln {
    () => {
        $crate::cmd::write_stdout(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::cmd::write_stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` for the commands' output (see [`outln!`](crate::outln)).
#[macro_export]
macro_rules! out {
    ($($arg:tt)*) => {
        $crate::cmd::write_stdout(format_args!($($arg)*))
    };
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
