//! What the EKF's slip witness (`ekf.slip`) reads over one soak seed's closed-loop run, against the
//! simulator's wet patch: once a second the true x, whether the robot is in the patch, the mode and
//! the witness's read; then how long the read stood at `lane_switch.slipping_min_slip` or more while
//! following, in the patch and out of it (docs/faults.md, session 50).
//!
//! `cargo run --release -p croprow-sim --example slip_witness -- SEED...`

use croprow_core::control::lane_switch::Mode;
use croprow_sim::closed_loop::ClosedLoop;
use croprow_sim::experiment::soak::soak_case;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let seeds: Vec<u64> = std::env::args().skip(1).map(|s| s.parse()).collect::<Result<_, _>>()?;
    for seed in if seeds.is_empty() { vec![13] } else { seeds } {
        let case = soak_case(seed);
        let patch = case.scenario.faults.slip_patch.clone();
        let min_slip = case.navigator.lane_switch.slipping_min_slip;
        println!("seed {seed}: {}", case.scenario.summary);
        let mut lp = ClosedLoop::new(&case.scenario, &case.navigator, case.run.clone())?;
        // Following time with the read at `min_slip` or more, and all following time, s: [dry, wet].
        let (mut read_s, mut following_s) = ([0.0; 2], [0.0; 2]);
        // Highest read while following, dry and wet.
        let mut highest = [f64::NEG_INFINITY; 2];
        let mut next_print_s = 0.0;
        while !lp.is_finished() {
            lp.step()?;
            let Some(tick) = lp.last_tick() else { continue };
            let x = tick.step.truth.pose.x;
            let wet = usize::from(patch.covers(x));
            let slip = lp.ekf().and_then(|e| e.wheel_slip());
            let mode = lp.progress().mode;
            if mode == Mode::Following {
                let dt = case.scenario.world.dt_s;
                following_s[wet] += dt;
                highest[wet] = highest[wet].max(slip.unwrap_or(f64::NEG_INFINITY));
                if slip.is_some_and(|s| s >= min_slip) {
                    read_s[wet] += dt;
                }
            }
            if tick.step.stamp_s >= next_print_s {
                next_print_s += 1.0;
                let slip = slip.map_or("-".to_owned(), |s| format!("{s:.2}"));
                println!("  t {:5.1} s  x {x:5.2} m  wet {wet}  {mode:?}  slip {slip}", tick.step.stamp_s);
            }
        }
        println!(
            "  following with slip >= {min_slip}: dry {:.1} of {:.1} s, wet {:.1} of {:.1} s; highest read dry {:.2}, wet {:.2}",
            read_s[0], following_s[0], read_s[1], following_s[1], highest[0], highest[1]
        );
    }
    Ok(())
}
