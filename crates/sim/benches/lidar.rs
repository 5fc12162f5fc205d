//! Ray-casting cost of one full VLP-16 revolution (28,800 rays) over full-size (200 m x 16 rows) fields.
//! ns/ray = time per revolution / 28,800.
//!
//! `cargo bench -p croprow-sim --bench lidar -- --warm-up-time 1 --measurement-time 3`

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_core::Pose2;
use croprow_sim::{BodyPose, Field, Lidar, ScanBuffer, Scenario};

fn revolution(c: &mut Criterion) {
    let mut group = c.benchmark_group("lidar_revolution");
    for name in ["young-corn", "grown-corn", "young-soybean", "grown-soybean", "curved-corn"] {
        let s = Scenario::builtin(name).expect("built-in scenario");
        let field = Field::generate(&s.field, s.seed).expect("valid field");
        let mut lidar = Lidar::new(&s.lidar, 1).expect("valid lidar");
        let mut scan = ScanBuffer::default();
        let lane = s.lane();
        // Step along the lane between iterations so caches see a moving robot, as in a run.
        let mut x = 20.0;
        group.bench_function(name, |b| {
            b.iter(|| {
                x = if x > 180.0 { 20.0 } else { x + 0.08 };
                let pose = Pose2::new(x, field.lane_y(lane, x), field.row_heading(x));
                lidar.scan(&field, &BodyPose::planar(pose), &mut scan);
                scan.points.len()
            })
        });
    }
    group.finish();
}

criterion_group!(benches, revolution);
criterion_main!(benches);
