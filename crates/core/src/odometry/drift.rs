//! The odometry's unsensed drift, estimated from the crop rows and taken out of the pose the navigator
//! works in.
//!
//! Where it sits: between the odometry ([`super::Ekf`]) and the navigator. Wheels and a gyro cannot
//! see a sideways slide on wet soil, nor a gyro bias step the EKF has not learned; in `odom` the rows
//! then move (sideways) or turn, although they stand still in the field. The detector keeps its row
//! centroids in the frame it is given for the 4-5 m they stay in view, so a moving `odom` shears its
//! map: measured in the 1000-run soak (issue 6), the fitted centre line stayed right where the newest
//! centroids are, about 3 m ahead, and pivoted about that point, 20-30 cm off at the robot; the robot
//! believed it was centred while its tyres rolled over a row.
//!
//! [`Drift`] models the drift as a lateral slide per metre driven forward (a crab angle, the slip
//! patch's `lateral_drift · v`) and a yaw rate (a gyro bias), both constant over a few metres, and
//! integrates them into a corrected pose, the `nav` frame: `odom` with the drift removed. It learns
//! them from the rows, which stand still in the field. Each trusted centre line (the robot nearly
//! parallel to it and close to it: not during a swing onto a line, where the map's own lag moves the
//! fit) is compared with the previous one at the point `drift.anchor_m` ahead of the robot, where the
//! fit rests on fresh centroids; the step, with the correction applied in between added back, is the
//! rows' motion in `odom`. Over the last `drift.window_m` driven those positions are fitted with a
//! straight line against distance: its slope is the slide, directly (not a residual), so a correction
//! already applied does not have to be waited out. A slope below `drift.min_lateral_per_m`, or a window
//! that the fit does not explain within `drift.max_residual_m`, is taken as no slide: that is the
//! closed canopy's fit noise and the map's lag, and the estimate then decays towards zero. The yaw
//! rate is fitted the same way from the line's heading against time (off by default, see
//! `drift.yaw_gain`).
//!
//! ```
//! use croprow_core::odometry::{Drift, DriftConfig};
//! use croprow_core::Pose2;
//! let mut drift = Drift::new(DriftConfig::default()).unwrap();
//! // Until rows are observed, `nav` is `odom`.
//! let nav = drift.correct(0.0, Pose2::new(1.0, 2.0, 0.1));
//! assert_eq!(nav, Pose2::new(1.0, 2.0, 0.1));
//! ```

use std::collections::VecDeque;

use serde::{Deserialize, Serialize};

use crate::control::path::Segment;
use crate::error::{ConfigError, check_range};
use crate::geometry::{Pose2, wrap_angle};

/// Most comparisons kept in the window: 1 m at 0.5 m/s and 10 Hz is 20; slower driving keeps the
/// newest ones.
const WINDOW_CAPACITY: usize = 64;

