//! ROS 2 message types, written once: serde structs whose field order is the CDR wire order, plus the
//! `ros2msg` definition text a recorder stores as the MCAP schema (the same form rosbag2 writes:
//! the message's own definition, then every dependency after a `MSG: pkg/Name` separator).
//!
//! Encoding is XCDR1 ("plain CDR") with the 4-byte encapsulation header ROS 2 puts in front of every
//! serialized message: `00 01 00 00` little endian, `00 00 00 00` big endian. [`decode`] reads both;
//! [`encode`] writes little endian (what every ROS 2 platform in the field produces) and
//! [`encode_big_endian`] exists for tests and odd hardware.
//!
//! ```
//! use croprow_io::msg::{self, Time, Twist, Vector3};
//! let cmd = Twist { linear: Vector3 { x: 0.5, y: 0.0, z: 0.0 }, angular: Vector3::default() };
//! let bytes = msg::encode(&cmd).unwrap();
//! let back: Twist = msg::decode(&bytes).unwrap();
//! assert_eq!(back, cmd);
//! assert_eq!(Time::from_seconds(1.25).unwrap().as_seconds(), 1.25);
//! ```

use std::borrow::Cow;

use byteorder::{BigEndian, LittleEndian};
use serde::{Deserialize, Serialize, de::DeserializeOwned};
use serde_big_array::BigArray;
use thiserror::Error;

/// The encapsulation header of a little-endian CDR message (`CDR_LE`).
const CDR_LE: [u8; 4] = [0, 1, 0, 0];
/// The encapsulation header of a big-endian CDR message (`CDR_BE`).
const CDR_BE: [u8; 4] = [0, 0, 0, 0];

/// A message could not be encoded or decoded.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum CdrError {
    /// Fewer than 4 bytes: there is no encapsulation header.
    #[error("CDR message of {0} bytes is too short for the 4-byte encapsulation header")]
    TooShort(usize),
    /// The encapsulation header names an encoding other than plain CDR.
    #[error("unsupported CDR encapsulation {0:02x?} (expected 00 01 = CDR_LE or 00 00 = CDR_BE)")]
    Encapsulation([u8; 2]),
    /// The payload does not match the message layout (truncated, wrong type, bad UTF-8).
    #[error("CDR payload does not match the message layout: {0}")]
    Payload(#[from] cdr_encoding::Error),
}

/// Decodes a ROS 2 CDR message (encapsulation header + payload), little or big endian.
///
/// Borrowing types (e.g. [`PointCloud2`]'s `data`) borrow from `bytes`; nothing is copied.
pub fn decode<'de, T: Deserialize<'de>>(bytes: &'de [u8]) -> Result<T, CdrError> {
    let (header, payload) = bytes.split_at_checked(4).ok_or(CdrError::TooShort(bytes.len()))?;
    // CDR alignment is counted from the end of the encapsulation header, so the payload is decoded on
    // its own.
    match [header[0], header[1]] {
        [0, 1] => Ok(cdr_encoding::from_bytes::<T, LittleEndian>(payload)?.0),
        [0, 0] => Ok(cdr_encoding::from_bytes::<T, BigEndian>(payload)?.0),
        other => Err(CdrError::Encapsulation(other)),
    }
}

/// Decodes into an owned value (convenience for types that do not borrow).
pub fn decode_owned<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, CdrError> {
    decode(bytes)
}

/// Encodes a message as little-endian CDR with its encapsulation header.
pub fn encode<T: Serialize>(msg: &T) -> Result<Vec<u8>, CdrError> {
    let mut out = CDR_LE.to_vec();
    encode_into::<T, LittleEndian>(msg, &mut out)?;
    Ok(out)
}

/// Encodes a message as big-endian CDR with its encapsulation header.
pub fn encode_big_endian<T: Serialize>(msg: &T) -> Result<Vec<u8>, CdrError> {
    let mut out = CDR_BE.to_vec();
    encode_into::<T, BigEndian>(msg, &mut out)?;
    Ok(out)
}

/// Encodes into a reused buffer (cleared first), little endian: no allocation once the buffer is
/// large enough.
pub fn encode_to<T: Serialize>(msg: &T, out: &mut Vec<u8>) -> Result<(), CdrError> {
    out.clear();
    out.extend_from_slice(&CDR_LE);
    encode_into::<T, LittleEndian>(msg, out)
}

