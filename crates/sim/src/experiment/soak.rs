//! The soak: many short randomised fields driven end to end by the whole stack, each watched by a
//! [`Monitor`] that counts what must never happen (issue 6, part 3).
//!
//! Where it sits: `seed ─► soak_case ─► ClosedLoop (World, EKF, Navigator) ─► Monitor ─► Outcome`.
//! It is pure (no files, threads or clocks): `croprow evaluate --suite soak` runs the cases in
//! parallel, catches panics per run and writes the report.
//!
//! # The cases
//! [`soak_case`] draws from the seed alone: crop and stage, 10-15 m rows, 0.70-0.80 m spacing, a
//! gentle curve, missing plants, gaps, weeds, relief, the start lane and pose, 2 or 3 lanes to drive
//! (1-2 headland turns, alternately left and right, sometimes skipping a lane) and none, one or two
//! faults from [`crate::faults`] (or a LiDAR that dies for good), placed along the rows with
//! parameters in the issue's ranges. A run drives about 20-45 m. The row curve's skew at the row ends
//! is kept under [`MAX_END_SKEW_RAD`] (the headland turn plans against the measured row ends,
//! [`croprow_core::control::headland`]); turns may go [`HEADLAND_EXCURSION_M`] past them (a 5 m
//! headland).
//!
//! # What the monitor counts
//! Against the simulator's truth, never the navigator's own belief:
//! * **crop contacts**: plants a wheel ran over;
//! * **unsafe commands**: a command that is not finite, outside the MPC's speed or yaw-rate bounds,
//!   changes faster than its acceleration limits, or moves the robot
//!   - while following with no row seen for more than `lane_switch.max_blind_distance_m` (+
//!     [`BLIND_SLACK_M`]), farther than `lane_switch.end_approach_m` (+ [`END_SLACK_M`]) from the true
//!     row end (closer, driving on to the end is the designed behaviour), or
//!   - while entering a lane deeper than `lane_switch.max_unconfirmed_entry_m` (+ [`END_SLACK_M`])
//!     into the crop (past the first plant of the lane's rows ahead when the entry began) without
//!     the detector having confirmed it.
//!
//! Safe stops (rows lost, a lane not confirmed, a time-out at rest, rows never acquired within
//! [`ACQUIRE_TIMEOUT_S`]) are outcomes, not failures.
//!
//! ```no_run
//! use croprow_sim::experiment::soak::{run_case, soak_case};
//! let outcome = run_case(&soak_case(7)).unwrap();
//! assert!(outcome.failures().is_empty(), "{:?}", outcome.failures());
//! ```

use std::fmt::Write as _;

