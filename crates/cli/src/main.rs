//! `croprow`: the command line. Parses arguments, reads and writes files, shows progress; every
//! algorithm lives in the library crates (`croprow-core`, `croprow-sim`, `croprow-io`).

mod cmd;
mod plot;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// LiDAR-only crop-row detection, row following and lane switching for field robots.
#[derive(Debug, Parser)]
#[command(name = "croprow", version, about, long_about = None)]
struct Cli {
    #[command(subcommand)]
    command: Option<Command>,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// List the built-in simulation scenarios.
    Scenarios(cmd::scenarios::Args),
    /// Drive a simulated field with a human-like driver and score the detector (Table I detection).
    DetectSim(cmd::detect_sim::Args),
    /// Run the detector over a ROS 2 recording (MCAP) and write one JSON line per scan.
    Detect(cmd::detect::Args),
    /// Run a scenario closed loop (EKF, detector, MPC, lane switching) and write metrics, trajectory, plots.
    Simulate(cmd::simulate::Args),
    /// Table I of the paper in simulation (detection and following, every field) next to its numbers.
    Evaluate(cmd::evaluate::Args),
    /// Extract every crop row of a whole-field point-cloud map (PCD, PLY, LAS, text) as GeoJSON.
    Rows(cmd::rows::Args),
    /// Quick benchmark of the detector, the closed-loop simulation and the MPC (`--json` for one object).
    Bench(cmd::bench::Args),
    /// Run the live ROS 2 node: point cloud + odometry in, /cmd_vel, rows, path and status out.
    #[cfg(feature = "ros2")]
    Node(cmd::node::Args),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        None => cmd::demo::run(),
        Some(Command::Scenarios(a)) => cmd::scenarios::run(a),
        Some(Command::DetectSim(a)) => cmd::detect_sim::run(a),
        Some(Command::Detect(a)) => cmd::detect::run(a),
        Some(Command::Rows(a)) => cmd::rows::run(a),
        Some(Command::Simulate(a)) => cmd::simulate::run(a),
        Some(Command::Evaluate(a)) => cmd::evaluate::run(a),
        Some(Command::Bench(a)) => cmd::bench::run(a),
        #[cfg(feature = "ros2")]
        Some(Command::Node(a)) => cmd::node::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The cause chain, without anyhow's backtrace (printed when RUST_BACKTRACE is set): a bad
            // file or a soak with failures is the user's news, not a bug in croprow.
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
