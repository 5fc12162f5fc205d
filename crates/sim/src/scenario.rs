//! Scenarios: a whole simulated experiment in one TOML file (field, sensor, robot, sensors, start pose,
//! driver, time step). The paper's experiments are built in (`young-corn`, `grown-corn`,
//! `young-soybean`, `grown-soybean`, `curved-corn`, `full-field`, `recovery`); their files live in
//! `crates/sim/scenarios/` and are embedded in the binary, so `croprow scenarios --show NAME` prints one
//! to copy and edit. Every section is optional: a file names only what it changes.
//!
//! ```
//! use croprow_sim::Scenario;
//! let s = Scenario::builtin("grown-corn").unwrap();
//! assert_eq!(s.field.rows, 16);
//! let custom = Scenario::from_toml_str("name = \"short\"\n[field]\nlength_m = 20.0\n").unwrap();
//! assert_eq!(custom.field.length_m, 20.0);
//! ```

use croprow_core::ConfigError;
use croprow_core::error::check_range;
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::driver::DriverConfig;
use crate::faults::FaultConfig;
use crate::field::FieldConfig;
use crate::lidar::LidarConfig;
use crate::robot::RobotConfig;
use crate::sensors::SensorConfig;

/// The built-in scenarios: name and TOML text.
const BUILTIN: [(&str, &str); 7] = [
    ("young-corn", include_str!("../scenarios/young-corn.toml")),
    ("grown-corn", include_str!("../scenarios/grown-corn.toml")),
    ("young-soybean", include_str!("../scenarios/young-soybean.toml")),
    ("grown-soybean", include_str!("../scenarios/grown-soybean.toml")),
    ("curved-corn", include_str!("../scenarios/curved-corn.toml")),
    ("full-field", include_str!("../scenarios/full-field.toml")),
    ("recovery", include_str!("../scenarios/recovery.toml")),
];

/// Why a scenario could not be loaded.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum ScenarioError {
    /// No built-in scenario has this name.
    #[error("unknown scenario `{name}` (built in: {known})")]
    Unknown {
        /// The name asked for.
        name: String,
        /// The built-in names, comma separated.
        known: String,
    },
    /// The TOML text is malformed or names an unknown key.
    #[error("scenario file: {0}")]
    Parse(String),
    /// A value is out of range.
    #[error(transparent)]
    Config(#[from] ConfigError),
}

/// Where and how the robot starts.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct StartConfig {
    /// Lane to drive in: between rows `lane` and `lane + 1` (row 0 is the rightmost). Default: the middle
    /// lane, `rows / 2 - 1` (omit the key for that).
    pub lane: Option<u32>,
    /// Start position along the rows, m. Default 1.
    pub x_m: f64,
    /// Start offset from the lane centre line, m, positive left. Default 0 (recovery: 0.3, paper Fig. 6).
    pub lateral_offset_m: f64,
    /// Start heading relative to the rows, deg, positive left. Default 0 (recovery: 8, paper Fig. 6).
    pub heading_offset_deg: f64,
}

impl Default for StartConfig {
    fn default() -> Self {
        Self { lane: None, x_m: 1.0, lateral_offset_m: 0.0, heading_offset_deg: 0.0 }
    }
}

/// Simulation clock settings.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct WorldConfig {
    /// Fixed time step, s. Default 0.01 (the IMU period).
    pub dt_s: f64,
    /// Fire the LiDAR columns as the robot moves during a revolution (motion skew, like a real spinning
    /// sensor). When false a whole revolution is cast from the pose at the scan stamp. Default true.
    pub motion_skew: bool,
}

impl Default for WorldConfig {
    fn default() -> Self {
        Self { dt_s: 0.01, motion_skew: true }
    }
}

/// A complete simulated experiment.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Scenario {
    /// Short name. Default "custom".
    pub name: String,
    /// One-line description.
    pub summary: String,
    /// Master seed: the field, the sensor noise, the slip and the driver derive their seeds from it.
    pub seed: u64,
    /// The field.
    pub field: FieldConfig,
    /// The LiDAR and its mount.
    pub lidar: LidarConfig,
    /// The robot.
    pub robot: RobotConfig,
    /// Wheel encoders and IMU.
    pub sensors: SensorConfig,
    /// Start pose.
    pub start: StartConfig,
    /// The human-like driver of detection runs.
    pub driver: DriverConfig,
    /// Time step.
    pub world: WorldConfig,
    /// Injected faults (issue 6), all off by default.
    pub faults: FaultConfig,
}

impl Default for Scenario {
    fn default() -> Self {
        Self {
            name: "custom".into(),
            summary: String::new(),
            seed: 0,
            field: FieldConfig::default(),
            lidar: LidarConfig::default(),
            robot: RobotConfig::default(),
            sensors: SensorConfig::default(),
            start: StartConfig::default(),
            driver: DriverConfig::default(),
            world: WorldConfig::default(),
            faults: FaultConfig::default(),
        }
    }
}

