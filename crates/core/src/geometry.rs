//! Small geometric types shared by every stage. Frames are named in every doc: `odom` is the
//! odometry frame (REP-105), `base_link` the robot body frame on the ground below the robot centre,
//! the sensor frame is the LiDAR's own (x forward, y left, z up when level).

use nalgebra::{Isometry3, Rotation3, Translation3, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::error::{ConfigError, check_range};

/// A LiDAR point in the sensor frame, metres. `f32` halves the memory traffic of a 29k-point scan;
/// centimetre precision at 100 m is well inside f32's 7 digits.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
#[repr(C)]
pub struct Point3 {
    /// Forward, m.
    pub x: f32,
    /// Left, m.
    pub y: f32,
    /// Up, m.
    pub z: f32,
}

impl Point3 {
    /// A point from its coordinates, metres.
    pub const fn new(x: f32, y: f32, z: f32) -> Self {
        Self { x, y, z }
    }

    /// True when all three coordinates are finite numbers.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }
}

/// A planar pose: position (m) and heading (rad, counter-clockwise from +x) of `base_link` in a
/// parent frame, usually `odom`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose2 {
    /// x of `base_link` in the parent frame, m.
    pub x: f64,
    /// y of `base_link` in the parent frame, m.
    pub y: f64,
    /// Heading ψ, rad.
    pub yaw: f64,
}

impl Pose2 {
    /// A pose from position (m) and heading (rad).
    pub const fn new(x: f64, y: f64, yaw: f64) -> Self {
        Self { x, y, yaw }
    }

    /// True when every component is finite.
    pub fn is_finite(&self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.yaw.is_finite()
    }

    /// Maps a point given in this pose's child frame into the parent frame.
    pub fn transform_point(&self, px: f64, py: f64) -> (f64, f64) {
        let (s, c) = self.yaw.sin_cos();
        (self.x + c * px - s * py, self.y + s * px + c * py)
    }

    /// Maps a point given in the parent frame into this pose's child frame.
    pub fn inverse_transform_point(&self, px: f64, py: f64) -> (f64, f64) {
        let (s, c) = self.yaw.sin_cos();
        let (dx, dy) = (px - self.x, py - self.y);
        (c * dx + s * dy, -s * dx + c * dy)
    }

    /// `self ∘ other`: the pose `other` (given relative to `self`) expressed in `self`'s parent frame.
    pub fn compose(&self, other: &Pose2) -> Pose2 {
        let (x, y) = self.transform_point(other.x, other.y);
        Pose2::new(x, y, wrap_angle(self.yaw + other.yaw))
    }

    /// The pose of `other` relative to `self` (both in the same parent frame).
    pub fn relative(&self, other: &Pose2) -> Pose2 {
        let (x, y) = self.inverse_transform_point(other.x, other.y);
        Pose2::new(x, y, wrap_angle(other.yaw - self.yaw))
    }
}

/// A body-frame velocity command or measurement: forward speed (m/s) and yaw rate (rad/s) of `base_link`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Twist2 {
    /// Forward speed v, m/s.
    pub v: f64,
    /// Yaw rate ω, rad/s, counter-clockwise positive.
    pub omega: f64,
}

impl Twist2 {
    /// Zero motion: what a robot is commanded when it must stop.
    pub const ZERO: Twist2 = Twist2 { v: 0.0, omega: 0.0 };

    /// A twist from forward speed (m/s) and yaw rate (rad/s).
    pub const fn new(v: f64, omega: f64) -> Self {
        Self { v, omega }
    }

    /// True when both components are finite.
    pub fn is_finite(&self) -> bool {
        self.v.is_finite() && self.omega.is_finite()
    }
}

/// Wraps an angle to (-π, π].
pub fn wrap_angle(a: f64) -> f64 {
    let mut r = a.rem_euclid(std::f64::consts::TAU);
    if r > std::f64::consts::PI {
        r -= std::f64::consts::TAU;
    }
    r
}

/// The rigid transform `base_link -> sensor`: where the LiDAR sits on the robot and how it is tilted.
///
/// Defaults to the paper's mount (Sec. IV): 1.5 m above the ground at the front centre, pitched 30°
/// nose-down (positive pitch in REP-103).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Mount {
    /// Sensor origin in `base_link`, forward, m. Default 0.6 (front of a 1.2 m long robot).
    pub x_m: f64,
    /// Sensor origin in `base_link`, left, m. Default 0.
    pub y_m: f64,
    /// Sensor origin in `base_link`, up from the ground, m. Default 1.5 (paper).
    pub z_m: f64,
    /// Roll about x, rad. Default 0.
    pub roll_rad: f64,
    /// Pitch about y, rad; positive tilts the nose down. Default 30° (paper).
    pub pitch_rad: f64,
    /// Yaw about z, rad. Default 0.
    pub yaw_rad: f64,
}

impl Default for Mount {
    fn default() -> Self {
        Self { x_m: 0.6, y_m: 0.0, z_m: 1.5, roll_rad: 0.0, pitch_rad: 30f64.to_radians(), yaw_rad: 0.0 }
    }
}

