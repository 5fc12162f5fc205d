//! Shared fixture of the node tests: a synthetic row-crop field seen by a tilted LiDAR (a dense
//! sample of the ground and the canopy surface in front of the robot, in the sensor frame), an ideal
//! unicycle, and the ROS messages a robot publishes (cloud, odometry, IMU, `/tf_static`).
#![allow(dead_code)]

use croprow_core::{Mount, Point3, Pose2, Twist2};
use croprow_io::cloud::{self, PointFormat, Stamped};
use croprow_io::msg::{
    Header, Imu, Odometry, PointCloud2, Quaternion, TfMessage, Time, Transform, TransformStamped, Vector3,
};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};

pub const SENSOR_FRAME: &str = "velodyne";

/// Rows along world +x at y = (k + ½)·spacing (the robot's lane centre is y = 0), hedges of a
/// parabolic cross-section with a plant every `plant_period_m`.
#[derive(Debug, Clone)]
pub struct Field {
    pub spacing_m: f64,
    pub plant_height_m: f64,
    pub half_width_m: f64,
    pub plant_period_m: f64,
    /// Rows start and end here (world x), m.
    pub start_x_m: f64,
    pub end_x_m: f64,
}

impl Default for Field {
    fn default() -> Self {
        Self {
            spacing_m: 0.75,
            plant_height_m: 0.5,
            half_width_m: 0.15,
            plant_period_m: 0.3,
            start_x_m: -5.0,
            end_x_m: 60.0,
        }
    }
}

impl Field {
    /// Surface height at a world point, m.
    pub fn height(&self, x: f64, y: f64) -> f64 {
        if x < self.start_x_m || x > self.end_x_m {
            return 0.0;
        }
        let k = (y / self.spacing_m - 0.5).round();
        let dy = y - (k + 0.5) * self.spacing_m;
        let across = 1.0 - (dy / self.half_width_m).powi(2);
        if across <= 0.0 {
            return 0.0;
        }
        let along = 0.75 + 0.25 * (std::f64::consts::TAU * x / self.plant_period_m).cos();
        self.plant_height_m * across * along
    }

    /// One scan in the sensor frame, seen from `pose` (world = `odom`) through `mount`: the surface
    /// sampled every 4 cm over the ground in front of the robot, with seeded 1 cm range noise.
    pub fn scan(&self, pose: Pose2, mount: &Mount, seed: u64) -> Vec<Point3> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let noise = Normal::new(0.0, 0.01).expect("valid normal");
        let to_sensor = mount.isometry().inverse();
        let mut points = Vec::with_capacity(20_000);
        for ix in 0..120 {
            for iy in 0..150 {
                let bx = 0.2 + ix as f64 * 0.04;
                let by = -3.0 + iy as f64 * 0.04;
                let (wx, wy) = pose.transform_point(bx, by);
                let z = self.height(wx, wy) + noise.sample(&mut rng);
                let p = to_sensor.transform_point(&nalgebra::Point3::new(bx, by, z));
                points.push(Point3::new(p.x as f32, p.y as f32, p.z as f32));
            }
        }
        points
    }
}

/// The ideal unicycle: `pose` after driving `cmd` for `dt` s.
pub fn drive(pose: Pose2, cmd: Twist2, dt: f64) -> Pose2 {
    let mid = pose.yaw + 0.5 * cmd.omega * dt;
    Pose2::new(pose.x + cmd.v * mid.cos() * dt, pose.y + cmd.v * mid.sin() * dt, pose.yaw + cmd.omega * dt)
}

pub fn header(stamp_s: f64, frame: &str) -> Header {
    Header { stamp: Time::from_seconds(stamp_s).expect("test stamps are valid"), frame_id: frame.into() }
}

pub fn cloud(stamp_s: f64, points: &[Point3]) -> PointCloud2<'static> {
    cloud::build(&Stamped::new(stamp_s, SENSOR_FRAME), points, &[], &[], PointFormat::XYZ)
        .expect("valid cloud")
}

pub fn odometry(stamp_s: f64, pose: Pose2, twist: Twist2) -> Odometry {
    let mut m = Odometry {
        header: header(stamp_s, "odom"),
        child_frame_id: "base_link".into(),
        ..Odometry::default()
    };
    m.pose.pose.position.x = pose.x;
    m.pose.pose.position.y = pose.y;
    m.pose.pose.orientation = Quaternion::from_yaw(pose.yaw);
    m.twist.twist.linear.x = twist.v;
    m.twist.twist.angular.z = twist.omega;
    m
}

pub fn imu(stamp_s: f64, yaw_rate: f64) -> Imu {
    Imu {
        header: header(stamp_s, "imu_link"),
        angular_velocity: Vector3 { z: yaw_rate, ..Vector3::default() },
        ..Imu::default()
    }
}

pub fn tf_static(mount: &Mount) -> TfMessage {
    TfMessage {
        transforms: vec![TransformStamped {
            header: header(0.0, "base_link"),
            child_frame_id: SENSOR_FRAME.into(),
            transform: Transform {
                translation: Vector3 { x: mount.x_m, y: mount.y_m, z: mount.z_m },
                rotation: Quaternion::from_rpy(mount.roll_rad, mount.pitch_rad, mount.yaw_rad),
            },
        }],
    }
}
