//! Table I detection runs: the paper's detection experiment (Sec. V-A) in the simulator.
//!
//! A human-like [`Driver`](crate::Driver) wanders along the scenario's lane (±10 cm, a few degrees of
//! heading) while one or more detector configurations run side by side on the SAME scans, each with the
//! same odometry pose: the core EKF fed by the simulated wheel odometry and IMU, or the true pose when the
//! scenario sets `sensors.perfect_odometry`. Every detection is scored against the truth with
//! [`metrics::score_detection`]: the paper's distance and angular errors of the first left and right rows,
//! summarised as mean ± std of the absolute errors, plus how often both rows were found, wrong-row picks
//! and where `EndOfRow` was raised relative to the true row end.
//!
//! Where it sits: scenario -> [`World`] + driver + EKF -> detectors -> metrics -> [`DetectionReport`].
//! It is pure (no clock, no files): `croprow detect-sim` prints the report and `croprow evaluate`
//! tabulates it.
//!
//! # The run
//! The robot first stands still for [`STANDSTILL_S`] (as after power-up: the EKF calibrates the gyro
//! bias against wheels that report zero; no scan is scored), then the driver sets off. The field is cut to end `length_m` past the start (when it is longer), so that a run drives
//! `length_m` of rows and ends at a row end, and a short run does not build a 200 m field. The driver keeps
//! going [`OVERRUN_M`] past the row end so that `EndOfRow` can be observed. Only scans taken while
//! `base_link` is still among the rows (before the true row end) are scored; statuses are counted over
//! every scan.
//!
//! ```
//! use croprow_core::DetectorConfig;
//! use croprow_sim::Scenario;
//! use croprow_sim::experiment::detection::run_detection;
//! let scenario = Scenario::builtin("young-soybean").unwrap();
//! let modes = [DetectorConfig::default(), DetectorConfig::paper()];
//! let report = run_detection(&scenario, 4.0, &modes, &mut |_fraction| {}).unwrap();
//! assert_eq!(report.modes.len(), 2);
//! assert!(report.scans > 40);
//! ```

use croprow_core::error::check_range;
use croprow_core::odometry::{Ekf, EkfConfig, EkfError};
use croprow_core::{ConfigError, Detection, DetectorConfig, DetectorMode, Point3, Pose2, RowDetector};
use croprow_core::{RowStatus, Twist2};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::field::Field;
use crate::metrics::{self, ErrorStats, RowError};
use crate::robot::StepError;
use crate::scenario::{Scenario, ScenarioError};
use crate::sensors::{ImuSample, WheelOdometry};
use crate::world::World;

/// How far past the true row end the driver keeps going, m: enough for `EndOfRow` to be raised by a
/// detector that waits for the end to pass under the robot.
pub const OVERRUN_M: f64 = 2.0;

/// Time the robot stands still at the start, s (see [`run_detection`]).
pub const STANDSTILL_S: f64 = 5.0;

/// Slack of the run's time limit over the time the driver needs, s (a stuck run ends instead of looping).
const TIME_SLACK_S: f64 = 20.0;

/// The paper's published Table I detection errors (simulated fields), by scenario name:
/// mean ± std of the absolute distance (cm) and angular (degrees) errors.
pub const PUBLISHED: [(&str, Accuracy); 5] = [
    ("young-corn", Accuracy { dist_cm_mean: 1.67, dist_cm_std: 1.12, ang_deg_mean: 0.28, ang_deg_std: 0.23 }),
    ("grown-corn", Accuracy { dist_cm_mean: 3.74, dist_cm_std: 2.49, ang_deg_mean: 1.77, ang_deg_std: 1.51 }),
    (
        "young-soybean",
        Accuracy { dist_cm_mean: 1.54, dist_cm_std: 1.07, ang_deg_mean: 0.49, ang_deg_std: 0.33 },
    ),
    (
        "grown-soybean",
        Accuracy { dist_cm_mean: 3.04, dist_cm_std: 1.69, ang_deg_mean: 1.14, ang_deg_std: 1.01 },
    ),
    (
        "curved-corn",
        Accuracy { dist_cm_mean: 2.72, dist_cm_std: 1.33, ang_deg_mean: 0.92, ang_deg_std: 0.71 },
    ),
];