fn encode_into<T: Serialize, BO: byteorder::ByteOrder>(msg: &T, out: &mut Vec<u8>) -> Result<(), CdrError> {
    // The serializer counts alignment from its own start, i.e. from the end of the header, as CDR wants.
    cdr_encoding::to_writer::<T, BO, _>(&mut *out, msg)?;
    Ok(())
}

/// A ROS 2 message type: its fully qualified name and its `ros2msg` definition text.
pub trait RosMessage {
    /// The type name as ROS 2 and MCAP schemas write it, e.g. `sensor_msgs/msg/PointCloud2`.
    const TYPE_NAME: &'static str;
    /// The full `ros2msg` definition with its dependencies, as rosbag2 stores it in MCAP schemas.
    fn definition() -> String;
}

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds since an epoch (the clock of the recording).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, in [0, 1e9).
    pub nanosec: u32,
}

impl Time {
    /// The time as seconds (f64: nanosecond resolution holds for ~100 days of sim time, microseconds
    /// for Unix stamps).
    pub fn as_seconds(&self) -> f64 {
        self.sec as f64 + self.nanosec as f64 * 1e-9
    }

    /// The time in nanoseconds (the unit of MCAP log times); `None` before the epoch.
    pub fn as_nanos(&self) -> Option<u64> {
        u64::try_from(self.sec).ok().map(|s| s * 1_000_000_000 + self.nanosec as u64)
    }

    /// A time from seconds; `None` when not finite or outside the `i32` seconds range.
    pub fn from_seconds(t_s: f64) -> Option<Self> {
        if !t_s.is_finite() || t_s < i32::MIN as f64 || t_s >= i32::MAX as f64 {
            return None;
        }
        let sec = t_s.floor();
        let mut nanosec = ((t_s - sec) * 1e9).round() as u32;
        let mut sec = sec as i32;
        if nanosec >= 1_000_000_000 {
            nanosec -= 1_000_000_000;
            sec = sec.checked_add(1)?;
        }
        Some(Self { sec, nanosec })
    }
}

/// `builtin_interfaces/msg/Duration`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Duration {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds, in [0, 1e9).
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`: stamp and coordinate frame of the data.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Header {
    /// When the data was acquired.
    pub stamp: Time,
    /// The frame the data is expressed in.
    pub frame_id: String,
}

/// `std_msgs/msg/String`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct StringMsg {
    /// The text.
    pub data: String,
}

/// `std_msgs/msg/ColorRGBA`, components in [0, 1].
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ColorRgba {
    /// Red.
    pub r: f32,
    /// Green.
    pub g: f32,
    /// Blue.
    pub b: f32,
    /// Alpha (opacity).
    pub a: f32,
}

/// `geometry_msgs/msg/Vector3`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Vector3 {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
}

/// `geometry_msgs/msg/Point`, m.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Point {
    /// x, m.
    pub x: f64,
    /// y, m.
    pub y: f64,
    /// z, m.
    pub z: f64,
}

/// `geometry_msgs/msg/Quaternion` (x, y, z, w).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Quaternion {
    /// x.
    pub x: f64,
    /// y.
    pub y: f64,
    /// z.
    pub z: f64,
    /// w.
    pub w: f64,
}

impl Default for Quaternion {
    fn default() -> Self {
        Self::IDENTITY
    }
}

impl Quaternion {
    /// No rotation.
    pub const IDENTITY: Quaternion = Quaternion { x: 0.0, y: 0.0, z: 0.0, w: 1.0 };

    /// A rotation about z by `yaw` rad.
    pub fn from_yaw(yaw: f64) -> Self {
        let (s, c) = (0.5 * yaw).sin_cos();
        Self { x: 0.0, y: 0.0, z: s, w: c }
    }

    /// A rotation from roll, pitch, yaw (rad; R = Rz(yaw) Ry(pitch) Rx(roll), as ROS `setRPY`).
    pub fn from_rpy(roll: f64, pitch: f64, yaw: f64) -> Self {
        let (sr, cr) = (0.5 * roll).sin_cos();
        let (sp, cp) = (0.5 * pitch).sin_cos();
        let (sy, cy) = (0.5 * yaw).sin_cos();
        Self {
            x: sr * cp * cy - cr * sp * sy,
            y: cr * sp * cy + sr * cp * sy,
            z: cr * cp * sy - sr * sp * cy,
            w: cr * cp * cy + sr * sp * sy,
        }
    }

    /// The heading (rotation about z) of this orientation, rad in (-π, π]; for a planar robot the
    /// yaw of `odom -> base_link`. Works for any norm (the quaternion need not be normalised).
    pub fn yaw(&self) -> f64 {
        (2.0 * (self.w * self.z + self.x * self.y)).atan2(1.0 - 2.0 * (self.y * self.y + self.z * self.z))
    }

    /// The components as `[x, y, z, w]`.
    pub fn to_array(&self) -> [f64; 4] {
        [self.x, self.y, self.z, self.w]
    }
}

/// `geometry_msgs/msg/Pose`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Pose {
    /// Position, m.
    pub position: Point,
    /// Orientation.
    pub orientation: Quaternion,
}

/// `geometry_msgs/msg/Twist`: linear (m/s) and angular (rad/s) velocity.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Twist {
    /// Linear velocity, m/s.
    pub linear: Vector3,
    /// Angular velocity, rad/s.
    pub angular: Vector3,
}

/// `geometry_msgs/msg/PoseWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PoseWithCovariance {
    /// The pose.
    pub pose: Pose,
    /// Row-major 6x6 covariance of (x, y, z, roll, pitch, yaw).
    #[serde(with = "BigArray")]
    pub covariance: [f64; 36],
}

