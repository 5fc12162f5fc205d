//! Motion deskew (runs inside the preprocessing pass, before levelling and the canopy split): a
//! spinning LiDAR fires its columns over one revolution, and a driver stamps the cloud at the END of
//! the sweep while giving every point in the sensor frame of its own firing instant. The detector places
//! a scan with the odometry pose at its stamp, so a point fired `τ` seconds earlier is placed where the
//! sensor is at the stamp, not where it was: while the robot turns at ω the rows ahead read rotated by
//! about ω·τ (0.2 rad/s × 50 ms = 0.01 rad, 4 cm at 4 m), which the map's stored centroids read as a
//! slide (docs/faults.md, "Contacts with no fault").
//!
//! Each point's firing time comes from its azimuth in the sensor frame (columns fired clockwise seen
//! from above, from `deskew_sweep_start_deg`, over `deskew_period_s`); the point is then moved from
//! `base_link` at its firing time to `base_link` at the stamp with the body twist (v, ω in `base_link`,
//! planar, constant over the sweep). Over one sweep ωτ ≤ 0.3 rad/s × 0.1 s = 0.03 rad, so the rotation
//! is taken to first order (error ≤ (ωτ)²/2 · r = 2 mm at 4 m) and the arc's lateral chord v·ω·τ²/2
//! (under 1 mm) is dropped: no trig per point.
//!
//! ```text
//! p(stamp) = R(ωτ) · p(τ) + (vτ, 0)   ≈   (x + τ(v − ω·y),  y + τ·ω·x,  z)      τ ∈ (−period, 0]
//! ```

use std::f32::consts::{FRAC_PI_2, PI, TAU};

use crate::geometry::{Point3, Twist2};

use super::config::DetectorConfig;

/// The per-scan deskew: the twist and the sweep's timing, ready for the per-point loop.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Deskew {
    v_mps: f32,
    omega_rps: f32,
    period_s: f32,
    /// Sweep start azimuth in turns (CCW from the sensor's +x), in [0, 1).
    start_turns: f32,
}

impl Deskew {
    /// The deskew of a scan taken with body twist `twist`, or `None` when there is nothing to undo:
    /// deskew off, twist unknown or non-finite (that scan is then used as stamped, documented on
    /// [`super::Scan::twist`]), or the robot standing still.
    pub(crate) fn new(twist: Option<Twist2>, config: &DetectorConfig) -> Option<Self> {
        Self::of_twist(twist.filter(|_| config.deskew), config)
    }

    /// As [`Deskew::new`], whether or not the detector deskews its points (canopy registration undoes
    /// the skew of the returns it registers either way: see `perception::register`).
    pub(crate) fn of_twist(twist: Option<Twist2>, config: &DetectorConfig) -> Option<Self> {
        let t = twist.filter(|t| t.is_finite() && (t.v != 0.0 || t.omega != 0.0))?;
        Some(Self {
            v_mps: t.v as f32,
            omega_rps: t.omega as f32,
            period_s: config.deskew_period_s as f32,
            start_turns: (config.deskew_sweep_start_deg / 360.0).rem_euclid(1.0) as f32,
        })
    }

    /// Time of firing of the return at sensor-frame `p` relative to the stamp, s (in (−period, 0]).
    pub(crate) fn offset_s(&self, p: &Point3) -> f32 {
        // Clockwise spin: the azimuth falls as time goes on, so the share of the sweep done when `p` was
        // fired is how far its azimuth lies clockwise of the start.
        // The difference lies in (−0.5, 1.5): one add or subtract wraps it, as `rem_euclid(1.0)` would,
        // without its call to `fmodf` per return.
        let mut done = self.start_turns - atan2_turns(p.y, p.x);
        if done < 0.0 {
            done += 1.0;
        } else if done >= 1.0 {
            done -= 1.0;
        }
        (done - 1.0) * self.period_s
    }

    /// `b`, the return at sensor-frame `p` placed in `base_link` at its firing time, moved to
    /// `base_link` at the stamp (first order in ωτ; see the module doc).
    pub(crate) fn apply(&self, p: &Point3, b: [f32; 3]) -> [f32; 3] {
        let tau = self.offset_s(p);
        let yaw = self.omega_rps * tau;
        [b[0] + self.v_mps * tau - yaw * b[1], b[1] + yaw * b[0], b[2]]
    }
}

