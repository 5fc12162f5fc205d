//! `croprow rows` (work in progress on its own branch).

/// Arguments of `croprow rows`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`rows` is not built yet")
}
