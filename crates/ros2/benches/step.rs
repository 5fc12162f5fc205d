//! Cost of one node step without DDS: a scan step (PointCloud2 decode, pose lookup, detector, lane
//! switching, MPC; 18,000 points of the synthetic field) and a control tick between scans (MPC only),
//! with the robot driving along the rows at 0.5 m/s so the detector and the solver warm-start as
//! on the robot. The robot drives open loop (straight along the lane), so every step tracks.
//!
//! `cargo bench -p croprow-ros2 --bench step -- --warm-up-time 1 --measurement-time 3`

#[path = "../tests/support/mod.rs"]
mod support;

use std::hint::black_box;
use std::time::{Duration, Instant};

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use croprow_core::control::Mode;
use croprow_core::{Mount, Pose2, Twist2};
use croprow_ros2::{NodeConfig, NodeCore};
use support::Field;

/// A node that has been following the rows for 3 s, its clock and the robot's pose.
fn following_node(field: &Field, mount: &Mount) -> (NodeCore, f64, Pose2) {
    let mut node = NodeCore::new(NodeConfig::default()).unwrap();
    let twist = Twist2::new(0.5, 0.0);
    let mut pose = Pose2::default();
    let mut t = 10.0;
    for i in 0..30 {
        t += 0.1;
        pose = support::drive(pose, twist, 0.1);
        node.on_odometry(t, &support::odometry(t, pose, twist)).unwrap();
        node.on_cloud(t, &support::cloud(t, &field.scan(pose, mount, i))).unwrap();
    }
    assert_eq!(node.navigator().lane_switcher().mode(), Mode::Following, "the bench measures row following");
    (node, t, pose)
}

fn bench(c: &mut Criterion) {
    // Rows long enough for every iteration criterion runs.
    let field = Field { end_x_m: 1.0e6, ..Field::default() };
    let mount = Mount::default();
    let twist = Twist2::new(0.5, 0.0);
    let (mut node, mut t, mut pose) = following_node(&field, &mount);
    let mut seed = 1000;
    c.bench_function("scan_step_18k_points", |b| {
        b.iter_batched(
            || {
                // Excluded from the timing: the robot moves on and its LiDAR sees the next scan.
                t += 0.1;
                seed += 1;
                pose = support::drive(pose, twist, 0.1);
                (t, support::odometry(t, pose, twist), support::cloud(t, &field.scan(pose, &mount, seed)))
            },
            |(t, odom, cloud)| {
                node.on_odometry(t, &odom).unwrap();
                node.on_cloud(t, &cloud).unwrap()
            },
            BatchSize::SmallInput,
        )
    });
    let (mut node, mut t, mut pose) = following_node(&field, &mount);
    c.bench_function("control_tick", |b| {
        b.iter_custom(|iters| {
            // Only the ticks are timed; every fifth 20 ms slot also brings a scan, as on the robot.
            let mut timed = Duration::ZERO;
            for i in 0..iters {
                t += 0.02;
                pose = support::drive(pose, twist, 0.02);
                node.on_odometry(t, &support::odometry(t, pose, twist)).unwrap();
                if i % 5 == 0 {
                    seed += 1;
                    node.on_cloud(t, &support::cloud(t, &field.scan(pose, &mount, seed))).unwrap();
                }
                let start = Instant::now();
                let out = black_box(node.tick(t));
                timed += start.elapsed();
                assert!(
                    out.halt.is_none() && out.nav.is_some_and(|n| n.solve_status.is_some()),
                    "{}",
                    out.status.data
                );
            }
            timed
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
