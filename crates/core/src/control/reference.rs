//! The centre-line reference: from a [`Detection`] (rows in `base_link` at the scan stamp) to a
//! [`Path`] in `odom` that the MPC tracks.
//!
//! The reference lives in `odom` so that odometry carries it between scans: a control step at 50 Hz
//! projects the current odometry pose onto the line built from the last 10 Hz scan.
//!
//! * Both rows seen: the midline (mean offset, heading and curvature).
//! * One row seen: that row shifted by half a row spacing towards the robot's lane, with the spacing
//!   the detector estimated online or, until it has one, `reference.fallback_row_spacing_m`.
//! * No row: the previous reference is kept; the caller decides how long it may be trusted.

use serde::{Deserialize, Serialize};

use crate::control::path::Path;
use crate::error::{ConfigError, check_range};
use crate::geometry::Pose2;
use crate::perception::{Detection, RowEstimate};

/// Settings of the centre-line reference.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ReferenceConfig {
    /// Row spacing used with a single visible row until the detector estimates one, m.
    /// Default 0.75 (the paper's fields, Sec. V).
    pub fallback_row_spacing_m: f64,
    /// Length of the reference ahead of the robot, m. Default 10 (beyond the 2 s horizon at any speed).
    pub ahead_m: f64,
    /// Length of the reference behind the robot, m. Default 2.
    pub behind_m: f64,
    /// Use the detector's curvature; false fits straight centre lines. Default true.
    pub use_curvature: bool,
    /// Largest curvature magnitude believed, 1/m; larger values are clamped. Default 0.2 (5 m radius).
    pub max_curvature_per_m: f64,
}

impl Default for ReferenceConfig {
    fn default() -> Self {
        Self {
            fallback_row_spacing_m: 0.75,
            ahead_m: 10.0,
            behind_m: 2.0,
            use_curvature: true,
            max_curvature_per_m: 0.2,
        }
    }
}

impl ReferenceConfig {
    /// Checks every field, naming the first bad one (`reference.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("reference.fallback_row_spacing_m", self.fallback_row_spacing_m, 0.1, 5.0)?;
        check_range("reference.ahead_m", self.ahead_m, 0.5, 1000.0)?;
        check_range("reference.behind_m", self.behind_m, 0.0, 1000.0)?;
        check_range("reference.max_curvature_per_m", self.max_curvature_per_m, 0.0, 10.0)?;
        Ok(())
    }
}

/// The centre line in `base_link` at the scan: where the robot should be.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CentreLine {
    /// Lateral offset of the centre line at x = 0, m, positive left.
    pub offset_m: f64,
    /// Direction of the centre line relative to the robot's x axis, rad.
    pub heading_rad: f64,
    /// Curvature, 1/m, positive bends left.
    pub curvature_per_m: f64,
}

impl CentreLine {
    /// The centre line as a pose in `base_link`: the point at x = 0 and its direction.
    pub fn pose(&self) -> Pose2 {
        Pose2::new(0.0, self.offset_m, self.heading_rad)
    }
}

/// Builds and keeps the centre-line path. Its path buffer is allocated once.
#[derive(Debug, Clone)]
pub struct Reference {
    cfg: ReferenceConfig,
    path: Path,
    stamp_s: Option<f64>,
}

impl Reference {
    /// Validates the configuration.
    pub fn new(cfg: ReferenceConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self { cfg, path: Path::with_capacity(1), stamp_s: None })
    }

    /// The configuration.
    pub fn config(&self) -> &ReferenceConfig {
        &self.cfg
    }

    /// The centre line a detection implies, in `base_link`, or `None` without a usable row.
    pub fn centre_line(&self, detection: &Detection) -> Option<CentreLine> {
        centre_line(&self.cfg, detection)
    }

    /// The row spacing of a detection, or the fallback, m.
    fn spacing_m(&self, detection: &Detection) -> f64 {
        spacing_m(&self.cfg, detection)
    }

    /// Updates the path from a detection and the `odom` pose at its scan stamp. Returns false (and
    /// keeps the previous path) when the detection has no usable row or the pose is not finite.
    pub fn update(&mut self, detection: &Detection, odom_at_scan: &Pose2) -> bool {
        if !odom_at_scan.is_finite() {
            return false;
        }
        let Some(line) = self.centre_line(detection) else { return false };
        self.set_line(odom_at_scan.compose(&line.pose()), line.curvature_per_m);
        self.path.set_row_spacing(Some(self.spacing_m(detection)));
        self.stamp_s = Some(detection.stamp_s);
        true
    }

    /// Sets the path to the line through `pose_odom` (a point of the line and its direction, in
    /// `odom`) with curvature `curvature_per_m`, from `behind_m` behind to `ahead_m` ahead.
    /// The row spacing the path carries is kept.
    pub fn set_line(&mut self, pose_odom: Pose2, curvature_per_m: f64) {
        let spacing = self.path.row_spacing_m();
        self.path.clear();
        self.path.push(pose_odom, 1.0, curvature_per_m);
        let start = self.path.pose_at(-self.cfg.behind_m);
        self.path.clear();
        self.path.push(start, self.cfg.behind_m + self.cfg.ahead_m, curvature_per_m);
        self.path.set_row_spacing(spacing);
    }

    /// Makes the current line straight from its point closest to `pose` on: past the row end the
    /// robot keeps the last row direction instead of extrapolating a curve into the headland.
    pub fn straighten_at(&mut self, pose: &Pose2) {
        if self.path.is_empty() {
            return;
        }
        let f = self.path.project(pose, 0.0);
        let on = self.path.pose_at(f.s_m);
        self.set_line(on, 0.0);
    }

    /// The current path, if a detection ever gave one.
    pub fn path(&self) -> Option<&Path> {
        (!self.path.is_empty()).then_some(&self.path)
    }

    /// Stamp of the detection behind the current path, s.
    pub fn stamp_s(&self) -> Option<f64> {
        self.stamp_s
    }

    /// Forgets the path.
    pub fn reset(&mut self) {
        self.path.clear();
        self.stamp_s = None;
    }
}

