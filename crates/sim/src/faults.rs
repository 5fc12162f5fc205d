//! Fault injection (issue 6): what a field throws at a robot, each fault injected where it physically
//! happens, all off by default. A scenario names the ones it wants in its `[faults]` table:
//!
//! | fault | `[faults.…]` | injected in |
//! |---|---|---|
//! | LiDAR dropout: whole scans missing | `lidar_dropout` | `world` (the completed scan is withheld) |
//! | partial scan: an azimuth sector missing | `partial_scan` | `world` (points removed from the scan) |
//! | spurious returns: dust, insects above the canopy | `spurious_returns` | `world` (points added) |
//! | a tall weed patch | `weed_patch` | `field` generation |
//! | a missing stretch of row | `row_gap` | `field` generation |
//! | wheel slip patch: wet soil | `slip_patch` | `robot` dynamics |
//! | gyro bias step | `gyro_bias_step` | `sensors` (IMU) |
//! | odometry time jitter, out-of-order messages | `odometry_timing` | `world` (message transport) |
//! | a scan stamped in the future or the past | `scan_stamp` | `world` (scan stamp) |
//! | a tilted or bumped LiDAR mount | `mount_error` | `world` (the TRUE mount casts the rays; the navigator keeps the nominal one) |
//!
//! Where a fault happens is given by the TRUE `x` of `base_link` in the field frame (distance along
//! the rows from their start, m), so that a fault sits at the same place of a field whatever the speed.
//!
//! ```
//! use croprow_sim::Scenario;
//! let s = Scenario::from_toml_str(
//!     "[field]\nlength_m = 20.0\n[faults.lidar_dropout]\nenabled = true\nfrom_x_m = 8.0\nduration_s = 2.0\n",
//! )
//! .unwrap();
//! assert!(s.faults.lidar_dropout.enabled && !s.faults.slip_patch.enabled);
//! ```

use croprow_core::ConfigError;
use croprow_core::error::check_range;
use serde::{Deserialize, Serialize};

/// Every fault the simulator can inject; each one is off unless its `enabled` is true.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct FaultConfig {
    /// Whole LiDAR scans missing.
    pub lidar_dropout: LidarDropout,
    /// An azimuth sector missing from every scan inside a stretch of the field.
    pub partial_scan: PartialScan,
    /// Random returns above the canopy (dust, insects).
    pub spurious_returns: SpuriousReturns,
    /// A patch of tall weeds between the rows.
    pub weed_patch: WeedPatch,
    /// A stretch of missing plants in some or all rows.
    pub row_gap: RowGap,
    /// Wet soil: strong longitudinal slip and a lateral drift.
    pub slip_patch: SlipPatch,
    /// The gyro bias jumps.
    pub gyro_bias_step: GyroBiasStep,
    /// Odometry stamps jitter and wheel odometry messages arrive out of order.
    pub odometry_timing: OdometryTiming,
    /// Scans carry a wrong stamp.
    pub scan_stamp: ScanStamp,
    /// The LiDAR is mounted (or knocked) off its nominal orientation.
    pub mount_error: MountError,
}

impl FaultConfig {
    /// Checks every fault's parameters (enabled or not, so that a typo is caught before it is
    /// switched on), naming the first bad field (`faults.lidar_dropout.duration_s`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.lidar_dropout.validate()?;
        self.partial_scan.validate()?;
        self.spurious_returns.validate()?;
        self.weed_patch.validate()?;
        self.row_gap.validate()?;
        self.slip_patch.validate()?;
        self.gyro_bias_step.validate()?;
        self.odometry_timing.validate()?;
        self.scan_stamp.validate()?;
        self.mount_error.validate()?;
        Ok(())
    }

    /// True when at least one fault is enabled.
    pub fn any(&self) -> bool {
        self.lidar_dropout.enabled
            || self.partial_scan.enabled
            || self.spurious_returns.enabled
            || self.weed_patch.enabled
            || self.row_gap.enabled
            || self.slip_patch.enabled
            || self.gyro_bias_step.enabled
            || self.odometry_timing.enabled
            || self.scan_stamp.enabled
            || self.mount_error.enabled
    }
}

/// Longest x any fault may be placed at, m (the simulator's longest field).
const MAX_X_M: f64 = 2000.0;

