//! `NodeCore` in closed loop over the synthetic field, without DDS: the messages a robot publishes go
//! in (odometry at 50 Hz, clouds at 10 Hz, received the moment they are stamped), the node's
//! commands drive an ideal unicycle. One behaviour per test.

mod support;

use croprow_core::control::StopReason;
use croprow_core::{Mount, Point3, Pose2, Twist2};
use croprow_ros2::{Halt, NodeConfig, NodeCore, OdometrySource, Output};
use support::Field;

const ODOM_DT: f64 = 0.02;

/// What the simulated robot sends in one 20 ms slot.
#[derive(Debug, Clone, Copy)]
struct Feeds {
    odometry: bool,
    cloud: bool,
}

/// A closed-loop run: robot, field, node and every output so far.
struct Run {
    node: NodeCore,
    field: Field,
    mount: Mount,
    /// The sensor returns nothing (every point NaN, as an organised cloud marks missing returns).
    blind: bool,
    /// A cloud reaches the node this long after its stamp (driver and transport latency), s.
    scan_latency_s: f64,
    /// Poses of the last slots, to see the scene as it was at a late scan's stamp.
    past: Vec<(f64, Pose2)>,
    pose: Pose2,
    cmd: Twist2,
    t: f64,
    step: u64,
    outputs: Vec<(f64, Output)>,
}

impl Run {
    fn new(cfg: NodeConfig) -> Self {
        Self {
            node: NodeCore::new(cfg).unwrap(),
            field: Field::default(),
            mount: Mount::default(),
            blind: false,
            scan_latency_s: 0.0,
            past: Vec::new(),
            pose: Pose2::new(0.0, 0.05, 0.03),
            cmd: Twist2::ZERO,
            t: 100.0,
            step: 0,
            outputs: Vec::new(),
        }
    }

    /// Runs `seconds` of 20 ms slots: odometry every slot, a cloud every fifth, a control tick every
    /// 50 ms (`node.control_period_s` default).
    fn run(&mut self, seconds: f64, feeds: impl Fn(f64) -> Feeds) {
        let slots = (seconds / ODOM_DT).round() as u64;
        for _ in 0..slots {
            self.step += 1;
            self.t += ODOM_DT;
            self.pose = support::drive(self.pose, self.cmd, ODOM_DT);
            self.past.push((self.t, self.pose));
            let f = feeds(self.t);
            let wheel_imu = self.node.config().node.odometry == OdometrySource::WheelImu;
            if f.odometry {
                let odom = support::odometry(self.t, self.pose, self.cmd);
                if wheel_imu {
                    self.node.on_imu(&support::imu(self.t - 0.001, self.cmd.omega)).unwrap();
                    self.node.on_wheel_odometry(self.t, &odom).unwrap();
                } else {
                    self.node.on_odometry(self.t, &odom).unwrap();
                }
            }
            if f.cloud && self.step.is_multiple_of(5) {
                // The scene at the scan's stamp: the newest slot not after it.
                let stamp = self.t - self.scan_latency_s;
                let seen_from =
                    self.past.iter().rev().find(|(t, _)| *t <= stamp + 1e-9).map_or(self.pose, |p| p.1);
                let points = if self.blind {
                    vec![Point3::new(f32::NAN, f32::NAN, f32::NAN); 1000]
                } else {
                    self.field.scan(seen_from, &self.mount, self.step)
                };
                let out = self.node.on_cloud(self.t, &support::cloud(stamp, &points));
                if let Ok(out) = out {
                    self.apply(out);
                }
            }
            // Ticks at 50 ms: every slot whose time crosses a multiple of the period.
            if ((self.t / 0.05).floor() - ((self.t - ODOM_DT) / 0.05).floor()) >= 1.0 {
                let out = self.node.tick(self.t);
                self.apply(out);
            }
        }
    }

    fn apply(&mut self, out: Output) {
        self.cmd = Twist2::new(out.cmd_vel.linear.x, out.cmd_vel.angular.z);
        self.outputs.push((self.t, out));
    }

    fn last(&self) -> &Output {
        &self.outputs.last().expect("a step ran").1
    }
}

fn all(_: f64) -> Feeds {
    Feeds { odometry: true, cloud: true }
}

