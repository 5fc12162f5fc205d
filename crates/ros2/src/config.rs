//! The node's configuration tree: the navigator's sections (`detector`, `reference`, `mpc`,
//! `lane_switch`, `input`, `drift`), the EKF (`ekf`), the fallback sensor mount (`mount`) and the node's own wiring
//! (`node`: topics, frames, watchdog). One dotted name per leaf, the same in a TOML file, in
//! `--set key=value` and as a ROS 2 parameter (`detector.range_m`, `mpc.horizon_steps`,
//! `node.stale_after_s`).
//!
//! ```
//! use croprow_ros2::NodeConfig;
//! let mut cfg = NodeConfig::default();
//! cfg.set("mpc.horizon_steps", "30").unwrap();
//! cfg.set("node.cloud_topic", "/points").unwrap();
//! assert_eq!(cfg.mpc.horizon_steps, 30);
//! assert!(cfg.set("mpc.horizon", "3").unwrap_err().to_string().contains("mpc.horizon"));
//! ```

use croprow_core::control::lane_switch::LaneSwitchConfig;
use croprow_core::control::mpc::MpcConfig;
use croprow_core::control::reference::ReferenceConfig;
use croprow_core::error::{ConfigError, check_range};
use croprow_core::navigator::InputConfig;
use croprow_core::odometry::{AttitudeConfig, DriftConfig, EkfConfig};
use croprow_core::{DetectorConfig, Mount, NavigatorConfig};
use croprow_io::overrides;
use serde::{Deserialize, Serialize};

/// Where the `odom -> base_link` pose comes from.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OdometrySource {
    /// A filtered `nav_msgs/Odometry` (e.g. robot_localization's `/odometry/filtered`), as on the
    /// paper's robot (Sec. III-A).
    #[default]
    Filtered,
    /// Wheel odometry (`nav_msgs/Odometry`, its twist) and a gyro (`sensor_msgs/Imu`) fused by the
    /// core EKF inside the node.
    WheelImu,
}

/// The node's wiring: topics, frames, rates and the watchdog. Dotted names `node.<field>`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Wiring {
    /// `sensor_msgs/PointCloud2` input. Default `/velodyne_points`.
    pub cloud_topic: String,
    /// Where odometry comes from. Default `filtered`.
    pub odometry: OdometrySource,
    /// `nav_msgs/Odometry` input when `odometry = "filtered"`. Default `/odometry/filtered`.
    pub odom_topic: String,
    /// `nav_msgs/Odometry` wheel odometry when `odometry = "wheel_imu"`. Default `/wheel/odometry`.
    pub wheel_odom_topic: String,
    /// `sensor_msgs/Imu` when `odometry = "wheel_imu"`. Default `/imu/data`.
    pub imu_topic: String,
    /// `geometry_msgs/Twist` output (body frame). Default `/cmd_vel`.
    pub cmd_vel_topic: String,
    /// `visualization_msgs/MarkerArray` output: the rows and centroids in `base_frame`. Default
    /// `/croprow/rows`.
    pub rows_topic: String,
    /// `nav_msgs/Path` output: the path being tracked, in `odom_frame`. Default `/croprow/path`.
    pub path_topic: String,
    /// `std_msgs/String` output: one JSON object per control step. Default `/croprow/status`.
    pub status_topic: String,
    /// `std_msgs/String` input: any message leaves a latched safety stop. Default `/croprow/resume`.
    pub resume_topic: String,
    /// The robot body frame (REP-105). Default `base_link`.
    pub base_frame: String,
    /// The odometry frame (REP-105). Default `odom`.
    pub odom_frame: String,
    /// Scans or odometry received longer ago than this stop the robot, s. Default 0.5.
    pub stale_after_s: f64,
    /// Period of the control step between scans, s. Default 0.05 (20 Hz; scans add steps).
    pub control_period_s: f64,
    /// Wall-time budget of one MPC solve, s; 0 means the iteration cap only. Default 0.03.
    pub mpc_budget_s: f64,
    /// Longest extrapolation of odometry to a scan stamp, s. Default 0.1.
    pub max_extrapolation_s: f64,
    /// Longest odometry gap interpolated across, s. Default 0.5.
    pub max_odom_gap_s: f64,
    /// Spacing of the poses published on `path_topic`, m. Default 0.25.
    pub path_spacing_m: f64,
}

