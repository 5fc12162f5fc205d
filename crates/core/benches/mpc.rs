//! MPC solve time at the default horizon (N = 20, 2 s), warm-started as on the robot.
//!
//! Each benchmark iteration is one control cycle of a closed loop on an ideal unicycle: solve, apply
//! the command for one 0.1 s step, measure the new state. So every solve is warm-started from the
//! previous cycle's shifted solution, exactly as in the navigator.
//! * `mpc_warm_solve_n20_following`: following a straight row with detector-like noise on the
//!   measured state (σ 1 cm lateral, 0.5° heading, seeded).
//! * `mpc_warm_solve_n20_recovery`: the paper's recovery case on a curved row (40 m radius): the
//!   robot is put back 30 cm and 8° off every 60 cycles (6 s, 3 m), so the mean covers the transient.
//!
//! `cargo bench -p croprow-core --bench mpc -- --warm-up-time 1 --measurement-time 3`

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use croprow_core::control::mpc::{Mpc, MpcConfig};
use croprow_core::control::path::Path;
use croprow_core::{Pose2, Twist2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

const PERIOD_S: f64 = 0.1;
const SPEED_MPS: f64 = 0.5;

fn advance(p: Pose2, cmd: Twist2) -> Pose2 {
    let mid = p.yaw + 0.5 * cmd.omega * PERIOD_S;
    Pose2::new(
        p.x + cmd.v * PERIOD_S * mid.cos(),
        p.y + cmd.v * PERIOD_S * mid.sin(),
        p.yaw + cmd.omega * PERIOD_S,
    )
}

fn following(c: &mut Criterion) {
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 1e6, 0.0);
    let mut mpc = Mpc::new(MpcConfig::default()).expect("default config is valid");
    let mut rng = ChaCha8Rng::seed_from_u64(1);
    let lateral_noise = Normal::new(0.0, 0.01).expect("valid sigma");
    let heading_noise = Normal::new(0.0, 0.5f64.to_radians()).expect("valid sigma");
    let mut pose = Pose2::default();
    let mut prev = Twist2::new(SPEED_MPS, 0.0);
    c.bench_function("mpc_warm_solve_n20_following", |b| {
        b.iter(|| {
            let mut state = path.project(&pose, pose.x);
            state.lateral_m += lateral_noise.sample(&mut rng);
            state.heading_rad += heading_noise.sample(&mut rng);
            let sol = mpc.solve(black_box(&state), &path, SPEED_MPS, prev, None);
            prev = sol.cmd;
            pose = advance(pose, sol.cmd);
            black_box(sol)
        });
    });
}

fn recovery(c: &mut Criterion) {
    let mut path = Path::with_capacity(1);
    path.push(Pose2::new(-1.0, 0.0, 0.0), 30.0, 1.0 / 40.0);
    let start = Pose2::new(0.0, 0.3, (-8f64).to_radians());
    let mut mpc = Mpc::new(MpcConfig::default()).expect("default config is valid");
    let mut pose = start;
    let mut prev = Twist2::new(SPEED_MPS, 0.0);
    let mut cycle = 0usize;
    c.bench_function("mpc_warm_solve_n20_recovery", |b| {
        b.iter(|| {
            if cycle.is_multiple_of(60) {
                pose = start;
            }
            cycle += 1;
            let state = path.project(&pose, 0.0);
            let sol = mpc.solve(black_box(&state), &path, SPEED_MPS, prev, None);
            prev = sol.cmd;
            pose = advance(pose, sol.cmd);
            black_box(sol)
        });
    });
}

criterion_group!(benches, following, recovery);
criterion_main!(benches);
