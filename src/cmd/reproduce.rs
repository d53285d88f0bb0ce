//! `rths reproduce`: the whole study end to end on embedded defaults.

use std::path::PathBuf;

use rths_hal_sim::Preset;

use crate::cmd::analyze::load_motion;
use crate::studies::study::{self, StudyConfig};

/// Arguments of `rths reproduce`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output directory (figures, CSVs, models, report.md, summary.json).
    #[arg(long, default_value = "out/reproduce", value_name = "DIR")]
    pub out: PathBuf,
    /// Print exactly one JSON object on stdout (progress goes nowhere).
    #[arg(long)]
    pub json: bool,
    /// Ground motion (default: the embedded El Centro record).
    #[arg(long, value_name = "PATH|NAME")]
    pub motion: Option<String>,
    /// Seed of the plant noise and of the RNN initialization.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// Run `rths reproduce`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let cfg = StudyConfig {
        motion: load_motion(args.motion.as_deref())?,
        preset: Preset::UnrCompact,
        seed: args.seed,
        rnn_hidden: vec![5, 10, 20],
        out_dir: args.out.clone(),
        quiet: args.json,
    };
    let started = std::time::Instant::now();
    let result = study::run(&cfg)?;
    if args.json {
        crate::outln!("{}", serde_json::to_string(&result.json)?);
        return Ok(());
    }
    crate::out!("{}", study::report_md(&cfg, &result));
    crate::outln!(
        "\n{} files in {} ({:.1} s)",
        result.files.len(),
        args.out.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
