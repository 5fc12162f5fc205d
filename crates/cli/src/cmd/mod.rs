//! One module per subcommand: argument struct + `run`.

pub mod bench;
pub mod detect;
pub mod detect_sim;
#[cfg(feature = "ros2")]
pub mod node;
pub mod rows;
pub mod scenarios;
