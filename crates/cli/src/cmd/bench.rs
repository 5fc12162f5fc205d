//! `croprow bench [--json]`: the command line's own quick benchmark (a few seconds, one thread, no
//! criterion). Every figure says what it measured, on what, and over how many runs:
//!
//! - `detect_us_median` / `detect_paper_us_median` (and `_mean`: registration's keyframes, every 0.15 m
//!   driven, make the times two-humped): one `RowDetector::detect` call, default / paper mode,
//!   on full-resolution simulated VLP-16 scans (16 beams × 1800 azimuths, motion skew) over the grown-corn
//!   scenario, driven by the human-like driver from rest with EKF odometry, each scan with its odometry
//!   twist (so the slide watch and the registration's skew are timed too); each mode runs over the whole
//!   sequence of scans in order (a warm map, as on the robot) and the first scans (at rest, start-up
//!   search) are not timed;
//! - `sim_realtime_factor`: simulated seconds per wall second of the full closed loop on one thread, the
//!   median of `runs.sim_loops` loops of 8 s simulated each (min and max beside it): field
//!   ray casting of every LiDAR revolution, robot dynamics, wheel odometry and IMU at their rates, crop
//!   contacts, the EKF at every sensor sample, and the `Navigator` (detector, lane switching, MPC) at every
//!   scan (10 Hz), its command held in between;
//! - `mpc_solve_us_median`: one warm-started MPC solve at the default horizon, following a straight row
//!   from a state perturbed as a detector would (±1 cm, ±0.5°), as in the criterion bench `mpc`.
//!
//! For the criterion benchmarks (statistics, per-stage breakdowns) see `cargo bench`.

use std::time::Instant;

use anyhow::Context;
use croprow_core::control::mpc::{Mpc, MpcConfig};
use croprow_core::control::path::Path;
use croprow_core::navigator::{NavInput, Navigator, NavigatorConfig};
use croprow_core::odometry::Ekf;
use croprow_core::{DetectorConfig, Point3, Pose2, RowDetector, Scan, Twist2};
use croprow_sim::experiment::detection::{self, fuse_odometry};
use croprow_sim::{Scenario, World};
use serde::Serialize;

/// Scenario of every figure: the hardest canopy for the detector and the ray caster.
const SCENARIO: &str = "grown-corn";
/// Rows of the benchmark field, m: long enough for every run, short to build.
const FIELD_LENGTH_M: f64 = 25.0;
/// Scans recorded for the detector timings, and the first ones of each sequence left untimed.
const DETECT_SCANS: usize = 80;
const DETECT_WARMUP_SCANS: usize = 10;
/// Scans recorded at rest before the driver sets off (inside the warm-up): the lane is found at rest,
/// as at the start of a run, so the slide watch registers it and is timed.
const DETECT_REST_SCANS: usize = 3;
/// Simulated time of one closed loop, s.
const LOOP_SIM_S: f64 = 8.0;
/// Closed loops timed: one loop is ~0.2 s of wall time, so a single one swings ±15 % with the load.
const LOOP_RUNS: usize = 5;
/// MPC solves timed, after untimed warm-up solves.
const MPC_SOLVES: usize = 400;
const MPC_WARMUP: usize = 20;

/// Arguments of `croprow bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Print one JSON object instead of a table.
    #[arg(long)]
    pub json: bool,
}

/// How many timed runs each figure is the median of.
#[derive(Debug, Serialize)]
struct Runs {
    detect: usize,
    detect_paper: usize,
    sim_scans: usize,
    sim_loops: usize,
    mpc: usize,
}

/// The machine the figures were taken on.
#[derive(Debug, Serialize)]
struct Machine {
    cpu: String,
    cores: usize,
    load_average_1m: Option<f64>,
    build: &'static str,
}

/// The benchmark's output.
#[derive(Debug, Serialize)]
struct Report {
    detect_us_median: f64,
    detect_us_mean: f64,
    detect_paper_us_median: f64,
    detect_paper_us_mean: f64,
    detect_points_per_scan: f64,
    sim_realtime_factor: f64,
    sim_realtime_factor_min: f64,
    sim_realtime_factor_max: f64,
    sim_time_s: f64,
    sim_wall_s: f64,
    sim_distance_m: f64,
    sim_includes: &'static str,
    mpc_solve_us_median: f64,
    mpc_horizon_steps: usize,
    scenario: &'static str,
    runs: Runs,
    machine: Machine,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut scenario = Scenario::builtin(SCENARIO).context("built-in scenario")?;
    scenario.field.length_m = FIELD_LENGTH_M;

    let (scans, points_per_scan) = record_scans(&scenario)?;
    let default = time_detector(DetectorConfig::default(), &scans, &scenario)?;
    let paper = time_detector(DetectorConfig::paper(), &scans, &scenario)?;
    let loops = (0..LOOP_RUNS).map(|_| closed_loop(&scenario)).collect::<anyhow::Result<Vec<_>>>()?;
    let factors: Vec<f64> = loops.iter().map(|l| l.sim_time_s / l.wall_s.max(1e-9)).collect();
    let mpc = time_mpc()?;

