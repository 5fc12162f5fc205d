//! Safety invariants of the lane-switching state machine (issue 6), for random valid geometries and
//! detection sequences, on the synthetic field of `control_field` with the MPC driving an ideal unicycle:
//!
//! * no lane is skipped silently: lanes are entered in order `start_lane`, `start_lane + lane_step`, …
//!   (one step per confirmed entry, only from `entering`), `lanes_completed` rises by at most one per
//!   step and only when a row end is cleared, and every confirmed entry puts the robot `lane_step`
//!   lanes over from where its turn started (a lane away would be a silent skip or repeat);
//! * no turn inside the crop: every point of a planned headland turn (both arcs and the straight
//!   between them) lies at least `turn_start_m` past the row end it turns at, and no wheel of a robot
//!   on those arcs is before that line; with an honest detector (dropouts and small noise only), no
//!   wheel is before the true row end by more than the noise allows.

mod control_field;
mod safety_common;

use control_field::{Field, PERIOD_S, SPACING, WHEELS, drive, lane_start};
use croprow_core::Pose2;
use croprow_core::control::lane_switch::{LaneSwitchConfig, LaneSwitcher, Mode, TurnDirection};
use croprow_core::control::mpc::{Mpc, MpcConfig};
use croprow_core::control::reference::ReferenceConfig;
use croprow_core::{Detection, RowEstimate, RowStatus, Twist2};
use proptest::prelude::*;
use safety_common::{Corruption, NOISE_END_M, NOISE_HEADING_RAD, corrupt, corruption, honest_corruption};

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

/// Centre y of the synthetic field's lane `k` (between rows `2k` and `2k + 1`), m.
fn pair_y(k: i64) -> f64 {
    -(2.0 * k as f64 + 0.5) * SPACING
}

/// The synthetic field's lane nearest to `y`.
fn nearest_pair(y: f64) -> i64 {
    ((-y / SPACING - 0.5) / 2.0).round() as i64
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
    let mut turn_pair: Option<i64> = None;
    // Lanes move towards −y (higher pairs) when the first turn is to the right, whatever the turn.
    let side = if cfg.first_turn == TurnDirection::Right { 1 } else { -1 };
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
        // An entry lands `lane_step` lanes over from where the turn started, in the mission's direction.
        if g.lane != lane {
            let from = turn_pair.expect("an entry follows a turn");
            let expected_y = pair_y(from + side * i64::from(cfg.lane_step));
            prop_assert!(
                (pose.y - expected_y).abs() < SPACING,
                "entered lane {} at y {:.2}, {} lane(s) from y {:.2} is y {:.2}",
                g.lane,
                pose.y,
                cfg.lane_step,
                pair_y(from),
                expected_y
            );
        }
        // A new turn: every planned point and every wheel on the arcs past the row end.
        if g.mode == Mode::Turning && mode != Mode::Turning {
            turn_pair = Some(nearest_pair(pose.y));
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
                        // The row end believed is off by the end noise, and its line turned by the
                        // heading noise about the centre line.
                        let past = if forward { x - field.length_m } else { -x };
                        let lateral = end.inverse_transform_point(x, y).1;
                        let tol = NOISE_END_M + lateral.abs() * NOISE_HEADING_RAD.sin() + 1e-6;
                        prop_assert!(
                            past >= -tol,
                            "wheel {past:.3} m inside the true crop (tolerance {tol:.3})"
                        );
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
    #![proptest_config(safety_common::config(40))]

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

// ----- regressions found by the properties and the soak -----

/// Drives two lanes of the synthetic field with the ideal detector, `lie` rewriting each step's
/// detection; returns the final mode and the robot's y at every step it followed the second lane.
fn two_lanes(lie: &dyn Fn(Detection) -> Detection) -> (Mode, Vec<f64>) {
    let cfg = LaneSwitchConfig { lanes: 2, ..LaneSwitchConfig::default() };
    let field = Field { rows: 6, length_m: 5.0, blackout: None };
    let mut sw = LaneSwitcher::new(cfg, ReferenceConfig::default()).expect("valid config");
    let mut mpc = Mpc::new(MpcConfig::default()).expect("valid config");
    let mut pose = lane_start(0);
    let (mut prev, mut second) = (Twist2::ZERO, Vec::new());
    for i in 0..2000 {
        let det = lie(field.detect(i as f64 * PERIOD_S, &pose));
        let g = sw.update(&pose, Some(&det));
        if g.mode == Mode::Following && g.lane == 1 {
            second.push(pose.y);
        }
        if matches!(g.mode, Mode::Done | Mode::Stopped { .. }) {
            return (g.mode, second);
        }
        let cmd = match sw.path() {
            Some(path) if !g.mode.is_stopped() => {
                mpc.solve(&path.project(&pose, sw.progress_m()), path, g.speed_mps, prev, None).cmd
            }
            _ => Twist2::ZERO,
        };
        pose = drive(pose, cmd, PERIOD_S);
        prev = cmd;
    }
    (sw.mode(), second)
}

#[test]
fn a_neighbouring_lane_seen_at_the_row_end_does_not_shift_the_turn() {
    // Found by the property above (PROPTEST_RNG_SEED=2): one scan reporting the rows of the next lane
    // over, on the step the row end was reached, anchored the row end and the whole headland turn
    // 1.5 m to the side, and the robot entered a lane it had not planned.
    let shifted_once = std::cell::Cell::new(false);
    let shift = |d: Detection| {
        if d.status == RowStatus::EndOfRow && !shifted_once.get() {
            shifted_once.set(true);
            corrupt(d, &Corruption::LaneShift(-1.5)).unwrap_or(d)
        } else {
            d
        }
    };
    let (mode, second) = two_lanes(&shift);
    assert!(shifted_once.get(), "the lie was never told");
    assert_eq!(mode, Mode::Done);
    assert!(!second.is_empty(), "the second lane was never followed");
    // Lane 1 of the synthetic field is centred on y = -1.875 m; lane 0 and 2 are 1.5 m away.
    for y in second {
        assert!((y - pair_y(1)).abs() < 0.2, "following at y {y:.2}");
    }
}

#[test]
fn rows_at_half_the_row_spacing_are_never_followed() {
    // Found by the soak (seeds 2 and 8, grown crops): a detector locked on half the row period reports
    // two "rows" 0.3-0.37 m apart around the robot. Followed, they steer it onto the real rows.
    let half = |d: Detection| {
        let row = |r: RowEstimate, side: f64| RowEstimate { offset_m: side * 0.17, ..r };
        Detection {
            left: d.left.map(|r| row(r, 1.0)),
            right: d.right.map(|r| row(r, -1.0)),
            row_spacing_m: Some(0.34),
            ..d
        }
    };
    let (mode, second) = two_lanes(&half);
    assert_eq!(mode, Mode::Acquiring, "rows at half the spacing started the mission");
    assert!(second.is_empty());
}