impl Default for Wiring {
    fn default() -> Self {
        Self {
            cloud_topic: "/velodyne_points".into(),
            odometry: OdometrySource::Filtered,
            odom_topic: "/odometry/filtered".into(),
            wheel_odom_topic: "/wheel/odometry".into(),
            imu_topic: "/imu/data".into(),
            cmd_vel_topic: "/cmd_vel".into(),
            rows_topic: "/croprow/rows".into(),
            path_topic: "/croprow/path".into(),
            status_topic: "/croprow/status".into(),
            resume_topic: "/croprow/resume".into(),
            base_frame: "base_link".into(),
            odom_frame: "odom".into(),
            stale_after_s: 0.5,
            control_period_s: 0.05,
            mpc_budget_s: 0.03,
            max_extrapolation_s: 0.1,
            max_odom_gap_s: 0.5,
            path_spacing_m: 0.25,
        }
    }
}

impl Wiring {
    /// Checks every field, naming the first bad one (`node.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        for (field, topic) in [
            ("node.cloud_topic", &self.cloud_topic),
            ("node.odom_topic", &self.odom_topic),
            ("node.wheel_odom_topic", &self.wheel_odom_topic),
            ("node.imu_topic", &self.imu_topic),
            ("node.cmd_vel_topic", &self.cmd_vel_topic),
            ("node.rows_topic", &self.rows_topic),
            ("node.path_topic", &self.path_topic),
            ("node.status_topic", &self.status_topic),
            ("node.resume_topic", &self.resume_topic),
        ] {
            if !topic.starts_with('/') || topic.len() < 2 || topic.ends_with('/') || topic.contains("//") {
                return Err(ConfigError::invalid(field, format!("`{topic}` is not an absolute topic name")));
            }
        }
        for (field, frame) in [("node.base_frame", &self.base_frame), ("node.odom_frame", &self.odom_frame)] {
            if frame.is_empty() {
                return Err(ConfigError::invalid(field, "must name a frame"));
            }
        }
        check_range("node.stale_after_s", self.stale_after_s, 0.05, 10.0)?;
        check_range("node.control_period_s", self.control_period_s, 0.005, 1.0)?;
        check_range("node.mpc_budget_s", self.mpc_budget_s, 0.0, 1.0)?;
        check_range("node.max_extrapolation_s", self.max_extrapolation_s, 0.0, 1.0)?;
        check_range("node.max_odom_gap_s", self.max_odom_gap_s, 0.0, 10.0)?;
        check_range("node.path_spacing_m", self.path_spacing_m, 0.01, 10.0)?;
        Ok(())
    }
}

/// Everything the node is built from. A TOML file names only what it overrides.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct NodeConfig {
    /// Crop-row detector.
    pub detector: DetectorConfig,
    /// Centre-line reference.
    pub reference: ReferenceConfig,
    /// Nonlinear MPC.
    pub mpc: MpcConfig,
    /// Lane switching and headland turns.
    pub lane_switch: LaneSwitchConfig,
    /// The EKF, used when `node.odometry = "wheel_imu"`.
    pub ekf: EkfConfig,
    /// Checks of each step's input (scan stamp tolerance).
    pub input: InputConfig,
    /// The odometry's unsensed drift learned from the rows (off by default).
    pub drift: DriftConfig,
    /// Roll and pitch from the IMU's accelerometer, used when `node.odometry = "wheel_imu"` (with
    /// `filtered` odometry no IMU is read, and `base_link` is taken as level).
    pub attitude: AttitudeConfig,
    /// `base_link -> sensor` used until `/tf_static` gives one for the cloud's frame. Default: the
    /// paper's mount (Sec. IV).
    pub mount: Mount,
    /// Topics, frames, watchdog.
    pub node: Wiring,
}

impl NodeConfig {
    /// Parses a TOML file's text and validates it.
    pub fn from_toml(text: &str) -> Result<Self, ConfigError> {
        let cfg: Self = toml::from_str(text).map_err(|e| ConfigError::invalid("config", e.to_string()))?;
        cfg.validate()?;
        Ok(cfg)
    }

    /// Validates every section.
    pub fn validate(&self) -> Result<(), ConfigError> {
        self.navigator().validate()?;
        self.mount.validate()?;
        self.node.validate()
    }

    /// The navigator's sections.
    pub fn navigator(&self) -> NavigatorConfig {
        NavigatorConfig {
            detector: self.detector.clone(),
            reference: self.reference.clone(),
            mpc: self.mpc.clone(),
            lane_switch: self.lane_switch.clone(),
            ekf: self.ekf.clone(),
            input: self.input.clone(),
            drift: self.drift.clone(),
            attitude: self.attitude.clone(),
        }
    }

    /// Every leaf as `(dotted name, value)`, in a stable order: what the node declares as ROS 2
    /// parameters.
    pub fn leaves(&self) -> Vec<(String, toml::Value)> {
        let mut out = Vec::new();
        if let Ok(toml::Value::Table(t)) = toml::Value::try_from(self) {
            flatten("", &t, &mut out);
        }
        out
    }

