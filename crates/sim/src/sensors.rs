//! Proprioceptive sensors: wheel encoders (as the Amiga reports them, a body twist from the wheel speeds)
//! and an IMU (gyro z with bias and noise, planar accelerations). They turn the robot's TRUE motion into
//! the stamped measurements an EKF fuses (what `robot_localization` gets on the paper's robot).
//!
//! With `perfect_odometry = true` both report the true body motion exactly, to debug everything
//! downstream of odometry.

use croprow_core::error::check_range;
use croprow_core::{ConfigError, Twist2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};

use crate::faults::GyroBiasStep;
use crate::robot::Robot;

/// Parameters of the encoders and the IMU.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SensorConfig {
    /// Report the true body motion with no error at all. Default false.
    pub perfect_odometry: bool,
    /// Wheel odometry rate, Hz. Default 50 (the sample recording's odometry rate).
    pub wheel_rate_hz: f64,
    /// Relative scale error of the encoders (wrong wheel radius): reported = true·(1 + this). Default 0.02.
    pub encoder_scale_error: f64,
    /// Standard deviation of each wheel speed reading, m/s. Default 0.01.
    pub encoder_noise_m_s: f64,
    /// IMU rate, Hz. Default 100 (issue 3).
    pub imu_rate_hz: f64,
    /// Constant gyro z bias, rad/s. Default 0.005 (≈0.3°/s, an uncalibrated MEMS gyro).
    pub gyro_bias_rad_s: f64,
    /// Standard deviation of each gyro z reading, rad/s. Default 0.003.
    pub gyro_noise_rad_s: f64,
    /// Constant accelerometer bias on each axis, m/s². Default 0.02 (0.12° of roll and of pitch).
    pub accel_bias_m_s2: f64,
    /// Standard deviation of each accelerometer reading, m/s². Default 0.05.
    pub accel_noise_m_s2: f64,
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self {
            perfect_odometry: false,
            wheel_rate_hz: 50.0,
            encoder_scale_error: 0.02,
            encoder_noise_m_s: 0.01,
            imu_rate_hz: 100.0,
            gyro_bias_rad_s: 0.005,
            gyro_noise_rad_s: 0.003,
            accel_bias_m_s2: 0.02,
            accel_noise_m_s2: 0.05,
        }
    }
}

impl SensorConfig {
    /// Checks every field, naming the first bad one (`sensors.imu_rate_hz`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("sensors.wheel_rate_hz", self.wheel_rate_hz, 1.0, 1000.0)?;
        check_range("sensors.encoder_scale_error", self.encoder_scale_error, -0.5, 0.5)?;
        check_range("sensors.encoder_noise_m_s", self.encoder_noise_m_s, 0.0, 1.0)?;
        check_range("sensors.imu_rate_hz", self.imu_rate_hz, 1.0, 1000.0)?;
        check_range("sensors.gyro_bias_rad_s", self.gyro_bias_rad_s, -1.0, 1.0)?;
        check_range("sensors.gyro_noise_rad_s", self.gyro_noise_rad_s, 0.0, 1.0)?;
        check_range("sensors.accel_bias_m_s2", self.accel_bias_m_s2, -5.0, 5.0)?;
        check_range("sensors.accel_noise_m_s2", self.accel_noise_m_s2, 0.0, 5.0)?;
        Ok(())
    }
}

/// A wheel odometry message: the body twist the drive computes from its encoders.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct WheelOdometry {
    /// Measurement time, s.
    pub stamp_s: f64,
    /// Body twist in `base_link`: `v = (l + r)/2`, `ω = (r - l)/B_eff`.
    pub twist: Twist2,
    /// Left wheel surface speed, m/s.
    pub left_m_s: f64,
    /// Right wheel surface speed, m/s.
    pub right_m_s: f64,
}

