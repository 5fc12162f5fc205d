//! Reference paths in `odom`: chains of straight and circular-arc segments, and the projection of a
//! robot pose onto them (path-frame, or Frenet, coordinates).
//!
//! Both the row centre line (one segment, carried by odometry between scans) and the headland turn
//! (arc, straight, arc, straight) are [`Path`]s, so one MPC tracks both.
//!
//! ```
//! use croprow_core::control::path::Path;
//! use croprow_core::Pose2;
//! let mut path = Path::with_capacity(4);
//! path.push(Pose2::new(0.0, 0.0, 0.0), 5.0, 0.0);
//! let f = path.project(&Pose2::new(1.0, 0.2, 0.1), 0.0);
//! assert!((f.s_m - 1.0).abs() < 1e-12 && (f.lateral_m - 0.2).abs() < 1e-12);
//! ```

use crate::geometry::{Pose2, wrap_angle};

/// Curvatures below this (1/m) are treated as straight lines: a radius over 1 km.
const STRAIGHT_EPS: f64 = 1e-6;

/// One piece of constant curvature, starting at a pose in `odom`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Segment {
    /// Start pose in `odom`; the heading is the path direction.
    pub start: Pose2,
    /// Length along the path, m.
    pub length_m: f64,
    /// Curvature, 1/m, positive turns left.
    pub curvature_per_m: f64,
}

impl Segment {
    /// The path pose at arc length `s` (m) from the start; `s` may be outside `[0, length]`, which
    /// extends the segment with the same curvature.
    pub fn pose_at(&self, s: f64) -> Pose2 {
        let k = self.curvature_per_m;
        let th0 = self.start.yaw;
        if k.abs() < STRAIGHT_EPS {
            let (sn, cs) = th0.sin_cos();
            return Pose2::new(self.start.x + s * cs, self.start.y + s * sn, th0);
        }
        let th = th0 + k * s;
        let x = self.start.x + (th.sin() - th0.sin()) / k;
        let y = self.start.y - (th.cos() - th0.cos()) / k;
        Pose2::new(x, y, wrap_angle(th))
    }

    /// The pose at the end of the segment.
    pub fn end(&self) -> Pose2 {
        self.pose_at(self.length_m)
    }

    /// Local arc length and signed lateral offset (m, positive left of the path) of point `(x, y)`.
    fn project_point(&self, x: f64, y: f64) -> (f64, f64) {
        let k = self.curvature_per_m;
        let th0 = self.start.yaw;
        let (sn, cs) = th0.sin_cos();
        let (dx, dy) = (x - self.start.x, y - self.start.y);
        if k.abs() < STRAIGHT_EPS {
            return (cs * dx + sn * dy, -sn * dx + cs * dy);
        }
        let r = 1.0 / k;
        // Centre of the circle, on the left of the start for a left turn.
        let (cx, cy) = (self.start.x - r * sn, self.start.y + r * cs);
        let (ex, ey) = (x - cx, y - cy);
        let rho = ex.hypot(ey);
        let sign = k.signum();
        // The path point at heading θ sits at centre + r (sin θ, -cos θ).
        let th = (sign * ex).atan2(-sign * ey);
        let s = wrap_angle(th - th0) / k;
        (s, sign * (r.abs() - rho))
    }
}

/// Where a pose sits relative to a path.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Frenet {
    /// Arc length of the closest path point from the path start, m.
    pub s_m: f64,
    /// Signed lateral offset of `base_link` from the path, m, positive left (REP-103).
    pub lateral_m: f64,
    /// Robot heading minus path heading, rad, wrapped to (-π, π].
    pub heading_rad: f64,
    /// Path curvature at the closest point, 1/m.
    pub curvature_per_m: f64,
}

/// A chain of segments in `odom`. Capacity is reserved once; [`Path::clear`] and [`Path::push`]
/// then reuse it, so rebuilding a path every scan allocates nothing.
///
/// A path along a lane's centre line may say so ([`Path::set_row_spacing`]): crop rows then run
/// parallel to it, `(k + ½)·spacing` to either side, and the MPC keeps the tyres between them.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Path {
    segments: Vec<Segment>,
    /// Arc length at the start of each segment, m.
    starts_m: Vec<f64>,
    row_spacing_m: Option<f64>,
}

