//! Lane-switching behaviour against the synthetic field of `control_field`, seen by an ideal detector. The closed-loop tests drive
//! an ideal unicycle with the MPC; the transition tests place the robot directly.

use croprow_core::control::lane_switch::{LaneSwitchConfig, LaneSwitcher, Mode, StopReason, TurnDirection};
use croprow_core::control::mpc::{Mpc, MpcConfig, SolveStatus};
use croprow_core::control::reference::ReferenceConfig;
use croprow_core::{Detection, Pose2, RowStatus, Twist2};

mod control_field;

use control_field::{Field, PERIOD_S, SPACING, drive, lane_start};

struct Run {
    final_mode: Mode,
    lanes_completed: u32,
    lanes_seen: Vec<u32>,
    contacts: usize,
    max_excursion_m: f64,
    modes: Vec<Mode>,
}

fn run(field: &Field, cfg: LaneSwitchConfig, start: Pose2, steps: usize) -> Run {
    let mut sw = LaneSwitcher::new(cfg, ReferenceConfig::default()).unwrap();
    let mut mpc = Mpc::new(MpcConfig::default()).unwrap();
    let mut pose = start;
    let mut prev = Twist2::ZERO;
    let mut out = Run {
        final_mode: Mode::Acquiring,
        lanes_completed: 0,
        lanes_seen: vec![],
        contacts: 0,
        max_excursion_m: 0.0,
        modes: vec![],
    };
    for i in 0..steps {
        let det = field.detect(i as f64 * PERIOD_S, &pose);
        let g = sw.update(&pose, Some(&det));
        if out.modes.last() != Some(&g.mode) {
            out.modes.push(g.mode);
        }
        if out.lanes_seen.last() != Some(&g.lane) {
            out.lanes_seen.push(g.lane);
        }
        let cmd = match sw.path() {
            Some(path) if !g.mode.is_stopped() => {
                let f = path.project(&pose, sw.progress_m());
                let sol = mpc.solve(&f, path, g.speed_mps, prev, None);
                assert_ne!(sol.status, SolveStatus::Failed);
                sol.cmd
            }
            _ => Twist2::ZERO,
        };
        pose = drive(pose, cmd, PERIOD_S);
        prev = cmd;
        out.contacts += field.contacts(&pose);
        out.final_mode = g.mode;
        out.lanes_completed = g.lanes_completed;
        if matches!(g.mode, Mode::Done | Mode::Stopped { .. }) {
            break;
        }
    }
    out.max_excursion_m = sw.max_excursion_m();
    out
}

#[test]
fn covers_four_lanes_alternating_turns_without_crop_contact() {
    let field = Field { rows: 8, length_m: 8.0, blackout: None };
    let cfg = LaneSwitchConfig { lanes: 4, first_turn: TurnDirection::Right, ..LaneSwitchConfig::default() };
    let r = run(&field, cfg, lane_start(0), 4000);
    assert_eq!(r.final_mode, Mode::Done, "modes {:?}", r.modes);
    eprintln!("4 lanes: max headland excursion {:.3} m, crop contacts {}", r.max_excursion_m, r.contacts);
    assert_eq!(r.lanes_completed, 4);
    assert_eq!(r.lanes_seen, vec![0, 1, 2, 3]);
    assert_eq!(r.contacts, 0);
    assert!(r.max_excursion_m <= 1.5, "excursion {:.3} m", r.max_excursion_m);
    let turns = r.modes.iter().filter(|m| **m == Mode::Turning).count();
    assert_eq!(turns, 3);
}

#[test]
fn skips_lanes_and_starts_from_any_lane() {
    // 16 rows = 8 lanes; start in lane 5, turn left (towards lower lanes here: the field lies to the
    // left of the robot when it drives back), skip one lane each time: lanes 5 -> 3 -> 1.
    let field = Field { rows: 16, length_m: 6.0, blackout: None };
    let cfg = LaneSwitchConfig {
        lanes: 3,
        start_lane: 5,
        lane_step: 2,
        first_turn: TurnDirection::Left,
        ..LaneSwitchConfig::default()
    };
    let r = run(&field, cfg, lane_start(5), 4000);
    assert_eq!(r.final_mode, Mode::Done, "modes {:?}", r.modes);
    assert_eq!(r.lanes_completed, 3);
    assert_eq!(r.contacts, 0);
    assert!(r.max_excursion_m <= 1.5, "excursion {:.3} m", r.max_excursion_m);
}

