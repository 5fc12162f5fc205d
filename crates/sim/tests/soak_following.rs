//! Soak seeds whose robot ran over plants while following a lane (the 1000-run soak, issue 6), each
//! kept as a regression named after what it guards. Each case is the seed's field, mission and faults
//! as `soak_case` draws them, cut to its first lane (where the contacts began); it runs once with the
//! guard under test off, where it must still run over plants (so the test can fail), and once with it
//! on, where it must not. The guard is the drift estimator (`drift.enabled`, off by default; see
//! `croprow_core::odometry::DriftConfig::enabled`), or the detector's shear term (`detector.shear_enabled`,
//! on by default: the lane fit models the map's unsensed sideways motion; off for the run that must
//! still fail), or the detector's slide test with the MPC planning from the course over the ground
//! (`detector.shear_window_m` 0.5 and `shear_max_per_m` 0.12, the defaults when these were built,
//! opt-in since session 28; the run that must still fail has it off: window 0, the shear term's bound
//! 0.2). Every case here runs with the slide test on unless it says otherwise, as it was traced. Seed
//! 530 is the exception: the defaults (the detector ignoring returns above the canopy, the EKF's bias
//! check) now drive it clean without it.

use croprow_sim::Scenario;
use croprow_sim::closed_loop::{self, ClosedLoop, RunConfig};
use croprow_sim::experiment::soak::{Case, Outcome, run_case, soak_case};

/// The soak case of `seed` with the slide test on (`shear_window_m` 0.5), as these seeds were traced.
fn with_slide_test(seed: u64) -> Case {
    let mut case = soak_case(seed);
    case.navigator.detector.shear_window_m = 0.5;
    case
}

/// The first lane of soak case `seed`, whose summary starts with `summary` (a check that the generator
/// still draws the same case), with the slide test on and canopy registration off: the guards here
/// were built before it was on by default, and it drives most of these seeds clean on its own
/// (`canopy_registration_alone_drives_the_slide_and_gyro_seeds_clean`), so with it on the runs that
/// must fail would not.
fn first_lane(seed: u64, summary: &str) -> Case {
    let mut case = with_slide_test(seed);
    assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
    case.run.lanes = 1;
    case.navigator.detector.register_enabled = false;
    case
}

#[test]
fn canopy_registration_alone_drives_the_slide_and_gyro_seeds_clean() {
    // The first lanes of the seeds below run over plants with every guard of this file off (the
    // slide test, the shear term, the drift estimator; 725 unlevelled, as in its own test); canopy
    // registration (on by default) measures their drift from the canopy and drives them clean alone.
    let seeds = [
        (234, "grown soybean 11.7 m"),
        (744, "young corn 10.7 m"),
        (152, "young soybean 10.7 m"),
        (187, "young soybean 12.6 m"),
        (549, "young corn 13.6 m"),
        (725, "grown corn 13.7 m"),
    ];
    for (seed, summary) in seeds {
        let mut case = without_slide_test(&first_lane(seed, summary));
        case.navigator.detector.shear_enabled = false;
        case.navigator.detector.level_enabled = seed != 725;
        let before = run_case(&case).expect("runs");
        assert!(before.crop_contacts > 0, "seed {seed} no longer provokes the failure: {before:?}");
        case.navigator.detector.register_enabled = true;
        let o = run_case(&case).expect("runs");
        assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "seed {seed}: {o:?}");
    }
}

/// Runs `case` with the drift estimator on or off.
fn run_with_drift(case: &Case, enabled: bool) -> Outcome {
    let mut case = case.clone();
    case.navigator.drift.enabled = enabled;
    run_case(&case).expect("runs")
}

/// `case` with the slide test off: the shear term alone, as before the test was on by default.
fn without_slide_test(case: &Case) -> Case {
    let mut off = case.clone();
    off.navigator.detector.shear_window_m = 0.0;
    off.navigator.detector.shear_max_per_m = 0.2;
    off
}

