//! The slide test of [`Lanes`](super::Lanes) (opt-in: `DetectorConfig::shear_window_m` > 0): the map's
//! centroids still in view are compared with the newest scan's, row by row, to tell a sideways slide of
//! the robot that odometry did not sense from a turn of `odom` and from weeds; a slide consistent over
//! the window fixes the map's shear. See [`Lanes::observe_slide`].

use super::*;

/// The slide test (see [`Lanes::observe_slide`]) compares the newest scan with map centroids of the same
/// stretch stored at most this long ago, m driven: older ones have moved by more than a gate at the
/// soak's strongest slides (0.16 m/m) and would be gated out one-sidedly.
const SLIDE_MAX_AGE_M: f64 = 0.8;

/// Fewest map centroids and least summed weight of this scan's centroids for one comparison.
const SLIDE_MIN_MAP: usize = 10;
const SLIDE_MIN_FRESH_WEIGHT: f64 = 3.0;

/// Fewest centroids of one row for its own shear in a comparison (three unknowns and some to spare),
/// and the least variance given a row's shear, (m/m)²: a clean synthetic row fits exactly, and one row
/// must not outweigh the rest of its side without bound.
const SLIDE_ROW_MIN_CENTROIDS: usize = 6;
const SLIDE_ROW_MIN_VARIANCE: f64 = 1e-6;

/// Fewest comparisons pooled before the slide test may decide, and the most kept (a window of 0.5 m
/// at 0.5 m/s and 10 Hz holds 10).
const SLIDE_MIN_SAMPLES: usize = 4;

/// Standard errors from none at which the rows' pooled turn (see [`turn_of_rows`]) is taken for a turn
/// of `odom` and removed from their shear.
const SLIDE_TURN_Z: f64 = 4.0;
pub(super) const SLIDE_CAPACITY: usize = 64;

/// Most the robot may have turned over the pooled comparisons for the slide test to declare a slide,
/// rad: while it swings onto a line (after a lane entry, measured on the full-field demo) the scans'
/// motion skew and the map's lag differ between fresh and stored centroids and read as a shear. A
/// slide already declared is kept while the robot turns into it.
const SLIDE_MAX_TURN_RAD: f64 = 0.05;

/// Distance driven in a lane before the slide test starts, m: right after a lane entry the map holds
/// the swing onto the line (measured on the full-field demo: false slides of 0.05-0.3 m/m), and least
/// distance driven between two comparisons, m (a robot standing or pivoting teaches nothing).
const SLIDE_MIN_LANE_M: f64 = 1.0;
const SLIDE_MIN_STEP_M: f64 = 0.02;

/// Per-scan rates at which `Lanes::near_view_m` follows a nearer view (quickly: the rows come into view
/// after a lane entry) and a farther one inside `DetectorConfig::shear_near_gap_m` (slowly).
const NEAR_VIEW_DOWN: f64 = 0.3;
const NEAR_VIEW_UP: f64 = 0.05;

/// Scans in a row whose near view is empty before the slide test stops comparing: one scan that
/// starts late is no gap, and skipping its comparison only reshuffles a chaotic run (without this,
/// soak seeds 287 and 647 touched a plant each and 657 went from 6 plants to 16).
const NEAR_GAP_SCANS: u32 = 3;