/// The centre line a detection implies under `cfg`, in `base_link`, or `None` without a usable row
/// (see the module docs).
pub fn centre_line(cfg: &ReferenceConfig, detection: &Detection) -> Option<CentreLine> {
    let spacing = spacing_m(cfg, detection);
    let usable = |r: &Option<RowEstimate>| {
        r.filter(|r| {
            r.offset_m.is_finite()
                && r.heading_rad.is_finite()
                && r.curvature_per_m.is_finite()
                && r.heading_rad.abs() < 1.2
        })
    };
    let shifted = |r: &RowEstimate, side: f64| {
        // The centre is parallel to the row at half a spacing: its offset at x = 0 grows by 1/cos.
        CentreLine {
            offset_m: r.offset_m - side * 0.5 * spacing / r.heading_rad.cos(),
            heading_rad: r.heading_rad,
            curvature_per_m: r.curvature_per_m,
        }
    };
    let line = match (usable(&detection.left), usable(&detection.right)) {
        (Some(l), Some(r)) => CentreLine {
            offset_m: 0.5 * (l.offset_m + r.offset_m),
            heading_rad: 0.5 * (l.heading_rad + r.heading_rad),
            curvature_per_m: 0.5 * (l.curvature_per_m + r.curvature_per_m),
        },
        (Some(l), None) => shifted(&l, 1.0),
        (None, Some(r)) => shifted(&r, -1.0),
        (None, None) => return None,
    };
    let k = if cfg.use_curvature {
        line.curvature_per_m.clamp(-cfg.max_curvature_per_m, cfg.max_curvature_per_m)
    } else {
        0.0
    };
    Some(CentreLine { curvature_per_m: k, ..line })
}

/// The row spacing of a detection, or `cfg`'s fallback, m.
fn spacing_m(cfg: &ReferenceConfig, detection: &Detection) -> f64 {
    detection.row_spacing_m.filter(|s| s.is_finite() && *s > 0.0).unwrap_or(cfg.fallback_row_spacing_m)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::RowStatus;

    fn row(offset_m: f64, heading_rad: f64) -> RowEstimate {
        RowEstimate {
            line: [0.0, offset_m, 4.0, offset_m],
            offset_m,
            heading_rad,
            curvature_per_m: 0.01,
            confidence: 1.0,
        }
    }

    #[test]
    fn two_rows_give_the_midline() {
        let r = Reference::new(ReferenceConfig::default()).unwrap();
        let d = Detection {
            left: Some(row(0.45, 0.05)),
            right: Some(row(-0.31, 0.03)),
            ..Detection::empty(0.0, RowStatus::Tracking)
        };
        let c = r.centre_line(&d).unwrap();
        assert!((c.offset_m - 0.07).abs() < 1e-12 && (c.heading_rad - 0.04).abs() < 1e-12);
        assert!((c.curvature_per_m - 0.01).abs() < 1e-12);
    }

    #[test]
    fn one_row_is_shifted_by_half_the_estimated_spacing() {
        let r = Reference::new(ReferenceConfig::default()).unwrap();
        let d = Detection {
            right: Some(row(-0.3, 0.0)),
            row_spacing_m: Some(0.8),
            ..Detection::empty(0.0, RowStatus::Tracking)
        };
        assert!((r.centre_line(&d).unwrap().offset_m - 0.1).abs() < 1e-12);
        let d = Detection { left: Some(row(0.3, 0.0)), ..Detection::empty(0.0, RowStatus::Tracking) };
        assert!((r.centre_line(&d).unwrap().offset_m - (0.3 - 0.375)).abs() < 1e-12);
    }

    #[test]
    fn reference_is_carried_in_odom() {
        let mut r = Reference::new(ReferenceConfig::default()).unwrap();
        let straight = |o| RowEstimate { curvature_per_m: 0.0, ..row(o, 0.0) };
        let d = Detection {
            left: Some(straight(0.5)),
            right: Some(straight(-0.3)),
            ..Detection::empty(0.0, RowStatus::Tracking)
        };
        let scan_pose = Pose2::new(10.0, 5.0, std::f64::consts::FRAC_PI_2);
        assert!(r.update(&d, &scan_pose));
        // Later the robot has moved 1 m along odom y: the centre line is still 0.1 m to its left (-x).
        let f = r.path().unwrap().project(&Pose2::new(10.0, 6.0, std::f64::consts::FRAC_PI_2), 0.0);
        assert!((f.lateral_m + 0.1).abs() < 1e-6, "{f:?}");
    }

    #[test]
    fn no_row_or_bad_numbers_keep_the_previous_path() {
        let mut r = Reference::new(ReferenceConfig::default()).unwrap();
        assert!(!r.update(&Detection::empty(0.0, RowStatus::Searching), &Pose2::default()));
        assert!(r.path().is_none());
        let d = Detection { left: Some(row(f64::NAN, 0.0)), ..Detection::empty(0.0, RowStatus::Tracking) };
        assert!(!r.update(&d, &Pose2::default()));
        let good = Detection { left: Some(row(0.4, 0.0)), ..Detection::empty(0.0, RowStatus::Tracking) };
        assert!(!r.update(&good, &Pose2::new(f64::NAN, 0.0, 0.0)));
        assert!(r.path().is_none());
    }
}