/// Checks a `[from, to]` stretch of the field.
fn check_window(prefix: &str, from_x_m: f64, to_x_m: f64) -> Result<(), ConfigError> {
    check_range(&format!("{prefix}.from_x_m"), from_x_m, -MAX_X_M, MAX_X_M)?;
    check_range(&format!("{prefix}.to_x_m"), to_x_m, from_x_m, MAX_X_M)
}

/// Whole scans missing (a loose connector, a driver hiccup): from the moment the robot's true x passes
/// `from_x_m`, no scan is delivered for `duration_s`; with `repeat_every_m > 0` it happens again every
/// that many metres further on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LidarDropout {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Where the first dropout starts: true x of `base_link`, m. Default 8.
    pub from_x_m: f64,
    /// How long each dropout lasts, s. Default 1.5 (issue 6: up to 2 s).
    pub duration_s: f64,
    /// Distance between the starts of successive dropouts, m; 0 for a single one. Default 0.
    pub repeat_every_m: f64,
}

impl Default for LidarDropout {
    fn default() -> Self {
        Self { enabled: false, from_x_m: 8.0, duration_s: 1.5, repeat_every_m: 0.0 }
    }
}

impl LidarDropout {
    fn validate(&self) -> Result<(), ConfigError> {
        check_range("faults.lidar_dropout.from_x_m", self.from_x_m, -MAX_X_M, MAX_X_M)?;
        check_range("faults.lidar_dropout.duration_s", self.duration_s, 0.0, 600.0)?;
        check_range("faults.lidar_dropout.repeat_every_m", self.repeat_every_m, 0.0, MAX_X_M)?;
        if self.repeat_every_m > 0.0 && self.repeat_every_m < 0.5 {
            return Err(ConfigError::invalid(
                "faults.lidar_dropout.repeat_every_m",
                "repeats closer than 0.5 m would never let a scan through; use 0 for one dropout",
            ));
        }
        Ok(())
    }
}

/// An azimuth sector missing from every scan while the robot's true x is in `[from_x_m, to_x_m]`
/// (a blocked window of the sensor, a mud splash, a failing part of the spinning head).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PartialScan {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Start of the stretch, true x of `base_link`, m. Default 6.
    pub from_x_m: f64,
    /// End of the stretch, m. Default 14.
    pub to_x_m: f64,
    /// Centre of the missing sector: azimuth in the SENSOR frame, deg, counter-clockwise from the
    /// sensor's x axis (0 straight ahead, 90 to the left). Default 45 (front left).
    pub sector_centre_deg: f64,
    /// Width of the missing sector, deg. Default 90.
    pub sector_width_deg: f64,
}

impl Default for PartialScan {
    fn default() -> Self {
        Self { enabled: false, from_x_m: 6.0, to_x_m: 14.0, sector_centre_deg: 45.0, sector_width_deg: 90.0 }
    }
}

impl PartialScan {
    fn validate(&self) -> Result<(), ConfigError> {
        check_window("faults.partial_scan", self.from_x_m, self.to_x_m)?;
        check_range("faults.partial_scan.sector_centre_deg", self.sector_centre_deg, -360.0, 360.0)?;
        check_range("faults.partial_scan.sector_width_deg", self.sector_width_deg, 0.0, 360.0)
    }
}

/// Random returns above the canopy (dust blown up by the wheels, insects) added to every scan while
/// the robot's true x is in `[from_x_m, to_x_m]`: points uniform in a box ahead of the robot, in
/// `base_link` (`0 ≤ x ≤ ahead_m`, `|y| ≤ half_width_m`, `min_height_m ≤ z ≤ max_height_m`), written
/// in the sensor frame of the true mount like every other return.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SpuriousReturns {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Start of the stretch, true x of `base_link`, m. Default 6.
    pub from_x_m: f64,
    /// End of the stretch, m. Default 14.
    pub to_x_m: f64,
    /// Spurious points added to each scan. Default 300 (about 2 % of the returns a VLP-16 gets from
    /// the crop inside the detector's 4 m range).
    pub points_per_scan: u32,
    /// Lowest spurious point above the ground, m. Default 0.8 (above a grown canopy).
    pub min_height_m: f64,
    /// Highest spurious point above the ground, m. Default 1.4 (below the sensor).
    pub max_height_m: f64,
    /// Reach of the box ahead of `base_link`, m. Default 5.
    pub ahead_m: f64,
    /// Half width of the box, m. Default 2.
    pub half_width_m: f64,
}