#[test]
fn follows_the_rows_with_finite_bounded_forward_commands() {
    let cfg = NodeConfig::default();
    let (v_max, w_max) = (cfg.mpc.speed_max_mps, cfg.mpc.yaw_rate_max_radps);
    let mut run = Run::new(cfg);
    run.run(12.0, all);
    for (_, out) in &run.outputs {
        let (v, w) = (out.cmd_vel.linear.x, out.cmd_vel.angular.z);
        assert!(v.is_finite() && w.is_finite());
        assert!((0.0..=v_max + 1e-9).contains(&v) && w.abs() <= w_max + 1e-9, "{v} {w}");
    }
    assert_eq!(run.last().halt, None, "{}", run.last().status.data);
    assert!(run.last().cmd_vel.linear.x > 0.3, "{}", run.last().status.data);
    assert!(run.pose.x > 3.0, "drove {:.2} m", run.pose.x);
    // Tolerance: a third of the 0.375 m half lane.
    assert!(run.pose.y.abs() < 0.12, "cross-track {:.3} m", run.pose.y);
}

#[test]
fn late_scans_are_placed_at_their_stamp_and_the_command_uses_the_newest_odometry() {
    let mut run = Run::new(NodeConfig::default());
    run.scan_latency_s = 0.08;
    run.run(12.0, all);
    assert_eq!(run.last().halt, None, "{}", run.last().status.data);
    let after_scan = run.outputs.iter().rev().find(|(_, o)| o.rows.is_some()).expect("a scan step");
    let nav = after_scan.1.nav.expect("the navigator ran");
    assert!(nav.detection.is_some(), "the scan's detection is reported");
    assert!((nav.stamp_s - after_scan.0).abs() < 1e-9, "the command comes from the newest odometry");
    assert!(run.pose.x > 3.0 && run.pose.y.abs() < 0.12, "x {:.2} y {:.3}", run.pose.x, run.pose.y);
}

#[test]
fn publishes_rows_and_the_tracked_path_after_each_scan() {
    let mut run = Run::new(NodeConfig::default());
    run.run(6.0, all);
    let after_scan = run.outputs.iter().rev().find(|(_, o)| o.rows.is_some()).expect("a scan step");
    let rows = after_scan.1.rows.as_ref().unwrap();
    assert!(rows.markers.iter().any(|m| m.points.len() == 2), "a row line");
    let path = after_scan.1.path.as_ref().unwrap();
    assert_eq!(path.header.frame_id, "odom");
    assert!(path.poses.len() >= 2);
    let status: serde_json::Value = serde_json::from_str(&after_scan.1.status.data).unwrap();
    assert_eq!(status["mode"], "following");
    assert_eq!(status["rows"], "tracking");
}

#[test]
fn odometry_silence_stops_the_robot_after_the_stale_window() {
    let mut run = Run::new(NodeConfig::default());
    run.run(6.0, all);
    assert!(run.cmd.v > 0.1);
    let silent_from = run.t;
    run.run(2.0, |_| Feeds { odometry: false, cloud: true });
    // Every step more than 0.5 s (+ one 50 ms tick) after the last odometry commands zero.
    let late: Vec<&Output> =
        run.outputs.iter().filter(|(t, _)| *t > silent_from + 0.5 + 0.05 + 1e-9).map(|(_, o)| o).collect();
    assert!(!late.is_empty());
    for out in late {
        assert_eq!((out.cmd_vel.linear.x, out.cmd_vel.angular.z), (0.0, 0.0));
        assert_eq!(out.halt, Some(Halt::StaleOdometry), "{}", out.status.data);
    }
    assert!(run.last().status.data.contains("\"halt\":\"stale_odometry\""), "{}", run.last().status.data);
}

#[test]
fn scan_silence_stops_the_robot_after_the_stale_window() {
    let mut run = Run::new(NodeConfig::default());
    run.run(6.0, all);
    let silent_from = run.t;
    run.run(2.0, |_| Feeds { odometry: true, cloud: false });
    for (_, out) in run.outputs.iter().filter(|(t, _)| *t > silent_from + 0.5 + 0.05 + 1e-9) {
        assert_eq!((out.cmd_vel.linear.x, out.halt), (0.0, Some(Halt::StaleScan)));
    }
}

#[test]
fn after_a_stale_hold_the_robot_starts_again_from_rest() {
    let cfg = NodeConfig::default();
    // The navigator limits the acceleration per elapsed time, capped at one MPC step.
    let dv = cfg.mpc.accel_max_mps2 * cfg.mpc.step_s;
    let mut run = Run::new(cfg);
    run.run(6.0, all);
    run.run(1.0, |_| Feeds { odometry: false, cloud: true });
    assert_eq!(run.cmd, Twist2::ZERO);
    let resumed_from = run.outputs.len();
    run.run(4.0, all);
    let mut prev = 0.0;
    for (_, out) in &run.outputs[resumed_from..] {
        let v = out.cmd_vel.linear.x;
        // Tolerance 1e-9.
        assert!(v - prev <= dv + 1e-9, "jumped {prev} -> {v}");
        prev = v;
    }
    assert!(run.cmd.v > 0.1, "{}", run.last().status.data);
}

