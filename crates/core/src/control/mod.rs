//! Control: the centre-line reference between the detected rows, a nonlinear MPC that outputs
//! `(v, ω)`, and the lane-switching state machine that covers a whole field.
//!
//! ```text
//! Detection ──► reference (centre line, a Path in odom) ──┐
//!                                                         ├──► lane_switch (mode, path, speed) ──► mpc ──► (v, ω)
//! row end + odometry ──► headland turn (a Path in odom) ──┘
//! ```

pub mod headland;
pub mod lane_switch;
pub mod mpc;
pub mod path;
pub mod reference;

pub use lane_switch::{Guidance, LaneSwitchConfig, LaneSwitcher, Mode, StopReason, TurnDirection};
pub use mpc::{Mpc, MpcConfig, SolveStatus};
pub use path::{Frenet, Path};
pub use reference::{Reference, ReferenceConfig};
