//! # croprow-sim
//!
//! A seeded, reproducible crop-field simulator: procedural corn and soybean fields, a ray-cast VLP-16,
//! an Amiga-like skid-steer robot with noisy wheel odometry and IMU, ground truth and metrics, and the
//! paper's experiments as scenarios. It calls `croprow-core` only through its public types.
//!
//! The pieces, in the order data flows through them:
//!
//! ```text
//! Scenario (TOML) ──► Field (plants, weeds, terrain, true rows) ──► Lidar (sensor-frame points + classes)
//!                 ──► Robot (true pose) ──► Sensors (wheel odometry, IMU)
//! World::step(cmd) ties them together at a fixed dt; Driver is the human operator of detection runs;
//! metrics score detections (Table I), cross-track error and crop contacts against the truth.
//! faults (a scenario's [faults] table) inject what a field throws at a robot, each where it happens.
//! ```
//!
//! Every random process has its own `ChaCha8Rng` seeded from the scenario seed: the same scenario gives
//! the same fields, scans and sensor streams bit for bit.
//!
//! ```
//! use croprow_sim::{Scenario, World, metrics};
//! let mut scenario = Scenario::builtin("grown-corn").unwrap();
//! scenario.field.length_m = 10.0;
//! let mut world = World::new(&scenario).unwrap();
//! let mut driver = world.driver().unwrap();
//! for _ in 0..20 {
//!     let cmd = driver.command(world.time_s(), &world.robot().pose(), world.field());
//!     // A step borrows the world (its scan points are the world's buffer): copy out what outlives it.
//!     let pose = world.step(cmd).unwrap().truth.pose;
//!     let ct = metrics::cross_track(world.field(), world.lane(), &pose).unwrap();
//!     assert!(ct.lateral_m.abs() < 0.2);
//! }
//! ```
#![warn(missing_docs)]

pub mod closed_loop;
pub mod driver;
pub mod experiment;
pub mod faults;
pub mod field;
pub mod lidar;
pub mod metrics;
pub mod robot;
pub mod scenario;
mod scene;
pub mod sensors;
pub mod terrain;
pub mod world;

pub use closed_loop::{ClosedLoop, Metrics, Run, RunConfig, RunError};
pub use driver::{Driver, DriverConfig};
pub use faults::FaultConfig;
pub use field::{Crop, Field, FieldConfig, Stage, Stem};
pub use lidar::{BodyPose, Lidar, LidarConfig, ScanBuffer};
pub use metrics::{CropDamage, CrossTrack, DetectionErrors, ErrorStats, RowError, TrueRow};
pub use robot::{Robot, RobotConfig, StepError};
pub use scenario::{Scenario, ScenarioError, StartConfig, WorldConfig};
pub use scene::Class;
pub use sensors::{ImuSample, SensorConfig, Sensors, WheelOdometry};
pub use world::{ScanView, Step, World};
