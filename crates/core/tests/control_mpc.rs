//! Closed-loop MPC behaviour on an ideal unicycle: recovery on straight and curved references,
//! bounds, and degradation to a stop.

use croprow_core::control::mpc::{Mpc, MpcConfig, SolveStatus};
use croprow_core::control::path::Path;
use croprow_core::{Pose2, Twist2};

mod control_field;

use control_field::{PERIOD_S, drive};

/// Runs the closed loop from `start` and returns, per step, (distance travelled, |lateral error|).
fn closed_loop(
    path: &Path,
    start: Pose2,
    speed: f64,
    steps: usize,
    mpc: &mut Mpc,
) -> Vec<(f64, f64, Twist2)> {
    let mut pose = start;
    let mut prev = Twist2::ZERO;
    let mut s = 0.0;
    let mut dist = 0.0;
    let mut out = Vec::with_capacity(steps);
    for _ in 0..steps {
        let f = path.project(&pose, s);
        s = f.s_m;
        let sol = mpc.solve(&f, path, speed, prev, None);
        assert_ne!(sol.status, SolveStatus::Failed);
        assert!(sol.cmd.is_finite());
        let next = drive(pose, sol.cmd, PERIOD_S);
        dist += (next.x - pose.x).hypot(next.y - pose.y);
        pose = next;
        prev = sol.cmd;
        out.push((dist, path.project(&pose, s).lateral_m.abs(), sol.cmd));
    }
    out
}

/// Distance after which the lateral error stays below `tol_m` for the rest of the run.
fn settle_distance(trace: &[(f64, f64, Twist2)], tol_m: f64) -> f64 {
    let last_bad = trace.iter().rposition(|&(_, e, _)| e >= tol_m);
    last_bad.and_then(|i| trace.get(i + 1)).map_or(0.0, |t| t.0)
}

#[test]
fn recovers_on_a_straight_row_from_30_cm_and_8_degrees() {
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 40.0, 0.0);
    for (dy, dyaw) in [(0.3, -8f64), (-0.3, 8.0), (0.3, 8.0), (-0.3, -8.0)] {
        let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
        let trace = closed_loop(&path, Pose2::new(0.0, dy, dyaw.to_radians()), 0.5, 150, &mut mpc);
        let settle = settle_distance(&trace, 0.02);
        eprintln!("straight, start ({dy} m, {dyaw}°): under 2 cm for good after {settle:.2} m");
        assert!(settle < 3.0, "start ({dy}, {dyaw}°): settled after {settle:.2} m");
    }
}

#[test]
fn recovers_on_a_curved_row() {
    // Alternating arcs of 40 m radius: tighter than the paper's curved field (about 42 m at the apex).
    let mut path = Path::with_capacity(4);
    path.extend(Pose2::new(-1.0, 0.0, 0.0), 12.0, 1.0 / 40.0);
    path.extend(Pose2::default(), 12.0, -1.0 / 40.0);
    path.extend(Pose2::default(), 12.0, 1.0 / 40.0);
    let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
    let trace = closed_loop(&path, Pose2::new(0.0, 0.3, (-8f64).to_radians()), 0.5, 300, &mut mpc);
    let settle = settle_distance(&trace, 0.02);
    eprintln!("curved: under 2 cm for good after {settle:.2} m");
    assert!(settle < 3.0, "settled after {settle:.2} m");
    // Across the curvature changes it stays within 2 cm.
    let worst = trace.iter().filter(|t| t.0 > 3.0 && t.0 < 34.0).map(|t| t.1).fold(0.0, f64::max);
    eprintln!("curved: worst lateral error after settling {worst:.4} m");
    assert!(worst < 0.02, "worst lateral after settling {worst:.4} m");
}

#[test]
fn tracks_a_headland_arc() {
    let r = 0.6;
    let mut path = Path::with_capacity(3);
    path.extend(Pose2::new(-1.0, 0.0, 0.0), 1.0, 0.0);
    path.extend(Pose2::default(), std::f64::consts::FRAC_PI_2 * r, 1.0 / r);
    path.extend(Pose2::default(), 3.0, 0.0);
    let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
    let trace = closed_loop(&path, Pose2::new(0.0, 0.0, 0.0), 0.3, 80, &mut mpc);
    let worst = trace.iter().map(|t| t.1).fold(0.0, f64::max);
    // A 0.6 m arc at 0.3 m/s needs 0.5 rad/s, inside the limits: the robot stays within 5 cm.
    assert!(worst < 0.05, "worst lateral {worst:.3} m");
}

