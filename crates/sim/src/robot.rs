//! An Amiga-like four-wheel skid-steer robot: velocity-controlled wheels with a first-order response,
//! speed and acceleration limits, longitudinal and lateral slip. It takes a `Twist2` command in
//! `base_link` and integrates the TRUE pose in the field frame (plus z, roll and pitch from the terrain).
//! What the robot believes about itself comes from [`crate::sensors`].
//!
//! Skid-steer kinematics: the wheel controller maps `(v, ω)` to side speeds `v ∓ ω·B_eff/2` with the
//! calibrated effective track `B_eff` (larger than the geometric track because the tyres scrub when
//! turning). The body then moves at `(1 - s)·(v_l + v_r)/2` and turns at `(1 - s)·(v_r - v_l)/B_eff`,
//! with `s` a slowly varying slip ratio, and slides sideways by `k_lat · v · ω` in turns.

use croprow_core::error::check_range;
use croprow_core::geometry::wrap_angle;
use croprow_core::{ConfigError, Pose2, Twist2};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, StandardNormal};
use serde::{Deserialize, Serialize};
use thiserror::Error;

use crate::faults::SlipPatch;
use crate::field::Field;
use crate::lidar::BodyPose;

/// Correlation time of the slip and yaw disturbances, s: soil changes over a few metres.
const DISTURBANCE_TAU_S: f64 = 1.0;
/// Forward speed at which a slip patch's lateral drift is its configured value, m/s.
const DRIFT_REFERENCE_SPEED_M_S: f64 = 0.5;

/// Parameters of the robot. Defaults: the paper's Amiga (Sec. III-A) with typical skid-steer slip.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct RobotConfig {
    /// Overall width, m. Default 1.8 (paper Sec. III-A).
    pub width_m: f64,
    /// Overall length, m. Default 1.2 (paper Sec. III-A).
    pub length_m: f64,
    /// Distance between left and right wheel centres, m. Default 1.524 (Amiga, 60 in).
    pub track_m: f64,
    /// Distance between front and rear axles, m. Default 1.219 (Amiga, 48 in).
    pub wheelbase_m: f64,
    /// Width of a tyre's contact patch, m. Default 0.15 (6-inch tyres).
    pub tire_width_m: f64,
    /// Length of a tyre's contact patch, m. Default 0.12.
    pub contact_length_m: f64,
    /// Effective track the wheel controller uses for turning, as a multiple of `track_m`. Default 1.3
    /// (tyre scrub makes a skid-steer turn as if its wheels were further apart).
    pub effective_track_factor: f64,
    /// First-order time constant of the wheel speed loop, s. Default 0.15.
    pub wheel_time_constant_s: f64,
    /// Wheel surface speed limit, m/s. Default 2.4 (5.5 mph, paper Sec. III-A).
    pub max_wheel_speed_m_s: f64,
    /// Wheel acceleration limit, m/s². Default 1.5.
    pub max_wheel_accel_m_s2: f64,
    /// Mean longitudinal slip ratio in [0, 0.5). Default 0.03.
    pub longitudinal_slip: f64,
    /// Standard deviation of the slowly varying part of the slip ratio. Default 0.01.
    pub slip_variation: f64,
    /// Lateral slide per unit `v·ω`, m/s per (m/s · rad/s). Default 0.03.
    pub lateral_slip_gain: f64,
    /// Standard deviation of the slowly varying yaw-rate disturbance (ruts, clods), rad/s. Default 0.01.
    pub yaw_disturbance_rad_s: f64,
}

impl Default for RobotConfig {
    fn default() -> Self {
        Self {
            width_m: 1.8,
            length_m: 1.2,
            track_m: 1.524,
            wheelbase_m: 1.219,
            tire_width_m: 0.15,
            contact_length_m: 0.12,
            effective_track_factor: 1.3,
            wheel_time_constant_s: 0.15,
            max_wheel_speed_m_s: 2.4,
            max_wheel_accel_m_s2: 1.5,
            longitudinal_slip: 0.03,
            slip_variation: 0.01,
            lateral_slip_gain: 0.03,
            yaw_disturbance_rad_s: 0.01,
        }
    }
}