impl Default for SpuriousReturns {
    fn default() -> Self {
        Self {
            enabled: false,
            from_x_m: 6.0,
            to_x_m: 14.0,
            points_per_scan: 300,
            min_height_m: 0.8,
            max_height_m: 1.4,
            ahead_m: 5.0,
            half_width_m: 2.0,
        }
    }
}

impl SpuriousReturns {
    fn validate(&self) -> Result<(), ConfigError> {
        check_window("faults.spurious_returns", self.from_x_m, self.to_x_m)?;
        check_range(
            "faults.spurious_returns.points_per_scan",
            f64::from(self.points_per_scan),
            0.0,
            100_000.0,
        )?;
        check_range("faults.spurious_returns.min_height_m", self.min_height_m, 0.0, 10.0)?;
        check_range("faults.spurious_returns.max_height_m", self.max_height_m, self.min_height_m, 10.0)?;
        check_range("faults.spurious_returns.ahead_m", self.ahead_m, 0.1, 100.0)?;
        check_range("faults.spurious_returns.half_width_m", self.half_width_m, 0.1, 100.0)
    }
}

/// A patch of tall weeds between the rows (every inter-row of the field) over `length_m` from
/// `from_x_m`: clumps `width_m` wide whose heights are uniform in `[0.5, 1] · height_m`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WeedPatch {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Start of the patch along the rows, field x, m. Default 8.
    pub from_x_m: f64,
    /// Length of the patch along the rows, m. Default 3.
    pub length_m: f64,
    /// Tallest weed, m. Default 0.5 (as tall as young corn; issue 3 weeds are 1-8 cm).
    pub height_m: f64,
    /// Width of a clump, m. Default 0.3.
    pub width_m: f64,
    /// Clumps per square metre of inter-row in the patch. Default 3.
    pub clumps_per_m2: f64,
}

impl Default for WeedPatch {
    fn default() -> Self {
        Self { enabled: false, from_x_m: 8.0, length_m: 3.0, height_m: 0.5, width_m: 0.3, clumps_per_m2: 3.0 }
    }
}

impl WeedPatch {
    fn validate(&self) -> Result<(), ConfigError> {
        check_range("faults.weed_patch.from_x_m", self.from_x_m, -MAX_X_M, MAX_X_M)?;
        check_range("faults.weed_patch.length_m", self.length_m, 0.0, MAX_X_M)?;
        check_range("faults.weed_patch.height_m", self.height_m, 0.01, 3.0)?;
        check_range("faults.weed_patch.width_m", self.width_m, 0.02, 2.0)?;
        check_range("faults.weed_patch.clumps_per_m2", self.clumps_per_m2, 0.0, 50.0)
    }
}

/// A stretch of row with no plants (washed out, eaten, a failed planter unit): `length_m` from
/// `from_x_m` in the rows listed (all rows when the list is empty).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RowGap {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Start of the gap along the rows, field x, m. Default 8.
    pub from_x_m: f64,
    /// Length of the gap, m. Default 4 (longer than the 2.5 m `lane_switch.end_approach_m` window and
    /// the 1 m `lane_switch.max_blind_distance_m`).
    pub length_m: f64,
    /// Rows without plants in the gap (0 = the rightmost row); empty for every row. Default empty.
    pub rows: Vec<u32>,
}

impl Default for RowGap {
    fn default() -> Self {
        Self { enabled: false, from_x_m: 8.0, length_m: 4.0, rows: Vec::new() }
    }
}

impl RowGap {
    fn validate(&self) -> Result<(), ConfigError> {
        check_range("faults.row_gap.from_x_m", self.from_x_m, -MAX_X_M, MAX_X_M)?;
        check_range("faults.row_gap.length_m", self.length_m, 0.0, MAX_X_M)?;
        check_range("faults.row_gap.rows", self.rows.len() as f64, 0.0, 200.0)
    }

