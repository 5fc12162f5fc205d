//! Simulation throughput: 0.1 s of simulated time (10 steps of 0.01 s: one full LiDAR revolution with
//! motion skew, robot dynamics, wheel odometry, IMU, crop-contact check, human-like driver) on one core.
//! Real-time factor = 0.1 s / time per iteration.
//!
//! `cargo bench -p croprow-sim --bench world -- --warm-up-time 1 --measurement-time 3`
//!
//! Measured 2026-11-22 on the shared 2-core build machine (load average 3-5; wall time), before ->
//! after the per-cell height ranges of the ray caster (commit 76b93fa), both binaries run back to back:
//! young corn 4.79 -> 3.71 ms, grown corn 9.87 -> 7.33 ms per 0.1 s simulated, i.e. a real-time factor
//! of 21x -> 27x and 10x -> 14x. The ray casting dominates: one revolution alone costs most of it on
//! the lidar bench.

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_sim::{Scenario, World};

fn step(c: &mut Criterion) {
    let mut group = c.benchmark_group("world_0.1s");
    for name in ["young-corn", "grown-corn"] {
        let s = Scenario::builtin(name).expect("built-in scenario");
        let mut world = World::new(&s).expect("valid scenario");
        let mut driver = world.driver().expect("valid driver");
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut points = 0;
                for _ in 0..10 {
                    // Drive back to the start before the rows end, so every iteration is in the crop.
                    if world.robot().pose().x > 190.0 {
                        world = World::new(&s).expect("valid scenario");
                    }
                    let cmd = driver.command(world.time_s(), &world.robot().pose(), world.field());
                    let step = world.step(cmd).expect("finite command");
                    points += step.scan.map_or(0, |s| s.points.len());
                }
                points
            })
        });
    }
    group.finish();
}

criterion_group!(benches, step);
criterion_main!(benches);
