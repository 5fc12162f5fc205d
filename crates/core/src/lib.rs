//! # croprow-core
//!
//! The pure heart of croprow: everything between a LiDAR scan and a velocity command, with no files,
//! sockets, clocks, threads or global logger. Time is always an input (stamped data), so simulation,
//! replay and a live robot run the very same code and tests are deterministic.
//!
//! The data flows one way, and the modules are named after that flow:
//!
//! ```text
//! sensor data ──► perception (rows in base_link) ──► control (centre line, MPC, lane switching) ──► (v, ω)
//!                      ▲
//! wheels + IMU ──► odometry (EKF, odom -> base_link)
//! ```
//!
//! Frames follow ROS REP-103 (x forward, y left, z up) and REP-105 (`odom`, `base_link`); units are SI.
#![warn(missing_docs)]

pub mod control;
pub mod error;
pub mod geometry;
pub mod mapping;
pub mod navigator;
pub mod odometry;
pub mod perception;

pub use error::ConfigError;
pub use geometry::{Attitude, Mount, Point3, Pose2, Twist2};
pub use mapping::RowMap;
pub use navigator::{NavInput, NavOutput, Navigator, NavigatorConfig};
pub use perception::{Detection, RowEstimate, RowStatus, Scan};
pub use perception::{DetectorConfig, DetectorMode, RowDetector};