#[test]
fn commands_respect_magnitude_and_rate_bounds() {
    let cfg = MpcConfig {
        speed_max_mps: 0.6,
        yaw_rate_max_radps: 0.4,
        accel_max_mps2: 0.5,
        yaw_accel_max_radps2: 1.0,
        ..MpcConfig::default()
    };
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 40.0, 0.0);
    let mut mpc = Mpc::new(cfg.clone()).unwrap();
    // A far-off start asks for much more than the bounds allow.
    let trace = closed_loop(&path, Pose2::new(0.0, 1.0, 0.6), 1.5, 100, &mut mpc);
    let mut prev = Twist2::ZERO;
    let eps = 1e-9;
    for &(_, _, cmd) in &trace {
        assert!(cmd.v >= cfg.speed_min_mps - eps && cmd.v <= cfg.speed_max_mps + eps, "{cmd:?}");
        assert!(cmd.omega.abs() <= cfg.yaw_rate_max_radps + eps, "{cmd:?}");
        assert!((cmd.v - prev.v).abs() <= cfg.accel_max_mps2 * PERIOD_S + eps, "{prev:?} -> {cmd:?}");
        assert!(
            (cmd.omega - prev.omega).abs() <= cfg.yaw_accel_max_radps2 * PERIOD_S + eps,
            "{prev:?} -> {cmd:?}"
        );
        prev = cmd;
    }
    // The bounds bind: the far start uses the full yaw rate at some point.
    assert!(trace.iter().any(|t| t.2.omega.abs() > cfg.yaw_rate_max_radps - 1e-3));
}

#[test]
fn iteration_budget_is_reported_as_data() {
    let cfg = MpcConfig { max_iterations: 1, tolerance: 1e-12, ..MpcConfig::default() };
    let mut mpc = Mpc::new(cfg).unwrap();
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 40.0, 0.0);
    let f = path.project(&Pose2::new(0.0, 0.3, 0.1), 0.0);
    let sol = mpc.solve(&f, &path, 0.5, Twist2::ZERO, None);
    assert_eq!(sol.status, SolveStatus::MaxIterations);
    assert!(sol.cmd.is_finite());
}

#[test]
fn zero_time_budget_is_out_of_time_with_a_finite_command() {
    let cfg = MpcConfig { tolerance: 1e-12, ..MpcConfig::default() };
    let mut mpc = Mpc::new(cfg).unwrap();
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 40.0, 0.0);
    let f = path.project(&Pose2::new(0.0, 0.3, 0.1), 0.0);
    let sol = mpc.solve(&f, &path, 0.5, Twist2::ZERO, Some(std::time::Duration::ZERO));
    assert_eq!(sol.status, SolveStatus::OutOfTime);
    assert!(sol.cmd.is_finite());
}

#[test]
fn non_finite_path_stops() {
    let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(0.0, 0.0, 0.0), 10.0, f64::NAN);
    let sol = mpc.solve(&Default::default(), &path, 0.5, Twist2::new(0.5, 0.0), None);
    assert_eq!((sol.status, sol.cmd), (SolveStatus::Failed, Twist2::ZERO));
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(200))]

    /// Whatever finite state, curvature and speed it is given, the command is finite and bounded.
    #[test]
    fn any_finite_input_gives_a_finite_bounded_command(
        lateral in -1e3f64..1e3,
        heading in -10.0f64..10.0,
        curvature in -5.0f64..5.0,
        speed in -10.0f64..10.0,
        prev_v in -5.0f64..5.0,
        prev_w in -5.0f64..5.0,
    ) {
        let cfg = MpcConfig::default();
        let mut mpc = Mpc::new(cfg.clone()).unwrap();
        let mut path = Path::with_capacity(1);
        path.push(Pose2::new(0.0, 0.0, 0.0), 10.0, curvature);
        let state = croprow_core::control::Frenet { s_m: 0.0, lateral_m: lateral, heading_rad: heading, curvature_per_m: curvature };
        let sol = mpc.solve(&state, &path, speed, Twist2::new(prev_v, prev_w), None);
        proptest::prop_assert!(sol.cmd.is_finite());
        proptest::prop_assert!(sol.cmd.v >= cfg.speed_min_mps && sol.cmd.v <= cfg.speed_max_mps);
        proptest::prop_assert!(sol.cmd.omega.abs() <= cfg.yaw_rate_max_radps);
    }
}

#[test]
fn the_mpc_never_plans_faster_than_the_cruise_speed_even_to_pull_a_tyre_back_between_the_rows() {
    // Regression: with the wheel corridor active, a robot far off its lane centre line sped up to
    // 0.94 m/s (cruise 0.5) to leave the rows sooner, and ran over plants at a row end.
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 40.0, 0.0);
    path.set_row_spacing(Some(0.75));
    for (dy, dyaw) in [(0.3, 8f64), (-0.3, -8.0), (0.2, -15.0)] {
        let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
        let trace = closed_loop(&path, Pose2::new(0.0, dy, dyaw.to_radians()), 0.5, 100, &mut mpc);
        let fastest = trace.iter().map(|t| t.2.v).fold(0.0, f64::max);
        assert!(fastest <= 0.5 + 1e-9, "start ({dy} m, {dyaw}°): {fastest} m/s");
    }
    // A zero speed (a pivot) keeps the robot on the spot.
    let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
    let trace = closed_loop(&path, Pose2::new(0.0, 0.0, 1.2), 0.0, 30, &mut mpc);
    assert!(trace.iter().all(|t| t.2.v == 0.0));
}