/// The paper's published Table I detection errors for a scenario name (`grown-corn`, ...), if it has one.
pub fn published(name: &str) -> Option<Accuracy> {
    PUBLISHED.iter().find(|(n, _)| *n == name).map(|(_, a)| *a)
}

/// Detection accuracy in the units of the paper's Table I: mean ± std of the absolute errors.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Accuracy {
    /// Mean absolute distance error, cm.
    pub dist_cm_mean: f64,
    /// Standard deviation of the absolute distance error, cm.
    pub dist_cm_std: f64,
    /// Mean absolute angular error, degrees.
    pub ang_deg_mean: f64,
    /// Standard deviation of the absolute angular error, degrees.
    pub ang_deg_std: f64,
}

/// Summary of a stream of absolute errors in one unit (named by the field holding it).
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ErrorSummary {
    /// Number of errors.
    pub count: usize,
    /// Mean absolute error (0 when `count` is 0).
    pub mean: f64,
    /// Standard deviation of the absolute error (population).
    pub std: f64,
    /// Largest absolute error.
    pub max: f64,
}

impl ErrorSummary {
    /// The summary of `stats`, scaled by `unit` (e.g. 100 for metres to centimetres).
    fn scaled(stats: &ErrorStats, unit: f64) -> Self {
        Self {
            count: stats.count(),
            mean: stats.mae() * unit,
            std: stats.std() * unit,
            max: stats.max() * unit,
        }
    }
}

/// Scans per detector status.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct StatusCounts {
    /// `Searching`.
    pub searching: usize,
    /// `Tracking`.
    pub tracking: usize,
    /// `EndOfRow`.
    pub end_of_row: usize,
    /// `Lost`.
    pub lost: usize,
    /// `InvalidInput`.
    pub invalid_input: usize,
}

impl StatusCounts {
    fn add(&mut self, status: RowStatus) {
        match status {
            RowStatus::Searching => self.searching += 1,
            RowStatus::Tracking => self.tracking += 1,
            RowStatus::EndOfRow => self.end_of_row += 1,
            RowStatus::Lost => self.lost += 1,
            // `RowStatus` is non-exhaustive: a status added later counts as invalid until named here.
            _ => self.invalid_input += 1,
        }
    }
}

/// What one detector configuration achieved over a run.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionStats {
    /// The detector's pipeline.
    pub mode: DetectorMode,
    /// Distance error of every scored row (left and right pooled, as the paper), cm.
    pub distance_cm: ErrorSummary,
    /// Angular error of every scored row, degrees.
    pub angle_deg: ErrorSummary,
    /// Scans scored: taken while `base_link` was among the rows.
    pub scans: usize,
    /// Scored scans where both the left and the right row were reported.
    pub scans_both_rows: usize,
    /// Scored scans where no row was reported.
    pub scans_no_row: usize,
    /// Reported rows nearer another true row than the true first left / right one (must be 0).
    pub wrong_row_picks: usize,
    /// Distance along the rows from `base_link` to the true row end when `EndOfRow` was first raised, m:
    /// positive while the end is still ahead, negative once passed. `None`: never raised.
    pub end_of_row_m: Option<f64>,
    /// Status of every scan of the run (scored or not).
    pub statuses: StatusCounts,
    #[serde(skip)]
    distance: ErrorStats,
    #[serde(skip)]
    angle: ErrorStats,
}

