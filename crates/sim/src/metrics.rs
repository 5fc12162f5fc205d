//! Ground-truth metrics: the paper's Table I detection errors, cross-track error to the lane centre
//! line, and crop damage. They compare what the robot believes (detections in `base_link`) with the
//! field's truth at the robot's TRUE pose.
//!
//! # Detection error (Table I)
//! For a predicted row `[x1, y1, x2, y2]` in `base_link` at the scan stamp and the true pose of the
//! robot at that stamp:
//! - the **true row** is the first row centre curve on that side: the row whose centre curve crosses the
//!   `base_link` y axis (x = 0) at the smallest positive offset (left) or the largest negative one (right);
//! - the **distance error** is `|y_pred(0) − y_true(0)|`: the lateral gap, along the `base_link` y axis,
//!   between the predicted row at x = 0 (`RowEstimate::offset_m`; the line extended to x = 0 when that is
//!   not finite) and the true curve's crossing of that axis;
//! - the **angular error** is `|wrap(θ_pred − θ_true)|`, with `θ_pred` the predicted row's direction at the
//!   robot (`RowEstimate::heading_rad`, else `atan2(y2 − y1, x2 − x1)`) and `θ_true` the direction of the
//!   true curve at its crossing, in `base_link`;
//! - the prediction **picked the wrong row** when its `y_pred(0)` lies closer to another true row than to the
//!   true one (more than half a row spacing off).
//!
//! Errors are summarised as mean absolute error ± standard deviation ([`ErrorStats`]), as in the paper.

use croprow_core::{Detection, Pose2, RowEstimate};

use crate::field::Field;
use crate::robot::RobotConfig;

/// Error of one predicted row against the truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowError {
    /// The true row it was compared with.
    pub row: u32,
    /// Lateral distance error at x = 0, m (≥ 0).
    pub distance_m: f64,
    /// Angle between predicted and true row, rad (≥ 0).
    pub angle_rad: f64,
    /// The prediction is nearer another true row than the one it should be.
    pub wrong_row: bool,
}

/// Errors of a detection's left and right rows (absent when the detector gave none or no true row exists
/// on that side).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct DetectionErrors {
    /// First row on the left.
    pub left: Option<RowError>,
    /// First row on the right.
    pub right: Option<RowError>,
}

/// A true row as seen from the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrueRow {
    /// Row index.
    pub row: u32,
    /// Where its centre curve crosses the `base_link` y axis, m (left positive).
    pub offset_m: f64,
    /// Its direction there, relative to the robot's x axis, rad.
    pub heading_rad: f64,
}

/// The first true rows `(left, right)` of a robot at `pose`.
pub fn neighbour_rows(field: &Field, pose: &Pose2) -> (Option<TrueRow>, Option<TrueRow>) {
    let (mut left, mut right): (Option<TrueRow>, Option<TrueRow>) = (None, None);
    for row in 0..field.config().rows {
        let Some((offset_m, heading_rad)) = field.row_in_base(row, pose) else { continue };
        let t = TrueRow { row, offset_m, heading_rad };
        if offset_m > 0.0 && left.is_none_or(|l| offset_m < l.offset_m) {
            left = Some(t);
        } else if offset_m <= 0.0 && right.is_none_or(|r| offset_m > r.offset_m) {
            right = Some(t);
        }
    }
    (left, right)
}

/// The predicted row's lateral offset at x = 0 and its direction there, both in `base_link`: the
/// estimate's own `offset_m` and `heading_rad` (what the controller uses) when finite, else the line
/// extended to x = 0. For a straight-line estimate both are the same; for a curved one the segment is a
/// chord whose direction differs from the row's direction at the robot by about half the curvature
/// times its length, which is not the detector's estimate of that direction.
fn line_at_origin(est: &RowEstimate) -> Option<(f64, f64)> {
    if est.offset_m.is_finite() && est.heading_rad.is_finite() {
        return Some((est.offset_m, est.heading_rad));
    }
    let [x1, y1, x2, y2] = est.line;
    if !est.line.iter().all(|v| v.is_finite()) {
        return None;
    }
    let (dx, dy) = (x2 - x1, y2 - y1);
    if dx.abs() < 1e-9 {
        // A degenerate or sideways segment has no offset at x = 0.
        return None;
    }
    Some((y1 - x1 * dy / dx, dy.atan2(dx)))
}

