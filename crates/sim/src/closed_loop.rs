//! The closed loop: the simulated robot driven by the whole croprow stack, scored against the truth.
//!
//! ```text
//! World ──wheel odometry + IMU──► Ekf (or the true pose with `sensors.perfect_odometry`) ──odom──┐
//!       ──LiDAR scan (10 Hz)─────────────────────────────────────────────────────────────────────┤
//!                                                                                                ▼
//!       ◄──────────── Twist2 (held between control steps) ◄── Navigator (detector, reference, MPC, lanes)
//! ```
//!
//! The world steps at the scenario's `world.dt_s`; the navigator runs every `run.control_period_s`
//! and on every completed scan (so each scan is used with the odometry pose of its stamp). The `odom`
//! frame is the field frame at the start of the run: the EKF starts at the true start pose.
//!
//! A [`ClosedLoop`] is stepped by the caller (so a recorder can see every scan and command), or
//! [`run`] drives it to the end. The [`Run`] it returns holds the trajectory and the [`Metrics`]:
//!
//! * cross-track statistics (`cross_track_*`, `heading_err_mean_deg`) are taken only while the
//!   navigator is **following** a lane (mode `following`): headland turns, the drive past a row end
//!   and the entry into a new lane are excluded; errors are to the TRUE centre line of the lane the
//!   navigator is in, at the TRUE pose;
//! * `settle_distance_m` is the distance travelled until the cross-track error stays under
//!   `run.settle_threshold_m` for the rest of the first lane's following (`None` if it never does);
//! * `max_headland_excursion_m` is how far `base_link` went past the rows' ends (`x = 0` and
//!   `x = field.length_m`, where plants stop) while clearing a row end, turning or entering;
//!   `max_wheel_excursion_m` is the same for the farthest wheel contact patch;
//! * a lane is covered when the robot drove along its centre line (within a quarter row spacing)
//!   from within `run.coverage_end_tolerance_m` of one end of the rows to as near the other end;
//!   `rows_covered` counts the distinct rows on either side of covered lanes;
//! * every command is checked finite and inside the MPC's speed and yaw-rate bounds.
//!
//! ```no_run
//! use croprow_sim::Scenario;
//! use croprow_sim::closed_loop::{self, RunConfig};
//! let scenario = Scenario::builtin("full-field").unwrap();
//! let run = closed_loop::run(&scenario, closed_loop::sim_navigator(), RunConfig::default(), |_| {}).unwrap();
//! assert_eq!(run.metrics.rows_covered, 16);
//! ```

use std::f64::consts::{FRAC_PI_2, PI};

use croprow_core::control::lane_switch::{Mode, TurnDirection};
use croprow_core::error::check_range;
use croprow_core::geometry::wrap_angle;
use croprow_core::navigator::{NavInput, NavOutput, Navigator, NavigatorConfig};
use croprow_core::odometry::{AttitudeFilter, Ekf, EkfConfig};
use croprow_core::{ConfigError, Pose2, RowStatus, Scan, Twist2};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::field::Field;
use crate::metrics::{self, ErrorStats};
use crate::robot::StepError;
use crate::scenario::{Scenario, ScenarioError};
use crate::world::{ScanView, Step, World};

/// Settings of a closed-loop run (the `[run]` section next to the navigator's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RunConfig {
    /// Period of the navigator's control steps, s. Default 0.05 (20 Hz; scans add a step at 10 Hz).
    pub control_period_s: f64,
    /// Lanes to drive; 0 drives every lane from the start lane to the field edge the first turn
    /// heads for (whole-field coverage). Sets `lane_switch.lanes`. Default 0.
    pub lanes: u32,
    /// Longest simulated time, s; 0 sets it from the mission: twice the time the lanes take at the
    /// entry speed, plus a minute. Default 0.
    pub max_time_s: f64,
    /// Cross-track error under which the robot counts as settled, m. Default 0.02 (issue 4).
    pub settle_threshold_m: f64,
    /// Distance of a lane's drive from each end of the rows that still counts as covering the lane,
    /// m. Default 2.0 (the built-in scenarios start up to 2 m into the rows).
    pub coverage_end_tolerance_m: f64,
    /// Time simulated after the navigator has stopped (done or a safety stop) so that the robot
    /// comes to rest, s. Default 2.
    pub stop_linger_s: f64,
    /// The robot stands still this long before the navigator starts, s: the EKF learns the gyro bias
    /// from a robot at rest (as a robot calibrates its gyro at start-up). Default 3.
    pub standstill_s: f64,
    /// Fault injection: from this distance travelled on, every scan is empty (a dead LiDAR), m.
    /// Default none.
    pub lidar_blackout_after_m: Option<f64>,
    /// Time the run waits at a stop that can clear by itself (rows lost, no rows: see
    /// `StopReason::clears_by_itself`) for the navigator to resume before it ends, s. Default 10.
    pub resume_wait_s: f64,
}

