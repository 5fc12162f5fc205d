//! The committed recordings under `tests/data/` (one per point layout) are what the writer produces
//! today and read back to the exact points. Regenerate with `CROPROW_REGENERATE=1 cargo test -p
//! croprow-io --test layouts`.

mod support;

use std::path::PathBuf;

use croprow_io::read::{MountSource, Recording, ReplayConfig};
use support::{Fixture, T0, fixture_mount, layouts, pose_at, scan_points, write_fixture};

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

#[test]
fn committed_recordings_are_what_the_writer_writes() {
    let regenerate = std::env::var_os("CROPROW_REGENERATE").is_some();
    for (name, format) in layouts() {
        let bytes = write_fixture(Fixture::small(format));
        assert!(bytes.len() < 200_000, "{name}: {} bytes", bytes.len());
        if regenerate {
            std::fs::write(data(name), &bytes).unwrap();
        }
        let committed = std::fs::read(data(name)).unwrap_or_else(|e| panic!("{name}: {e}; regenerate it"));
        assert!(committed == bytes, "{name} differs from the writer's output; regenerate and review");
    }
}

#[test]
fn every_layout_reads_back_exactly() {
    for (name, format) in layouts() {
        let rec = Recording::open(data(name)).unwrap();
        assert!(rec.is_indexed(), "{name}: summary present");
        let mut replay = rec.replay(&ReplayConfig::default()).unwrap();
        let mut k = 0;
        while let Some(frame) = replay.next_scan() {
            let f = frame.unwrap_or_else(|e| panic!("{name}: {e}"));
            let want = scan_points(k, 200);
            assert_eq!(f.points.len(), want.len(), "{name} {format:?}");
            for (p, q) in f.points.iter().zip(&want) {
                // f32 written as f32 or widened to f64: exact either way; NaN dropouts stay NaN.
                assert!(p == q || (p.x.is_nan() && q.x.is_nan()), "{name}: {p:?} != {q:?}");
            }
            let t = 0.1 * (k + 1) as f64;
            assert!((f.stamp_s - (T0 + t)).abs() < 1e-6, "{name}: stamp {}", f.stamp_s);
            let pose = f.odom_pose.unwrap();
            let truth = pose_at(t);
            // Odometry at 50 Hz; the scan stamp falls on a sample, so up to f64 stamp rounding: 1e-6.
            assert!(
                (pose.x - truth.x).abs() < 1e-6 && (pose.yaw - truth.yaw).abs() < 1e-6,
                "{name}: {pose:?}"
            );
            assert_eq!(f.mount_source, MountSource::TfStatic);
            assert!((f.mount.pitch_rad - fixture_mount().pitch_rad).abs() < 1e-9);
            k += 1;
        }
        assert_eq!(k, 3, "{name}");
    }
}
