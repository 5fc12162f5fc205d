//! The [`Navigator`]: the one facade the simulator, the recording replayer and the ROS node call.
//!
//! Each step reads like the paper's system design (Sec. III): the LiDAR scan and the filtered
//! odometry go to the crop-row detector (rows in `base_link`); the lane switcher turns the rows into
//! the centre-line path in `odom` (or, at a row end, a headland turn); the nonlinear MPC tracks that
//! path and returns `(v, ω)`. Scans come at 10 Hz; steps without a scan reuse the last path, carried
//! by odometry, so the controller may run faster than the LiDAR.
//!
//! Every stage works in the `nav` frame: the odometry pose with the drift the wheels and the gyro
//! cannot see (a sideways slide on wet soil) removed, as learned from the rows by
//! [`crate::odometry::Drift`]. Until it has learned anything, `nav` is `odom`; the detector's map and
//! the paths ([`LaneSwitcher::path`]) live in `nav`, which departs from `odom` by the slide integrated
//! so far (centimetres over a slip patch).
//!
//! On uneven ground each scan may carry the robot's roll and pitch ([`Scan::attitude`], from the
//! accelerometer: [`crate::odometry::AttitudeFilter`]), so that the detector puts a canopy over its
//! stems (see [`crate::perception`]).
//!
//! ```
//! use croprow_core::navigator::{NavInput, Navigator, NavigatorConfig};
//! use croprow_core::{Mount, Pose2, Twist2};
//! let mut nav = Navigator::new(NavigatorConfig::default()).unwrap();
//! let mount = Mount::default();
//! let out = nav.step(NavInput { stamp_s: 0.0, odom: Pose2::default(), odom_twist: Twist2::ZERO, scan: None, mount: &mount, mpc_budget: None, wheel_slip: None });
//! assert_eq!(out.cmd, Twist2::ZERO); // no rows yet: wait
//! ```

use std::time::Duration;

use serde::{Deserialize, Serialize};

use crate::control::lane_switch::{LaneSwitchConfig, LaneSwitcher, Mode, StopReason};
use crate::control::mpc::{Mpc, MpcConfig, SolveStatus};
use crate::control::path::Frenet;
use crate::control::reference::{ReferenceConfig, centre_line};
use crate::error::{ConfigError, check_range};
use crate::geometry::{Mount, Pose2, Twist2, wrap_angle};
use crate::odometry::{AttitudeConfig, Drift, DriftConfig, EkfConfig};
use crate::perception::{Detection, DetectorConfig, RowDetector, RowStatus, Scan};

/// The whole navigation configuration: one section per stage, with the same dotted names in config
/// files, `--set` overrides and ROS parameters (`detector.fov_deg`, `mpc.horizon_steps`, ...).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NavigatorConfig {
    /// Crop-row detector.
    pub detector: DetectorConfig,
    /// Centre-line reference.
    pub reference: ReferenceConfig,
    /// Nonlinear MPC.
    pub mpc: MpcConfig,
    /// Lane switching and headland turns.
    pub lane_switch: LaneSwitchConfig,
    /// Odometry EKF. Not run by the navigator (its input is already filtered odometry); kept in the
    /// same tree so the simulator and the ROS node build their [`crate::odometry::Ekf`] from one file.
    pub ekf: EkfConfig,
    /// Checks of each step's input.
    pub input: InputConfig,
    /// The odometry's unsensed drift, learned from the rows and removed (see [`Drift`]).
    pub drift: DriftConfig,
    /// Roll and pitch from the accelerometer. Like the EKF, not run by the navigator: the simulator
    /// and the ROS node build their [`crate::odometry::AttitudeFilter`] from it and give its estimate
    /// with each scan ([`Scan::attitude`]).
    pub attitude: AttitudeConfig,
}

/// Checks of the navigator's input (section `input`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InputConfig {
    /// Largest difference between a scan's stamp and the step's (odometry) stamp, s. A scan further
    /// off in the future or the past would be placed with the pose of another moment (0.25 s at
    /// 0.5 m/s is 12 cm along the row, and the heading of another time): it is refused, reported as a
    /// detection with status `invalid_input`, and the step goes on without it. Default 0.25 (2.5 scan
    /// periods: the ROS node steps a scan at its own stamp, or at the last step's when odometry ran
    /// ahead by the cloud's latency; only a broken clock gets near it).
    pub scan_stamp_tolerance_s: f64,
}