/// An IMU sample in `base_link` axes (the IMU is assumed aligned with the body).
///
/// The accelerometer reads the specific force, as a real one does (REP-145): the body's acceleration
/// minus gravity, so +9.81 m/s² on z when level and still, and on uneven ground gravity's share on x
/// and y tells the robot's roll and pitch. The body's vertical acceleration over the relief (under
/// 0.02 m/s² on the soak's fields at 0.5 m/s) is left out.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct ImuSample {
    /// Measurement time, s.
    pub stamp_s: f64,
    /// Yaw rate about z, rad/s.
    pub gyro_z_rad_s: f64,
    /// Specific force along x (forward), m/s².
    pub accel_x_m_s2: f64,
    /// Specific force along y (left), m/s².
    pub accel_y_m_s2: f64,
    /// Specific force along z (up), m/s².
    pub accel_z_m_s2: f64,
}

/// Standard gravity, m/s².
const GRAVITY_M_S2: f64 = 9.80665;

/// The specific force in body axes of a body at `roll`, `pitch` (rad) accelerating by `accel`
/// (m/s², forward and left along the ground).
fn specific_force(roll_rad: f64, pitch_rad: f64, accel: (f64, f64)) -> [f64; 3] {
    let body = nalgebra::Rotation3::from_euler_angles(roll_rad, pitch_rad, 0.0);
    let f = body.inverse() * nalgebra::Vector3::new(accel.0, accel.1, GRAVITY_M_S2);
    [f.x, f.y, f.z]
}

/// The sensor models and their schedules.
#[derive(Debug, Clone)]
pub struct Sensors {
    config: SensorConfig,
    effective_track_m: f64,
    next_wheel_s: f64,
    next_imu_s: f64,
    /// `faults.gyro_bias_step`, and whether the robot has passed it (the step stays).
    bias_step: GyroBiasStep,
    bias_stepped: bool,
    rng: ChaCha8Rng,
    /// The accelerometer's z noise, on its own stream: the other readings' noise is as it was before
    /// the z axis was modelled.
    z_rng: ChaCha8Rng,
}

impl Sensors {
    /// Sensors for a robot whose drive turns with `effective_track_m`; first samples at `start_s`.
    pub fn new(
        config: &SensorConfig,
        effective_track_m: f64,
        start_s: f64,
        seed: u64,
    ) -> Result<Self, ConfigError> {
        config.validate()?;
        check_range("robot.effective_track_m", effective_track_m, 0.05, 20.0)?;
        Ok(Self {
            config: config.clone(),
            effective_track_m,
            next_wheel_s: start_s,
            next_imu_s: start_s,
            bias_step: GyroBiasStep::default(),
            bias_stepped: false,
            rng: ChaCha8Rng::seed_from_u64(seed),
            z_rng: {
                let mut r = ChaCha8Rng::seed_from_u64(seed);
                r.set_stream(1);
                r
            },
        })
    }

    /// Sets a gyro bias step (`faults.gyro_bias_step`): once the robot's true x passes `at_x_m` the
    /// gyro reads `step_rad_s` more, for good. Perfect odometry ignores it.
    pub fn set_gyro_bias_step(&mut self, step: GyroBiasStep) {
        self.bias_step = step;
    }

    /// The configuration.
    pub fn config(&self) -> &SensorConfig {
        &self.config
    }

    fn noise(&mut self, sigma: f64) -> f64 {
        let n: f64 = StandardNormal.sample(&mut self.rng);
        sigma * n
    }

    /// Wheel odometry at `now_s` if one is due (the schedule tolerates a step that is not a multiple
    /// of the period: a sample is emitted at the first step at or after its due time).
    pub fn wheel(&mut self, now_s: f64, robot: &Robot) -> Option<WheelOdometry> {
        if now_s + 1e-9 < self.next_wheel_s {
            return None;
        }
        self.next_wheel_s += 1.0 / self.config.wheel_rate_hz;
        if self.config.perfect_odometry {
            let t = robot.twist();
            let half = 0.5 * t.omega * self.effective_track_m;
            return Some(WheelOdometry {
                stamp_s: now_s,
                twist: t,
                left_m_s: t.v - half,
                right_m_s: t.v + half,
            });
        }
        let (l, r) = robot.wheel_speeds();
        let k = 1.0 + self.config.encoder_scale_error;
        let sigma = self.config.encoder_noise_m_s;
        let (l, r) = (k * l + self.noise(sigma), k * r + self.noise(sigma));
        let twist = Twist2::new(0.5 * (l + r), (r - l) / self.effective_track_m);
        Some(WheelOdometry { stamp_s: now_s, twist, left_m_s: l, right_m_s: r })
    }

