//! A witness of wheel slip: how much less the body turns than its wheels say.
//!
//! A skid-steer on wet soil slips: its wheels overcount the distance, and they overcount its turns
//! by the same ratio (the body turns at `(1 - s)` times the wheels' `(v_r - v_l) / B_eff`). The gyro
//! sees the body's turn. So while the controller steers, the gyro's yaw rate regressed on the
//! wheels' gives `1 - s`. Both are centred over the window first: a gyro bias, or a slow yaw
//! disturbance the wheels correct (a rut), is a common offset, not a ratio. The read counts only
//! when the wheels' yaw rate varied enough over the window to tell a ratio from noise; while the
//! robot drives straight and steady there is none, and the last read is held for a stretch of
//! driving (`hold_m`), then forgotten.
//!
//! Measured in the closed loop (`docs/faults.md`, session 50): with the defaults, fault-free following
//! mostly reads 0.03-0.1, but the simulated robot's yaw disturbance lifts a read to 0.2-0.3 now and
//! then; wet patches of 0.31-0.36 slip read 0.3-0.45 once the robot steered (and 0.18-0.19 before).
//! This is a witness, not an estimate for the odometry: it tells the navigator that the wheels slip,
//! so that it can be stricter where slides happen. Noise in the wheels' yaw rate flattens the slope
//! (reads more slip than there is): `min_excitation_radps` must stay well above that noise.

use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, check_range};

/// Longest time one sample counts for, s: the window measures driving time, not gaps.
const MAX_SAMPLE_S: f64 = 0.1;

/// The slip witness's window and thresholds (`ekf.slip`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SlipWitnessConfig {
    /// Time constant of the exponentially weighted window, s. Default 0.5: the controller's
    /// corrections last about a second, and wet soil starts within a wheel's length.
    pub window_s: f64,
    /// Least standard deviation of the wheels' yaw rate over the window for a read, rad/s. Default
    /// 0.04: the simulated robot's yaw disturbance (0.01 rad/s, correlated over 1 s) blurs reads of
    /// weaker steering (offline, one-second windows at 0.01-0.02 read dry soil anywhere in 0-1).
    pub min_excitation_radps: f64,
    /// Slowest forward speed that counts, m/s. Default 0.2: starting, stopping and turning on the
    /// spot scrub the tyres in ways a slip ratio does not describe.
    pub min_speed_mps: f64,
    /// Fastest wheel yaw rate that counts, rad/s. Default 0.5 (the headland pivots are faster).
    pub max_yaw_rate_radps: f64,
    /// Driving after the last read for which it is held, m. Default 3: about one slip patch's length
    /// of the soak; a patch that lasts is read again whenever the robot steers.
    pub hold_m: f64,
}

impl Default for SlipWitnessConfig {
    fn default() -> Self {
        Self {
            window_s: 0.5,
            min_excitation_radps: 0.04,
            min_speed_mps: 0.2,
            max_yaw_rate_radps: 0.5,
            hold_m: 3.0,
        }
    }
}

impl SlipWitnessConfig {
    /// Checks every field, naming the first bad one (`ekf.slip.<field>`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("ekf.slip.window_s", self.window_s, 0.05, 60.0)?;
        check_range("ekf.slip.min_excitation_radps", self.min_excitation_radps, 1e-4, 1.0)?;
        check_range("ekf.slip.min_speed_mps", self.min_speed_mps, 0.0, 5.0)?;
        check_range("ekf.slip.max_yaw_rate_radps", self.max_yaw_rate_radps, 0.01, 10.0)?;
        check_range("ekf.slip.hold_m", self.hold_m, 0.0, 1000.0)
    }
}

/// The witness's running state: exponentially weighted means and (co)variances of the wheels' and
/// the gyro's yaw rates, rad/s and (rad/s)².
#[derive(Debug, Clone, Default)]
pub struct SlipWitness {
    cfg: SlipWitnessConfig,
    last_s: Option<f64>,
    /// Driving time in the window so far, s (a read needs one full window).
    filled_s: f64,
    mean_wheels: f64,
    mean_gyro: f64,
    var_wheels: f64,
    cov: f64,
    /// The latest read slip ratio and the driving since, m.
    read: Option<(f64, f64)>,
}

impl SlipWitness {
    /// A witness with no read; an invalid `cfg` is refused, naming the field.
    pub fn new(cfg: SlipWitnessConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        Ok(Self { cfg, ..Self::default() })
    }

