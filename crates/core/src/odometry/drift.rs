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
//! them from the rows, which stand still in the field: every `drift.baseline_m` driven it compares the
//! centre line detected now with the one detected a baseline ago, both in `nav`, at the point
//! `drift.anchor_m` ahead of the robot (where the fit rests on fresh centroids). A row line that moved
//! sideways by `δ` over a baseline `Δs` means the robot slid by `−δ`: the slide estimate moves by
//! `−gain · δ / Δs`; a heading that turned by `δψ` over `Δt` (net of the rows' own curvature) moves
//! the yaw-rate estimate by `−gain · δψ / Δt` (off by default, see `drift.yaw_gain`). It is an
//! integral controller on the rows' apparent motion: once the estimates are right the rows stand
//! still in `nav` and the map is consistent again.
//!
//! ```
//! use croprow_core::odometry::{Drift, DriftConfig};
//! use croprow_core::Pose2;
//! let mut drift = Drift::new(DriftConfig::default()).unwrap();
//! // Until rows are observed, `nav` is `odom`.
//! let nav = drift.correct(0.0, Pose2::new(1.0, 2.0, 0.1));
//! assert_eq!(nav, Pose2::new(1.0, 2.0, 0.1));
//! ```

use serde::{Deserialize, Serialize};

use crate::control::path::Segment;
use crate::error::{ConfigError, check_range};
use crate::geometry::{Pose2, wrap_angle};

/// Settings of the drift estimator (section `drift`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriftConfig {
    /// Estimate and remove the drift; false leaves `nav` = `odom`. Default false, until it stops
    /// costing where nothing slides. On: the 34 soak seeds that ran over plants while following or
    /// entering ran over 129 instead of 790 (19 of them none). But it learns from the map's lag while
    /// the robot swings back onto a line far off, and from the fit's noise in closed canopies, and
    /// wanders by 1-2 cm: on the `recovery` scenario (0.3 m and ±8° off, young corn) the cross-track
    /// error no longer stays under 2 cm (+8°: 12 plants, settled after 2.46 m, off: 9 plants, 2.54 m;
    /// −8°: 13 plants, never settled, off: 11, 2.41 m; on 12 m of it, 14 plants), and 20 m of grown
    /// soybean follows at 2.09 cm instead of 1.37 cm.
    pub enabled: bool,
    /// Distance ahead of `base_link` at which successive centre lines are compared, m. Default 3.0:
    /// on the soak's slip-patch runs the detected line was within 5 cm of the truth there, against
    /// 20-30 cm at the robot and up to 30 cm 4 m ahead (the paper's mount sees 1.6-4 m ahead).
    pub anchor_m: f64,
    /// Distance driven between two compared lines, m. Default 0.1 (two scans at 0.5 m/s): over it a
    /// 0.05 m/s slide at 0.5 m/s moves the rows 1 cm in `odom`, above the line's scan-to-scan noise
    /// (millimetres). Measured on the 34 soak seeds that ran over plants while following or entering
    /// (790 plants before): 0.25 left 196 plants, 0.15 left 140, 0.1 left 129; 0.5 was worse than 0.25.
    pub baseline_m: f64,
    /// Fraction of the apparent slide per metre fed into the estimate per baseline. Default 0.5.
    pub lateral_gain: f64,
    /// Fraction of the apparent turn rate fed into the estimate per baseline. Default 0 (off): the
    /// fitted heading turns while a slide shears the map, and the yaw loop took that for a gyro bias.
    /// Measured on the soak seeds 35, 78, 100, 180, 549, 725, 744 and 910 (slides and gyro bias steps):
    /// 0.3 left 26, 1, 3, 1, 0, 3, 3, 2 contacts, 0 left 30, 1, 0, 0, 0, 0, 1, 0 (before: 82, 95, 37,
    /// 16, 43, 11, 31, 72).
    pub yaw_gain: f64,
    /// Largest slide estimate magnitude, m per m driven. Default 0.25 (14°: the soak's 0.08 m/s at
    /// 0.5 m/s is 0.16).
    pub max_lateral_per_m: f64,
    /// Largest yaw-rate estimate magnitude, rad/s. Default 0.05 (the soak's bias steps reach 0.03).
    pub max_yaw_rate_radps: f64,
    /// Largest sideways move (m) and turn (rad) of the line over one baseline believed to be drift;
    /// a larger one is a new lock of the detector, and the comparison starts over. Default 0.1 m
    /// (a 0.08 m/s slide moves the line 4 cm per baseline) and 0.1 rad.
    pub max_step_m: f64,
    /// See `max_step_m`, rad. Default 0.1.
    pub max_step_rad: f64,
    /// Distance over which the slide estimate decays to 1/e while no line is compared (turns, the
    /// headland, stops without rows), m. Default 3: a slip patch is local.
    pub lateral_memory_m: f64,
}

