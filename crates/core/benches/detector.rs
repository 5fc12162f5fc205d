//! Detector benchmark: one full-resolution VLP-16 scan (16 rings × 1800 azimuths = 28,800 points, an
//! organised cloud with NaN where a ray has no return) over a grown-crop canopy, from the test fixture. Whole `detect` step for
//! both modes, then each stage alone; the default mode's preprocessing again with the motion deskew on
//! (`deskew/Preprocess`: its cost is the difference to `default/Preprocess`).
//!
//! `cargo bench -p croprow-core --bench detector -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_core::perception::Stage;
use croprow_core::{DetectorConfig, Mount, Point3, Pose2, RowDetector, Scan, Twist2};

#[path = "../tests/support/mod.rs"]
mod support;

/// Scans of a grown, closed canopy, 0.1 m apart, and their poses.
fn scans() -> Vec<(Pose2, Vec<Point3>)> {
    let field = support::Field::grown_closed();
    let mut lidar = support::Lidar::vlp16(42);
    lidar.organized = true;
    (0..40)
        .map(|i| {
            let pose = Pose2::new(0.1 * i as f64, 0.02, 0.01);
            let pts = lidar.scan(&field, &pose, &Mount::default());
            (pose, pts)
        })
        .collect()
}

/// A detector that has run over every scan but the last (a warm map, tracked rows).
fn warm(config: DetectorConfig, scans: &[(Pose2, Vec<Point3>)]) -> RowDetector {
    let mut det = RowDetector::new(config).expect("valid config");
    for (i, (pose, pts)) in scans.iter().enumerate().take(scans.len() - 1) {
        det.detect(
            Scan { stamp_s: 0.1 * i as f64, points: pts, twist: None, attitude: None },
            *pose,
            &Mount::default(),
        );
    }
    det
}

fn bench(c: &mut Criterion) {
    let scans = scans();
    let mount = Mount::default();
    let (pose, pts) = scans.last().cloned().expect("scans");
    let returns = pts.iter().filter(|p| p.is_finite()).count();
    eprintln!("scan: {} points, {returns} returns", pts.len());
    let mut g = c.benchmark_group("detector");
    for (name, config) in [("default", DetectorConfig::default()), ("paper", DetectorConfig::paper())] {
        let base = warm(config, &scans);
        // Whole step: every iteration continues from the warm state with a later stamp (robot at rest).
        let mut det = base.clone();
        let mut t = 0.1 * (scans.len() - 2) as f64;
        g.bench_function(format!("{name}/detect"), |b| {
            b.iter(|| {
                t += 0.1;
                black_box(det.detect(
                    Scan { stamp_s: t, points: &pts, twist: None, attitude: None },
                    pose,
                    &mount,
                ))
            })
        });
        let mut det = base.clone();
        for stage in [Stage::Preprocess, Stage::Cluster, Stage::Fit] {
            det.run_stage(
                Stage::Preprocess,
                Scan { stamp_s: 0.0, points: &pts, twist: None, attitude: None },
                pose,
                &mount,
            );
            g.bench_function(format!("{name}/{stage:?}"), |b| {
                b.iter(|| {
                    black_box(det.run_stage(
                        stage,
                        Scan { stamp_s: 0.0, points: &pts, twist: None, attitude: None },
                        pose,
                        &mount,
                    ))
                })
            });
        }
    }
    // The deskew runs inside the preprocessing pass, on the cropped returns of a turning robot.
    let deskew = DetectorConfig { deskew: true, ..DetectorConfig::default() };
    let mut det = warm(deskew, &scans);
    let turning = Scan { stamp_s: 0.0, points: &pts, twist: Some(Twist2::new(0.5, 0.2)), attitude: None };
    g.bench_function("deskew/Preprocess", |b| {
        b.iter(|| black_box(det.run_stage(Stage::Preprocess, turning, pose, &mount)))
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
