//! Soak seeds (issue 6) whose row fit was pulled by canopy that is not a row seen through the edge of a
//! row's gate: tall weed clumps between the rows, and the outer leaves of a field's last row; and by
//! returns that are not canopy at all, dust and insects floating above a young crop. Each test
//! replays the seed's case as `soak_case` draws it, faults included, and asserts no crop contact and no
//! unsafe command, and that the same case with every bin kept still touches plants; the summary check
//! catches a generator that changed. Guards
//! `DetectorConfig::core_fraction` (the detector leaves out bins whose canopy peaks outside the gate),
//! opt-in (off by default, see its doc): the guarded run sets it to 0.1; and the clutter test of the
//! preprocessing (`DetectorConfig::clutter_min_points`, on by default).

use croprow_sim::experiment::soak::{Case, Outcome, run_case, soak_case};

/// Runs the soak case of `seed` (whose summary starts with `summary`) once with `unguard` applied (it
/// must touch plants, as it did) and once with `guard` applied; returns the guarded outcome.
fn run_guarded(seed: u64, summary: &str, unguard: impl Fn(&mut Case), guard: impl Fn(&mut Case)) -> Outcome {
    let case = soak_case(seed);
    assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
    let mut unguarded = case.clone();
    unguard(&mut unguarded);
    let before = run_case(&unguarded).expect("runs");
    assert!(before.crop_contacts > 0, "the case no longer provokes the failure: {before:?}");
    let mut guarded = case;
    guard(&mut guarded);
    run_case(&guarded).expect("runs")
}

#[test]
fn a_fault_free_grown_soybean_field_edge_is_not_run_over() {
    // Fault-free grown soybean, 4 rows: in the 1000-run soak, re-entering the field after the first
    // headland turn, the lattice predicted a row beyond the field's last one, took that row's outer
    // leaves for it and shrank the spacing from 0.74 m to 0.54 m; the robot followed the shrunken
    // lattice onto a row (2 contacts). `core_fraction` = 0.1 fixed it; since the scan is levelled and the
    // fit models shear, the defaults (every bin kept) stop safely at re-entry instead (`no_rows`, measured).
    let case = soak_case(119);
    assert!(
        case.scenario.summary.starts_with("grown soybean 14.8 m x 4 rows 0.74 m"),
        "{}",
        case.scenario.summary
    );
    let o = run_case(&case).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
}

#[test]
fn tall_weeds_in_view_after_a_headland_turn_do_not_pull_the_fit() {
    // Young corn with 0.5 m weeds (taller than the crop) over x = 7-9.3 m: re-acquired after the
    // first turn with the patch in view, the fit took the weed clumps reaching into the rows' gates
    // and turned 6-10° off the rows (6 contacts). Both runs go without the entry's heading watch
    // (`lane_switch.entry_heading_watch_m`, on by default since session 31), which stops this robot
    // first, 0.1 m after the lane is confirmed, rows 0.15 rad off the lane before (asserted below).
    let unwatched = |c: &mut Case, core_fraction| {
        c.navigator.detector.core_fraction = core_fraction;
        c.navigator.lane_switch.entry_heading_watch_m = 0.0;
    };
    let summary = "young corn 10.2 m x 7 rows 0.78 m";
    let o = run_guarded(50, summary, |c| unwatched(c, 0.0), |c| unwatched(c, 0.1));
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    let o = run_case(&soak_case(50)).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    assert_eq!(o.end, "stopped: wrong_lane", "{o:?}");
}

#[test]
fn dust_over_a_young_crop_does_not_lift_the_canopy_plane() {
    // Young corn with 585 spurious returns a scan 0.8-1.4 m up over x = 4.6-7.2 m: 6 % of the cropped
    // returns, so the 95th height percentile jumped from the crop's tops (0.3 m) into the dust
    // (0.9 m), the canopy plane rose over the crop and the fit followed the dust (8 contacts, second
    // lane). The clutter test drops returns alone in their voxel before the plane is placed.
    // The guarded run is the defaults (`clutter_min_points` 3), both runs without canopy
    // registration and with the slide test (`shear_window_m` 0.5), as when this was traced: with
    // registration on (the default), or the slide test off (the default since session 28), the
    // unguarded run spares the plants too (measured).
    // Both also go without the slide stop (on by default since session 30), which stops the robot
    // at the slide the dust reads as.
    let as_traced = |c: &mut Case| {
        c.navigator.detector.register_enabled = false;
        c.navigator.detector.shear_window_m = 0.5;
        c.navigator.lane_switch.max_slide_per_m = 0.0;
    };
    let o = run_guarded(
        148,
        "young corn 13.7 m x 10 rows 0.73 m",
        |c| {
            c.navigator.detector.clutter_min_points = 0;
            as_traced(c);
        },
        as_traced,
    );
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
}

#[test]
fn a_fit_that_turns_onto_tall_weeds_in_a_gap_across_every_row_stops_the_robot() {
    // Grown soybean, every row missing over 3.3 m from x = 4.1 m and 0.24 m weeds over 1.5 m inside
    // the gap: in the 1000-run soak the fit took the weed strip for the lane's rows, turned 0.14 rad
    // within a metre and led the robot over 3 plants in its third lane. Rows that turn in `odom` by
    // more than `lane_switch.max_row_turn_rad` (0.1 rad) within a metre stop the robot (`wrong_lane`):
    // here in the first lane, its true heading already 0.13 rad off the rows, before the gap.
    let summary = "grown soybean 11.3 m x 7 rows 0.78 m";
    let o = run_guarded(680, summary, |c| c.navigator.lane_switch.max_row_turn_rad = 0.0, |_| ());
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    assert_eq!(o.end, "stopped: wrong_lane", "{o:?}");
}
