//! `croprow detect-sim --scenario NAME|FILE.toml`: the paper's Table I detection experiment in the
//! simulator. A human-like driver wanders along the scenario's lane while the default and the paper
//! detector run side by side on the same scans (see `croprow_sim::experiment::detection`); the errors
//! are printed next to the paper's published numbers for that field, and `--json FILE` writes the whole
//! report.

use std::path::{Path, PathBuf};

use anyhow::Context;
use croprow_core::DetectorConfig;
use croprow_sim::Scenario;
use croprow_sim::experiment::detection::{self, DetectionReport, DetectionStats, Odometry};
use indicatif::{ProgressBar, ProgressStyle};

/// Arguments of `croprow detect-sim`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A built-in scenario name (`croprow scenarios` lists them) or a scenario TOML file.
    #[arg(long)]
    pub scenario: String,
    /// Length of rows to drive, m. Default: the whole row, from the start pose to the end.
    #[arg(long)]
    pub length_m: Option<f64>,
    /// Override the scenario's seed (field, sensor noise, driver).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Write the report as JSON to this file.
    #[arg(long, value_name = "FILE")]
    pub json: Option<PathBuf>,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut scenario = load_scenario(&args.scenario)?;
    if let Some(seed) = args.seed {
        scenario.seed = seed;
    }
    let length_m = args.length_m.unwrap_or(scenario.field.length_m - scenario.start.x_m);
    let modes = [DetectorConfig::default(), DetectorConfig::paper()];

    let bar = ProgressBar::new(1000);
    bar.set_style(
        ProgressStyle::with_template("{msg} [{bar:40}] {percent:>3}% {elapsed_precise} (eta {eta})")
            .context("progress bar template")?
            .progress_chars("=> "),
    );
    bar.set_message(format!("{} {length_m:.0} m", scenario.name));
    let report = detection::run_detection(&scenario, length_m, &modes, &mut |f| {
        bar.set_position((f * 1000.0).round() as u64)
    })
    .with_context(|| format!("detection run on `{}`", scenario.name))?;
    bar.finish_and_clear();

    print!("{}", table(&report));
    if let Some(path) = &args.json {
        let text = serde_json::to_string_pretty(&report).context("serialising the report")?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
        eprintln!("report written to {}", path.display());
    }
    Ok(())
}

/// A built-in scenario by name, else a scenario file.
pub fn load_scenario(name_or_path: &str) -> anyhow::Result<Scenario> {
    if let Some(text) = Scenario::builtin_toml(name_or_path) {
        return Scenario::from_toml_str(text).with_context(|| format!("built-in scenario `{name_or_path}`"));
    }
    let path = Path::new(name_or_path);
    if !path.exists() {
        anyhow::bail!(
            "`{name_or_path}` is neither a built-in scenario ({}) nor a file",
            Scenario::names().join(", ")
        );
    }
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    Scenario::from_toml_str(&text).with_context(|| format!("scenario file {}", path.display()))
}

/// The report as a plain-text table, the paper's published row last.
fn table(r: &DetectionReport) -> String {
    let mut out = format!(
        "{}: {:.1} m of rows, {} scans ({:.0} points each), {:.1} s simulated, seed {}, {} odometry \
         (final position error {:.2} m)\n",
        r.scenario,
        r.length_m,
        r.scans,
        r.points_per_scan,
        r.sim_time_s,
        r.seed,
        match r.odometry {
            Odometry::Ekf => "EKF",
            Odometry::Perfect => "perfect",
        },
        r.odometry_error_m
    );
    out += &format!(
        "{:<18} {:>16} {:>16} {:>10} {:>11} {:>12}\n",
        "detector", "distance (cm)", "angle (deg)", "both rows", "wrong rows", "end of row"
    );
    for m in &r.modes {
        out += &mode_line(m);
    }
    match detection::published(&r.scenario) {
        Some(p) => {
            out += &format!(
                "{:<18} {:>16} {:>16}\n",
                "paper, published",
                format!("{:.2} ± {:.2}", p.dist_cm_mean, p.dist_cm_std),
                format!("{:.2} ± {:.2}", p.ang_deg_mean, p.ang_deg_std)
            );
        }
        None => out += "(the paper publishes no detection numbers for this scenario)\n",
    }
    out += "errors: mean ± std of the absolute error of each reported first left / right row at the robot;\n\
            end of row: distance along the rows to the true row end when EndOfRow was first raised.\n";
    out
}

fn mode_line(m: &DetectionStats) -> String {
    let end = match m.end_of_row_m {
        Some(d) if d >= 0.0 => format!("{d:.2} m before"),
        Some(d) => format!("{:.2} m after", -d),
        None => "not raised".into(),
    };
    format!(
        "{:<18} {:>16} {:>16} {:>9.1}% {:>11} {:>12}\n",
        m.mode.as_str(),
        format!("{:.2} ± {:.2}", m.distance_cm.mean, m.distance_cm.std),
        format!("{:.2} ± {:.2}", m.angle_deg.mean, m.angle_deg.std),
        100.0 * m.both_rows_share(),
        m.wrong_row_picks,
        end
    )
}
