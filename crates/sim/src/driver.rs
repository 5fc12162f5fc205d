//! A human-like driver for detection runs (paper Sec. V-A: "a human operator controls the robot"): it
//! sees the TRUE field and follows the centre line of its lane with a smooth, seeded wander of the
//! lateral offset (±`wander_m`), which brings heading deviations of a few degrees with it.
//!
//! ```
//! use croprow_sim::{Driver, DriverConfig, Field, FieldConfig};
//! use croprow_core::Pose2;
//! let field = Field::generate(&FieldConfig { length_m: 10.0, ..FieldConfig::default() }, 1).unwrap();
//! let mut driver = Driver::new(&DriverConfig::default(), 7, 1).unwrap();
//! let cmd = driver.command(0.0, &Pose2::new(1.0, field.lane_y(7, 1.0), 0.0), &field);
//! assert!(cmd.v > 0.0);
//! ```

use std::f64::consts::TAU;

use croprow_core::error::check_range;
use croprow_core::{ConfigError, Pose2, Twist2};
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};

use crate::field::Field;

/// How the human-like driver drives.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct DriverConfig {
    /// Forward speed, m/s. Default 0.8 (the sample recording drives at 0.5-1.0 m/s).
    pub speed_m_s: f64,
    /// Peak lateral wander about the lane centre line, m. Default 0.1 (issue 3).
    pub wander_m: f64,
    /// Typical period of the wander, s. Default 10.
    pub wander_period_s: f64,
    /// Look-ahead distance of the pure-pursuit steering, m. Default 2.
    pub lookahead_m: f64,
    /// Yaw-rate limit, rad/s. Default 0.5.
    pub max_yaw_rate_rad_s: f64,
    /// The driver stops this far before the end of the rows, m. Default 1.
    pub stop_before_end_m: f64,
}

impl Default for DriverConfig {
    fn default() -> Self {
        Self {
            speed_m_s: 0.8,
            wander_m: 0.1,
            wander_period_s: 10.0,
            lookahead_m: 2.0,
            max_yaw_rate_rad_s: 0.5,
            stop_before_end_m: 1.0,
        }
    }
}

impl DriverConfig {
    /// Checks every field, naming the first bad one (`driver.speed_m_s`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("driver.speed_m_s", self.speed_m_s, 0.05, 3.0)?;
        check_range("driver.wander_m", self.wander_m, 0.0, 0.3)?;
        check_range("driver.wander_period_s", self.wander_period_s, 1.0, 600.0)?;
        check_range("driver.lookahead_m", self.lookahead_m, 0.3, 20.0)?;
        check_range("driver.max_yaw_rate_rad_s", self.max_yaw_rate_rad_s, 0.01, 3.0)?;
        check_range("driver.stop_before_end_m", self.stop_before_end_m, -100.0, 100.0)?;
        Ok(())
    }
}

/// The driver: a pure-pursuit steering law on the wandering target line.
#[derive(Debug, Clone)]
pub struct Driver {
    config: DriverConfig,
    lane: u32,
    /// Two sinusoids (angular frequency, phase, weight) whose sum, scaled to `wander_m`, is the offset.
    waves: [(f64, f64, f64); 2],
}

impl Driver {
    /// A driver for `lane` (between rows `lane` and `lane + 1`); the seed picks its wander.
    pub fn new(config: &DriverConfig, lane: u32, seed: u64) -> Result<Self, ConfigError> {
        config.validate()?;
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let p = config.wander_period_s;
        let mut wave = |weight: f64, scale: f64| {
            let period = p * scale * rng.random_range(0.7..1.3);
            (TAU / period, rng.random_range(0.0..TAU), weight)
        };
        let waves = [wave(0.7, 1.0), wave(0.3, 0.37)];
        Ok(Self { config: config.clone(), lane, waves })
    }

    /// The lane it drives in.
    pub fn lane(&self) -> u32 {
        self.lane
    }

    /// The lateral offset it aims at, at time `t_s`, m (left positive, |offset| ≤ `wander_m`).
    pub fn target_offset_m(&self, t_s: f64) -> f64 {
        let s: f64 = self.waves.iter().map(|(w, ph, k)| k * (w * t_s + ph).sin()).sum();
        self.config.wander_m * s
    }

    /// The command for a robot at true pose `pose` at time `t_s`. Zero once past the end of the rows.
    pub fn command(&mut self, t_s: f64, pose: &Pose2, field: &Field) -> Twist2 {
        let c = &self.config;
        if !pose.is_finite() || pose.x > field.config().length_m - c.stop_before_end_m {
            return Twist2::ZERO;
        }
        // Target: the lane centre line shifted by the wander, one look-ahead ahead along the rows.
        let xa = pose.x + c.lookahead_m * field.row_heading(pose.x).cos();
        let th = field.row_heading(xa);
        let off = self.target_offset_m(t_s + c.lookahead_m / c.speed_m_s);
        let (tx, ty) = (xa - off * th.sin(), field.lane_y(self.lane, xa) + off * th.cos());
        let (bx, by) = pose.inverse_transform_point(tx, ty);
        let d2 = bx * bx + by * by;
        let kappa = if d2 > 1e-9 { 2.0 * by / d2 } else { 0.0 };
        let omega = (c.speed_m_s * kappa).clamp(-c.max_yaw_rate_rad_s, c.max_yaw_rate_rad_s);
        Twist2::new(c.speed_m_s, omega)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wander_stays_within_its_bound_and_depends_on_the_seed() {
        let a = Driver::new(&DriverConfig::default(), 7, 1).unwrap();
        let b = Driver::new(&DriverConfig::default(), 7, 2).unwrap();
        let mut peak: f64 = 0.0;
        for k in 0..10_000 {
            let t = k as f64 * 0.05;
            peak = peak.max(a.target_offset_m(t).abs());
        }
        assert!(peak <= 0.1 + 1e-12 && peak > 0.05, "{peak}");
        assert_ne!(a.target_offset_m(3.0), b.target_offset_m(3.0));
    }

    #[test]
    fn absurd_speed_is_refused_by_name() {
        let e = Driver::new(&DriverConfig { speed_m_s: -1.0, ..DriverConfig::default() }, 7, 0).unwrap_err();
        assert!(e.to_string().contains("driver.speed_m_s"));
    }
}
