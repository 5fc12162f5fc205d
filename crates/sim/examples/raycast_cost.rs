//! Cost of full VLP-16 revolutions over the built-in full-size fields, for profiling the ray caster
//! under load where criterion's wall times are noisy: prints the CPU time per revolution (Linux,
//! `/proc/thread-self/schedstat`) and a hash of the scan points, so that a change to the caster can be
//! checked to leave the scans bit for bit the same. Instruction counts of the casting alone:
//!
//! ```text
//! cargo build --release -p croprow-sim --example raycast_cost
//! valgrind --tool=callgrind --toggle-collect='*Lidar*cast_columns*' \
//!     target/release/examples/raycast_cost 3 grown-corn      # Collected / 3 = instructions per revolution
//! ```
//!
//! Add `--cache-sim=yes --LL=2097152,16,64` for cache misses and `--branch-sim=yes` for mispredicted
//! branches (`callgrind_annotate --auto=yes --show=Ir,D1mr,DLmr,Bcm` puts them on source lines).
//!
//! The casting is spread over `cast_packet` and `Scene::cast`/`cast_from` (rays packets leave alone):
//! collect from `Lidar::cast_columns` down as above and read inclusive costs with
//! `callgrind_annotate --inclusive=yes`.
//!
//! Arguments: revolutions (default 50), then scenario names (default: the five field scenarios).

use std::hash::{DefaultHasher, Hasher};

use croprow_core::Pose2;
use croprow_sim::{BodyPose, Field, Lidar, ScanBuffer, Scenario};

#[path = "common/cpu.rs"]
mod cpu;
use cpu::cpu_ns;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let revolutions: usize = args.first().map(|a| a.parse()).transpose()?.unwrap_or(50).max(1);
    let default = ["young-corn", "grown-corn", "young-soybean", "grown-soybean", "curved-corn"];
    let names: Vec<&str> =
        if args.len() > 1 { args[1..].iter().map(String::as_str).collect() } else { default.to_vec() };
    for name in names {
        let s = Scenario::builtin(name)?;
        let t0 = cpu_ns();
        let field = Field::generate(&s.field, s.seed)?;
        let generate_ms = (cpu_ns() - t0) as f64 * 1e-6;
        let mut lidar = Lidar::new(&s.lidar, 1)?;
        let mut scan = ScanBuffer::default();
        let (mut cpu, mut points, mut hash) = (0u64, 0usize, DefaultHasher::new());
        // Step 0.8 m along the lane between revolutions, as the lidar bench does (0.08 m there).
        let mut x = 20.0;
        for _ in 0..revolutions {
            x = if x > 180.0 { 20.0 } else { x + 0.8 };
            let pose = Pose2::new(x, field.lane_y(s.lane(), x), field.row_heading(x));
            let t = cpu_ns();
            lidar.scan(&field, &BodyPose::planar(pose), &mut scan);
            cpu += cpu_ns() - t;
            points += scan.points.len();
            for p in &scan.points {
                hash.write_u32(p.x.to_bits());
                hash.write_u32(p.y.to_bits());
                hash.write_u32(p.z.to_bits());
            }
        }
        let per_rev_ms = cpu as f64 * 1e-6 / revolutions as f64;
        println!(
            "{name:14} {:8} primitives, field built in {generate_ms:6.1} ms | {per_rev_ms:.3} ms CPU per revolution \
             ({:.0} ns/ray), {} points per revolution, scan hash {:016x}",
            field.primitive_count(),
            per_rev_ms * 1e6 / lidar.rays_per_revolution() as f64,
            points / revolutions,
            hash.finish()
        );
    }
    Ok(())
}