use croprow_core::control::lane_switch::{Mode, TurnDirection};
use croprow_core::navigator::{NavOutput, NavigatorConfig};
use croprow_core::{Pose2, RowStatus, Twist2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use crate::closed_loop::{self, ClosedLoop, RunConfig, RunError};
use crate::field::{Crop, Field, Stage};
use crate::scenario::Scenario;

/// Largest planned distance of `base_link` past a row end on the soak's fields, m: their headland is
/// 5 m, and a turn may need more than the paper's 1.5 m where rows end raggedly.
pub const HEADLAND_EXCURSION_M: f64 = 2.0;
/// Largest angle between the rows and the square headland edge at a row end, rad (see module docs).
pub const MAX_END_SKEW_RAD: f64 = 0.06;
/// Distance beyond `max_blind_distance_m` a robot may still be commanded to move with no row, m: one
/// control step at the highest speed plus the odometry's scale error over the blind stretch.
pub const BLIND_SLACK_M: f64 = 0.15;
/// Slack on distances to the true row end, m: the detector's row-end estimate and the odometry since
/// it was made may be off by this much.
pub const END_SLACK_M: f64 = 0.5;
/// Events kept per run and kind (contacts, unsafe commands); the counts go on.
const MAX_EVENTS: usize = 4;
/// A run whose navigator is still acquiring this long after the standstill ends there, s: a robot
/// that never starts is safe, and waiting out the time limit would only slow the soak down.
pub const ACQUIRE_TIMEOUT_S: f64 = 20.0;
/// Seed offsets of the case generator's streams (field and mission; faults), so that they differ
/// from each other and from the world's.
const SEED_CASE: u64 = 0x50A4_5EED;
const SEED_FAULTS: u64 = 0xFA17_5EED;

/// One soak run: everything `croprow simulate` needs to replay it.
#[derive(Debug, Clone, PartialEq)]
pub struct Case {
    /// The seed the case was drawn from (also the scenario's master seed).
    pub seed: u64,
    /// The field, robot, sensors and start.
    pub scenario: Scenario,
    /// The navigator: the simulator's ([`closed_loop::sim_navigator`]) with [`Case::overrides`].
    pub navigator: NavigatorConfig,
    /// The run settings (lanes to drive, time limit, run-level faults).
    pub run: RunConfig,
    /// The `--set key=value` overrides of `croprow simulate` that turn its defaults into this case's
    /// navigator and run settings (the scenario itself goes in a TOML file).
    pub overrides: Vec<String>,
}

/// Draws the soak case of `seed` (see the module docs); the same seed always gives the same case.
pub fn soak_case(seed: u64) -> Case {
    let mut rng = ChaCha8Rng::seed_from_u64(seed ^ SEED_CASE);
    let mut s = Scenario { seed, ..Scenario::default() };
    let f = &mut s.field;
    f.crop = if rng.random_bool(0.5) { Crop::Corn } else { Crop::Soybean };
    f.stage = if rng.random_bool(0.5) { Stage::Young } else { Stage::Grown };
    f.row_spacing_m = round(rng.random_range(0.70..=0.80), 0.01);
    f.missing_probability = round(rng.random_range(0.0..=0.15), 0.01);
    f.gaps_per_100m = round(rng.random_range(0.0..=6.0), 0.1);
    f.gap_min_m = round(rng.random_range(0.3..=1.0), 0.1);
    f.gap_max_m = round(f.gap_min_m + rng.random_range(0.0..=1.5), 0.1);
    f.weeds_per_m2 = round(rng.random_range(0.0..=1.0), 0.05);
    f.relief_m = if rng.random_bool(0.4) { round(rng.random_range(0.0..=0.1), 0.01) } else { 0.0 };
    f.relief_wavelength_m = round(rng.random_range(8.0..=30.0), 1.0);
    f.headland_m = 5.0;
    // A curve y = A sin(2πx/λ) meets the row ends (x = 0) at slope 2πA/λ: bounded by the end skew.
    if rng.random_bool(0.5) {
        f.curve_wavelength_m = round(rng.random_range(30.0..=100.0), 1.0);
        let a_max = MAX_END_SKEW_RAD.tan() * f.curve_wavelength_m / std::f64::consts::TAU;
        f.curve_amplitude_m = round(rng.random_range(0.0..=a_max), 0.01).min(a_max);
    } else {
        f.curve_amplitude_m = 0.0;
    }

    let lanes: u32 = if rng.random_bool(0.7) { 2 } else { 3 };
    f.length_m =
        round(if lanes == 2 { rng.random_range(10.0..=15.0) } else { rng.random_range(10.0..=12.0) }, 0.1);
    let lane_step: u32 = if rng.random_bool(0.2) { 2 } else { 1 };
    let first_turn = if rng.random_bool(0.5) { TurnDirection::Right } else { TurnDirection::Left };
    // Navigator lanes are two field lanes apart (a lane switch moves over two rows, Sec. III-B).
    let span = 2 * lane_step * (lanes - 1);
    let margin_right: u32 = rng.random_range(0..=2);
    let margin_left: u32 = rng.random_range(0..=2);
    f.rows = margin_right + span + 2 + margin_left;
    let start_lane = match first_turn {
        TurnDirection::Right => margin_right + span,
        TurnDirection::Left => margin_right,
    };
    s.start.lane = Some(start_lane);
    s.start.x_m = round(rng.random_range(0.5..=2.0), 0.1);
    s.start.lateral_offset_m = round(rng.random_range(-0.06..=0.06), 0.01);
    s.start.heading_offset_deg = round(rng.random_range(-3.0..=3.0), 0.1);

    let mut navigator = closed_loop::sim_navigator();
    navigator.lane_switch.first_turn = first_turn;
    navigator.lane_switch.lane_step = lane_step;
    // The soak fields have a 5 m headland: a user with room to spare lets a turn go past the paper's
    // 1.5 m when the measured row ends need it (ragged or skewed ends), rather than stop.
    navigator.lane_switch.max_headland_excursion_m = HEADLAND_EXCURSION_M;
    let length = s.field.length_m;
    let drive_s = f64::from(lanes) * length / navigator.lane_switch.cruise_speed_mps;
    let mut run = RunConfig {
        lanes,
        max_time_s: round(60.0 + 2.0 * (drive_s + f64::from(lanes - 1) * 30.0), 1.0),
        ..RunConfig::default()
    };
    // Faults from their own stream: the field and mission of a seed do not depend on them.
    let mut fault_rng = ChaCha8Rng::seed_from_u64(seed ^ SEED_FAULTS);
    let faults = draw_faults(&mut fault_rng, &mut s, &mut run, lanes);
    let overrides = vec![
        format!("run.lanes={lanes}"),
        format!("run.max_time_s={:?}", run.max_time_s),
        format!(
            "lane_switch.first_turn={}",
            if first_turn == TurnDirection::Left { "left" } else { "right" }
        ),
        format!("lane_switch.lane_step={lane_step}"),
        format!("lane_switch.max_headland_excursion_m={HEADLAND_EXCURSION_M:?}"),
    ]
    .into_iter()
    .chain(run.lidar_blackout_after_m.map(|d| format!("run.lidar_blackout_after_m={d:?}")))
    .collect();

    s.name = format!("soak-{seed}");
    let f = &s.field;
    let mut summary = format!(
        "{} {} {:.1} m x {} rows {:.2} m apart, curve {:.2} m / {:.0} m, weeds {:.2}/m², gaps {:.1}/100 m, \
         relief {:.2} m; {lanes} lanes from lane {start_lane}, first turn {}, step {lane_step}",
        stage_name(f.stage),
        crop_name(f.crop),
        f.length_m,
        f.rows,
        f.row_spacing_m,
        f.curve_amplitude_m,
        f.curve_wavelength_m,
        f.weeds_per_m2,
        f.gaps_per_100m,
        f.relief_m,
        if first_turn == TurnDirection::Left { "left" } else { "right" },
    );
    if !faults.is_empty() {
        let _ = write!(summary, "; faults: {}", faults.join(", "));
    }
    s.summary = summary;
    Case { seed, scenario: s, navigator, run, overrides }
}

/// Fault kinds a case may draw: the simulator's ten ([`crate::faults`]) and a LiDAR that dies for good.
const FAULT_KINDS: usize = 11;

/// Draws none (35 %), one (45 %) or two (20 %) distinct faults into the scenario and the run, placed
/// along the rows of a field `s.field.length_m` long; returns their one-line descriptions.
fn draw_faults(rng: &mut ChaCha8Rng, s: &mut Scenario, run: &mut RunConfig, lanes: u32) -> Vec<String> {
    let count = match rng.random_range(0.0..1.0) {
        p if p < 0.35 => 0,
        p if p < 0.8 => 1,
        _ => 2,
    };
    let first = rng.random_range(0..FAULT_KINDS);
    let second = (first + rng.random_range(1..FAULT_KINDS)) % FAULT_KINDS;
    let length = s.field.length_m;
    let rows = s.field.rows;
    let f = &mut s.faults;
    let mut out = Vec::new();
    for kind in [first, second].into_iter().take(count) {
        // A stretch [from, to] of the rows, m, at least 1 m from their ends.
        let mut stretch = |min_m: f64, max_m: f64| {
            let len = round(rng.random_range(min_m..=max_m), 0.1);
            let from = round(rng.random_range(1.0..=(length - 1.0 - len).max(1.0)), 0.1);
            (from, from + len)
        };
        let (from, to) = stretch(1.0, 6.0);
        let text = match kind {
            0 => {
                let d = &mut f.lidar_dropout;
                d.enabled = true;
                d.from_x_m = from;
                d.duration_s = round(rng.random_range(0.3..=2.0), 0.1);
                d.repeat_every_m =
                    if rng.random_bool(0.3) { round(rng.random_range(3.0..=8.0), 0.1) } else { 0.0 };
                format!("LiDAR dropout {:.1} s at x {from} m (repeat {} m)", d.duration_s, d.repeat_every_m)
            }
            1 => {
                let p = &mut f.partial_scan;
                (p.enabled, p.from_x_m, p.to_x_m) = (true, from, to);
                p.sector_centre_deg = round(rng.random_range(-180.0..=180.0), 1.0);
                p.sector_width_deg = round(rng.random_range(20.0..=120.0), 1.0);
                format!(
                    "{}° sector at {}° missing over x {from}-{to} m",
                    p.sector_width_deg, p.sector_centre_deg
                )
            }
            2 => {
                let r = &mut f.spurious_returns;
                (r.enabled, r.from_x_m, r.to_x_m) = (true, from, to);
                r.points_per_scan = rng.random_range(50..=600);
                format!("{} spurious returns per scan over x {from}-{to:.1} m", r.points_per_scan)
            }
            3 => {
                let w = &mut f.weed_patch;
                (w.enabled, w.from_x_m, w.length_m) = (true, from, round(rng.random_range(1.0..=3.0), 0.1));
                w.height_m = round(rng.random_range(0.2..=0.5), 0.01);
                w.clumps_per_m2 = round(rng.random_range(1.0..=4.0), 0.1);
                format!("weeds {} m tall over {} m from x {from} m", w.height_m, w.length_m)
            }
            4 => {
                // 1-4 m: longer than the detector's 1 m of empty ground that ends a row, and shorter
                // than the 5.6 m the scan sees past a row end from the first pivot, so a stretch missing
                // from every row must be crossed, not turned at (a longer one would look like the
                // headland; see `croprow_core::control::lane_switch`).
                let g = &mut f.row_gap;
                (g.enabled, g.from_x_m, g.length_m) = (true, from, round(rng.random_range(1.0..=4.0), 0.1));
                g.rows = match rng.random_range(0..3) {
                    0 => Vec::new(),
                    n => (0..n).map(|_| rng.random_range(0..rows)).collect(),
                };
                format!("rows {:?} missing over {} m from x {from} m", g.rows, g.length_m)
            }
            5 => {
                let p = &mut f.slip_patch;
                (p.enabled, p.from_x_m, p.to_x_m) = (true, from, to);
                p.longitudinal_slip = round(rng.random_range(0.2..=0.4), 0.01);
                p.lateral_drift_m_s = round(rng.random_range(-0.08..=0.08), 0.01);
                format!(
                    "slip {} drift {} m/s over x {from}-{to:.1} m",
                    p.longitudinal_slip, p.lateral_drift_m_s
                )
            }
            6 => {
                let g = &mut f.gyro_bias_step;
                (g.enabled, g.at_x_m) = (true, from);
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                g.step_rad_s = round(sign * rng.random_range(0.005..=0.03), 0.001);
                format!("gyro bias step {} rad/s at x {from} m", g.step_rad_s)
            }
            7 => {
                let o = &mut f.odometry_timing;
                o.enabled = true;
                o.jitter_s = round(rng.random_range(0.001..=0.01), 0.001);
                o.out_of_order_probability = round(rng.random_range(0.0..=0.1), 0.01);
                format!("odometry jitter {} s, {} out of order", o.jitter_s, o.out_of_order_probability)
            }
            8 => {
                let t = &mut f.scan_stamp;
                (t.enabled, t.from_x_m, t.to_x_m) = (true, from, from + 1.0);
                let sign = if rng.random_bool(0.5) { 1.0 } else { -1.0 };
                t.offset_s = round(sign * rng.random_range(0.05..=1.0), 0.01);
                format!("scans stamped {} s off over x {from}-{:.1} m", t.offset_s, from + 1.0)
            }
            9 => {
                let m = &mut f.mount_error;
                m.enabled = true;
                m.at_x_m = if rng.random_bool(0.5) { -1000.0 } else { from };
                m.roll_deg = round(rng.random_range(-3.0..=3.0), 0.1);
                m.pitch_deg = round(rng.random_range(-3.0..=3.0), 0.1);
                m.yaw_deg = round(rng.random_range(-3.0..=3.0), 0.1);
                format!(
                    "mount off by ({}, {}, {})° from x {} m",
                    m.roll_deg, m.pitch_deg, m.yaw_deg, m.at_x_m
                )
            }
            _ => {
                let after = round(rng.random_range(2.0..=f64::from(lanes) * length), 0.01);
                run.lidar_blackout_after_m = Some(after);
                format!("LiDAR dead after {after} m driven")
            }
        };
        out.push(text);
    }
    out
}

/// The scenario of [`soak_case`] (the field, robot and start; the lanes and faults are in the case).
pub fn soak_scenario(seed: u64) -> Scenario {
    soak_case(seed).scenario
}

fn crop_name(c: Crop) -> &'static str {
    match c {
        Crop::Corn => "corn",
        Crop::Soybean => "soybean",
    }
}

