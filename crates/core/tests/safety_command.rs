//! Safety invariant (issue 6): whatever comes in (NaN/inf or backwards stamps, non-finite or jumping
//! odometry, dropped, absurd or lying detections, absurd points and mounts), the Navigator's command is
//! finite, inside the MPC's speed and yaw-rate bounds, changes no faster than its acceleration limits,
//! and is zero whenever the input is refused or the mission is stopped.
//!
//! The robot is an ideal unicycle on the synthetic field of `control_field`, driven by the commands,
//! so the sequences reach every mode (following, row end, turns, entries, stops).

mod control_field;
mod safety_common;

use control_field::{Field, PERIOD_S, drive, lane_start};
use croprow_core::control::lane_switch::LaneSwitchConfig;
use croprow_core::control::mpc::MpcConfig;
use croprow_core::navigator::{NavInput, NavOutput, Navigator, NavigatorConfig};
use croprow_core::{Mount, Point3, Pose2, Scan, Twist2};
use proptest::prelude::*;
use safety_common::{Corruption, InputGlitch, corrupt, corruption, glitch, wild_f64};

/// Tolerance on the bounds: they are exact clamps, so only rounding of `last ± rate·dt`.
const EPS: f64 = 1e-9;

/// MPC limits and speeds drawn over their useful range (cruise speeds may exceed the speed bound).
fn config() -> impl Strategy<Value = NavigatorConfig> {
    (-0.3..0.0f64, 0.2..1.5f64, 0.3..1.5f64, 0.2..2.0f64, 0.5..4.0f64, 0.2..1.2f64, 0.02..0.2f64).prop_map(
        |(
            speed_min_mps,
            speed_max_mps,
            yaw_rate_max_radps,
            accel_max_mps2,
            yaw_accel_max_radps2,
            cruise,
            step_s,
        )| {
            NavigatorConfig {
                mpc: MpcConfig {
                    speed_min_mps,
                    speed_max_mps,
                    yaw_rate_max_radps,
                    accel_max_mps2,
                    yaw_accel_max_radps2,
                    step_s,
                    ..MpcConfig::default()
                },
                lane_switch: LaneSwitchConfig {
                    lanes: 4,
                    cruise_speed_mps: cruise,
                    ..LaneSwitchConfig::default()
                },
                ..NavigatorConfig::default()
            }
        },
    )
}

/// Checks one output against the limits; `prev` is the previous output's command and `elapsed_s` the
/// time since the last accepted step (capped at the model step), `None` before the first one.
fn check(
    cfg: &MpcConfig,
    out: &NavOutput,
    prev: Twist2,
    elapsed_s: Option<f64>,
) -> Result<(), TestCaseError> {
    let cmd = out.cmd;
    prop_assert!(cmd.is_finite(), "non-finite command {cmd:?}");
    prop_assert!(cmd.v >= cfg.speed_min_mps - EPS && cmd.v <= cfg.speed_max_mps + EPS, "speed {cmd:?}");
    prop_assert!(cmd.omega.abs() <= cfg.yaw_rate_max_radps + EPS, "yaw rate {cmd:?}");
    if out.input_fault.is_some() || out.mode.is_stopped() {
        prop_assert_eq!(cmd, Twist2::ZERO, "refused or stopped ({:?}) but moving", out.mode);
    }
    if cmd != Twist2::ZERO {
        let dt = elapsed_s.unwrap_or(cfg.step_s);
        prop_assert!(
            (cmd.v - prev.v).abs() <= cfg.accel_max_mps2 * dt + EPS,
            "{prev:?} -> {cmd:?} in {dt} s"
        );
        prop_assert!(
            (cmd.omega - prev.omega).abs() <= cfg.yaw_accel_max_radps2 * dt + EPS,
            "{prev:?} -> {cmd:?} in {dt} s"
        );
    }
    Ok(())
}