impl Lanes {
    /// The slide test: measures the map's shear on the stretch of row this scan sees, and returns the
    /// shear that every comparison over the last `shear_window_m` driven agrees on, if any.
    ///
    /// Map centroids stored up to [`SLIDE_MAX_AGE_M`] of driving ago that lie in this scan's view
    /// (`x >= view_start`) were measured on the same rows as this scan's own centroids; a slide the
    /// odometry did not sense has since moved them sideways by the shear times their age. Their lateral
    /// residuals from `predicted` (less the shear already known), with this scan's centroids at age 0,
    /// are fitted as `c + e·x + Δk·age`: the offset and heading of `predicted` are absorbed by `c` and `e`,
    /// so the shear is measured directly, not through the fitted heading as in [`Lanes::correct`]'s
    /// joint fit, whose prior and deadband make it lag a slide's first metre (issue 6: the soak's slide
    /// seeds ran over plants 1-2 m into the slide). A slide is declared when the comparisons pooled
    /// over the window (inverse-variance weights) span at least half of it, their mean is at least
    /// `shear_test_min_per_m` and each one lies at least half that far on the same side of zero: a sign
    /// test, so that a field without a slide, whose comparisons scatter about zero, never opens it.
    /// A slide is declared only while the robot drives straight ([`SLIDE_MAX_TURN_RAD`] over the
    /// window), and kept while it turns into it; it starts [`SLIDE_MIN_LANE_M`] into a lane and pools
    /// comparisons at least [`SLIDE_MIN_STEP_M`] of driving apart. Each row also fits a turn term
    /// `m·x·age` ([`RowFit`]): a turn of `odom` the odometry did not sense (a gyro bias) is taken out
    /// of the rows' shear ([`turn_of_rows`]) rather than called a slide. A declared slide has an onset,
    /// the odometer where it was declared less the window, and moves a stored centroid by the shear
    /// times the shorter of its age and the distance since the onset ([`Lanes::correct`]): applied to
    /// every age, it shifted the lane by the shear times the map's mean age (8 cm on a false slide of
    /// 0.045 m/m, soak seed 765).
    pub(super) fn observe_slide(
        &mut self,
        predicted: &Lane,
        odom: &Pose2,
        config: &DetectorConfig,
        map: &CentroidMap,
        view_start: f64,
    ) -> Option<f64> {
        if !config.shear_enabled
            || config.shear_window_m <= 0.0
            || self.odometer_m - self.lane_since_m < SLIDE_MIN_LANE_M
        {
            self.slide.clear();
            return None;
        }
        if self.slide.back().is_some_and(|e| self.odometer_m - e[0] < SLIDE_MIN_STEP_M) {
            return self.slide_consensus(config);
        }
        if self.near_view_empty(view_start, config.shear_near_gap_m) {
            // A gap across every row ahead: the crop past it, seen only at the far end of the view
            // and side-on where it begins, reads as a slide (soak seed 869). The comparisons pooled
            // before stay and the window stands still (the distance driven while the near view is
            // empty does not age them), so a declared slide does not lapse in a gap.
            let since = *self.near_gap_since_m.get_or_insert(self.odometer_m);
            for e in &mut self.slide {
                e[0] += self.odometer_m - since;
            }
            self.near_gap_since_m = Some(self.odometer_m);
            return self.slide_consensus(config);
        }
        self.near_gap_since_m = None;
        let gate = config.gate_fraction * predicted.s;
        let known = self.shear_per_m;
        let slid_m = self.slid_m();
        // One fit per row: a slide moves every row alike, a weed clump the centroids of one or two.
        let mut rows = [RowFit::default(); ROWS];
        let mut fresh_w = 0.0;
        let mut add = |x: f64, y: f64, w: f64, age_m: f64| {
            let (j, d) = predicted.assign(x, y - known * age_m.min(slid_m));
            let Some(row) = usize::try_from(j - J_MIN).ok().and_then(|r| rows.get_mut(r)) else {
                return false;
            };
            if d.abs() > gate {
                return false;
            }
            row.add(x, d, w, age_m);
            true
        };
        let x_far = self.current.iter().map(|c| c[0]).fold(f64::NEG_INFINITY, f64::max);
        for &[x, y, w] in &self.current {
            if add(x, y, w, 0.0) {
                fresh_w += w;
            }
        }
        let mut stored = 0usize;
        let (sin, cos) = odom.yaw.sin_cos();
        for p in map.points() {
            let age_m = self.odometer_m - p[3];
            if age_m <= 1e-6 || age_m > SLIDE_MAX_AGE_M {
                continue;
            }
            let (dx, dy) = (p[0] - odom.x, p[1] - odom.y);
            let x = cos * dx + sin * dy;
            if x >= view_start && x <= x_far && add(x, cos * dy - sin * dx, p[2], age_m) {
                stored += 1;
            }
        }
        let floor = self.odometer_m - config.shear_window_m;
        while self.slide.front().is_some_and(|e| e[0] < floor) || self.slide.len() >= SLIDE_CAPACITY {
            self.slide.pop_front();
        }
        if stored >= SLIDE_MIN_MAP
            && fresh_w >= SLIDE_MIN_FRESH_WEIGHT
            && let Some((k, variance)) = slide_consensus_of_rows(&rows, J_MIN)
        {
            let k = known + k;
            if k.is_finite() && variance.is_finite() {
                self.slide.push_back([self.odometer_m, k, 1.0 / variance.max(1e-12), odom.yaw]);
            }
        }
        self.slide_consensus(config)
    }