/// Runs `case` with the slide test off (it must run over plants) and on, as `case` has it (it must
/// not).
fn safe_with_slide_test(case: &Case) -> Outcome {
    let before = run_case(&without_slide_test(case)).expect("runs");
    assert!(before.crop_contacts > 0, "the case no longer provokes the failure: {before:?}");
    let outcome = run_case(case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    outcome
}

#[test]
fn a_slide_under_a_grown_soybean_canopy_is_found_and_steered_out() {
    // Grown soybean, slip 37 % with 0.07 m/s drift to the left over x 5.4-7.8 m: the shear term alone
    // lagged the slide's start and the MPC, told the heading and not the course, held the crab angle
    // 20 cm off the centre line.
    safe_with_slide_test(&first_lane(234, "grown soybean 11.7 m x 7 rows 0.73 m apart"));
}

#[test]
fn a_slide_on_young_corn_is_found_and_steered_out() {
    // Young corn, slip 27 % with 0.07 m/s drift to the left over x 4.8-7.1 m: 21 plants over the
    // whole soak run with the defaults.
    safe_with_slide_test(&first_lane(744, "young corn 10.7 m x 7 rows 0.72 m apart"));
}

/// Runs `case` with the detector's shear term off (it must run over plants) and on, as the shear term
/// alone (the slide test off), where it must not.
fn safe_with_shear(case: &Case) -> Outcome {
    let case = without_slide_test(case);
    let mut off = case.clone();
    off.navigator.detector.shear_enabled = false;
    let before = run_case(&off).expect("runs");
    assert!(before.crop_contacts > 0, "the case no longer provokes the failure: {before:?}");
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    outcome
}

#[test]
fn a_slide_on_young_soybean_is_taken_out_of_the_lane_fit() {
    // Young soybean on a curved lane, slip with a sideways slide: the shear term keeps the lane where
    // the rows are now.
    safe_with_shear(&first_lane(152, "young soybean 10.7 m x 9 rows 0.70 m apart"));
}

#[test]
fn a_late_slide_on_young_soybean_is_taken_out_of_the_lane_fit() {
    safe_with_shear(&first_lane(187, "young soybean 12.6 m x 7 rows 0.71 m apart"));
}

/// Runs `case` with the slide test off (the estimator was built beside the shear term alone), without
/// the drift estimator (it must run over plants) and with it (it must not).
fn safe_with_drift_estimate(case: &Case) -> Outcome {
    let case = &without_slide_test(case);
    let before = run_with_drift(case, false);
    assert!(before.crop_contacts > 0, "the case no longer provokes the failure: {before:?}");
    let outcome = run_with_drift(case, true);
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    outcome
}

#[test]
fn a_sideways_slide_does_not_bend_the_rows_onto_the_tyres() {
    // Young soybean, slip patch 20 % with 0.07 m/s drift to the right from x 3.7 m: the detector's
    // map sheared, the centre line pivoted about 3 m ahead and the robot, believing itself centred,
    // ran over 37 plants.
    safe_with_drift_estimate(&first_lane(100, "young soybean 14.5 m x 7 rows 0.75 m apart"));
}

#[test]
fn a_strong_slide_among_tall_weeds_runs_over_far_fewer_plants() {
    // Young soybean, slip 35 % with 0.07 m/s drift to the right over 4.8 m and a patch of 0.47 m
    // tall weeds: 72 plants run over (37 on this first lane). The windowed estimator learns too slowly for
    // this one and still runs over 8 (at most a quarter is asserted; the previous one-baseline estimator ran over none, but it cost
    // the recovery lane): a known gap, guarded here against getting worse.
    let case = first_lane(910, "young soybean 13.6 m x 9 rows 0.78 m apart");
    let mut off = case.clone();
    off.navigator.detector.shear_enabled = false;
    let before = run_with_drift(&off, false);
    let after = run_with_drift(&case, true);
    assert!(
        after.crop_contacts * 4 <= before.crop_contacts,
        "{} -> {}",
        before.crop_contacts,
        after.crop_contacts
    );
    assert_eq!(after.unsafe_commands, 0);
}

#[test]
fn a_slide_on_a_curved_lane_does_not_bend_the_rows_onto_the_tyres() {
    // Young corn on a gently curved lane, slip 33 % with 0.07 m/s drift to the right: 43 plants.
    safe_with_drift_estimate(&first_lane(549, "young corn 13.6 m x 7 rows 0.76 m apart"));
}

#[test]
fn a_gyro_bias_step_does_not_lead_the_robot_onto_a_row() {
    // Grown corn on a curved lane with relief, an unlearned gyro bias step of 0.025 rad/s at x 7.7 m:
    // the map turned under the detector and 11 plants were run over. (Seed 180, the first case kept
    // here, is no longer acquired since the closed-canopy spacing search changed; see soak_acquire.)
    // With the shear term on (the default) it is driven clean without the drift estimator. With the
    // detector's levelling on, the shear-off run happens to spare the plants as well (measured, cause not
    // traced), so the run that must still fail leaves the scan unlevelled too.
    let case = first_lane(725, "grown corn 13.7 m x 9 rows 0.77 m apart, curve 0.68 m");
    let mut unlevelled = case.clone();
    unlevelled.navigator.detector.level_enabled = false;
    safe_with_shear(&unlevelled);
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
}

#[test]
fn a_slide_in_a_closed_soybean_canopy_does_not_bend_the_rows_onto_the_tyres() {
    // Grown soybean (the closed canopy whose fit noise the estimator must not take for a slide), slip
    // 31 % with 0.05 m/s drift to the left: 3 plants run over 4.6 m into the lane.
    safe_with_drift_estimate(&first_lane(13, "grown soybean 14.6 m x 5 rows 0.78 m apart"));
}

#[test]
fn a_gyro_bias_step_among_spurious_returns_does_not_lead_the_robot_onto_a_row() {
    // Grown corn with 514 spurious returns per scan and a gyro bias step: 12 plants run over while
    // following. The detector no longer counts returns floating above the canopy as canopy and the
    // EKF's bias check relearns the bias; with the defaults, and with the drift estimator on too, the
    // lane is driven clean (it now is even with the bias check off).
    let case = first_lane(530, "grown corn 11.9 m x 8 rows 0.72 m apart");
    for drift in [false, true] {
        let o = run_with_drift(&case, drift);
        assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "drift {drift}: {o:?}");
    }
}