impl RobotConfig {
    /// Checks every field, naming the first bad one (`robot.track_m`).
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("robot.width_m", self.width_m, 0.2, 10.0)?;
        check_range("robot.length_m", self.length_m, 0.2, 10.0)?;
        check_range("robot.track_m", self.track_m, 0.1, self.width_m)?;
        check_range("robot.wheelbase_m", self.wheelbase_m, 0.0, 10.0)?;
        check_range("robot.tire_width_m", self.tire_width_m, 0.01, 1.0)?;
        check_range("robot.contact_length_m", self.contact_length_m, 0.01, 1.0)?;
        check_range("robot.effective_track_factor", self.effective_track_factor, 1.0, 3.0)?;
        check_range("robot.wheel_time_constant_s", self.wheel_time_constant_s, 0.0, 5.0)?;
        check_range("robot.max_wheel_speed_m_s", self.max_wheel_speed_m_s, 0.01, 20.0)?;
        check_range("robot.max_wheel_accel_m_s2", self.max_wheel_accel_m_s2, 0.01, 50.0)?;
        check_range("robot.longitudinal_slip", self.longitudinal_slip, 0.0, 0.5)?;
        check_range("robot.slip_variation", self.slip_variation, 0.0, 0.2)?;
        check_range("robot.lateral_slip_gain", self.lateral_slip_gain, 0.0, 1.0)?;
        check_range("robot.yaw_disturbance_rad_s", self.yaw_disturbance_rad_s, 0.0, 1.0)?;
        Ok(())
    }

    /// The effective track `B_eff`, m.
    pub fn effective_track_m(&self) -> f64 {
        self.track_m * self.effective_track_factor
    }

    /// Wheel centres in `base_link`, m: front-left, front-right, rear-left, rear-right.
    pub fn wheel_positions(&self) -> [(f64, f64); 4] {
        let (a, b) = (0.5 * self.wheelbase_m, 0.5 * self.track_m);
        [(a, b), (a, -b), (-a, b), (-a, -b)]
    }
}

/// Why a step was refused.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum StepError {
    /// The command held NaN or infinity; the robot state was left untouched.
    #[error("non-finite command (v = {v}, ω = {omega})")]
    NonFiniteCommand {
        /// Commanded forward speed.
        v: f64,
        /// Commanded yaw rate.
        omega: f64,
    },
    /// The time step is not a positive finite number of seconds below 1 s.
    #[error("invalid time step {0} s")]
    InvalidStep(f64),
}

/// The robot's true state and dynamics.
#[derive(Debug, Clone)]
pub struct Robot {
    config: RobotConfig,
    pose: Pose2,
    body: BodyPose,
    /// True wheel surface speeds (left, right), m/s.
    wheels: (f64, f64),
    /// True body twist and body-frame acceleration (forward, lateral) after the last step.
    twist: Twist2,
    lateral_m_s: f64,
    accel: (f64, f64),
    slip: f64,
    yaw_disturbance: f64,
    /// Wet soil (`faults.slip_patch`); off unless set.
    slip_patch: SlipPatch,
    rng: ChaCha8Rng,
}

impl Robot {
    /// A robot at rest at `start` (field frame), with its own seeded slip process.
    pub fn new(config: &RobotConfig, start: Pose2, seed: u64) -> Result<Self, ConfigError> {
        config.validate()?;
        if !start.is_finite() {
            return Err(ConfigError::invalid("start", "start pose is not finite"));
        }
        Ok(Self {
            config: config.clone(),
            pose: start,
            body: BodyPose::planar(start),
            wheels: (0.0, 0.0),
            twist: Twist2::ZERO,
            lateral_m_s: 0.0,
            accel: (0.0, 0.0),
            slip: config.longitudinal_slip,
            yaw_disturbance: 0.0,
            slip_patch: SlipPatch::default(),
            rng: ChaCha8Rng::seed_from_u64(seed),
        })
    }

    /// The configuration.
    pub fn config(&self) -> &RobotConfig {
        &self.config
    }