impl Path {
    /// An empty path with room for `n` segments.
    pub fn with_capacity(n: usize) -> Self {
        Self { segments: Vec::with_capacity(n), starts_m: Vec::with_capacity(n), row_spacing_m: None }
    }

    /// Removes all segments and the row spacing, keeping the capacity.
    pub fn clear(&mut self) {
        self.segments.clear();
        self.starts_m.clear();
        self.row_spacing_m = None;
    }

    /// Declares the path a lane centre line between crop rows `spacing_m` apart (`None`: no rows
    /// along it, e.g. a headland turn). A spacing that is not finite and positive counts as `None`.
    pub fn set_row_spacing(&mut self, spacing_m: Option<f64>) {
        self.row_spacing_m = spacing_m.filter(|s| s.is_finite() && *s > 0.0);
    }

    /// Spacing of the crop rows the path runs between, m, when it is a lane centre line.
    pub fn row_spacing_m(&self) -> Option<f64> {
        self.row_spacing_m
    }

    /// Appends a segment starting at `start`.
    pub fn push(&mut self, start: Pose2, length_m: f64, curvature_per_m: f64) {
        let s0 = self.length_m();
        self.segments.push(Segment { start, length_m, curvature_per_m });
        self.starts_m.push(s0);
    }

    /// Appends a segment that continues from the end of the last one (or from `origin` when empty).
    pub fn extend(&mut self, origin: Pose2, length_m: f64, curvature_per_m: f64) {
        let start = self.segments.last().map_or(origin, Segment::end);
        self.push(start, length_m, curvature_per_m);
    }

    /// Removes the first segment (a leg that is done) and returns its length, m; arc lengths then
    /// count from the new first segment. In place: nothing is allocated.
    pub fn pop_front(&mut self) -> Option<f64> {
        if self.segments.is_empty() {
            return None;
        }
        let done = self.segments.remove(0).length_m;
        self.starts_m.remove(0);
        self.starts_m.iter_mut().for_each(|s0| *s0 -= done);
        Some(done)
    }

    /// The segments, in order.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// True when the path has no segment.
    pub fn is_empty(&self) -> bool {
        self.segments.is_empty()
    }

    /// Total length, m.
    pub fn length_m(&self) -> f64 {
        match (self.segments.last(), self.starts_m.last()) {
            (Some(seg), Some(s0)) => s0 + seg.length_m,
            _ => 0.0,
        }
    }

    fn segment_index(&self, s: f64) -> usize {
        // The last segment whose start is at or before s; before the path, the first one.
        self.starts_m.iter().rposition(|&s0| s0 <= s).unwrap_or(0)
    }

    /// Curvature at arc length `s` (m); beyond the ends, that of the first or last segment.
    pub fn curvature_at(&self, s: f64) -> f64 {
        self.segments.get(self.segment_index(s)).map_or(0.0, |seg| seg.curvature_per_m)
    }

    /// The path pose at arc length `s` (m), extending the end segments beyond the path.
    pub fn pose_at(&self, s: f64) -> Pose2 {
        let i = self.segment_index(s);
        match (self.segments.get(i), self.starts_m.get(i)) {
            (Some(seg), Some(s0)) => seg.pose_at(s - s0),
            _ => Pose2::default(),
        }
    }

