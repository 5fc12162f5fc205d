//! Row following under the MPC, closed loop with the EKF and the default detector, on 20 m of each
//! simulated Table I field, against the paper's cross-track means (Table I, Sec. V-B), plus recovery
//! from an offset start (Fig. 6) and the safety stop when the rows vanish mid-row.

use croprow_core::control::lane_switch::{Mode, StopReason};
use croprow_sim::Scenario;
use croprow_sim::closed_loop::{self, Run, RunConfig};

/// Runs scenario `name` cut to `length_m` of rows, one lane.
fn follow(name: &str, length_m: f64, cfg: RunConfig) -> Run {
    let mut s = Scenario::builtin(name).unwrap();
    s.field.length_m = s.start.x_m + length_m;
    closed_loop::run(&s, closed_loop::sim_navigator(), RunConfig { lanes: 1, ..cfg }, |_| {}).unwrap()
}

/// A clean single-lane run whose cross-track mean beats the paper's `paper_cm`.
fn beats_the_paper(name: &str, paper_cm: f64) {
    let run = follow(name, 20.0, RunConfig::default());
    let m = &run.metrics;
    eprintln!(
        "{name}: {:.2} ± {:.2} cm (paper {paper_cm} cm)",
        m.cross_track_mean_m * 100.0,
        m.cross_track_std_m * 100.0
    );
    assert_eq!(m.final_mode, Mode::Done, "{name}: {m:?}");
    assert_eq!((m.crop_contacts, m.command_violations), (0, 0), "{name}: {m:?}");
    assert!(m.following_samples > 300, "{name}: {m:?}");
    assert!(m.cross_track_mean_m * 100.0 < paper_cm, "{name}: {m:?}");
}

#[test]
fn young_corn_follows_at_least_as_well_as_the_paper() {
    beats_the_paper("young-corn", 0.97);
}

#[test]
fn grown_corn_follows_at_least_as_well_as_the_paper() {
    beats_the_paper("grown-corn", 2.45);
}

#[test]
fn young_soybean_follows_at_least_as_well_as_the_paper() {
    beats_the_paper("young-soybean", 0.64);
}

#[test]
fn grown_soybean_follows_within_the_measured_bound() {
    // Known gap (issue 4): the paper reports 1.24 cm over 200 m; this 20 m run measures 1.37 cm. It was
    // 1.52 cm while the simulator's EKF trusted the wheel yaw rate in turns (`ekf.wheel_yaw_rate_slip`
    // 0.3, see `closed_loop::sim_navigator`): the scrubbing tyres over-read the corrections made at the
    // start of a lane on the closed canopy. This bound guards what is measured now against regressions;
    // beating 1.24 cm on short runs is open work.
    beats_the_paper("grown-soybean", 1.4);
}

#[test]
fn curved_corn_follows_under_our_three_centimetre_aim() {
    // The paper: 9.21 cm; our aim: under 3 cm.
    beats_the_paper("curved-corn", 3.0);
}

#[test]
fn recovers_from_a_start_0_3_m_and_8_degrees_off_within_3_m() {
    let run = follow("recovery", 12.0, RunConfig::default());
    let m = &run.metrics;
    eprintln!("recovery: {m:?}");
    let settle = m.settle_distance_m.expect("settles under 2 cm");
    assert!(settle <= 3.0, "settled after {settle:.2} m");
    // Issue 4 asks for no crop contact; this start makes some unavoidable. Tyres 0.15 m wide at ±0.762 m
    // stay off the rows (±0.375 m, ±1.125 m from the centre line) only while each tyre centre keeps
    // 0.45-1.05 m from the centre line: a robot y to the left with heading ψ needs
    // y + 0.61·|sin ψ| ≤ 0.288 m for its left tyres (front ones when ψ > 0, rear ones when ψ < 0).
    // * The start pose (y = 0.3, ψ = 8°) already has the front-left tyre on the row at 1.125 m and the
    //   front-right one on the lane's right row: 0.24 m of row line under tyre patches, 1.4 plants at
    //   0.17 m spacing on average.
    // * At y = 0.3 no heading clears the left tyres, and only driving forward with ψ < 0 reduces y,
    //   which swings the rear-left tyre onto the row: some row length is always run over. A search
    //   over pivot-drive-pivot-drive manoeuvres of a forward-only unicycle finds at least 1.33 m of
    //   row line under the tyres, 7.8 plants on average.
    // Measured with the MPC's wheel corridor: 12, all in the first metre, then none (10 while the MPC
    // could speed up past the cruise speed to escape sooner, which it may no longer; 13 without the
    // corridor).
    let after_first_metre = run.samples.iter().find(|s| s.distance_m >= 1.0).map(|s| s.crop_contacts);
    assert_eq!(after_first_metre, Some(m.crop_contacts), "{m:?}");
    assert!(m.crop_contacts <= 12, "{m:?}");
}

