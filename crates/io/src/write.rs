//! Writing ROS 2 MCAP recordings that Foxglove, RViz (via `ros2 bag play`) and [`crate::read`] open:
//! CDR messages with full `ros2msg` schemas, the `ros2` profile and rosbag2's channel metadata
//! (`offered_qos_profiles`; `/tf_static` is transient-local, so late joiners get it). Chunks are
//! zstd-compressed and the summary carries the chunk and message indexes and statistics.
//!
//! Log time of every message = its header stamp (a simulation's clock), so a replay is in stamp order.
//!
//! ```no_run
//! use croprow_core::{Pose2, Twist2};
//! use croprow_io::RecordingWriter;
//! let mut rec = RecordingWriter::create("run.mcap")?;
//! rec.write_odometry("/odometry/filtered", 0.1, Pose2::new(1.0, 0.0, 0.0), Twist2::new(0.5, 0.0))?;
//! rec.write_cmd_vel("/cmd_vel", 0.1, Twist2::new(0.5, 0.01))?;
//! rec.finish()?;
//! # Ok::<(), croprow_io::WriteError>(())
//! ```

use std::collections::{BTreeMap, HashMap};
use std::fs::File;
use std::io::{BufWriter, Seek, Write};
use std::path::Path;

use croprow_core::{Detection, Mount, Point3, Pose2, RowEstimate, Twist2};
use serde::Serialize;
use thiserror::Error;

use crate::cloud::{self, BuildError, PointFormat, Stamped};
use crate::msg::{
    self, CdrError, ColorRgba, Header, Marker, MarkerArray, Odometry, Path as PathMsg, Point, Pose,
    PoseStamped, Quaternion, RosMessage, StringMsg, TfMessage, Time, Transform, TransformStamped, Twist,
    Vector3,
};
use crate::read::TF_STATIC;