fn stage_name(s: Stage) -> &'static str {
    match s {
        Stage::Young => "young",
        Stage::Grown => "grown",
    }
}

/// `x` rounded to a multiple of `step` (0.1, 0.01, ...): the nearest double to that decimal, so that
/// scenario files and summaries read `3.3`, not `3.3000000000000003`.
fn round(x: f64, step: f64) -> f64 {
    let per_unit = (1.0 / step).round();
    (x * per_unit).round() / per_unit
}

/// Something the monitor saw, where and when (field frame, true pose).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Event {
    /// Simulated time, s.
    pub t_s: f64,
    /// True distance driven so far, m.
    pub distance_m: f64,
    /// True position of `base_link`, m.
    pub x_m: f64,
    /// True position of `base_link`, m.
    pub y_m: f64,
    /// Navigator mode at the time.
    pub mode: &'static str,
    /// What happened.
    pub what: String,
}

/// The limits a [`Monitor`] checks, read from the navigator configuration.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Limits {
    speed_min_mps: f64,
    speed_max_mps: f64,
    yaw_rate_max_radps: f64,
    accel_max_mps2: f64,
    yaw_accel_max_radps2: f64,
    step_s: f64,
    max_blind_m: f64,
    end_approach_m: f64,
    max_unconfirmed_entry_m: f64,
}