#[test]
fn a_tall_weed_patch_is_no_slide_for_the_slide_test() {
    // `fault-weed-patch` (clumps 0.25-0.5 m tall in every inter-row over x = 8-11 m) with the slide
    // test on: one offset and heading fitted to all rows read it as a slide of 0.04-0.06 m/m on 160
    // scans and steered the robot off the line (over that lane's 3 cm bound); fitted per row, with
    // both sides of the robot required to agree, it never declares one, and the lane is tracked as
    // with the test off (< 1 cm mean, < 3 cm max).
    let text = include_str!("../scenarios/fault-weed-patch.toml");
    let scenario = Scenario::from_toml_str(text).expect("parses");
    let nav = closed_loop::sim_navigator();
    let mut lp =
        ClosedLoop::new(&scenario, &nav, RunConfig { lanes: 1, ..RunConfig::default() }).expect("builds");
    let mut declared = 0;
    while !lp.is_finished() {
        lp.step().expect("steps");
        declared += usize::from(lp.navigator().detector().slide_per_m().is_some());
    }
    let m = lp.finish().metrics;
    assert_eq!(declared, 0, "scans with a slide declared");
    assert_eq!((m.crop_contacts, m.command_violations), (0, 0), "{m:?}");
    assert!(m.cross_track_mean_m < 0.01 && m.cross_track_max_m < 0.03, "{m:?}");
}