    let report = Report {
        detect_us_median: median(&default),
        detect_us_mean: mean(&default),
        detect_paper_us_median: median(&paper),
        detect_paper_us_mean: mean(&paper),
        detect_points_per_scan: points_per_scan,
        sim_realtime_factor: median(&factors),
        sim_realtime_factor_min: factors.iter().copied().fold(f64::INFINITY, f64::min),
        sim_realtime_factor_max: factors.iter().copied().fold(0.0, f64::max),
        sim_time_s: loops.iter().map(|l| l.sim_time_s).sum(),
        sim_wall_s: loops.iter().map(|l| l.wall_s).sum(),
        sim_distance_m: loops.iter().map(|l| l.distance_m).sum(),
        sim_includes: "ray-cast VLP-16 with motion skew, robot dynamics, wheel odometry 50 Hz, IMU 100 Hz, \
                       crop contacts, EKF, Navigator (detector + lane switching + MPC) at 10 Hz; one thread",
        mpc_solve_us_median: median(&mpc),
        mpc_horizon_steps: MpcConfig::default().horizon_steps,
        scenario: SCENARIO,
        runs: Runs {
            detect: default.len(),
            detect_paper: paper.len(),
            sim_scans: loops.iter().map(|l| l.scans).sum(),
            sim_loops: loops.len(),
            mpc: mpc.len(),
        },
        machine: machine(),
    };
    if args.json {
        println!("{}", serde_json::to_string(&report).context("serialising the report")?);
    } else {
        print_table(&report);
    }
    Ok(())
}

/// A scan with the odometry pose and twist at its stamp.
struct Recorded {
    stamp_s: f64,
    odom: Pose2,
    odom_twist: Twist2,
    points: Vec<Point3>,
}

/// Drives the human-like driver over the field, from rest, and keeps every scan with its EKF pose and
/// twist.
fn record_scans(scenario: &Scenario) -> anyhow::Result<(Vec<Recorded>, f64)> {
    let mut world = World::new(scenario).context("building the world")?;
    let mut driver = world.driver().context("driver")?;
    let mut ekf = Ekf::new(detection::ekf_config()).context("EKF")?;
    ekf.reset(0.0, world.robot().pose()).context("EKF start")?;
    let mut scans = Vec::with_capacity(DETECT_SCANS);
    while scans.len() < DETECT_SCANS {
        let cmd = if scans.len() < DETECT_REST_SCANS {
            Twist2::ZERO
        } else {
            driver.command(world.time_s(), &world.robot().pose(), world.field())
        };
        let step = world.step(cmd).context("world step")?;
        fuse_odometry(&mut ekf, step.wheel, step.imu).context("EKF")?;
        if let Some(scan) = step.scan {
            let (odom, odom_twist) = (ekf.pose(), ekf.twist());
            scans.push(Recorded { stamp_s: scan.stamp_s, odom, odom_twist, points: scan.points.to_vec() });
        }
    }
    let points = scans.iter().map(|s| s.points.len()).sum::<usize>() as f64 / scans.len().max(1) as f64;
    Ok((scans, points))
}

/// Wall time of each `detect` call over the scan sequence, µs, after the warm-up scans. Each scan carries
/// its odometry twist, as the navigator passes it: the detector undoes the motion skew of the returns it
/// registers, and the slide watch registers a lane found at rest (`register_rest_watch`).
fn time_detector(
    config: DetectorConfig,
    scans: &[Recorded],
    scenario: &Scenario,
) -> anyhow::Result<Vec<f64>> {
    let mut detector = RowDetector::new(config).context("detector")?;
    let mount = scenario.lidar.mount;
    let mut times = Vec::with_capacity(scans.len());
    for (k, s) in scans.iter().enumerate() {
        let t0 = Instant::now();
        // The default pipeline: no attitude (`attitude.enabled` is opt-in).
        let scan = Scan { stamp_s: s.stamp_s, points: &s.points, twist: Some(s.odom_twist), attitude: None };
        let d = detector.detect(scan, s.odom, &mount);
        let us = t0.elapsed().as_secs_f64() * 1e6;
        std::hint::black_box(d);
        if k >= DETECT_WARMUP_SCANS {
            times.push(us);
        }
    }
    Ok(times)
}

/// One timed closed loop.
struct Loop {
    sim_time_s: f64,
    wall_s: f64,
    scans: usize,
    distance_m: f64,
}