impl Default for DriftConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            anchor_m: 3.0,
            baseline_m: 0.1,
            lateral_gain: 0.5,
            yaw_gain: 0.0,
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
        check_range("drift.baseline_m", self.baseline_m, 0.01, 10.0)?;
        check_range("drift.lateral_gain", self.lateral_gain, 0.0, 1.0)?;
        check_range("drift.yaw_gain", self.yaw_gain, 0.0, 1.0)?;
        check_range("drift.max_lateral_per_m", self.max_lateral_per_m, 0.0, 1.0)?;
        check_range("drift.max_yaw_rate_radps", self.max_yaw_rate_radps, 0.0, 1.0)?;
        check_range("drift.max_step_m", self.max_step_m, 0.001, 10.0)?;
        check_range("drift.max_step_rad", self.max_step_rad, 0.001, 1.0)?;
        check_range("drift.lateral_memory_m", self.lateral_memory_m, 0.01, 1000.0)?;
        Ok(())
    }
}

/// A centre line observed in `nav`: its point `anchor_m` ahead of the robot, with the line's
/// direction there and its curvature, and when and after how much travel it was seen.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Sighting {
    anchor: Pose2,
    curvature_per_m: f64,
    stamp_s: f64,
    odometer_m: f64,
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
    /// The line compared against, one baseline back.
    sighting: Option<Sighting>,
}