impl Default for RunConfig {
    fn default() -> Self {
        Self {
            control_period_s: 0.05,
            lanes: 0,
            max_time_s: 0.0,
            settle_threshold_m: 0.02,
            coverage_end_tolerance_m: 2.0,
            stop_linger_s: 2.0,
            standstill_s: 3.0,
            lidar_blackout_after_m: None,
            resume_wait_s: 10.0,
        }
    }
}

impl RunConfig {
    /// Checks every field, naming the first bad one (`run.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("run.control_period_s", self.control_period_s, 1e-3, 1.0)?;
        check_range("run.lanes", f64::from(self.lanes), 0.0, 10_000.0)?;
        check_range("run.max_time_s", self.max_time_s, 0.0, 1e6)?;
        check_range("run.settle_threshold_m", self.settle_threshold_m, 1e-4, 1.0)?;
        check_range("run.coverage_end_tolerance_m", self.coverage_end_tolerance_m, 0.0, 100.0)?;
        check_range("run.stop_linger_s", self.stop_linger_s, 0.0, 60.0)?;
        check_range("run.standstill_s", self.standstill_s, 0.0, 600.0)?;
        check_range("run.resume_wait_s", self.resume_wait_s, 0.0, 3600.0)?;
        if let Some(d) = self.lidar_blackout_after_m {
            check_range("run.lidar_blackout_after_m", d, 0.0, 1e6)?;
        }
        Ok(())
    }
}

/// Why a run could not start or go on.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum RunError {
    /// The scenario is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// The navigator or run configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The world refused a step (a non-finite command: a bug upstream, never silently driven).
    #[error(transparent)]
    Step(#[from] StepError),
}

/// One control step of the run, in the field frame (= `odom` at the start), SI units.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Sample {
    /// Simulated time, s.
    pub t_s: f64,
    /// True pose of `base_link` in the field frame.
    pub truth: Pose2,
    /// Pose of `base_link` in `odom` as the robot believes it.
    pub odom: Pose2,
    /// Command sent, body frame.
    pub cmd: Twist2,
    /// Mission mode after the step.
    pub mode: Mode,
    /// Lane (between rows `lane` and `lane + 1`) the errors are measured to: the lane being driven,
    /// or, while turning and entering, the next one.
    pub lane: u32,
    /// Signed true cross-track error to that lane's centre line, m, positive to the left of the
    /// direction of travel along the lane.
    pub cross_track_m: f64,
    /// True heading error to that lane's direction of travel, rad, positive left.
    pub heading_err_rad: f64,
    /// True distance travelled since the start, m.
    pub distance_m: f64,
    /// Detector status, when a scan came with this step.
    pub detection: Option<RowStatus>,
    /// Plants run over since the start.
    pub crop_contacts: usize,
}

/// The scores of a run; see the module docs for what each one covers.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metrics {
    /// Mean absolute cross-track error while following, m.
    pub cross_track_mean_m: f64,
    /// Standard deviation of the absolute cross-track error while following, m.
    pub cross_track_std_m: f64,
    /// Largest absolute cross-track error while following, m.
    pub cross_track_max_m: f64,
    /// Mean absolute heading error while following, deg.
    pub heading_err_mean_deg: f64,
    /// Control steps the statistics were taken over.
    pub following_samples: usize,
    /// Plants run over.
    pub crop_contacts: usize,
    /// The least clearance from a tyre's side to a stem beside it, m: negative on a contact, `None`
    /// when no stem passed alongside a tyre (see [`crate::metrics::CropDamage::least_clearance_m`]).
    pub least_stem_clearance_m: Option<f64>,
    /// Lanes whose row end was cleared.
    pub lanes_completed: u32,
    /// Lanes the mission asked for.
    pub lanes_planned: u32,
    /// Distinct rows beside covered lanes.
    pub rows_covered: u32,
    /// Farthest `base_link` went past the rows' ends in headland manoeuvres, m.
    pub max_headland_excursion_m: f64,
    /// Farthest a wheel contact patch went past the rows' ends in headland manoeuvres, m.
    pub max_wheel_excursion_m: f64,
    /// True distance travelled, m.
    pub distance_m: f64,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Distance travelled until the cross-track error stays under the threshold, m.
    pub settle_distance_m: Option<f64>,
    /// Commands that were not finite or outside the MPC's bounds (must be 0).
    pub command_violations: usize,
    /// Mode at the end (`done` when the mission finished).
    pub final_mode: Mode,
    /// Scans the detector processed.
    pub scans: usize,
    /// Odometry samples the EKF refused, and accelerometer samples the attitude filter refused (out
    /// of order).
    pub ekf_rejections: usize,
    /// The run hit `run.max_time_s` before the navigator stopped.
    pub timed_out: bool,
}

