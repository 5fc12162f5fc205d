//! Detector accuracy on synthetic VLP-16 scans (ray-cast through the default mount, range noise σ 3 cm,
//! perfect odometry, 10 Hz, 0.1 m per scan). Errors are per scan, for the first row left and right,
//! after 2 m of driving (20 scans) to let the centroid map reach behind the robot.
mod support;

use croprow_core::{DetectorConfig, RowStatus};
use support::{Errors, Field, drive, run};

/// Default-mode tolerances (issue 2): every scan after convergence within 2 cm and 1°.
const OFFSET_TOL_M: f64 = 0.02;
const HEADING_TOL_DEG: f64 = 1.0;
const SKIP: usize = 20;

fn assert_default(name: &str, field: &Field, lateral_m: f64, yaw_deg: f64, x0: f64) -> Errors {
    assert_within(name, field, DetectorConfig::default(), lateral_m, yaw_deg, x0)
}

fn assert_within(
    name: &str,
    field: &Field,
    config: DetectorConfig,
    lateral_m: f64,
    yaw_deg: f64,
    x0: f64,
) -> Errors {
    let poses = drive(field, x0, x0 + 5.0, 0.1, lateral_m, yaw_deg.to_radians());
    let e = run(field, config, &poses, SKIP, 7);
    println!("{name}: {}", e.summary());
    assert_eq!(e.misses, 0, "{name}: {}", e.summary());
    assert!(Errors::max(&e.offset_m) <= OFFSET_TOL_M, "{name}: {}", e.summary());
    assert!(Errors::max(&e.heading_rad).to_degrees() <= HEADING_TOL_DEG, "{name}: {}", e.summary());
    e
}

#[test]
fn straight_rows_off_centre_and_yawed() {
    assert_default("straight", &Field::default(), 0.08, 3.0, 0.0);
}

#[test]
fn young_corn() {
    assert_default("young", &Field::young_corn(), -0.05, -2.0, 0.0);
}

#[test]
fn closed_canopy_hides_the_ground() {
    assert_default("closed", &Field::grown_closed(), 0.05, 1.0, 0.0);
}

#[test]
fn registration_applies_no_drift_from_fewer_than_four_increments() {
    // Perfect odometry under a closed canopy, 5 cm off centre and yawed 1°: the first three
    // registration increments (-3.6, -2.3, -10.8 mm) passed the significance test against a noise
    // estimate made of one difference, a false 1.7 cm correction sheared the map and the rows were
    // 2.8 cm off. No window of fewer than four increments is tested now.
    let config = DetectorConfig { register_enabled: true, ..DetectorConfig::default() };
    assert_within("closed, registered", &Field::grown_closed(), config, 0.05, 1.0, 0.0);
}

#[test]
fn curved_rows_report_their_curvature() {
    // y = 6 sin(2πx/100): around x = 25 m the curvature is -6(2π/100)² ≈ -0.0237 1/m.
    let field = Field { curve_amplitude_m: 6.0, ..Field::default() };
    let e = assert_default("curved", &field, 0.0, 0.0, 22.0);
    let last = e.detections.last().and_then(|d| d.left).expect("tracked");
    assert!((last.curvature_per_m + 0.0237).abs() < 0.01, "{last:?}");
}

#[test]
fn curved_rows_at_their_steepest() {
    // Around x = 0 the rows run at 20.6° to the field's x axis; the robot follows them.
    let field = Field { curve_amplitude_m: 6.0, ..Field::default() };
    assert_default("curved-steep", &field, 0.0, 0.0, -2.0);
}

#[test]
fn gaps_and_weeds_between_rows() {
    let field = Field {
        gaps: vec![(0, 2.5, 4.0), (-1, 4.0, 5.0), (1, 1.0, 3.0)],
        weed_density: 0.3,
        ..Field::default()
    };
    assert_default("gaps+weeds", &field, 0.0, 0.0, 0.0);
}

#[test]
fn a_missing_outer_row_changes_nothing() {
    let field = Field { missing_rows: vec![1], ..Field::default() };
    assert_default("missing-outer", &field, 0.03, 0.0, 0.0);
}