/// The error of `est` against true row `row` for a robot at `pose` (see the module docs).
pub fn row_error(field: &Field, pose: &Pose2, row: u32, est: &RowEstimate) -> Option<RowError> {
    let (off, hd) = field.row_in_base(row, pose)?;
    let (y0, th) = line_at_origin(est)?;
    let distance_m = (y0 - off).abs();
    let angle_rad = croprow_core::geometry::wrap_angle(th - hd).abs();
    let wrong_row = (0..field.config().rows)
        .filter(|&r| r != row)
        .filter_map(|r| field.row_in_base(r, pose))
        .any(|(o, _)| (y0 - o).abs() < distance_m);
    Some(RowError { row, distance_m, angle_rad, wrong_row })
}

/// Scores both rows of a detection against the true neighbours of the robot at its true `pose`.
pub fn score_detection(field: &Field, pose: &Pose2, detection: &Detection) -> DetectionErrors {
    let (l, r) = neighbour_rows(field, pose);
    DetectionErrors {
        left: l.zip(detection.left.as_ref()).and_then(|(t, e)| row_error(field, pose, t.row, e)),
        right: r.zip(detection.right.as_ref()).and_then(|(t, e)| row_error(field, pose, t.row, e)),
    }
}

/// Where the robot is relative to the centre line of a lane.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CrossTrack {
    /// Signed perpendicular distance from the lane centre line to `base_link`, m; positive left of the line.
    pub lateral_m: f64,
    /// Robot heading minus the line's direction at the closest point, rad.
    pub heading_rad: f64,
}

/// Cross-track error of a robot at `pose` to the centre line of `lane` (between rows `lane`, `lane + 1`).
pub fn cross_track(field: &Field, lane: u32, pose: &Pose2) -> Option<CrossTrack> {
    if !pose.is_finite() {
        return None;
    }
    // Closest point on y = c(x) by Gauss-Newton on x; the curve is gentle (slope ≤ 1), five steps suffice.
    let mut x = pose.x;
    for _ in 0..5 {
        let slope = field.row_heading(x).tan();
        let c = field.lane_y(lane, x);
        x += ((pose.x - x) + slope * (pose.y - c)) / (1.0 + slope * slope);
    }
    let th = field.row_heading(x);
    let (s, c) = th.sin_cos();
    let (dx, dy) = (pose.x - x, pose.y - field.lane_y(lane, x));
    Some(CrossTrack {
        lateral_m: -s * dx + c * dy,
        heading_rad: croprow_core::geometry::wrap_angle(pose.yaw - th),
    })
}

/// Mean absolute error and standard deviation of a stream of errors (the paper's "MAE ± std").
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ErrorStats {
    count: usize,
    sum_abs: f64,
    sum_sq: f64,
    max_abs: f64,
}

impl ErrorStats {
    /// Adds one error; non-finite values are ignored.
    pub fn add(&mut self, e: f64) {
        if e.is_finite() {
            let a = e.abs();
            self.count += 1;
            self.sum_abs += a;
            self.sum_sq += a * a;
            self.max_abs = self.max_abs.max(a);
        }
    }

    /// Number of errors added.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Mean absolute error (0 when empty).
    pub fn mae(&self) -> f64 {
        if self.count == 0 { 0.0 } else { self.sum_abs / self.count as f64 }
    }

    /// Standard deviation of the absolute error (population; 0 when empty).
    pub fn std(&self) -> f64 {
        if self.count == 0 {
            return 0.0;
        }
        let m = self.mae();
        (self.sum_sq / self.count as f64 - m * m).max(0.0).sqrt()
    }

    /// Largest absolute error.
    pub fn max(&self) -> f64 {
        self.max_abs
    }
}

