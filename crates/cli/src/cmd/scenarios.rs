//! `croprow scenarios`: lists the built-in simulation scenarios, or prints one as TOML to copy and edit.

use anyhow::Context;
use croprow_sim::Scenario;

/// Arguments of `croprow scenarios`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print the TOML file of this scenario (copy it, edit it, pass it back as a scenario file).
    #[arg(long, value_name = "NAME")]
    pub show: Option<String>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    if let Some(name) = args.show {
        let text = Scenario::builtin_toml(&name).with_context(|| {
            format!("unknown scenario `{name}`; built in: {}", Scenario::names().join(", "))
        })?;
        print!("{text}");
        return Ok(());
    }
    let names = Scenario::names();
    let width = names.iter().map(|n| n.len()).max().unwrap_or(0);
    for name in names {
        let s = Scenario::builtin(name).with_context(|| format!("built-in scenario `{name}`"))?;
        println!("{name:width$}  {}", s.summary);
    }
    Ok(())
}
