//! Perception: from one LiDAR scan (sensor frame) and the odometry pose to the first crop row on the
//! robot's left and right, as lines in `base_link` (REP-103).
//!
//! The types here are the contract between perception and everything downstream (control, recordings,
//! the ROS node, evaluation). The detector itself lives in the sub-modules, in the order of the flow:
//!
//! ```text
//! Scan (sensor) ─► preprocess: base_link, FOV/range crop, level (default mode), canopy above a virtual
//!                  ground plane
//!               ─► paper:   K-means per depth bin ─► centroid map (odom) ─► RANSAC, first row left/right
//!               ─► lanes:   rows binned against the predicted lane ─► centroid map (odom)
//!                           ─► joint least squares of all rows (offset, heading, curvature, spacing) ─► row end
//!               ─► Detection (base_link) + RowStatus
//! ```
//!
//! ```
//! use croprow_core::{DetectorConfig, Mount, Point3, Pose2, RowDetector, Scan};
//! let mut detector = RowDetector::new(DetectorConfig::default())?;
//! let points = vec![Point3::new(2.0, 0.3, -1.0); 10];
//! let d = detector.detect(Scan { stamp_s: 0.0, points: &points, twist: None, attitude: None }, Pose2::default(), &Mount::default());
//! println!("{}: {:?} {:?}", d.status.as_str(), d.left, d.right);
//! # Ok::<(), croprow_core::ConfigError>(())
//! ```

use serde::{Deserialize, Serialize};

mod config;
mod deskew;
mod detector;
mod holes;
mod interleave;
mod lanes;
mod level;
mod map;
mod paper;
mod preprocess;
mod register;
mod rng;

pub use config::{DetectorConfig, DetectorMode};
pub use detector::RowDetector;
#[doc(hidden)]
pub use detector::Stage;
pub use level::{LevelStatus, Tilt};

use crate::geometry::{Attitude, Point3, Twist2};

/// One LiDAR revolution, borrowed: points in the sensor frame (m) and the stamp of the scan (s).
///
/// The stamp is the time at which the odometry pose passed alongside the scan is valid (for a Velodyne
/// driver, the end of the sweep). Non-finite points are allowed and skipped by the detector.
#[derive(Debug, Clone, Copy)]
pub struct Scan<'a> {
    /// Scan time, s (any epoch, but the same clock as the odometry).
    pub stamp_s: f64,
    /// Points in the sensor frame, m.
    pub points: &'a [Point3],
    /// Body twist of `base_link` over the sweep (v, ω in `base_link`), for undoing the motion skew
    /// (`detector.deskew`). `None`, or a non-finite twist, leaves the scan as stamped. The
    /// [`Navigator`](crate::Navigator) fills it from `NavInput::odom_twist` when it is `None`.
    pub twist: Option<Twist2>,
    /// Roll and pitch of `base_link` against gravity at the scan (from the accelerometer:
    /// [`crate::odometry::AttitudeFilter`]). On a slope a plant's canopy leans, in `base_link`, by its
    /// height times the roll (3 cm for a 1 m canopy at 1.7°); the detector puts each return back over
    /// the ground it stands on. `None` takes `base_link` as level; beyond ±0.5 rad or not finite, the
    /// scan is refused (`invalid_input`). The rows are then reported in that upright view of
    /// `base_link` (the same frame up to the tilt's cosine: 0.05 % at 1.7°).
    pub attitude: Option<Attitude>,
}

/// What the detector knows about the rows after a scan. Outcomes are data: the caller decides.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
#[non_exhaustive]
pub enum RowStatus {
    /// Not enough evidence yet for a row line (start-up, or re-acquiring after a reset).
    Searching,
    /// At least one of the two neighbouring rows is tracked.
    Tracking,
    /// The canopy ahead has ended: the robot is at the end of the row.
    EndOfRow,
    /// Rows were tracked but have not been seen for too long: stop, do not guess.
    Lost,
    /// This scan or its pose was unusable (empty, non-finite, time going backwards, odometry jump);
    /// the previous state is kept and nothing was updated.
    InvalidInput,
}

impl RowStatus {
    /// Stable lower-case name, as written in JSON lines and ROS status messages.
    pub fn as_str(&self) -> &'static str {
        match self {
            RowStatus::Searching => "searching",
            RowStatus::Tracking => "tracking",
            RowStatus::EndOfRow => "end_of_row",
            RowStatus::Lost => "lost",
            RowStatus::InvalidInput => "invalid_input",
        }
    }
}

/// One detected crop row, in `base_link` at the scan stamp.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RowEstimate {
    /// The row as a segment `[x1, y1, x2, y2]` in `base_link`, m, with `x1 < x2` (the paper's output).
    pub line: [f64; 4],
    /// Signed lateral offset of the row at the robot (x = 0) in `base_link`, m; positive to the left.
    pub offset_m: f64,
    /// Row direction relative to the robot's x axis, rad, counter-clockwise positive.
    pub heading_rad: f64,
    /// Row curvature, 1/m (positive bends left); 0 when the detector fits straight lines.
    pub curvature_per_m: f64,
    /// Confidence in [0, 1]: how well the evidence supports this row.
    pub confidence: f64,
}

/// The result of one detector step.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Detection {
    /// Stamp of the scan this detection belongs to, s.
    pub stamp_s: f64,
    /// First crop row on the robot's left (y > 0), if any.
    pub left: Option<RowEstimate>,
    /// First crop row on the robot's right (y < 0), if any.
    pub right: Option<RowEstimate>,
    /// Overall status.
    pub status: RowStatus,
    /// Row spacing estimated online, m (crop-agnostic: never configured), when known.
    pub row_spacing_m: Option<f64>,
    /// Distance along the rows from `base_link` to where the canopy ends, m, once that end is in view
    /// (negative once the robot has passed it). Lane switching uses it to clear the row end.
    pub row_end_ahead_m: Option<f64>,
}

impl Detection {
    /// A detection with no rows and the given status. Build richer ones with struct update syntax,
    /// `Detection { left: Some(row), ..Detection::empty(t, RowStatus::Tracking) }`, so that fields added
    /// later do not break callers.
    pub fn empty(stamp_s: f64, status: RowStatus) -> Self {
        Self { stamp_s, left: None, right: None, status, row_spacing_m: None, row_end_ahead_m: None }
    }
}

/// Returns the finite points of a slice as an iterator (non-finite points are sensor dropouts).
pub fn finite_points(points: &[Point3]) -> impl Iterator<Item = &Point3> {
    points.iter().filter(|p| p.is_finite())
}
