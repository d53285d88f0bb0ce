//! `rths analyze`.

/// Arguments of `rths analyze`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Run `rths analyze`.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`rths analyze` is not built yet")
}