    /// Sets one leaf from text, parsed as the leaf's type (`--set mpc.horizon_steps=30`); the result
    /// is validated and `self` is unchanged on error.
    pub fn set(&mut self, key: &str, text: &str) -> Result<(), ConfigError> {
        let value = overrides::parse_as(&self.leaf(key)?, key, text)?;
        self.set_value(key, value)
    }

    /// Sets one leaf to a typed value (an integer is accepted for a float leaf); validated, and
    /// `self` is unchanged on error.
    pub fn set_value(&mut self, key: &str, value: toml::Value) -> Result<(), ConfigError> {
        // Only existing leaves: a node parameter can never create a section.
        self.leaf(key)?;
        let cfg = overrides::set(self, key, value)?;
        cfg.validate()?;
        *self = cfg;
        Ok(())
    }

    /// The current value of a leaf.
    pub fn leaf(&self, key: &str) -> Result<toml::Value, ConfigError> {
        overrides::leaf(self, key)
    }
}

fn flatten(prefix: &str, table: &toml::Table, out: &mut Vec<(String, toml::Value)>) {
    for (k, v) in table {
        let name = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
        match v {
            toml::Value::Table(t) => flatten(&name, t, out),
            leaf => out.push((name, leaf.clone())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_round_trip_through_toml() {
        let cfg = NodeConfig::default();
        cfg.validate().unwrap();
        let text = toml::to_string(&cfg).unwrap();
        assert_eq!(NodeConfig::from_toml(&text).unwrap(), cfg);
    }

    #[test]
    fn a_file_names_only_what_it_overrides() {
        let cfg = NodeConfig::from_toml("[node]\nstale_after_s = 0.3\n[mpc]\nhorizon_steps = 25\n").unwrap();
        assert_eq!((cfg.node.stale_after_s, cfg.mpc.horizon_steps), (0.3, 25));
        assert_eq!(cfg.detector, DetectorConfig::default());
    }

    #[test]
    fn unknown_and_invalid_file_settings_are_refused() {
        assert!(NodeConfig::from_toml("[node]\nstale_after = 0.3\n").is_err());
        let e = NodeConfig::from_toml("[node]\nstale_after_s = -1.0\n").unwrap_err();
        assert!(e.to_string().contains("node.stale_after_s"), "{e}");
    }

    #[test]
    fn set_parses_as_the_leaf_type() {
        let mut cfg = NodeConfig::default();
        cfg.set("detector.range_m", "5").unwrap();
        cfg.set("detector.mode", "paper").unwrap();
        cfg.set("detector.fit_curvature", "false").unwrap();
        cfg.set("node.odometry", "wheel_imu").unwrap();
        assert_eq!(cfg.detector.range_m, 5.0);
        assert_eq!(cfg.detector.mode, croprow_core::DetectorMode::Paper);
        assert!(!cfg.detector.fit_curvature);
        assert_eq!(cfg.node.odometry, OdometrySource::WheelImu);
    }

    #[test]
    fn bad_set_names_the_key_and_changes_nothing() {
        let mut cfg = NodeConfig::default();
        for (key, value) in [
            ("mpc.horizon_steps", "many"),
            ("mpc.horizon_steps", "0"),
            ("detector.mode", "magic"),
            ("mpc.nope", "1"),
            ("mpc", "1"),
            ("node.cmd_vel_topic", "cmd_vel"),
        ] {
            let e = cfg.set(key, value).unwrap_err();
            assert!(e.to_string().contains(key), "{key}: {e}");
        }
        assert_eq!(cfg, NodeConfig::default());
    }

    #[test]
    fn set_value_accepts_an_integer_for_a_float_and_refuses_other_types() {
        let mut cfg = NodeConfig::default();
        cfg.set_value("node.stale_after_s", toml::Value::Integer(1)).unwrap();
        assert_eq!(cfg.node.stale_after_s, 1.0);
        assert!(cfg.set_value("mpc.horizon_steps", toml::Value::Float(3.5)).is_err());
        assert!(cfg.set_value("node.stale_after_s", toml::Value::String("x".into())).is_err());
    }

    #[test]
    fn leaves_name_every_setting_once() {
        let leaves = NodeConfig::default().leaves();
        let names: Vec<&str> = leaves.iter().map(|(n, _)| n.as_str()).collect();
        for name in [
            "detector.range_m",
            "mpc.horizon_steps",
            "lane_switch.lanes",
            "ekf.max_gap_s",
            "input.scan_stamp_tolerance_s",
            "drift.enabled",
            "mount.z_m",
            "node.stale_after_s",
        ] {
            assert_eq!(names.iter().filter(|n| **n == name).count(), 1, "{name}");
        }
        let cfg = NodeConfig::default();
        for (name, value) in &leaves {
            assert_eq!(&cfg.leaf(name).unwrap(), value, "{name}");
        }
    }
}
