//! Odometry: an EKF that fuses wheel odometry and an IMU into the planar `odom -> base_link` pose the
//! detector and the controller use (what robot_localization does on the paper's robot, Sec. III-A).
//!
//! ```
//! use croprow_core::odometry::{Ekf, EkfConfig};
//! let mut ekf = Ekf::new(EkfConfig::default()).unwrap();
//! ekf.update_wheel(0.00, 0.5, 0.0).unwrap();
//! ekf.update_imu(0.01, 0.0).unwrap();
//! ekf.update_wheel(0.02, 0.5, 0.0).unwrap();
//! assert!(ekf.pose().x > 0.0);
//! ```
//!
//! A gyro bias that steps while driving is found by the EKF's bias check (the wheels and the gyro
//! disagree persistently) and relearnt. What the wheels and the gyro cannot see (a sideways slide) is
//! estimated from the crop rows by [`Drift`] and removed in the navigator's own frame, `nav`. The
//! robot's roll and pitch on uneven ground come from the accelerometer ([`AttitudeFilter`]): the
//! navigator looks at the crop from a level frame.

mod attitude;
mod drift;
mod ekf;
mod slip;

pub use attitude::{AttitudeConfig, AttitudeError, AttitudeFilter};
pub use drift::{Drift, DriftConfig};
pub use ekf::{Ekf, EkfConfig, EkfError};
pub use slip::{SlipWitness, SlipWitnessConfig};