impl DetectionStats {
    fn new(mode: DetectorMode) -> Self {
        Self {
            mode,
            distance_cm: ErrorSummary::default(),
            angle_deg: ErrorSummary::default(),
            scans: 0,
            scans_both_rows: 0,
            scans_no_row: 0,
            wrong_row_picks: 0,
            end_of_row_m: None,
            statuses: StatusCounts::default(),
            distance: ErrorStats::default(),
            angle: ErrorStats::default(),
        }
    }

    /// Scores one detection made with the robot at true pose `truth`, `to_end_m` before the row end.
    fn record(&mut self, field: &Field, truth: &Pose2, detection: &Detection, to_end_m: f64) {
        self.statuses.add(detection.status);
        if detection.status == RowStatus::EndOfRow && self.end_of_row_m.is_none() {
            self.end_of_row_m = Some(to_end_m);
        }
        if to_end_m <= 0.0 {
            return;
        }
        self.scans += 1;
        match (detection.left.is_some(), detection.right.is_some()) {
            (true, true) => self.scans_both_rows += 1,
            (false, false) => self.scans_no_row += 1,
            _ => {}
        }
        let errors = metrics::score_detection(field, truth, detection);
        for e in [errors.left, errors.right].iter().flatten() {
            self.add(e);
        }
        self.distance_cm = ErrorSummary::scaled(&self.distance, 100.0);
        self.angle_deg = ErrorSummary::scaled(&self.angle, 1f64.to_degrees());
    }

    fn add(&mut self, e: &RowError) {
        self.distance.add(e.distance_m);
        self.angle.add(e.angle_rad);
        if e.wrong_row {
            self.wrong_row_picks += 1;
        }
    }

    /// The run's accuracy in Table I units.
    pub fn accuracy(&self) -> Accuracy {
        Accuracy {
            dist_cm_mean: self.distance_cm.mean,
            dist_cm_std: self.distance_cm.std,
            ang_deg_mean: self.angle_deg.mean,
            ang_deg_std: self.angle_deg.std,
        }
    }

    /// Share of scored scans with both rows reported, in [0, 1] (0 without scans).
    pub fn both_rows_share(&self) -> f64 {
        if self.scans == 0 { 0.0 } else { self.scans_both_rows as f64 / self.scans as f64 }
    }
}

/// Where the detectors' odometry came from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Odometry {
    /// The core EKF fusing the simulated wheel odometry and IMU.
    Ekf,
    /// The true pose (`sensors.perfect_odometry`).
    Perfect,
}

/// The result of [`run_detection`].
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct DetectionReport {
    /// Scenario name.
    pub scenario: String,
    /// Scenario seed.
    pub seed: u64,
    /// Length of rows driven: from the start to the row end, m.
    pub length_m: f64,
    /// Distance the robot actually drove (true, including the overrun past the row end), m.
    pub distance_m: f64,
    /// Simulated time, s.
    pub sim_time_s: f64,
    /// LiDAR scans of the run (scored or not).
    pub scans: usize,
    /// Mean number of points per scan.
    pub points_per_scan: f64,
    /// Odometry source of the detectors.
    pub odometry: Odometry,
    /// Position error of the odometry at the end of the run (odom starts at the true start pose), m.
    pub odometry_error_m: f64,
    /// One entry per detector configuration, in the order given.
    pub modes: Vec<DetectionStats>,
}

