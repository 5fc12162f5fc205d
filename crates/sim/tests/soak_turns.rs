//! Soak seeds whose headland turns ran over plants (issue 6: 72 of the 1000-run soak's contacts were
//! first hit while turning), each kept as a regression named after the cause it guards. They run as
//! the soak draws them, faults included: the turn must be safe under what the field throws at it.
//!
//! The causes, measured on the replays: the lane's row end (one line for the lane, at the farthest
//! centroid of its two rows) lay 0.1-0.3 m short of some row's last stem (rows end raggedly, a
//! neighbouring row runs on); wheel slip made the odometry over-report the blind drive from the last
//! sighting of the plants to the pivot by about 5 % (0.14 m short of the plan); and the second pivot
//! landed up to 0.12 m off the next lane's centre line after the sideways leg, bringing a row nearer.
//!
//! A gyro bias step while following (0.011-0.027 rad/s, 11 of the 1000-run soak's seeds) went unlearnt:
//! the EKF hardly trusts the wheels' yaw rate while moving, so the pivots turned by the bias error times
//! the turn's 10 s, the robot came back 0.2-0.4 rad crooked over a row and crushed its last plants. The
//! EKF's bias check finds the step from the wheels while following when the blocks are clean; when the
//! rows turned in `odom` (the heading drifts) the robot stands still at the row end and the check
//! finds it at rest, where the gyro's bias is plain; so does a stop that clears by itself after rows
//! that turned in `odom` (`lane_switch.resume_rest_s`).

use croprow_sim::experiment::soak::{Case, Outcome, run_case, soak_case};

/// Runs the soak case of `seed` (whose summary starts with `summary`) and checks it was safe.
fn safe_run(seed: u64, summary: &str) -> Outcome {
    safe_run_with(seed, summary, |_| {})
}

/// [`safe_run`] with `configure` applied to the case first.
fn safe_run_with(seed: u64, summary: &str, configure: impl Fn(&mut Case)) -> Outcome {
    let mut case = soak_case(seed);
    assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
    configure(&mut case);
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    outcome
}

/// A gyro bias step of 0.014 rad/s or more makes canopy registration read `odom` sliding past the
/// slide stop's limit (`lane_switch.max_slide_per_m`, on by default since session 30): with the
/// defaults these runs stop there, `sliding`, clean. The learning of the step at a stand or a stop
/// is tested with the slide stop off, and without the slide watch (`detector.register_rest_watch`,
/// the default since session 42), which reads for that stop: on its own it steers the MPC's crab by
/// the slides it reads, and soak seed 978 then came back from its turn onto a plant.
fn safe_run_past_a_gyro_step(seed: u64, summary: &str) -> Outcome {
    let stopped = safe_run(seed, summary);
    assert_eq!(stopped.end.as_str(), "stopped: sliding", "{stopped:?}");
    safe_run_with(seed, summary, |c| {
        c.navigator.lane_switch.max_slide_per_m = 0.0;
        c.navigator.detector.register_rest_watch = false;
    })
}