    /// Whether this scan's nearest centroid (`view_start`, m along x) lies more than `near_gap_m` (> 0)
    /// farther than this lane's usual, for the [`NEAR_GAP_SCANS`]th scan in a row or more; the usual
    /// is updated by the others. A scan without centroids (the rows ended, or a dropout) is no gap:
    /// the window ages as before, so a slide lapses past a row end.
    fn near_view_empty(&mut self, view_start: f64, near_gap_m: f64) -> bool {
        if self.current.is_empty() {
            return false;
        }
        let usual = *self.near_view_m.get_or_insert(view_start);
        let rate = if view_start < usual {
            NEAR_VIEW_DOWN
        } else if near_gap_m <= 0.0 || view_start <= usual + near_gap_m {
            NEAR_VIEW_UP
        } else {
            self.near_gap_scans += 1;
            return self.near_gap_scans >= NEAR_GAP_SCANS;
        };
        self.near_gap_scans = 0;
        self.near_view_m = Some(usual + rate * (view_start - usual));
        false
    }

    /// Longest distance over which the current shear has moved a stored centroid, m: since the declared
    /// slide began, or unbounded (each centroid's age) when none is declared.
    pub(super) fn slid_m(&self) -> f64 {
        self.slide_onset_m.map_or(f64::INFINITY, |onset| (self.odometer_m - onset).max(0.0))
    }

    /// The shear the slide test's pooled comparisons agree on (see [`Lanes::observe_slide`]).
    fn slide_consensus(&self, config: &DetectorConfig) -> Option<f64> {
        let (first, last) = (self.slide.front()?, self.slide.back()?);
        if self.slide.len() < SLIDE_MIN_SAMPLES || last[0] - first[0] < 0.5 * config.shear_window_m {
            return None;
        }
        let (sw, swk) = self.slide.iter().fold((0.0, 0.0), |(sw, swk), e| (sw + e[2], swk + e[2] * e[1]));
        let mean = swk / sw;
        let min = config.shear_test_min_per_m;
        let agreed = mean.abs() >= min && self.slide.iter().all(|e| e[1] * mean.signum() >= 0.5 * min);
        let straight = self.slide_found.is_some()
            || self.slide.iter().all(|e| wrap_angle(e[3] - last[3]).abs() <= SLIDE_MAX_TURN_RAD);
        let bound = config.shear_max_per_m;
        (agreed && straight && mean.is_finite()).then_some(mean.clamp(-bound, bound))
    }
}

/// One row's share of a slide-test comparison: the normal equations of its lateral residuals fitted as
/// `c + e·x + Δk·age + m·x·age` (see [`Lanes::observe_slide`]). A slide moves the row by `Δk·age`
/// wherever it is seen; a turn of `odom` the odometry did not sense (a gyro bias) rotates the stored
/// centroids about the robot, moving each by its age times its distance ahead, `m·x·age`.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct RowFit {
    n: Matrix4<f64>,
    v: Vector4<f64>,
    rss: f64,
    count: usize,
}

impl RowFit {
    pub(super) fn add(&mut self, x: f64, d: f64, w: f64, age_m: f64) {
        let phi = Vector4::new(1.0, x, age_m, x * age_m);
        self.n += w * phi * phi.transpose();
        self.v += w * d * phi;
        self.rss += w * d * d;
        self.count += 1;
    }

    /// The row's shear `Δk` and its variance from `c + e·x + Δk·age` (no turn), when it holds enough
    /// centroids of more than one age.
    fn shear(&self) -> Option<(f64, f64)> {
        if self.count < SLIDE_ROW_MIN_CENTROIDS {
            return None;
        }
        let n: Matrix3<f64> = self.n.fixed_view::<3, 3>(0, 0).into();
        let v: Vector3<f64> = self.v.fixed_rows::<3>(0).into();
        let inv = n.try_inverse().filter(|m| m[(2, 2)] > 0.0)?;
        let p = inv * v;
        let variance = (self.rss - p.dot(&v)).max(0.0) / (self.count - 3) as f64 * inv[(2, 2)];
        (p[2].is_finite() && variance.is_finite()).then_some((p[2], variance.max(SLIDE_ROW_MIN_VARIANCE)))
    }

