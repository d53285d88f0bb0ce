//! The `rths` command line: its arguments (one [`Command`] per subcommand) and the dispatch to the
//! subcommands' modules. In the library so the tests can read every `--help` (tests/help.rs).

use clap::{Parser, Subcommand};

use crate::cmd;

/// Real-time hybrid simulation with a machine-learning metamodel.
#[derive(Debug, Parser)]
#[command(name = "rths", version, about)]
pub struct Cli {
    /// The subcommand.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
pub enum Command {
    /// Pure finite-element analysis of the prototype frame under a ground motion.
    Analyze(cmd::analyze::Args),
    /// Properties of the virtual servo-hydraulic plant: delay, gain and phase, Bode plot.
    Plant(cmd::plant::Args),
    /// Run one hybrid-simulation scenario in closed loop against the virtual plant.
    Simulate(cmd::simulate_args::Args),
    /// The whole study end to end: train, run every scenario, write figures and report.md.
    Reproduce(cmd::reproduce::Args),
    /// Train a metamodel (LR, RNN, LRX, the structure meta or the nonlinear one) and write its model file.
    Train(cmd::train::Args),
    /// Run the fault-injection matrix against the closed loop and print its table.
    Faults(cmd::faults::Args),
    /// Validate a model file: exit 0 with a summary, or 1 with the reason it is rejected.
    CheckModel(cmd::check_model::Args),
    /// Characterize a rig from its measured signals: delay, gain/phase, lead filter, stiffness.
    Identify(cmd::identify::Args),
    /// Robustness study: Monte-Carlo over the plant's uncertainty, identified rig per draw.
    Robustness(cmd::robustness::Args),
    /// Drive and record a test on a board over the command link (serial port, QEMU socket).
    Link(cmd::link::Args),
    /// The figures, metrics and plots of `rths simulate` for a recording of a board's test.
    Report(cmd::report::Args),
    /// The vRTHS benchmark problem: one case × record with J1-J9, or the whole grid's table.
    Benchmark(cmd::benchmark::Args),
    /// Be the experimental site of an OpenSees analysis (its genericClient elements).
    Site(cmd::site::Args),
    /// Score the nonlinear scenarios on held-out records from elastic to past ductility 4.
    NonlinearStudy(cmd::nonlinear_study::Args),
    /// Import a lab's finite-element model (OpenSees) as a structure file.
    Import(cmd::import::Args),
}

/// Run the parsed command line.
pub fn run(cli: Cli) -> anyhow::Result<()> {
    match cli.command {
        Command::Analyze(a) => cmd::analyze::run(a),
        Command::Plant(a) => cmd::plant::run(a),
        Command::Simulate(a) => cmd::simulate::run(a),
        Command::Reproduce(a) => cmd::reproduce::run(a),
        Command::Train(a) => cmd::train::run(a),
        Command::Faults(a) => cmd::faults::run(a),
        Command::CheckModel(a) => cmd::check_model::run(a),
        Command::Link(a) => cmd::link::run(a),
        Command::Report(a) => cmd::report::run(a),
        Command::Identify(a) => cmd::identify::run(a),
        Command::Robustness(a) => cmd::robustness::run(a),
        Command::Benchmark(a) => cmd::benchmark::run(a),
        Command::Site(a) => cmd::site::run(a),
        Command::NonlinearStudy(a) => cmd::nonlinear_study::run(a),
        Command::Import(a) => cmd::import::run(a),
    }
}