#[test]
fn a_row_ending_past_the_lane_end_is_cleared_by_the_pivot() {
    // Young soybean 0.72 m apart, curved: the lane's end was put at 9.84 m, the left row's last stem
    // stood at 10.00 m; the pivot's rear tyre crushed it (3 plants over three turns).
    let o = safe_run(10, "young soybean 10.1 m x 8 rows 0.72 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 3), "{o:?}");
}

#[test]
fn a_robot_off_the_centre_line_at_the_pivot_still_clears_the_rows() {
    // Young soybean, the LiDAR mount knocked 2.9° in roll: the robot reached the row end 0.13 m off
    // the lane's centre, nearer one row, and pivoted 1.0 m past its last plant.
    let o = safe_run(14, "young soybean 12.3 m x 5 rows 0.75 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_two_lane_shift_lands_the_second_pivot_clear_of_the_rows() {
    // Young corn, skipping a lane (2.9 m sideways): slip shortened the sideways leg by 0.12 m and the
    // second pivot swept the next lane's row.
    let o = safe_run(23, "young corn 10.4 m x 8 rows 0.72 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_neighbouring_row_longer_than_the_lane_is_cleared() {
    // Young corn 0.71 m apart: the lane's rows ended at 10.88 m, the next row out at 11.05 m, inside
    // the first pivot's reach.
    let o = safe_run(68, "young corn 11.2 m x 8 rows 0.71 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 3), "{o:?}");
}

#[test]
fn an_unconfirmed_lane_is_not_entered_on_odometry_alone() {
    // Grown corn with spurious returns: after the turn the detector saw the canopy at half its period,
    // so the lane was never confirmed, and the robot drove 2 m on odometry into the crop 0.23 m off the
    // lane (5 plants). Then its front tyres stopped short of the plants (`reentry_not_confirmed`);
    // since the start-up search refuses a heading at its edge the detector confirms this lane and the
    // run is done. Either is safe (`safe_run` asserts no contact); driving on blind is not.
    let o = safe_run(26, "grown corn 11.3 m x 7 rows 0.70 m apart");
    let done = (o.end.as_str(), o.lanes_completed) == ("done", 2);
    assert!(done || o.end == "stopped: reentry_not_confirmed", "{o:?}");
}

/// Runs the soak case of `seed` with the lane switcher's gap rule on (`lane_switch.gap_confirmations`
/// = 3, off by default) and checks it was safe.
fn safe_run_with_gap_rule(seed: u64, summary: &str) -> Outcome {
    let mut case = soak_case(seed);
    assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
    case.navigator.lane_switch.gap_confirmations = 3;
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    outcome
}

#[test]
fn a_gap_across_every_row_is_crossed_not_turned_at() {
    // Young soybean, every row empty over x = 5.2-6.3 m: the detector called the canopy end at the gap
    // for a few scans, then saw the crop beyond and withdrew it, but the lane switcher kept the end and
    // pivoted 1.3 m past it, into the plants beyond the gap (7 plants). With the gap rule, crop
    // standing past the end beyond an empty stretch drops it: the robot follows on across the gap.
    let o = safe_run_with_gap_rule(600, "young soybean 12.3 m x 8 rows 0.76 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_row_end_seen_through_a_missing_scan_sector_does_not_turn_into_the_crop() {
    // Young soybean, a 119° sector of the scan missing over x = 2.8-5.7 m: the rows' far part
    // vanished with it and the canopy seemed to end; the turn started there, in the field (9 plants).
    // With the gap rule the crop shows again at the first pivot and the robot stops there (a variant
    // of the levelling saw the crop past the sector in time and finished the mission). Since the
    // detector knows the sector for a hole (`detector.hold_scan_holes`, session 33) the robot stops as
    // soon as the hole hides the lane's rows and the map runs short ahead (`rows_lost`, 2.9 m in).
    // Each is safe (`safe_run_with_gap_rule` asserts no contact); turning into the crop is not.
    let o = safe_run_with_gap_rule(646, "young soybean 13.9 m x 7 rows 0.76 m apart");
    let done = (o.end.as_str(), o.lanes_completed) == ("done", 2);
    let stopped = ["stopped: crop_past_row_end", "stopped: rows_lost"].contains(&o.end.as_str());
    assert!(done || stopped, "{o:?}");
}

#[test]
fn a_row_end_that_recedes_with_a_tilted_lidar_stops_the_robot() {
    // Young soybean, the LiDAR mount off by (1.8, -0.8, -2.3)°, the detector's levelling off: past the
    // crop the ground read as canopy, the row end stayed 2-3 m ahead of the robot wherever it went,
    // and the robot followed phantom rows round a 14 m circle outside the field for 80 m, then turned
    // into the crop (12 plants). Now an end that moves away more than 2 m past where it was first seen
    // stops it.
    // The mount's yaw reads as a slide of 0.05-0.08 m/m (the map shears in `odom`): without the
    // lag limit (`lane_switch.max_slide_lag_m`, on by default since session 42) registration
    // corrects it; with it the robot stops `sliding` 1.6 m in, clean.
    let mut case = soak_case(948);
    assert!(case.scenario.summary.starts_with("young soybean 12.5 m x 7 rows 0.75 m apart"));
    case.navigator.detector.level_enabled = false;
    case.navigator.lane_switch.max_slide_lag_m = 0.0;
    let o = run_case(&case).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    assert_eq!(o.end, "stopped: row_end_receding", "{o:?}");
    assert!(o.distance_m < 13.0, "{o:?}");
}

#[test]
fn a_tilted_lidar_levelled_by_the_detector_ends_its_lanes_at_the_row_ends() {
    // The same field with the detector's levelling on (the default): the ground past the rows stays
    // ground, and both lanes end where the rows do. Without the lag limit, as above: with it the
    // robot stops `sliding` 3.7 m in, clean.
    let o = safe_run_with(948, "young soybean 12.5 m x 7 rows 0.75 m apart", |c| {
        c.navigator.lane_switch.max_slide_lag_m = 0.0
    });
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
    let o = safe_run(948, "young soybean 12.5 m x 7 rows 0.75 m apart");
    assert_eq!(o.end.as_str(), "stopped: sliding", "{o:?}");
}

#[test]
fn a_gyro_bias_step_while_following_is_learnt_before_the_turn() {
    // Young corn, +0.021 rad/s from x 3.9 m, the turn 20 s later: the pivots came out 0.3 rad off and
    // the entry ran over 2 plants (then `wrong_lane`). With the detector's shear term the moving
    // blocks never found the step (5 plants at the turn): the rows turned in `odom` at 0.04 rad/m,
    // so the robot stood 1.5 s at the row end and the EKF found it at rest (0.0266 against 0.026).
    // With the slide test (the default) the step reads as slides of -0.06 to -0.12 m/m over 11-23 s,
    // the fit straightens and the rows' turn in `odom` falls under `bias_suspect_rad_per_m` 2 m
    // before the row end: the suspicion, held 5 m in mid-lane, still decides the stand (4 plants at
    // the turn without it).
    let o = safe_run_past_a_gyro_step(699, "young corn 12.2 m x 4 rows 0.74 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_large_gyro_bias_step_near_the_row_end_is_learnt_at_rest() {
    // Young corn, curved, +0.027 rad/s from x 7.3 m, 6 m before the row end: too late for the moving
    // blocks; the turn came back 0.3 rad crooked over the next lane (9 plants).
    let o = safe_run_past_a_gyro_step(978, "young corn 13.8 m x 8 rows 0.78 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_small_gyro_bias_step_is_learnt_at_rest_before_the_turn() {
    // Young corn, curved, -0.011 rad/s from x 2.2 m: under what the moving blocks can find; its
    // turn ran over a plant (then `wrong_lane`). At rest it is 5 σ of a rest block.
    let o = safe_run(221, "young corn 12.5 m x 10 rows 0.79 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_large_gyro_bias_step_under_odometry_jitter_is_learnt_before_the_turn() {
    // Young corn, +0.026 rad/s from x 2.4 m with stamp jitter and wheel messages out of order (the
    // bias check pairs each wheel sample with the latest gyro sample): 1 plant run over.
    let o = safe_run_past_a_gyro_step(137, "young corn 12.6 m x 4 rows 0.73 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}

#[test]
fn a_gyro_bias_step_before_a_stop_is_learnt_at_the_stop() {
    // Young corn, a -0.018 rad/s gyro step at x 5.5 m, then scans stamped 0.75 s off over x 7-8 m: a
    // `no_rows` stop at x 7.9 m. It stood 0.7 s and followed again with the step unfound (the
    // refitted rows turned in `odom` under the suspicion's rate, so no stand at the row end); the
    // pivots turned 0.37 rad off and the entry ran over 2 plants (`wrong_lane`). The rows had turned
    // 0.0069 rad/m before the stop, so it now stands `lane_switch.resume_rest_s` (1.5 s) and the
    // EKF's rest check finds the step (with `resume_rest_s = 0`: 2 plants again).
    let o = safe_run_past_a_gyro_step(664, "young corn 13.0 m x 6 rows 0.78 m apart");
    assert_eq!((o.end.as_str(), o.lanes_completed), ("done", 2), "{o:?}");
}
