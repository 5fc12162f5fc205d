//! Broken recordings give a clear error, never a panic, and the scans before the fault still come out.

mod support;

use croprow_core::Mount;
use croprow_io::cloud::PointFormat;
use croprow_io::read::{MountSource, Recording, RecordingError, ReplayConfig};
use support::{Fixture, temp_path, write_fixture};

fn write_temp(name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = temp_path(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Drains a replay: the scans read, then the error that ended it (if any).
fn drain(path: &std::path::Path, config: &ReplayConfig) -> (usize, Option<RecordingError>) {
    let mut replay = match Recording::open(path).and_then(|r| r.replay(config)) {
        Ok(r) => r,
        Err(e) => return (0, Some(e)),
    };
    let mut n = 0;
    while let Some(item) = replay.next_scan() {
        match item {
            Ok(_) => n += 1,
            Err(e) => {
                assert!(replay.next_scan().is_none(), "the replay ends after its fault");
                return (n, Some(e));
            }
        }
    }
    (n, None)
}

fn many_chunks() -> Vec<u8> {
    write_fixture(Fixture {
        scans: 10,
        points: 3000,
        chunk_bytes: 16 * 1024,
        ..Fixture::small(PointFormat::VELODYNE)
    })
}

#[test]
fn empty_file() {
    let p = write_temp("empty.mcap", &[]);
    let (_, e) = drain(&p, &ReplayConfig::default());
    let e = e.unwrap();
    assert!(matches!(e, RecordingError::Empty(_)), "{e}");
    assert!(e.to_string().contains("empty"));
}

#[test]
fn not_an_mcap_file() {
    let p = write_temp("text.mcap", b"x y z\n1 2 3\n");
    let e = drain(&p, &ReplayConfig::default()).1.unwrap();
    assert!(matches!(e, RecordingError::NotMcap(_)), "{e}");
    assert!(e.to_string().contains("not an MCAP"));
}

#[test]
fn missing_file() {
    let e = drain(&temp_path("does-not-exist.mcap"), &ReplayConfig::default()).1.unwrap();
    assert!(matches!(e, RecordingError::Io { .. }), "{e}");
}

#[test]
fn truncated_file_yields_the_scans_before_the_cut() {
    let bytes = many_chunks();
    let p = write_temp("truncated.mcap", &bytes[..bytes.len() * 6 / 10]);
    assert!(!Recording::open(&p).unwrap().is_indexed(), "no footer, read front to back");
    let (n, e) = drain(&p, &ReplayConfig::default());
    let e = e.unwrap();
    assert!(matches!(e, RecordingError::Truncated { .. }), "{e}");
    assert!(e.to_string().contains("truncated"), "{e}");
    assert!((3..10).contains(&n), "{n} scans before the cut");
}

#[test]
fn corrupt_chunk_is_reported() {
    let mut bytes = many_chunks();
    let mid = bytes.len() / 2;
    for b in &mut bytes[mid..mid + 64] {
        *b ^= 0x5A;
    }
    let p = write_temp("corrupt.mcap", &bytes);
    let (n, e) = drain(&p, &ReplayConfig::default());
    let e = e.expect("corruption is detected");
    assert!(matches!(e, RecordingError::Corrupt { .. } | RecordingError::Decode { .. }), "{e}");
    assert!(n < 10);
}

#[test]
fn missing_topic_lists_the_topics() {
    let p = write_temp("topics.mcap", &write_fixture(Fixture::small(PointFormat::XYZ)));
    let config = ReplayConfig { cloud_topic: "/points_raw".into(), ..ReplayConfig::default() };
    let e = drain(&p, &config).1.unwrap();
    assert!(matches!(e, RecordingError::MissingTopic { .. }), "{e}");
    let msg = e.to_string();
    assert!(
        msg.contains("/points_raw") && msg.contains("/velodyne_points (sensor_msgs/msg/PointCloud2)"),
        "{msg}"
    );
}

#[test]
fn missing_topic_in_an_unindexed_file() {
    let bytes = many_chunks();
    let p = write_temp("topics-unindexed.mcap", &bytes[..bytes.len() * 6 / 10]);
    let config = ReplayConfig { cloud_topic: "/points_raw".into(), ..ReplayConfig::default() };
    let e = drain(&p, &config).1.unwrap();
    // The cut comes first; either way the user learns what is wrong.
    assert!(matches!(e, RecordingError::Truncated { .. } | RecordingError::MissingTopic { .. }), "{e}");
}

#[test]
fn wrong_type_on_the_cloud_topic() {
    let p = write_temp("schema.mcap", &write_fixture(Fixture::small(PointFormat::XYZ)));
    let config = ReplayConfig { cloud_topic: "/imu/data".into(), ..ReplayConfig::default() };
    let e = drain(&p, &config).1.unwrap();
    assert!(matches!(e, RecordingError::SchemaMismatch { .. }), "{e}");
    assert!(e.to_string().contains("sensor_msgs/msg/Imu"), "{e}");
}

#[test]
fn missing_transform_without_fallback() {
    let bytes = write_fixture(Fixture { tf_static: false, ..Fixture::small(PointFormat::XYZ) });
    let p = write_temp("no-tf.mcap", &bytes);
    let e = drain(&p, &ReplayConfig::default()).1.unwrap();
    assert!(matches!(e, RecordingError::MissingTransform(_)), "{e}");
    assert!(e.to_string().contains("`base_link` to `velodyne`"), "{e}");
}

#[test]
fn missing_transform_uses_the_fallback_mount() {
    let bytes = write_fixture(Fixture { tf_static: false, ..Fixture::small(PointFormat::XYZ) });
    let p = write_temp("fallback.mcap", &bytes);
    let config = ReplayConfig { fallback_mount: Some(Mount::default()), ..ReplayConfig::default() };
    let mut replay = Recording::open(&p).unwrap().replay(&config).unwrap();
    let f = replay.next_scan().unwrap().unwrap();
    assert_eq!(f.mount_source, MountSource::Fallback);
    assert_eq!(f.mount, Mount::default());
}

#[test]
fn odometry_going_backwards() {
    use croprow_core::{Pose2, Twist2};
    let mut rec = croprow_io::RecordingWriter::new(std::io::Cursor::new(Vec::new())).unwrap();
    rec.write_tf_static(1.0, "velodyne", &Mount::default()).unwrap();
    rec.write_odometry("/odometry/filtered", 1.0, Pose2::default(), Twist2::ZERO).unwrap();
    rec.write_cloud("/velodyne_points", 1.0, "velodyne", &support::scan_points(0, 50), &[], &[]).unwrap();
    rec.write_odometry("/odometry/filtered", 1.02, Pose2::default(), Twist2::ZERO).unwrap();
    rec.write_odometry("/odometry/filtered", 1.03, Pose2::default(), Twist2::ZERO).unwrap();
    rec.write(
        "/odometry/filtered",
        1.04,
        &croprow_io::msg::Odometry {
            header: croprow_io::msg::Header {
                stamp: croprow_io::msg::Time { sec: 0, nanosec: 5 },
                frame_id: "odom".into(),
            },
            child_frame_id: "base_link".into(),
            ..Default::default()
        },
    )
    .unwrap();
    let p = write_temp("backwards.mcap", &rec.finish().unwrap().into_inner());
    let (n, e) = drain(&p, &ReplayConfig::default());
    assert_eq!(n, 1, "the scan before the fault is kept");
    let e = e.unwrap();
    assert!(matches!(e, RecordingError::OdometryBackwards { .. }), "{e}");
    assert!(e.to_string().contains("backwards"));
}

#[test]
fn scans_outside_odometry_have_no_pose() {
    use croprow_core::{Pose2, Twist2};
    let mut rec = croprow_io::RecordingWriter::new(std::io::Cursor::new(Vec::new())).unwrap();
    rec.write_tf_static(1.0, "velodyne", &Mount::default()).unwrap();
    rec.write_cloud("/velodyne_points", 1.0, "velodyne", &support::scan_points(0, 50), &[], &[]).unwrap();
    rec.write_odometry("/odometry/filtered", 2.0, Pose2::default(), Twist2::ZERO).unwrap();
    let p = write_temp("no-odom.mcap", &rec.finish().unwrap().into_inner());
    let mut replay = Recording::open(&p).unwrap().replay(&ReplayConfig::default()).unwrap();
    let f = replay.next_scan().unwrap().unwrap();
    assert!(f.odom_pose.is_err(), "1 s before the first odometry sample: no pose, not a guess");
    assert!(replay.next_scan().is_none());
}

#[test]
fn missing_odometry_topic_is_named() {
    let p = write_temp("no-odom-topic.mcap", &write_fixture(Fixture::small(PointFormat::XYZ)));
    let config = ReplayConfig { odom_topic: "/odom".into(), ..ReplayConfig::default() };
    let e = drain(&p, &config).1.unwrap();
    assert!(matches!(e, RecordingError::MissingTopic { ref topic, .. } if topic == "/odom"), "{e}");
    assert!(e.to_string().contains("/odometry/filtered (nav_msgs/msg/Odometry)"), "{e}");
}
