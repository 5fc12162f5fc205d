//! # croprow-io
//!
//! Files and recordings: ROS 2 MCAP recordings (CDR-encoded messages) in and out, point-cloud maps
//! (PCD, PLY, LAS, text) and config files. Adapters only: every algorithm lives in `croprow-core`.
#![warn(missing_docs)]

pub mod maps;