#[test]
fn a_blinded_sensor_stops_the_robot_and_the_stop_is_latched_until_resume() {
    // Stops for lost rows end by themselves by default (lane_switch.resume_confirmations); latched here.
    let mut cfg = NodeConfig::default();
    cfg.lane_switch.resume_confirmations = 0;
    let mut run = Run::new(cfg);
    run.run(6.0, all);
    // Mud on the lens: the scans keep coming, with no return in them.
    run.blind = true;
    run.run(8.0, all);
    let halt = run.last().halt;
    assert!(
        matches!(halt, Some(Halt::Stopped(StopReason::RowsLost | StopReason::NoRows))),
        "{halt:?}: {}",
        run.last().status.data
    );
    assert_eq!(run.cmd, Twist2::ZERO);
    // The field comes back, but the stop holds until an operator resumes.
    run.blind = false;
    run.run(2.0, all);
    assert!(matches!(run.last().halt, Some(Halt::Stopped(_))));
    run.node.resume();
    run.run(6.0, all);
    assert_eq!(run.last().halt, None, "{}", run.last().status.data);
    assert!(run.cmd.v > 0.1);
}

#[test]
fn the_mount_comes_from_tf_static_when_published() {
    // The config's mount is wrong (level sensor); /tf_static has the true 30° tilt.
    let mut cfg = NodeConfig::default();
    cfg.mount.pitch_rad = 0.0;
    let mut run = Run::new(cfg);
    run.node.on_tf_static(&support::tf_static(&Mount::default()));
    run.run(8.0, all);
    assert!(run.last().status.data.contains("\"mount\":\"tf_static\""), "{}", run.last().status.data);
    assert!(run.cmd.v > 0.3 && run.pose.y.abs() < 0.12, "{}", run.last().status.data);
}

#[test]
fn wheel_odometry_and_imu_drive_through_the_ekf() {
    let mut cfg = NodeConfig::default();
    cfg.node.odometry = OdometrySource::WheelImu;
    let mut run = Run::new(cfg);
    // The EKF integrates from the odom origin: start the robot there.
    run.pose = Pose2::new(0.0, 0.0, 0.0);
    run.run(10.0, all);
    assert_eq!(run.last().halt, None, "{}", run.last().status.data);
    assert!(run.cmd.v > 0.3 && run.pose.x > 2.0 && run.pose.y.abs() < 0.12);
}

#[test]
fn undecodable_clouds_do_not_feed_the_watchdog() {
    let mut run = Run::new(NodeConfig::default());
    run.run(6.0, all);
    let t0 = run.t;
    let mut broken = support::cloud(t0, &run.field.scan(run.pose, &run.mount, 1));
    broken.point_step = 3;
    for i in 1..=20 {
        let t = t0 + 0.05 * i as f64;
        run.node.on_odometry(t, &support::odometry(t, run.pose, Twist2::ZERO)).unwrap();
        broken.header = support::header(t, support::SENSOR_FRAME);
        assert!(run.node.on_cloud(t, &broken).is_err());
        let out = run.node.tick(t);
        if t > t0 + 0.5 + 1e-9 {
            assert_eq!(out.halt, Some(Halt::StaleScan));
            assert!(out.status.data.contains("point cloud"), "{}", out.status.data);
        }
    }
}

#[test]
fn non_finite_or_foreign_odometry_is_refused_and_reported() {
    let mut node = NodeCore::new(NodeConfig::default()).unwrap();
    let mut bad = support::odometry(1.0, Pose2::new(f64::NAN, 0.0, 0.0), Twist2::ZERO);
    assert!(node.on_odometry(1.0, &bad).is_err());
    bad = support::odometry(1.0, Pose2::default(), Twist2::ZERO);
    bad.pose.pose.orientation.w = 0.0;
    assert!(node.on_odometry(1.0, &bad).unwrap_err().to_string().contains("quaternion"));
    bad = support::odometry(1.0, Pose2::default(), Twist2::ZERO);
    bad.child_frame_id = "base_footprint".into();
    assert!(node.on_odometry(1.0, &bad).unwrap_err().to_string().contains("base_footprint"));
    let out = node.tick(1.0);
    assert_eq!(out.halt, Some(Halt::NoOdometry));
    assert!(out.status.data.contains("base_footprint"), "{}", out.status.data);
    // Time going backwards is refused too.
    node.on_odometry(2.0, &support::odometry(2.0, Pose2::default(), Twist2::ZERO)).unwrap();
    assert!(node.on_odometry(2.1, &support::odometry(1.5, Pose2::default(), Twist2::ZERO)).is_err());
}