/// Settings of the drift estimator (section `drift`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriftConfig {
    /// Estimate and remove the drift; false leaves `nav` = `odom`. Default false. On the 33 soak seeds
    /// that ran over plants while following under a slide or a gyro step it leaves 503 plants (off:
    /// 1220), but it takes a LiDAR rolled 3° for a slide (`fault-mount-error`: 38 cm max cross-track
    /// against under 3 cm off), follows a tall weed patch and the dropout lane worse, and 20 m of grown
    /// soybean (`closed_loop_follow`) follows at 1.56 cm mean, 7.9 cm max (off 1.37 cm). Measured, on
    /// against off: the
    /// recovery lane both ways as without it (9 and 11 plants, settled after 2.58 and 2.56 m); Table I
    /// following at 200 m 0.40 / 0.96 / 0.31 / 1.07 / 0.59 cm (off: 0.40 / 0.98 / 0.31 / 1.09 / 0.59);
    /// the full-field demo 8 of 8 lanes, 0 contacts; the 33 soak seeds that ran over plants while
    /// following under a slide or a gyro step, see `docs/faults.md`.
    pub enabled: bool,
    /// Distance ahead of `base_link` at which successive centre lines are compared, m. Default 3.0:
    /// on the soak's slip-patch runs the detected line was within 5 cm of the truth there, against
    /// 20-30 cm at the robot and up to 30 cm 4 m ahead (the paper's mount sees 1.6-4 m ahead).
    pub anchor_m: f64,
    /// Least distance driven between two compared lines, m. Default 0.04 (a scan at 0.5 m/s is
    /// 0.05 m): a robot standing still teaches nothing.
    pub sample_m: f64,
    /// Distance driven over which the rows' positions are fitted, m. Default 1.0.
    pub window_m: f64,
    /// Least distance the window must span before it is believed, m. Default 0.3: on the soak's 33
    /// slide and gyro-step seeds (`docs/faults.md`) 0.5 with gain 0.3 left 539 plants, 0.3 with gain
    /// 0.5 left 394; a 0.3 m window learned faster still but wandered on the recovery lane.
    pub min_span_m: f64,
    /// Fraction of the way from the estimate to the window's slope moved per comparison. Default 0.5.
    pub lateral_gain: f64,
    /// Smallest slope believed to be a slide, m per m; smaller ones count as none. Default 0.03 (the
    /// soak's weakest slides that ran over plants are 0.04 m/s at 0.5 m/s, 0.08 m per m).
    pub min_lateral_per_m: f64,
    /// Largest RMS distance of the window's positions from their fitted line, m; a larger one is a
    /// fit that wanders, not a slide, and counts as none. Default 0.01.
    pub max_residual_m: f64,
    /// Largest angle between the robot and the centre line for a comparison to be trusted, rad.
    /// Default 0.3 (17°: only a gross swing). 0.05 (3°) also cut comparisons during the slides, whose
    /// sheared line leans off the robot: on the 33 soak seeds 539 plants against 438 without it; the
    /// recovery lane's swing is kept out by `max_line_offset_m` alone.
    pub max_line_heading_rad: f64,
    /// Largest offset of the centre line from the robot for a comparison to be trusted, m. Default
    /// 0.1: with 0.3 (and 0.15 rad) the recovery lane (0.3 m, 8° off) settled after 5-7.5 m instead of
    /// 2.4-2.6 m.
    pub max_line_offset_m: f64,
    /// Fraction of the way from the yaw-rate estimate to the window's turn rate moved per comparison.
    /// Default 0 (off): the fitted heading turns while a slide shears the map, and the yaw loop took
    /// that for a gyro bias.
    pub yaw_gain: f64,
    /// Smallest turn rate believed to be a gyro bias, rad/s. Default 0.005.
    pub min_yaw_rate_radps: f64,
    /// Largest slide estimate magnitude, m per m driven. Default 0.25 (14°: the soak's 0.08 m/s at
    /// 0.5 m/s is 0.16).
    pub max_lateral_per_m: f64,
    /// Largest yaw-rate estimate magnitude, rad/s. Default 0.05 (the soak's bias steps reach 0.03).
    pub max_yaw_rate_radps: f64,
    /// Largest sideways move (m) and turn (rad) of the line between two comparisons believed to be
    /// drift; a larger one is a new lock of the detector, and the window starts over. Default 0.1 m
    /// (a 0.08 m/s slide moves the line 1 cm per scan) and 0.1 rad.
    pub max_step_m: f64,
    /// See `max_step_m`, rad. Default 0.1.
    pub max_step_rad: f64,
    /// Distance over which the slide estimate decays to 1/e while no line is compared (turns, the
    /// headland, stops without rows, swings), m. Default 3: a slip patch is local.
    pub lateral_memory_m: f64,
}

impl Default for DriftConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            anchor_m: 3.0,
            sample_m: 0.04,
            window_m: 1.0,
            min_span_m: 0.3,
            lateral_gain: 0.5,
            min_lateral_per_m: 0.03,
            max_residual_m: 0.01,
            max_line_heading_rad: 0.3,
            max_line_offset_m: 0.1,
            yaw_gain: 0.0,
            min_yaw_rate_radps: 0.005,
            max_lateral_per_m: 0.25,
            max_yaw_rate_radps: 0.05,
            max_step_m: 0.1,
            max_step_rad: 0.1,
            lateral_memory_m: 3.0,
        }
    }
}

