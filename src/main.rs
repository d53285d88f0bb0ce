//! `rths`: the host command-line tool of the RTHS controller (analysis, plant, training, scenarios).
#![forbid(unsafe_code)]

use clap::Parser;

use rths::cmd;
use rths::cmd::cli::Cli;

fn main() -> std::process::ExitCode {
    let result = cmd::cli::run(Cli::parse());
    match result {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) if e.downcast_ref::<cmd::RunStopped>().is_some() => {
            eprintln!("stopped: {}", cmd::error_text(&e));
            std::process::ExitCode::from(cmd::EXIT_RUN_STOPPED)
        }
        Err(e) => {
            eprintln!("error: {}", cmd::error_text(&e));
            std::process::ExitCode::FAILURE
        }
    }
}