    /// Adds one pair of samples at `stamp_s`: the wheels' forward speed `v` (m/s) and yaw rate
    /// (rad/s), and the gyro's yaw rate (rad/s, bias included). Stamps that do not increase are
    /// skipped; a sample outside the speed and yaw-rate bounds restarts the window.
    pub fn add(&mut self, stamp_s: f64, v: f64, wheels_radps: f64, gyro_radps: f64) {
        let Some(dt) = self.step(stamp_s) else { return };
        if let Some((_, driven)) = self.read.as_mut() {
            *driven += v.abs() * dt;
            if *driven > self.cfg.hold_m {
                self.read = None;
            }
        }
        if v < self.cfg.min_speed_mps || wheels_radps.abs() > self.cfg.max_yaw_rate_radps {
            self.filled_s = 0.0;
            return;
        }
        if self.filled_s == 0.0 {
            (self.mean_wheels, self.mean_gyro, self.var_wheels, self.cov) =
                (wheels_radps, gyro_radps, 0.0, 0.0);
        }
        let a = 1.0 - (-dt / self.cfg.window_s).exp();
        self.mean_wheels += a * (wheels_radps - self.mean_wheels);
        self.mean_gyro += a * (gyro_radps - self.mean_gyro);
        let (dw, dg) = (wheels_radps - self.mean_wheels, gyro_radps - self.mean_gyro);
        self.var_wheels += a * (dw * dw - self.var_wheels);
        self.cov += a * (dw * dg - self.cov);
        self.filled_s += dt;
        if self.filled_s >= self.cfg.window_s && self.var_wheels >= self.cfg.min_excitation_radps.powi(2) {
            self.read = Some((1.0 - self.cov / self.var_wheels, 0.0));
        }
    }

    /// The time since the previous sample, clamped (`None` for the first sample or a stamp that does
    /// not increase).
    fn step(&mut self, stamp_s: f64) -> Option<f64> {
        if !stamp_s.is_finite() || self.last_s.is_some_and(|t| stamp_s <= t) {
            return None;
        }
        let dt = self.last_s.map(|t| (stamp_s - t).min(MAX_SAMPLE_S));
        self.last_s = Some(stamp_s);
        dt
    }

    /// The slip ratio last read (1 minus the body's turn over the wheels'), while held; `None` before
    /// the first read or after `hold_m` of driving without one.
    pub fn slip(&self) -> Option<f64> {
        self.read.map(|(s, _)| s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The wheels steer as a slow sine (amplitude 0.1 rad/s, period 3 s), the body turns at `1 - slip`
    /// of it plus a constant gyro bias; 50 Hz at 0.5 m/s for `seconds`.
    fn drive(w: &mut SlipWitness, slip: f64, bias: f64, from_s: f64, seconds: f64) {
        let n = (seconds * 50.0) as usize;
        for i in 0..n {
            let t = from_s + i as f64 * 0.02;
            let wheels = 0.1 * (t * std::f64::consts::TAU / 3.0).sin();
            w.add(t, 0.5, wheels, (1.0 - slip) * wheels + bias);
        }
    }

    #[test]
    fn reads_the_slip_ratio_of_a_steering_robot_whatever_the_gyro_bias() {
        let mut w = SlipWitness::new(SlipWitnessConfig::default()).unwrap();
        drive(&mut w, 0.3, 0.02, 0.0, 4.0);
        let s = w.slip().expect("a steering robot is read");
        assert!((s - 0.3).abs() < 0.02, "read {s}");
        let mut dry = SlipWitness::new(SlipWitnessConfig::default()).unwrap();
        drive(&mut dry, 0.03, -0.01, 0.0, 4.0);
        assert!((dry.slip().unwrap() - 0.03).abs() < 0.02);
    }

    #[test]
    fn a_robot_driving_straight_gives_no_read_and_a_read_is_forgotten_after_the_hold() {
        let mut w = SlipWitness::new(SlipWitnessConfig::default()).unwrap();
        for i in 0..500 {
            let t = i as f64 * 0.02;
            w.add(t, 0.5, 0.001, 0.3);
        }
        assert_eq!(w.slip(), None, "no steering, no read");
        drive(&mut w, 0.3, 0.0, 10.0, 4.0);
        assert!(w.slip().is_some());
        // 3 m at 0.5 m/s is 6 s straight; past it the read is gone.
        for i in 0..350 {
            w.add(14.0 + i as f64 * 0.02, 0.5, 0.0, 0.0);
        }
        assert_eq!(w.slip(), None);
    }

    #[test]
    fn an_absurd_window_is_refused_by_name() {
        let err = SlipWitness::new(SlipWitnessConfig { window_s: f64::NAN, ..SlipWitnessConfig::default() });
        assert!(err.unwrap_err().to_string().contains("ekf.slip.window_s"));
    }

    #[test]
    fn stamps_that_go_back_and_slow_driving_are_not_read() {
        let mut w = SlipWitness::new(SlipWitnessConfig::default()).unwrap();
        drive(&mut w, 0.3, 0.0, 0.0, 4.0);
        let before = w.slip();
        // Samples from the past are skipped: the read stays as it was.
        w.add(1.0, 0.5, 0.4, -0.4);
        w.add(f64::NAN, 0.5, 0.4, -0.4);
        assert_eq!(w.slip(), before);
        let mut slow = SlipWitness::new(SlipWitnessConfig::default()).unwrap();
        for i in 0..200 {
            let t = i as f64 * 0.02;
            slow.add(t, 0.1, 0.1 * (t * 2.0).sin(), 0.0);
        }
        assert_eq!(slow.slip(), None, "under min_speed_mps nothing is read");
    }
}