impl DriftConfig {
    /// Checks every field, naming the first bad one (`drift.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("drift.anchor_m", self.anchor_m, 0.0, 20.0)?;
        check_range("drift.sample_m", self.sample_m, 0.001, 1.0)?;
        check_range("drift.window_m", self.window_m, 0.05, 20.0)?;
        check_range("drift.min_span_m", self.min_span_m, 0.01, self.window_m)?;
        check_range("drift.lateral_gain", self.lateral_gain, 0.0, 1.0)?;
        check_range("drift.min_lateral_per_m", self.min_lateral_per_m, 0.0, 1.0)?;
        check_range("drift.max_residual_m", self.max_residual_m, 0.0, 1.0)?;
        check_range("drift.max_line_heading_rad", self.max_line_heading_rad, 0.0, 1.0)?;
        check_range("drift.max_line_offset_m", self.max_line_offset_m, 0.0, 5.0)?;
        check_range("drift.yaw_gain", self.yaw_gain, 0.0, 1.0)?;
        check_range("drift.min_yaw_rate_radps", self.min_yaw_rate_radps, 0.0, 1.0)?;
        check_range("drift.max_lateral_per_m", self.max_lateral_per_m, 0.0, 1.0)?;
        check_range("drift.max_yaw_rate_radps", self.max_yaw_rate_radps, 0.0, 1.0)?;
        check_range("drift.max_step_m", self.max_step_m, 0.001, 10.0)?;
        check_range("drift.max_step_rad", self.max_step_rad, 0.001, 1.0)?;
        check_range("drift.lateral_memory_m", self.lateral_memory_m, 0.01, 1000.0)?;
        Ok(())
    }
}

/// A centre line observed in `nav`: its point `anchor_m` ahead of the robot, with the line's
/// direction there and its curvature, when and after how much travel it was seen, and the correction
/// `nav` had accumulated then.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sighting {
    anchor: Pose2,
    curvature_per_m: f64,
    stamp_s: f64,
    odometer_m: f64,
    applied_m: f64,
    applied_rad: f64,
}

/// One comparison in the window: where the rows stood in `odom` (net of the correction), sideways at
/// the anchor and in heading, accumulated since the window started.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sample {
    odometer_m: f64,
    stamp_s: f64,
    lateral_m: f64,
    heading_rad: f64,
}

