//! Cost of the full closed loop of `croprow bench` (ray-cast VLP-16 with motion skew, robot, wheel
//! odometry and IMU, crop contacts, the EKF at every sensor sample, the `Navigator` at every scan), for
//! profiling it where wall times are noisy: prints the CPU time per simulated 0.1 s, the share of it in
//! the `Navigator` (the rest is the world and the EKF; the clock is read at each scan only, as a read
//! costs ~10 µs) and the real-time factor on one core. Instructions by function:
//!
//! ```text
//! cargo build --release -p croprow-sim --example loop_cost
//! valgrind --tool=callgrind target/release/examples/loop_cost 4 grown-corn
//! callgrind_annotate --inclusive=yes callgrind.out.<pid> | head -60
//! ```
//!
//! Arguments: simulated seconds (default 8), then scenario names (default: grown-corn); the field is
//! cut to 25 m as in `croprow bench`.

use croprow_core::Twist2;
use croprow_core::navigator::{NavInput, Navigator, NavigatorConfig};
use croprow_core::odometry::Ekf;
use croprow_sim::experiment::detection::fuse_odometry;
use croprow_sim::{Scenario, World};

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_ns;

/// Field length of `croprow bench`, m.
const FIELD_LENGTH_M: f64 = 25.0;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let sim_s: f64 = args.first().map(|a| a.parse()).transpose()?.unwrap_or(8.0);
    let names: Vec<&str> =
        if args.len() > 1 { args[1..].iter().map(String::as_str).collect() } else { vec!["grown-corn"] };
    for name in names {
        let mut s = Scenario::builtin(name)?;
        s.field.length_m = FIELD_LENGTH_M;
        let mut world = World::new(&s)?;
        let mut nav = Navigator::new(NavigatorConfig::default())?;
        let mut ekf = Ekf::new(nav.config().ekf.clone())?;
        let mount = s.lidar.mount;
        let mut cmd = Twist2::ZERO;
        let (mut t_nav, mut scans) = (0u64, 0usize);
        let t_start = cpu_ns();
        while world.time_s() < sim_s {
            let step = world.step(cmd)?;
            fuse_odometry(&mut ekf, step.wheel, step.imu)?;
            if let Some(scan) = step.scan {
                scans += 1;
                let t0 = cpu_ns();
                let out = nav.step(NavInput {
                    stamp_s: scan.stamp_s,
                    odom: ekf.pose(),
                    odom_twist: ekf.twist(),
                    scan: Some(scan.as_scan()),
                    mount: &mount,
                    mpc_budget: None,
                    wheel_slip: ekf.wheel_slip(),
                });
                cmd = out.cmd;
                t_nav += cpu_ns() - t0;
            }
        }
        let total_ns = cpu_ns() - t_start;
        let total_s = total_ns as f64 * 1e-9;
        let per_step_ms = |ns: u64| ns as f64 * 1e-6 * 0.1 / world.time_s();
        println!(
            "{name:14} {:.1} s simulated ({scans} scans): {:.2} ms CPU per simulated 0.1 s (world and EKF \
             {:.2}, navigator {:.3}), real-time factor {:.1}",
            world.time_s(),
            per_step_ms(total_ns),
            per_step_ms(total_ns.saturating_sub(t_nav)),
            per_step_ms(t_nav),
            world.time_s() / total_s
        );
    }
    Ok(())
}