    /// True when row `row` has no plants at field x `x_m`.
    pub fn covers(&self, row: u32, x_m: f64) -> bool {
        self.enabled
            && x_m >= self.from_x_m
            && x_m <= self.from_x_m + self.length_m
            && (self.rows.is_empty() || self.rows.contains(&row))
    }
}

/// Wet soil while the robot's true x is in `[from_x_m, to_x_m]`: the longitudinal slip ratio is
/// `longitudinal_slip` instead of `robot.longitudinal_slip` (the wheels, and so the encoders, turn
/// faster than the robot moves), and the body slides sideways at `lateral_drift_m_s`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlipPatch {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Start of the patch, true x of `base_link`, m. Default 6.
    pub from_x_m: f64,
    /// End of the patch, m. Default 14.
    pub to_x_m: f64,
    /// Slip ratio inside the patch, in [0, 0.6]. Default 0.3 (issue 6: 20-40 %).
    pub longitudinal_slip: f64,
    /// Sideways slide inside the patch, m/s, positive to the robot's left, scaled by the forward speed
    /// over 0.5 m/s (a robot at rest does not slide). Default 0.05.
    pub lateral_drift_m_s: f64,
}

impl Default for SlipPatch {
    fn default() -> Self {
        Self { enabled: false, from_x_m: 6.0, to_x_m: 14.0, longitudinal_slip: 0.3, lateral_drift_m_s: 0.05 }
    }
}

impl SlipPatch {
    fn validate(&self) -> Result<(), ConfigError> {
        check_window("faults.slip_patch", self.from_x_m, self.to_x_m)?;
        check_range("faults.slip_patch.longitudinal_slip", self.longitudinal_slip, 0.0, 0.6)?;
        check_range("faults.slip_patch.lateral_drift_m_s", self.lateral_drift_m_s, -0.5, 0.5)
    }

    /// True when the patch is on and `x_m` is inside it.
    pub fn covers(&self, x_m: f64) -> bool {
        self.enabled && x_m >= self.from_x_m && x_m <= self.to_x_m
    }
}

/// The gyro z bias jumps by `step_rad_s` once the robot's true x passes `at_x_m` (a temperature
/// change, a knock) and stays there.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GyroBiasStep {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Where the bias jumps, true x of `base_link`, m. Default 6.
    pub at_x_m: f64,
    /// Size of the jump, rad/s. Default 0.02 (≈1.1°/s, four times the default bias).
    pub step_rad_s: f64,
}

impl Default for GyroBiasStep {
    fn default() -> Self {
        Self { enabled: false, at_x_m: 6.0, step_rad_s: 0.02 }
    }
}

impl GyroBiasStep {
    fn validate(&self) -> Result<(), ConfigError> {
        check_range("faults.gyro_bias_step.at_x_m", self.at_x_m, -MAX_X_M, MAX_X_M)?;
        check_range("faults.gyro_bias_step.step_rad_s", self.step_rad_s, -0.5, 0.5)
    }
}

/// Odometry transport faults, all run long: every wheel odometry and IMU stamp is shifted by a
/// uniform error in `±jitter_s` (never later than the time it is delivered), and each wheel odometry
/// message is, with `out_of_order_probability`, held back and delivered after the next one.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OdometryTiming {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Largest stamp error, s. Default 0.004 (a driver stamping on receipt with a busy CPU).
    pub jitter_s: f64,
    /// Probability that a wheel odometry message arrives after the next one, in [0, 0.5]. Default 0.05.
    pub out_of_order_probability: f64,
}

impl Default for OdometryTiming {
    fn default() -> Self {
        Self { enabled: false, jitter_s: 0.004, out_of_order_probability: 0.05 }
    }
}

impl OdometryTiming {
    fn validate(&self) -> Result<(), ConfigError> {
        check_range("faults.odometry_timing.jitter_s", self.jitter_s, 0.0, 0.1)?;
        check_range(
            "faults.odometry_timing.out_of_order_probability",
            self.out_of_order_probability,
            0.0,
            0.5,
        )
    }
}

/// Scans completed while the robot's true x is in `[from_x_m, to_x_m]` carry their stamp plus
/// `offset_s` (a clock jump, an unsynchronised sensor): positive in the future, negative in the past.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScanStamp {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Start of the stretch, true x of `base_link`, m. Default 8.
    pub from_x_m: f64,
    /// End of the stretch, m. Default 9.
    pub to_x_m: f64,
    /// Stamp error, s. Default 0.5.
    pub offset_s: f64,
}