impl Default for PoseWithCovariance {
    fn default() -> Self {
        Self { pose: Pose::default(), covariance: [0.0; 36] }
    }
}

/// `geometry_msgs/msg/TwistWithCovariance`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct TwistWithCovariance {
    /// The twist.
    pub twist: Twist,
    /// Row-major 6x6 covariance.
    #[serde(with = "BigArray")]
    pub covariance: [f64; 36],
}

impl Default for TwistWithCovariance {
    fn default() -> Self {
        Self { twist: Twist::default(), covariance: [0.0; 36] }
    }
}

/// `geometry_msgs/msg/Transform`: translation (m) and rotation of a child frame in its parent.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct Transform {
    /// Translation, m.
    pub translation: Vector3,
    /// Rotation.
    pub rotation: Quaternion,
}

/// `geometry_msgs/msg/TransformStamped`: `header.frame_id -> child_frame_id`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TransformStamped {
    /// Stamp and parent frame.
    pub header: Header,
    /// The child frame.
    pub child_frame_id: String,
    /// The child frame's pose in the parent.
    pub transform: Transform,
}

/// `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PoseStamped {
    /// Stamp and frame.
    pub header: Header,
    /// The pose.
    pub pose: Pose,
}

/// `tf2_msgs/msg/TFMessage`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct TfMessage {
    /// The transforms.
    pub transforms: Vec<TransformStamped>,
}

/// `sensor_msgs/msg/PointField`: one field of a [`PointCloud2`] point.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct PointField {
    /// Field name (`x`, `y`, `z`, `intensity`, `ring`, ...).
    pub name: String,
    /// Byte offset inside the point.
    pub offset: u32,
    /// Datatype code, see the `PointField::*` constants.
    pub datatype: u8,
    /// Number of elements (1 for scalars).
    pub count: u32,
}

impl PointField {
    /// `int8`.
    pub const INT8: u8 = 1;
    /// `uint8`.
    pub const UINT8: u8 = 2;
    /// `int16`.
    pub const INT16: u8 = 3;
    /// `uint16`.
    pub const UINT16: u8 = 4;
    /// `int32`.
    pub const INT32: u8 = 5;
    /// `uint32`.
    pub const UINT32: u8 = 6;
    /// `float32`.
    pub const FLOAT32: u8 = 7;
    /// `float64`.
    pub const FLOAT64: u8 = 8;

    /// A scalar field.
    pub fn new(name: &str, offset: u32, datatype: u8) -> Self {
        Self { name: name.to_owned(), offset, datatype, count: 1 }
    }

    /// Size in bytes of one element of `datatype`, or `None` for an unknown code.
    pub fn datatype_size(datatype: u8) -> Option<u32> {
        match datatype {
            Self::INT8 | Self::UINT8 => Some(1),
            Self::INT16 | Self::UINT16 => Some(2),
            Self::INT32 | Self::UINT32 | Self::FLOAT32 => Some(4),
            Self::FLOAT64 => Some(8),
            _ => None,
        }
    }
}

