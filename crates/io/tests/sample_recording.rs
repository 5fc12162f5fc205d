//! The shared recording made by an independent field recorder (`../shared/data/sample-young-corn.mcap`
//! from the repository root) reads correctly: scans, layout, stamps, odometry and the mount.

use std::path::PathBuf;

use croprow_io::read::{MountSource, Recording, ReplayConfig};

/// `../shared/data` next to the repository, or `$CROPROW_SHARED_DATA` (for worktrees elsewhere).
fn data_dir() -> PathBuf {
    std::env::var_os("CROPROW_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"))
}

fn sample() -> PathBuf {
    let p = data_dir().join("sample-young-corn.mcap");
    assert!(
        p.is_file(),
        "the shared recording is missing: expected {} (see /work/shared/data/README.md)",
        p.display()
    );
    p
}

fn ground_truth() -> serde_json::Value {
    let p = data_dir().join("sample-young-corn.gt.json");
    let text = std::fs::read_to_string(&p)
        .unwrap_or_else(|e| panic!("ground truth {} unreadable: {e}", p.display()));
    serde_json::from_str(&text).expect("ground truth is JSON")
}

#[test]
fn lists_its_topics() {
    let rec = Recording::open(sample()).unwrap();
    assert!(rec.is_indexed());
    let topics = rec.topics().unwrap();
    let find =
        |t: &str| topics.iter().find(|i| i.topic == t).unwrap_or_else(|| panic!("{t} missing: {topics:?}"));
    assert_eq!(find("/velodyne_points").schema_name, "sensor_msgs/msg/PointCloud2");
    assert_eq!(find("/velodyne_points").message_count, Some(23));
    assert_eq!(find("/odometry/filtered").schema_name, "nav_msgs/msg/Odometry");
    assert_eq!(find("/imu/data").schema_name, "sensor_msgs/msg/Imu");
    assert_eq!(find("/tf_static").encoding, "cdr");
}

#[test]
fn yields_23_scans_with_mount_from_tf_static_and_interpolated_odometry() {
    let gt = ground_truth();
    let gt_scans = gt["scans"].as_array().unwrap();
    let mut replay = Recording::open(sample()).unwrap().replay(&ReplayConfig::default()).unwrap();
    let mut n = 0;
    let mut last_stamp = f64::NEG_INFINITY;
    while let Some(frame) = replay.next_scan() {
        let f = frame.unwrap();
        assert_eq!(f.frame_id, "velodyne");
        assert!(f.stamp_s > last_stamp, "stamps increase");
        last_stamp = f.stamp_s;
        // Mount (0.6, 0, 1.5) pitched 30° nose-down, from /tf_static; 1e-6 m / 1e-5 rad.
        assert_eq!(f.mount_source, MountSource::TfStatic);
        assert!(
            (f.mount.x_m - 0.6).abs() < 1e-6 && f.mount.y_m.abs() < 1e-6 && (f.mount.z_m - 1.5).abs() < 1e-6
        );
        assert!((f.mount.pitch_rad - 30f64.to_radians()).abs() < 1e-5 && f.mount.roll_rad.abs() < 1e-6);
        // 16 rings x up to 1800 azimuths, returns only; every decoded point is a real return.
        assert!(f.points.len() > 5_000 && f.points.len() <= 28_800, "{} points", f.points.len());
        assert!(f.points.iter().all(|p| p.is_finite() && p.x.hypot(p.y).hypot(p.z) < 130.0));
        // The 18-byte layout decoded right: within 4 m of the robot, young corn is mostly bare ground,
        // so the median height in base_link is the ground plane, z ≈ 0 (±0.1 m).
        let mut z: Vec<f64> = f
            .points
            .iter()
            .map(|p| f.mount.to_base(*p))
            .filter(|v| v.x.hypot(v.y) < 4.0)
            .map(|v| v.z)
            .collect();
        z.sort_by(f64::total_cmp);
        let median = z[z.len() / 2];
        assert!(median.abs() < 0.1, "median near z in base_link is {median} m, expected the ground near 0");
        // The stamp matches the ground truth, and odometry (drifting, world = odom at start) stays
        // within 0.15 m and 0.05 rad of the true pose over 2.3 s.
        let truth = &gt_scans[n];
        assert!((truth["stamp"].as_f64().unwrap() - f.stamp_s).abs() < 1e-6);
        let pose = f.odom_pose.expect("odometry covers every scan");
        let tp = truth["pose"].as_array().unwrap();
        let (tx, ty, tyaw) = (tp[0].as_f64().unwrap(), tp[1].as_f64().unwrap(), tp[5].as_f64().unwrap());
        assert!((pose.x - tx).hypot(pose.y - ty) < 0.15, "scan {n}: odom {pose:?} vs truth ({tx}, {ty})");
        assert!((pose.yaw - tyaw).abs() < 0.05, "scan {n}: yaw {} vs {tyaw}", pose.yaw);
        n += 1;
    }
    assert_eq!(n, 23);
}

