//! Whole-process cost of the everyday commands, as a user runs them (the release binary, process
//! start-up and all): `rths simulate --scenario lr-online --json` against `rths analyze` on the
//! same record (El Centro), as the ratio of their medians, then one `rths reproduce` in seconds.
//!
//! `cargo bench --bench commands` (add `-- --no-reproduce` to skip the study, `-- --runs N` for
//! another number of runs per command). The figures depend on the machine and on its load: compare
//! the ratio, and run `reproduce` on otherwise idle cores.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

/// The release binary cargo built for this bench.
const RTHS: &str = env!("CARGO_BIN_EXE_rths");

fn run(args: &[&str]) -> Duration {
    let start = Instant::now();
    let status = Command::new(RTHS)
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status();
    let elapsed = start.elapsed();
    match status {
        Ok(s) if s.success() => elapsed,
        other => panic!("rths {args:?} failed: {other:?}"),
    }
}

fn median_ms(mut xs: Vec<Duration>) -> f64 {
    xs.sort();
    xs[xs.len() / 2].as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let runs = args
        .iter()
        .position(|a| a == "--runs")
        .and_then(|i| args.get(i + 1))
        .and_then(|n| n.parse().ok())
        .unwrap_or(21usize);
    let simulate = ["simulate", "--scenario", "lr-online", "--json"];
    let analyze = ["analyze"];
    // Warm the page cache, then alternate so both commands see the same machine load.
    run(&simulate);
    run(&analyze);
    let (mut sim, mut ana) = (Vec::new(), Vec::new());
    for _ in 0..runs {
        sim.push(run(&simulate));
        ana.push(run(&analyze));
    }
    let (sim_ms, ana_ms) = (median_ms(sim), median_ms(ana));
    println!(
        "simulate --scenario lr-online --json: {sim_ms:.1} ms, analyze: {ana_ms:.1} ms \
         (medians of {runs}); ratio {:.2}",
        sim_ms / ana_ms
    );
    if args.iter().any(|a| a == "--no-reproduce") {
        return;
    }
    let out = std::env::temp_dir().join(format!("rths-bench-reproduce-{}", std::process::id()));
    let out_s = out.display().to_string();
    let t = run(&["reproduce", "--json", "--out", &out_s]);
    println!(
        "reproduce: {:.1} s on {} threads",
        t.as_secs_f64(),
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    if Path::new(&out).exists() {
        let _ = std::fs::remove_dir_all(&out);
    }
}