/// Why a detection run could not run.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum RunError {
    /// The scenario (or the field cut from it) is invalid.
    #[error(transparent)]
    Scenario(#[from] ScenarioError),
    /// A detector configuration or the run length is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The world refused a step (a bug of the driver: its commands are finite).
    #[error("simulation step: {0}")]
    Step(#[from] StepError),
    /// The EKF refused a sensor sample (a bug of the sensor models: their stamps are regular).
    #[error("odometry: {0}")]
    Odometry(#[from] EkfError),
}

/// The EKF tuning that matches the simulated skid-steer: its wheel yaw rate wanders slowly while driving
/// (yaw disturbance, slip), so it weighs little once moving and the gyro bias is calibrated at rest
/// (`ekf.wheel_yaw_rate_per_speed` = 0.5 rad/s per m/s; the rest as [`EkfConfig::default`]). Measured on
/// 20 m of young corn: with the default EKF (which learns the gyro bias from the moving wheels) the
/// odometry heading drifted ~1° per 3 s and the default detector's errors were 9 cm / 2.3°; with this one
/// 0.4 cm / 0.2°, as with perfect odometry.
pub fn ekf_config() -> EkfConfig {
    EkfConfig { wheel_yaw_rate_per_speed: 0.5, ..EkfConfig::default() }
}

/// Drives `length_m` of the scenario's lane with its human-like driver and runs every configuration of
/// `modes` on every scan (see the module docs), with the odometry of [`ekf_config`]. `progress` is called
/// after each scan with the fraction of the run done, in [0, 1].
pub fn run_detection(
    scenario: &Scenario,
    length_m: f64,
    modes: &[DetectorConfig],
    progress: &mut dyn FnMut(f64),
) -> Result<DetectionReport, RunError> {
    run_detection_with(scenario, length_m, modes, &ekf_config(), progress)
}

/// [`run_detection`] with the EKF configured by `ekf` (e.g. the navigator config's `ekf` section).
pub fn run_detection_with(
    scenario: &Scenario,
    length_m: f64,
    modes: &[DetectorConfig],
    ekf: &EkfConfig,
    progress: &mut dyn FnMut(f64),
) -> Result<DetectionReport, RunError> {
    check_range("length_m", length_m, 0.5, 2000.0)?;
    if modes.is_empty() {
        return Err(ConfigError::invalid("modes", "no detector configuration to run").into());
    }
    let mut s = scenario.clone();
    s.field.length_m = s.field.length_m.min(s.start.x_m + length_m);
    s.driver.stop_before_end_m = -OVERRUN_M;
    let mut world = World::new(&s)?;
    let mut driver = world.driver()?;
    let mut detectors =
        modes.iter().map(|c| RowDetector::new(c.clone())).collect::<Result<Vec<_>, ConfigError>>()?;
    let mut stats: Vec<DetectionStats> = modes.iter().map(|c| DetectionStats::new(c.mode)).collect();
    let perfect = s.sensors.perfect_odometry;
    let mount = s.lidar.mount;

    let start = world.robot().pose();
    let mut ekf = Ekf::new(ekf.clone())?;
    ekf.reset(0.0, start)?;
    let lane = world.lane();
    let end_x = row_end_x(world.field(), lane);
    let start_x = lane_x(world.field(), lane, &start);
    let total_m = (end_x + OVERRUN_M - start_x).max(f64::EPSILON);
    let time_limit_s = STANDSTILL_S + total_m / s.driver.speed_m_s + TIME_SLACK_S;

    // The robot stands still first, as after power-up: the EKF calibrates the gyro bias against wheels
    // that report exactly zero, before the wander starts (and before any scan is scored).
    while world.time_s() < STANDSTILL_S {
        let step = world.step(Twist2::ZERO)?;
        fuse_odometry(&mut ekf, step.wheel, step.imu)?;
    }
    let mut points: Vec<Point3> = Vec::with_capacity(world.lidar().rays_per_revolution());
    let (mut scans, mut point_sum, mut distance_m) = (0usize, 0usize, 0.0);
    let mut last = start;
    while world.time_s() < time_limit_s {
        let cmd = driver.command(world.time_s(), &world.robot().pose(), world.field());
        if cmd == Twist2::ZERO {
            break;
        }
        let step = world.step(cmd)?;
        fuse_odometry(&mut ekf, step.wheel, step.imu)?;
        let truth = step.truth.pose;
        distance_m += (truth.x - last.x).hypot(truth.y - last.y);
        last = truth;
        let Some(scan) = step.scan else { continue };
        // The scan borrows the world: copy it out so the field can be read while scoring.
        let stamp_s = scan.stamp_s;
        points.clear();
        points.extend_from_slice(scan.points);
        let truth = scan.truth.pose;
        let (odom, twist) = if perfect {
            (truth, step.true_twist)
        } else {
            ekf.predict_to(stamp_s)?;
            (ekf.pose(), ekf.twist())
        };
        scans += 1;
        point_sum += points.len();
        let field = world.field();
        let x = lane_x(field, lane, &truth);
        let to_end_m = if x < end_x { arc_length(field, x, end_x) } else { -arc_length(field, end_x, x) };
        for (detector, st) in detectors.iter_mut().zip(stats.iter_mut()) {
            let d = detector.detect(
                croprow_core::Scan { stamp_s, points: &points, twist: Some(twist), attitude: None },
                odom,
                &mount,
            );
            st.record(field, &truth, &d, to_end_m);
        }
        progress(((x - start_x) / total_m).clamp(0.0, 1.0));
    }
    let odom = if perfect { world.robot().pose() } else { ekf.pose() };
    let truth = world.robot().pose();
    Ok(DetectionReport {
        scenario: s.name.clone(),
        seed: s.seed,
        length_m: arc_length(world.field(), start_x, end_x),
        distance_m,
        sim_time_s: world.time_s(),
        scans,
        points_per_scan: if scans == 0 { 0.0 } else { point_sum as f64 / scans as f64 },
        odometry: if perfect { Odometry::Perfect } else { Odometry::Ekf },
        odometry_error_m: (odom.x - truth.x).hypot(odom.y - truth.y),
        modes: stats,
    })
}

/// Feeds one world step's wheel odometry and IMU sample, when there are, to the EKF.
pub fn fuse_odometry(
    ekf: &mut Ekf,
    wheel: Option<WheelOdometry>,
    imu: Option<ImuSample>,
) -> Result<(), EkfError> {
    if let Some(w) = wheel {
        ekf.update_wheel(w.stamp_s, w.twist.v, w.twist.omega)?;
    }
    if let Some(i) = imu {
        ekf.update_imu(i.stamp_s, i.gyro_z_rad_s)?;
    }
    Ok(())
}

/// Where the rows of `lane` end: the farthest last plant of its two rows, x in the field frame, m.
fn row_end_x(field: &Field, lane: u32) -> f64 {
    [lane, lane + 1]
        .iter()
        .filter_map(|&r| field.row_stems(r).last().map(|s| s.x_m))
        .fold(f64::NEG_INFINITY, f64::max)
        .max(0.0)
}

/// x (field frame) of the point of the lane centre line closest to `pose`: the robot's place along the
/// rows. Exact on straight rows; on curved ones it corrects for the offset from the centre line.
fn lane_x(field: &Field, lane: u32, pose: &Pose2) -> f64 {
    match metrics::cross_track(field, lane, pose) {
        Some(ct) => pose.x + ct.lateral_m * field.row_heading(pose.x).sin(),
        None => pose.x,
    }
}

/// Length along the row curve between `x0 ≤ x1` (field frame), m: ∫ dx / cos(heading), midpoint rule
/// on 5 cm steps (the curves bend over tens of metres, so this is exact to well under a millimetre).
fn arc_length(field: &Field, x0: f64, x1: f64) -> f64 {
    let span = x1 - x0;
    // Also catches NaN.
    if span.is_nan() || span <= 0.0 {
        return 0.0;
    }
    let n = (span / 0.05).ceil().clamp(1.0, 1e6);
    let h = span / n;
    (0..n as usize).map(|k| h / field.row_heading(x0 + (k as f64 + 0.5) * h).cos()).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::FieldConfig;

    #[test]
    fn arc_length_of_straight_and_curved_rows() {
        let straight = Field::generate(&FieldConfig { length_m: 5.0, ..FieldConfig::default() }, 1).unwrap();
        assert!((arc_length(&straight, 1.0, 4.0) - 3.0).abs() < 1e-12);
        assert_eq!(arc_length(&straight, 4.0, 1.0), 0.0);
        let curved = Field::generate(
            &FieldConfig { length_m: 5.0, curve_amplitude_m: 6.0, ..FieldConfig::default() },
            1,
        )
        .unwrap();
        // At x = 0 the slope is 2π·6/100 = 0.377: over 1 cm the arc is 1/cos(atan 0.377) longer.
        let expected = 0.01 * (1.0 + 0.377f64.powi(2)).sqrt();
        assert!((arc_length(&curved, -0.005, 0.005) - expected).abs() < 1e-6);
    }

    #[test]
    fn published_numbers_cover_the_five_fields() {
        for name in ["young-corn", "grown-corn", "young-soybean", "grown-soybean", "curved-corn"] {
            assert!(published(name).is_some(), "{name}");
        }
        assert_eq!(published("grown-corn").map(|a| a.dist_cm_mean), Some(3.74));
        assert!(published("recovery").is_none());
    }

    #[test]
    fn empty_modes_and_absurd_lengths_are_refused() {
        let s = Scenario::builtin("young-corn").unwrap();
        let e = run_detection(&s, 5.0, &[], &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains("modes"), "{e}");
        let e = run_detection(&s, f64::NAN, &[DetectorConfig::default()], &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains("length_m"), "{e}");
        let bad = DetectorConfig { range_m: -1.0, ..DetectorConfig::default() };
        let e = run_detection(&s, 5.0, &[bad], &mut |_| {}).unwrap_err();
        assert!(e.to_string().contains("detector.range_m"), "{e}");
    }

    #[test]
    fn statuses_are_counted_and_errors_pooled() {
        let mut st = DetectionStats::new(DetectorMode::Default);
        let field = Field::generate(&FieldConfig { length_m: 5.0, ..FieldConfig::default() }, 1).unwrap();
        // Lane 7 (rows 7 and 8 at y = 5.25 and 6.0), robot on its centre line.
        let truth = Pose2::new(2.0, 5.625, 0.0);
        let row = |y: f64| croprow_core::RowEstimate {
            line: [0.0, y, 2.0, y],
            offset_m: y,
            heading_rad: 0.0,
            curvature_per_m: 0.0,
            confidence: 1.0,
        };
        let both = Detection {
            left: Some(row(0.375 + 0.02)),
            right: Some(row(-0.375)),
            ..Detection::empty(0.1, RowStatus::Tracking)
        };
        st.record(&field, &truth, &both, 3.0);
        // The right row reported one spacing too far right: a wrong-row pick, still scored.
        let wrong = Detection { right: Some(row(-1.125)), ..Detection::empty(0.2, RowStatus::Tracking) };
        st.record(&field, &truth, &wrong, 2.9);
        st.record(&field, &truth, &Detection::empty(0.3, RowStatus::EndOfRow), 0.4);
        // Past the row end: counted as a status, not scored.
        st.record(&field, &truth, &Detection::empty(0.4, RowStatus::EndOfRow), -0.1);
        assert_eq!((st.scans, st.scans_both_rows, st.scans_no_row, st.wrong_row_picks), (3, 1, 1, 1));
        assert_eq!((st.statuses.tracking, st.statuses.end_of_row), (2, 2));
        assert_eq!(st.end_of_row_m, Some(0.4));
        // Errors 2, 0 and 75 cm (tolerance 1e-9 cm: arithmetic only).
        assert_eq!(st.distance_cm.count, 3);
        assert!((st.distance_cm.mean - 77.0 / 3.0).abs() < 1e-9, "{:?}", st.distance_cm);
        assert!((st.both_rows_share() - 1.0 / 3.0).abs() < 1e-12);
    }
}
