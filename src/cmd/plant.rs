//! `rths plant`.

/// Arguments of `rths plant`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `rths plant`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`rths plant` is not built yet")
}
