//! Shared fixtures: small synthetic recordings written with the crate's own writer.

#![allow(dead_code)]

use std::io::Cursor;

use croprow_core::{Mount, Point3, Pose2, Twist2};
use croprow_io::RecordingWriter;
use croprow_io::cloud::PointFormat;

/// First stamp of every fixture, s (a plausible Unix time, to exercise f64 stamps).
pub const T0: f64 = 1_700_000_000.0;

/// Deterministic sensor-frame points for scan `k`: a tilted grid with one dropout (NaN).
pub fn scan_points(k: usize, n: usize) -> Vec<Point3> {
    (0..n)
        .map(|i| {
            if i == 7 {
                return Point3::new(f32::NAN, f32::NAN, f32::NAN);
            }
            let (a, b) = ((i % 40) as f32, (i / 40) as f32);
            Point3::new(0.5 + 0.1 * a + 0.01 * k as f32, -2.0 + 0.13 * b, -1.2 + 0.017 * a - 0.003 * b)
        })
        .collect()
}

/// The odometry pose at `t` s after `T0`: 0.5 m/s forward with a slow turn.
pub fn pose_at(t: f64) -> Pose2 {
    Pose2::new(0.5 * t, 0.02 * t * t, 0.04 * t)
}

/// Options of a fixture recording.
#[derive(Debug, Clone, Copy)]
pub struct Fixture {
    /// Point layout of the clouds.
    pub format: PointFormat,
    /// Scans (10 Hz).
    pub scans: usize,
    /// Points per scan.
    pub points: usize,
    /// Write `/tf_static` (`base_link -> velodyne`).
    pub tf_static: bool,
    /// Chunk size, bytes.
    pub chunk_bytes: u64,
}

impl Fixture {
    /// Three scans of 200 points in `format`, with `/tf_static`.
    pub fn small(format: PointFormat) -> Self {
        Self { format, scans: 3, points: 200, tf_static: true, chunk_bytes: 1 << 20 }
    }
}

/// The mount written to `/tf_static`.
pub fn fixture_mount() -> Mount {
    Mount { x_m: 0.5, y_m: 0.0, z_m: 1.2, roll_rad: 0.0, pitch_rad: 0.4, yaw_rad: 0.0 }
}

/// Writes a fixture recording in memory: odometry at 50 Hz from 0.1 s before the first scan to 0.1 s
/// after the last, `/tf`, IMU at 100 Hz, clouds at 10 Hz, all in log-time order.
pub fn write_fixture(f: Fixture) -> Vec<u8> {
    let mut rec = RecordingWriter::with_chunk_size(Cursor::new(Vec::new()), f.chunk_bytes).unwrap();
    if f.tf_static {
        rec.write_tf_static(T0, "velodyne", &fixture_mount()).unwrap();
    }
    let end_ms = (f.scans as u64 + 1) * 100 + 100;
    for ms in (0..=end_ms).step_by(10) {
        let t = ms as f64 / 1000.0;
        let stamp = T0 + t;
        if ms % 20 == 0 {
            rec.write_odometry("/odometry/filtered", stamp, pose_at(t), Twist2::new(0.5, 0.04)).unwrap();
            rec.write_tf(stamp, pose_at(t)).unwrap();
        }
        rec.write_imu("/imu/data", stamp, "imu_link", [0.0, 0.0, 0.04], [0.0, 0.0, 9.81]).unwrap();
        if ms >= 100 && ms % 100 == 0 && ((ms / 100 - 1) as usize) < f.scans {
            let k = (ms / 100 - 1) as usize;
            let points = scan_points(k, f.points);
            let intensity: Vec<f32> = (0..f.points).map(|i| i as f32).collect();
            let ring: Vec<u16> = (0..f.points).map(|i| (i % 16) as u16).collect();
            rec.write_cloud_as("/velodyne_points", stamp, "velodyne", &points, &intensity, &ring, f.format)
                .unwrap();
        }
    }
    rec.finish().unwrap().into_inner()
}

/// Every point layout the committed recordings cover, with their file names.
pub fn layouts() -> Vec<(&'static str, PointFormat)> {
    let xyz = PointFormat::XYZ;
    vec![
        ("xyz_f32.mcap", xyz),
        ("xyz_f64.mcap", PointFormat { xyz_f64: true, ..xyz }),
        ("xyz_intensity_f32.mcap", PointFormat { intensity: true, ..xyz }),
        ("xyz_ring_f32.mcap", PointFormat { ring: true, ..xyz }),
        ("velodyne_packed18.mcap", PointFormat::VELODYNE),
        ("xyz_intensity_padded32.mcap", PointFormat { intensity: true, padding: 16, ..xyz }),
        ("velodyne_big_endian.mcap", PointFormat { big_endian: true, ..PointFormat::VELODYNE }),
        ("xyz_f64_ring_big_endian.mcap", PointFormat { xyz_f64: true, ring: true, big_endian: true, ..xyz }),
    ]
}

/// A unique temporary path for a test.
pub fn temp_path(name: &str) -> std::path::PathBuf {
    std::env::temp_dir().join(format!("croprow-io-{}-{name}", std::process::id()))
}