#[test]
fn stops_at_the_end_of_the_last_lane() {
    let field = Field { rows: 4, length_m: 5.0, blackout: None };
    let cfg = LaneSwitchConfig { lanes: 1, ..LaneSwitchConfig::default() };
    let r = run(&field, cfg, lane_start(0), 2000);
    assert_eq!(r.final_mode, Mode::Done);
    assert_eq!(r.modes, vec![Mode::Following, Mode::ClearingRowEnd, Mode::Done]);
    assert!(r.max_excursion_m >= LaneSwitchConfig::default().turn_start_m() - 0.06);
}

#[test]
fn rows_missing_mid_row_stop_the_robot() {
    let field = Field { rows: 4, length_m: 20.0, blackout: Some((5.0, 20.0)) };
    let r = run(&field, LaneSwitchConfig::default(), lane_start(0), 2000);
    assert_eq!(r.final_mode, Mode::Stopped { reason: StopReason::NoRows });
}

#[test]
fn a_lane_off_the_field_is_never_entered_silently() {
    // Turning right out of the last lane of a 4-row field: only the edge row is in view, and the lane
    // it implies is not the planned one.
    let field = Field { rows: 4, length_m: 5.0, blackout: None };
    let cfg = LaneSwitchConfig { lanes: 3, ..LaneSwitchConfig::default() };
    let r = run(&field, cfg, lane_start(1), 3000);
    assert_eq!(r.final_mode, Mode::Stopped { reason: StopReason::WrongLane }, "modes {:?}", r.modes);
    assert_eq!(r.lanes_completed, 1);
    assert_eq!(r.contacts, 0);
}

#[test]
fn an_unconfirmed_lane_stops_before_going_deep_into_the_field() {
    // The detector sees nothing from 2 m before the row end on: the known row end carries the robot
    // out, but the new lane can never be confirmed.
    let field = Field { rows: 8, length_m: 10.0, blackout: Some((8.0, 12.0)) };
    let cfg = LaneSwitchConfig { lanes: 2, ..LaneSwitchConfig::default() };
    let r = run(&field, cfg.clone(), lane_start(0), 3000);
    assert_eq!(
        r.final_mode,
        Mode::Stopped { reason: StopReason::ReentryNotConfirmed },
        "modes {:?}",
        r.modes
    );
    assert_eq!(r.lanes_completed, 1);
    assert_eq!(r.contacts, 0);
}

// ----- single transitions, robot placed by hand -----

fn switcher(cfg: LaneSwitchConfig) -> LaneSwitcher {
    LaneSwitcher::new(cfg, ReferenceConfig::default()).unwrap()
}

fn field() -> Field {
    Field { rows: 8, length_m: 10.0, blackout: None }
}

#[test]
fn waits_stopped_until_rows_are_tracked() {
    let mut sw = switcher(LaneSwitchConfig::default());
    let g = sw.update(&lane_start(0), Some(&Detection::empty(0.0, RowStatus::Searching)));
    assert_eq!((g.mode, g.speed_mps), (Mode::Acquiring, 0.0));
    let g = sw.update(&lane_start(0), Some(&field().detect(0.1, &lane_start(0))));
    assert_eq!(g.mode, Mode::Following);
    assert!(g.speed_mps > 0.0);
}

#[test]
fn rows_lost_status_stops_immediately() {
    let mut sw = switcher(LaneSwitchConfig::default());
    sw.update(&lane_start(0), Some(&field().detect(0.0, &lane_start(0))));
    let g = sw.update(&lane_start(0), Some(&Detection::empty(0.1, RowStatus::Lost)));
    assert_eq!(g.mode, Mode::Stopped { reason: StopReason::RowsLost });
    assert_eq!(g.speed_mps, 0.0);
    assert!(sw.path().is_none());
    // One detection of the rows coming back is not enough to move again: the automatic resume needs
    // `resume_confirmations` (5) consistent ones.
    let g = sw.update(&lane_start(0), Some(&field().detect(0.2, &lane_start(0))));
    assert_eq!(g.mode, Mode::Stopped { reason: StopReason::RowsLost });
    sw.resume();
    assert_eq!(sw.mode(), Mode::Acquiring);
}

