//! PointCloud2 decoding cost for a 29k-point Velodyne-like cloud (VLP-16: 16 rings x 1800 azimuths),
//! from CDR bytes to `Vec<Point3>`: the per-scan work `croprow detect` does before the detector runs.
//!
//! `cargo bench -p croprow-io --bench decode -- --warm-up-time 1 --measurement-time 3`
//!
//! The `sample_*` pair compares decoding with detection on the 23 real scans of the shared recording.

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_core::Point3;
use croprow_io::cloud::{self, PointFormat, Stamped};
use croprow_io::msg::{self, PointCloud2};

/// 16 rings x 1800 azimuth steps, ranges 2-20 m: the size of one VLP-16 sweep.
fn vlp16_points() -> Vec<Point3> {
    let mut points = Vec::with_capacity(16 * 1800);
    for ring in 0..16 {
        let elevation = (-15.0f32 + 2.0 * ring as f32).to_radians();
        for step in 0..1800 {
            let azimuth = (step as f32 * 0.2).to_radians();
            let range = 2.0 + 18.0 * ((step * 7 + ring * 13) % 100) as f32 / 100.0;
            points.push(Point3::new(
                range * elevation.cos() * azimuth.cos(),
                range * elevation.cos() * azimuth.sin(),
                range * elevation.sin(),
            ));
        }
    }
    points
}

fn bench(c: &mut Criterion) {
    let points = vlp16_points();
    let mut out = Vec::new();
    for (name, format) in [
        ("velodyne_f32_18B", PointFormat::VELODYNE),
        (
            "xyz_f64_padded_be",
            PointFormat { xyz_f64: true, padding: 8, big_endian: true, ..PointFormat::XYZ },
        ),
    ] {
        let cloud = cloud::build(&Stamped::new(1.0, "velodyne"), &points, &[], &[], format).unwrap();
        let bytes = msg::encode(&cloud).unwrap();
        c.bench_function(&format!("decode_cdr_and_points_{name}_28800"), |b| {
            b.iter(|| {
                let cloud: PointCloud2<'_> = msg::decode(std::hint::black_box(&bytes)).unwrap();
                cloud::decode(&cloud, &mut out).unwrap();
                std::hint::black_box(out.len())
            })
        });
    }
}

criterion_group!(benches, bench);

/// The shared recording (`../shared/data` from the repository root, or `$CROPROW_SHARED_DATA`):
/// decoding all 23 real scans vs running the default detector on them. Divide by 23 for per-scan times.
fn sample_scans(c: &mut Criterion) {
    use croprow_core::{DetectorConfig, RowDetector};
    use croprow_io::read::{Recording, ReplayConfig};
    let dir = std::env::var_os("CROPROW_SHARED_DATA")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let path = dir.join("sample-young-corn.mcap");
    let bytes = std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let raw: Vec<Vec<u8>> = mcap::MessageStream::new(&bytes)
        .unwrap()
        .map(|m| m.unwrap())
        .filter(|m| m.channel.topic == "/velodyne_points")
        .map(|m| m.data.into_owned())
        .collect();
    let mut frames = Vec::new();
    let mut replay = Recording::open(&path).unwrap().replay(&ReplayConfig::default()).unwrap();
    while let Some(f) = replay.next_scan() {
        let f = f.unwrap();
        frames.push((f.stamp_s, f.points.to_vec(), f.odom_pose.unwrap(), f.mount));
    }
    assert_eq!(raw.len(), 23);
    let mut out = Vec::new();
    c.bench_function("sample_decode_23_scans", |b| {
        b.iter(|| {
            for r in &raw {
                let cloud: PointCloud2<'_> = msg::decode(r).unwrap();
                cloud::decode(&cloud, &mut out).unwrap();
            }
            std::hint::black_box(out.len())
        })
    });
    c.bench_function("sample_detect_23_scans", |b| {
        b.iter(|| {
            let mut detector = RowDetector::new(DetectorConfig::default()).unwrap();
            for (stamp_s, points, pose, mount) in &frames {
                let scan = croprow_core::Scan { stamp_s: *stamp_s, points, twist: None, attitude: None };
                std::hint::black_box(detector.detect(scan, *pose, mount));
            }
        })
    });
}

criterion_group!(sample, sample_scans);
criterion_main!(benches, sample);