#[test]
fn a_missing_first_row_is_placed_by_its_neighbours() {
    // The first right row is absent: it is inferred one spacing from the next row (5 cm, stated).
    let field = Field { missing_rows: vec![-1], ..Field::default() };
    let poses = drive(&field, 0.0, 5.0, 0.1, 0.0, 0.0);
    let d = run(&field, DetectorConfig::default(), &poses, SKIP, 3).detections;
    let last = d.last().expect("scans");
    let right = last.right.expect("inferred right row");
    assert!((right.offset_m + 0.375).abs() < 0.05, "{right:?}");
    assert!(right.confidence < 0.5, "{right:?}");
    assert!((last.left.expect("left").offset_m - 0.375).abs() < OFFSET_TOL_M);
}

#[test]
fn row_spacing_is_learned_not_configured() {
    let field = Field { spacing_m: 0.95, ..Field::default() };
    let e = assert_default("spacing-0.95", &field, 0.0, 0.0, 0.0);
    let s = e.detections.last().and_then(|d| d.row_spacing_m).expect("spacing");
    assert!((s - 0.95).abs() < 0.04, "{s}");
}

#[test]
fn drifting_odometry_keeps_the_tolerances() {
    // Odometry 3 % long and drifting 0.2°/m in heading (an IMU-aided EKF at 1 m/s with a 0.2°/s gyro
    // bias): the map spans only a few metres, so the drift between its centroids stays small. At 1°/m
    // the offset error grows to about 5 cm (measured): the map then needs better odometry.
    let field = Field::default();
    let poses = drive(&field, 0.0, 5.0, 0.1, 0.04, 1f64.to_radians());
    let odom = support::drifting_odometry(&poses, 0.03, 0.2f64.to_radians());
    let e = support::run_with_odometry(&field, DetectorConfig::default(), &poses, &odom, SKIP, 4);
    println!("drift: {}", e.summary());
    assert_eq!(e.misses, 0);
    // Stated tolerance with drift: mean within 2 cm, every scan within 3 cm (measured max 2.1 cm).
    assert!(Errors::mean(&e.offset_m) <= OFFSET_TOL_M, "{}", e.summary());
    assert!(Errors::max(&e.offset_m) <= 0.03, "{}", e.summary());
    assert!(Errors::max(&e.heading_rad).to_degrees() <= HEADING_TOL_DEG, "{}", e.summary());
}

/// First scan with `EndOfRow`: the robot's x and the reported distance to the row end.
fn end_raised(field: &Field, config: DetectorConfig, x1: f64) -> Option<(f64, Option<f64>)> {
    let poses = drive(field, 0.0, x1, 0.1, 0.0, 0.0);
    let d = run(field, config, &poses, 0, 5).detections;
    d.iter().zip(&poses).find(|(d, _)| d.status == RowStatus::EndOfRow).map(|(d, p)| (p.x, d.row_end_ahead_m))
}

#[test]
fn end_of_row_within_one_metre_of_the_true_end() {
    let field = Field { row_end_x_m: Some(8.0), ..Field::default() };
    let (x, ahead) = end_raised(&field, DetectorConfig::default(), 11.0).expect("EndOfRow raised");
    println!("EndOfRow at x = {x:.2} m, true end 8.0 m, reported {ahead:?} m ahead");
    assert!((x - 8.0).abs() <= 1.0, "{x}");
    // The reported distance matches the true one within 0.5 m (one bin and the last plant's half-length).
    let ahead = ahead.expect("row end distance");
    assert!((ahead - (8.0 - x)).abs() <= 0.5, "{ahead} at x = {x}");
}

#[test]
fn gaps_of_one_to_three_metres_across_all_rows_are_not_the_end() {
    for gap_m in [1.0, 2.0, 3.0] {
        let field = Field { gaps: (-4..4).map(|k| (k, 5.0, 5.0 + gap_m)).collect(), ..Field::default() };
        assert_eq!(end_raised(&field, DetectorConfig::default(), 6.0 + gap_m), None, "gap {gap_m} m");
    }
}

#[test]
fn paper_mode_runs_with_its_own_tolerances() {
    // Measured yardstick, not a target: the paper's pipeline finds the rows on most scans, within
    // 6 cm and 1.5°, on the straight field.
    let field = Field::default();
    let poses = drive(&field, 0.0, 5.0, 0.1, 0.0, 0.0);
    for cfg in [DetectorConfig::paper(), DetectorConfig::paper_code()] {
        let e = run(&field, cfg, &poses, SKIP, 7);
        println!("paper: {}", e.summary());
        assert!(!e.offset_m.is_empty());
        assert!(Errors::mean(&e.offset_m) <= 0.06, "{}", e.summary());
        assert!(Errors::mean(&e.heading_rad).to_degrees() <= 1.5, "{}", e.summary());
    }
}