/// Watches a closed-loop run against the truth; see the module docs for what it counts.
#[derive(Debug, Clone)]
pub struct Monitor {
    limits: Limits,
    mode: Mode,
    last_truth: Option<Pose2>,
    distance_m: f64,
    /// True distance driven while following since the last detection with a row, m.
    blind_m: f64,
    last_cmd: Twist2,
    last_nav_s: Option<f64>,
    crop_contacts: usize,
    unsafe_commands: usize,
    events: Vec<Event>,
    /// Where the plants of the lane being entered begin (true x, m) and the direction of travel
    /// along x (±1), from the start of the entry.
    crop_start: Option<(f64, f64)>,
}

/// Absolute tolerance on the command bounds (the bounds are exact clamps).
const EPS: f64 = 1e-9;

impl Monitor {
    /// A monitor for a run of the navigator configured by `nav`.
    pub fn new(nav: &NavigatorConfig) -> Self {
        let (m, ls) = (&nav.mpc, &nav.lane_switch);
        Self {
            limits: Limits {
                speed_min_mps: m.speed_min_mps,
                speed_max_mps: m.speed_max_mps,
                yaw_rate_max_radps: m.yaw_rate_max_radps,
                accel_max_mps2: m.accel_max_mps2,
                yaw_accel_max_radps2: m.yaw_accel_max_radps2,
                step_s: m.step_s,
                max_blind_m: ls.max_blind_distance_m,
                end_approach_m: ls.end_approach_m,
                max_unconfirmed_entry_m: ls.max_unconfirmed_entry_m,
            },
            mode: Mode::Acquiring,
            last_truth: None,
            distance_m: 0.0,
            blind_m: 0.0,
            last_cmd: Twist2::ZERO,
            last_nav_s: None,
            crop_contacts: 0,
            unsafe_commands: 0,
            events: Vec::new(),
            crop_start: None,
        }
    }

