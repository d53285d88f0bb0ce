//! `rths faults`: the fault-injection matrix (see [`crate::studies::faults`]).

use std::path::PathBuf;

use anyhow::Context;

use crate::studies::faults;

/// Arguments of `rths faults`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print the matrix as one JSON object instead of the Markdown table.
    #[arg(long)]
    pub json: bool,
    /// Also write the Markdown table to this file.
    #[arg(long, value_name = "FILE.md")]
    pub out: Option<PathBuf>,
}

/// Run the matrix, print it; an error if any row fails.
pub fn run(args: Args) -> anyhow::Result<()> {
    let m = faults::run_matrix()?;
    let md = m.to_markdown();
    if args.json {
        crate::outln!("{}", serde_json::to_string(&m)?);
    } else {
        crate::out!("{md}");
    }
    if let Some(path) = &args.out {
        std::fs::write(path, &md).with_context(|| format!("writing {}", path.display()))?;
    }
    let failed = m.cases.iter().filter(|c| !c.pass).count();
    anyhow::ensure!(
        failed == 0,
        "{failed} of {} fault cases failed",
        m.cases.len()
    );
    Ok(())
}
