//! Headland geometry measured on the way out of a lane: where each crop row really ends, and where
//! the two pivots of a headland turn must stand so that the swept tyre patches miss those ends.
//!
//! Where it sits: inside [`crate::control::lane_switch`]. While the robot follows a lane, every
//! scan's row centroids (the detector's map, `odom`) are sorted into rows about the followed centre
//! line; [`RowEnds`] keeps the farthest one of each row. At the row end, [`plan_pivots`] places the
//! first pivot on the lane's centre line and the second on the next lane's, each as far past its
//! rows' measured ends as the tyres' reach needs, so a skewed or ragged headland edge (rows ending
//! at different places) is handled row by row rather than assumed square.
//!
//! ```
//! use croprow_core::control::headland::{Clearance, Footprint, plan_pivots};
//! let tyres = Footprint { wheel_x_m: 0.6095, wheel_y_m: 0.762, tire_length_m: 0.12, tire_width_m: 0.15 };
//! let budget = Clearance { margin_m: 0.05, allowance_m: 0.1, drift_fraction: 0.05, view_m: 1.6 };
//! // Rows 0.75 m apart, every row ending on the line x = 0 except the left row of the lane, 0.2 m longer.
//! let end = |q: i32| if q == 0 { 0.2 } else { 0.0 };
//! let plan = plan_pivots(&tyres, &budget, 0.75, -1.5, end);
//! assert!(plan.first_m > plan.second_m); // the longer row is next to the first pivot
//! ```

use crate::geometry::Pose2;

/// Rows kept either side of the lane: `q` in `-ROW_SLOTS/2 .. ROW_SLOTS/2` (the detector tracks four
/// each side; a two-lane skip reaches the fifth).
const ROW_SLOTS: usize = 12;
const Q_MIN: i32 = -(ROW_SLOTS as i32) / 2;
/// A centroid belongs to a row when it lies within this fraction of the spacing of the row line
/// (the detector's own gate).
const ROW_GATE: f64 = 0.3;
/// Largest skew of a fitted end line (along-row metres per lateral metre) believed when the ends of
/// unmeasured rows are extrapolated: 0.3 is 17°, far beyond any planted headland.
const MAX_END_SLOPE: f64 = 0.3;

/// The tyre contact patches of a skid-steer, `base_link` frame: the parts that crush plants.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Footprint {
    /// Distance of the wheel contact points ahead of and behind `base_link`, m.
    pub wheel_x_m: f64,
    /// Distance of the wheel contact points to the side of `base_link`, m.
    pub wheel_y_m: f64,
    /// Length of a tyre's contact patch, m.
    pub tire_length_m: f64,
    /// Width of a tyre's contact patch, m.
    pub tire_width_m: f64,
}

impl Footprint {
    /// Radius of the circle the farthest patch corner sweeps when the robot turns on the spot, m.
    pub fn pivot_reach_m(&self) -> f64 {
        (self.wheel_x_m + 0.5 * self.tire_length_m).hypot(self.wheel_y_m + 0.5 * self.tire_width_m)
    }

    /// How far the patches reach backwards along the rows while the robot drives across them at
    /// `angle_rad` from square (0: heading straight across the rows), m.
    pub fn side_reach_m(&self, angle_rad: f64) -> f64 {
        let (s, c) = angle_rad.abs().min(std::f64::consts::FRAC_PI_2).sin_cos();
        (self.wheel_y_m + 0.5 * self.tire_width_m) * c + (self.wheel_x_m + 0.5 * self.tire_length_m) * s
    }
}

/// What the pivots keep between the swept tyres and the plants, m or fractions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clearance {
    /// Fixed distance along the rows between the swept patches and the nearest plant, m.
    pub margin_m: f64,
    /// Distance a row's last stem may stand past its farthest centroid, m (a centroid is the mean of a
    /// map bin: the last plants' canopy centre, not their last stem).
    pub allowance_m: f64,
    /// Odometry error per metre driven without seeing the plants (wheel slip, gyro drift): the row ends
    /// are carried by odometry from where they were last seen to each pivot.
    pub drift_fraction: f64,
    /// Distance ahead of `base_link` at which the last plants leave the scan, m: the blind drive to the
    /// first pivot starts there.
    pub view_m: f64,
}

/// Where the two pivots of a headland turn stand, along the rows past the row-end line, m.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PivotPlan {
    /// First pivot, on the centre line of the lane being left.
    pub first_m: f64,
    /// Second pivot, on the centre line of the next lane.
    pub second_m: f64,
}