#[test]
fn a_fault_free_grown_corn_field_has_no_false_slide() {
    // Fault-free grown corn, three lanes (soak seed 765), with the slide test on. Its comparisons
    // scatter about none by ±0.02 m/m here; 1.8 m into the first lane they read 0.045 for half a
    // metre, and the slide so declared was applied to every stored centroid by its age: the lane
    // jumped 8 cm, the robot swung 0.19 rad after it and the run ended `wrong_lane` over 22 plants. A
    // declared slide now moves the centroids only by the distance driven since it began.
    // With the slide test off (the default since session 28) this run touched 13 plants for another
    // reason, guarded since session 31 by
    // `a_lane_entered_on_a_fit_that_turns_off_the_planned_direction_is_searched_again`.
    let case = with_slide_test(765);
    assert!(case.scenario.summary.starts_with("grown corn 11.5 m x 8 rows 0.71 m apart"));
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
}

#[test]
fn a_slide_too_strong_to_crab_against_in_a_narrow_lane_stops_the_robot() {
    // Grown soybean 0.70 m apart, slip 29 % with 0.07 m/s drift to the left from the start (0.2 m per
    // metre driven): to hold the line the body must point 11° into the slide, which swings its corner
    // tyres 12 cm across the rows. The MPC placed the tyres by the course over the ground and ran
    // over 9 plants; placing them by the body it finds no way on that keeps them off the rows and
    // plans no motion, and the navigator stops the robot and says why instead of standing still
    // while "following". With the slide test off (the default since session 28) the robot takes 3
    // plants before it stops the same way (`no_safe_motion`, measured).
    // Without the slide stop (`lane_switch.max_slide_per_m`, on by default since session 30): it stops
    // the robot first, 1.5 m in, clean
    // (`soak_follow_faults.rs` guards it).
    // And without the slide watch (`detector.register_rest_watch`, the default since session 42):
    // it reads the slide from the first keyframe, the MPC crabs against it from the first metre,
    // before the robot is off the line, and drives the lane clean.
    let mut watched = with_slide_test(350);
    assert!(watched.scenario.summary.starts_with("grown soybean 13.7 m x 10 rows 0.70 m apart"));
    watched.run.lanes = 1;
    watched.navigator.lane_switch.max_slide_per_m = 0.0;
    let mut case = watched.clone();
    case.navigator.detector.register_rest_watch = false;
    let o = run_case(&case).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    assert_eq!(o.end, "stopped: no_safe_motion", "{o:?}");
    let o = run_case(&watched).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands, o.end.as_str()), (0, 0, "done"), "{o:?}");
}

#[test]
fn a_lane_entered_on_a_fit_that_turns_off_the_planned_direction_is_searched_again() {
    // Fault-free grown corn (soak seed 765): entering the second lane, the fit in the closed canopy
    // turned scan by scan, each scan within the entry's tolerance of the last, to 0.18 rad off the
    // rows by the first scan followed, and the robot followed it across two rows (13 plants,
    // `wrong_lane`). Held to the planned direction (`lane_switch.entry_heading_watch_m`), the
    // entry asks the detector to search again and the robot drives all three lanes clean.
    // The provoking run and the held one compare every band of the canopy registration, as before
    // session 38: leaving out the bands past the row end (the default since) the robot reaches that
    // entry on another path and drives the field clean without the watch too. The slide watch
    // (`detector.register_rest_watch`, the default since session 42) sends it on another path as
    // well, so both runs go without it.
    let defaults = soak_case(765);
    assert!(defaults.scenario.summary.starts_with("grown corn 11.5 m x 8 rows 0.71 m apart"));
    let mut held = defaults.clone();
    held.navigator.detector.register_before_row_end = false;
    held.navigator.detector.register_rest_watch = false;
    let mut unheld = held.clone();
    unheld.navigator.lane_switch.entry_heading_watch_m = 0.0;
    let before = run_case(&unheld).expect("runs");
    assert!(before.crop_contacts > 0, "the case no longer provokes the failure: {before:?}");
    for case in [held, defaults] {
        let o = run_case(&case).expect("runs");
        assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
        assert_eq!(o.end, "done", "{o:?}");
    }
}
