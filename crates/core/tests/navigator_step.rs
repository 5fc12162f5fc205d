//! The Navigator facade: configuration, input checks, the detector wiring, and closed-loop row
//! following and lane switching through `step_with_detection` over the synthetic field.

mod control_field;

use control_field::{Field, PERIOD_S, drive, lane_start};
use croprow_core::control::lane_switch::{LaneSwitchConfig, Mode};
use croprow_core::navigator::{InputFault, NavInput, Navigator, NavigatorConfig};
use croprow_core::{Mount, Point3, Pose2, RowStatus, Scan, Twist2};

#[test]
fn config_round_trips_through_toml_with_per_stage_sections() {
    let text = "[mpc]\nhorizon_steps = 30\n\n[lane_switch]\nlanes = 3\nfirst_turn = \"left\"\n\n[ekf]\nmax_gap_s = 1.0\n";
    let cfg: NavigatorConfig = toml::from_str(text).unwrap();
    assert_eq!(cfg.mpc.horizon_steps, 30);
    assert_eq!(cfg.lane_switch.lanes, 3);
    assert_eq!(cfg.ekf.max_gap_s, 1.0);
    let back: NavigatorConfig = toml::from_str(&toml::to_string(&cfg).unwrap()).unwrap();
    assert_eq!(back, cfg);
    assert!(toml::from_str::<NavigatorConfig>("[mpc]\nhorizon = 3\n").is_err(), "unknown fields are refused");
}

#[test]
fn invalid_config_names_the_field() {
    let mut cfg = NavigatorConfig::default();
    cfg.mpc.step_s = -0.1;
    assert!(Navigator::new(cfg).unwrap_err().to_string().contains("mpc.step_s"));
    let mut cfg = NavigatorConfig::default();
    cfg.lane_switch.turn_radius_m = 5.0;
    assert!(Navigator::new(cfg).unwrap_err().to_string().contains("lane_switch.turn_radius_m"));
}

#[test]
fn time_going_backwards_is_refused_with_a_zero_command() {
    let mut nav = Navigator::new(NavigatorConfig::default()).unwrap();
    let field = Field { rows: 4, length_m: 30.0, blackout: None };
    let pose = lane_start(0);
    let out = nav.step_with_detection(1.0, pose, Twist2::ZERO, Some(field.detect(1.0, &pose)), None);
    assert_eq!(out.mode, Mode::Following);
    let out = nav.step_with_detection(1.1, pose, Twist2::ZERO, None, None);
    assert!(out.cmd.v > 0.0);
    let out = nav.step_with_detection(1.05, pose, Twist2::ZERO, None, None);
    assert_eq!(
        (out.input_fault, out.cmd, out.mode),
        (Some(InputFault::BadStamp), Twist2::ZERO, Mode::Following)
    );
    let out = nav.step_with_detection(1.2, Pose2::new(0.0, f64::NAN, 0.0), Twist2::ZERO, None, None);
    assert_eq!((out.input_fault, out.cmd), (Some(InputFault::BadOdometry), Twist2::ZERO));
    // Good input again: the robot goes on.
    let out = nav.step_with_detection(1.3, pose, Twist2::ZERO, None, None);
    assert_eq!(out.input_fault, None);
    assert!(out.cmd.v > 0.0 && out.cmd.is_finite());
}

#[test]
fn step_runs_the_detector_on_the_scan() {
    let mut nav = Navigator::new(NavigatorConfig::default()).unwrap();
    let mount = Mount::default();
    let points = [Point3::new(f32::NAN, 0.0, 0.0)];
    let out = nav.step(NavInput {
        stamp_s: 0.0,
        odom: Pose2::default(),
        odom_twist: Twist2::ZERO,
        scan: Some(Scan { stamp_s: 0.0, points: &points, twist: None, attitude: None }),
        mount: &mount,
        mpc_budget: None,
        wheel_slip: None,
    });
    // A scan without a finite point: the detector refuses it, the robot waits.
    assert_eq!(out.detection.map(|d| d.status), Some(RowStatus::InvalidInput));
    assert_eq!((out.mode, out.cmd), (Mode::Acquiring, Twist2::ZERO));
}