    /// True planar pose of `base_link` in the field frame.
    pub fn pose(&self) -> Pose2 {
        self.pose
    }

    /// True 3-D pose (z, roll, pitch follow the terrain).
    pub fn body(&self) -> BodyPose {
        self.body
    }

    /// True body twist (forward speed, yaw rate) over the last step.
    pub fn twist(&self) -> Twist2 {
        self.twist
    }

    /// True lateral velocity (slide) in `base_link` over the last step, m/s.
    pub fn lateral_velocity_m_s(&self) -> f64 {
        self.lateral_m_s
    }

    /// True body-frame acceleration `(forward, lateral)` over the last step, m/s² (gravity excluded).
    pub fn acceleration(&self) -> (f64, f64) {
        self.accel
    }

    /// True wheel surface speeds `(left, right)`, m/s: what ideal encoders would read.
    pub fn wheel_speeds(&self) -> (f64, f64) {
        self.wheels
    }

    /// Wheel contact-patch centres in the field frame: front-left, front-right, rear-left, rear-right.
    pub fn wheel_contacts(&self) -> [(f64, f64); 4] {
        self.config.wheel_positions().map(|(x, y)| self.pose.transform_point(x, y))
    }

    /// Sets a patch of wet soil (`faults.slip_patch`): while the true x is inside it the slip ratio is
    /// the patch's and the body slides sideways (see [`SlipPatch`]).
    pub fn set_slip_patch(&mut self, patch: SlipPatch) {
        self.slip_patch = patch;
    }

    /// Puts the robot down on the terrain at its current planar pose (z, roll, pitch).
    pub(crate) fn settle(&mut self, field: &Field) {
        self.body = terrain_body(field, self.pose);
    }

    /// Advances the robot by `dt_s` under command `cmd`. The terrain of `field` sets z, roll and pitch.
    pub fn step(&mut self, cmd: Twist2, dt_s: f64, field: &Field) -> Result<(), StepError> {
        if !cmd.is_finite() {
            return Err(StepError::NonFiniteCommand { v: cmd.v, omega: cmd.omega });
        }
        if !(dt_s > 0.0 && dt_s < 1.0) {
            return Err(StepError::InvalidStep(dt_s));
        }
        let c = &self.config;
        let b_eff = c.effective_track_m();
        let vmax = c.max_wheel_speed_m_s;
        let target = (
            (cmd.v - 0.5 * cmd.omega * b_eff).clamp(-vmax, vmax),
            (cmd.v + 0.5 * cmd.omega * b_eff).clamp(-vmax, vmax),
        );
        // First-order response (exact discretisation), then the acceleration limit.
        let alpha =
            if c.wheel_time_constant_s > 0.0 { 1.0 - (-dt_s / c.wheel_time_constant_s).exp() } else { 1.0 };
        let max_dv = c.max_wheel_accel_m_s2 * dt_s;
        let follow = |w: f64, t: f64| w + (alpha * (t - w)).clamp(-max_dv, max_dv);
        self.wheels = (follow(self.wheels.0, target.0), follow(self.wheels.1, target.1));

        // Ornstein-Uhlenbeck disturbances: stationary σ as configured, correlation time DISTURBANCE_TAU_S.
        let a = (-dt_s / DISTURBANCE_TAU_S).exp();
        let q = (1.0 - a * a).sqrt();
        let (n1, n2): (f64, f64) =
            (StandardNormal.sample(&mut self.rng), StandardNormal.sample(&mut self.rng));
        self.slip = c.longitudinal_slip + a * (self.slip - c.longitudinal_slip) + q * c.slip_variation * n1;
        self.yaw_disturbance = a * self.yaw_disturbance + q * c.yaw_disturbance_rad_s * n2;
        let wet = self.slip_patch.covers(self.pose.x);
        // The soil's own slip variation rides on the patch's mean (the OU process keeps running).
        let s =
            if wet { self.slip_patch.longitudinal_slip + self.slip - c.longitudinal_slip } else { self.slip }
                .clamp(0.0, 0.9);

        let (vl, vr) = self.wheels;
        let v = (1.0 - s) * 0.5 * (vl + vr);
        let omega = (1.0 - s) * (vr - vl) / b_eff + if v.abs() > 0.01 { self.yaw_disturbance } else { 0.0 };
        let drift = if wet { self.slip_patch.lateral_drift_m_s * v / DRIFT_REFERENCE_SPEED_M_S } else { 0.0 };
        let lateral = c.lateral_slip_gain * v * omega + drift;

        // Midpoint integration of the planar motion.
        let mid = self.pose.yaw + 0.5 * omega * dt_s;
        let (sm, cm) = mid.sin_cos();
        self.pose.x += (v * cm - lateral * sm) * dt_s;
        self.pose.y += (v * sm + lateral * cm) * dt_s;
        self.pose.yaw = wrap_angle(self.pose.yaw + omega * dt_s);
        self.accel = ((v - self.twist.v) / dt_s, (lateral - self.lateral_m_s) / dt_s + v * omega);
        self.twist = Twist2::new(v, omega);
        self.lateral_m_s = lateral;
        self.body = terrain_body(field, self.pose);
        Ok(())
    }
}