/// The record of a closed-loop run.
#[derive(Debug, Clone)]
pub struct Run {
    /// Scenario name.
    pub scenario: String,
    /// Scores.
    pub metrics: Metrics,
    /// One sample per control step.
    pub samples: Vec<Sample>,
    /// Detected rows `[x1, y1, x2, y2]` (from `base_link`) placed in the field frame with the true
    /// pose at their scan, m, while following: they show the detector's error, not the odometry's drift.
    pub detected_rows: Vec<[f64; 4]>,
    /// True row centre polylines `[x, y]` in the field frame, every 0.5 m, m.
    pub true_rows: Vec<Vec<[f64; 2]>>,
}

/// How far the run is, for a progress bar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Progress {
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// Time limit, s.
    pub max_time_s: f64,
    /// Lanes whose row end was cleared.
    pub lanes_completed: u32,
    /// Lanes planned.
    pub lanes_planned: u32,
    /// Current mode.
    pub mode: Mode,
}

/// What one world step did, borrowed from the loop until its next step (for recorders).
#[derive(Debug, Clone, Copy)]
pub struct Tick<'a> {
    /// The world's step: truth, wheel odometry, IMU.
    pub step: Step<'a>,
    /// The scan completed in this step (as given to the detector: empty during a blackout).
    pub scan: Option<ScanView<'a>>,
    /// Odometry pose in `odom` at the step.
    pub odom: Pose2,
    /// Odometry twist at the step.
    pub odom_twist: Twist2,
    /// The navigator's output, when it ran in this step.
    pub nav: Option<NavOutput>,
}

/// The navigator configuration for the simulated robot: the defaults, with the EKF tuned to the
/// simulated skid-steer ([`crate::experiment::detection::ekf_config`]) but trusting the wheel yaw rate
/// even less while driving (`ekf.wheel_yaw_rate_per_speed` 3 instead of 0.5): in the closed loop the
/// robot's own corrections and turns make the wheel yaw rate worse than under the human-like driver.
/// Measured on 40 m of young corn, closed loop: 0.5 gave a heading drift that wanders (up to 0.04 rad)
/// and 2.03 ± 2.06 cm cross-track; 3 a steady 0.0015 rad/m drift and 0.50 ± 0.38 cm.
/// The wheel yaw rate in turns on the spot is trusted less too (`ekf.wheel_yaw_rate_slip` 1 instead of
/// 0.3): the simulated tyres scrub, so the wheels report a pivot 1.3 times too fast, a steady error the
/// filter must not average in. Measured on the `full-field` run: 0.3 turned the odometry heading by
/// 0.08-0.12 rad in each pair of headland pivots (and a lane entry was refused as the wrong lane);
/// 1 by at most 0.04 rad, as much as the heading drifts along one 30 m lane. Row following gains too:
/// 20 m of grown soybean went from 1.52 to 1.37 cm cross-track.
///
/// Samples up to 30 ms late (`ekf.max_lag_s`) are fused rather than dropped: stamp jitter and a wheel
/// message overtaken by the next one (`faults.odometry_timing`) then cost nothing.
pub fn sim_navigator() -> NavigatorConfig {
    let ekf = EkfConfig {
        wheel_yaw_rate_per_speed: 3.0,
        wheel_yaw_rate_slip: 1.0,
        max_lag_s: 0.03,
        ..crate::experiment::detection::ekf_config()
    };
    NavigatorConfig { ekf, ..NavigatorConfig::default() }
}

