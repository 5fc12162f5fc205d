//! Bad input never panics: it gives `InvalidInput` (state kept), a documented status, or a `ConfigError`.
mod support;

use croprow_core::{Attitude, DetectorConfig, Mount, Point3, Pose2, RowDetector, RowStatus, Scan};
use proptest::prelude::*;
use support::{Field, Lidar};

/// A detector that has tracked the rows of the default field for 3 m (30 scans, t = 0..2.9 s).
fn tracking(config: DetectorConfig) -> (RowDetector, Lidar, Field) {
    let field = Field::default();
    let mut lidar = Lidar::vlp16(11);
    let mut det = RowDetector::new(config).unwrap();
    for i in 0..30 {
        let pose = Pose2::new(0.1 * i as f64, 0.0, 0.0);
        let pts = lidar.scan(&field, &pose, &Mount::default());
        det.detect(
            Scan { stamp_s: 0.1 * i as f64, points: &pts, twist: None, attitude: None },
            pose,
            &Mount::default(),
        );
    }
    (det, lidar, field)
}

fn step(
    det: &mut RowDetector,
    lidar: &mut Lidar,
    field: &Field,
    t: f64,
    pose: Pose2,
) -> croprow_core::Detection {
    let pts = lidar.scan(field, &pose, &Mount::default());
    det.detect(Scan { stamp_s: t, points: &pts, twist: None, attitude: None }, pose, &Mount::default())
}

#[test]
fn empty_and_non_finite_scans_are_invalid_input() {
    let mut det = RowDetector::new(DetectorConfig::default()).unwrap();
    let m = Mount::default();
    let d = det.detect(Scan { stamp_s: 0.0, points: &[], twist: None, attitude: None }, Pose2::default(), &m);
    assert_eq!(d.status, RowStatus::InvalidInput);
    let junk = [Point3::new(f32::NAN, 1.0, 0.0), Point3::new(f32::INFINITY, 0.0, 0.0)];
    let d =
        det.detect(Scan { stamp_s: 0.1, points: &junk, twist: None, attitude: None }, Pose2::default(), &m);
    assert_eq!(d.status, RowStatus::InvalidInput);
    let d = det.detect(
        Scan { stamp_s: f64::NAN, points: &junk, twist: None, attitude: None },
        Pose2::default(),
        &m,
    );
    assert_eq!(d.status, RowStatus::InvalidInput);
    let d = det.detect(
        Scan { stamp_s: 0.2, points: &junk, twist: None, attitude: None },
        Pose2::new(f64::NAN, 0.0, 0.0),
        &m,
    );
    assert_eq!(d.status, RowStatus::InvalidInput);
}

#[test]
fn non_finite_points_among_good_ones_are_skipped() {
    for config in [DetectorConfig::default(), DetectorConfig::paper()] {
        let (mut det, mut lidar, field) = tracking(config);
        let pose = Pose2::new(3.0, 0.0, 0.0);
        let mut pts = lidar.scan(&field, &pose, &Mount::default());
        for p in pts.iter_mut().step_by(7) {
            *p = Point3::new(f32::NAN, f32::INFINITY, f32::NEG_INFINITY);
        }
        let d = det.detect(
            Scan { stamp_s: 3.0, points: &pts, twist: None, attitude: None },
            pose,
            &Mount::default(),
        );
        assert_eq!(d.status, RowStatus::Tracking);
        assert!(d.left.is_some_and(|r| r.line.iter().all(|v| v.is_finite())));
    }
}

#[test]
fn an_absurd_or_non_finite_attitude_refuses_the_scan_and_keeps_the_state() {
    let (mut det, mut lidar, field) = tracking(DetectorConfig::default());
    let pose = Pose2::new(3.0, 0.0, 0.0);
    let pts = lidar.scan(&field, &pose, &Mount::default());
    for (roll_rad, pitch_rad) in [(f64::NAN, 0.0), (0.0, f64::INFINITY), (0.6, 0.0), (0.0, -0.6)] {
        let attitude = Some(Attitude { roll_rad, pitch_rad });
        let d =
            det.detect(Scan { stamp_s: 3.0, points: &pts, twist: None, attitude }, pose, &Mount::default());
        assert_eq!(d.status, RowStatus::InvalidInput, "{attitude:?}");
    }
    // The same scan, level, is taken: the refusals left the state as it was.
    let level = Some(Attitude::default());
    let d = det.detect(
        Scan { stamp_s: 3.0, points: &pts, twist: None, attitude: level },
        pose,
        &Mount::default(),
    );
    assert_eq!(d.status, RowStatus::Tracking);
}

