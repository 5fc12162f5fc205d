//! Fuzzing of the CDR decoder ([`croprow_io::msg::decode`]) for every ROS 2 message type croprow
//! reads or writes: mutated encodings of valid messages (both byte orders) must decode or fail with a
//! `CdrError`, never panic, and whatever decodes must re-encode to bytes that decode to the same
//! message (the decoder reads exactly what the encoder writes, nothing invented).
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test --release -p croprow-io --test fuzz_cdr -- --nocapture`

mod fuzzer;

use std::borrow::Cow;

use croprow_core::Point3;
use croprow_io::cloud::{self, PointFormat, Stamped};
use croprow_io::msg::{
    self, CdrError, ColorRgba, Header, Imu, Marker, MarkerArray, Odometry, Path, Point, PointCloud2, Pose,
    PoseStamped, Quaternion, StringMsg, TfMessage, Time, TransformStamped, Twist, Vector3,
};
use fuzzer::{Campaign, Outcome, Verdict};
use serde::Serialize;
use serde::de::DeserializeOwned;

/// Executions per message type by default (the long run's figures are in docs/fuzzing.md).
const EXECS: usize = 20_000;

fn header(sec: i32, frame: &str) -> Header {
    Header { stamp: Time { sec, nanosec: 123_456_789 }, frame_id: frame.into() }
}

/// Every value encoded in both byte orders.
fn seeds<T: Serialize>(values: &[T]) -> Vec<Vec<u8>> {
    values
        .iter()
        .flat_map(|v| [msg::encode(v).expect("encodes"), msg::encode_big_endian(v).expect("encodes")])
        .collect()
}

/// Re-encodes `value` in the byte order of `bytes`.
fn reencode<T: Serialize>(value: &T, bytes: &[u8]) -> Result<Vec<u8>, CdrError> {
    if bytes.get(1) == Some(&0) { msg::encode_big_endian(value) } else { msg::encode(value) }
}

/// Decode, then check that encode -> decode -> encode is a fixed point.
fn round_trip<T: Serialize + DeserializeOwned>(bytes: &[u8]) -> Outcome {
    let value: T = match msg::decode_owned(bytes) {
        Ok(v) => v,
        Err(e) => {
            let _ = e.to_string();
            return Ok(Verdict::Rejected);
        }
    };
    let once = reencode(&value, bytes).map_err(|e| format!("a decoded message does not re-encode: {e}"))?;
    let again: T =
        msg::decode_owned(&once).map_err(|e| format!("a re-encoded message does not decode: {e}"))?;
    let twice = reencode(&again, bytes).map_err(|e| format!("second re-encode failed: {e}"))?;
    if once != twice {
        return Err("decode(encode(m)) differs from m".into());
    }
    Ok(Verdict::Accepted)
}

fn odometry(frame: &str, child: &str, x: f64) -> Odometry {
    let mut o = Odometry {
        header: header(1_700_000_000, frame),
        child_frame_id: child.into(),
        ..Odometry::default()
    };
    o.pose.pose.position = Point { x, y: -2.5, z: 0.0 };
    o.pose.pose.orientation = Quaternion::from_yaw(0.3);
    o.pose.covariance[0] = 0.01;
    o.twist.twist.linear.x = 0.5;
    o.twist.covariance[35] = 0.02;
    o
}

fn transform(parent: &str, child: &str) -> TransformStamped {
    let mut t =
        TransformStamped { header: header(5, parent), child_frame_id: child.into(), ..Default::default() };
    t.transform.translation = Vector3 { x: 0.5, y: 0.0, z: 1.2 };
    t.transform.rotation = Quaternion::from_rpy(0.0, 0.4, 0.0);
    t
}

fn cloud_seed(format: PointFormat, n: usize) -> PointCloud2<'static> {
    let points: Vec<Point3> = (0..n).map(|i| Point3::new(i as f32 * 0.5, -1.0, 0.25 * i as f32)).collect();
    cloud::build(&Stamped::new(12.5, "velodyne"), &points, &[1.0; 4], &[3; 4], format).expect("builds")
}

#[test]
fn fuzz_cdr_header() {
    let values = [header(0, ""), header(-5, "a"), header(i32::MAX, "velodyne"), header(7, "base_link_xyz")];
    Campaign::new("cdr_header", seeds(&values), EXECS).run(round_trip::<Header>);
}

#[test]
fn fuzz_cdr_string() {
    let values = [StringMsg::default(), StringMsg { data: "Lost: rows out of view".into() }];
    Campaign::new("cdr_string", seeds(&values), EXECS).run(round_trip::<StringMsg>);
}

#[test]
fn fuzz_cdr_twist() {
    let values = [
        Twist::default(),
        Twist { linear: Vector3 { x: 0.5, y: 0.0, z: 0.0 }, angular: Vector3 { x: 0.0, y: 0.0, z: -0.3 } },
    ];
    Campaign::new("cdr_twist", seeds(&values), EXECS).run(round_trip::<Twist>);
}

#[test]
fn fuzz_cdr_odometry() {
    let values = [Odometry::default(), odometry("odom", "base_link", 3.0), odometry("o", "b", -1e6)];
    Campaign::new("cdr_odometry", seeds(&values), EXECS).run(round_trip::<Odometry>);
}

#[test]
fn fuzz_cdr_imu() {
    let mut imu = Imu { header: header(3, "imu_link"), ..Imu::default() };
    imu.angular_velocity.z = 0.04;
    imu.linear_acceleration.z = 9.81;
    imu.orientation_covariance[0] = -1.0;
    Campaign::new("cdr_imu", seeds(&[Imu::default(), imu]), EXECS).run(round_trip::<Imu>);
}

#[test]
fn fuzz_cdr_tf_message() {
    let values = [
        TfMessage::default(),
        TfMessage { transforms: vec![transform("base_link", "velodyne")] },
        TfMessage { transforms: vec![transform("odom", "base_link"), transform("base_link", "mast_1")] },
    ];
    Campaign::new("cdr_tf_message", seeds(&values), EXECS).run(round_trip::<TfMessage>);
}

#[test]
fn fuzz_cdr_path() {
    let pose = |x: f64| PoseStamped {
        header: header(9, "odom"),
        pose: Pose { position: Point { x, y: 1.0, z: 0.0 }, orientation: Quaternion::from_yaw(x) },
    };
    let values = [Path::default(), Path { header: header(9, "odom"), poses: vec![pose(0.0), pose(1.5)] }];
    Campaign::new("cdr_path", seeds(&values), EXECS).run(round_trip::<Path>);
}

#[test]
fn fuzz_cdr_marker_array() {
    let marker = Marker {
        header: header(4, "odom"),
        ns: "rows".into(),
        id: 3,
        marker_type: Marker::LINE_LIST,
        points: vec![Point { x: 1.0, y: 2.0, z: 0.0 }, Point { x: 3.0, y: 2.0, z: 0.0 }],
        colors: vec![ColorRgba { r: 1.0, g: 0.0, b: 0.0, a: 1.0 }],
        text: "lane 2".into(),
        ..Marker::default()
    };
    let values = [MarkerArray::default(), MarkerArray { markers: vec![marker.clone(), marker] }];
    Campaign::new("cdr_marker_array", seeds(&values), EXECS).run(round_trip::<MarkerArray>);
}

#[test]
fn fuzz_cdr_point_cloud2() {
    let values = [
        PointCloud2::default(),
        cloud_seed(PointFormat::VELODYNE, 4),
        cloud_seed(PointFormat { xyz_f64: true, big_endian: true, ..PointFormat::XYZ }, 3),
        cloud_seed(PointFormat { padding: 6, intensity: true, ..PointFormat::XYZ }, 2),
    ];
    let mut points = Vec::new();
    Campaign::new("cdr_point_cloud2", seeds(&values), EXECS).run(|bytes| {
        let Ok(cloud) = msg::decode::<PointCloud2<'_>>(bytes) else { return Ok(Verdict::Rejected) };
        let once = reencode(&cloud, bytes).map_err(|e| format!("a decoded cloud does not re-encode: {e}"))?;
        let again: PointCloud2<'_> = msg::decode(&once).map_err(|e| format!("re-encoded cloud: {e}"))?;
        if reencode(&again, bytes).map_err(|e| e.to_string())? != once {
            return Err("decode(encode(cloud)) differs from cloud".into());
        }
        if !matches!(again.data, Cow::Borrowed(_)) {
            return Err("a decoded cloud copied its data instead of borrowing it".into());
        }
        match cloud::decode(&cloud, &mut points) {
            Ok(()) if points.len() as u64 != u64::from(cloud.width) * u64::from(cloud.height) => {
                Err(format!("{} points decoded from a {}x{} cloud", points.len(), cloud.width, cloud.height))
            }
            Ok(()) => Ok(Verdict::Accepted),
            Err(e) => {
                let _ = e.to_string();
                Ok(Verdict::Rejected)
            }
        }
    });
}
