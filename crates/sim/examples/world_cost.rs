//! Cost of the simulated world alone (LiDAR with motion skew, robot, sensors, crop contacts) driven by
//! the scenario's human-like driver, for profiling the closed loop under load where wall times are
//! noisy: prints the CPU time per simulated second and the real-time factor on one core. Where the
//! instructions go:
//!
//! ```text
//! cargo build --release -p croprow-sim --example world_cost
//! valgrind --tool=callgrind target/release/examples/world_cost 2 grown-corn
//! callgrind_annotate --inclusive=yes callgrind.out.<pid> | grep croprow_sim
//! ```
//!
//! Arguments: simulated seconds (default 8), then scenario names (default: grown-corn, young-corn).

use croprow_sim::{Scenario, World};

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_ns;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let sim_s: f64 = args.first().map(|a| a.parse()).transpose()?.unwrap_or(8.0);
    let default = ["grown-corn", "young-corn"];
    let names: Vec<&str> =
        if args.len() > 1 { args[1..].iter().map(String::as_str).collect() } else { default.to_vec() };
    for name in names {
        let s = Scenario::builtin(name)?;
        let mut world = World::new(&s)?;
        let mut driver = world.driver()?;
        let (t0, mut scans) = (cpu_ns(), 0usize);
        while world.time_s() < sim_s {
            let cmd = driver.command(world.time_s(), &world.robot().pose(), world.field());
            scans += usize::from(world.step(cmd)?.scan.is_some());
        }
        let cpu_s = (cpu_ns() - t0) as f64 * 1e-9;
        println!(
            "{name:14} {:.1} s simulated ({scans} scans) in {cpu_s:.3} s CPU: {:.1} ms per simulated 0.1 s, \
             real-time factor {:.1}",
            world.time_s(),
            cpu_s * 1e3 * 0.1 / world.time_s(),
            world.time_s() / cpu_s
        );
    }
    Ok(())
}
