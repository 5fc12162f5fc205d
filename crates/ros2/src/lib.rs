//! # croprow-ros2
//!
//! The live ROS 2 node: `croprow node` on the robot. It subscribes to a `sensor_msgs/PointCloud2`
//! (`/velodyne_points`) and to filtered odometry (`/odometry/filtered`), or to wheel odometry and an
//! IMU (then the core EKF fuses them), reads the sensor mount from `/tf_static`, and publishes
//! `/cmd_vel`, the rows (`MarkerArray`), the tracked path (`nav_msgs/Path`) and a status
//! (`std_msgs/String`, one JSON object per step).
//!
//! ```text
//! DDS readers ──► NodeCore (pure: messages + receive time in, messages out) ──► DDS writers
//!                    │ watchdog (stale scan / odometry) ─► zero command + reason
//!                    └ croprow_core::Navigator (detector ─► reference ─► MPC ─► lane switching)
//! ```
//!
//! - [`config`]: [`NodeConfig`], the dotted names shared by the config file, `--set` and ROS parameters.
//! - [`logic`]: [`NodeCore`], every decision and safety rule, testable without a network.
//! - [`dds`]: [`LiveNode`], the shell on `ros2-client` + RustDDS (pure Rust, no ROS install), with
//!   a participant restricted to the given networks (loopback by default: no multicast).
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use croprow_ros2::{DdsOptions, LiveNode, NodeConfig};
//! let mut node = LiveNode::new(NodeConfig::default(), &DdsOptions::default())?;
//! node.run(&AtomicBool::new(false), |out| eprintln!("{}", out.status.data))?;
//! # Ok::<(), croprow_ros2::DdsError>(())
//! ```
#![warn(missing_docs)]

pub mod config;
mod convert;
pub mod dds;
pub mod logic;

pub use config::{NodeConfig, OdometrySource, Wiring};
pub use convert::twist;
pub use dds::{DdsError, DdsOptions, LiveNode};
pub use logic::{Halt, InputError, NodeCore, Output};
