//! `croprow detect_sim` (work in progress on its own branch).

/// Arguments of `croprow detect_sim`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`detect_sim` is not built yet")
}
