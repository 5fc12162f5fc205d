//! # croprow-sim
//!
//! A seeded, reproducible crop-field simulator: procedural corn and soybean fields, a ray-cast VLP-16,
//! an Amiga-like skid-steer robot with noisy wheel odometry and IMU, ground truth and metrics, and the
//! paper's experiments as scenarios. It calls `croprow-core` only through its public facade.
#![warn(missing_docs)]