/// `sensor_msgs/msg/PointCloud2`. `data` borrows from the decoded bytes (no copy) or owns its buffer
/// when built for writing. Decode the points with [`crate::cloud`].
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PointCloud2<'a> {
    /// Stamp and sensor frame.
    pub header: Header,
    /// Rows (1 for an unorganised cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// Layout of one point.
    pub fields: Vec<PointField>,
    /// True when `data` is big endian.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// The points, `row_step * height` bytes.
    #[serde(with = "serde_bytes", borrow)]
    pub data: Cow<'a, [u8]>,
    /// True when no point is invalid.
    pub is_dense: bool,
}

/// `sensor_msgs/msg/Imu`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Imu {
    /// Stamp and IMU frame.
    pub header: Header,
    /// Orientation estimate.
    pub orientation: Quaternion,
    /// Row-major 3x3 covariance; element 0 = -1 means "no orientation".
    pub orientation_covariance: [f64; 9],
    /// Angular velocity, rad/s.
    pub angular_velocity: Vector3,
    /// Row-major 3x3 covariance.
    pub angular_velocity_covariance: [f64; 9],
    /// Linear acceleration, m/s².
    pub linear_acceleration: Vector3,
    /// Row-major 3x3 covariance.
    pub linear_acceleration_covariance: [f64; 9],
}

impl Default for Imu {
    fn default() -> Self {
        Self {
            header: Header::default(),
            orientation: Quaternion::IDENTITY,
            orientation_covariance: [0.0; 9],
            angular_velocity: Vector3::default(),
            angular_velocity_covariance: [0.0; 9],
            linear_acceleration: Vector3::default(),
            linear_acceleration_covariance: [0.0; 9],
        }
    }
}

/// `nav_msgs/msg/Odometry`: pose of `child_frame_id` in `header.frame_id`, twist in `child_frame_id`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Odometry {
    /// Stamp and parent frame (`odom`).
    pub header: Header,
    /// The body frame (`base_link`).
    pub child_frame_id: String,
    /// Pose in the parent frame.
    pub pose: PoseWithCovariance,
    /// Velocity in the child frame.
    pub twist: TwistWithCovariance,
}

/// `nav_msgs/msg/Path`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Path {
    /// Stamp and frame of the path.
    pub header: Header,
    /// The poses along the path.
    pub poses: Vec<PoseStamped>,
}

/// `sensor_msgs/msg/CompressedImage` (only as a member of [`Marker`]).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct CompressedImage {
    /// Stamp and frame.
    pub header: Header,
    /// Image format (`jpeg`, `png`).
    pub format: String,
    /// Compressed bytes.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `visualization_msgs/msg/UVCoordinate`.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct UvCoordinate {
    /// u.
    pub u: f32,
    /// v.
    pub v: f32,
}

/// `visualization_msgs/msg/MeshFile`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct MeshFile {
    /// File name.
    pub filename: String,
    /// File content.
    #[serde(with = "serde_bytes")]
    pub data: Vec<u8>,
}

/// `visualization_msgs/msg/Marker` (ROS 2 Humble and later layout).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Marker {
    /// Stamp and frame.
    pub header: Header,
    /// Namespace.
    pub ns: String,
    /// Id, unique within the namespace.
    pub id: i32,
    /// Shape, see the `Marker::*` type constants.
    #[serde(rename = "type")]
    pub marker_type: i32,
    /// `ADD`, `DELETE` or `DELETEALL`.
    pub action: i32,
    /// Pose of the marker frame.
    pub pose: Pose,
    /// Size, m (line width in `scale.x` for lines).
    pub scale: Vector3,
    /// Colour.
    pub color: ColorRgba,
    /// How long the marker lives (0 = forever).
    pub lifetime: Duration,
    /// Re-transform the marker every frame.
    pub frame_locked: bool,
    /// Points of lists and strips, m.
    pub points: Vec<Point>,
    /// Per-point colours (empty = `color`).
    pub colors: Vec<ColorRgba>,
    /// Texture resource.
    pub texture_resource: String,
    /// Texture image.
    pub texture: CompressedImage,
    /// Texture coordinates.
    pub uv_coordinates: Vec<UvCoordinate>,
    /// Text of `TEXT_VIEW_FACING`.
    pub text: String,
    /// Mesh resource.
    pub mesh_resource: String,
    /// Embedded mesh.
    pub mesh_file: MeshFile,
    /// Use the mesh's own materials.
    pub mesh_use_embedded_materials: bool,
}