impl Default for InputConfig {
    fn default() -> Self {
        Self { scan_stamp_tolerance_s: 0.25 }
    }
}

impl InputConfig {
    /// Checks every field, naming the first bad one (`input.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("input.scan_stamp_tolerance_s", self.scan_stamp_tolerance_s, 0.0, 60.0)
    }
}

impl NavigatorConfig {
    /// Validates every section.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.detector.validate()?;
        self.reference.validate()?;
        self.mpc.validate()?;
        self.lane_switch.validate()?;
        self.ekf.validate()?;
        self.input.validate()?;
        self.drift.validate()?;
        self.attitude.validate()?;
        Ok(())
    }
}

/// One step's input.
#[derive(Debug, Clone, Copy)]
pub struct NavInput<'a> {
    /// Time of this step, s (the odometry's clock). Must not decrease.
    pub stamp_s: f64,
    /// Pose of `base_link` in `odom` at `stamp_s` (filtered odometry, e.g. [`crate::odometry::Ekf`]).
    pub odom: Pose2,
    /// Body twist at `stamp_s` (logged; the controller uses its own last command for rate limits).
    pub odom_twist: Twist2,
    /// The LiDAR scan, when one completed at `stamp_s` (its stamp should equal `stamp_s`, so that
    /// `odom` is the pose of the scan). A scan stamped more than `input.scan_stamp_tolerance_s` away
    /// from `stamp_s` is refused: the output's detection has status `invalid_input`.
    pub scan: Option<Scan<'a>>,
    /// `base_link -> sensor`.
    pub mount: &'a Mount,
    /// Wall-time budget of the MPC solve (`None`: iteration cap only, deterministic).
    pub mpc_budget: Option<Duration>,
    /// The wheel slip ratio the odometry witnessed ([`crate::odometry::Ekf::wheel_slip`]); `None`
    /// when unknown (no read, or odometry from elsewhere). Wheels seen slipping make the lag stop
    /// stricter (`lane_switch.slipping_slide_lag_m`).
    pub wheel_slip: Option<f64>,
}

/// Why a step's input was refused. The navigator's state is kept and the command is zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InputFault {
    /// The stamp is not finite or is before the previous step's.
    BadStamp,
    /// The odometry pose or twist is not finite.
    BadOdometry,
}

/// One step's output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NavOutput {
    /// Stamp of the step, s.
    pub stamp_s: f64,
    /// Command for `base_link`: always finite; zero whenever the robot must not move.
    pub cmd: Twist2,
    /// Mission mode after this step.
    pub mode: Mode,
    /// The detector's result, when a scan came with this step.
    pub detection: Option<Detection>,
    /// How the MPC solve ended, when one ran.
    pub solve_status: Option<SolveStatus>,
    /// PANOC iterations of the solve (0 without one).
    pub solve_iterations: usize,
    /// Where the robot is relative to the tracked path (lateral and heading error), when tracking.
    pub tracking: Option<Frenet>,
    /// Lanes whose row end has been cleared.
    pub lanes_completed: u32,
    /// Current lane index.
    pub lane: u32,
    /// Set when the input was refused (zero command, state kept).
    pub input_fault: Option<InputFault>,
}

/// Yaw rate allowed at any speed while following, rad/s, on top of `max_following_curvature_per_m`
/// times the speed: enough to hold a heading at a standstill, far from a pivot.
const FOLLOWING_YAW_RATE_FLOOR_RADPS: f64 = 0.02;

/// While following at a cruise speed of at least `STALL_CRUISE_MPS`, an MPC that plans under
/// `STALL_SPEED_MPS` for `STALL_S` has found every way on worse than standing: the corridor cost says a
/// tyre would cross a row (measured: soak seed 350, a 0.2 m/m slide in grown soybean 0.70 m apart,
/// where the body must crab 11° into the slide). m/s, m/s, s.
const STALL_CRUISE_MPS: f64 = 0.1;
const STALL_SPEED_MPS: f64 = 0.02;
const STALL_S: f64 = 2.0;