/// `atan2(y, x)` in turns (radians / 2π), in [−0.5, 0.5], within 2e-4 rad (3 µs of a 0.1 s sweep): a minimax polynomial on
/// [0, 1] and the octant folds, about ten flops and no call into libm.
fn atan2_turns(y: f32, x: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let (lo, hi) = if ax < ay { (ax, ay) } else { (ay, ax) };
    if hi == 0.0 {
        return 0.0;
    }
    let a = lo / hi;
    let s = a * a;
    let mut r = ((-0.046_496_475 * s + 0.159_314_22) * s - 0.327_622_76) * s * a + a;
    if ay > ax {
        r = FRAC_PI_2 - r;
    }
    if x < 0.0 {
        r = PI - r;
    }
    if y < 0.0 {
        r = -r;
    }
    r / TAU
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::perception::Scan;

    /// A scan at t = 0 of a level robot, for the preprocessing alone.
    fn level(points: &[Point3]) -> Scan<'_> {
        Scan { stamp_s: 0.0, points, twist: None, attitude: None }
    }

    fn cfg() -> DetectorConfig {
        DetectorConfig { deskew: true, ..DetectorConfig::default() }
    }

    #[test]
    fn atan2_turns_matches_libm() {
        for i in 0..3600 {
            let a = (i as f32 * 0.1 - 180.0).to_radians();
            for r in [0.5_f32, 4.0] {
                let (y, x) = (r * a.sin(), r * a.cos());
                let e = (atan2_turns(y, x) - y.atan2(x) / TAU).abs();
                // ±0.5 turns are the same azimuth.
                assert!(e.min((e - 1.0).abs()) < 4e-5, "{i}: {e}");
            }
        }
        assert_eq!(atan2_turns(0.0, 0.0), 0.0);
    }

    #[test]
    fn firing_times_run_clockwise_from_behind() {
        let d = Deskew::new(Some(Twist2::new(0.5, 0.2)), &cfg()).unwrap();
        let at = |x, y| d.offset_s(&Point3::new(x, y, -1.0));
        // Behind: first (a whole period before the stamp); left a quarter in; ahead half; right last.
        assert!((at(-1.0, 1e-6) + 0.1).abs() < 1e-4, "{}", at(-1.0, 1e-6));
        assert!((at(0.0, 1.0) + 0.075).abs() < 1e-4);
        assert!((at(1.0, 0.0) + 0.05).abs() < 1e-4);
        assert!((at(0.0, -1.0) + 0.025).abs() < 1e-4);
        assert!(at(-1.0, -1e-6).abs() < 1e-4);
    }

    /// Rows at `ROWS_Y` (`base_link` at the stamp, which is `odom` here), 0.3 m tall, seen by the
    /// default mount (30° down) on a robot driving at `twist` over one sweep, each return in the
    /// sensor frame of its firing instant (the simulator's and a Velodyne driver's convention).
    const ROWS_Y: [f64; 4] = [-1.2, -0.4, 0.4, 1.2];

    fn turning_sweep(twist: Twist2) -> Vec<Point3> {
        let mount = crate::geometry::Mount::default();
        let (v, w) = (twist.v, twist.omega);
        let mut points = Vec::new();
        for y in ROWS_Y {
            for i in 0..150 {
                let world = nalgebra::Point3::new(1.0 + 0.02 * i as f64, y, 0.3);
                // The firing time depends on the azimuth seen at that time: a fixed point in a few steps.
                let mut tau = -0.05;
                let mut sensor = world;
                for _ in 0..6 {
                    // Exact constant-twist arc back from the stamp.
                    let yaw = w * tau;
                    let (bx, by) = if w == 0.0 {
                        (v * tau, 0.0)
                    } else {
                        (v / w * yaw.sin(), v / w * (1.0 - yaw.cos()))
                    };
                    let (dx, dy) = (world.x - bx, world.y - by);
                    let base = nalgebra::Point3::new(
                        dx * yaw.cos() + dy * yaw.sin(),
                        -dx * yaw.sin() + dy * yaw.cos(),
                        world.z,
                    );
                    sensor = mount.isometry().inverse_transform_point(&base);
                    let az = sensor.y.atan2(sensor.x) / std::f64::consts::TAU;
                    tau = -(1.0 - (0.5 - az).rem_euclid(1.0)) * 0.1;
                }
                points.push(Point3::new(sensor.x as f32, sensor.y as f32, sensor.z as f32));
            }
        }
        points
    }

    /// Largest distance of a cropped return from the row it belongs to, m.
    fn worst_off_row_m(cropped: &[[f32; 3]]) -> f64 {
        cropped
            .iter()
            .map(|p| ROWS_Y.iter().map(|y| (p[1] as f64 - y).abs()).fold(f64::INFINITY, f64::min))
            .fold(0.0, f64::max)
    }

    #[test]
    fn rows_seen_while_turning_are_straight_and_in_place_after_deskew() {
        use super::super::preprocess::{PlaneRule, Preprocessor};
        let mount = crate::geometry::Mount::default();
        let twist = Twist2::new(0.5, 0.3);
        let points = turning_sweep(twist);
        let config = cfg();
        let mut pre = Preprocessor::new(points.len(), &config);
        // As stamped: every return placed with the stamp's pose, the rows ahead read turned by about
        // ω·50 ms (1.5 cm at 1 m, 6 cm at 4 m) and the left rows (fired earlier) more than the right.
        pre.run(&level(&points), &mount, &config, PlaneRule::Centroid, None);
        let n = pre.cropped.len();
        assert!(n > 300, "{n}");
        let skewed = worst_off_row_m(&pre.cropped);
        assert!(skewed > 0.04, "{skewed}");
        pre.run(&level(&points), &mount, &config, PlaneRule::Centroid, Deskew::new(Some(twist), &config));
        assert_eq!(pre.cropped.len(), n);
        // Deskewed: on the rows within the first-order error (ωτ)²/2 · 4 m and the arc's chord, 3 mm.
        let deskewed = worst_off_row_m(&pre.cropped);
        assert!(deskewed < 0.003, "{deskewed}");
        // Driving straight needs no deskew across the rows: they stay in place either way.
        let straight = turning_sweep(Twist2::new(0.5, 0.0));
        pre.run(&level(&straight), &mount, &config, PlaneRule::Centroid, None);
        assert!(worst_off_row_m(&pre.cropped) < 1e-4);
    }

    #[test]
    fn nothing_to_undo_without_a_usable_twist() {
        let off = DetectorConfig { deskew: false, ..cfg() };
        assert!(Deskew::new(Some(Twist2::new(0.5, 0.2)), &off).is_none());
        assert!(Deskew::new(None, &cfg()).is_none());
        assert!(Deskew::new(Some(Twist2::new(f64::NAN, 0.2)), &cfg()).is_none());
        assert!(Deskew::new(Some(Twist2::new(0.5, f64::INFINITY)), &cfg()).is_none());
        assert!(Deskew::new(Some(Twist2::ZERO), &cfg()).is_none());
    }
}
