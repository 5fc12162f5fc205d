//! Shared fixture of the control and navigator tests: a synthetic field of straight rows along odom x
//! from x = 0 to x = `length_m`, 0.75 m apart at y = −j·0.75, an ideal detector over it, crop-contact
//! counting for the robot's four wheels, and an ideal unicycle.
#![allow(dead_code)]

use croprow_core::geometry::wrap_angle;
use croprow_core::{Detection, Pose2, RowEstimate, RowStatus, Twist2};

pub const SPACING: f64 = 0.75;
pub const PERIOD_S: f64 = 0.1;
/// A wheel closer than this to a row line, inside the field, touches a plant, m.
pub const PLANT_HALF_WIDTH: f64 = 0.05;
pub const WHEELS: [(f64, f64); 4] = [(0.6095, 0.762), (0.6095, -0.762), (-0.6095, 0.762), (-0.6095, -0.762)];

pub struct Field {
    /// Number of rows.
    pub rows: usize,
    /// Row length, m.
    pub length_m: f64,
    /// Rows missing (as if the detector lost them) between these x, m.
    pub blackout: Option<(f64, f64)>,
}

impl Field {
    pub fn row_y(&self, j: usize) -> f64 {
        -(j as f64) * SPACING
    }

    /// What an ideal detector reports at `pose`: the nearest rows left and right, the row end when it
    /// is within 4 m ahead, nothing when the robot looks away from the field.
    pub fn detect(&self, stamp_s: f64, pose: &Pose2) -> Detection {
        let forward = pose.yaw.cos() >= 0.0;
        let row_dir = if forward { 0.0 } else { std::f64::consts::PI };
        let heading = wrap_angle(row_dir - pose.yaw);
        let ahead_to_end = if forward { self.length_m - pose.x } else { pose.x };
        let behind_start = if forward { pose.x } else { self.length_m - pose.x };
        let in_view = ahead_to_end > -0.5 && behind_start > -4.0;
        if heading.abs() > 0.6 || !in_view || self.blackout.is_some_and(|(a, b)| pose.x > a && pose.x < b) {
            return Detection::empty(stamp_s, RowStatus::Searching);
        }
        let mut left: Option<RowEstimate> = None;
        let mut right: Option<RowEstimate> = None;
        let c = pose.yaw.cos();
        for j in 0..self.rows {
            let t = (self.row_y(j) - pose.y) / c;
            let est = RowEstimate {
                line: [0.0, t, 4.0, t],
                offset_m: t,
                heading_rad: heading,
                curvature_per_m: 0.0,
                confidence: 1.0,
            };
            if t > 0.0 && left.is_none_or(|l| t < l.offset_m) {
                left = Some(est);
            }
            if t < 0.0 && right.is_none_or(|r| t > r.offset_m) {
                right = Some(est);
            }
        }
        let status = if ahead_to_end <= 0.0 { RowStatus::EndOfRow } else { RowStatus::Tracking };
        Detection {
            left,
            right,
            row_spacing_m: Some(SPACING),
            row_end_ahead_m: (ahead_to_end < 4.0).then_some(ahead_to_end),
            ..Detection::empty(stamp_s, status)
        }
    }

    /// Wheels over a plant at `pose`.
    pub fn contacts(&self, pose: &Pose2) -> usize {
        WHEELS
            .iter()
            .filter(|&&(wx, wy)| {
                let (x, y) = pose.transform_point(wx, wy);
                x >= 0.0
                    && x <= self.length_m
                    && (0..self.rows).any(|j| (y - self.row_y(j)).abs() < PLANT_HALF_WIDTH)
            })
            .count()
    }
}

pub fn drive(p: Pose2, cmd: Twist2, dt: f64) -> Pose2 {
    let h = dt / 10.0;
    let mut q = p;
    for _ in 0..10 {
        let mid = q.yaw + 0.5 * cmd.omega * h;
        q = Pose2::new(
            q.x + cmd.v * h * mid.cos(),
            q.y + cmd.v * h * mid.sin(),
            wrap_angle(q.yaw + cmd.omega * h),
        );
    }
    q
}

/// Lane `k` lies between rows 2k and 2k+1.
pub fn lane_start(k: usize) -> Pose2 {
    Pose2::new(0.5, -(2.0 * k as f64 + 0.5) * SPACING, 0.0)
}
