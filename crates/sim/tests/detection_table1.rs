//! Table I detection on short runs of the five simulated fields (issue 3): over 20 m of a human-like
//! wander with EKF odometry, the DEFAULT detector stays within the paper's published detection errors
//! for that field (mean distance and mean angle) and never picks the wrong row; the paper mode runs on
//! the same scans (its numbers are reported by `croprow detect-sim`, not asserted here).

use croprow_core::{DetectorConfig, DetectorMode};
use croprow_sim::Scenario;
use croprow_sim::experiment::detection::{published, run_detection};

/// A 20 m run is about 250 scans: long enough for weeds, a gap and the row end, short enough for a test.
const LENGTH_M: f64 = 20.0;

fn default_detector_is_within_table_1(name: &str) {
    let scenario = Scenario::builtin(name).expect("built-in scenario");
    let modes = [DetectorConfig::default(), DetectorConfig::paper()];
    let report = run_detection(&scenario, LENGTH_M, &modes, &mut |_| {}).expect("valid run");
    let paper = published(name).expect("published Table I numbers");
    let [default, paper_mode] = report.modes.as_slice() else { panic!("two modes: {report:?}") };
    assert_eq!((default.mode, paper_mode.mode), (DetectorMode::Default, DetectorMode::Paper));
    // Both modes saw every scan of the rows (20 m at 0.8 m/s, 10 Hz: ~250).
    assert!(default.scans > 200 && paper_mode.scans == default.scans, "{report:?}");
    let acc = default.accuracy();
    eprintln!("{name}: default {acc:?}, paper mode {:?}, published {paper:?}", paper_mode.accuracy());
    assert_eq!(default.wrong_row_picks, 0, "{name}: wrong rows picked");
    assert!(default.distance_cm.count > 2 * 150, "{name}: too few rows scored: {report:?}");
    assert!(acc.dist_cm_mean <= paper.dist_cm_mean, "{name}: distance {acc:?} vs published {paper:?}");
    assert!(acc.ang_deg_mean <= paper.ang_deg_mean, "{name}: angle {acc:?} vs published {paper:?}");
}

#[test]
fn young_corn_within_table_1() {
    default_detector_is_within_table_1("young-corn");
}

#[test]
fn grown_corn_within_table_1() {
    default_detector_is_within_table_1("grown-corn");
}

#[test]
fn young_soybean_within_table_1() {
    default_detector_is_within_table_1("young-soybean");
}

#[test]
fn grown_soybean_within_table_1() {
    default_detector_is_within_table_1("grown-soybean");
}

#[test]
fn curved_corn_within_table_1() {
    default_detector_is_within_table_1("curved-corn");
}