impl Marker {
    /// Line strip: consecutive points joined.
    pub const LINE_STRIP: i32 = 4;
    /// Line list: pairs of points are segments.
    pub const LINE_LIST: i32 = 5;
    /// Sphere list.
    pub const SPHERE_LIST: i32 = 7;
    /// Points (squares of `scale.x` by `scale.y`).
    pub const POINTS: i32 = 8;
    /// Text facing the viewer.
    pub const TEXT_VIEW_FACING: i32 = 9;
    /// Add or modify.
    pub const ADD: i32 = 0;
    /// Delete this marker.
    pub const DELETE: i32 = 2;
    /// Delete every marker of the namespace.
    pub const DELETEALL: i32 = 3;
}

/// `visualization_msgs/msg/MarkerArray`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct MarkerArray {
    /// The markers.
    pub markers: Vec<Marker>,
}

// ---- ros2msg definitions (comments stripped, constants kept where a reader needs them) ----

const TIME: &str = "int32 sec\nuint32 nanosec\n";
const DURATION: &str = "int32 sec\nuint32 nanosec\n";
const HEADER: &str = "builtin_interfaces/Time stamp\nstring frame_id\n";
const VECTOR3: &str = "float64 x\nfloat64 y\nfloat64 z\n";
const POINT: &str = "float64 x\nfloat64 y\nfloat64 z\n";
const QUATERNION: &str = "float64 x 0\nfloat64 y 0\nfloat64 z 0\nfloat64 w 1\n";
const POSE: &str = "Point position\nQuaternion orientation\n";
const TWIST: &str = "Vector3  linear\nVector3  angular\n";
const TRANSFORM: &str = "Vector3 translation\nQuaternion rotation\n";
const TRANSFORM_STAMPED: &str = "std_msgs/Header header\nstring child_frame_id\nTransform transform\n";
const POSE_STAMPED: &str = "std_msgs/Header header\nPose pose\n";
const COLOR_RGBA: &str = "float32 r\nfloat32 g\nfloat32 b\nfloat32 a\n";
const POINT_FIELD: &str = "uint8 INT8    = 1\nuint8 UINT8   = 2\nuint8 INT16   = 3\nuint8 UINT16  = 4\n\
uint8 INT32   = 5\nuint8 UINT32  = 6\nuint8 FLOAT32 = 7\nuint8 FLOAT64 = 8\n\
string name\nuint32 offset\nuint8  datatype\nuint32 count\n";
const COMPRESSED_IMAGE: &str = "std_msgs/Header header\nstring format\nuint8[] data\n";
const UV_COORDINATE: &str = "float32 u\nfloat32 v\n";
const MESH_FILE: &str = "string filename\nuint8[] data\n";

/// Builds a definition: the main text, then each dependency as rosbag2 separates them.
fn with_deps(main: &str, deps: &[(&str, &str)]) -> String {
    let mut s = main.to_owned();
    for (name, text) in deps {
        s.push_str("================================================================================\nMSG: ");
        s.push_str(name);
        s.push('\n');
        s.push_str(text);
    }
    s
}

const DEP_HEADER: [(&str, &str); 2] = [("std_msgs/Header", HEADER), ("builtin_interfaces/Time", TIME)];

macro_rules! ros_message {
    ($ty:ty, $name:literal, $main:expr, [$($dep:expr),* $(,)?]) => {
        impl RosMessage for $ty {
            const TYPE_NAME: &'static str = $name;
            fn definition() -> String {
                let deps: Vec<(&str, &str)> = vec![$($dep),*];
                with_deps($main, &deps)
            }
        }
    };
}