impl PivotPlan {
    /// The farther of the two pivots: how far `base_link` goes into the headland, m.
    pub fn excursion_m(&self) -> f64 {
        self.first_m.max(self.second_m)
    }
}

/// Places the two pivots of a turn that shifts `shift_m` to the side (positive left; rows at
/// `(q + ½)·spacing_m` from the lane's centre line, `q` = 0 the lane's left row), given where each
/// row ends along the rows past the row-end line (`row_end_m(q)`, m; 0 for a square headland).
///
/// Each pivot stands where the circle swept by the tyres ([`Footprint::pivot_reach_m`]) misses every
/// row by `margin + drift` along the row: with the first pivot on the lane's centre line, the second
/// on the next lane's, possibly off it sideways by the drift over the shift. The straight between them
/// then keeps its patches ([`Footprint::side_reach_m`]) past the rows it crosses by the same margin;
/// where it would not, both pivots move out.
pub fn plan_pivots(
    tyres: &Footprint,
    budget: &Clearance,
    spacing_m: f64,
    shift_m: f64,
    row_end_m: impl Fn(i32) -> f64,
) -> PivotPlan {
    let reach = tyres.pivot_reach_m();
    let drift_1 = budget.drift_fraction * (budget.view_m + reach);
    let drift_2 = drift_1 + budget.drift_fraction * shift_m.abs();
    let lateral_2 = budget.drift_fraction * shift_m.abs();
    // Rows within the reach of either pivot (and every row crossed in between).
    let lo = ((shift_m.min(0.0) - reach) / spacing_m - 1.5).floor() as i32;
    let hi = ((shift_m.max(0.0) + reach) / spacing_m + 0.5).ceil() as i32;
    let pivot_at = |y: f64, uncertainty: f64, drift: f64| {
        (lo..=hi)
            .filter_map(|q| {
                let dy = ((q as f64 + 0.5) * spacing_m - y).abs() - uncertainty;
                let dy = dy.max(0.0);
                (dy < reach).then(|| row_end_m(q) + budget.allowance_m + (reach * reach - dy * dy).sqrt())
            })
            .fold(f64::NEG_INFINITY, f64::max)
            + budget.margin_m
            + drift
    };
    let mut first_m = pivot_at(0.0, 0.0, drift_1);
    let mut second_m = pivot_at(shift_m, lateral_2, drift_2);
    // The straight between the pivots: at each row it crosses, its patches reach back by the side reach.
    let angle = ((second_m - first_m) / shift_m.abs().max(1e-9)).atan();
    let back = tyres.side_reach_m(angle) + budget.margin_m + drift_2;
    let deficit = (lo..=hi)
        .filter_map(|q| {
            let y = (q as f64 + 0.5) * spacing_m;
            let t = y / shift_m;
            (shift_m.abs() > 1e-9 && (0.0..=1.0).contains(&t)).then(|| {
                let leg_m = first_m + t * (second_m - first_m);
                row_end_m(q) + budget.allowance_m + back - leg_m
            })
        })
        .fold(0.0, f64::max);
    first_m += deficit;
    second_m += deficit;
    PivotPlan { first_m, second_m }
}

/// Counts the rows `q` in `rows` (the rows `(q + ½)·spacing_m` to the left of the lane's centre line,
/// as in [`RowEnds::observe`]) that hold a point farther than `past_m` along the lane past its row end
/// and none between `clear_m` and `past_m`: crop beyond an empty stretch. `end` is a pose on the
/// centre line at the row end, heading out of the field (`odom`); `points` are in `odom`, m. Crop
/// standing on several rows beyond an empty stretch past a measured row end means the "end" was a gap
/// in the rows, not the headland; one row's worth (a weed on a row line, a stray return) is not
/// enough, and canopy that runs on without a break past the end is not a gap (a tilted sensor reading
/// the ground as crop). Non-finite points and points between rows are skipped; at most 32 rows count.
/// Also returns the nearest such crop, m along past the end (infinite with none): crop that stays
/// where it is while the robot drives on is a place; crop that keeps its distance ahead of the
/// robot is not.
pub fn rows_past_end(
    spacing_m: f64,
    end: &Pose2,
    clear_m: f64,
    past_m: f64,
    rows: std::ops::RangeInclusive<i32>,
    points: impl Iterator<Item = (f64, f64)>,
) -> (u32, f64) {
    if !spacing_m.is_finite() || spacing_m <= 0.0 || !past_m.is_finite() || !clear_m.is_finite() {
        return (0, f64::INFINITY);
    }
    let first = *rows.start();
    let (mut past, mut within) = (0u32, 0u32);
    let mut nearest = [f64::INFINITY; 32];
    for (x, y) in points.filter(|(x, y)| x.is_finite() && y.is_finite()) {
        let (along, lateral) = end.inverse_transform_point(x, y);
        let row = lateral / spacing_m - 0.5;
        let q = row.round();
        if along <= clear_m || (row - q).abs() > ROW_GATE || !rows.contains(&(q as i32)) {
            continue;
        }
        let Some(i) = u32::try_from(q as i64 - i64::from(first)).ok().filter(|i| *i < 32) else {
            continue;
        };
        let bit = 1u32 << i;
        if along > past_m {
            past |= bit;
            if let Some(n) = nearest.get_mut(i as usize) {
                *n = n.min(along);
            }
        } else {
            within |= bit;
        }
    }
    let counted = past & !within;
    let near = (0..32)
        .filter(|i| counted & (1 << i) != 0)
        .filter_map(|i| nearest.get(i))
        .fold(f64::INFINITY, |a, &b| a.min(b));
    (counted.count_ones(), near)
}