/// A recording could not be written.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum WriteError {
    /// The file could not be created or written.
    #[error("cannot write the recording: {0}")]
    Io(#[from] std::io::Error),
    /// The MCAP writer refused a record.
    #[error("MCAP writer: {0}")]
    Mcap(#[from] mcap::McapError),
    /// A message could not be encoded.
    #[error(transparent)]
    Cdr(#[from] CdrError),
    /// A point cloud could not be built.
    #[error(transparent)]
    Cloud(#[from] BuildError),
    /// A stamp is negative, not finite or too large for a ROS time.
    #[error("stamp {0} s cannot be recorded (must be finite, >= 0 and < 2^31 s)")]
    Stamp(f64),
}

/// The QoS rosbag2 records for a topic, as the YAML it stores in channel metadata.
fn qos_yaml(transient_local: bool) -> String {
    let durability = if transient_local { 1 } else { 2 };
    let forever = "    sec: 2147483647\n    nsec: 4294967295\n";
    format!(
        "- history: 3\n  depth: 0\n  reliability: 1\n  durability: {durability}\n  deadline:\n{forever}  lifespan:\n\
{forever}  liveliness: 1\n  liveliness_lease_duration:\n{forever}  avoid_ros_namespace_conventions: false\n"
    )
}

/// Writes a ROS 2 MCAP recording; see the module docs. Call [`RecordingWriter::finish`] at the end,
/// or the file has no summary (it then still reads front to back).
pub struct RecordingWriter<W: Write + Seek = BufWriter<File>> {
    writer: mcap::Writer<W>,
    /// topic -> (channel id, next sequence number).
    channels: HashMap<String, (u16, u32)>,
    /// type name -> schema id.
    schemas: HashMap<&'static str, u16>,
    buf: Vec<u8>,
}

impl<W: Write + Seek> std::fmt::Debug for RecordingWriter<W> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordingWriter").field("topics", &self.channels.len()).finish()
    }
}

impl RecordingWriter<BufWriter<File>> {
    /// Creates (or truncates) a recording file.
    pub fn create(path: impl AsRef<Path>) -> Result<Self, WriteError> {
        Self::new(BufWriter::new(File::create(path)?))
    }
}

impl<W: Write + Seek> RecordingWriter<W> {
    /// Starts a recording on any seekable writer (chunks of about 1 MiB, like rosbag2).
    pub fn new(w: W) -> Result<Self, WriteError> {
        Self::with_chunk_size(w, 1 << 20)
    }

    /// Starts a recording whose chunks close after about `chunk_bytes` (uncompressed): smaller chunks
    /// lose less to a crash mid-write.
    pub fn with_chunk_size(w: W, chunk_bytes: u64) -> Result<Self, WriteError> {
        let writer = mcap::WriteOptions::new()
            .profile("ros2")
            .library(concat!("croprow-io ", env!("CARGO_PKG_VERSION")))
            .compression(Some(mcap::Compression::Zstd))
            .chunk_size(Some(chunk_bytes))
            .create(w)?;
        Ok(Self { writer, channels: HashMap::new(), schemas: HashMap::new(), buf: Vec::new() })
    }

    /// Writes any message on `topic` with log time = `stamp_s`.
    pub fn write<M: Serialize + RosMessage>(
        &mut self,
        topic: &str,
        stamp_s: f64,
        message: &M,
    ) -> Result<(), WriteError> {
        let log_time =
            Time::from_seconds(stamp_s).and_then(|t| t.as_nanos()).ok_or(WriteError::Stamp(stamp_s))?;
        let (channel_id, sequence) = self.channel::<M>(topic)?;
        msg::encode_to(message, &mut self.buf)?;
        let header = mcap::records::MessageHeader { channel_id, sequence, log_time, publish_time: log_time };
        self.writer.write_to_known_channel(&header, &self.buf)?;
        Ok(())
    }

    fn channel<M: RosMessage>(&mut self, topic: &str) -> Result<(u16, u32), WriteError> {
        if let Some((id, seq)) = self.channels.get_mut(topic) {
            *seq += 1;
            return Ok((*id, *seq));
        }
        let schema_id = match self.schemas.get(M::TYPE_NAME) {
            Some(id) => *id,
            None => {
                let id = self.writer.add_schema(M::TYPE_NAME, "ros2msg", M::definition().as_bytes())?;
                self.schemas.insert(M::TYPE_NAME, id);
                id
            }
        };
        let metadata = BTreeMap::from([("offered_qos_profiles".to_owned(), qos_yaml(topic == TF_STATIC))]);
        let id = self.writer.add_channel(schema_id, topic, "cdr", &metadata)?;
        self.channels.insert(topic.to_owned(), (id, 1));
        Ok((id, 1))
    }

    /// A LiDAR scan in the sensor frame as a Velodyne driver publishes it: x y z intensity float32
    /// and ring uint16, 18 bytes per point. Missing intensities/rings are written as 0.
    pub fn write_cloud(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        points: &[Point3],
        intensity: &[f32],
        ring: &[u16],
    ) -> Result<(), WriteError> {
        self.write_cloud_as(topic, stamp_s, frame_id, points, intensity, ring, PointFormat::VELODYNE)
    }

    /// A scan in any [`PointFormat`] (other drivers' layouts, tests).
    #[allow(clippy::too_many_arguments)]
    pub fn write_cloud_as(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        points: &[Point3],
        intensity: &[f32],
        ring: &[u16],
        format: PointFormat,
    ) -> Result<(), WriteError> {
        let cloud = cloud::build(&Stamped::new(stamp_s, frame_id), points, intensity, ring, format)?;
        if format.big_endian {
            // A big-endian cloud comes from big-endian hardware, whose CDR is big endian too.
            let log_time =
                Time::from_seconds(stamp_s).and_then(|t| t.as_nanos()).ok_or(WriteError::Stamp(stamp_s))?;
            let (channel_id, sequence) = self.channel::<msg::PointCloud2<'_>>(topic)?;
            let bytes = msg::encode_big_endian(&cloud)?;
            let header =
                mcap::records::MessageHeader { channel_id, sequence, log_time, publish_time: log_time };
            self.writer.write_to_known_channel(&header, &bytes)?;
            return Ok(());
        }
        self.write(topic, stamp_s, &cloud)
    }

    /// `odom -> base_link` pose and body twist (planar).
    pub fn write_odometry(
        &mut self,
        topic: &str,
        stamp_s: f64,
        pose: Pose2,
        twist: Twist2,
    ) -> Result<(), WriteError> {
        let mut m = Odometry {
            header: header(stamp_s, "odom")?,
            child_frame_id: "base_link".into(),
            ..Default::default()
        };
        m.pose.pose = pose3(pose);
        m.twist.twist = Twist {
            linear: Vector3 { x: twist.v, ..Default::default() },
            angular: Vector3 { z: twist.omega, ..Default::default() },
        };
        self.write(topic, stamp_s, &m)
    }

    /// `odom -> base_link` on `/tf`.
    pub fn write_tf(&mut self, stamp_s: f64, pose: Pose2) -> Result<(), WriteError> {
        let p = pose3(pose);
        let t = TransformStamped {
            header: header(stamp_s, "odom")?,
            child_frame_id: "base_link".into(),
            transform: Transform {
                translation: Vector3 { x: p.position.x, y: p.position.y, z: p.position.z },
                rotation: p.orientation,
            },
        };
        self.write("/tf", stamp_s, &TfMessage { transforms: vec![t] })
    }

    /// The sensor mount `base_link -> sensor_frame` on `/tf_static` (write once, at the start).
    pub fn write_tf_static(
        &mut self,
        stamp_s: f64,
        sensor_frame: &str,
        mount: &Mount,
    ) -> Result<(), WriteError> {
        let t = TransformStamped {
            header: header(stamp_s, "base_link")?,
            child_frame_id: sensor_frame.into(),
            transform: Transform {
                translation: Vector3 { x: mount.x_m, y: mount.y_m, z: mount.z_m },
                rotation: Quaternion::from_rpy(mount.roll_rad, mount.pitch_rad, mount.yaw_rad),
            },
        };
        self.write(TF_STATIC, stamp_s, &TfMessage { transforms: vec![t] })
    }

    /// A velocity command (`geometry_msgs/msg/Twist`, body frame).
    pub fn write_cmd_vel(&mut self, topic: &str, stamp_s: f64, cmd: Twist2) -> Result<(), WriteError> {
        let t = Twist {
            linear: Vector3 { x: cmd.v, ..Default::default() },
            angular: Vector3 { z: cmd.omega, ..Default::default() },
        };
        self.write(topic, stamp_s, &t)
    }

    /// The detected rows (one `LINE_STRIP` each, deleted when not detected) and the row centroids
    /// (`SPHERE_LIST`, `[x, y]` in `base_link`, m) as a `MarkerArray` in `base_link`.
    pub fn write_rows(
        &mut self,
        topic: &str,
        detection: &Detection,
        centroids: &[[f64; 2]],
    ) -> Result<(), WriteError> {
        let markers = row_markers(detection, centroids, header(detection.stamp_s, "base_link")?);
        self.write(topic, detection.stamp_s, &markers)
    }

    /// An IMU sample: angular velocity (rad/s) and linear acceleration (m/s²) in `frame_id`, no
    /// orientation (covariance element 0 = -1, as REP-145 says for "not provided").
    pub fn write_imu(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        angular_velocity: [f64; 3],
        linear_acceleration: [f64; 3],
    ) -> Result<(), WriteError> {
        let v = |a: [f64; 3]| Vector3 { x: a[0], y: a[1], z: a[2] };
        let mut imu = msg::Imu {
            header: header(stamp_s, frame_id)?,
            angular_velocity: v(angular_velocity),
            linear_acceleration: v(linear_acceleration),
            ..msg::Imu::default()
        };
        imu.orientation_covariance[0] = -1.0;
        self.write(topic, stamp_s, &imu)
    }

    /// A path (e.g. the centre-line reference) of planar poses in `frame_id`.
    pub fn write_path(
        &mut self,
        topic: &str,
        stamp_s: f64,
        frame_id: &str,
        poses: &[Pose2],
    ) -> Result<(), WriteError> {
        let h = header(stamp_s, frame_id)?;
        let poses = poses.iter().map(|p| PoseStamped { header: h.clone(), pose: pose3(*p) }).collect();
        self.write(topic, stamp_s, &PathMsg { header: h, poses })
    }

    /// A status text (`std_msgs/msg/String`).
    pub fn write_status(&mut self, topic: &str, stamp_s: f64, text: &str) -> Result<(), WriteError> {
        self.write(topic, stamp_s, &StringMsg { data: text.to_owned() })
    }

    /// Writes the summary (indexes, statistics) and the footer; returns the inner writer.
    pub fn finish(mut self) -> Result<W, WriteError> {
        self.writer.finish()?;
        Ok(self.writer.into_inner())
    }
}

/// The rows of a detection as a `MarkerArray` stamped with `header` (frame `base_link`): each row a
/// LINE_STRIP (a DELETE while it is not seen, so stale rows vanish in RViz/Foxglove) and the detector's
/// centroids as a SPHERE_LIST. Shared by recordings and the live node, so both look the same.
pub fn row_markers(detection: &Detection, centroids: &[[f64; 2]], header: Header) -> MarkerArray {
    let base = Marker { header, ns: "rows".into(), pose: Pose::default(), ..Marker::default() };
    let row = |id: i32, r: Option<&RowEstimate>, color: ColorRgba| match r {
        Some(r) => Marker {
            id,
            marker_type: Marker::LINE_STRIP,
            action: Marker::ADD,
            scale: Vector3 { x: 0.05, ..Default::default() },
            color,
            points: vec![
                Point { x: r.line[0], y: r.line[1], z: 0.0 },
                Point { x: r.line[2], y: r.line[3], z: 0.0 },
            ],
            ..base.clone()
        },
        None => Marker { id, action: Marker::DELETE, ..base.clone() },
    };
    let markers = vec![
        row(0, detection.left.as_ref(), ColorRgba { r: 0.1, g: 0.9, b: 0.1, a: 1.0 }),
        row(1, detection.right.as_ref(), ColorRgba { r: 0.1, g: 0.4, b: 1.0, a: 1.0 }),
        Marker {
            ns: "centroids".into(),
            id: 2,
            marker_type: Marker::SPHERE_LIST,
            action: Marker::ADD,
            scale: Vector3 { x: 0.06, y: 0.06, z: 0.06 },
            color: ColorRgba { r: 1.0, g: 0.6, b: 0.0, a: 1.0 },
            points: centroids.iter().map(|c| Point { x: c[0], y: c[1], z: 0.0 }).collect(),
            ..base.clone()
        },
    ];
    MarkerArray { markers }
}

fn header(stamp_s: f64, frame_id: &str) -> Result<Header, WriteError> {
    Ok(Header {
        stamp: Time::from_seconds(stamp_s).ok_or(WriteError::Stamp(stamp_s))?,
        frame_id: frame_id.to_owned(),
    })
}

fn pose3(p: Pose2) -> Pose {
    Pose { position: Point { x: p.x, y: p.y, z: 0.0 }, orientation: Quaternion::from_yaw(p.yaw) }
}