impl Drift {
    /// Validates the configuration.
    pub fn new(cfg: DriftConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self { cfg, last: None, lateral_per_m: 0.0, yaw_rate_radps: 0.0, odometer_m: 0.0, sighting: None })
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
        if self.sighting.is_none() {
            // Nothing compared: a slip patch is local, let its estimate fade with distance.
            self.lateral_per_m *= (-forward.abs() / self.cfg.lateral_memory_m).exp();
        }
        let moved =
            Pose2::new(step.x, step.y + self.lateral_per_m * forward, step.yaw + self.yaw_rate_radps * dt);
        let nav = nav0.compose(&moved);
        if !nav.is_finite() {
            self.restart(stamp_s, odom);
            return odom;
        }
        self.last = Some((stamp_s, odom, nav));
        nav
    }

    /// Learns from a centre line seen at `stamp_s` from the `nav` pose `nav`: the line's pose at the
    /// robot in `base_link` (`line`, as [`crate::control::reference::CentreLine::pose`] gives it) and its
    /// curvature. Pass only lines the robot follows (both rows tracked, no row end in view closer than
    /// the anchor): a line that jumps is taken as a new lock and only restarts the comparison.
    pub fn observe(&mut self, stamp_s: f64, nav: &Pose2, line: Pose2, curvature_per_m: f64) {
        if !self.cfg.enabled || !stamp_s.is_finite() || !nav.is_finite() || !line.is_finite() {
            return;
        }
        let on_line = Segment { start: nav.compose(&line), length_m: self.cfg.anchor_m, curvature_per_m };
        let now = Sighting {
            anchor: on_line.pose_at(self.cfg.anchor_m),
            curvature_per_m,
            stamp_s,
            odometer_m: self.odometer_m,
        };
        if !now.anchor.is_finite() || !curvature_per_m.is_finite() {
            return;
        }
        let Some(before) = self.sighting else {
            self.sighting = Some(now);
            return;
        };
        let travelled = now.odometer_m - before.odometer_m;
        let dt = now.stamp_s - before.stamp_s;
        if dt <= 0.0 {
            self.sighting = Some(now);
            return;
        }
        if travelled < self.cfg.baseline_m {
            return;
        }
        // The line seen before, continued to abreast of the new anchor.
        let old = Segment { start: before.anchor, length_m: 0.0, curvature_per_m: before.curvature_per_m };
        let along = before.anchor.inverse_transform_point(now.anchor.x, now.anchor.y).0;
        let abreast = old.pose_at(along);
        let rel = abreast.relative(&now.anchor);
        let (shift_m, turn_rad) = (rel.y, wrap_angle(rel.yaw));
        self.sighting = Some(now);
        if shift_m.abs() > self.cfg.max_step_m || turn_rad.abs() > self.cfg.max_step_rad {
            return;
        }
        let max_l = self.cfg.max_lateral_per_m;
        let max_w = self.cfg.max_yaw_rate_radps;
        self.lateral_per_m =
            (self.lateral_per_m - self.cfg.lateral_gain * shift_m / travelled).clamp(-max_l, max_l);
        self.yaw_rate_radps = (self.yaw_rate_radps - self.cfg.yaw_gain * turn_rad / dt).clamp(-max_w, max_w);
    }

    /// Forgets the line compared against (a new lane, a detector reset, a stop); the estimates stay
    /// (a gyro bias does not change with the lane) and the slide fades with distance until lines are
    /// compared again.
    pub fn forget_line(&mut self) {
        self.sighting = None;
    }

    fn restart(&mut self, stamp_s: f64, odom: Pose2) {
        self.last = Some((stamp_s, odom, odom));
        self.lateral_per_m = 0.0;
        self.yaw_rate_radps = 0.0;
        self.sighting = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Drives along y = 0 in the field at 0.5 m/s for `seconds`, with odometry that misses a slide of
    /// `slide_per_m` (m per m, left) and a yaw-rate error `yaw_bias` (rad/s: `odom` turns that much
    /// faster than the robot); the centre line is the field's x axis, seen every 0.1 s. Returns the
    /// final drift estimator and the final true and `nav` poses.
    fn on() -> DriftConfig {
        DriftConfig { enabled: true, ..DriftConfig::default() }
    }

    fn drive(cfg: DriftConfig, slide_per_m: f64, yaw_bias: f64, seconds: f64) -> (Drift, Pose2, Pose2) {
        let mut drift = Drift::new(cfg).unwrap();
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
                let at_robot = Pose2::new(0.0, line.y - line.x * line.yaw.tan(), line.yaw);
                drift.observe(t, &nav, at_robot, 0.0);
            }
        }
        (drift, truth, nav)
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
        let (drift, _, _) = drive(on(), -0.16, 0.0, 6.0);
        // After 3 m (12 baselines at gain 0.5) the estimate is within 1 % of the slide.
        assert!((drift.lateral_per_m() + 0.16).abs() < 0.0016, "{}", drift.lateral_per_m());
        assert!(drift.yaw_rate_radps().abs() < 1e-9, "{}", drift.yaw_rate_radps());
    }

    #[test]
    fn a_gyro_bias_is_learned_from_the_rows() {
        let cfg = DriftConfig { yaw_gain: 0.3, ..on() };
        let (drift, _, _) = drive(cfg, 0.0, 0.025, 10.0);
        // 20 baselines at gain 0.3, each seeing the rotation of the last 0.5 s: within 5 %.
        assert!((drift.yaw_rate_radps() + 0.025).abs() < 0.00125, "{}", drift.yaw_rate_radps());
    }

    #[test]
    fn rows_still_in_odom_teach_nothing() {
        let cfg = DriftConfig { yaw_gain: 0.3, ..on() };
        let (drift, _, _) = drive(cfg, 0.0, 0.0, 5.0);
        assert_eq!((drift.lateral_per_m(), drift.yaw_rate_radps()), (0.0, 0.0));
    }

    #[test]
    fn a_jump_of_the_line_is_a_new_lock_not_drift() {
        let mut drift = Drift::new(on()).unwrap();
        let mut odometer = 0.0;
        let mut at = |t: f64, y: f64, d: &mut Drift| {
            odometer += 0.3;
            let nav = d.correct(t, Pose2::new(odometer, 0.0, 0.0));
            d.observe(t, &nav, Pose2::new(0.0, y, 0.0), 0.0);
        };
        at(0.0, 0.0, &mut drift);
        // The neighbouring lane, 0.75 m over, for one scan.
        at(0.6, 0.75, &mut drift);
        at(1.2, 0.75, &mut drift);
        assert_eq!(drift.lateral_per_m(), 0.0);
    }

    #[test]
    fn an_absurd_config_is_refused_by_name() {
        let cfg = DriftConfig { baseline_m: 0.0, ..DriftConfig::default() };
        assert!(Drift::new(cfg).unwrap_err().to_string().contains("drift.baseline_m"));
    }
}