/// The navigator configuration a scenario's run uses: `base` with the lane-switch geometry of the
/// field (`lane_switch.row_spacing_m`) and of the robot (wheel positions and tyre patches, which set
/// where a headland turn may start and the MPC's wheel corridor), and the number of lanes of the mission (`lane_switch.lanes`).
pub fn navigator_config(scenario: &Scenario, base: &NavigatorConfig, run: &RunConfig) -> NavigatorConfig {
    let mut cfg = base.clone();
    cfg.lane_switch.row_spacing_m = scenario.field.row_spacing_m;
    let robot = &scenario.robot;
    cfg.lane_switch.wheel_x_m = 0.5 * robot.wheelbase_m;
    cfg.lane_switch.wheel_y_m = 0.5 * robot.track_m;
    cfg.lane_switch.tire_width_m = robot.tire_width_m;
    cfg.lane_switch.tire_length_m = robot.contact_length_m;
    cfg.mpc.wheel_x_m = cfg.lane_switch.wheel_x_m;
    cfg.mpc.wheel_y_m = cfg.lane_switch.wheel_y_m;
    cfg.mpc.tire_width_m = robot.tire_width_m;
    cfg.lane_switch.lanes = if run.lanes > 0 { run.lanes } else { lanes_to_edge(scenario, &cfg) };
    cfg
}

/// Lanes from the scenario's start lane to the field edge the first turn heads for.
fn lanes_to_edge(scenario: &Scenario, cfg: &NavigatorConfig) -> u32 {
    let stride = 2 * cfg.lane_switch.lane_step.max(1);
    let lane = scenario.lane();
    let room = match cfg.lane_switch.first_turn {
        TurnDirection::Right => lane,
        TurnDirection::Left => scenario.field.rows.saturating_sub(2).saturating_sub(lane),
    };
    room / stride + 1
}

/// The closed loop, stepped by the caller; see the module docs.
#[derive(Debug)]
pub struct ClosedLoop {
    cfg: RunConfig,
    name: String,
    world: World,
    ekf: Option<Ekf>,
    /// Roll and pitch from the accelerometer (`attitude.enabled`); none when off.
    attitude: Option<AttitudeFilter>,
    nav: Navigator,
    mount: croprow_core::Mount,
    control_every: u64,
    steps: u64,
    cmd: Twist2,
    mode: Mode,
    lanes_completed: u32,
    lanes_planned: u32,
    /// The field lane of navigator lane `start_lane`; the direction the lanes move in (−1: towards
    /// row 0); navigator lanes moved per switch.
    lane0: i64,
    turn_sign: i64,
    lane_step: i64,
    start_lane: u32,
    max_time_s: f64,
    stopped_at_s: Option<f64>,
    last_truth: Pose2,
    distance_m: f64,
    // Scores.
    cross: ErrorStats,
    heading: ErrorStats,
    settle: Settle,
    coverage: Vec<Option<(f64, f64)>>,
    excursion_m: f64,
    wheel_excursion_m: f64,
    violations: usize,
    scans: usize,
    ekf_rejections: usize,
    samples: Vec<Sample>,
    detected_rows: Vec<[f64; 4]>,
    last: Option<LastStep>,
}

/// The copyable part of the last step (its scan is read back from the world).
#[derive(Debug, Clone, Copy)]
struct LastStep {
    step: Step<'static>,
    scan_done: bool,
    blackout: bool,
    odom: Pose2,
    odom_twist: Twist2,
    nav: Option<NavOutput>,
}

/// Tracks the first lane's settle distance.
#[derive(Debug, Clone, Copy, Default)]
struct Settle {
    /// Distance at the last following sample of the first lane at or over the threshold.
    last_over_m: Option<f64>,
    /// Following samples seen in the first lane; the last one's error.
    seen: bool,
    last_over: bool,
    closed: bool,
}