/// Detector -> reference -> lane switching -> MPC, built from one [`NavigatorConfig`].
#[derive(Debug)]
pub struct Navigator {
    cfg: NavigatorConfig,
    detector: RowDetector,
    switcher: LaneSwitcher,
    mpc: Mpc,
    drift: Drift,
    last_cmd: Twist2,
    last_stamp_s: Option<f64>,
    /// Time the MPC has planned no forward motion while following at a cruise speed, s.
    stalled_s: f64,
    /// Where (`odom`) the detector last read a wheel slide while following: the MPC weighs the
    /// heading by `mpc.sliding_heading_factor` until `mpc.sliding_hold_m` past it.
    slide_read_at: Option<Pose2>,
}

impl Navigator {
    /// Validates the configuration and builds every stage (all buffers are allocated here).
    pub fn new(cfg: NavigatorConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        // The planted spacing the turns use is the detector's prior on the lanes' spacing, unless the
        // detector is given its own or could never track rows at it.
        let mut detector = cfg.detector.clone();
        let planted = cfg.lane_switch.row_spacing_m;
        if detector.spacing_prior_m == 0.0
            && (detector.spacing_min_m..=detector.spacing_max_m).contains(&planted)
        {
            detector.spacing_prior_m = planted;
        }
        Ok(Self {
            detector: RowDetector::new(detector)?,
            switcher: LaneSwitcher::new(cfg.lane_switch.clone(), cfg.reference.clone())?,
            mpc: Mpc::new(cfg.mpc.clone())?,
            drift: Drift::new(cfg.drift.clone())?,
            last_cmd: Twist2::ZERO,
            last_stamp_s: None,
            stalled_s: 0.0,
            slide_read_at: None,
            cfg,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &NavigatorConfig {
        &self.cfg
    }

    /// The detector (for its centroids, to draw them).
    pub fn detector(&self) -> &RowDetector {
        &self.detector
    }

    /// The lane switcher (mode, path being tracked, row end, headland excursion).
    pub fn lane_switcher(&self) -> &LaneSwitcher {
        &self.switcher
    }

    /// The MPC (its current plan).
    pub fn mpc(&self) -> &Mpc {
        &self.mpc
    }

    /// The drift estimator. The detector's map and the lane switcher's paths live in its `nav` frame:
    /// `odom` with the estimated drift removed.
    pub fn drift(&self) -> &Drift {
        &self.drift
    }

    /// Leaves a safety stop: the detector and the controller start over, the lane count is kept.
    pub fn resume(&mut self) {
        self.switcher.resume();
        self.detector.reset();
        self.mpc.reset();
        self.drift.forget_line();
        self.last_cmd = Twist2::ZERO;
    }

    /// One control step: runs the detector on the scan, if any, then lane switching and the MPC.
    /// A scan whose stamp is not within `input.scan_stamp_tolerance_s` of the step's is not given to
    /// the detector; its detection reads `invalid_input` (no rows) and the step goes on without it, so
    /// a run of such scans ends in the blind-distance stop (`no_rows`), which clears by itself.
    pub fn step(&mut self, input: NavInput<'_>) -> NavOutput {
        if let Some(fault) = self.check(&input) {
            return self.refuse(input.stamp_s, fault);
        }
        let tolerance = self.cfg.input.scan_stamp_tolerance_s;
        let pose = self.drift.correct(input.stamp_s, input.odom);
        let detection = input.scan.map(|scan| {
            if (scan.stamp_s - input.stamp_s).abs() <= tolerance {
                // The odometry's twist undoes the scan's motion skew unless the caller gave its own.
                let scan = Scan { twist: scan.twist.or(Some(input.odom_twist)), ..scan };
                self.detector.detect(scan, pose, input.mount)
            } else {
                Detection::empty(scan.stamp_s, RowStatus::InvalidInput)
            }
        });
        if let Some(d) = detection.filter(|d| d.status != RowStatus::InvalidInput) {
            // The detector's mapped row centroids (in `nav`) tell the lane switcher where each row ends.
            self.switcher.observe_canopy(&pose, &d, self.detector.centroids());
        }
        let wheel_slip = input.wheel_slip.filter(|s| s.is_finite());
        self.advance(input.stamp_s, pose, detection, input.mpc_budget, wheel_slip)
    }

    /// One control step with a detection made elsewhere (a recorded one, or a test's): the same as
    /// [`Navigator::step`] without running the detector. `odom_twist` is only checked.
    pub fn step_with_detection(
        &mut self,
        stamp_s: f64,
        odom: Pose2,
        odom_twist: Twist2,
        detection: Option<Detection>,
        mpc_budget: Option<Duration>,
    ) -> NavOutput {
        let mount = Mount::default();
        let input =
            NavInput { stamp_s, odom, odom_twist, scan: None, mount: &mount, mpc_budget, wheel_slip: None };
        if let Some(fault) = self.check(&input) {
            return self.refuse(stamp_s, fault);
        }
        let pose = self.drift.correct(stamp_s, odom);
        self.advance(stamp_s, pose, detection, mpc_budget, None)
    }

    /// Feeds the drift estimator the centre line of a detection the robot follows: both rows tracked,
    /// at the lane's spacing, no row end before the anchor, within `lane_switch.max_line_jump_m` of
    /// the path followed at the robot (a line of another lane teaches nothing). Anything else, or any
    /// other mode, restarts its comparison; any other mode leaves the lane (drops the slide).
    fn learn_drift(&mut self, mode: Mode, pose: &Pose2, detection: Option<&Detection>) {
        if mode != Mode::Following {
            self.drift.leave_lane();
            return;
        }
        let Some(d) = detection else { return };
        let ls = &self.cfg.lane_switch;
        let anchor_m = self.drift.config().anchor_m;
        let usable = d.status == RowStatus::Tracking
            && d.left.is_some()
            && d.right.is_some()
            && d.row_spacing_m
                .is_some_and(|s| (s - ls.row_spacing_m).abs() <= ls.spacing_tolerance * ls.row_spacing_m)
            && d.row_end_ahead_m.is_none_or(|end| end > anchor_m + 1.0);
        let line = centre_line(&self.cfg.reference, d).filter(|_| usable);
        let on_path = line.filter(|line| {
            self.switcher.path().is_some_and(|path| {
                let at = pose.compose(&line.pose());
                path.project(&at, self.switcher.progress_m()).lateral_m.abs() <= ls.max_line_jump_m
            })
        });
        match on_path {
            Some(line) => self.drift.observe(d.stamp_s, pose, line.pose(), line.curvature_per_m),
            None => self.drift.forget_line(),
        }
    }

    /// True while following with a wheel slide read by the detector now or within
    /// `mpc.sliding_hold_m` of driving: the MPC then weighs the heading `mpc.sliding_heading_factor`
    /// times as much (opt-in: 1 by default). Any other mode forgets the slide.
    fn sliding(&mut self, mode: Mode, odom: &Pose2) -> bool {
        if mode != Mode::Following {
            self.slide_read_at = None;
            return false;
        }
        if self.detector.slide_per_m().is_some_and(f64::is_finite) {
            self.slide_read_at = Some(*odom);
        }
        let hold = self.cfg.mpc.sliding_hold_m;
        self.slide_read_at.is_some_and(|p| (odom.x - p.x).hypot(odom.y - p.y) <= hold)
    }

    /// The pose the MPC plans from: while following through a slide the detector found (see
    /// [`RowDetector::slide_per_m`]), the heading is replaced by the course over the ground, heading +
    /// atan(slide per metre). The MPC's unicycle moves along its heading; on wet soil the robot moves
    /// along its course, and a controller told the heading holds the crab angle that cancels the
    /// slide without ever closing the offset it has built up (issue 6: 20-25 cm off the centre line,
    /// the rows detected within 1-2 cm). Told the course, it steers until the robot's motion over the
    /// ground follows the line. Returns the course and the crab angle atan(slide per metre), by which
    /// the body points off it (the MPC places the tyres by the body).
    fn course(&self, mode: Mode, frenet: Frenet) -> (Frenet, f64) {
        match self.detector.slide_per_m().filter(|k| mode == Mode::Following && k.is_finite()) {
            Some(k) => {
                (Frenet { heading_rad: wrap_angle(frenet.heading_rad + k.atan()), ..frenet }, k.atan())
            }
            None => (frenet, 0.0),
        }
    }

    fn check(&self, input: &NavInput<'_>) -> Option<InputFault> {
        if !input.stamp_s.is_finite() || self.last_stamp_s.is_some_and(|t| input.stamp_s < t) {
            return Some(InputFault::BadStamp);
        }
        if !input.odom.is_finite() || !input.odom_twist.is_finite() {
            return Some(InputFault::BadOdometry);
        }
        None
    }

    fn refuse(&mut self, stamp_s: f64, fault: InputFault) -> NavOutput {
        self.last_cmd = Twist2::ZERO;
        NavOutput {
            stamp_s,
            cmd: Twist2::ZERO,
            mode: self.switcher.mode(),
            detection: None,
            solve_status: None,
            solve_iterations: 0,
            tracking: None,
            lanes_completed: self.switcher.lanes_completed(),
            lane: self.switcher.lane(),
            input_fault: Some(fault),
        }
    }

    fn advance(
        &mut self,
        stamp_s: f64,
        odom: Pose2,
        detection: Option<Detection>,
        budget: Option<Duration>,
        wheel_slip: Option<f64>,
    ) -> NavOutput {
        // The MPC limits rates per model step; a controller running faster than that must limit them
        // per elapsed time. Capped at one model step so that a pause does not release a jump.
        let elapsed_s =
            self.last_stamp_s.map_or(self.cfg.mpc.step_s, |t| (stamp_s - t).min(self.cfg.mpc.step_s));
        self.last_stamp_s = Some(stamp_s);
        self.switcher.set_time(stamp_s);
        let mut guidance = self.switcher.update(&odom, detection.as_ref());
        if guidance.reset_detector {
            self.detector.reset();
        }
        // A drift of `odom` that the detector measures past the limit, or one the lanes lag too far:
        // the map lags it (see `LaneSwitchConfig::max_slide_per_m` and `max_slide_lag_m`), so the
        // robot stops rather than follow the lag. Slipping wheels make the lag limit stricter.
        let ls = &self.cfg.lane_switch;
        let max_slide = ls.max_slide_per_m;
        let slipping = ls.slipping_slide_lag_m > 0.0 && wheel_slip.is_some_and(|s| s >= ls.slipping_min_slip);
        let max_lag =
            if slipping { ls.slipping_slide_lag_m.min(ls.max_slide_lag_m) } else { ls.max_slide_lag_m };
        let lagging = |(k, lag): (f64, f64)| max_lag > 0.0 && k.abs() >= 0.5 * max_slide && lag >= max_lag;
        if guidance.mode == Mode::Following
            && max_slide > 0.0
            && (self.detector.slide_per_m().is_some_and(|k| k.abs() >= max_slide)
                || self.detector.watched_slide_lag().is_some_and(lagging))
        {
            self.switcher.stop(StopReason::Sliding);
            guidance.mode = self.switcher.mode();
        }
        self.learn_drift(guidance.mode, &odom, detection.as_ref());
        let mut out = NavOutput {
            stamp_s,
            cmd: Twist2::ZERO,
            mode: guidance.mode,
            detection,
            solve_status: None,
            solve_iterations: 0,
            tracking: None,
            lanes_completed: guidance.lanes_completed,
            lane: guidance.lane,
            input_fault: None,
        };
        let sliding = self.sliding(guidance.mode, &odom);
        self.mpc.set_sliding(sliding);
        let path = if guidance.mode.is_stopped() || guidance.hold { None } else { self.switcher.path() };
        if let Some(path) = path {
            let frenet = path.project(&odom, self.switcher.progress_m());
            let (course, crab_rad) = self.course(guidance.mode, frenet);
            let sol =
                self.mpc.solve_crabbing(&course, crab_rad, path, guidance.speed_mps, self.last_cmd, budget);
            out.solve_status = Some(sol.status);
            out.solve_iterations = sol.iterations;
            out.tracking = Some(frenet);
            if sol.status == SolveStatus::Failed || !sol.cmd.is_finite() {
                self.switcher.stop(StopReason::SolverFailed);
                out.mode = self.switcher.mode();
            } else {
                let dv = self.cfg.mpc.accel_max_mps2 * elapsed_s;
                let dw = self.cfg.mpc.yaw_accel_max_radps2 * elapsed_s;
                let mut omega = sol.cmd.omega;
                if guidance.mode == Mode::Turning && guidance.speed_mps == 0.0 {
                    // Turning on the spot: the MPC's rate penalty is soft and the wheels lag, so it
                    // brakes the spin too late and overshoots the next leg's heading. Cap the yaw rate
                    // to what stops, at half the yaw acceleration limit, where the heading is reached
                    // (the rate limit below still wins).
                    let brake = (self.cfg.mpc.yaw_accel_max_radps2 * frenet.heading_rad.abs()).sqrt();
                    omega = omega.clamp(-brake, brake);
                }
                let max_curvature = self.cfg.lane_switch.max_following_curvature_per_m;
                if guidance.mode == Mode::Following && max_curvature > 0.0 {
                    // Rows are followed along arcs, not by turning on the spot (see
                    // `LaneSwitchConfig::max_following_curvature_per_m`); the arc is at the MPC's planned
                    // speed, before the rate limits.
                    let bound = max_curvature * sol.cmd.v.abs() + FOLLOWING_YAW_RATE_FLOOR_RADPS;
                    omega = omega.clamp(-bound, bound);
                }
                let omega = omega.clamp(self.last_cmd.omega - dw, self.last_cmd.omega + dw);
                out.cmd = Twist2::new(sol.cmd.v.clamp(self.last_cmd.v - dv, self.last_cmd.v + dv), omega);
                let stalled = guidance.mode == Mode::Following
                    && guidance.speed_mps >= STALL_CRUISE_MPS
                    && sol.cmd.v < STALL_SPEED_MPS;
                self.stalled_s = if stalled { self.stalled_s + elapsed_s } else { 0.0 };
                if self.stalled_s >= STALL_S {
                    // Standing still in "following" would look like a robot at work; say why it stands.
                    self.switcher.stop(StopReason::NoSafeMotion);
                    out.mode = self.switcher.mode();
                    out.cmd = Twist2::ZERO;
                    self.stalled_s = 0.0;
                }
            }
        } else {
            self.mpc.reset();
            self.stalled_s = 0.0;
        }
        self.last_cmd = out.cmd;
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Point3;

    /// Ground every 0.1 m from 1 to 4 m ahead and two 0.3 m tall rows at ±0.375 m, seen by a level
    /// sensor 1.5 m above `base_link`.
    fn lane_points() -> Vec<Point3> {
        let mut pts = Vec::new();
        for i in 0..30 {
            let x = 1.0 + 0.1 * i as f32;
            for j in -15..=15 {
                let y = 0.1 * j as f32;
                let z = if (y.abs() - 0.375).abs() < 0.06 { -1.2 } else { -1.5 };
                pts.push(Point3::new(x, y, z));
            }
        }
        pts
    }

    #[test]
    fn a_scan_stamped_away_from_the_odometry_is_refused_not_detected() {
        let mount = Mount { x_m: 0.0, pitch_rad: 0.0, ..Mount::default() };
        let points = lane_points();
        let step = |nav: &mut Navigator, t: f64, scan_t: f64| {
            nav.step(NavInput {
                stamp_s: t,
                odom: Pose2::default(),
                odom_twist: Twist2::ZERO,
                scan: Some(Scan { stamp_s: scan_t, points: &points, twist: None, attitude: None }),
                mount: &mount,
                mpc_budget: None,
                wheel_slip: None,
            })
        };
        let mut nav = Navigator::new(NavigatorConfig::default()).unwrap();
        // 0.2 s off is inside the 0.25 s tolerance: the detector sees the scan.
        let out = step(&mut nav, 1.0, 0.8);
        assert_ne!(out.detection.map(|d| d.status), Some(RowStatus::InvalidInput), "{out:?}");
        // 0.5 s in the future, 0.5 s in the past, or no stamp at all: refused, zero command, no fault
        // on the step itself (the odometry is fine).
        for scan_t in [1.6, 0.6, f64::NAN] {
            let out = step(&mut nav, 1.1, scan_t);
            let d = out.detection.unwrap();
            assert_eq!((d.status, d.left, out.input_fault), (RowStatus::InvalidInput, None, None));
            assert_eq!(out.cmd, Twist2::ZERO);
        }
    }

    #[test]
    fn an_absurd_stamp_tolerance_is_refused_by_name() {
        let cfg = NavigatorConfig {
            input: InputConfig { scan_stamp_tolerance_s: -1.0 },
            ..NavigatorConfig::default()
        };
        let e = Navigator::new(cfg).unwrap_err().to_string();
        assert!(e.contains("input.scan_stamp_tolerance_s"), "{e}");
    }
}
