//! `croprow detect` (work in progress on its own branch).

/// Arguments of `croprow detect`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`detect` is not built yet")
}
