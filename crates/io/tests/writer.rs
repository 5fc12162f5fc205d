//! Recordings written by `RecordingWriter` are valid MCAP for other readers (the `mcap` crate's own
//! reader, as Foxglove's): ros2 profile, ros2msg schemas, QoS metadata, summary and indexes, and every
//! message decodes back to what was written.

use std::io::Cursor;

use croprow_core::{Detection, Mount, Point3, Pose2, RowEstimate, RowStatus, Twist2};
use croprow_io::RecordingWriter;
use croprow_io::msg::{
    self, Imu, Marker, MarkerArray, Odometry, Path, PointCloud2, StringMsg, TfMessage, Twist,
};

fn row(y: f64) -> RowEstimate {
    RowEstimate {
        line: [0.0, y, 4.0, y + 0.1],
        offset_m: y,
        heading_rad: 0.025,
        curvature_per_m: 0.0,
        confidence: 0.9,
    }
}

fn recording() -> Vec<u8> {
    let mut rec = RecordingWriter::new(Cursor::new(Vec::new())).unwrap();
    rec.write_tf_static(10.0, "velodyne", &Mount::default()).unwrap();
    rec.write_cloud("/velodyne_points", 10.0, "velodyne", &[Point3::new(1.0, 2.0, 3.0)], &[5.0], &[3])
        .unwrap();
    rec.write_odometry("/odometry/filtered", 10.0, Pose2::new(1.0, 2.0, 0.3), Twist2::new(0.8, 0.1)).unwrap();
    rec.write_tf(10.0, Pose2::new(1.0, 2.0, 0.3)).unwrap();
    rec.write_imu("/imu/data", 10.0, "imu_link", [0.0, 0.0, 0.1], [0.1, 0.0, 9.81]).unwrap();
    rec.write_cmd_vel("/cmd_vel", 10.0, Twist2::new(0.7, -0.05)).unwrap();
    let detection = Detection { left: Some(row(0.37)), ..Detection::empty(10.0, RowStatus::Tracking) };
    rec.write_rows("/croprow/rows", &detection, &[[1.0, 0.37], [2.0, 0.38]]).unwrap();
    rec.write_path(
        "/croprow/centre_line",
        10.0,
        "base_link",
        &[Pose2::new(0.0, 0.0, 0.0), Pose2::new(1.0, 0.05, 0.05)],
    )
    .unwrap();
    rec.write_status("/croprow/status", 10.0, "tracking").unwrap();
    rec.finish().unwrap().into_inner()
}

#[test]
fn summary_schemas_and_metadata_are_present() {
    let bytes = recording();
    let summary = mcap::Summary::read(&bytes).unwrap().expect("summary section");
    assert!(!summary.chunk_indexes.is_empty());
    assert_eq!(summary.stats.as_ref().unwrap().message_count, 9);
    let channel = |topic: &str| summary.channels.values().find(|c| c.topic == topic).unwrap().clone();
    for (topic, ty) in [
        ("/velodyne_points", "sensor_msgs/msg/PointCloud2"),
        ("/odometry/filtered", "nav_msgs/msg/Odometry"),
        ("/tf", "tf2_msgs/msg/TFMessage"),
        ("/tf_static", "tf2_msgs/msg/TFMessage"),
        ("/imu/data", "sensor_msgs/msg/Imu"),
        ("/cmd_vel", "geometry_msgs/msg/Twist"),
        ("/croprow/rows", "visualization_msgs/msg/MarkerArray"),
        ("/croprow/centre_line", "nav_msgs/msg/Path"),
        ("/croprow/status", "std_msgs/msg/String"),
    ] {
        let c = channel(topic);
        let schema = c.schema.as_ref().unwrap();
        assert_eq!(
            (schema.name.as_str(), schema.encoding.as_str(), c.message_encoding.as_str()),
            (ty, "ros2msg", "cdr")
        );
        assert!(c.metadata["offered_qos_profiles"].contains("reliability: 1"), "{topic}");
    }
    // Late joiners (Foxglove, `ros2 bag play`) must receive the mount: transient-local durability.
    assert!(channel("/tf_static").metadata["offered_qos_profiles"].contains("durability: 1"));
    let marker_schema =
        String::from_utf8(channel("/croprow/rows").schema.as_ref().unwrap().data.to_vec()).unwrap();
    assert!(
        marker_schema.contains("MSG: visualization_msgs/Marker\n")
            && marker_schema.contains("MSG: std_msgs/ColorRGBA")
    );
}

#[test]
fn every_message_decodes_back() {
    let bytes = recording();
    let mut seen = 0;
    for message in mcap::MessageStream::new(&bytes).unwrap() {
        let m = message.unwrap();
        assert_eq!(m.log_time, 10_000_000_000);
        let data = &m.data[..];
        match m.channel.topic.as_str() {
            "/velodyne_points" => {
                let c: PointCloud2<'_> = msg::decode(data).unwrap();
                assert_eq!((c.point_step, c.header.frame_id.as_str()), (18, "velodyne"));
                let names: Vec<&str> = c.fields.iter().map(|f| f.name.as_str()).collect();
                assert_eq!(names, ["x", "y", "z", "intensity", "ring"]);
            }
            "/odometry/filtered" => {
                let o: Odometry = msg::decode_owned(data).unwrap();
                assert_eq!((o.header.frame_id.as_str(), o.child_frame_id.as_str()), ("odom", "base_link"));
                assert!((o.pose.pose.orientation.yaw() - 0.3).abs() < 1e-12 && o.twist.twist.linear.x == 0.8);
            }
            "/tf" | "/tf_static" => {
                let t: TfMessage = msg::decode_owned(data).unwrap();
                assert_eq!(t.transforms.len(), 1);
            }
            "/imu/data" => assert_eq!(msg::decode_owned::<Imu>(data).unwrap().linear_acceleration.z, 9.81),
            "/cmd_vel" => {
                let t: Twist = msg::decode_owned(data).unwrap();
                assert_eq!((t.linear.x, t.angular.z), (0.7, -0.05));
            }
            "/croprow/rows" => {
                let a: MarkerArray = msg::decode_owned(data).unwrap();
                let kinds: Vec<(i32, i32)> = a.markers.iter().map(|m| (m.marker_type, m.action)).collect();
                // Left row drawn, right row deleted (not detected), centroids as spheres.
                assert_eq!(kinds[0], (Marker::LINE_STRIP, Marker::ADD));
                assert_eq!(kinds[1].1, Marker::DELETE);
                assert_eq!(kinds[2], (Marker::SPHERE_LIST, Marker::ADD));
                assert_eq!(a.markers[0].points[1].y, 0.47);
                assert_eq!(a.markers[2].points.len(), 2);
            }
            "/croprow/centre_line" => assert_eq!(msg::decode_owned::<Path>(data).unwrap().poses.len(), 2),
            "/croprow/status" => assert_eq!(msg::decode_owned::<StringMsg>(data).unwrap().data, "tracking"),
            other => panic!("unexpected topic {other}"),
        }
        seen += 1;
    }
    assert_eq!(seen, 9);
}

#[test]
fn bad_stamps_are_refused() {
    let mut rec = RecordingWriter::new(Cursor::new(Vec::new())).unwrap();
    assert!(rec.write_cmd_vel("/cmd_vel", f64::NAN, Twist2::ZERO).is_err());
    assert!(rec.write_cmd_vel("/cmd_vel", -1.0, Twist2::ZERO).is_err());
    assert!(rec.write_status("/s", 1e12, "x").is_err());
}
