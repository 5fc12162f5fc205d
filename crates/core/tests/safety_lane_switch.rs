//! Safety invariants of the lane-switching state machine (issue 6), for random valid geometries and
//! detection sequences, on the synthetic field of `control_field` with the MPC driving an ideal unicycle:
//!
//! * no lane is skipped silently: lanes are entered in order `start_lane`, `start_lane + lane_step`, …
//!   (one step per confirmed entry, only from `entering`), `lanes_completed` rises by at most one per
//!   step and only when a row end is cleared, and a robot that follows a lane is in the lane planned;
//! * no turn inside the crop: every point of a planned headland turn (both arcs and the straight
//!   between them) lies at least `turn_start_m` past the row end it turns at, and no wheel of a robot
//!   on those arcs is before that line; with an honest detector (dropouts and small noise only), that
//!   line is the true row end within the noise.

mod control_field;
mod safety_common;

use control_field::{Field, PERIOD_S, SPACING, WHEELS, drive, lane_start};
use croprow_core::Pose2;
use croprow_core::control::lane_switch::{LaneSwitchConfig, LaneSwitcher, Mode, TurnDirection};
use croprow_core::control::mpc::{Mpc, MpcConfig};
use croprow_core::control::reference::ReferenceConfig;
use croprow_core::{Detection, Twist2};
use proptest::prelude::*;
use safety_common::{Corruption, corrupt, corruption, honest_corruption};

/// Largest row-end error of an honest detection (`Corruption::Noise`), m.
const END_NOISE_M: f64 = 0.1;

/// A valid lane-switch configuration with random lanes, direction and turn geometry.
fn config() -> impl Strategy<Value = LaneSwitchConfig> {
    (2..5u32, 1..3u32, 0..3u32, any::<bool>(), 0.3..0.75f64, 0.1..0.6f64, 0.3..1.0f64, 1..4u32)
        .prop_map(
            |(lanes, lane_step, start_lane, right, turn_radius_m, clearance_margin_m, wheel_y_m, conf)| {
                LaneSwitchConfig {
                    lanes,
                    lane_step,
                    start_lane,
                    first_turn: if right { TurnDirection::Right } else { TurnDirection::Left },
                    turn_radius_m,
                    clearance_margin_m,
                    wheel_y_m,
                    max_headland_excursion_m: 3.0,
                    entry_confirmations: conf,
                    ..LaneSwitchConfig::default()
                }
            },
        )
        .prop_filter("valid geometry", |c| c.validate().is_ok())
}

/// Along-row distance of `(x, y)` past the row-end line `end` (a pose heading along the row), m.
fn along(end: &Pose2, x: f64, y: f64) -> f64 {
    end.inverse_transform_point(x, y).0
}

/// The synthetic-field lane (pair of rows) the robot starts in, and the pair navigator lane `lane`
/// lies in: pair `k` is between rows `2k` and `2k + 1`, at y = −(2k + ½)·spacing; right turns go to −y.
fn pair_of(cfg: &LaneSwitchConfig, start_pair: u32, lane: u32) -> i64 {
    let moved = i64::from(lane) - i64::from(cfg.start_lane);
    match cfg.first_turn {
        TurnDirection::Right => i64::from(start_pair) + moved,
        TurnDirection::Left => i64::from(start_pair) - moved,
    }
}

