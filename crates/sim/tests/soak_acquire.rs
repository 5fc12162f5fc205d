//! Grown crops that the detector once never acquired (issue 6): under a closed canopy the canopy's
//! density crests twice per row spacing, the start-up search locked on about half the spacing, and
//! the lane switcher (rightly) refused those rows, so the robot stood at the start until the soak gave
//! up. Each test is named after what it guards; a seed names the field `soak_case` draws for it (the
//! summary check catches a generator that changed).

use croprow_core::control::lane_switch::Mode;
use croprow_sim::closed_loop::{ClosedLoop, RunConfig, sim_navigator};
use croprow_sim::experiment::soak::{Outcome, run_case, soak_case};
use croprow_sim::field::Stage;
use croprow_sim::{FaultConfig, Scenario};

/// Runs the soak case of `seed` (whose summary starts with `summary`) without faults: it must be
/// acquired, drive at least `lanes` lanes, and touch no plant.
fn acquired_run(seed: u64, summary: &str, lanes: u32) -> Outcome {
    let mut case = soak_case(seed);
    assert!(case.scenario.summary.starts_with(summary), "{}", case.scenario.summary);
    case.scenario.faults = FaultConfig::default();
    case.run.lidar_blackout_after_m = None;
    let outcome = run_case(&case).expect("runs");
    assert_ne!(outcome.end, "never acquired", "{outcome:?}");
    assert!(outcome.lanes_completed >= lanes, "{outcome:?}");
    assert_eq!((outcome.crop_contacts, outcome.unsafe_commands), (0, 0), "{outcome:?}");
    outcome
}

#[test]
fn grown_corn_half_period_canopy_is_acquired_and_driven() {
    // 14 rows 0.70 m apart: the canopy density repeats about every 0.35 m.
    let outcome = acquired_run(37, "grown corn 10.0 m x 14 rows 0.70 m", 2);
    assert_eq!(outcome.end, "done", "{outcome:?}");
}

/// The ends a grown-crop run may have once acquired: done, or the safe stop before an unconfirmed
/// lane. Re-entering a closed canopy is not always confirmed from the headland (the front tyres wait
/// at the row ends until the detector agrees with the planned lane), a known gap in the README.
const DONE_OR_SAFE_REENTRY_STOP: [&str; 2] = ["done", "stopped: reentry_not_confirmed"];

#[test]
fn grown_corn_in_a_five_row_curved_field_is_acquired_and_driven() {
    // Five rows, so at most five in view, on a gentle curve.
    let outcome = acquired_run(46, "grown corn 12.9 m x 5 rows 0.75 m apart, curve 0.35 m", 1);
    assert!(DONE_OR_SAFE_REENTRY_STOP.contains(&outcome.end.as_str()), "{outcome:?}");
}

#[test]
fn grown_soybean_half_period_canopy_is_acquired_and_driven() {
    // 12 rows 0.71 m apart: the search said 0.36 m and the lane centre sat on a row.
    let outcome = acquired_run(11, "grown soybean 11.5 m x 12 rows 0.71 m", 2);
    assert!(DONE_OR_SAFE_REENTRY_STOP.contains(&outcome.end.as_str()), "{outcome:?}");
}

#[test]
fn grown_corn_in_the_edge_lane_is_acquired() {
    // Lane 0: one row on the right, then bare ground; the search said 0.31 m.
    acquired_run(27, "grown corn 11.8 m x 8 rows 0.75 m", 1);
}

#[test]
fn full_field_grown_corn_is_acquired() {
    // The full-field scenario with grown corn never left `acquiring`; it must follow within a few
    // seconds of the standstill and then report the field's spacing (0.75 m) within 5 cm.
    let mut s = Scenario::builtin("full-field").expect("built in");
    s.field.stage = Stage::Grown;
    let run = RunConfig { lanes: 1, ..RunConfig::default() };
    let acquire_by_s = run.standstill_s + 5.0;
    let mut lp = ClosedLoop::new(&s, &sim_navigator(), run).expect("valid");
    while lp.progress().mode == Mode::Acquiring && lp.world().time_s() < acquire_by_s {
        lp.step().expect("steps");
    }
    assert_eq!(lp.progress().mode, Mode::Following, "at {:.1} s", lp.world().time_s());
    let drive_until_s = lp.world().time_s() + 5.0;
    let mut spacing = None;
    while lp.world().time_s() < drive_until_s {
        lp.step().expect("steps");
        let detection = lp.last_tick().and_then(|t| t.nav).and_then(|n| n.detection);
        spacing = detection.and_then(|d| d.row_spacing_m).or(spacing);
    }
    assert_eq!(lp.progress().mode, Mode::Following);
    assert_eq!(lp.world().crop_contacts(), 0);
    let spacing = spacing.expect("a spacing");
    assert!((spacing - 0.75).abs() < 0.05, "{spacing}");
}