/// Closed loop at 50 Hz control with 10 Hz detections; returns (distance, |lateral|) per step and
/// the navigator.
fn closed_loop(
    field: &Field,
    cfg: NavigatorConfig,
    start: Pose2,
    seconds: f64,
) -> (Vec<(f64, f64)>, Navigator) {
    let mut nav = Navigator::new(cfg).unwrap();
    let control_dt = PERIOD_S / 5.0;
    let mut pose = start;
    let mut dist = 0.0;
    let mut trace = vec![];
    let mut prev = Twist2::ZERO;
    let steps = (seconds / control_dt) as usize;
    for i in 0..steps {
        let t = i as f64 * control_dt;
        let det = (i % 5 == 0).then(|| field.detect(t, &pose));
        let out = nav.step_with_detection(t, pose, Twist2::ZERO, det, None);
        assert!(out.cmd.is_finite());
        // Rates are limited per elapsed control period, not only per MPC step (the first step may use a
        // whole MPC step; a stop is immediate by design).
        let mpc = &nav.config().mpc;
        let dt = if i == 0 { mpc.step_s } else { control_dt };
        if !out.mode.is_stopped() {
            assert!(
                (out.cmd.v - prev.v).abs() <= mpc.accel_max_mps2 * dt + 1e-9,
                "{prev:?} -> {:?}",
                out.cmd
            );
            assert!(
                (out.cmd.omega - prev.omega).abs() <= mpc.yaw_accel_max_radps2 * dt + 1e-9,
                "{prev:?} -> {:?}",
                out.cmd
            );
        }
        prev = out.cmd;
        let next = drive(pose, out.cmd, control_dt);
        dist += (next.x - pose.x).hypot(next.y - pose.y);
        pose = next;
        // Cross-track error to the lane centre the robot is in.
        let lane_y = -(2.0 * out.lane as f64 + 0.5) * 0.75;
        trace.push((dist, (pose.y - lane_y).abs()));
        if matches!(out.mode, Mode::Done | Mode::Stopped { .. }) {
            break;
        }
    }
    (trace, nav)
}

#[test]
fn recovers_from_30_cm_and_8_degrees_within_3_m() {
    let field = Field { rows: 4, length_m: 40.0, blackout: None };
    let start = Pose2::new(0.5, lane_start(0).y + 0.3, (-8f64).to_radians());
    let (trace, _) = closed_loop(&field, NavigatorConfig::default(), start, 20.0);
    let last_bad = trace.iter().rposition(|t| t.1 >= 0.02).unwrap_or(0);
    let settle = trace.get(last_bad + 1).map_or(f64::INFINITY, |t| t.0);
    eprintln!("navigator recovery from 0.3 m / 8 deg: under 2 cm for good after {settle:.2} m");
    assert!(settle < 3.0, "settled after {settle:.2} m");
}

#[test]
fn drives_two_lanes_and_stops_done() {
    let field = Field { rows: 4, length_m: 6.0, blackout: None };
    let cfg = NavigatorConfig {
        lane_switch: LaneSwitchConfig { lanes: 2, ..LaneSwitchConfig::default() },
        ..NavigatorConfig::default()
    };
    let (_, nav) = closed_loop(&field, cfg, lane_start(0), 200.0);
    let sw = nav.lane_switcher();
    assert_eq!(sw.mode(), Mode::Done);
    assert_eq!((sw.lanes_completed(), sw.lane()), (2, 1));
    assert!(sw.max_excursion_m() <= 1.5, "excursion {}", sw.max_excursion_m());
}

/// Largest yaw rate commanded while following from the recovery start (0.3 m and 8° off the lane
/// centre), rad/s, with `max_following_curvature_per_m` set to `max_curvature`.
fn max_following_yaw_rate(max_curvature: f64) -> f64 {
    let field = Field { rows: 4, length_m: 20.0, blackout: None };
    let cfg = NavigatorConfig {
        lane_switch: LaneSwitchConfig {
            max_following_curvature_per_m: max_curvature,
            ..LaneSwitchConfig::default()
        },
        ..NavigatorConfig::default()
    };
    let mut nav = Navigator::new(cfg).unwrap();
    let control_dt = PERIOD_S / 5.0;
    let mut pose = Pose2::new(0.5, lane_start(0).y + 0.3, (-8f64).to_radians());
    let mut max_omega: f64 = 0.0;
    for i in 0..(10.0 / control_dt) as usize {
        let t = i as f64 * control_dt;
        let det = (i % 5 == 0).then(|| field.detect(t, &pose));
        let out = nav.step_with_detection(t, pose, Twist2::ZERO, det, None);
        if out.mode == Mode::Following {
            max_omega = max_omega.max(out.cmd.omega.abs());
        }
        pose = drive(pose, out.cmd, control_dt);
    }
    max_omega
}

#[test]
fn following_turns_along_arcs_not_on_the_spot() {
    // The bound is the curvature times the MPC's planned speed (at most `speed_max_mps`, 1 m/s) plus
    // 0.02 rad/s; without it the same start swings the robot faster.
    let bounded = max_following_yaw_rate(0.1);
    assert!(bounded <= 0.1 * 1.0 + 0.02 + 1e-9, "{bounded} rad/s");
    let free = max_following_yaw_rate(0.0);
    assert!(free > 0.15, "{free} rad/s: the start no longer tests the bound");
}