/// Runs the state machine with the MPC over the field and checks every invariant at every step.
fn check_run(cfg: LaneSwitchConfig, corruptions: &[Corruption], honest: bool) -> Result<(), TestCaseError> {
    let lanes_span = (cfg.lanes - 1) * cfg.lane_step;
    let start_pair = match cfg.first_turn {
        TurnDirection::Right => 0,
        TurnDirection::Left => lanes_span,
    };
    let field = Field { rows: 2 * (lanes_span as usize + 1) + 2, length_m: 5.0, blackout: None };
    let mut sw = LaneSwitcher::new(cfg.clone(), ReferenceConfig::default()).expect("valid config");
    let mut mpc = Mpc::new(MpcConfig::default()).expect("valid config");
    let mut pose = lane_start(start_pair as usize);
    let mut prev = Twist2::ZERO;
    let (mut mode, mut lane, mut done) = (Mode::Acquiring, cfg.start_lane, 0u32);
    for (i, c) in corruptions.iter().enumerate() {
        let t = i as f64 * PERIOD_S;
        let det: Option<Detection> = corrupt(field.detect(t, &pose), c);
        let g = sw.update(&pose, det.as_ref());

        // Lanes in order, one step per confirmed entry.
        if g.lane != lane {
            prop_assert_eq!(g.lane, lane + cfg.lane_step, "lane jumped from {} to {}", lane, g.lane);
            prop_assert_eq!(mode, Mode::Entering, "lane changed outside an entry");
            prop_assert_eq!(g.mode, Mode::Following);
        }
        // Row ends cleared one at a time, and only by clearing one.
        if g.lanes_completed != done {
            prop_assert_eq!(g.lanes_completed, done + 1, "lanes_completed jumped");
            prop_assert_eq!(mode, Mode::ClearingRowEnd, "a lane counted outside a row end");
            prop_assert!(matches!(g.mode, Mode::Turning | Mode::Done), "{:?}", g.mode);
        }
        prop_assert!(g.lanes_completed <= cfg.lane_count());
        // A robot following a lane it entered is in the planned lane (neighbours are 2 spacings away).
        if g.mode == Mode::Following && g.lanes_completed > 0 {
            let expected_y = -(2.0 * pair_of(&cfg, start_pair, g.lane) as f64 + 0.5) * SPACING;
            prop_assert!(
                (pose.y - expected_y).abs() < SPACING,
                "following lane {} at y {:.2}, planned y {:.2}",
                g.lane,
                pose.y,
                expected_y
            );
        }
        // A new turn: every planned point and every wheel on the arcs past the row end.
        if g.mode == Mode::Turning && mode != Mode::Turning {
            let end = sw.row_end().expect("a turn has a row end");
            let path = sw.path().expect("a turn has a path");
            let arcs_m: f64 = path.segments().iter().take(3).map(|s| s.length_m).sum();
            let n = (arcs_m / 0.01).ceil() as usize;
            // The true row end of the lane being left: x = length when driving +x, x = 0 driving −x.
            let forward = end.yaw.cos() > 0.0;
            for k in 0..=n {
                let p = path.pose_at(arcs_m * k as f64 / n as f64);
                prop_assert!(
                    along(&end, p.x, p.y) >= cfg.turn_start_m() - 1e-6,
                    "turn point {:?} only {:.3} m past the row end",
                    p,
                    along(&end, p.x, p.y)
                );
                for (wx, wy) in WHEELS {
                    let (x, y) = p.transform_point(wx.signum() * cfg.wheel_x_m, wy.signum() * cfg.wheel_y_m);
                    prop_assert!(along(&end, x, y) >= -1e-6, "wheel at ({x:.3}, {y:.3}) before the row end");
                    if honest {
                        let past = if forward { x - field.length_m } else { -x };
                        prop_assert!(past >= -END_NOISE_M - 1e-6, "wheel {past:.3} m inside the true crop");
                    }
                }
            }
        }
        (mode, lane, done) = (g.mode, g.lane, g.lanes_completed);
        let cmd = match sw.path() {
            Some(path) if !g.mode.is_stopped() => {
                let f = path.project(&pose, sw.progress_m());
                mpc.solve(&f, path, g.speed_mps, prev, None).cmd
            }
            _ => Twist2::ZERO,
        };
        pose = drive(pose, cmd, PERIOD_S);
        prev = cmd;
        if matches!(g.mode, Mode::Done | Mode::Stopped { .. }) {
            break;
        }
    }
    Ok(())
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(40))]

    #[test]
    fn lanes_are_never_skipped_and_turns_stay_out_of_the_crop_under_any_detections(
        cfg in config(),
        corruptions in prop::collection::vec(corruption(), 600..1500),
    ) {
        check_run(cfg, &corruptions, false)?;
    }

    #[test]
    fn turns_clear_the_true_row_end_with_an_honest_detector(
        cfg in config(),
        corruptions in prop::collection::vec(honest_corruption(), 1500..2000),
    ) {
        check_run(cfg, &corruptions, true)?;
    }
}
