//! # croprow-sim
//!
//! A seeded, reproducible crop-field simulator: procedural corn and soybean fields, a ray-cast VLP-16,
//! an Amiga-like skid-steer robot with noisy wheel odometry and IMU, ground truth and metrics, and the
//! paper's experiments as scenarios. It calls `croprow-core` only through its public facade.
#![warn(missing_docs)]

pub mod field;
pub mod lidar;
mod scene;
pub mod terrain;

pub use field::{Crop, Field, FieldConfig, Stage, Stem};
pub use lidar::{BodyPose, Lidar, LidarConfig, ScanBuffer};
pub use scene::Class;
pub mod metrics;
pub mod robot;
pub mod sensors;

pub use metrics::{CropDamage, CrossTrack, DetectionErrors, ErrorStats, RowError};
pub use robot::{Robot, RobotConfig, StepError};
pub use sensors::{ImuSample, SensorConfig, Sensors, WheelOdometry};