impl ClosedLoop {
    /// Builds the world and the navigator (`base` adjusted by [`navigator_config`]).
    pub fn new(scenario: &Scenario, base: &NavigatorConfig, cfg: RunConfig) -> Result<Self, RunError> {
        cfg.validate()?;
        let nav_cfg = navigator_config(scenario, base, &cfg);
        let world = World::new(scenario)?;
        let ekf = if scenario.sensors.perfect_odometry {
            None
        } else {
            let mut ekf = Ekf::new(nav_cfg.ekf.clone())?;
            // `odom` starts on the true start pose: the field frame and `odom` coincide at t = 0.
            ekf.reset(world.time_s(), world.robot().pose())
                .map_err(|e| ConfigError::invalid("start", e.to_string()))?;
            Some(ekf)
        };
        let dt = scenario.world.dt_s;
        let control_every = ((cfg.control_period_s / dt).round() as u64).max(1);
        let ls = &nav_cfg.lane_switch;
        let lanes_planned = ls.lane_count();
        let sign = match ls.first_turn {
            TurnDirection::Right => -1,
            TurnDirection::Left => 1,
        };
        let max_time_s = if cfg.max_time_s > 0.0 {
            cfg.max_time_s
        } else {
            let per_lane_m =
                scenario.field.length_m + 4.0 * ls.row_spacing_m + 2.0 * ls.max_headland_excursion_m;
            2.0 * f64::from(lanes_planned) * per_lane_m / ls.entry_speed_mps.min(ls.cruise_speed_mps)
                + 60.0
                + cfg.standstill_s
        };
        let rows = scenario.field.rows;
        let start = world.robot().pose();
        Ok(Self {
            name: scenario.name.clone(),
            mount: scenario.lidar.mount,
            attitude: nav_cfg
                .attitude
                .enabled
                .then(|| AttitudeFilter::new(nav_cfg.attitude.clone()))
                .transpose()?,
            nav: Navigator::new(nav_cfg.clone())?,
            ekf,
            control_every,
            steps: 0,
            cmd: Twist2::ZERO,
            mode: Mode::Acquiring,
            lanes_completed: 0,
            lanes_planned,
            lane0: i64::from(scenario.lane()),
            turn_sign: sign,
            lane_step: i64::from(ls.lane_step),
            start_lane: ls.start_lane,
            max_time_s,
            stopped_at_s: None,
            last_truth: start,
            distance_m: 0.0,
            cross: ErrorStats::default(),
            heading: ErrorStats::default(),
            settle: Settle::default(),
            coverage: vec![None; rows.saturating_sub(1) as usize],
            excursion_m: 0.0,
            wheel_excursion_m: 0.0,
            violations: 0,
            scans: 0,
            ekf_rejections: 0,
            samples: Vec::with_capacity((max_time_s / cfg.control_period_s).min(1e6) as usize),
            detected_rows: Vec::new(),
            last: None,
            world,
            cfg,
        })
    }

    /// The world (field, robot, LiDAR).
    pub fn world(&self) -> &World {
        &self.world
    }

    /// The navigator (detector centroids, path being tracked).
    pub fn navigator(&self) -> &Navigator {
        &self.nav
    }

    /// The odometry filter (`None` with perfect odometry).
    pub fn ekf(&self) -> Option<&Ekf> {
        self.ekf.as_ref()
    }

    /// The run's configuration.
    pub fn config(&self) -> &RunConfig {
        &self.cfg
    }

    /// True once the navigator has stopped for `run.stop_linger_s` (`run.resume_wait_s` if the stop
    /// can clear by itself), or time ran out.
    pub fn is_finished(&self) -> bool {
        let t = self.world.time_s();
        let wait = match self.mode {
            Mode::Stopped { reason } if reason.clears_by_itself() => {
                self.cfg.stop_linger_s.max(self.cfg.resume_wait_s)
            }
            _ => self.cfg.stop_linger_s,
        };
        t >= self.max_time_s || self.stopped_at_s.is_some_and(|s| t - s >= wait)
    }

    /// Where the run is.
    pub fn progress(&self) -> Progress {
        Progress {
            sim_time_s: self.world.time_s(),
            max_time_s: self.max_time_s,
            lanes_completed: self.lanes_completed,
            lanes_planned: self.lanes_planned,
            mode: self.mode,
        }
    }

    /// The field lane the errors are measured to (see [`Sample::lane`]).
    fn target_lane(&self, nav_lane: u32) -> Option<u32> {
        let ahead = if matches!(self.mode, Mode::Turning | Mode::Entering) { self.lane_step } else { 0 };
        // Navigator lanes are pairs of rows: one navigator lane is two field lanes over.
        let k = i64::from(nav_lane) - i64::from(self.start_lane) + ahead;
        let lane = self.lane0 + self.turn_sign * 2 * k;
        u32::try_from(lane).ok().filter(|&l| (l as usize) < self.coverage.len())
    }