/// The 3-D pose of a robot standing on the terrain at `pose`: z from the ground under its centre,
/// roll and pitch from the ground slope along and across its heading.
pub(crate) fn terrain_body(field: &Field, pose: Pose2) -> BodyPose {
    let (gx, gy) = field.ground_gradient(pose.x, pose.y);
    let (s, c) = pose.yaw.sin_cos();
    let along = gx * c + gy * s;
    let across = -gx * s + gy * c;
    // REP-103: positive pitch is nose down, i.e. the ground rising behind; positive roll lifts the left.
    BodyPose { pose, z_m: field.ground_z(pose.x, pose.y), roll_rad: across.atan(), pitch_rad: -along.atan() }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::field::FieldConfig;

    fn flat_field() -> Field {
        Field::generate(&FieldConfig { rows: 1, length_m: 1.0, ..FieldConfig::default() }, 0).unwrap()
    }

    fn ideal() -> RobotConfig {
        RobotConfig {
            longitudinal_slip: 0.0,
            slip_variation: 0.0,
            lateral_slip_gain: 0.0,
            yaw_disturbance_rad_s: 0.0,
            ..RobotConfig::default()
        }
    }

    fn drive(robot: &mut Robot, cmd: Twist2, seconds: f64, field: &Field) {
        for _ in 0..(seconds / 0.01).round() as usize {
            robot.step(cmd, 0.01, field).unwrap();
        }
    }

    #[test]
    fn straight_command_drives_straight_at_the_commanded_speed() {
        let f = flat_field();
        let mut r = Robot::new(&ideal(), Pose2::default(), 0).unwrap();
        drive(&mut r, Twist2::new(1.0, 0.0), 10.0, &f);
        // The wheels first ramp at 1.5 m/s² to ~0.77 m/s (0.32 m lost), then close the rest with the
        // 0.15 s time constant (~0.035 m lost): about 9.65 m.
        let p = r.pose();
        assert!((p.x - 9.65).abs() < 0.03 && p.y.abs() < 1e-9 && p.yaw.abs() < 1e-12, "{p:?}");
        assert!((r.twist().v - 1.0).abs() < 1e-6);
    }

    #[test]
    fn turn_command_gives_the_commanded_circle() {
        let f = flat_field();
        let mut r = Robot::new(&ideal(), Pose2::default(), 0).unwrap();
        // v = 0.5 m/s, ω = 0.25 rad/s: a 2 m radius circle centred at (0, 2).
        drive(&mut r, Twist2::new(0.5, 0.25), 30.0, &f);
        let p = r.pose();
        let radius = (p.x.powi(2) + (p.y - 2.0).powi(2)).sqrt();
        // The start-up transient shifts the centre by a few centimetres.
        assert!((radius - 2.0).abs() < 0.05, "{radius}");
        assert!((r.twist().omega - 0.25).abs() < 1e-6);
    }

    #[test]
    fn slip_makes_the_robot_fall_short() {
        let f = flat_field();
        let cfg = RobotConfig {
            slip_variation: 0.0,
            yaw_disturbance_rad_s: 0.0,
            longitudinal_slip: 0.1,
            ..RobotConfig::default()
        };
        let mut r = Robot::new(&cfg, Pose2::default(), 0).unwrap();
        drive(&mut r, Twist2::new(1.0, 0.0), 10.0, &f);
        // 10 % slip: 0.9 m/s instead of 1 m/s (tolerance 1e-6 m/s).
        assert!((r.twist().v - 0.9).abs() < 1e-6);
        assert!((r.wheel_speeds().0 - 1.0).abs() < 1e-6);
    }

    #[test]
    fn a_slip_patch_slows_the_robot_and_pushes_it_sideways_inside_it_only() {
        let f = flat_field();
        let mut r = Robot::new(&ideal(), Pose2::default(), 0).unwrap();
        r.set_slip_patch(SlipPatch {
            enabled: true,
            from_x_m: 5.0,
            to_x_m: 10.0,
            longitudinal_slip: 0.3,
            lateral_drift_m_s: 0.05,
        });
        drive(&mut r, Twist2::new(1.0, 0.0), 5.0, &f);
        assert!(r.pose().x < 5.0 && r.pose().y == 0.0, "{:?}", r.pose());
        drive(&mut r, Twist2::new(1.0, 0.0), 3.0, &f);
        // Inside: 30 % slip, so 0.7 m/s, drifting 0.05 · 0.7 / 0.5 = 0.07 m/s left (tolerance 1e-6 m/s).
        assert!(r.pose().x > 5.0 && r.pose().x < 10.0, "{:?}", r.pose());
        assert!((r.twist().v - 0.7).abs() < 1e-6 && (r.lateral_velocity_m_s() - 0.07).abs() < 1e-6);
        assert!((r.wheel_speeds().0 - 1.0).abs() < 1e-6);
        drive(&mut r, Twist2::new(1.0, 0.0), 6.0, &f);
        assert!(r.pose().x > 10.0 && (r.twist().v - 1.0).abs() < 1e-6 && r.lateral_velocity_m_s() == 0.0);
    }

    #[test]
    fn wheel_speed_is_limited_and_bad_commands_are_refused() {
        let f = flat_field();
        let mut r = Robot::new(&ideal(), Pose2::default(), 0).unwrap();
        drive(&mut r, Twist2::new(10.0, 0.0), 5.0, &f);
        assert!((r.twist().v - 2.4).abs() < 1e-6);
        let before = r.pose();
        assert!(r.step(Twist2::new(f64::NAN, 0.0), 0.01, &f).is_err());
        assert!(r.step(Twist2::ZERO, -0.01, &f).is_err());
        assert_eq!(r.pose(), before);
    }

    #[test]
    fn absurd_robot_parameters_name_the_field() {
        let e = Robot::new(&RobotConfig { track_m: -1.0, ..RobotConfig::default() }, Pose2::default(), 0)
            .unwrap_err()
            .to_string();
        assert!(e.contains("robot.track_m"), "{e}");
    }

    #[test]
    fn terrain_tilts_the_body() {
        let c = FieldConfig {
            rows: 1,
            length_m: 1.0,
            relief_m: 0.2,
            relief_wavelength_m: 10.0,
            ..FieldConfig::default()
        };
        let f = Field::generate(&c, 2).unwrap();
        let mut r = Robot::new(&ideal(), Pose2::default(), 0).unwrap();
        let mut max_pitch: f64 = 0.0;
        for _ in 0..1000 {
            r.step(Twist2::new(1.0, 0.0), 0.01, &f).unwrap();
            max_pitch = max_pitch.max(r.body().pitch_rad.abs());
            assert!((r.body().z_m - f.ground_z(r.pose().x, r.pose().y)).abs() < 1e-12);
        }
        // Peak slope of a 0.2 m, 10 m relief is ~2π·0.2/10·(0.5+0.3/0.7+0.2/0.45) ≈ 0.17; some is seen.
        assert!(max_pitch > 0.01 && max_pitch < 0.2, "{max_pitch}");
    }
}
