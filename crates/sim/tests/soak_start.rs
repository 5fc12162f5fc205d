//! Soak seeds whose robot ran over plants within its first 1.5 m (issue 6): the start-up search of
//! the detector locked onto something that was not the crop's lattice and the robot followed it. Each
//! test replays the seed's case as `soak_case` draws it, faults included, and asserts no contact.
//! The summary check catches a generator that changed.

use croprow_sim::experiment::soak::{Case, Outcome, run_case, soak_case};

fn run_seed(seed: u64, summary: &str) -> Outcome {
    run_seed_with(seed, summary, |_| {})
}

/// As [`run_seed`], with the detector told the field's planted spacing (`detector.planted_spacing_m`,
/// opt-in: on by default it cost more plants on the 1000-run soak than it saved, see docs/faults.md).
fn run_planted(seed: u64, summary: &str) -> Outcome {
    run_seed_with(seed, summary, |c| c.navigator.detector.planted_spacing_m = c.scenario.field.row_spacing_m)
}

/// As [`run_seed`], with `configure` applied to the case first.
fn run_seed_with(seed: u64, summary: &str, configure: impl FnOnce(&mut Case)) -> Outcome {
    let mut case = soak_case(seed);
    assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
    configure(&mut case);
    run_case(&case).expect("runs")
}

#[test]
fn closed_canopy_start_does_not_take_the_edge_of_the_heading_search() {
    // Grown soybean: no heading is sharper than another, and 20° (the edge) won by noise.
    let o = run_seed(92, "grown soybean 13.6 m x 5 rows 0.71 m");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
}

#[test]
fn spurious_returns_above_the_canopy_do_not_turn_the_start_heading() {
    // Young corn with 56 returns per scan 0.8-1.4 m up: their height-squared weight turned the heading 10°.
    let o = run_seed(561, "young corn 14.7 m x 7 rows 0.76 m");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
}

#[test]
fn a_grown_canopy_start_takes_the_planted_spacing_not_twice_it() {
    // Grown corn 0.71 m apart under odometry jitter: the ground, seen mostly in the robot's own
    // inter-row, read as repeating every second row; the search took two crests per row (1.38 m), the
    // fit wandered at rest to 0.85 m and 19° and the lane switcher drove along it (24 plants).
    let o = run_planted(439, "grown corn 14.2 m x 6 rows 0.71 m");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
}

#[test]
fn a_grown_soybean_start_waits_for_the_planted_spacing() {
    // Grown soybean 0.73 m apart: the search took 1.5 m, the fit wandered at rest 20° off to 0.9 m
    // (within the lane switcher's 25 %) and the robot drove along it (7 plants).
    let o = run_planted(982, "grown soybean 11.9 m x 9 rows 0.73 m");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
}

#[test]
fn a_grown_corn_start_with_the_planted_spacing_stands_in_the_inter_row() {
    // Fault-free grown corn 0.70 m apart: of the gaps between the canopy's two crests per row, the
    // start-up search took one 0.2 m off the envelope's lane and the fit swung 13° before it settled
    // (1 plant at 0.69 m); the ground now settles which gap is the lane's. With canopy registration
    // (on by default) the start is the same, but the second lane's re-entry is not confirmed and the
    // robot stops there safely (measured: its registered lanes move against the turn's `odom` plan);
    // the mission is asserted whole without it.
    let o = run_planted(37, "grown corn 10.0 m x 14 rows 0.70 m");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    let mut case = soak_case(37);
    case.navigator.detector.planted_spacing_m = case.scenario.field.row_spacing_m;
    case.navigator.detector.register_enabled = false;
    let o = run_case(&case).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands, o.end.as_str()), (0, 0, "done"), "{o:?}");
}

#[test]
fn a_closed_canopy_fit_at_twice_the_spacing_is_searched_again_not_followed() {
    // The same start as above with the defaults (no planted spacing for the detector): the lane
    // switcher, which knows the field's spacing, resets the detector while its lattice is 1.38 m
    // instead of letting the fit wander into its 25 % band (20 plants); a fresh search starts on the
    // crop's lattice and the mission is done.
    let o = run_seed(439, "grown corn 14.2 m x 6 rows 0.71 m");
    assert_eq!((o.crop_contacts, o.unsafe_commands, o.end.as_str()), (0, 0, "done"), "{o:?}");
}

#[test]
fn a_start_lane_far_off_the_robot_heading_is_not_followed() {
    // Young corn with every row missing 2.9-6.5 m: a metre of row in view, the search's lane 26° off
    // the robot, which turned onto it (6 plants at 0.2 m). Over `max_start_heading_rad` (0.2 rad) the
    // robot waits for a better lane instead (here, none comes: it never starts).
    let mut case = soak_case(337);
    assert!(
        case.scenario.summary.starts_with("young corn 12.0 m x 6 rows 0.76 m"),
        "{}",
        case.scenario.summary
    );
    let o = run_case(&case).expect("runs");
    assert_eq!((o.crop_contacts, o.unsafe_commands), (0, 0), "{o:?}");
    case.navigator.lane_switch.max_start_heading_rad = 1.0;
    let before = run_case(&case).expect("runs");
    assert!(before.crop_contacts > 0, "the case no longer provokes the failure: {before:?}");
}

#[test]
fn a_robot_set_down_among_tall_weeds_waits_for_rows_that_run_along_the_view() {
    // Young corn set down before a patch of weeds taller than the crop in every inter-row: the
    // search took a lattice of weeds and crop (451: half a spacing off, 4 plants; 1951: its lane
    // centre 0.45 spacings off, on a row, 9-11 plants). Over bare ground the canopy of the first 3 m
    // ahead must now run along the lattice's rows (`detector.start_row_contrast`); along these
    // lattices' rows it does not (their first searches read -0.26 to -0.11), and the robot never
    // starts.
    for (seed, summary) in
        [(451, "young corn 13.1 m x 7 rows 0.70 m"), (1951, "young corn 12.6 m x 6 rows 0.77 m")]
    {
        let mut case = soak_case(seed);
        assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
        let o = run_case(&case).expect("runs");
        assert_eq!((o.crop_contacts, o.unsafe_commands, o.end.as_str()), (0, 0, "never acquired"), "{o:?}");
        case.navigator.detector.start_row_contrast = 0.0;
        let before = run_case(&case).expect("runs");
        assert!(before.crop_contacts > 0, "seed {seed} no longer provokes the failure: {before:?}");
    }
}

#[test]
fn a_grown_corn_lane_with_two_crests_per_row_is_centred_on_the_middle_crest() {
    // Fault-free grown corn 0.73 m apart: the plant tops crest over the rows and the arching leaves
    // meet in a second crest over the middle of each inter-row. The search took the gap between
    // crests nearest the robot for the lane centre, a quarter spacing off, and the robot followed the
    // first lane 13-23 cm off its centre line (1 plant); the envelope's rise over the rows now puts
    // the centre on the middle crest.
    // The first lane only: with the slide watch (`detector.register_rest_watch`, the default since
    // session 42) a false slide of 0.03 m/m for 0.2 s sends the robot on a path that stands at the
    // row end and stops, clean, at the next lane's entry (`wrong_lane`).
    let o = run_seed_with(1390, "grown corn 10.7 m x 8 rows 0.73 m", |c| c.run.lanes = 1);
    assert_eq!((o.crop_contacts, o.unsafe_commands, o.end.as_str()), (0, 0, "done"), "{o:?}");
}