ros_message!(StringMsg, "std_msgs/msg/String", "string data\n", []);
ros_message!(Twist, "geometry_msgs/msg/Twist", TWIST, [("geometry_msgs/Vector3", VECTOR3)]);
ros_message!(
    PointCloud2<'_>,
    "sensor_msgs/msg/PointCloud2",
    "std_msgs/Header header\nuint32 height\nuint32 width\nPointField[] fields\nbool    is_bigendian\n\
uint32  point_step\nuint32  row_step\nuint8[] data\nbool is_dense\n",
    [DEP_HEADER[0], DEP_HEADER[1], ("sensor_msgs/PointField", POINT_FIELD)]
);
ros_message!(
    Imu,
    "sensor_msgs/msg/Imu",
    "std_msgs/Header header\ngeometry_msgs/Quaternion orientation\nfloat64[9] orientation_covariance\n\
geometry_msgs/Vector3 angular_velocity\nfloat64[9] angular_velocity_covariance\n\
geometry_msgs/Vector3 linear_acceleration\nfloat64[9] linear_acceleration_covariance\n",
    [
        DEP_HEADER[0],
        DEP_HEADER[1],
        ("geometry_msgs/Quaternion", QUATERNION),
        ("geometry_msgs/Vector3", VECTOR3)
    ]
);
ros_message!(
    Odometry,
    "nav_msgs/msg/Odometry",
    "std_msgs/Header header\nstring child_frame_id\ngeometry_msgs/PoseWithCovariance pose\n\
geometry_msgs/TwistWithCovariance twist\n",
    [
        DEP_HEADER[0],
        DEP_HEADER[1],
        ("geometry_msgs/PoseWithCovariance", "Pose pose\nfloat64[36] covariance\n"),
        ("geometry_msgs/Pose", POSE),
        ("geometry_msgs/Point", POINT),
        ("geometry_msgs/Quaternion", QUATERNION),
        ("geometry_msgs/TwistWithCovariance", "Twist twist\nfloat64[36] covariance\n"),
        ("geometry_msgs/Twist", TWIST),
        ("geometry_msgs/Vector3", VECTOR3),
    ]
);
ros_message!(
    Path,
    "nav_msgs/msg/Path",
    "std_msgs/Header header\ngeometry_msgs/PoseStamped[] poses\n",
    [
        DEP_HEADER[0],
        DEP_HEADER[1],
        ("geometry_msgs/PoseStamped", POSE_STAMPED),
        ("geometry_msgs/Pose", POSE),
        ("geometry_msgs/Point", POINT),
        ("geometry_msgs/Quaternion", QUATERNION),
    ]
);
ros_message!(
    TfMessage,
    "tf2_msgs/msg/TFMessage",
    "geometry_msgs/TransformStamped[] transforms\n",
    [
        ("geometry_msgs/TransformStamped", TRANSFORM_STAMPED),
        DEP_HEADER[0],
        DEP_HEADER[1],
        ("geometry_msgs/Transform", TRANSFORM),
        ("geometry_msgs/Vector3", VECTOR3),
        ("geometry_msgs/Quaternion", QUATERNION),
    ]
);
ros_message!(
    MarkerArray,
    "visualization_msgs/msg/MarkerArray",
    "Marker[] markers\n",
    [
        (
            "visualization_msgs/Marker",
            "int32 ARROW=0\nint32 CUBE=1\nint32 SPHERE=2\nint32 CYLINDER=3\nint32 LINE_STRIP=4\n\
int32 LINE_LIST=5\nint32 CUBE_LIST=6\nint32 SPHERE_LIST=7\nint32 POINTS=8\nint32 TEXT_VIEW_FACING=9\n\
int32 MESH_RESOURCE=10\nint32 TRIANGLE_LIST=11\nint32 ARROW_STRIP=12\nint32 ADD=0\nint32 MODIFY=0\n\
int32 DELETE=2\nint32 DELETEALL=3\n\
std_msgs/Header header\nstring ns\nint32 id\nint32 type\nint32 action\ngeometry_msgs/Pose pose\n\
geometry_msgs/Vector3 scale\nstd_msgs/ColorRGBA color\nbuiltin_interfaces/Duration lifetime\n\
bool frame_locked\ngeometry_msgs/Point[] points\nstd_msgs/ColorRGBA[] colors\nstring texture_resource\n\
sensor_msgs/CompressedImage texture\nUVCoordinate[] uv_coordinates\nstring text\nstring mesh_resource\n\
MeshFile mesh_file\nbool mesh_use_embedded_materials\n"
        ),
        DEP_HEADER[0],
        DEP_HEADER[1],
        ("geometry_msgs/Pose", POSE),
        ("geometry_msgs/Point", POINT),
        ("geometry_msgs/Quaternion", QUATERNION),
        ("geometry_msgs/Vector3", VECTOR3),
        ("std_msgs/ColorRGBA", COLOR_RGBA),
        ("builtin_interfaces/Duration", DURATION),
        ("sensor_msgs/CompressedImage", COMPRESSED_IMAGE),
        ("visualization_msgs/UVCoordinate", UV_COORDINATE),
        ("visualization_msgs/MeshFile", MESH_FILE),
    ]
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_round_trips_in_both_endiannesses() {
        let h = Header { stamp: Time { sec: 12, nanosec: 345 }, frame_id: "velodyne".into() };
        let le = encode(&h).unwrap();
        let be = encode_big_endian(&h).unwrap();
        assert_eq!(&le[..4], &CDR_LE);
        assert_eq!(&be[..4], &CDR_BE);
        assert_ne!(le, be);
        assert_eq!(decode_owned::<Header>(&le).unwrap(), h);
        assert_eq!(decode_owned::<Header>(&be).unwrap(), h);
    }

    #[test]
    fn header_wire_layout_matches_ros2() {
        // sec=1, nanosec=2, frame_id "a": 4 + 4 + (len 2) + "a\0", little endian.
        let h = Header { stamp: Time { sec: 1, nanosec: 2 }, frame_id: "a".into() };
        assert_eq!(encode(&h).unwrap(), [0, 1, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 2, 0, 0, 0, b'a', 0]);
    }

    #[test]
    fn odometry_aligns_f64_after_strings() {
        let mut o = Odometry { child_frame_id: "base_link".into(), ..Odometry::default() };
        o.header.frame_id = "odom".into();
        o.pose.pose.position.x = 1.5;
        o.pose.covariance[35] = 0.25;
        o.twist.twist.angular.z = -0.3;
        let back: Odometry = decode_owned(&encode(&o).unwrap()).unwrap();
        assert_eq!(back, o);
        let back: Odometry = decode_owned(&encode_big_endian(&o).unwrap()).unwrap();
        assert_eq!(back, o);
    }

    #[test]
    fn marker_array_round_trips() {
        let m = Marker {
            ns: "rows".into(),
            marker_type: Marker::LINE_LIST,
            points: vec![Point { x: 1.0, y: 2.0, z: 0.0 }, Point { x: 3.0, y: 2.0, z: 0.0 }],
            color: ColorRgba { r: 1.0, g: 0.0, b: 0.0, a: 1.0 },
            ..Marker::default()
        };
        let a = MarkerArray { markers: vec![m.clone(), m] };
        assert_eq!(decode_owned::<MarkerArray>(&encode(&a).unwrap()).unwrap(), a);
    }

    #[test]
    fn truncated_or_foreign_bytes_are_errors() {
        let bytes = encode(&Odometry::default()).unwrap();
        assert!(matches!(decode_owned::<Odometry>(&bytes[..bytes.len() - 3]), Err(CdrError::Payload(_))));
        assert!(matches!(decode_owned::<Odometry>(&bytes[..2]), Err(CdrError::TooShort(2))));
        let mut xcdr2 = bytes.clone();
        xcdr2[1] = 7;
        assert!(matches!(decode_owned::<Odometry>(&xcdr2), Err(CdrError::Encapsulation([0, 7]))));
    }

    #[test]
    fn definitions_list_dependencies_like_rosbag2() {
        let d = Odometry::definition();
        assert!(d.starts_with("std_msgs/Header header\n"));
        assert!(d.contains("\nMSG: geometry_msgs/TwistWithCovariance\n"));
        assert_eq!(d.matches("MSG: ").count(), 9);
        assert_eq!(TfMessage::TYPE_NAME, "tf2_msgs/msg/TFMessage");
    }

    #[test]
    fn time_conversions() {
        let t = Time::from_seconds(3.999_999_999_9).unwrap();
        assert_eq!((t.sec, t.nanosec), (4, 0));
        assert_eq!(Time::from_seconds(f64::NAN), None);
        assert_eq!(Time { sec: 2, nanosec: 5 }.as_nanos(), Some(2_000_000_005));
        assert_eq!(Time { sec: -1, nanosec: 0 }.as_nanos(), None);
    }

    #[test]
    fn yaw_of_quaternion() {
        let q = Quaternion::from_rpy(0.1, -0.2, 2.5);
        assert!((q.yaw() - 2.5).abs() < 1e-12);
        assert!((Quaternion::from_yaw(-3.0).yaw() + 3.0).abs() < 1e-12);
    }
}