#[test]
fn a_scan_of_bare_ground_finds_no_rows() {
    let field = Field { rows_each_side: 0, ..Field::default() };
    let mut lidar = Lidar::vlp16(2);
    let mut det = RowDetector::new(DetectorConfig::default()).unwrap();
    for i in 0..10 {
        let pose = Pose2::new(0.1 * i as f64, 0.0, 0.0);
        let d = step(&mut det, &mut lidar, &field, 0.1 * i as f64, pose);
        assert_eq!(d.status, RowStatus::Searching, "scan {i}");
        assert!(d.left.is_none() && d.right.is_none());
    }
}

#[test]
fn paper_mode_on_bare_ground_gives_finite_output() {
    // Measured weakness of the paper's method: the centroid plane keeps about half of a noisy ground, and
    // K-means + RANSAC turn it into "rows". It must still give finite output and never panic.
    let field = Field { rows_each_side: 0, ..Field::default() };
    let mut lidar = Lidar::vlp16(2);
    let mut det = RowDetector::new(DetectorConfig::paper()).unwrap();
    for i in 0..10 {
        let d = step(&mut det, &mut lidar, &field, 0.1 * i as f64, Pose2::new(0.1 * i as f64, 0.0, 0.0));
        assert_ne!(d.status, RowStatus::InvalidInput);
        assert!(d.left.iter().chain(d.right.iter()).all(|r| r.line.iter().all(|v| v.is_finite())));
    }
}

#[test]
fn rows_unseen_for_too_long_are_lost() {
    let (mut det, mut lidar, _) = tracking(DetectorConfig::default());
    let bare = Field { rows_each_side: 0, ..Field::default() };
    let mut last = RowStatus::Tracking;
    for i in 30..50 {
        last = step(&mut det, &mut lidar, &bare, 0.1 * i as f64, Pose2::new(0.1 * i as f64, 0.0, 0.0)).status;
    }
    assert_eq!(last, RowStatus::Lost);
}

#[test]
fn time_going_backwards_is_refused_and_the_state_kept() {
    let (mut det, mut lidar, field) = tracking(DetectorConfig::default());
    let pose = Pose2::new(2.9, 0.0, 0.0);
    assert_eq!(step(&mut det, &mut lidar, &field, 2.0, pose).status, RowStatus::InvalidInput);
    assert_eq!(step(&mut det, &mut lidar, &field, 2.9, pose).status, RowStatus::InvalidInput);
    let d = step(&mut det, &mut lidar, &field, 3.0, Pose2::new(3.0, 0.0, 0.0));
    assert_eq!(d.status, RowStatus::Tracking);
}

#[test]
fn an_odometry_spike_is_refused_and_the_state_kept() {
    let (mut det, mut lidar, field) = tracking(DetectorConfig::default());
    let d = step(&mut det, &mut lidar, &field, 3.0, Pose2::new(30.0, 5.0, 1.0));
    assert_eq!(d.status, RowStatus::InvalidInput);
    let d = step(&mut det, &mut lidar, &field, 3.1, Pose2::new(3.1, 0.0, 0.0));
    assert_eq!(d.status, RowStatus::Tracking);
    assert!(d.left.is_some_and(|r| (r.offset_m - 0.375).abs() < 0.02), "{d:?}");
}