impl Default for ScanStamp {
    fn default() -> Self {
        Self { enabled: false, from_x_m: 8.0, to_x_m: 9.0, offset_s: 0.5 }
    }
}

impl ScanStamp {
    fn validate(&self) -> Result<(), ConfigError> {
        check_window("faults.scan_stamp", self.from_x_m, self.to_x_m)?;
        check_range("faults.scan_stamp.offset_s", self.offset_s, -3600.0, 3600.0)
    }
}

/// The LiDAR's TRUE orientation differs from the nominal `lidar.mount` the navigator is given by
/// these angles (added to the mount's roll, pitch and yaw): from the start when `at_x_m` is at or
/// before the start, or from the first revolution after the robot's true x passes `at_x_m` (a branch
/// knocked the sensor).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct MountError {
    /// Inject this fault. Default false.
    pub enabled: bool,
    /// Where the mount is knocked, true x of `base_link`, m; at or before the start: mounted wrong.
    /// Default -1000 (from the start).
    pub at_x_m: f64,
    /// Roll error, deg. Default 0.
    pub roll_deg: f64,
    /// Pitch error, deg, positive nose down. Default 3 (issue 6: ±3°).
    pub pitch_deg: f64,
    /// Yaw error, deg. Default 0.
    pub yaw_deg: f64,
}

impl Default for MountError {
    fn default() -> Self {
        Self { enabled: false, at_x_m: -1000.0, roll_deg: 0.0, pitch_deg: 3.0, yaw_deg: 0.0 }
    }
}

impl MountError {
    fn validate(&self) -> Result<(), ConfigError> {
        check_range("faults.mount_error.at_x_m", self.at_x_m, -MAX_X_M, MAX_X_M)?;
        check_range("faults.mount_error.roll_deg", self.roll_deg, -10.0, 10.0)?;
        check_range("faults.mount_error.pitch_deg", self.pitch_deg, -10.0, 10.0)?;
        check_range("faults.mount_error.yaw_deg", self.yaw_deg, -10.0, 10.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_fault_is_off_by_default() {
        let f = FaultConfig::default();
        assert!(!f.any());
        f.validate().unwrap();
        assert_eq!(toml::from_str::<FaultConfig>("").unwrap(), f);
    }

    #[test]
    fn absurd_fault_parameters_name_the_field() {
        let mut f = FaultConfig::default();
        f.lidar_dropout.duration_s = -1.0;
        assert!(f.validate().unwrap_err().to_string().contains("faults.lidar_dropout.duration_s"));
        let mut f = FaultConfig::default();
        f.slip_patch.to_x_m = 1.0;
        assert!(f.validate().unwrap_err().to_string().contains("faults.slip_patch.to_x_m"));
        let mut f = FaultConfig::default();
        f.mount_error.pitch_deg = f64::NAN;
        assert!(f.validate().unwrap_err().to_string().contains("faults.mount_error.pitch_deg"));
        let mut f = FaultConfig::default();
        f.lidar_dropout.repeat_every_m = 0.1;
        assert!(f.validate().unwrap_err().to_string().contains("faults.lidar_dropout.repeat_every_m"));
    }

    #[test]
    fn unknown_fault_keys_are_refused() {
        let e = toml::from_str::<FaultConfig>("[slip_patch]\nslip = 0.3\n").unwrap_err().to_string();
        assert!(e.contains("slip"), "{e}");
    }

    #[test]
    fn a_row_gap_covers_its_rows_and_stretch_only() {
        let g = RowGap { enabled: true, from_x_m: 2.0, length_m: 3.0, rows: vec![4] };
        assert!(g.covers(4, 2.0) && g.covers(4, 5.0));
        assert!(!g.covers(4, 5.1) && !g.covers(3, 3.0));
        let all = RowGap { rows: Vec::new(), ..g.clone() };
        assert!(all.covers(0, 3.0) && all.covers(15, 3.0));
        assert!(!RowGap { enabled: false, ..g }.covers(4, 3.0));
    }
}
