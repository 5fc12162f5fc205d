//! Soak seeds that once failed (issue 6), each kept as a regression named after what it guards. A
//! seed names the case `soak_case` draws for it; the summary check catches a generator that changed.

use croprow_sim::experiment::soak::{run_case, soak_case};

#[test]
fn half_period_lock_at_the_start_never_drives_into_the_rows() {
    // Grown corn 0.70 m apart: the detector locked on half the row period (rows ~0.35 m apart) from
    // the first scans, steered the robot 0.17 m sideways and ran over 9 plants in the first metre.
    let case = soak_case(8);
    assert!(case.scenario.summary.starts_with("grown corn 13.2 m"), "{}", case.scenario.summary);
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
}

#[test]
fn half_period_lock_after_a_turn_is_not_entered() {
    // Grown soybean: after the second headland turn the detector re-acquired on half the period while
    // still turning, the lane was confirmed on those rows and the robot drifted onto a row (8 plants).
    let case = soak_case(2);
    assert!(case.scenario.summary.starts_with("grown soybean 11.7 m"), "{}", case.scenario.summary);
    let outcome = run_case(&case).expect("runs");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    assert!(outcome.lanes_completed >= 2, "the first two lanes are still driven: {outcome:?}");
}
