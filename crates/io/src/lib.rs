//! # croprow-io
//!
//! Files and recordings: ROS 2 MCAP recordings (CDR-encoded messages) in and out, point-cloud maps
//! (PCD, PLY, LAS, text) and config files. Adapters only: every algorithm lives in `croprow-core`.
//!
//! - [`msg`]: the ROS 2 message structs (CDR via serde) and their `ros2msg` definitions.
//! - [`cloud`]: `PointCloud2` of any layout -> [`croprow_core::Point3`] into a reused buffer, and back.
//! - [`read`]: [`Recording`] / [`Replay`]: scans with interpolated odometry and the `/tf_static` mount.
//! - [`overrides`]: `--set section.key=value` on any configuration (CLI and ROS 2 node alike).
//! - [`write`]: [`RecordingWriter`]: clouds, odometry, IMU, tf, commands, rows and status for Foxglove.
#![warn(missing_docs)]

pub mod cloud;
pub mod maps;
pub mod msg;
pub mod odom;
pub mod overrides;
pub mod read;
pub mod tf;
pub mod write;

pub use read::{Recording, RecordingError, Replay, ReplayConfig, ScanFrame};
pub use write::{RecordingWriter, WriteError};