/// Row lines (at `(k + ½)·spacing` from the lane centre line, k = -3..=2) that lie under a tyre patch
/// of a robot at lateral offset `y_m` (left of the centre line) and heading `psi_rad` (to the rows),
/// as `(tyre index, row offset)`, from the robot and field geometry of scenario `name`.
fn rows_under_tyres(name: &str, y_m: f64, psi_rad: f64) -> Vec<(usize, f64)> {
    let s = Scenario::builtin(name).unwrap();
    let spacing = s.field.row_spacing_m;
    let (half_w, half_l) = (0.5 * s.robot.tire_width_m, 0.5 * s.robot.contact_length_m);
    let (sin, cos) = psi_rad.sin_cos();
    let mut under = Vec::new();
    for (i, (x, y)) in s.robot.wheel_positions().into_iter().enumerate() {
        let centre = y_m + x * sin + y * cos;
        // Lateral half-extent of a rectangle `2 half_l` long, `2 half_w` wide, turned by ψ.
        let reach = half_w * cos.abs() + half_l * sin.abs();
        for k in -3..=2 {
            let row = (f64::from(k) + 0.5) * spacing;
            if (row - centre).abs() <= reach {
                under.push((i, row));
            }
        }
    }
    under
}

#[test]
fn the_recovery_start_already_has_a_tyre_over_a_row() {
    // Zero contacts is impossible from this start, whatever the controller does: at 0.3 m left of the
    // centre line a tyre patch already covers a row line at t = 0, for either start heading. With
    // the default geometry (0.75 m spacing, wheels at ±0.6095 m and ±0.762 m, patches 0.12 × 0.15 m):
    // heading +8° puts the front-left tyre (centre 0.3 + 0.085 + 0.755 = 1.140 m, reaching 0.083 m
    // to either side) on the row at 1.125 m and the front-right one (−0.370 m) on the lane's right
    // row; heading −8° does the same with the two rear tyres.
    let s = Scenario::builtin("recovery").unwrap();
    let (y, psi) = (s.start.lateral_offset_m, s.start.heading_offset_deg.to_radians());
    assert!((y - 0.3).abs() < 1e-12 && (psi.to_degrees() - 8.0).abs() < 1e-12, "{:?}", s.start);
    assert_eq!(rows_under_tyres("recovery", y, psi), vec![(0, 1.125), (1, -0.375)]);
    assert_eq!(rows_under_tyres("recovery", y, -psi), vec![(2, 1.125), (3, -0.375)]);
    // The check itself: centred and aligned, every tyre runs in its inter-row.
    assert!(rows_under_tyres("recovery", 0.0, 0.0).is_empty());
}

#[test]
fn rows_vanishing_mid_row_stop_the_robot() {
    // A dead LiDAR 8 m into a 20 m row: the navigator must stop, not drive on blind.
    let cfg = RunConfig { lidar_blackout_after_m: Some(8.0), ..RunConfig::default() };
    let run = follow("young-corn", 20.0, cfg);
    let m = &run.metrics;
    assert!(
        matches!(m.final_mode, Mode::Stopped { reason: StopReason::NoRows | StopReason::RowsLost }),
        "{m:?}"
    );
    // At most `lane_switch.max_blind_distance_m` (1 m) blind plus braking from 0.5 m/s.
    assert!(m.distance_m < 8.0 + 1.0 + 0.5, "{m:?}");
    let last = run.samples.last().unwrap();
    assert_eq!((last.cmd.v, last.cmd.omega), (0.0, 0.0));
    assert_eq!(m.crop_contacts, 0);
}