    /// The row's turn `m` (rad per metre driven) and its variance from the full fit with the turn term,
    /// when it holds enough centroids spread over ages and distances ahead.
    fn turn(&self) -> Option<(f64, f64)> {
        if self.count < SLIDE_ROW_MIN_CENTROIDS + 1 {
            return None;
        }
        let inv = self.n.try_inverse().filter(|m| m[(3, 3)] > 0.0)?;
        let p = inv * self.v;
        let variance = (self.rss - p.dot(&self.v)).max(0.0) / (self.count - 4) as f64 * inv[(3, 3)];
        (p[3].is_finite() && variance.is_finite()).then_some((p[3], variance.max(SLIDE_ROW_MIN_VARIANCE)))
    }

    /// Weighted mean distance ahead of the row's stored centroids (age > 0), m.
    fn stored_x_m(&self) -> Option<f64> {
        // Σw·age·x / Σw·age: the centroids that carry the shear, weighted by how much they carry.
        let (swa, swax) = (self.n[(0, 2)], self.n[(1, 2)]);
        (swa > 0.0).then(|| swax / swa)
    }
}

/// The shear that the rows on both sides of the robot agree on, with its variance: each side's rows
/// (`j >= 0` left, `j < 0` right; `rows[i]` is row `j_min + i`) are pooled with inverse-variance
/// weights; when the two sides agree in sign, all rows pooled are the comparison's shear (a slide
/// moves every row alike, so both sides measure it); when they disagree, the comparison is 0, which
/// keeps the sign test of [`Lanes::slide_consensus`] shut for a window. A weed clump pulls the
/// centroids of the one or two rows beside it, and a clump in an inter-row pulls its two rows towards
/// each other (opposite signs), so it rarely moves both sides alike. Taking the weaker side instead of
/// all rows pooled was measured too (docs/faults.md): slower on slides. `None` while one side shows
/// no row with a shear.
pub(super) fn slide_consensus_of_rows(rows: &[RowFit], j_min: i32) -> Option<(f64, f64)> {
    let turn = turn_of_rows(rows);
    let mut sides = [(0.0, 0.0); 2];
    for (j, row) in (j_min..).zip(rows) {
        if let (Some((k, variance)), Some(x)) = (row.shear(), row.stored_x_m()) {
            let side = &mut sides[usize::from(j < 0)];
            let k = k - turn * x;
            side.0 += k / variance;
            side.1 += 1.0 / variance;
        }
    }
    let [(lk, lw), (rk, rw)] = sides;
    if lw <= 0.0 || rw <= 0.0 {
        return None;
    }
    if lk * rk <= 0.0 {
        return Some((0.0, (1.0 / lw).max(1.0 / rw)));
    }
    Some(((lk + rk) / (lw + rw), 1.0 / (lw + rw)))
}

/// The turn of `odom` that all rows agree on, rad per metre driven (`rows` as in
/// [`slide_consensus_of_rows`]), or 0 when the rows' pooled turn lies within [`SLIDE_TURN_Z`] standard
/// errors of none. A yaw-rate error of the odometry (a gyro bias step the EKF has not learned yet)
/// rotates the stored centroids about the robot: every row moves by its age times its distance ahead,
/// 2-4 m in view, and without this term reads as a slide of that many times the turn.
fn turn_of_rows(rows: &[RowFit]) -> f64 {
    let (sw, swm) = rows
        .iter()
        .filter_map(RowFit::turn)
        .fold((0.0, 0.0), |(sw, swm), (m, variance)| (sw + 1.0 / variance, swm + m / variance));
    if sw <= 0.0 {
        return 0.0;
    }
    let m = swm / sw;
    if m.is_finite() && m.abs() * sw.sqrt() >= SLIDE_TURN_Z { m } else { 0.0 }
}