    /// Observes one world step: the true pose of `base_link` after it, the plants newly run over, and
    /// the navigator's output when it ran in this step.
    pub fn observe(
        &mut self,
        field: &Field,
        t_s: f64,
        truth: Pose2,
        new_contacts: usize,
        nav: Option<&NavOutput>,
    ) {
        let step_m = self.last_truth.map_or(0.0, |p| (truth.x - p.x).hypot(truth.y - p.y));
        self.last_truth = Some(truth);
        self.distance_m += step_m;
        if self.mode == Mode::Following {
            self.blind_m += step_m;
        }
        if let Some(out) = nav {
            if out.mode == Mode::Entering && self.mode != Mode::Entering {
                self.crop_start = crop_start_ahead(field, &truth);
            }
            self.mode = out.mode;
            if out.mode != Mode::Following || out.detection.as_ref().is_some_and(saw_row) {
                self.blind_m = 0.0;
            }
            if let Some(what) = self.check(field, truth, out) {
                self.unsafe_commands += 1;
                self.record(
                    t_s,
                    truth,
                    format!("unsafe command ({:.3} m/s, {:.3} rad/s): {what}", out.cmd.v, out.cmd.omega),
                );
            }
            self.last_cmd = out.cmd;
            self.last_nav_s = Some(out.stamp_s);
        }
        if new_contacts > 0 {
            self.crop_contacts += new_contacts;
            self.record(t_s, truth, format!("{new_contacts} plant(s) run over"));
        }
    }

    /// What is wrong with this command, if anything.
    fn check(&self, field: &Field, truth: Pose2, out: &NavOutput) -> Option<String> {
        let (cmd, l) = (out.cmd, &self.limits);
        if !cmd.is_finite() {
            return Some("not finite".into());
        }
        if cmd.v < l.speed_min_mps - EPS || cmd.v > l.speed_max_mps + EPS {
            return Some(format!("speed outside [{}, {}] m/s", l.speed_min_mps, l.speed_max_mps));
        }
        if cmd.omega.abs() > l.yaw_rate_max_radps + EPS {
            return Some(format!("yaw rate over {} rad/s", l.yaw_rate_max_radps));
        }
        if cmd == Twist2::ZERO {
            // Stopping is always allowed, however abrupt.
            return None;
        }
        if let Some(t0) = self.last_nav_s {
            let dt = (out.stamp_s - t0).min(l.step_s);
            if (cmd.v - self.last_cmd.v).abs() > l.accel_max_mps2 * dt + EPS {
                return Some(format!("acceleration over {} m/s²", l.accel_max_mps2));
            }
            if (cmd.omega - self.last_cmd.omega).abs() > l.yaw_accel_max_radps2 * dt + EPS {
                return Some(format!("yaw acceleration over {} rad/s²", l.yaw_accel_max_radps2));
            }
        }
        let length = field.config().length_m;
        let forward = truth.yaw.cos() >= 0.0;
        match out.mode {
            Mode::Following => {
                let to_end = if forward { length - truth.x } else { truth.x };
                (self.blind_m > l.max_blind_m + BLIND_SLACK_M && to_end > l.end_approach_m + END_SLACK_M)
                    .then(|| {
                        format!(
                            "moving with no row seen for {:.2} m, {to_end:.2} m before the row end",
                            self.blind_m
                        )
                    })
            }
            Mode::Entering => {
                let (start_x, dir) = self.crop_start?;
                let depth = (truth.x - start_x) * dir;
                (depth > l.max_unconfirmed_entry_m + END_SLACK_M)
                    .then(|| format!("entering {depth:.2} m deep into the crop without a confirmed lane"))
            }
            _ => None,
        }
    }