impl Scenario {
    /// Names of the built-in scenarios, in the paper's order.
    pub fn names() -> Vec<&'static str> {
        BUILTIN.iter().map(|(n, _)| *n).collect()
    }

    /// The TOML text of a built-in scenario.
    pub fn builtin_toml(name: &str) -> Option<&'static str> {
        BUILTIN.iter().find(|(n, _)| *n == name).map(|(_, t)| *t)
    }

    /// A built-in scenario by name.
    pub fn builtin(name: &str) -> Result<Self, ScenarioError> {
        let text = Self::builtin_toml(name)
            .ok_or_else(|| ScenarioError::Unknown { name: name.into(), known: Self::names().join(", ") })?;
        Self::from_toml_str(text)
    }

    /// Parses and validates a scenario file.
    pub fn from_toml_str(text: &str) -> Result<Self, ScenarioError> {
        let s: Scenario = toml::from_str(text).map_err(|e| ScenarioError::Parse(e.to_string()))?;
        s.validate()?;
        Ok(s)
    }

    /// The lane the robot drives in (the configured one or the middle lane).
    pub fn lane(&self) -> u32 {
        self.start.lane.unwrap_or((self.field.rows / 2).saturating_sub(1))
    }

    /// Checks every section, naming the first bad field.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.field.validate()?;
        self.lidar.validate()?;
        self.robot.validate()?;
        self.sensors.validate()?;
        self.driver.validate()?;
        self.faults.validate()?;
        if let Some(row) = self.faults.row_gap.rows.iter().find(|&&r| r >= self.field.rows) {
            return Err(ConfigError::invalid(
                "faults.row_gap.rows",
                format!("row {row} does not exist: the field has {} rows", self.field.rows),
            ));
        }
        if self.field.rows < 2 || self.lane() > self.field.rows - 2 {
            return Err(ConfigError::invalid(
                "start.lane",
                format!(
                    "lane {} needs rows {} and {} but the field has {}",
                    self.lane(),
                    self.lane(),
                    self.lane() + 1,
                    self.field.rows
                ),
            ));
        }
        check_range("start.x_m", self.start.x_m, -self.field.headland_m, self.field.length_m)?;
        check_range(
            "start.lateral_offset_m",
            self.start.lateral_offset_m,
            -self.field.row_spacing_m,
            self.field.row_spacing_m,
        )?;
        check_range("start.heading_offset_deg", self.start.heading_offset_deg, -90.0, 90.0)?;
        check_range("world.dt_s", self.world.dt_s, 1e-4, 0.05)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Crop, Stage};

    #[test]
    fn every_builtin_parses_and_validates() {
        for name in Scenario::names() {
            let s = Scenario::builtin(name).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(s.name, name);
            assert!(!s.summary.is_empty());
        }
        assert_eq!(Scenario::names().len(), 7);
    }

    #[test]
    fn builtins_match_the_paper() {
        let g = Scenario::builtin("grown-soybean").unwrap();
        assert_eq!(
            (g.field.crop, g.field.stage, g.field.rows, g.field.length_m),
            (Crop::Soybean, Stage::Grown, 16, 200.0)
        );
        assert_eq!(Scenario::builtin("curved-corn").unwrap().field.curve_amplitude_m, 6.0);
        assert_eq!(Scenario::builtin("full-field").unwrap().field.length_m, 30.0);
        let r = Scenario::builtin("recovery").unwrap();
        assert_eq!((r.start.lateral_offset_m, r.start.heading_offset_deg), (0.3, 8.0));
    }

    #[test]
    fn unknown_names_and_keys_are_refused() {
        assert!(matches!(Scenario::builtin("moon"), Err(ScenarioError::Unknown { .. })));
        let e = Scenario::from_toml_str("[field]\nrow_spacing = 0.75\n").unwrap_err().to_string();
        assert!(e.contains("row_spacing"), "{e}");
        let e = Scenario::from_toml_str("[field]\nrow_spacing_m = -0.75\n").unwrap_err().to_string();
        assert!(e.contains("field.row_spacing_m"), "{e}");
        let e = Scenario::from_toml_str("[lidar.mount]\nz_m = -1.0\n").unwrap_err().to_string();
        assert!(e.contains("lidar.mount.z_m"), "{e}");
        let e = Scenario::from_toml_str("[start]\nlane = 15\n").unwrap_err().to_string();
        assert!(e.contains("start.lane"), "{e}");
    }

    #[test]
    fn faults_are_a_validated_table() {
        let s = Scenario::from_toml_str("[faults.slip_patch]\nenabled = true\nlongitudinal_slip = 0.4\n")
            .unwrap();
        assert!(s.faults.slip_patch.enabled && s.faults.slip_patch.longitudinal_slip == 0.4);
        let e = Scenario::from_toml_str("[faults.slip_patch]\nlongitudinal_slip = 0.9\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("faults.slip_patch.longitudinal_slip"), "{e}");
        let e = Scenario::from_toml_str("[faults.row_gap]\nrows = [16]\n").unwrap_err().to_string();
        assert!(e.contains("faults.row_gap.rows"), "{e}");
    }
}
