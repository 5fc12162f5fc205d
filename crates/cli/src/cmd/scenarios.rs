//! `croprow scenarios` (work in progress on its own branch).

/// Arguments of `croprow scenarios`.
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Runs the subcommand.
pub fn run(_args: Args) -> anyhow::Result<()> {
    anyhow::bail!("`scenarios` is not built yet")
}