/// The farthest row centroid seen on each row about a lane's centre line, in `odom`. A fixed array:
/// nothing is allocated after construction.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct RowEnds {
    ends: [Option<(f64, f64)>; ROW_SLOTS],
}

impl RowEnds {
    /// Forgets every row (a new lane).
    pub fn clear(&mut self) {
        self.ends = [None; ROW_SLOTS];
    }

    /// True when no row end has been seen.
    pub fn is_empty(&self) -> bool {
        self.ends.iter().all(Option::is_none)
    }

    /// Sorts `points` (`odom`, m) into the rows `(q + ½)·spacing_m` to the left of a lane's centre line
    /// and keeps the farthest ahead of each row. `frame` maps an `odom` point to its arc length along
    /// the centre line (positive in the direction of travel) and its lateral offset (positive left), m:
    /// a projection on a curved line sorts the rows of a curved field. Non-finite points and points
    /// between rows are skipped.
    pub fn observe(
        &mut self,
        spacing_m: f64,
        points: impl Iterator<Item = (f64, f64)>,
        frame: impl Fn(f64, f64) -> (f64, f64),
    ) {
        if !spacing_m.is_finite() || spacing_m <= 0.0 {
            return;
        }
        for (x, y) in points.filter(|(x, y)| x.is_finite() && y.is_finite()) {
            let (along, lateral) = frame(x, y);
            let row = lateral / spacing_m - 0.5;
            let q = row.round();
            if !along.is_finite() || !(row - q).abs().le(&ROW_GATE) {
                continue;
            }
            let Some(slot) =
                usize::try_from(q as i64 - i64::from(Q_MIN)).ok().and_then(|i| self.ends.get_mut(i))
            else {
                continue;
            };
            if slot.is_none_or(|(ox, oy)| frame(ox, oy).0 < along) {
                *slot = Some((x, y));
            }
        }
    }

    /// Along-row distance past `end` (a pose on the lane's centre line at the row end, heading out of
    /// the field, `odom`) of the farthest centroid of row `q`, m, when one was seen.
    pub fn end_m(&self, q: i32, end: &Pose2) -> Option<f64> {
        let i = usize::try_from(q - Q_MIN).ok()?;
        let (x, y) = (*self.ends.get(i)?)?;
        Some(end.inverse_transform_point(x, y).0)
    }