    /// Projects `pose` onto the path. `s_hint_m` is the previous progress: only the segment holding
    /// it and the next one are searched, so a turn whose legs pass close to each other never makes
    /// the progress jump backwards or skip a leg. An empty path gives the default [`Frenet`].
    pub fn project(&self, pose: &Pose2, s_hint_m: f64) -> Frenet {
        let first = self.segment_index(s_hint_m);
        let last_index = self.segments.len().saturating_sub(1);
        let mut best: Option<(f64, Frenet)> = None;
        for i in first..=(first + 1).min(last_index) {
            let (Some(seg), Some(&s0)) = (self.segments.get(i), self.starts_m.get(i)) else { break };
            let (s_local, lateral) = seg.project_point(pose.x, pose.y);
            // The ends of the whole path extend; inner segments only count inside their span.
            let lo = if i == 0 { f64::NEG_INFINITY } else { -1e-9 };
            let hi = if i == last_index { f64::INFINITY } else { seg.length_m + 1e-9 };
            let clamped = s_local.clamp(lo, hi);
            let along_gap = (s_local - clamped).abs();
            let score = lateral.abs() + along_gap;
            let path_pose = seg.pose_at(clamped);
            let f = Frenet {
                s_m: s0 + clamped,
                lateral_m: lateral,
                heading_rad: wrap_angle(pose.yaw - path_pose.yaw),
                curvature_per_m: seg.curvature_per_m,
            };
            if best.is_none_or(|(b, _)| score < b) {
                best = Some((score, f));
            }
        }
        best.map_or_else(Frenet::default, |(_, f)| f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    #[test]
    fn arc_end_is_a_quarter_circle() {
        let seg = Segment {
            start: Pose2::new(1.0, 2.0, 0.0),
            length_m: FRAC_PI_2 * 0.6,
            curvature_per_m: 1.0 / 0.6,
        };
        let e = seg.end();
        assert!((e.x - 1.6).abs() < 1e-12 && (e.y - 2.6).abs() < 1e-12 && (e.yaw - FRAC_PI_2).abs() < 1e-12);
    }

    #[test]
    fn projection_on_left_and_right_arcs() {
        for k in [1.0 / 0.6, -1.0 / 0.6] {
            let seg = Segment { start: Pose2::new(0.0, 0.0, 0.3), length_m: 0.9, curvature_per_m: k };
            let on = seg.pose_at(0.5);
            // 5 cm to the left of the path point.
            let (sn, cs) = on.yaw.sin_cos();
            let (s, lat) = seg.project_point(on.x - 0.05 * sn, on.y + 0.05 * cs);
            assert!((s - 0.5).abs() < 1e-9, "k {k}: s {s}");
            assert!((lat - 0.05).abs() < 1e-9, "k {k}: lateral {lat}");
        }
    }

    #[test]
    fn progress_follows_the_hint_through_a_u_turn() {
        let mut p = Path::with_capacity(4);
        let r = 0.6;
        p.extend(Pose2::new(0.0, 0.0, 0.0), FRAC_PI_2 * r, 1.0 / r);
        p.extend(Pose2::default(), 0.3, 0.0);
        p.extend(Pose2::default(), FRAC_PI_2 * r, 1.0 / r);
        p.extend(Pose2::default(), 3.0, 0.0);
        let total = p.length_m();
        let mut s = 0.0;
        for i in 0..=100 {
            let target = total * i as f64 / 100.0;
            let f = p.project(&p.pose_at(target), s);
            assert!((f.s_m - target).abs() < 1e-6, "at {target}: {}", f.s_m);
            assert!(f.lateral_m.abs() < 1e-6 && f.heading_rad.abs() < 1e-6);
            s = f.s_m;
        }
        let end = p.pose_at(total);
        assert!((end.yaw.abs() - std::f64::consts::PI).abs() < 1e-9);
        assert!((end.y - (2.0 * r + 0.3)).abs() < 1e-9 && (end.x - (-3.0)).abs() < 1e-9);
    }

    #[test]
    fn popping_a_done_leg_rebases_the_arc_length() {
        let mut p = Path::with_capacity(3);
        p.push(Pose2::new(0.0, 0.0, 0.0), 2.0, 0.0);
        p.push(Pose2::new(2.0, 0.0, FRAC_PI_2), 1.5, 0.0);
        let corner_to_end = p.pose_at(3.5);
        assert_eq!(p.pop_front(), Some(2.0));
        assert_eq!(p.segments().len(), 1);
        assert!((p.length_m() - 1.5).abs() < 1e-12);
        // The same place on the path, now 1.5 m from its start (arithmetic: 1e-12).
        let e = p.pose_at(1.5);
        assert!((e.x - corner_to_end.x).abs() < 1e-12 && (e.y - corner_to_end.y).abs() < 1e-12);
        assert_eq!(p.pop_front(), Some(1.5));
        assert_eq!(p.pop_front(), None);
        assert!(p.is_empty());
    }
}
