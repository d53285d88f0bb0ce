//! `rths robustness`: the robustness study (Monte-Carlo over the benchmark's uncertainty).

use std::path::PathBuf;

use rths_hal_sim::Preset;

use crate::cmd::plant::PresetArg;
use crate::studies::robustness::{self, report, RobustnessConfig, QUICK_DRAWS};

/// Arguments of `rths robustness`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Draws of the uncertainty per preset (seeds --seed .. --seed + draws − 1).
    #[arg(long, default_value_t = 50)]
    pub draws: usize,
    /// Plant presets, comma-separated.
    #[arg(
        long,
        value_enum,
        value_delimiter = ',',
        default_value = "unr-compact,benchmark"
    )]
    pub presets: Vec<PresetArg>,
    /// The first draw's seed.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Output directory (report.md, robustness.json, runs.csv, robustness.png).
    #[arg(long, default_value = "out/robustness", value_name = "DIR")]
    pub out: PathBuf,
    /// Print exactly one JSON object on stdout (the files are written too).
    #[arg(long)]
    pub json: bool,
    /// A smoke run: 2 draws (overrides --draws).
    #[arg(long)]
    pub quick: bool,
}

/// Run `rths robustness`.
pub fn run(args: Args) -> anyhow::Result<()> {
    crate::machinery::output::writable_dir(&args.out)?;
    let cfg = RobustnessConfig {
        draws: if args.quick { QUICK_DRAWS } else { args.draws },
        presets: args
            .presets
            .iter()
            .map(|p| match p {
                PresetArg::Benchmark => Preset::Benchmark,
                PresetArg::UnrCompact => Preset::UnrCompact,
            })
            .collect(),
        first_seed: args.seed,
        out_dir: args.out.clone(),
        quiet: args.json,
    };
    let started = std::time::Instant::now();
    let result = robustness::run(&cfg)?;
    let wall_time_s = started.elapsed().as_secs_f64();
    let json = report::json(&result, rayon::current_num_threads(), wall_time_s);
    let files = report::write(&result, &json, &cfg.out_dir)?;
    if args.json {
        crate::outln!("{}", serde_json::to_string(&json)?);
        return Ok(());
    }
    crate::out!("{}", report::markdown(&result, &json));
    crate::outln!(
        "\nwrote {} files in {}:",
        files.len(),
        cfg.out_dir.display()
    );
    for f in files {
        crate::outln!("  {}", f.display());
    }
    Ok(())
}
