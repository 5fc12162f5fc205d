//! Safety invariant (issue 6): with the rows lost for longer than `lane_switch.max_blind_distance_m`
//! while following, away from any row end the detector has seen, the Navigator's command is zero and
//! stays zero (mode `stopped`), whatever the "no row" looks like: no scan, an empty result of any
//! status, `Lost` with rows, rows with non-finite numbers or facing across the field.

mod control_field;
mod safety_common;

use control_field::{Field, PERIOD_S, drive, lane_start};
use croprow_core::control::lane_switch::{LaneSwitchConfig, Mode, StopReason};
use croprow_core::navigator::{Navigator, NavigatorConfig};
use croprow_core::{Detection, RowEstimate, RowStatus, Twist2};
use proptest::prelude::*;

/// The ways a scan can carry no usable row.
#[derive(Debug, Clone, Copy)]
enum NoRow {
    Dropped,
    Empty(RowStatus),
    LostWithRows,
    NonFinite(f64),
    Across,
}

fn no_row() -> impl Strategy<Value = NoRow> {
    prop_oneof![
        Just(NoRow::Dropped),
        prop_oneof![
            Just(RowStatus::Searching),
            Just(RowStatus::Tracking),
            Just(RowStatus::Lost),
            Just(RowStatus::InvalidInput)
        ]
        .prop_map(NoRow::Empty),
        Just(NoRow::LostWithRows),
        prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(f64::NEG_INFINITY)].prop_map(NoRow::NonFinite),
        Just(NoRow::Across),
    ]
}

fn apply(d: Detection, k: NoRow) -> Option<Detection> {
    let rows = |d: Detection, f: &dyn Fn(RowEstimate) -> RowEstimate| Detection {
        left: d.left.map(f),
        right: d.right.map(f),
        ..d
    };
    match k {
        NoRow::Dropped => None,
        NoRow::Empty(s) => Some(Detection::empty(d.stamp_s, s)),
        NoRow::LostWithRows => Some(Detection { status: RowStatus::Lost, ..d }),
        NoRow::NonFinite(v) => Some(rows(d, &|r| RowEstimate { offset_m: v, ..r })),
        // A row at 90° to the robot is not a row to follow (the reference ignores |heading| ≥ 1.2 rad).
        NoRow::Across => Some(rows(d, &|r| RowEstimate { heading_rad: 1.5, ..r })),
    }
}

proptest! {
    #![proptest_config(safety_common::config(64))]

    #[test]
    fn rows_lost_beyond_the_blind_distance_stop_the_robot(
        max_blind_m in 0.0..3.0f64,
        cruise in 0.2..1.0f64,
        lose_after_s in 1.0..6.0f64,
        kinds in prop::collection::vec(no_row(), 1..8),
    ) {
        let cfg = NavigatorConfig {
            lane_switch: LaneSwitchConfig {
                max_blind_distance_m: max_blind_m,
                cruise_speed_mps: cruise,
                ..LaneSwitchConfig::default()
            },
            ..NavigatorConfig::default()
        };
        let speed_max = cfg.mpc.speed_max_mps;
        let mut nav = Navigator::new(cfg).expect("valid config");
        // Rows 100 m long: no row end is ever in view.
        let field = Field { rows: 4, length_m: 100.0, blackout: None };
        let mut pose = lane_start(0);
        let mut blind_m = 0.0;
        let mut followed = false;
        let mut stopped = false;
        for i in 0..400 {
            let t = i as f64 * PERIOD_S;
            let ideal = field.detect(t, &pose);
            let lost = t >= lose_after_s;
            let det = if lost { apply(ideal, kinds[i % kinds.len()]) } else { Some(ideal) };
            let out = nav.step_with_detection(t, pose, Twist2::ZERO, det, None);
            followed |= out.mode == Mode::Following;
            if stopped {
                prop_assert_eq!(out.cmd, Twist2::ZERO, "moved again after stopping");
            }
            // One step's travel at the top speed is the most the blind count can lag behind.
            if lost && followed && blind_m > max_blind_m + speed_max * PERIOD_S + 1e-9 {
                prop_assert_eq!(out.cmd, Twist2::ZERO, "still moving {} m blind", blind_m);
                prop_assert!(
                    matches!(out.mode, Mode::Stopped { reason: StopReason::NoRows | StopReason::RowsLost }),
                    "{:?}",
                    out.mode
                );
            }
            stopped |= out.mode.is_stopped() && followed;
            let next = drive(pose, out.cmd, PERIOD_S);
            if lost {
                blind_m += (next.x - pose.x).hypot(next.y - pose.y);
            }
            pose = next;
        }
        prop_assert!(followed, "the robot never followed the rows");
        prop_assert!(stopped, "the robot never stopped");
    }
}