    fn record(&mut self, t_s: f64, truth: Pose2, what: String) {
        let unsafe_kind = what.starts_with("unsafe");
        let same_kind = self.events.iter().filter(|e| e.what.starts_with("unsafe") == unsafe_kind).count();
        if same_kind < MAX_EVENTS {
            self.events.push(Event {
                t_s,
                distance_m: self.distance_m,
                x_m: truth.x,
                y_m: truth.y,
                mode: self.mode.as_str(),
                what,
            });
        }
    }

    /// Plants run over so far.
    pub fn crop_contacts(&self) -> usize {
        self.crop_contacts
    }

    /// Unsafe commands so far.
    pub fn unsafe_commands(&self) -> usize {
        self.unsafe_commands
    }

    /// True distance driven so far, m.
    pub fn distance_m(&self) -> f64 {
        self.distance_m
    }

    /// The first events of each kind (at most four each).
    pub fn events(&self) -> &[Event] {
        &self.events
    }
}

/// Where the first plant ahead of `truth` (field frame) stands in the two rows beside it, as
/// `(x, direction of travel along x)`: the start of the crop a robot entering a lane drives into (a
/// gap across every row ends the crop like a headland does). `None` with no plant ahead.
fn crop_start_ahead(field: &Field, truth: &Pose2) -> Option<(f64, f64)> {
    let dir = if truth.yaw.cos() >= 0.0 { 1.0 } else { -1.0 };
    let lane = ((truth.y - field.row_y(0, truth.x)) / field.config().row_spacing_m).floor();
    let rows = [lane, lane + 1.0].into_iter().filter(|&r| r >= 0.0 && r < f64::from(field.config().rows));
    rows.flat_map(|r| field.row_stems(r as u32))
        .map(|stem| (stem.x_m - truth.x) * dir)
        .filter(|ahead| *ahead >= 0.0)
        .min_by(f64::total_cmp)
        .map(|ahead| (truth.x + dir * ahead, dir))
}

/// True when a detection gave the reference a row to follow (what resets the navigator's blind count).
fn saw_row(d: &croprow_core::Detection) -> bool {
    let finite = |r: &Option<croprow_core::RowEstimate>| r.is_some_and(|r| r.offset_m.is_finite());
    !matches!(d.status, RowStatus::Lost | RowStatus::InvalidInput) && (finite(&d.left) || finite(&d.right))
}

/// The result of one soak run.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Outcome {
    /// The case's seed.
    pub seed: u64,
    /// True distance driven, m.
    pub distance_m: f64,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Plants run over.
    pub crop_contacts: usize,
    /// The least clearance from a tyre's side to a stem beside it, m (negative: a contact; `None`:
    /// no stem passed alongside a tyre). See [`crate::metrics::CropDamage::least_clearance_m`].
    pub least_stem_clearance_m: Option<f64>,
    /// Unsafe commands (see the module docs).
    pub unsafe_commands: usize,
    /// How the run ended: `done`, `stopped: <reason>`, or the mode it timed out in.
    pub end: String,
    /// Lanes whose row end was cleared.
    pub lanes_completed: u32,
    /// Lanes the case asked for.
    pub lanes_planned: u32,
    /// The first events the monitor recorded.
    pub events: Vec<Event>,
}

impl Outcome {
    /// One line per failure (a crop contact or an unsafe command); empty when the run was safe.
    pub fn failures(&self) -> Vec<String> {
        let first = |pred: &dyn Fn(&Event) -> bool| {
            self.events.iter().find(|e| pred(e)).map_or(String::new(), |e| {
                format!(
                    ", first at t {:.1} s, {:.2} m driven, ({:.2}, {:.2}), {}: {}",
                    e.t_s, e.distance_m, e.x_m, e.y_m, e.mode, e.what
                )
            })
        };
        let mut out = Vec::new();
        if self.crop_contacts > 0 {
            out.push(format!(
                "{} crop contact(s){}",
                self.crop_contacts,
                first(&|e| e.what.contains("run over"))
            ));
        }
        if self.unsafe_commands > 0 {
            out.push(format!(
                "{} unsafe command(s){}",
                self.unsafe_commands,
                first(&|e| e.what.starts_with("unsafe"))
            ));
        }
        out
    }
}