/// Lateral offset (y at x = 0, base_link) and heading of a world polyline seen from a true pose.
fn truth_in_base(polyline: &[serde_json::Value], pose: (f64, f64, f64)) -> Option<(f64, f64)> {
    let (px, py, pyaw) = pose;
    let (s, c) = pyaw.sin_cos();
    let local: Vec<(f64, f64)> = polyline
        .iter()
        .map(|p| {
            let (wx, wy) = (p[0].as_f64().unwrap() - px, p[1].as_f64().unwrap() - py);
            (c * wx + s * wy, -s * wx + c * wy)
        })
        .collect();
    local.windows(2).find(|w| w[0].0 <= 0.0 && w[1].0 > 0.0).map(|w| {
        let t = -w[0].0 / (w[1].0 - w[0].0);
        (w[0].1 + t * (w[1].1 - w[0].1), (w[1].1 - w[0].1).atan2(w[1].0 - w[0].0))
    })
}

#[test]
fn detected_rows_match_the_ground_truth() {
    rows_match_the_ground_truth(croprow_core::DetectorConfig::default());
}

#[test]
fn deskewed_rows_match_the_ground_truth() {
    // The recorder stamps each cloud at the end of its sweep with every point in the sensor frame of
    // its firing instant, the convention the deskew undoes.
    rows_match_the_ground_truth(croprow_core::DetectorConfig { deskew: true, ..Default::default() });
}

/// Runs the detector with `config` over the recording and checks every tracked scan's rows against the
/// ground truth; the scans carry the twist of the odometry around their stamps.
fn rows_match_the_ground_truth(config: croprow_core::DetectorConfig) {
    use croprow_core::{RowDetector, RowStatus};
    let gt = ground_truth();
    let rows = gt["rows"].as_array().unwrap();
    let polyline = |key: &str| {
        let index = gt["followed_rows"][key].as_u64().unwrap();
        rows.iter().find(|r| r["index"].as_u64() == Some(index)).unwrap()["polyline"]
            .as_array()
            .unwrap()
            .clone()
    };
    let (left_row, right_row) = (polyline("left"), polyline("right"));
    let gt_scans = gt["scans"].as_array().unwrap();
    let mut detector = RowDetector::new(config).unwrap();
    let mut replay = Recording::open(sample()).unwrap().replay(&ReplayConfig::default()).unwrap();
    let (mut n, mut tracked) = (0, 0);
    while let Some(frame) = replay.next_scan() {
        let f = frame.unwrap();
        // A field robot's twist from the odometry poses: forward under 2 m/s, turning under 1 rad/s.
        let twist = f.scan().twist.expect("odometry covers every scan");
        assert!(twist.v.abs() < 2.0 && twist.omega.abs() < 1.0, "scan {n}: {twist:?}");
        let d = detector.detect(f.scan(), f.odom_pose.unwrap(), &f.mount);
        let tp = gt_scans[n]["pose"].as_array().unwrap();
        let pose = (tp[0].as_f64().unwrap(), tp[1].as_f64().unwrap(), tp[5].as_f64().unwrap());
        n += 1;
        if d.status != RowStatus::Tracking {
            continue;
        }
        tracked += 1;
        for (row, truth_line, side) in [(d.left, &left_row, "left"), (d.right, &right_row, "right")] {
            let row = row.unwrap_or_else(|| panic!("scan {n}: tracking without a {side} row"));
            let (offset, heading) = truth_in_base(truth_line, pose).expect("the true row passes the robot");
            assert!((offset.abs() - 0.375).abs() < 0.1, "truth itself: {side} row at {offset} m");
            // Tolerances: 0.08 m lateral (a tenth of the 0.75 m spacing), 5° heading.
            let [x1, y1, x2, y2] = row.line;
            let y0 = y1 - x1 * (y2 - y1) / (x2 - x1);
            assert!((y0 - offset).abs() < 0.08, "scan {n} {side}: detected {y0:.3} m, truth {offset:.3} m");
            let h = (y2 - y1).atan2(x2 - x1);
            assert!(
                (h - heading).abs() < 5f64.to_radians(),
                "scan {n} {side}: heading {h:.3} vs {heading:.3} rad"
            );
        }
    }
    assert_eq!(n, 23);
    assert!(tracked >= 20, "only {tracked} of 23 scans tracked");
}