/// Counts plants run over: a plant counts once, the first time its stem lies inside any wheel's
/// contact patch (`tire_width_m × contact_length_m`, lengthened by the distance driven since the last
/// update so that no stem slips between two updates). It also keeps the least clearance between a
/// tyre's side and a stem beside it: how near the run came to a contact, a margin that moves
/// smoothly where the count of plants run over jumps from 0 to 1.
#[derive(Debug, Clone)]
pub struct CropDamage {
    hit: Vec<bool>,
    /// Least lateral distance from a tyre's side to a stem alongside its contact patch, m (negative:
    /// inside it). Infinite until a stem has passed alongside a tyre.
    least_clearance_m: f64,
    /// Index of each row's first stem in `Field::stems`.
    row_offsets: Vec<usize>,
    count: usize,
    last: Option<Pose2>,
}

impl CropDamage {
    /// A counter for `field` with no contact yet.
    pub fn new(field: &Field) -> Self {
        let mut offset = 0;
        let row_offsets = (0..field.config().rows)
            .map(|r| {
                let o = offset;
                offset += field.row_stems(r).len();
                o
            })
            .collect();
        Self {
            hit: vec![false; field.stems().len()],
            least_clearance_m: f64::INFINITY,
            row_offsets,
            count: 0,
            last: None,
        }
    }

    /// The least lateral distance from the side of a tyre to a stem alongside its contact patch over
    /// the run so far, m, measured across the robot (negative: the stem was inside the patch, a contact).
    /// `None` until a stem within a row of a tyre has passed alongside it.
    pub fn least_clearance_m(&self) -> Option<f64> {
        self.least_clearance_m.is_finite().then_some(self.least_clearance_m)
    }

    /// Plants contacted so far.
    pub fn count(&self) -> usize {
        self.count
    }

