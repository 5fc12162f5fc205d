//! Experiments: the paper's evaluations as reusable runs over a [`Scenario`](crate::Scenario), each
//! returning a plain report (numbers, no files) that the CLI prints and writes.
//!
//! - [`detection`]: Table I detection: a human-like driver wanders along a lane while the detector
//!   modes run side by side on the same scans, scored against the truth.
//! - [`soak`]: many short randomised fields driven end to end, watched for crop contacts and unsafe
//!   commands (issue 6).

pub mod detection;
pub mod soak;