/// The closed loop for `LOOP_SIM_S` simulated seconds, from a fresh world (its build not timed).
fn closed_loop(scenario: &Scenario) -> anyhow::Result<Loop> {
    let mut world = World::new(scenario).context("building the world")?;
    let mut nav = Navigator::new(NavigatorConfig::default()).context("navigator")?;
    let mut ekf = Ekf::new(nav.config().ekf.clone()).context("EKF")?;
    let mount = scenario.lidar.mount;
    let mut cmd = Twist2::ZERO;
    let mut scans = 0;
    let start = world.robot().pose();
    let wall = Instant::now();
    while world.time_s() < LOOP_SIM_S {
        let step = world.step(cmd).context("world step")?;
        fuse_odometry(&mut ekf, step.wheel, step.imu).context("EKF")?;
        if let Some(scan) = step.scan {
            scans += 1;
            let out = nav.step(NavInput {
                stamp_s: scan.stamp_s,
                odom: ekf.pose(),
                odom_twist: ekf.twist(),
                scan: Some(scan.as_scan()),
                mount: &mount,
                mpc_budget: None,
                wheel_slip: ekf.wheel_slip(),
            });
            cmd = out.cmd;
        }
    }
    let wall_s = wall.elapsed().as_secs_f64();
    let end = world.robot().pose();
    Ok(Loop {
        sim_time_s: world.time_s(),
        wall_s,
        scans,
        distance_m: (end.x - start.x).hypot(end.y - start.y),
    })
}

/// Wall time of warm MPC solves following a straight row, µs.
fn time_mpc() -> anyhow::Result<Vec<f64>> {
    const PERIOD_S: f64 = 0.1;
    const SPEED_MPS: f64 = 0.5;
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 1e6, 0.0);
    let mut mpc = Mpc::new(MpcConfig::default()).context("MPC")?;
    let mut pose = Pose2::default();
    let mut prev = Twist2::new(SPEED_MPS, 0.0);
    let mut times = Vec::with_capacity(MPC_SOLVES);
    for k in 0..MPC_WARMUP + MPC_SOLVES {
        // A detector-like perturbation of the measured state, deterministic (no RNG in the binary).
        let phase = k as f64;
        let mut state = path.project(&pose, pose.x);
        state.lateral_m += 0.01 * (1.7 * phase).sin();
        state.heading_rad += 0.5f64.to_radians() * (2.3 * phase).cos();
        let t0 = Instant::now();
        let sol = mpc.solve(&state, &path, SPEED_MPS, prev, None);
        let us = t0.elapsed().as_secs_f64() * 1e6;
        if k >= MPC_WARMUP {
            times.push(us);
        }
        prev = sol.cmd;
        let mid = pose.yaw + 0.5 * sol.cmd.omega * PERIOD_S;
        pose = Pose2::new(
            pose.x + sol.cmd.v * PERIOD_S * mid.cos(),
            pose.y + sol.cmd.v * PERIOD_S * mid.sin(),
            pose.yaw + sol.cmd.omega * PERIOD_S,
        );
    }
    Ok(times)
}

/// Mean of a sample's finite values (0 when there are none).
fn mean(values: &[f64]) -> f64 {
    let (sum, n) = values.iter().filter(|x| x.is_finite()).fold((0.0, 0usize), |(s, n), x| (s + x, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

/// Median of a sample (0 when empty).
fn median(values: &[f64]) -> f64 {
    let mut v: Vec<f64> = values.iter().copied().filter(|x| x.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    match (v.get(n.wrapping_sub(1) / 2), v.get(n / 2)) {
        (Some(a), Some(b)) => 0.5 * (a + b),
        _ => 0.0,
    }
}

fn machine() -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|text| {
            text.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split_once(':'))
                .map(|(_, v)| v.trim().to_string())
        })
        .unwrap_or_else(|| "unknown".into());
    let load_average_1m = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|t| t.split_whitespace().next().and_then(|v| v.parse().ok()));
    Machine {
        cpu,
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        load_average_1m,
        build: if cfg!(debug_assertions) { "debug assertions on" } else { "release" },
    }
}

fn print_table(r: &Report) {
    let m = &r.machine;
    println!(
        "croprow bench on {} ({} cores, load {}, {}), scenario {}",
        m.cpu,
        m.cores,
        m.load_average_1m.map_or("?".into(), |l| format!("{l:.2}")),
        m.build,
        r.scenario
    );
    println!(
        "detect, default mode   median {:>9.1} µs  (mean {:.1})  over {} scans of {:.0} points",
        r.detect_us_median, r.detect_us_mean, r.runs.detect, r.detect_points_per_scan
    );
    println!(
        "detect, paper mode     median {:>9.1} µs  (mean {:.1})  over {} scans",
        r.detect_paper_us_median, r.detect_paper_us_mean, r.runs.detect_paper
    );
    println!(
        "closed loop            median {:>6.1} × real time (min {:.1}, max {:.1}) over {} loops: \
         {:.1} s simulated in {:.2} s wall, {} scans, {:.1} m driven",
        r.sim_realtime_factor,
        r.sim_realtime_factor_min,
        r.sim_realtime_factor_max,
        r.runs.sim_loops,
        r.sim_time_s,
        r.sim_wall_s,
        r.runs.sim_scans,
        r.sim_distance_m
    );
    println!("  includes: {}", r.sim_includes);
    println!(
        "MPC warm solve, N = {}  median {:>9.1} µs  over {} solves",
        r.mpc_horizon_steps, r.mpc_solve_us_median, r.runs.mpc
    );
}