    /// The end of every row `q` past `end`, m: the measured one, or for a row not seen, the line
    /// through the measured ends (least squares over the rows, slope bounded, at least three rows)
    /// or, with fewer, the farthest measured end; with none, 0 (a square headland at `end`).
    /// A measured row never counts as shorter than its own centroids.
    pub fn end_or_fit_m(&self, q: i32, end: &Pose2, spacing_m: f64) -> f64 {
        if let Some(m) = self.end_m(q, end) {
            return m;
        }
        let (mut n, mut sy, mut sx, mut syy, mut sxy, mut far) = (0.0, 0.0, 0.0, 0.0, 0.0, f64::NEG_INFINITY);
        for k in Q_MIN..Q_MIN + ROW_SLOTS as i32 {
            if let Some(x) = self.end_m(k, end) {
                let y = (k as f64 + 0.5) * spacing_m;
                n += 1.0;
                sy += y;
                sx += x;
                syy += y * y;
                sxy += x * y;
                far = far.max(x);
            }
        }
        if n == 0.0 {
            return 0.0;
        }
        let den = n * syy - sy * sy;
        if n < 3.0 || den.abs() < 1e-12 {
            return far;
        }
        let slope = ((n * sxy - sx * sy) / den).clamp(-MAX_END_SLOPE, MAX_END_SLOPE);
        let mean_y = sy / n;
        sx / n + slope * ((q as f64 + 0.5) * spacing_m - mean_y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TYRES: Footprint =
        Footprint { wheel_x_m: 0.6095, wheel_y_m: 0.762, tire_length_m: 0.12, tire_width_m: 0.15 };
    const NONE: Clearance = Clearance { margin_m: 0.0, allowance_m: 0.0, drift_fraction: 0.0, view_m: 0.0 };

    /// Distance from a pivot at `(px, py)` to the row `y = row_y`, `x <= end_x` (a ray), m.
    fn to_row(px: f64, py: f64, end_x: f64, row_y: f64) -> f64 {
        if px >= end_x { (px - end_x).hypot(py - row_y) } else { (py - row_y).abs() }
    }

    #[test]
    fn a_square_headland_pivots_where_the_reach_just_misses_the_lane_rows() {
        let plan = plan_pivots(&TYRES, &NONE, 0.75, 1.5, |_| 0.0);
        // √(ρ² − 0.375²) with ρ = √(0.6695² + 0.837²) (arithmetic: 1e-12).
        let reach = 0.6695f64.hypot(0.837);
        let expected = (reach * reach - 0.375 * 0.375).sqrt();
        assert!((plan.first_m - expected).abs() < 1e-12, "{plan:?}");
        assert!((plan.second_m - expected).abs() < 1e-12, "{plan:?}");
    }

    #[test]
    fn every_row_end_is_outside_the_swept_circle_of_both_pivots() {
        // A ragged, skewed edge: rows end between -0.3 and +0.4 m; the turn goes 1.4 m right.
        let ends = |q: i32| 0.1 * f64::from(q) + if q % 2 == 0 { 0.15 } else { -0.05 };
        let plan = plan_pivots(&TYRES, &NONE, 0.7, -1.4, ends);
        let reach = TYRES.pivot_reach_m();
        for q in -6..5 {
            let y = (f64::from(q) + 0.5) * 0.7;
            let d1 = to_row(plan.first_m, 0.0, ends(q), y);
            let d2 = to_row(plan.second_m, -1.4, ends(q), y);
            assert!(d1 >= reach - 1e-9 && d2 >= reach - 1e-9, "row {q}: {d1:.3} {d2:.3} {plan:?}");
        }
        // The edge recedes to the right (−y): the second pivot stands nearer the crop than the first.
        assert!(plan.second_m < plan.first_m, "{plan:?}");
    }

    #[test]
    fn margins_drift_and_allowance_add_along_the_rows() {
        let budget = Clearance { margin_m: 0.05, allowance_m: 0.1, drift_fraction: 0.05, view_m: 1.6 };
        let bare = plan_pivots(&TYRES, &NONE, 0.75, 1.5, |_| 0.0);
        let plan = plan_pivots(&TYRES, &budget, 0.75, 1.5, |_| 0.0);
        let drift_1 = 0.05 * (1.6 + TYRES.pivot_reach_m());
        assert!((plan.first_m - bare.first_m - (0.05 + 0.1 + drift_1)).abs() < 1e-12, "{plan:?}");
        // The second pivot also drifts over the 1.5 m shift, along and across the rows.
        assert!(plan.second_m > plan.first_m + 0.05 * 1.5, "{plan:?}");
    }

    #[test]
    fn a_row_sticking_out_between_the_pivots_pushes_both_out() {
        // Shift 3 m: the row at q = 2 (1.5 m over, out of both pivots' reach) ends 0.6 m out.
        let ends = |q: i32| if q == 2 { 0.6 } else { 0.0 };
        let bare = plan_pivots(&TYRES, &NONE, 0.6, 3.0, |_| 0.0);
        let plan = plan_pivots(&TYRES, &NONE, 0.6, 3.0, ends);
        assert!(plan.first_m > bare.first_m + 0.3 && plan.second_m > bare.second_m + 0.3, "{plan:?}");
        let angle = ((plan.second_m - plan.first_m) / 3.0).atan();
        let y = 2.5 * 0.6;
        let leg = plan.first_m + y / 3.0 * (plan.second_m - plan.first_m);
        assert!(leg >= 0.6 + TYRES.side_reach_m(angle) - 1e-9, "{plan:?} leg {leg}");
    }

    #[test]
    fn row_ends_keep_the_farthest_centroid_of_each_row() {
        let mut ends = RowEnds::default();
        let frame = |x: f64, y: f64| (x, y);
        let first = [(3.0, 0.37), (4.2, 0.39), (3.9, -0.36), (4.0, 0.75), (f64::NAN, 0.0)];
        ends.observe(0.75, first.into_iter(), frame);
        ends.observe(0.75, [(4.1, 0.36), (4.6, 1.13)].into_iter(), frame);
        let end = Pose2::new(4.0, 0.0, 0.0);
        assert!((ends.end_m(0, &end).unwrap() - 0.2).abs() < 1e-12);
        assert!((ends.end_m(-1, &end).unwrap() + 0.1).abs() < 1e-12);
        assert!((ends.end_m(1, &end).unwrap() - 0.6).abs() < 1e-12);
        // 4.0, 0.75 lies between rows 0 and 1: skipped.
        assert_eq!(ends.end_m(2, &end), None);
        ends.clear();
        assert!(ends.is_empty());
    }

    #[test]
    fn unseen_rows_follow_the_line_through_the_measured_ends() {
        let mut ends = RowEnds::default();
        // A headland edge skewed by 0.1 m per metre across the rows, rows 0.5 m apart.
        let points = (-2..2).map(|q| (0.1 * (f64::from(q) + 0.5) * 0.5, (f64::from(q) + 0.5) * 0.5));
        let centre = Pose2::new(-5.0, 0.0, 0.0);
        ends.observe(0.5, points, |x, y| centre.inverse_transform_point(x, y));
        let end = Pose2::default();
        let q3 = ends.end_or_fit_m(3, &end, 0.5);
        assert!((q3 - 0.1 * 3.5 * 0.5).abs() < 1e-9, "{q3}");
        assert!((ends.end_or_fit_m(0, &end, 0.5) - 0.025).abs() < 1e-12);
        assert_eq!(RowEnds::default().end_or_fit_m(2, &end, 0.5), 0.0);
    }

    #[test]
    fn rows_past_an_end_count_crop_beyond_an_empty_stretch_once_per_row() {
        // The end at x = 4 heading +x; rows 0.75 m apart at ±0.375, ±1.125.
        let end = Pose2::new(4.0, 0.0, 0.0);
        let points =
            [(5.0, 0.37), (5.5, 0.38), (5.0, -0.4), (4.4, 1.12), (5.0, 0.75), (f64::NAN, 0.37), (6.0, 3.0)];
        // Row 0 twice (counted once), row -1; row 1 is not past 0.5 m; 0.75 is between rows; 3.0 is
        // outside the rows counted.
        assert_eq!(rows_past_end(0.75, &end, 0.25, 0.5, -2..=1, points.into_iter()), (2, 1.0));
        assert_eq!(rows_past_end(0.75, &end, 0.25, 0.5, 0..=0, points.into_iter()).0, 1);
        // Row 1's point at 0.4 m: with the empty stretch starting at 0.1 m and crop counted past
        // 0.3 m, it counts; with crop counted past 0.45 m, that point lies in the stretch.
        let (rows, near) = rows_past_end(0.75, &end, 0.1, 0.3, -2..=1, points.into_iter());
        assert!(rows == 3 && (near - 0.4).abs() < 1e-12, "{rows} {near}");
        let on_row_1 = points.into_iter().chain([(6.0, 1.125)]);
        assert_eq!(rows_past_end(0.75, &end, 0.1, 0.45, -2..=1, on_row_1).0, 2);
        // Canopy running on without a break past the end is no gap.
        let running_on = (0..40).map(|k| (4.0 + 0.05 * f64::from(k), 0.375));
        assert_eq!(rows_past_end(0.75, &end, 0.25, 0.75, -2..=1, running_on).0, 0);
        // Behind the end, or with an absurd spacing, nothing counts.
        let reversed = Pose2::new(4.0, 0.0, std::f64::consts::PI);
        assert_eq!(rows_past_end(0.75, &reversed, 0.25, 0.5, -2..=1, points.into_iter()).0, 0);
        assert_eq!(rows_past_end(f64::NAN, &end, 0.25, 0.5, -2..=1, points.into_iter()).0, 0);
    }
}