#[test]
fn non_finite_odometry_stops() {
    let mut sw = switcher(LaneSwitchConfig::default());
    sw.update(&lane_start(0), Some(&field().detect(0.0, &lane_start(0))));
    let g = sw.update(&Pose2::new(f64::NAN, 0.0, 0.0), None);
    assert_eq!(g.mode, Mode::Stopped { reason: StopReason::InvalidOdometry });
}

#[test]
fn reaching_the_row_end_starts_clearing_then_turning_with_a_detector_reset() {
    let f = field();
    let mut sw = switcher(LaneSwitchConfig::default());
    let mut pose = lane_start(0);
    sw.update(&pose, Some(&f.detect(0.0, &pose)));
    let mut resets = 0;
    let mut modes = vec![];
    // Walk along the lane centre in 5 cm steps to 1.5 m past the row end.
    while pose.x < f.length_m + 1.5 {
        pose.x += 0.05;
        let g = sw.update(&pose, Some(&f.detect(0.0, &pose)));
        resets += usize::from(g.reset_detector);
        if modes.last() != Some(&g.mode) {
            modes.push(g.mode);
            if g.mode == Mode::ClearingRowEnd {
                assert!((pose.x - f.length_m).abs() < 0.051, "clearing began at x {}", pose.x);
            }
            if g.mode == Mode::Turning {
                let start = LaneSwitchConfig::default().turn_start_m();
                assert!((pose.x - f.length_m - start).abs() < 0.051, "turn began at x {}", pose.x);
            }
        }
    }
    assert_eq!(modes, vec![Mode::Following, Mode::ClearingRowEnd, Mode::Turning]);
    assert_eq!(resets, 1);
    // The planned turn pivots right (first_turn default) at the turn start, crosses two row spacings
    // and pivots again into the next lane (arithmetic: 1e-9).
    let path = sw.path().unwrap();
    let start = LaneSwitchConfig::default().turn_start_m();
    let [sideways, entry] = path.segments() else { panic!("{:?}", path.segments()) };
    assert!((sideways.start.x - (f.length_m + start)).abs() < 1e-9, "{sideways:?}");
    assert!((sideways.start.yaw + std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    let entry = entry.start;
    assert!((entry.x - (f.length_m + start)).abs() < 1e-9, "{entry:?}");
    assert!((entry.y - (lane_start(0).y - 2.0 * SPACING)).abs() < 1e-9, "{entry:?}");
    assert!((entry.yaw.abs() - std::f64::consts::PI).abs() < 1e-9);
}

/// Walks the robot exactly along the turn path, 5 cm a step (a pivot done in one step), until the
/// switcher leaves `Turning`; returns the last pose.
fn walk_turn(sw: &mut LaneSwitcher) -> Pose2 {
    let mut pose = Pose2::default();
    for _ in 0..1000 {
        if sw.mode() != Mode::Turning {
            break;
        }
        let path = sw.path().unwrap().clone();
        let s = (sw.progress_m() + 0.05).min(path.segments()[0].length_m);
        pose = path.pose_at(s);
        let g = sw.update(&pose, None);
        if g.mode == Mode::Turning {
            assert!(g.speed_mps <= LaneSwitchConfig::default().turn_speed_mps);
        }
    }
    pose
}

#[test]
fn a_pivot_turn_stands_still_while_turning_and_brakes_into_each_corner() {
    let f = field();
    let mut sw = switcher(LaneSwitchConfig::default());
    let mut pose = lane_start(0);
    sw.update(&pose, Some(&f.detect(0.0, &pose)));
    let mut speeds = vec![];
    while sw.mode() != Mode::Turning {
        pose.x += 0.01;
        speeds.push((pose.x, sw.update(&pose, Some(&f.detect(0.0, &pose))).speed_mps));
    }
    // Clearing the row end brakes at stop_decel_mps2 to a stop at the turn start (within 2 cm):
    // 0.3 m/s needs 0.18 m at 0.25 m/s², so 10 cm before the start the speed is √(2·0.25·0.1).
    let cfg = LaneSwitchConfig::default();
    let stop_x = f.length_m + cfg.turn_start_m();
    assert!((pose.x - stop_x).abs() <= 0.021, "turn began at x {}", pose.x);
    let (_, v) = speeds.iter().copied().find(|(x, _)| (x - (stop_x - 0.1)).abs() < 0.005).unwrap();
    assert!((v - (2.0f64 * 0.25 * 0.1).sqrt()).abs() < 0.02, "{v}");
    // Heading still along the row: pivot on the spot.
    let g = sw.update(&pose, None);
    assert_eq!((g.mode, g.speed_mps), (Mode::Turning, 0.0));
    // Turned onto the sideways leg: drive, braking into the next corner.
    let leg = sw.path().unwrap().segments()[0];
    let g = sw.update(&leg.start, None);
    assert_eq!((g.mode, g.speed_mps), (Mode::Turning, cfg.turn_speed_mps));
    let g = sw.update(&leg.pose_at(leg.length_m - 0.05), None);
    assert!((g.speed_mps - (2.0f64 * 0.25 * 0.05).sqrt()).abs() < 1e-6, "{g:?}");
    // At the corner: pivot again, then enter.
    let g = sw.update(&leg.end(), None);
    assert_eq!((g.mode, g.speed_mps), (Mode::Turning, 0.0));
    let entry = sw.path().unwrap().segments()[0];
    assert_eq!(sw.path().unwrap().segments().len(), 1);
    let g = sw.update(&entry.start, None);
    assert_eq!(g.mode, Mode::Entering);
    assert!(g.reset_detector);
}

/// Follows the first lane of `field()` to its end and walks the robot through the turn; returns the
/// switcher, now `entering`, and the pose where the entry began.
fn at_next_lane_entry(cfg: LaneSwitchConfig) -> (LaneSwitcher, Pose2) {
    let f = field();
    let mut sw = switcher(cfg);
    let mut pose = lane_start(0);
    sw.update(&pose, Some(&f.detect(0.0, &pose)));
    while sw.mode() != Mode::Turning {
        pose.x += 0.05;
        sw.update(&pose, Some(&f.detect(0.0, &pose)));
    }
    let at_entry = walk_turn(&mut sw);
    assert_eq!(sw.mode(), Mode::Entering);
    (sw, at_entry)
}

#[test]
fn entering_a_lane_that_is_not_the_planned_one_stops() {
    let f = field();
    // Walk the robot through the turn, then show it rows centred half a lane off the plan.
    let (mut sw, at_entry) = at_next_lane_entry(LaneSwitchConfig::default());
    // 0.3 m off: the rows then imply a centre line beyond the 0.25 m tolerance.
    let shifted = Pose2::new(at_entry.x, at_entry.y + 0.3, at_entry.yaw);
    for i in 0..3 {
        sw.update(&at_entry, Some(&f.detect(i as f64, &shifted)));
    }
    assert_eq!(sw.mode(), Mode::Stopped { reason: StopReason::WrongLane });
}

/// Walks the robot of [`at_next_lane_entry`] straight on along its entry while the detector sees
/// the new lane `offset_m` to the left of the plan (within the entry tolerance, so it agrees): the
/// robot never closes on the lane it sees. Returns the mode it ends in and the x of its front tyres'
/// leading edge there (the new lane's rows end at x = `field().length_m`, the robot drives towards
/// -x).
fn walk_entry_beside_the_seen_lane(offset_m: f64, cfg: LaneSwitchConfig) -> (Mode, f64) {
    let f = field();
    let (mut sw, at_entry) = at_next_lane_entry(cfg.clone());
    let mut pose = at_entry;
    for i in 0..400 {
        // Seen from a robot `offset_m` to the right, the rows sit that much to the left.
        let seen_from = Pose2::new(pose.x, pose.y - offset_m, pose.yaw);
        let g = sw.update(&pose, Some(&f.detect(i as f64 * PERIOD_S, &seen_from)));
        if g.mode != Mode::Entering {
            break;
        }
        pose.x += 0.02 * pose.yaw.cos();
    }
    (sw.mode(), pose.x - cfg.wheel_x_m - 0.5 * cfg.tire_length_m)
}

#[test]
fn a_robot_too_far_off_the_lane_it_agrees_on_stops_before_its_tyres_reach_the_crop() {
    // The lane seen lies 0.23 m off the plan: it agrees (tolerance 0.25 m) and the entry moves onto
    // it, but the robot is still 0.23 m off it at the crop's edge, over `entry_max_offset_m` (0.2):
    // its tyres would land on the lane's rows (soak seed 799, fault-free: 4 plants).
    let cfg = LaneSwitchConfig::default();
    let (mode, front_x) = walk_entry_beside_the_seen_lane(0.23, cfg.clone());
    assert_eq!(mode, Mode::Stopped { reason: StopReason::ReentryNotConfirmed });
    let row_ends_x = field().length_m;
    assert!(front_x > row_ends_x, "the front tyres stopped at x {front_x:.2}, inside the crop");
    // Closer, or with the rule off (the row spacing), the robot drives in; walked straight on, it
    // never aligns to confirm the lane and stops 1 m deep (`max_unconfirmed_entry_m`).
    let off = LaneSwitchConfig { entry_max_offset_m: SPACING, ..cfg.clone() };
    for (offset_m, cfg) in [(0.15, cfg), (0.23, off)] {
        let (mode, front_x) = walk_entry_beside_the_seen_lane(offset_m, cfg);
        assert_eq!(mode, Mode::Stopped { reason: StopReason::ReentryNotConfirmed });
        assert!(front_x < row_ends_x - 0.5, "{offset_m} m off: stopped at x {front_x:.2}, short of the crop");
    }
}

#[test]
fn an_end_of_row_without_distance_assumes_the_configured_one() {
    let cfg = LaneSwitchConfig::default();
    let ahead = cfg.default_row_end_ahead_m;
    let mut sw = switcher(cfg);
    let pose = lane_start(0);
    sw.update(&pose, Some(&field().detect(0.0, &pose)));
    let end = Detection { row_end_ahead_m: None, ..field().detect(0.1, &pose) };
    let end = Detection { status: RowStatus::EndOfRow, ..end };
    let g = sw.update(&pose, Some(&end));
    assert_eq!(g.mode, Mode::ClearingRowEnd);
    let row_end = sw.row_end().unwrap();
    assert!((row_end.x - (pose.x + ahead)).abs() < 1e-9 && (row_end.y - pose.y).abs() < 1e-9, "{row_end:?}");
}

#[test]
fn rows_lost_close_to_a_seen_row_end_are_expected() {
    let f = field();
    let mut sw = switcher(LaneSwitchConfig::default());
    // 2 m before the end of a 10 m row: the end is in view.
    let pose = Pose2::new(8.0, lane_start(0).y, 0.0);
    sw.update(&pose, Some(&f.detect(0.0, &pose)));
    let lost = Detection { row_end_ahead_m: Some(1.9), ..Detection::empty(0.1, RowStatus::Lost) };
    let g = sw.update(&Pose2::new(8.1, pose.y, 0.0), Some(&lost));
    assert_eq!(g.mode, Mode::Following);
    assert!(g.speed_mps > 0.0);
    // Far from any row end, the same status stops the robot.
    let mut sw = switcher(LaneSwitchConfig::default());
    let pose = Pose2::new(2.0, lane_start(0).y, 0.0);
    sw.update(&pose, Some(&f.detect(0.0, &pose)));
    let g = sw.update(&pose, Some(&Detection { row_end_ahead_m: Some(8.0), ..lost }));
    assert_eq!(g.mode, Mode::Stopped { reason: StopReason::RowsLost });
}

/// Turns into the next lane of `field()`, then walks the robot 5 cm a step along the new lane's
/// centre line (or `aside_m` to its left) while its rows read turned by `rate` rad per metre from
/// `from_m` past the entry on (as if a fit took up a turn: the rows rotate about the robot). Returns
/// the mode after `to_m` (or at a stop), the distance walked and where the switcher first asked the
/// detector to search again.
fn enter_with_rows_turning(
    cfg: LaneSwitchConfig,
    aside_m: f64,
    rate: f64,
    from_m: f64,
    to_m: f64,
) -> (Mode, f64, Option<f64>) {
    let f = field();
    let (mut sw, at_entry) = at_next_lane_entry(cfg);
    let mut walked = 0.0;
    let mut first_search = None;
    while walked < to_m {
        let pose = Pose2::new(at_entry.x - walked, at_entry.y - aside_m, at_entry.yaw);
        let turned = rate * (walked - from_m).max(0.0);
        let seen_from = Pose2::new(pose.x, pose.y, pose.yaw - turned);
        let g = sw.update(&pose, Some(&f.detect(walked, &seen_from)));
        if g.reset_detector && first_search.is_none() {
            first_search = Some(walked);
        }
        if matches!(g.mode, Mode::Stopped { .. }) {
            return (g.mode, walked, first_search);
        }
        walked += 0.05;
    }
    (sw.mode(), walked, first_search)
}

#[test]
fn rows_turning_off_the_planned_lane_while_entering_are_searched_again() {
    // The robot walks 15 cm beside the entry line, so it stays `entering` (not aligned), while the
    // rows turn 0.2 rad/m from its first scan of the new lane: each scan agrees with the last, but
    // from 0.75 m on they run 0.15 rad off the lane planned from the last one (soak seed 765's
    // entry, which then took 13 plants). Those are a fit that took up a turn: the switcher asks the
    // detector to search again, and neither enters on them nor calls them another lane.
    let entry = |rate| enter_with_rows_turning(LaneSwitchConfig::default(), 0.15, rate, 0.0, 1.0);
    let (mode, _, first_search) = entry(0.2);
    assert_eq!(mode, Mode::Entering);
    let first = first_search.expect("a search");
    assert!((0.75..=0.85).contains(&first), "searched again from {first:.2} m");
    // Straight rows: no search.
    assert_eq!(entry(0.0).2, None);
}

#[test]
fn rows_turning_just_after_the_entry_stop_the_robot_within_the_watch() {
    // The entry's watch alone: the watch over the whole lane (`max_row_turn_rad`) is off here.
    let entry_watch = LaneSwitchConfig { max_row_turn_rad: 0.0, ..LaneSwitchConfig::default() };
    let turned_after_entry = |cfg| enter_with_rows_turning(cfg, 0.0, 0.2, 0.5, 4.0);
    // Confirmed on straight rows, then 0.15 rad off by 1.25 m: inside the 2 m watch.
    let (mode, walked, _) = turned_after_entry(entry_watch.clone());
    assert_eq!(mode, Mode::Stopped { reason: StopReason::WrongLane });
    assert!((1.25..=1.35).contains(&walked), "stopped after {walked:.2} m");
    // Without the watch the same rows are followed.
    let off = LaneSwitchConfig { entry_heading_watch_m: 0.0, ..entry_watch.clone() };
    assert_eq!(turned_after_entry(off).0, Mode::Following);
    // Rows that turn once the watch is over (curved rows further in) are followed too.
    let (mode, ..) = enter_with_rows_turning(entry_watch, 0.0, 0.2, 2.5, 4.0);
    assert_eq!(mode, Mode::Following);
}

#[test]
fn rows_that_turn_faster_than_crop_rows_bend_stop_the_robot_anywhere_in_the_lane() {
    // Past the entry's watch, rows turning 0.2 rad/m from 2.5 m in (a fit that took up weeds in a
    // gap, soak seeds 324 and 680) have turned 0.1 rad a metre later: the robot stops there.
    let (mode, walked, _) = enter_with_rows_turning(LaneSwitchConfig::default(), 0.0, 0.2, 2.5, 5.0);
    assert_eq!(mode, Mode::Stopped { reason: StopReason::WrongLane });
    assert!((3.0..=3.8).contains(&walked), "stopped after {walked:.2} m");
    // Rows bending like the paper's curved field (0.024 rad/m), or twice that, are followed.
    for rate in [0.024, 0.05] {
        let (mode, ..) = enter_with_rows_turning(LaneSwitchConfig::default(), 0.0, rate, 2.5, 5.0);
        assert_eq!(mode, Mode::Following, "{rate} rad/m");
    }
}