    /// What the last step did (`None` before the first step).
    pub fn last_tick(&self) -> Option<Tick<'_>> {
        let last = self.last?;
        let scan = completed_scan(&self.world, last.scan_done, last.blackout);
        Some(Tick {
            step: Step { scan, ..last.step },
            scan,
            odom: last.odom,
            odom_twist: last.odom_twist,
            nav: last.nav,
        })
    }

    /// Advances the world by one step and runs the navigator when due; [`ClosedLoop::last_tick`]
    /// tells what happened.
    pub fn step(&mut self) -> Result<(), RunError> {
        let (step_copy, scan_done) = {
            let s = self.world.step(self.cmd)?;
            let copy: Step<'static> = Step {
                stamp_s: s.stamp_s,
                truth: s.truth,
                true_twist: s.true_twist,
                wheel: s.wheel,
                imu: s.imu,
                scan: None,
                new_contacts: s.new_contacts,
            };
            (copy, s.scan.is_some())
        };
        let t = step_copy.stamp_s;
        let (odom, odom_twist) = match self.ekf.as_mut() {
            None => (step_copy.truth.pose, step_copy.true_twist),
            Some(ekf) => {
                let mut rejected = 0;
                if let Some(w) = step_copy.wheel {
                    rejected += usize::from(ekf.update_wheel(w.stamp_s, w.twist.v, w.twist.omega).is_err());
                }
                if let Some(imu) = step_copy.imu {
                    rejected += usize::from(ekf.update_imu(imu.stamp_s, imu.gyro_z_rad_s).is_err());
                }
                rejected += usize::from(ekf.predict_to(t).is_err());
                self.ekf_rejections += rejected;
                (ekf.pose(), ekf.twist())
            }
        };
        if let (Some(filter), Some(imu)) = (self.attitude.as_mut(), step_copy.imu) {
            let force = [imu.accel_x_m_s2, imu.accel_y_m_s2, imu.accel_z_m_s2];
            // A sample the odometry-timing fault put out of order is refused, and counted.
            self.ekf_rejections += usize::from(filter.update(imu.stamp_s, force, odom_twist).is_err());
        }
        let truth = step_copy.truth.pose;
        self.distance_m += (truth.x - self.last_truth.x).hypot(truth.y - self.last_truth.y);
        self.last_truth = truth;
        self.steps += 1;

        let mut nav = None;
        let blackout = self.cfg.lidar_blackout_after_m.is_some_and(|d| self.distance_m >= d);
        let scan = completed_scan(&self.world, scan_done, blackout);
        let started = t >= self.cfg.standstill_s - 1e-9;
        let attitude = self.attitude.as_ref().and_then(AttitudeFilter::attitude);
        if started && (scan.is_some() || self.steps.is_multiple_of(self.control_every)) {
            let input = NavInput {
                stamp_s: t,
                odom,
                odom_twist,
                scan: scan.map(|s| Scan { stamp_s: s.stamp_s, points: s.points, twist: None, attitude }),
                mount: &self.mount,
                mpc_budget: None,
                wheel_slip: self.ekf.as_ref().and_then(Ekf::wheel_slip),
            };
            nav = Some(self.nav.step(input));
        }
        if let Some(out) = &nav {
            self.cmd = out.cmd;
            self.mode = out.mode;
            self.lanes_completed = out.lanes_completed;
            self.score(out, truth, odom, t);
        }
        let field = self.world.field();
        if matches!(self.mode, Mode::ClearingRowEnd | Mode::Turning | Mode::Entering) {
            self.excursion_m = self.excursion_m.max(past_ends(field, truth.x));
            for (x, _) in self.world.robot().wheel_contacts() {
                self.wheel_excursion_m = self.wheel_excursion_m.max(past_ends(field, x));
            }
        }
        if self.mode.is_stopped() && self.mode != Mode::Acquiring {
            self.stopped_at_s.get_or_insert(t);
        } else {
            // The navigator resumed by itself.
            self.stopped_at_s = None;
        }
        self.last = Some(LastStep { step: step_copy, scan_done, blackout, odom, odom_twist, nav });
        Ok(())
    }

    /// Scores one navigator output against the truth.
    fn score(&mut self, out: &NavOutput, truth: Pose2, odom: Pose2, t: f64) {
        let cmd = out.cmd;
        let mpc = &self.nav.config().mpc;
        let eps = 1e-9;
        if !cmd.is_finite()
            || cmd.v < mpc.speed_min_mps - eps
            || cmd.v > mpc.speed_max_mps + eps
            || cmd.omega.abs() > mpc.yaw_rate_max_radps + eps
        {
            self.violations += 1;
        }
        if let Some(d) = &out.detection {
            self.scans += 1;
            // Only the rows the navigator follows by: while it turns or enters a lane the detector's
            // lines are not used, and drawn they would hide the headland.
            let rows = if out.mode == Mode::Following { [d.left, d.right] } else { [None, None] };
            for row in rows.into_iter().flatten() {
                let [x1, y1, x2, y2] = row.line;
                let (a, b) = truth.transform_point(x1, y1);
                let (c, e) = truth.transform_point(x2, y2);
                if [a, b, c, e].iter().all(|v| v.is_finite()) {
                    self.detected_rows.push([a, b, c, e]);
                }
            }
        }
        let lane = self.target_lane(out.lane);
        let field = self.world.field();
        let ct = lane.and_then(|l| metrics::cross_track(field, l, &truth));
        let (mut lateral, mut heading) = ct.map_or((f64::NAN, f64::NAN), |c| (c.lateral_m, c.heading_rad));
        if heading.abs() > FRAC_PI_2 {
            // Driving the lane towards -x: errors relative to the direction of travel.
            heading = wrap_angle(heading + PI);
            lateral = -lateral;
        }
        if out.mode == Mode::Following {
            self.cross.add(lateral);
            self.heading.add(heading.to_degrees());
        }
        // Settling: following samples of the first lane only.
        if out.mode == Mode::Following && out.lanes_completed == 0 && !self.settle.closed {
            self.settle.seen = true;
            let over = lateral.is_nan() || lateral.abs() >= self.cfg.settle_threshold_m;
            if over {
                self.settle.last_over_m = Some(self.distance_m);
            }
            self.settle.last_over = over;
        } else if self.settle.seen {
            self.settle.closed = true;
        }
        if let (Some(l), Some(c)) = (lane, ct)
            && !matches!(out.mode, Mode::Turning)
            && c.lateral_m.abs() < 0.25 * field.config().row_spacing_m
            && let Some(slot) = self.coverage.get_mut(l as usize)
        {
            let (lo, hi) = slot.get_or_insert((truth.x, truth.x));
            *lo = lo.min(truth.x);
            *hi = hi.max(truth.x);
        }
        self.samples.push(Sample {
            t_s: t,
            truth,
            odom,
            cmd,
            mode: out.mode,
            lane: lane.unwrap_or(u32::MAX),
            cross_track_m: lateral,
            heading_err_rad: heading,
            distance_m: self.distance_m,
            detection: out.detection.map(|d| d.status),
            crop_contacts: self.world.crop_contacts(),
        });
    }

    /// Ends the run: metrics and record.
    pub fn finish(self) -> Run {
        let field = self.world.field();
        let length = field.config().length_m;
        let tol = self.cfg.coverage_end_tolerance_m;
        let mut rows = vec![false; field.config().rows as usize];
        for (lane, span) in self.coverage.iter().enumerate() {
            if let Some((lo, hi)) = span
                && *lo <= tol
                && *hi >= length - tol
            {
                for r in [lane, lane + 1] {
                    if let Some(slot) = rows.get_mut(r) {
                        *slot = true;
                    }
                }
            }
        }
        let settle_distance_m = match (self.settle.seen, self.settle.last_over, self.settle.last_over_m) {
            (false, _, _) | (true, true, _) => None,
            (true, false, last) => Some(last.unwrap_or(0.0)),
        };
        let t = self.world.time_s();
        let metrics = Metrics {
            cross_track_mean_m: self.cross.mae(),
            cross_track_std_m: self.cross.std(),
            cross_track_max_m: self.cross.max(),
            heading_err_mean_deg: self.heading.mae(),
            following_samples: self.cross.count(),
            crop_contacts: self.world.crop_contacts(),
            least_stem_clearance_m: self.world.least_stem_clearance_m(),
            lanes_completed: self.lanes_completed,
            lanes_planned: self.lanes_planned,
            rows_covered: rows.iter().filter(|r| **r).count() as u32,
            max_headland_excursion_m: self.excursion_m,
            max_wheel_excursion_m: self.wheel_excursion_m,
            distance_m: self.distance_m,
            sim_time_s: t,
            settle_distance_m,
            command_violations: self.violations,
            final_mode: self.mode,
            scans: self.scans,
            ekf_rejections: self.ekf_rejections,
            timed_out: self.stopped_at_s.is_none() && t >= self.max_time_s,
        };
        Run {
            scenario: self.name,
            metrics,
            samples: self.samples,
            detected_rows: self.detected_rows,
            true_rows: row_polylines(field, 0.5),
        }
    }
}