/// Least-squares slope of `y` against `x` and the RMS residual about the fitted line, or `None`
/// when `x` does not vary.
fn fit_slope(points: impl Iterator<Item = (f64, f64)> + Clone) -> Option<(f64, f64)> {
    let (mut n, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for (x, y) in points.clone() {
        n += 1.0;
        sx += x;
        sy += y;
    }
    if n < 3.0 {
        return None;
    }
    let (mx, my) = (sx / n, sy / n);
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for (x, y) in points {
        let (dx, dy) = (x - mx, y - my);
        sxx += dx * dx;
        sxy += dx * dy;
        syy += dy * dy;
    }
    if sxx <= f64::EPSILON {
        return None;
    }
    let slope = sxy / sxx;
    let residual = ((syy - slope * sxy).max(0.0) / n).sqrt();
    Some((slope, residual)).filter(|(b, r)| b.is_finite() && r.is_finite())
}

/// The drift estimator and the `nav` pose it integrates (see the module docs).
#[derive(Debug, Clone)]
pub struct Drift {
    cfg: DriftConfig,
    /// Last `odom` pose and the `nav` pose it was corrected to, with its stamp.
    last: Option<(f64, Pose2, Pose2)>,
    lateral_per_m: f64,
    yaw_rate_radps: f64,
    odometer_m: f64,
    /// Sideways correction (m, `base_link` left) and turn (rad) `nav` has accumulated over `odom`.
    applied_m: f64,
    applied_rad: f64,
    /// The line compared against: the last trusted one.
    sighting: Option<Sighting>,
    /// The trusted comparisons of the last `window_m` driven, oldest first; allocated once.
    window: VecDeque<Sample>,
}

impl Drift {
    /// Validates the configuration.
    pub fn new(cfg: DriftConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self {
            cfg,
            last: None,
            lateral_per_m: 0.0,
            yaw_rate_radps: 0.0,
            odometer_m: 0.0,
            applied_m: 0.0,
            applied_rad: 0.0,
            sighting: None,
            window: VecDeque::with_capacity(WINDOW_CAPACITY),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &DriftConfig {
        &self.cfg
    }

    /// The estimated slide, m per m driven forward, positive to the left of `base_link`.
    pub fn lateral_per_m(&self) -> f64 {
        self.lateral_per_m
    }

    /// The estimated yaw-rate error of `odom` removed in `nav`, rad/s, counter-clockwise positive.
    pub fn yaw_rate_radps(&self) -> f64 {
        self.yaw_rate_radps
    }

    /// The `nav` pose for the `odom` pose `odom` at `stamp_s`: the previous `nav` pose moved by the
    /// odometry's motion since then, plus the estimated slide and turn. The caller checks that the
    /// input is finite and that time does not go backwards; a non-finite result never comes out (the
    /// `odom` pose is returned instead and the estimator restarts from it).
    pub fn correct(&mut self, stamp_s: f64, odom: Pose2) -> Pose2 {
        let Some((t0, odom0, nav0)) = self.last.filter(|_| self.cfg.enabled) else {
            self.last = Some((stamp_s, odom, odom));
            return odom;
        };
        let step = odom0.relative(&odom);
        let dt = (stamp_s - t0).max(0.0);
        let forward = step.x;
        self.odometer_m += forward.abs();
        if self.window.is_empty() {
            // Nothing trusted to compare: a slip patch is local, let its estimate fade with distance.
            self.lateral_per_m *= (-forward.abs() / self.cfg.lateral_memory_m).exp();
        }
        let (slide_m, turn_rad) = (self.lateral_per_m * forward, self.yaw_rate_radps * dt);
        self.applied_m += slide_m;
        self.applied_rad += turn_rad;
        let moved = nav0.compose(&Pose2::new(step.x, step.y + slide_m, step.yaw + turn_rad));
        // `compose` wraps the heading; `odom`'s may run past ±π (after a headland U-turn), and the
        // lane switcher compares headings on that branch: keep it (wrapped, the full-field demo
        // stopped `no_room_to_turn` at its second row end even with nothing learned).
        let nav = Pose2::new(moved.x, moved.y, odom.yaw + self.applied_rad);
        if !nav.is_finite() || !self.applied_m.is_finite() || !self.applied_rad.is_finite() {
            self.restart(stamp_s, odom);
            return odom;
        }
        self.last = Some((stamp_s, odom, nav));
        nav
    }

    /// Learns from a centre line seen at `stamp_s` from the `nav` pose `nav`: the line's pose at the
    /// robot in `base_link` (`line`, as [`crate::control::reference::CentreLine::pose`] gives it) and its
    /// curvature. Pass only lines the robot follows (both rows tracked, no row end in view closer than
    /// the anchor). A line the robot is not parallel and close to (a swing) empties the window; a line
    /// that jumps is taken as a new lock and starts the window over.
    pub fn observe(&mut self, stamp_s: f64, nav: &Pose2, line: Pose2, curvature_per_m: f64) {
        if !self.cfg.enabled || !stamp_s.is_finite() || !nav.is_finite() || !line.is_finite() {
            return;
        }
        if wrap_angle(line.yaw).abs() > self.cfg.max_line_heading_rad
            || line.y.abs() > self.cfg.max_line_offset_m
        {
            self.forget_line();
            return;
        }
        let on_line = Segment { start: nav.compose(&line), length_m: self.cfg.anchor_m, curvature_per_m };
        let now = Sighting {
            anchor: on_line.pose_at(self.cfg.anchor_m),
            curvature_per_m,
            stamp_s,
            odometer_m: self.odometer_m,
            applied_m: self.applied_m,
            applied_rad: self.applied_rad,
        };
        if !now.anchor.is_finite() || !curvature_per_m.is_finite() {
            return;
        }
        let Some(before) = self.sighting else {
            self.start_window(now);
            return;
        };
        if now.stamp_s <= before.stamp_s {
            self.start_window(now);
            return;
        }
        if now.odometer_m - before.odometer_m < self.cfg.sample_m {
            return;
        }
        // The line seen before, continued to abreast of the new anchor.
        let old = Segment { start: before.anchor, length_m: 0.0, curvature_per_m: before.curvature_per_m };
        let along = before.anchor.inverse_transform_point(now.anchor.x, now.anchor.y).0;
        let rel = old.pose_at(along).relative(&now.anchor);
        let (shift_m, turn_rad) = (rel.y, wrap_angle(rel.yaw));
        if shift_m.abs() > self.cfg.max_step_m || turn_rad.abs() > self.cfg.max_step_rad {
            self.start_window(now);
            return;
        }
        // `nav` moved left of `odom` by the correction applied in between, and turned, which swings the
        // anchor sideways by its distance: in `odom` the rows moved by the rest.
        let turned = now.applied_rad - before.applied_rad;
        let odom_shift = shift_m - (now.applied_m - before.applied_m) - self.cfg.anchor_m * turned;
        let odom_turn = turn_rad - turned;
        let last = self.window.back().copied().unwrap_or(Sample {
            odometer_m: before.odometer_m,
            stamp_s: before.stamp_s,
            lateral_m: 0.0,
            heading_rad: 0.0,
        });
        self.push(Sample {
            odometer_m: now.odometer_m,
            stamp_s: now.stamp_s,
            lateral_m: last.lateral_m + odom_shift,
            heading_rad: last.heading_rad + odom_turn,
        });
        self.sighting = Some(now);
        self.learn();
    }

    /// Forgets the line compared against and the window (a new lane, a detector reset, a stop, a
    /// swing); the estimates stay (a gyro bias does not change with the lane) and the slide fades with
    /// distance until lines are compared again.
    pub fn forget_line(&mut self) {
        self.sighting = None;
        self.window.clear();
    }

    /// Leaves the lane (a turn, a stop, acquiring): forgets the line and drops the slide estimate. A
    /// slip patch is local, and a slide carried into a headland turn bends the turn's geometry (the
    /// full-field demo stopped after its first lane on a slide of a few centimetres per metre learned
    /// at the row end); the yaw-rate estimate stays, a gyro bias does not change with the lane.
    pub fn leave_lane(&mut self) {
        self.forget_line();
        self.lateral_per_m = 0.0;
    }

    fn start_window(&mut self, now: Sighting) {
        self.window.clear();
        self.window.push_back(Sample {
            odometer_m: now.odometer_m,
            stamp_s: now.stamp_s,
            lateral_m: 0.0,
            heading_rad: 0.0,
        });
        self.sighting = Some(now);
    }

    fn push(&mut self, sample: Sample) {
        while self.window.len() >= WINDOW_CAPACITY
            || self.window.front().is_some_and(|s| sample.odometer_m - s.odometer_m > self.cfg.window_m)
        {
            self.window.pop_front();
        }
        self.window.push_back(sample);
    }

    /// Moves the estimates towards the window's slopes, or towards zero when the window shows no
    /// drift it can vouch for.
    fn learn(&mut self) {
        let (Some(first), Some(last)) = (self.window.front(), self.window.back()) else { return };
        if last.odometer_m - first.odometer_m < self.cfg.min_span_m {
            return;
        }
        let lateral = fit_slope(self.window.iter().map(|s| (s.odometer_m, s.lateral_m)));
        let yaw = fit_slope(self.window.iter().map(|s| (s.stamp_s, s.heading_rad)));
        let (Some((lateral_slope, residual_m)), Some((yaw_slope, _))) = (lateral, yaw) else { return };
        let trusted = residual_m <= self.cfg.max_residual_m;
        // The rows moving right in `odom` means the robot slid left; rows turning counter-clockwise
        // with `odom` mean `odom` turns counter-clockwise too fast.
        let slide =
            if trusted && lateral_slope.abs() >= self.cfg.min_lateral_per_m { -lateral_slope } else { 0.0 };
        let bias = if trusted && yaw_slope.abs() >= self.cfg.min_yaw_rate_radps { -yaw_slope } else { 0.0 };
        let (max_l, max_w) = (self.cfg.max_lateral_per_m, self.cfg.max_yaw_rate_radps);
        self.lateral_per_m += self.cfg.lateral_gain * (slide - self.lateral_per_m);
        self.lateral_per_m = self.lateral_per_m.clamp(-max_l, max_l);
        self.yaw_rate_radps += self.cfg.yaw_gain * (bias - self.yaw_rate_radps);
        self.yaw_rate_radps = self.yaw_rate_radps.clamp(-max_w, max_w);
    }

    fn restart(&mut self, stamp_s: f64, odom: Pose2) {
        self.last = Some((stamp_s, odom, odom));
        self.lateral_per_m = 0.0;
        self.yaw_rate_radps = 0.0;
        self.applied_m = 0.0;
        self.applied_rad = 0.0;
        self.forget_line();
    }
}

#[cfg(test)]
mod tests {
    use rand::{RngExt, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    fn on() -> DriftConfig {
        DriftConfig { enabled: true, ..DriftConfig::default() }
    }

    /// `on()` with the trust gates open: these robots do not steer back onto the line.
    fn ungated() -> DriftConfig {
        DriftConfig { max_line_heading_rad: 1.0, max_line_offset_m: 5.0, ..on() }
    }

    /// Drives along y = 0 in the field at 0.5 m/s for `seconds`, with odometry that misses a slide of
    /// `slide_per_m` (m per m, left) and a yaw-rate error `yaw_bias` (rad/s: `odom` turns that much
    /// faster than the robot); the centre line is the field's x axis, seen every 0.1 s with a seeded
    /// uniform error of up to `noise_m` in its offset. Returns the drift estimator and the true and
    /// `nav` poses at the end.
    fn drive(
        drift: &mut Drift,
        slide_per_m: f64,
        yaw_bias: f64,
        seconds: f64,
        noise_m: f64,
    ) -> (Pose2, Pose2) {
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let dt = 0.02;
        let (mut truth, mut odom) = (Pose2::default(), Pose2::default());
        let mut nav = drift.correct(0.0, odom);
        let steps = (seconds / dt).round() as usize;
        for k in 1..=steps {
            let t = k as f64 * dt;
            let ds = 0.5 * dt;
            // The robot keeps its true heading along the rows but slides; odometry sees neither.
            truth = truth.compose(&Pose2::new(ds, slide_per_m * ds, 0.0));
            odom = odom.compose(&Pose2::new(ds, 0.0, yaw_bias * dt));
            nav = drift.correct(t, odom);
            if k % 5 == 0 {
                // The rows as the robot sees them (true geometry, base_link): the field's x axis.
                let line = truth.relative(&Pose2::default());
                let noise = if noise_m > 0.0 { rng.random_range(-noise_m..noise_m) } else { 0.0 };
                let at_robot = Pose2::new(0.0, line.y - line.x * line.yaw.tan() + noise, line.yaw);
                drift.observe(t, &nav, at_robot, 0.0);
            }
        }
        (truth, nav)
    }

    #[test]
    fn without_rows_nav_is_odom() {
        let mut drift = Drift::new(on()).unwrap();
        for k in 0..10 {
            let odom = Pose2::new(0.1 * k as f64, 0.02 * k as f64, 0.01 * k as f64);
            let nav = drift.correct(0.1 * k as f64, odom);
            assert!((nav.x - odom.x).abs() < 1e-12 && (nav.y - odom.y).abs() < 1e-12);
            assert!((nav.yaw - odom.yaw).abs() < 1e-12);
        }
    }

    #[test]
    fn a_sideways_slide_is_learned_from_the_rows() {
        // The soak's strongest slip patch: 0.08 m/s sideways at 0.5 m/s, 0.16 m per m.
        let mut drift = Drift::new(ungated()).unwrap();
        let (truth, nav) = drive(&mut drift, -0.16, 0.0, 6.0, 0.0);
        // After 3 m (a 1 m window, then 40 comparisons at gain 0.3) the estimate is within 1 %.
        assert!((drift.lateral_per_m() + 0.16).abs() < 0.0016, "{}", drift.lateral_per_m());
        assert!(drift.yaw_rate_radps().abs() < 1e-9, "{}", drift.yaw_rate_radps());
        // `nav` followed the truth to within 12 cm of the 48 cm slid: nothing is learned before the
        // window spans 0.5 m, and the estimate ramps up over the next few decimetres.
        assert!((nav.y - truth.y).abs() < 0.12, "nav {nav:?} truth {truth:?}");
    }

    #[test]
    fn a_slide_that_ends_is_forgotten() {
        let mut drift = Drift::new(ungated()).unwrap();
        drive(&mut drift, -0.16, 0.0, 6.0, 0.0);
        // 2 m further without a slide: the window sees none and the estimate decays.
        let mut odometer = 3.0;
        let mut stamp = 6.0;
        for _ in 0..40 {
            odometer += 0.05;
            stamp += 0.1;
            let nav = drift.correct(stamp, Pose2::new(odometer, 0.0, 0.0));
            // The rows stand still in `odom` now: dead ahead of the robot, which no longer slides.
            drift.observe(stamp, &nav, Pose2::default(), 0.0);
        }
        assert!(drift.lateral_per_m().abs() < 0.01, "{}", drift.lateral_per_m());
    }

    #[test]
    fn a_gyro_bias_is_learned_from_the_rows() {
        let cfg = DriftConfig { yaw_gain: 0.3, ..ungated() };
        let mut drift = Drift::new(cfg).unwrap();
        drive(&mut drift, 0.0, 0.025, 10.0, 0.0);
        // The window's turn rate is exact; 0.3 per comparison over the last 8 s: within 5 %.
        assert!((drift.yaw_rate_radps() + 0.025).abs() < 0.00125, "{}", drift.yaw_rate_radps());
    }

    #[test]
    fn rows_still_in_odom_teach_nothing() {
        let cfg = DriftConfig { yaw_gain: 0.3, ..on() };
        let mut drift = Drift::new(cfg).unwrap();
        drive(&mut drift, 0.0, 0.0, 5.0, 0.0);
        assert_eq!((drift.lateral_per_m(), drift.yaw_rate_radps()), (0.0, 0.0));
    }

    #[test]
    fn fit_noise_of_a_closed_canopy_teaches_nothing() {
        // Scan-to-scan noise of ±1 cm in the line's offset, nothing sliding: each pair of scans 5 cm
        // apart shows up to 0.4 m per m, the 1 m window's slope stays under the 0.03 threshold.
        let mut drift = Drift::new(on()).unwrap();
        drive(&mut drift, 0.0, 0.0, 20.0, 0.01);
        assert_eq!(drift.lateral_per_m(), 0.0);
    }

    #[test]
    fn a_swing_onto_the_line_teaches_nothing() {
        // The robot 0.3 m off the line and closing in, the fitted line moving 1 cm per scan as the map
        // catches up: not a slide while the line is more than `max_line_offset_m` away.
        let mut drift = Drift::new(on()).unwrap();
        for k in 0..19 {
            let t = 0.1 * f64::from(k);
            let nav = drift.correct(t, Pose2::new(0.05 * f64::from(k), 0.0, 0.14));
            drift.observe(t, &nav, Pose2::new(0.0, -0.3 + 0.01 * f64::from(k), -0.14), 0.0);
        }
        assert_eq!(drift.lateral_per_m(), 0.0);
    }

    #[test]
    fn a_jump_of_the_line_is_a_new_lock_not_drift() {
        let mut drift = Drift::new(ungated()).unwrap();
        let mut odometer = 0.0;
        let mut at = |t: f64, y: f64, d: &mut Drift| {
            odometer += 0.3;
            let nav = d.correct(t, Pose2::new(odometer, 0.0, 0.0));
            d.observe(t, &nav, Pose2::new(0.0, y, 0.0), 0.0);
        };
        at(0.0, 0.0, &mut drift);
        at(0.6, 0.0, &mut drift);
        // The neighbouring lane, 0.75 m over, from then on.
        for k in 2..8 {
            at(0.6 * f64::from(k), 0.75, &mut drift);
        }
        assert_eq!(drift.lateral_per_m(), 0.0);
    }

    #[test]
    fn a_straight_fit_recovers_slope_and_residual() {
        let (slope, residual) = fit_slope([(0.0, 1.0), (1.0, 3.0), (2.0, 5.0)].into_iter()).unwrap();
        assert!((slope - 2.0).abs() < 1e-12 && residual < 1e-9, "{slope} {residual}");
        // Too few points, or all at one x: no slope.
        assert_eq!(fit_slope([(0.0, 1.0), (1.0, 3.0)].into_iter()), None);
        assert_eq!(fit_slope([(1.0, 1.0), (1.0, 3.0), (1.0, 2.0)].into_iter()), None);
    }

    #[test]
    fn an_absurd_config_is_refused_by_name() {
        let cfg = DriftConfig { window_m: 0.0, ..DriftConfig::default() };
        assert!(Drift::new(cfg).unwrap_err().to_string().contains("drift.window_m"));
        let cfg = DriftConfig { min_span_m: 2.0, ..DriftConfig::default() };
        assert!(Drift::new(cfg).unwrap_err().to_string().contains("drift.min_span_m"));
    }
}