/// How a run ended, as a short stable label.
fn end_label(mode: Mode, timed_out: bool) -> String {
    match mode {
        Mode::Stopped { reason } => format!("stopped: {}", reason.as_str()),
        m if timed_out => format!("timed out: {}", m.as_str()),
        m => m.as_str().to_owned(),
    }
}

/// Runs one case closed loop to its end under a [`Monitor`].
pub fn run_case(case: &Case) -> Result<Outcome, RunError> {
    let mut lp = ClosedLoop::new(&case.scenario, &case.navigator, case.run.clone())?;
    let mut monitor = Monitor::new(lp.navigator().config());
    let give_up_s = case.run.standstill_s + ACQUIRE_TIMEOUT_S;
    let mut never_started = false;
    while !lp.is_finished() {
        lp.step()?;
        if lp.progress().mode == Mode::Acquiring && lp.world().time_s() >= give_up_s {
            never_started = true;
            break;
        }
        if let Some(tick) = lp.last_tick() {
            let truth = tick.step.truth.pose;
            monitor.observe(
                lp.world().field(),
                tick.step.stamp_s,
                truth,
                tick.step.new_contacts,
                tick.nav.as_ref(),
            );
        }
    }
    let run = lp.finish();
    let m = &run.metrics;
    Ok(Outcome {
        seed: case.seed,
        distance_m: monitor.distance_m(),
        sim_time_s: m.sim_time_s,
        crop_contacts: monitor.crop_contacts(),
        least_stem_clearance_m: m.least_stem_clearance_m,
        unsafe_commands: monitor.unsafe_commands(),
        end: if never_started { "never acquired".to_owned() } else { end_label(m.final_mode, m.timed_out) },
        lanes_completed: m.lanes_completed,
        lanes_planned: m.lanes_planned,
        events: monitor.events,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::FieldConfig;

    fn field() -> Field {
        Field::generate(&FieldConfig { length_m: 10.0, rows: 4, ..FieldConfig::default() }, 1).unwrap()
    }

    fn output(t: f64, cmd: Twist2, mode: Mode, detection: Option<croprow_core::Detection>) -> NavOutput {
        NavOutput {
            stamp_s: t,
            cmd,
            mode,
            detection,
            solve_status: None,
            solve_iterations: 0,
            tracking: None,
            lanes_completed: 0,
            lane: 0,
            input_fault: None,
        }
    }

    fn rows(t: f64) -> croprow_core::Detection {
        let row = croprow_core::RowEstimate {
            line: [0.0, 0.375, 4.0, 0.375],
            offset_m: 0.375,
            heading_rad: 0.0,
            curvature_per_m: 0.0,
            confidence: 1.0,
        };
        croprow_core::Detection { left: Some(row), ..croprow_core::Detection::empty(t, RowStatus::Tracking) }
    }

    /// Drives the monitor along +x at `v` from x = 1 for `steps` control steps of 0.05 s, with rows seen
    /// only on the first step.
    fn drive_blind(steps: usize, v: f64) -> Monitor {
        let field = field();
        let mut m = Monitor::new(&closed_loop::sim_navigator());
        let cmd = Twist2::new(v, 0.0);
        let mut pose = Pose2::new(1.0, 0.0, 0.0);
        let mut last = Twist2::ZERO;
        for i in 0..steps {
            let t = i as f64 * 0.05;
            // Within the acceleration limit: 0.8 m/s² · 0.05 s.
            let c = Twist2::new((last.v + 0.04).min(cmd.v), 0.0);
            last = c;
            let det = (i == 0).then(|| rows(t));
            m.observe(&field, t, pose, 0, Some(&output(t, c, Mode::Following, det)));
            pose.x += c.v * 0.05;
        }
        m
    }

    #[test]
    fn cases_are_reproducible_valid_and_short() {
        for seed in 0..300 {
            let c = soak_case(seed);
            assert_eq!(c, soak_case(seed));
            c.scenario.validate().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            c.run.validate().unwrap();
            let nav = closed_loop::navigator_config(&c.scenario, &c.navigator, &c.run);
            nav.validate().unwrap_or_else(|e| panic!("seed {seed}: {e}"));
            let f = &c.scenario.field;
            assert!((10.0..=15.0).contains(&f.length_m), "seed {seed}: {}", f.length_m);
            assert!(matches!(c.run.lanes, 2 | 3));
            // Every lane the mission plans exists in the field.
            let ls = &c.navigator.lane_switch;
            let span = 2 * ls.lane_step * (c.run.lanes - 1);
            let start = c.scenario.lane();
            match ls.first_turn {
                TurnDirection::Right => assert!(start >= span, "seed {seed}"),
                TurnDirection::Left => assert!(start + span <= f.rows - 2, "seed {seed}"),
            }
            let skew = (std::f64::consts::TAU * f.curve_amplitude_m / f.curve_wavelength_m).atan();
            assert!(skew <= MAX_END_SKEW_RAD + 1e-9, "seed {seed}: skew {skew}");
        }
        assert_ne!(soak_case(1).scenario, soak_case(2).scenario);
    }

    #[test]
    fn case_scenario_round_trips_through_toml() {
        for seed in [0, 5, 99] {
            let s = soak_scenario(seed);
            let text = toml::to_string(&s).unwrap();
            assert_eq!(Scenario::from_toml_str(&text).unwrap(), s, "seed {seed}");
        }
    }

    #[test]
    fn a_command_over_the_speed_limit_is_unsafe() {
        let mut m = Monitor::new(&closed_loop::sim_navigator());
        let out = output(0.0, Twist2::new(1.5, 0.0), Mode::Following, Some(rows(0.0)));
        m.observe(&field(), 0.0, Pose2::new(1.0, 0.0, 0.0), 0, Some(&out));
        assert_eq!(m.unsafe_commands(), 1);
        assert!(m.events()[0].what.contains("speed outside"), "{:?}", m.events());
    }

    #[test]
    fn a_non_finite_command_is_unsafe() {
        let mut m = Monitor::new(&closed_loop::sim_navigator());
        let out = output(0.0, Twist2::new(f64::NAN, 0.0), Mode::Following, Some(rows(0.0)));
        m.observe(&field(), 0.0, Pose2::new(1.0, 0.0, 0.0), 0, Some(&out));
        assert_eq!(m.unsafe_commands(), 1);
    }

    #[test]
    fn a_jump_in_speed_is_unsafe() {
        let mut m = Monitor::new(&closed_loop::sim_navigator());
        let f = field();
        let p = Pose2::new(1.0, 0.0, 0.0);
        m.observe(&f, 0.0, p, 0, Some(&output(0.0, Twist2::new(0.1, 0.0), Mode::Following, Some(rows(0.0)))));
        m.observe(&f, 0.05, p, 0, Some(&output(0.05, Twist2::new(0.5, 0.0), Mode::Following, None)));
        assert_eq!(m.unsafe_commands(), 1);
        assert!(m.events()[0].what.contains("acceleration"), "{:?}", m.events());
    }

    #[test]
    fn moving_blind_beyond_the_blind_distance_is_unsafe() {
        // 0.5 m/s for 60 steps of 0.05 s: ~1.3 m blind, from x = 1 to 2.3, far from the end at 10 m.
        let m = drive_blind(60, 0.5);
        assert!(m.unsafe_commands() > 0);
        assert!(m.events()[0].what.contains("no row seen"), "{:?}", m.events());
    }

    #[test]
    fn moving_blind_within_the_blind_distance_is_safe() {
        // ~0.9 m blind: under the 1 m default.
        let m = drive_blind(45, 0.5);
        assert_eq!(m.unsafe_commands(), 0, "{:?}", m.events());
    }

    /// A robot that began entering at x = -0.8 m (plants from x ≈ 0) and is now at `x_m`, moving.
    fn entering_at(x_m: f64) -> Monitor {
        let (f, nav) = (field(), closed_loop::sim_navigator());
        let mut m = Monitor::new(&nav);
        let y = f.lane_y(1, 0.0);
        m.observe(
            &f,
            0.0,
            Pose2::new(-0.8, y, 0.0),
            0,
            Some(&output(0.0, Twist2::ZERO, Mode::Entering, None)),
        );
        let moving = output(0.05, Twist2::new(0.04, 0.0), Mode::Entering, None);
        m.observe(&f, 0.05, Pose2::new(x_m, y, 0.0), 0, Some(&moving));
        m
    }

    #[test]
    fn entering_deep_into_the_crop_unconfirmed_is_unsafe() {
        // 1.8 m past the first plant: over the 1 m limit plus the 0.5 m slack.
        let m = entering_at(1.8);
        assert_eq!(m.unsafe_commands(), 1, "{:?}", m.events());
        assert!(m.events()[0].what.contains("deep into the crop"), "{:?}", m.events());
        assert_eq!(entering_at(1.2).unsafe_commands(), 0);
    }

    #[test]
    fn contacts_are_counted_with_where_they_happened() {
        let mut m = Monitor::new(&closed_loop::sim_navigator());
        m.observe(&field(), 2.0, Pose2::new(3.0, 0.4, 0.0), 2, None);
        assert_eq!(m.crop_contacts(), 2);
        assert_eq!(m.events()[0].x_m, 3.0);
    }
}