/// The scan completed in this step as the detector gets it (empty during a LiDAR blackout).
fn completed_scan(world: &World, done: bool, blackout: bool) -> Option<ScanView<'_>> {
    let scan = if done { world.last_scan() } else { None };
    scan.map(|s| if blackout { ScanView { points: &[], classes: &[], ..s } } else { s })
}

/// How far `x` lies outside the rows' extent `[0, length_m]`, m (0 inside).
fn past_ends(field: &Field, x: f64) -> f64 {
    (x - field.config().length_m).max(-x).max(0.0)
}

/// True row centre curves sampled every `step_m` over the rows' length.
pub fn row_polylines(field: &Field, step_m: f64) -> Vec<Vec<[f64; 2]>> {
    let length = field.config().length_m;
    let n = (length / step_m.max(1e-3)).ceil() as usize;
    (0..field.config().rows)
        .map(|r| {
            (0..=n)
                .map(|i| {
                    let x = (i as f64 * step_m).min(length);
                    [x, field.row_y(r, x)]
                })
                .collect()
        })
        .collect()
}

/// Runs a scenario closed loop to the end; `progress` is called after every control step.
pub fn run(
    scenario: &Scenario,
    base: NavigatorConfig,
    cfg: RunConfig,
    mut progress: impl FnMut(&Progress),
) -> Result<Run, RunError> {
    let mut lp = ClosedLoop::new(scenario, &base, cfg)?;
    while !lp.is_finished() {
        lp.step()?;
        if lp.last_tick().is_some_and(|t| t.nav.is_some()) {
            progress(&lp.progress());
        }
    }
    Ok(lp.finish())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn absurd_run_settings_are_refused_by_name() {
        let e = RunConfig { control_period_s: 0.0, ..RunConfig::default() }.validate().unwrap_err();
        assert!(e.to_string().contains("run.control_period_s"), "{e}");
        let e = RunConfig { lidar_blackout_after_m: Some(f64::NAN), ..RunConfig::default() }
            .validate()
            .unwrap_err();
        assert!(e.to_string().contains("run.lidar_blackout_after_m"), "{e}");
    }

    #[test]
    fn whole_field_coverage_plans_every_lane_pair_to_the_edge() {
        // full-field: 16 rows, start lane 14 (rows 14 and 15), first turn right (towards row 0).
        let s = Scenario::builtin("full-field").unwrap();
        let cfg = navigator_config(&s, &sim_navigator(), &RunConfig::default());
        assert_eq!(cfg.lane_switch.lanes, 8);
        assert_eq!(cfg.lane_switch.row_spacing_m, s.field.row_spacing_m);
        let one = navigator_config(&s, &sim_navigator(), &RunConfig { lanes: 1, ..RunConfig::default() });
        assert_eq!(one.lane_switch.lanes, 1);
    }

    #[test]
    fn errors_are_measured_to_the_lane_the_navigator_drives() {
        let mut s = Scenario::builtin("full-field").unwrap();
        s.field.length_m = 4.0;
        let mut lp = ClosedLoop::new(&s, &sim_navigator(), RunConfig::default()).unwrap();
        // Navigator lane k is field lane 14 - 2k; while turning, the next one.
        assert_eq!(lp.target_lane(0), Some(14));
        assert_eq!(lp.target_lane(3), Some(8));
        lp.mode = Mode::Turning;
        assert_eq!(lp.target_lane(0), Some(12));
        assert_eq!(lp.target_lane(7), None);
    }

    #[test]
    fn a_robot_that_sees_no_rows_times_out_at_rest() {
        // Rows too far apart for the detector's search (spacing 1.5 m max): it never acquires.
        let mut s = Scenario::builtin("young-corn").unwrap();
        s.field.length_m = 6.0;
        s.field.row_spacing_m = 3.0;
        let cfg = RunConfig { lanes: 1, max_time_s: 5.0, ..RunConfig::default() };
        let run = run(&s, sim_navigator(), cfg, |_| {}).unwrap();
        assert!(run.metrics.timed_out, "{:?}", run.metrics);
        assert!(run.metrics.distance_m < 0.05, "{:?}", run.metrics);
        assert_eq!(run.metrics.command_violations, 0);
    }
}