#[test]
fn a_confirmed_odometry_jump_restarts_the_map() {
    // The odometry origin moves 20 m and stays there (an EKF reset): after one refused scan the detector
    // accepts the new origin, drops its map and finds the rows again.
    let (mut det, mut lidar, field) = tracking(DetectorConfig::default());
    let shift = |x: f64| Pose2::new(x + 20.0, 0.0, 0.0);
    assert_eq!(step(&mut det, &mut lidar, &field, 3.0, shift(3.0)).status, RowStatus::InvalidInput);
    let mut last = None;
    for i in 31..40 {
        let t = 0.1 * i as f64;
        // The field moves with the origin.
        let pts = lidar.scan(&field, &Pose2::new(t, 0.0, 0.0), &Mount::default());
        last = Some(det.detect(
            Scan { stamp_s: t, points: &pts, twist: None, attitude: None },
            shift(t),
            &Mount::default(),
        ));
    }
    let d = last.unwrap();
    assert_eq!(d.status, RowStatus::Tracking);
    assert!(d.left.is_some_and(|r| (r.offset_m - 0.375).abs() < 0.03), "{d:?}");
}

#[test]
fn an_absurd_mount_is_invalid_input() {
    let (mut det, mut lidar, field) = tracking(DetectorConfig::default());
    let pts = lidar.scan(&field, &Pose2::new(3.0, 0.0, 0.0), &Mount::default());
    for mount in [
        Mount { z_m: -1.0, ..Mount::default() },
        Mount { pitch_rad: f64::NAN, ..Mount::default() },
        Mount { roll_rad: 3.0, ..Mount::default() },
    ] {
        let d = det.detect(
            Scan { stamp_s: 3.0, points: &pts, twist: None, attitude: None },
            Pose2::new(3.0, 0.0, 0.0),
            &mount,
        );
        assert_eq!(d.status, RowStatus::InvalidInput);
    }
}

#[test]
fn an_absurd_config_is_refused() {
    for bad in [
        DetectorConfig { fov_deg: 0.0, ..DetectorConfig::default() },
        DetectorConfig { range_m: f64::INFINITY, ..DetectorConfig::default() },
        DetectorConfig { ransac_iterations: 0, ..DetectorConfig::paper() },
        DetectorConfig { map_bin_m: -0.25, ..DetectorConfig::default() },
    ] {
        let e = RowDetector::new(bad).unwrap_err();
        assert!(e.to_string().contains("detector."), "{e}");
    }
}

#[test]
fn reset_forgets_the_rows() {
    let (mut det, mut lidar, _) = tracking(DetectorConfig::default());
    det.reset();
    assert!(det.centroids().is_empty());
    let bare = Field { rows_each_side: 0, ..Field::default() };
    let d = step(&mut det, &mut lidar, &bare, 0.0, Pose2::default());
    assert_eq!(d.status, RowStatus::Searching);
}

fn garbage_point() -> impl Strategy<Value = Point3> {
    let coord = prop_oneof![
        8 => -20.0f32..20.0,
        1 => Just(f32::NAN),
        1 => Just(f32::INFINITY),
        1 => Just(f32::MAX),
        1 => Just(-f32::MIN_POSITIVE),
    ];
    (coord.clone(), coord.clone(), coord).prop_map(|(x, y, z)| Point3::new(x, y, z))
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    #[test]
    fn garbage_points_never_panic_nor_give_non_finite_rows(
        scans in prop::collection::vec(prop::collection::vec(garbage_point(), 0..400), 1..6),
        paper in any::<bool>(),
    ) {
        let config = if paper { DetectorConfig::paper() } else { DetectorConfig::default() };
        let mut det = RowDetector::new(config).unwrap();
        for (i, pts) in scans.iter().enumerate() {
            let d = det.detect(Scan { stamp_s: 0.1 * i as f64, points: pts, twist: None, attitude: None }, Pose2::new(0.1 * i as f64, 0.0, 0.0), &Mount::default());
            for r in d.left.iter().chain(d.right.iter()) {
                prop_assert!(r.line.iter().all(|v| v.is_finite()));
                prop_assert!(r.offset_m.is_finite() && r.heading_rad.is_finite() && r.curvature_per_m.is_finite());
                prop_assert!((0.0..=1.0).contains(&r.confidence));
            }
            prop_assert!(d.row_spacing_m.is_none_or(f64::is_finite));
            prop_assert!(d.row_end_ahead_m.is_none_or(f64::is_finite));
        }
    }
}