proptest! {
    #![proptest_config(safety_common::config(48))]

    #[test]
    fn command_is_finite_and_within_limits_under_any_detections_and_stamps(
        cfg in config(),
        steps in prop::collection::vec((corruption(), glitch()), 50..400),
    ) {
        let mut nav = Navigator::new(cfg.clone()).expect("valid config");
        let field = Field { rows: 10, length_m: 6.0, blackout: None };
        let mut pose = lane_start(0);
        let (mut t, mut clock_offset) = (0.0, 0.0);
        let mut prev = Twist2::ZERO;
        let mut last_accepted: Option<f64> = None;
        let mut last_stamp = 0.0;
        for (c, g) in &steps {
            t += PERIOD_S;
            let mut stamp = t + clock_offset;
            let (mut odom, mut twist) = (pose, Twist2::new(prev.v, prev.omega));
            match *g {
                InputGlitch::None => {}
                InputGlitch::BadStamp(s) => stamp = s,
                InputGlitch::Backwards(d) => stamp = last_stamp - d,
                InputGlitch::ClockJump(d) => {
                    clock_offset += d;
                    stamp += d;
                }
                InputGlitch::Repeat => stamp = last_stamp,
                InputGlitch::BadPose(p) => odom = Pose2::new(odom.x + p.x, odom.y + p.y, odom.yaw + p.yaw),
                InputGlitch::BadTwist => twist = Twist2::new(f64::NAN, 0.0),
                InputGlitch::Teleport(dx, dy) => odom = Pose2::new(odom.x + dx, odom.y + dy, odom.yaw),
            }
            if stamp.is_finite() {
                last_stamp = stamp;
            }
            let det = corrupt(field.detect(stamp, &pose), c);
            let out = nav.step_with_detection(stamp, odom, twist, det, None);
            let elapsed = last_accepted.map(|t0: f64| (stamp - t0).min(cfg.mpc.step_s));
            check(&cfg.mpc, &out, prev, elapsed)?;
            if out.input_fault.is_none() {
                last_accepted = Some(stamp);
            }
            prev = out.cmd;
            pose = drive(pose, out.cmd, PERIOD_S);
        }
    }

    #[test]
    fn command_is_finite_and_within_limits_for_absurd_scans_and_mounts(
        points in prop::collection::vec(
            (wild_f64(-10.0..10.0), wild_f64(-10.0..10.0), wild_f64(-3.0..1.0))
                .prop_map(|(x, y, z)| Point3::new(x as f32, y as f32, z as f32)),
            0..300,
        ),
        mount in (wild_f64(-1.0..1.0), wild_f64(0.5..2.5), wild_f64(-0.3..1.2))
            .prop_map(|(x_m, z_m, pitch_rad)| Mount { x_m, z_m, pitch_rad, ..Mount::default() }),
        stamps in prop::collection::vec(wild_f64(0.0..5.0), 1..12),
        odom in (wild_f64(-5.0..5.0), wild_f64(-5.0..5.0), wild_f64(-3.2..3.2)),
    ) {
        let cfg = NavigatorConfig::default();
        let mut nav = Navigator::new(cfg.clone()).expect("valid config");
        let odom = Pose2::new(odom.0, odom.1, odom.2);
        let mut prev = Twist2::ZERO;
        let mut last_accepted: Option<f64> = None;
        for &stamp in &stamps {
            let out = nav.step(NavInput {
                stamp_s: stamp,
                odom,
                odom_twist: Twist2::ZERO,
                scan: Some(Scan { stamp_s: stamp, points: &points, twist: None, attitude: None }),
                mount: &mount,
                mpc_budget: None,
                wheel_slip: None,
            });
            let elapsed = last_accepted.map(|t0: f64| (stamp - t0).min(cfg.mpc.step_s));
            check(&cfg.mpc, &out, prev, elapsed)?;
            if out.input_fault.is_none() {
                last_accepted = Some(stamp);
            }
            prev = out.cmd;
        }
    }
}

#[test]
fn the_corruptions_reach_every_moving_mode() {
    // Guards the property above against testing only a robot at rest: the ideal detections alone, on
    // the same field, take the robot through following, the row end, a turn and an entry.
    let mut nav = Navigator::new(NavigatorConfig {
        lane_switch: LaneSwitchConfig { lanes: 2, ..LaneSwitchConfig::default() },
        ..NavigatorConfig::default()
    })
    .expect("valid config");
    let field = Field { rows: 10, length_m: 6.0, blackout: None };
    let mut pose = lane_start(0);
    let mut seen = std::collections::BTreeSet::new();
    // 600 steps: the pivots brake their spin, so the second lane ends after about 420.
    for i in 0..600 {
        let t = i as f64 * PERIOD_S;
        let det = corrupt(field.detect(t, &pose), &Corruption::None);
        let out = nav.step_with_detection(t, pose, Twist2::ZERO, det, None);
        seen.insert(out.mode.as_str());
        pose = drive(pose, out.cmd, PERIOD_S);
    }
    for mode in ["following", "clearing_row_end", "turning", "entering", "done"] {
        assert!(seen.contains(mode), "{mode} not reached: {seen:?}");
    }
}
