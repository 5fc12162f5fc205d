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
//!
//! 2026-11-22 after the coarse height blocks (commit 8265261), back to back with the binary before it,
//! twice each (load average 2.5-5): young corn 6.79 / 3.97 ms before, 4.02 / 4.74 ms after; grown corn
//! 7.42 / 5.59 ms before, 5.69 / 5.58 ms after per 0.1 s simulated, i.e. about 18x real time for grown
//! corn either way: the 4 % fewer casting instructions are inside the wall-time noise.
//!
//! 2026-11-22, beam packets (branch `raycast`), load average 7-8 so wall times are inflated: CPU time
//! of 8 s simulated (`examples/world_cost.rs`, median of 3 runs alternating the binaries) before ->
//! after: grown corn 5.6 -> 3.7 ms per 0.1 s simulated, real-time factor 17.9x -> 27.0x; young corn
//! 4.3 -> 2.4 ms, 23.4x -> 42.2x. The LiDAR is 99.8 % of a world step's instructions (callgrind).
//!
//! 2026-11-22, the packets' table of tested primitives (branch `simperf3`; 21 % fewer casting
//! instructions, see the lidar bench): CPU time of 8 s simulated over grown corn, 3 runs alternating
//! the binaries at load average 11 on the 2 cores: before 3.7 / 3.5 / 4.0 ms, after 3.5 / 3.5 / 4.0 ms
//! per 0.1 s simulated (real-time factor 25-29x either way): inside the noise of a loaded machine.

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
