//! One module per subcommand: argument struct + `run`.

pub mod bench;
pub mod demo;
pub mod detect;
pub mod detect_sim;
pub mod evaluate;
#[cfg(feature = "ros2")]
pub mod node;
pub mod rows;
pub mod scenarios;
pub mod simulate;
pub mod soak;