    /// An IMU sample at `now_s` if one is due.
    pub fn imu(&mut self, now_s: f64, robot: &Robot) -> Option<ImuSample> {
        if now_s + 1e-9 < self.next_imu_s {
            return None;
        }
        self.next_imu_s += 1.0 / self.config.imu_rate_hz;
        let omega = robot.twist().omega;
        let body = robot.body();
        let [fx, fy, fz] = specific_force(body.roll_rad, body.pitch_rad, robot.acceleration());
        if self.config.perfect_odometry {
            return Some(ImuSample {
                stamp_s: now_s,
                gyro_z_rad_s: omega,
                accel_x_m_s2: fx,
                accel_y_m_s2: fy,
                accel_z_m_s2: fz,
            });
        }
        self.bias_stepped |= self.bias_step.enabled && robot.pose().x >= self.bias_step.at_x_m;
        let bias =
            self.config.gyro_bias_rad_s + if self.bias_stepped { self.bias_step.step_rad_s } else { 0.0 };
        let c = self.config.clone();
        let z_noise: f64 = StandardNormal.sample(&mut self.z_rng);
        Some(ImuSample {
            stamp_s: now_s,
            gyro_z_rad_s: omega + bias + self.noise(c.gyro_noise_rad_s),
            accel_x_m_s2: fx + c.accel_bias_m_s2 + self.noise(c.accel_noise_m_s2),
            accel_y_m_s2: fy + c.accel_bias_m_s2 + self.noise(c.accel_noise_m_s2),
            accel_z_m_s2: fz + c.accel_bias_m_s2 + c.accel_noise_m_s2 * z_noise,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::{Field, FieldConfig};
    use crate::robot::RobotConfig;
    use croprow_core::Pose2;

    fn run(cfg: &SensorConfig, cmd: Twist2) -> (Vec<WheelOdometry>, Vec<ImuSample>, Vec<Twist2>) {
        let f =
            Field::generate(&FieldConfig { rows: 1, length_m: 1.0, ..FieldConfig::default() }, 0).unwrap();
        let rc = RobotConfig::default();
        let mut robot = Robot::new(&rc, Pose2::default(), 1).unwrap();
        let mut s = Sensors::new(cfg, rc.effective_track_m(), 0.01, 2).unwrap();
        let (mut w, mut i, mut truth) = (Vec::new(), Vec::new(), Vec::new());
        for k in 1..=2000 {
            robot.step(cmd, 0.01, &f).unwrap();
            let now = k as f64 * 0.01;
            w.extend(s.wheel(now, &robot));
            if let Some(m) = s.imu(now, &robot) {
                i.push(m);
                truth.push(robot.twist());
            }
        }
        (w, i, truth)
    }

    #[test]
    fn rates_follow_the_configuration() {
        let (w, i, _) = run(&SensorConfig::default(), Twist2::new(1.0, 0.0));
        // 20 s at 50 Hz and 100 Hz.
        assert_eq!(w.len(), 1000);
        assert_eq!(i.len(), 2000);
        assert!(w.windows(2).all(|p| (p[1].stamp_s - p[0].stamp_s - 0.02).abs() < 1e-9));
    }

    #[test]
    fn gyro_shows_its_bias_and_encoders_their_scale_error() {
        let cfg =
            SensorConfig { gyro_bias_rad_s: 0.02, encoder_scale_error: 0.05, ..SensorConfig::default() };
        let (w, i, truth) = run(&cfg, Twist2::new(1.0, 0.0));
        let bias: f64 =
            i.iter().zip(&truth).map(|(m, t)| m.gyro_z_rad_s - t.omega).sum::<f64>() / i.len() as f64;
        // Mean of 2000 samples of σ = 0.003: standard error 7e-5.
        assert!((bias - 0.02).abs() < 5e-4, "{bias}");
        // Steady state: wheels at 1 m/s read 1.05 m/s (encoder σ 0.01/√2 per twist: tolerance 0.01).
        let late: Vec<_> = w.iter().skip(500).collect();
        let v = late.iter().map(|m| m.twist.v).sum::<f64>() / late.len() as f64;
        assert!((v - 1.05).abs() < 0.005, "{v}");
    }

    #[test]
    fn a_gyro_bias_step_adds_to_the_bias_once_passed() {
        let f =
            Field::generate(&FieldConfig { rows: 1, length_m: 1.0, ..FieldConfig::default() }, 0).unwrap();
        let rc = RobotConfig::default();
        let mut robot = Robot::new(&rc, Pose2::default(), 1).unwrap();
        let cfg = SensorConfig { gyro_noise_rad_s: 0.0, ..SensorConfig::default() };
        let mut s = Sensors::new(&cfg, rc.effective_track_m(), 0.01, 2).unwrap();
        s.set_gyro_bias_step(GyroBiasStep { enabled: true, at_x_m: 2.0, step_rad_s: 0.02 });
        let mut errors = Vec::new();
        for k in 1..=1000 {
            // Forward 1 m/s for 5 s, then back for 5 s: the step, once passed, stays.
            let v = if k <= 500 { 1.0 } else { -1.0 };
            robot.step(Twist2::new(v, 0.0), 0.01, &f).unwrap();
            let m = s.imu(k as f64 * 0.01, &robot).unwrap();
            errors.push((robot.pose().x, m.gyro_z_rad_s - robot.twist().omega));
        }
        // Noise-free: the error is the bias exactly (tolerance 1e-12 rad/s).
        let before = errors.iter().take_while(|(x, _)| *x < 2.0);
        assert!(before.clone().count() > 100 && before.clone().all(|(_, e)| (e - 0.005).abs() < 1e-12));
        let after = errors.iter().skip_while(|(x, _)| *x < 2.0);
        assert!(after.clone().count() > 500 && after.clone().all(|(_, e)| (e - 0.025).abs() < 1e-12));
    }

    #[test]
    fn the_accelerometer_reads_gravity_square_to_the_ground_the_robot_stands_on() {
        // Still on a slope, the specific force is gravity's, in body axes: roll and pitch read from
        // it are the body's (the filter that does so is croprow_core::odometry::AttitudeFilter).
        let (roll, pitch) = (0.03, -0.02);
        let [fx, fy, fz] = specific_force(roll, pitch, (0.0, 0.0));
        assert!((fy.atan2(fz) - roll).abs() < 1e-12 && ((-fx).atan2(fy.hypot(fz)) - pitch).abs() < 1e-12);
        assert!((fx.hypot(fy).hypot(fz) - GRAVITY_M_S2).abs() < 1e-12);
        // Level and turning: only the centripetal acceleration shows, on y.
        assert_eq!(specific_force(0.0, 0.0, (0.0, 0.2)), [0.0, 0.2, GRAVITY_M_S2]);
        // Noise-free on flat ground, the sensor reads gravity on z.
        let cfg = SensorConfig { accel_noise_m_s2: 0.0, accel_bias_m_s2: 0.0, ..SensorConfig::default() };
        let (_, i, _) = run(&cfg, Twist2::new(1.0, 0.0));
        assert!(i.iter().all(|m| (m.accel_z_m_s2 - GRAVITY_M_S2).abs() < 1e-9), "{:?}", i[0]);
    }

    #[test]
    fn perfect_odometry_reports_the_truth() {
        let cfg = SensorConfig { perfect_odometry: true, ..SensorConfig::default() };
        let (w, i, truth) = run(&cfg, Twist2::new(0.8, 0.2));
        for (m, t) in i.iter().zip(&truth) {
            assert_eq!(m.gyro_z_rad_s, t.omega);
        }
        // The true body speed includes slip: the perfect odometry reports that, not the wheel speed.
        for m in &w {
            let k = i.iter().position(|s| s.stamp_s == m.stamp_s).unwrap();
            assert_eq!(m.twist, truth[k]);
        }
    }

    #[test]
    fn absurd_sensor_parameters_name_the_field() {
        let cfg = SensorConfig { imu_rate_hz: 0.0, ..SensorConfig::default() };
        let e = Sensors::new(&cfg, 2.0, 0.0, 0).unwrap_err().to_string();
        assert!(e.contains("sensors.imu_rate_hz"), "{e}");
    }
}