/// Roll and pitch of `base_link` against gravity, rad (REP-103: positive roll lifts the left side,
/// positive pitch tilts the nose down). The robot's yaw is the odometry's.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct Attitude {
    /// Roll about x, rad.
    pub roll_rad: f64,
    /// Pitch about y, rad.
    pub pitch_rad: f64,
}

impl Attitude {
    /// Largest roll or pitch believed, rad (29°: no field robot drives there).
    pub const MAX_RAD: f64 = 0.5;

    /// True when both angles are finite and within [`Attitude::MAX_RAD`].
    pub fn is_plausible(&self) -> bool {
        self.roll_rad.abs() <= Self::MAX_RAD && self.pitch_rad.abs() <= Self::MAX_RAD
    }
}

impl Mount {
    /// A mount from a translation (m) and a unit quaternion `(x, y, z, w)`, as ROS `/tf_static` gives it.
    pub fn from_translation_quaternion(t: [f64; 3], q_xyzw: [f64; 4]) -> Result<Self, ConfigError> {
        let norm = q_xyzw.iter().map(|v| v * v).sum::<f64>().sqrt();
        if !norm.is_finite() || norm < 1e-9 {
            return Err(ConfigError::invalid("mount.rotation", "quaternion is zero or not finite"));
        }
        let q = UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(
            q_xyzw[3], q_xyzw[0], q_xyzw[1], q_xyzw[2],
        ));
        let (roll_rad, pitch_rad, yaw_rad) = q.euler_angles();
        let m = Self { x_m: t[0], y_m: t[1], z_m: t[2], roll_rad, pitch_rad, yaw_rad };
        m.validate()?;
        Ok(m)
    }

    /// Checks the mount is physically plausible: finite, the sensor above the ground and within
    /// 10 m of the robot, looking more down than up.
    pub fn validate(&self) -> Result<(), ConfigError> {
        check_range("mount.x_m", self.x_m, -10.0, 10.0)?;
        check_range("mount.y_m", self.y_m, -10.0, 10.0)?;
        check_range("mount.z_m", self.z_m, 0.05, 10.0)?;
        check_range("mount.roll_rad", self.roll_rad, -0.5, 0.5)?;
        check_range("mount.pitch_rad", self.pitch_rad, -0.2, 1.5)?;
        check_range("mount.yaw_rad", self.yaw_rad, -std::f64::consts::PI, std::f64::consts::PI)?;
        Ok(())
    }

    /// The transform as an isometry: `p_base = iso * p_sensor`.
    pub fn isometry(&self) -> Isometry3<f64> {
        Isometry3::from_parts(
            Translation3::new(self.x_m, self.y_m, self.z_m),
            UnitQuaternion::from_rotation_matrix(&Rotation3::from_euler_angles(
                self.roll_rad,
                self.pitch_rad,
                self.yaw_rad,
            )),
        )
    }

    /// Maps a sensor-frame point into `base_link`.
    pub fn to_base(&self, p: Point3) -> Vector3<f64> {
        self.isometry().transform_point(&nalgebra::Point3::new(p.x as f64, p.y as f64, p.z as f64)).coords
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pose_round_trip() {
        let p = Pose2::new(1.0, -2.0, 0.7);
        let (x, y) = p.transform_point(0.3, 0.4);
        let (bx, by) = p.inverse_transform_point(x, y);
        assert!((bx - 0.3).abs() < 1e-12 && (by - 0.4).abs() < 1e-12);
        let q = Pose2::new(0.5, 0.1, -0.2);
        let r = p.relative(&p.compose(&q));
        assert!((r.x - q.x).abs() < 1e-12 && (r.y - q.y).abs() < 1e-12 && (r.yaw - q.yaw).abs() < 1e-12);
    }

    #[test]
    fn paper_mount_from_tf_static() {
        // The sample recording's /tf_static: 30° nose-down pitch.
        let m = Mount::from_translation_quaternion([0.6, 0.0, 1.5], [0.0, 0.258819, 0.0, 0.965926]).unwrap();
        assert!((m.pitch_rad.to_degrees() - 30.0).abs() < 1e-3);
        // A point 1 m straight ahead of a nose-down sensor lies below the sensor in base_link.
        let p = m.to_base(Point3::new(1.0, 0.0, 0.0));
        assert!((p.z - (1.5 - 0.5)).abs() < 1e-4, "{p:?}");
        assert!((p.x - (0.6 + 30f64.to_radians().cos())).abs() < 1e-4);
    }

    #[test]
    fn absurd_mount_is_refused() {
        let m = Mount { z_m: -1.0, ..Mount::default() };
        assert!(m.validate().is_err());
        assert!(Mount::from_translation_quaternion([0.0; 3], [0.0; 4]).is_err());
    }

    #[test]
    fn wrap() {
        assert!((wrap_angle(3.0 * std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
        assert!((wrap_angle(-0.5) + 0.5).abs() < 1e-12);
    }
}