    /// Records the wheels of a robot of shape `robot` at its true `pose`; returns the new contacts.
    pub fn update(&mut self, field: &Field, robot: &RobotConfig, pose: &Pose2) -> usize {
        if !pose.is_finite() {
            return 0;
        }
        let travel = self.last.map_or(0.0, |p| (pose.x - p.x).hypot(pose.y - p.y));
        self.last = Some(*pose);
        let half_len = 0.5 * robot.contact_length_m + travel;
        let half_w = 0.5 * robot.tire_width_m;
        let reach = half_len.hypot(half_w) + 0.05;
        let spacing = field.config().row_spacing_m;
        let rows = field.config().rows as i64;
        let mut new = 0;
        for (wx, wy) in robot.wheel_positions() {
            let (cx, cy) = pose.transform_point(wx, wy);
            let k = ((cy - field.row_y(0, cx)) / spacing).round() as i64;
            for r in (k - 1).max(0)..=(k + 1).min(rows - 1) {
                let stems = field.row_stems(r as u32);
                let first = stems.partition_point(|s| s.x_m < cx - reach);
                for (i, s) in stems.iter().enumerate().skip(first) {
                    if s.x_m > cx + reach {
                        break;
                    }
                    let (bx, by) = pose.inverse_transform_point(s.x_m, s.y_m);
                    if (bx - wx).abs() > half_len {
                        continue;
                    }
                    self.least_clearance_m = self.least_clearance_m.min((by - wy).abs() - half_w);
                    if (by - wy).abs() <= half_w {
                        let id = self.row_offsets.get(r as usize).map_or(usize::MAX, |o| o + i);
                        if let Some(h) = self.hit.get_mut(id)
                            && !*h
                        {
                            *h = true;
                            new += 1;
                        }
                    }
                }
            }
        }
        self.count += new;
        new
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::FieldConfig;
    use croprow_core::{RowStatus, Twist2};

    fn straight() -> Field {
        Field::generate(&FieldConfig { length_m: 20.0, ..FieldConfig::default() }, 1).unwrap()
    }

    fn est(line: [f64; 4]) -> RowEstimate {
        RowEstimate { line, offset_m: f64::NAN, heading_rad: f64::NAN, curvature_per_m: 0.0, confidence: 1.0 }
    }

    #[test]
    fn known_geometry_gives_known_errors() {
        let f = straight();
        // Robot in lane 7 (rows 7 and 8 at y = 5.25 and 6.0), 2 cm left of centre, heading +x.
        let pose = Pose2::new(5.0, 5.625 + 0.02, 0.0);
        // Predicted left row exactly 0.355 m left and parallel: perfect.
        let e = row_error(&f, &pose, 8, &est([0.0, 0.355, 3.0, 0.355])).unwrap();
        assert!(e.distance_m < 1e-9 && e.angle_rad < 1e-12 && !e.wrong_row);
        // Predicted 5 cm too far left and turned by 2°: 5 cm and 2° at x = 0.
        let a = 2f64.to_radians();
        let e = row_error(&f, &pose, 8, &est([-1.0, 0.405 - a.tan(), 3.0, 0.405 + 3.0 * a.tan()])).unwrap();
        assert!((e.distance_m - 0.05).abs() < 1e-9, "{e:?}");
        assert!((e.angle_rad - a).abs() < 1e-9);
        // A prediction on row 9 (0.75 m further) is the wrong row.
        let e = row_error(&f, &pose, 8, &est([0.0, 1.105, 3.0, 1.105])).unwrap();
        assert!(e.wrong_row);
    }

    #[test]
    fn a_curved_estimate_is_scored_by_its_direction_at_the_robot() {
        let f = straight();
        let pose = Pose2::new(5.0, 5.625, 0.0);
        // Right at the robot and parallel to the row, bending away further on: the chord to x = 4 turns by
        // atan(0.16 / 4) = 2.3°, but the row's direction at the robot is exact (tolerance 1e-12: arithmetic).
        let curved = RowEstimate {
            line: [0.0, 0.375, 4.0, 0.375 + 0.16],
            offset_m: 0.375,
            heading_rad: 0.0,
            curvature_per_m: 0.02,
            confidence: 1.0,
        };
        let e = row_error(&f, &pose, 8, &curved).unwrap();
        assert!(e.distance_m < 1e-12 && e.angle_rad < 1e-12, "{e:?}");
    }

    #[test]
    fn detections_are_scored_against_the_neighbour_rows() {
        let f = straight();
        let pose = Pose2::new(5.0, 5.625, 0.1);
        let (l, r) = neighbour_rows(&f, &pose);
        assert_eq!((l.unwrap().row, r.unwrap().row), (8, 7));
        let d = Detection {
            left: Some(est([0.0, 0.375 / 0.1f64.cos(), 1.0, 0.375 / 0.1f64.cos() - 0.1f64.tan()])),
            ..Detection::empty(0.0, RowStatus::Tracking)
        };
        let s = score_detection(&f, &pose, &d);
        let left = s.left.unwrap();
        assert!(left.distance_m < 1e-9 && left.angle_rad < 1e-9, "{left:?}");
        assert!(s.right.is_none());
    }

    #[test]
    fn cross_track_is_signed_and_perpendicular() {
        let f = straight();
        let ct = cross_track(&f, 7, &Pose2::new(3.0, 5.625 - 0.1, 0.05)).unwrap();
        assert!((ct.lateral_m + 0.1).abs() < 1e-9 && (ct.heading_rad - 0.05).abs() < 1e-12);
        let c = Field::generate(
            &FieldConfig { length_m: 20.0, curve_amplitude_m: 6.0, ..FieldConfig::default() },
            1,
        )
        .unwrap();
        // 0.1 m along the normal of the curved centre line at x = 10.
        let th = c.row_heading(10.0);
        let p = Pose2::new(10.0 - 0.1 * th.sin(), c.lane_y(7, 10.0) + 0.1 * th.cos(), th);
        let ct = cross_track(&c, 7, &p).unwrap();
        assert!((ct.lateral_m - 0.1).abs() < 1e-6 && ct.heading_rad.abs() < 1e-4, "{ct:?}");
    }

    #[test]
    fn stats_give_mae_and_std() {
        let mut s = ErrorStats::default();
        for e in [1.0, -3.0, f64::NAN] {
            s.add(e);
        }
        assert_eq!(s.count(), 2);
        assert!((s.mae() - 2.0).abs() < 1e-12 && (s.std() - 1.0).abs() < 1e-12 && s.max() == 3.0);
    }

    fn drive_damage(f: &Field, y: f64) -> usize {
        let rc = RobotConfig::default();
        let mut d = CropDamage::new(f);
        let mut x = 1.0;
        while x < 15.0 {
            d.update(f, &rc, &Pose2::new(x, y, 0.0));
            x += Twist2::new(1.0, 0.0).v * 0.01;
        }
        d.count()
    }

    #[test]
    fn driving_centred_in_a_lane_damages_nothing() {
        assert_eq!(drive_damage(&straight(), 5.625), 0);
    }

    /// The least clearance a drive at `y` (heading +x, x from 1 to 15) must report lies between the
    /// least over the stems every wheel surely passed (x 1.5-14.5) and over any it may have (0.2-15.8).
    fn clearance_bounds(f: &Field, y: f64) -> (f64, f64) {
        let least = |from: f64, to: f64| {
            f.stems()
                .iter()
                .filter(|s| s.x_m > from && s.x_m < to)
                .flat_map(|s| [(s.y_m - (y + 0.762)).abs(), (s.y_m - (y - 0.762)).abs()])
                .filter(|d| *d < 0.75)
                .fold(f64::INFINITY, f64::min)
                - 0.075
        };
        (least(0.2, 15.8), least(1.5, 14.5))
    }

    fn drive_clearance(f: &Field, y: f64) -> Option<f64> {
        let rc = RobotConfig::default();
        let mut d = CropDamage::new(f);
        assert_eq!(d.least_clearance_m(), None, "no stem has passed yet");
        let mut x = 1.0;
        while x < 15.0 {
            d.update(f, &rc, &Pose2::new(x, y, 0.0));
            x += 0.01;
        }
        d.least_clearance_m()
    }

    #[test]
    fn the_least_stem_clearance_is_the_nearest_stem_to_a_tyre_side_and_negative_on_a_contact() {
        let f = straight();
        // Centred in lane 7: every tyre runs 0.36-0.39 m from the rows beside it, 0.29-0.31 m from
        // its side, less the stems' scatter. 0.2 m to the left: the left tyres pass row 9 at about 0.09.
        // On row 9: a contact, so the clearance is negative.
        for (y, around) in [(5.625, 0.29), (5.825, 0.09), (6.75 - 0.762, -0.075)] {
            let c = drive_clearance(&f, y).expect("stems passed alongside");
            let (low, high) = clearance_bounds(&f, y);
            assert!(low - 1e-9 <= c && c <= high + 1e-9, "y {y}: {c} outside [{low}, {high}]");
            assert!((c - around).abs() < 0.04, "y {y}: {c} not near {around}");
        }
    }

    #[test]
    fn a_wheel_on_a_row_counts_each_plant_once() {
        let f = straight();
        // Left wheels (y + 0.762) right on row 9 (y = 6.75); the right wheels (y - 0.762) then run
        // 2.4 cm beside row 7 and touch it too.
        let y = 6.75 - 0.762;
        let n = drive_damage(&f, y);
        // Front and rear wheels pass the same plants: each counts once. The front wheels reach
        // x = 15.61 + 0.06, the rear ones start at 0.39 - 0.06; a stem counts when within 7.5 cm laterally.
        let expected = f
            .stems()
            .iter()
            .filter(|s| s.x_m > 0.33 && s.x_m < 15.67)
            .filter(|s| (s.y_m - (y + 0.762)).abs() <= 0.075 || (s.y_m - (y - 0.762)).abs() <= 0.075)
            .count();
        // Stems right at the patch ends may or may not be reached by the discrete steps: ±2.
        assert!(n.abs_diff(expected) <= 2, "{n} vs {expected}");
        assert!(n > 50);
    }
}
