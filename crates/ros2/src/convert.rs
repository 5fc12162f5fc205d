//! Core types <-> the ROS 2 message structs of `croprow_io::msg`: odometry in, commands, rows and the
//! tracked path out. Pure functions; the stamps are the messages' own (the odometry clock).

use croprow_core::control::Path as TrackPath;
use croprow_core::{Detection, Mount, Pose2, Twist2};
use croprow_io::msg::{
    Header, MarkerArray, Odometry, Path, Point, Pose, PoseStamped, Quaternion, Time, Twist, Vector3,
};
use nalgebra::Isometry3;

/// Most poses a published path holds (the reference is a few metres; a turn is a few arcs).
const MAX_PATH_POSES: usize = 400;

/// A header; a stamp that is no ROS time (negative, non-finite) is written as zero.
pub(crate) fn header(stamp_s: f64, frame_id: &str) -> Header {
    Header { stamp: Time::from_seconds(stamp_s).unwrap_or_default(), frame_id: frame_id.to_owned() }
}

/// The planar pose and body twist of a `nav_msgs/Odometry` (`header.frame_id -> child_frame_id`).
pub(crate) fn odometry(msg: &Odometry) -> (Pose2, Twist2) {
    let p = &msg.pose.pose;
    let t = &msg.twist.twist;
    (Pose2::new(p.position.x, p.position.y, p.orientation.yaw()), Twist2::new(t.linear.x, t.angular.z))
}

/// A `geometry_msgs/Twist` for `base_link`: forward speed and yaw rate only.
pub fn twist(cmd: Twist2) -> Twist {
    Twist {
        linear: Vector3 { x: cmd.v, ..Vector3::default() },
        angular: Vector3 { z: cmd.omega, ..Vector3::default() },
    }
}

/// `base_link -> sensor` from a looked-up transform; refused when implausible (see [`Mount::validate`]).
pub(crate) fn mount(iso: &Isometry3<f64>) -> Result<Mount, croprow_core::ConfigError> {
    let t = iso.translation.vector;
    let q = iso.rotation.quaternion();
    Mount::from_translation_quaternion([t.x, t.y, t.z], [q.i, q.j, q.k, q.w])
}

/// The rows of a detection as a `MarkerArray` in `frame_id` (`base_link`) at the scan stamp: each row a
/// line (deleted while not seen, so stale rows vanish), the detector's centroids as spheres.
pub(crate) fn rows(detection: &Detection, centroids: &[[f64; 2]], frame_id: &str) -> MarkerArray {
    croprow_io::write::row_markers(detection, centroids, header(detection.stamp_s, frame_id))
}

/// The tracked path sampled every `spacing_m` (and at its end) as a `nav_msgs/Path` in `frame_id`
/// (`odom`), at most [`MAX_PATH_POSES`] poses.
pub(crate) fn path(track: Option<&TrackPath>, stamp_s: f64, frame_id: &str, spacing_m: f64) -> Path {
    let h = header(stamp_s, frame_id);
    let Some(track) = track.filter(|p| !p.is_empty()) else {
        return Path { header: h, poses: Vec::new() };
    };
    let length_m = track.length_m();
    let step_m = spacing_m.max(length_m / (MAX_PATH_POSES - 1) as f64);
    let count = ((length_m / step_m).floor() as usize).min(MAX_PATH_POSES - 2);
    let end = (count as f64 * step_m < length_m - 1e-9).then_some(length_m);
    let poses = (0..=count)
        .map(|i| i as f64 * step_m)
        .chain(end)
        .map(|s| {
            let p = track.pose_at(s);
            PoseStamped {
                header: h.clone(),
                pose: Pose {
                    position: Point { x: p.x, y: p.y, z: 0.0 },
                    orientation: Quaternion::from_yaw(p.yaw),
                },
            }
        })
        .collect();
    Path { header: h, poses }
}

#[cfg(test)]
mod tests {
    use super::*;
    use croprow_core::{RowEstimate, RowStatus};
    use croprow_io::msg::Marker;

    #[test]
    fn odometry_gives_planar_pose_and_body_twist() {
        let mut m = Odometry::default();
        m.pose.pose.position = Point { x: 1.0, y: -2.0, z: 0.3 };
        m.pose.pose.orientation = Quaternion::from_yaw(0.4);
        m.twist.twist = twist(Twist2::new(0.5, -0.1));
        let (pose, tw) = odometry(&m);
        assert!(
            (pose.x - 1.0).abs() < 1e-12 && (pose.y + 2.0).abs() < 1e-12 && (pose.yaw - 0.4).abs() < 1e-12
        );
        assert_eq!(tw, Twist2::new(0.5, -0.1));
    }

    #[test]
    fn missing_rows_are_deleted_markers() {
        let row = RowEstimate {
            line: [0.0, 0.4, 3.0, 0.4],
            offset_m: 0.4,
            heading_rad: 0.0,
            curvature_per_m: 0.0,
            confidence: 1.0,
        };
        let d = Detection { left: Some(row), ..Detection::empty(2.5, RowStatus::Tracking) };
        let m = rows(&d, &[[1.0, 0.4], [2.0, 0.4]], "base_link");
        assert_eq!(m.markers.len(), 3);
        assert_eq!((m.markers[0].action, m.markers[0].points.len()), (Marker::ADD, 2));
        assert_eq!(m.markers[1].action, Marker::DELETE);
        assert_eq!(m.markers[2].points.len(), 2);
        assert_eq!(m.markers[0].header.stamp, Time { sec: 2, nanosec: 500_000_000 });
    }

    #[test]
    fn path_is_sampled_to_its_end() {
        let mut track = TrackPath::with_capacity(1);
        track.push(Pose2::new(1.0, 2.0, 0.0), 1.0, 0.0);
        let p = path(Some(&track), 0.0, "odom", 0.3);
        assert_eq!(p.poses.len(), 5, "0, 0.3, 0.6, 0.9 and the end");
        let last = p.poses.last().unwrap().pose.position;
        assert!((last.x - 2.0).abs() < 1e-9 && (last.y - 2.0).abs() < 1e-9);
        assert!(path(None, 0.0, "odom", 0.3).poses.is_empty());
    }

    #[test]
    fn mount_round_trips_through_an_isometry() {
        let m = Mount::default();
        let back = mount(&m.isometry()).unwrap();
        assert!((back.pitch_rad - m.pitch_rad).abs() < 1e-12 && (back.z_m - m.z_m).abs() < 1e-12);
    }
}
