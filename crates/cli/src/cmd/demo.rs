//! The default demo (`croprow` with no arguments, `cargo run --release`): whole-field coverage of the
//! built-in `full-field` scenario (paper Sec. V-C: 30 m x 12 m, 16 rows, lane switching in a 1.5 m
//! headland) closed loop, written to `./out/demo/`, with the summary and where the plots are.

use std::path::Path;

use anyhow::Result;

use crate::cmd::simulate::{Setup, print_summary, simulate};

/// Where the demo writes.
const OUT: &str = "out/demo";

/// Runs the demo.
pub fn run() -> Result<()> {
    eprintln!(
        "croprow demo: whole-field coverage (scenario `full-field`, 16 rows), closed loop; `croprow --help` lists the commands"
    );
    let setup = Setup::load("full-field", None, &[])?;
    let out = Path::new(OUT);
    // No recording by default: ten minutes of full VLP-16 scans make about 1 GB of MCAP
    // (`croprow simulate --scenario full-field --out DIR --mcap FILE` writes one).
    let record = simulate(&setup, out, None)?;
    print_summary(&record, out, None);
    println!("  plots: {} and {}", out.join("top_view.png").display(), out.join("errors.png").display());
    Ok(())
}
