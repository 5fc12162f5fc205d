//! [`NodeCore`]: the whole node without DDS. Messages go in with the time they were received, messages
//! come out; the DDS shell ([`crate::dds`]) only moves them. Every safety rule lives here, so it is
//! tested without a network.
//!
//! Two clocks, on purpose: the **message stamps** (the odometry clock) drive the algorithms (the
//! odometry pose at a scan's stamp, the navigator's steps), while the **receive times** `now_s` (the
//! node's monotonic clock) drive the watchdog, so a robot whose clock differs from the node's
//! computer is still stopped when its data stops.
//!
//! Safety, checked at every control step before the navigator runs: the command is zero while no
//! usable scan or no odometry was received for `node.stale_after_s`; the navigator itself stops
//! (latched, see [`NodeCore::resume`]) when the rows are lost or the MPC fails. [`Output::halt`] and
//! the status text say why.
//!
//! ```
//! use croprow_ros2::{Halt, NodeConfig, NodeCore};
//! let mut node = NodeCore::new(NodeConfig::default()).unwrap();
//! let out = node.tick(0.0);
//! assert_eq!(out.halt, Some(Halt::NoOdometry));
//! assert_eq!(out.cmd_vel.linear.x, 0.0);
//! ```

use std::time::Duration;

use croprow_core::control::{Mode, SolveStatus, StopReason};
use croprow_core::navigator::{InputFault, NavInput, NavOutput};
use croprow_core::odometry::{AttitudeError, AttitudeFilter, Ekf, EkfError};
use croprow_core::{ConfigError, Mount, Navigator, Point3, Pose2, Scan, Twist2};
use croprow_io::cloud::{self, LayoutError};
use croprow_io::msg::{Imu, MarkerArray, Odometry, Path, PointCloud2, StringMsg, TfMessage, Twist};
use croprow_io::odom::{History, PoseGap};
use croprow_io::tf::TransformBuffer;
use serde::Serialize;
use thiserror::Error;

use crate::config::{NodeConfig, OdometrySource};
use crate::convert;

/// Odometry kept behind the newest sample for scans that arrive late, s.
const HISTORY_S: f64 = 2.0;

/// Why the command is zero.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[non_exhaustive]
pub enum Halt {
    /// No odometry received yet.
    NoOdometry,
    /// No usable scan received yet.
    NoScan,
    /// The last odometry was received more than `node.stale_after_s` ago.
    StaleOdometry,
    /// The last usable scan was received more than `node.stale_after_s` ago.
    StaleScan,
    /// The receive clock went backwards or is not finite.
    BadClock,
    /// Waiting for the detector's first rows.
    Acquiring,
    /// Every requested lane is driven.
    Done,
    /// The navigator stopped (latched until [`NodeCore::resume`]): rows lost, solver failed, ...
    Stopped(StopReason),
    /// The navigator refused this step's input.
    Refused(InputFault),
}

impl Halt {
    /// Stable lower-case name, as written in the status.
    pub fn as_str(&self) -> &'static str {
        match self {
            Halt::NoOdometry => "no_odometry",
            Halt::NoScan => "no_scan",
            Halt::StaleOdometry => "stale_odometry",
            Halt::StaleScan => "stale_scan",
            Halt::BadClock => "bad_clock",
            Halt::Acquiring => "acquiring",
            Halt::Done => "done",
            Halt::Stopped(r) => r.as_str(),
            Halt::Refused(InputFault::BadStamp) => "bad_stamp",
            Halt::Refused(InputFault::BadOdometry) => "bad_odometry",
        }
    }

    /// True for the watchdog's own reasons (data missing or old); the rest come from the navigator.
    pub fn is_watchdog(&self) -> bool {
        matches!(
            self,
            Halt::NoOdometry | Halt::NoScan | Halt::StaleOdometry | Halt::StaleScan | Halt::BadClock
        )
    }
}

/// An input message that was not used. The node's state is unchanged; the error is also shown in
/// the status until a message of the same kind is used.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum InputError {
    /// The cloud's layout or data is unusable.
    #[error("point cloud: {0}")]
    Cloud(#[from] LayoutError),
    /// A header stamp is not a usable time.
    #[error("{what} stamp {stamp_s} s is not finite")]
    Stamp {
        /// Which message.
        what: &'static str,
        /// The stamp, s.
        stamp_s: f64,
    },
    /// No odometry pose at the scan's stamp.
    #[error("no odometry at scan stamp {stamp_s:.3} s: {gap}")]
    NoPose {
        /// The scan stamp, s.
        stamp_s: f64,
        /// Why.
        gap: PoseGap,
    },
    /// The `/tf_static` mount of the cloud's frame is not plausible.
    #[error("mount from /tf_static for `{frame}`: {error}")]
    Mount {
        /// The cloud's frame.
        frame: String,
        /// What is wrong.
        error: ConfigError,
    },
    /// An odometry message is not finite, or for another frame.
    #[error("odometry: {0}")]
    Odometry(String),
    /// A stamp older than the previous one of the same stream.
    #[error("{what} went back in time: {stamp_s:.3} s after {previous_s:.3} s")]
    Backwards {
        /// Which stream.
        what: &'static str,
        /// The refused stamp, s.
        stamp_s: f64,
        /// The previous stamp, s.
        previous_s: f64,
    },
    /// The EKF refused a sample.
    #[error("EKF: {0}")]
    Ekf(#[from] EkfError),
    /// The attitude filter refused an accelerometer sample.
    #[error("attitude: {0}")]
    Attitude(#[from] AttitudeError),
    /// A message for the other odometry source (`node.odometry`).
    #[error("{0} is not used with this node.odometry")]
    WrongSource(&'static str),
}

/// What one step publishes.
#[derive(Debug, Clone, PartialEq)]
pub struct Output {
    /// The command for `base_link`: always finite, zero whenever `halt` is set.
    pub cmd_vel: Twist,
    /// Why the command is zero, if it must be.
    pub halt: Option<Halt>,
    /// One JSON object (see [`Status`]).
    pub status: StringMsg,
    /// The rows of the scan processed in this step, in `node.base_frame`.
    pub rows: Option<MarkerArray>,
    /// The path being tracked, in `node.odom_frame`, after a scan.
    pub path: Option<Path>,
    /// The navigator's own output, when it ran.
    pub nav: Option<NavOutput>,
}

/// The status text, one JSON object per step.
#[derive(Debug, Clone, Serialize)]
pub struct Status<'a> {
    /// Stamp of the step (odometry clock), s; absent before any odometry.
    pub stamp: Option<f64>,
    /// Commanded forward speed, m/s.
    pub v: f64,
    /// Commanded yaw rate, rad/s.
    pub omega: f64,
    /// Why the robot is held (`null` when it may move).
    pub halt: Option<&'static str>,
    /// The navigator's mode.
    pub mode: &'static str,
    /// The last detection's row status.
    pub rows: Option<&'static str>,
    /// How the last MPC solve ended.
    pub solve: Option<SolveStatus>,
    /// Current lane index and lanes completed.
    pub lane: u32,
    /// Lanes whose row end has been cleared.
    pub lanes_completed: u32,
    /// `tf_static` or `config`: where the sensor mount came from.
    pub mount: &'static str,
    /// Age of the last odometry and of the last usable scan at this step, s.
    pub odom_age_s: Option<f64>,
    /// See `odom_age_s`.
    pub scan_age_s: Option<f64>,
    /// The last input that was not used, if any since the last good one.
    pub input_error: Option<&'a str>,
}

#[derive(Debug, Clone, Copy)]
struct OdomSample {
    stamp_s: f64,
    pose: Pose2,
    twist: Twist2,
}

/// The node without DDS; see the module docs.
#[derive(Debug)]
pub struct NodeCore {
    cfg: NodeConfig,
    navigator: Navigator,
    ekf: Option<Ekf>,
    /// Roll and pitch from the IMU (`wheel_imu` with `attitude.enabled`).
    attitude: Option<AttitudeFilter>,
    history: History,
    tf: TransformBuffer,
    points: Vec<Point3>,
    odom: Option<OdomSample>,
    odom_rx_s: Option<f64>,
    scan_rx_s: Option<f64>,
    last_now_s: Option<f64>,
    last_step_s: Option<f64>,
    last_nav: Option<NavOutput>,
    last_rows: Option<&'static str>,
    /// The watchdog held the robot at the previous step: the navigator restarts from rest.
    held: bool,
    mount_from_tf: bool,
    input_error: Option<(Stream, String)>,
}

/// Which input an error belongs to (it is cleared by the next good message of that kind).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Stream {
    Cloud,
    Odometry,
    Imu,
}

impl NodeCore {
    /// Validates the configuration and builds the navigator (and the EKF for `wheel_imu`).
    pub fn new(cfg: NodeConfig) -> Result<Self, ConfigError> {
        cfg.validate()?;
        let ekf = match cfg.node.odometry {
            OdometrySource::Filtered => None,
            OdometrySource::WheelImu => Some(Ekf::new(cfg.ekf.clone())?),
        };
        let reads_imu = cfg.node.odometry == OdometrySource::WheelImu && cfg.attitude.enabled;
        let attitude = reads_imu.then(|| AttitudeFilter::new(cfg.attitude.clone())).transpose()?;
        Ok(Self {
            navigator: Navigator::new(cfg.navigator())?,
            ekf,
            attitude,
            history: History::new(cfg.node.max_extrapolation_s, cfg.node.max_odom_gap_s),
            tf: TransformBuffer::new(),
            points: Vec::new(),
            odom: None,
            odom_rx_s: None,
            scan_rx_s: None,
            last_now_s: None,
            last_step_s: None,
            last_nav: None,
            last_rows: None,
            held: true,
            mount_from_tf: false,
            input_error: None,
            cfg,
        })
    }

    /// The configuration.
    pub fn config(&self) -> &NodeConfig {
        &self.cfg
    }

    /// The navigator (mode, detector, plan).
    pub fn navigator(&self) -> &Navigator {
        &self.navigator
    }

    /// Leaves a latched navigator stop (rows lost, solver failed): the rows are searched again from rest.
    pub fn resume(&mut self) {
        self.navigator.resume();
    }

    /// Takes over the static transforms another core received (they are published once, so a
    /// rebuilt core could not hear them again).
    pub fn adopt_transforms(&mut self, other: &NodeCore) {
        self.tf = other.tf.clone();
    }

    /// Static transforms (`/tf_static`): the sensor mount is looked up here for every scan.
    pub fn on_tf_static(&mut self, msg: &TfMessage) {
        for t in &msg.transforms {
            self.tf.insert(t);
        }
    }

    /// Filtered odometry (`node.odometry = "filtered"`), received at `now_s`.
    pub fn on_odometry(&mut self, now_s: f64, msg: &Odometry) -> Result<(), InputError> {
        if self.ekf.is_some() {
            return Err(InputError::WrongSource("filtered odometry"));
        }
        let result = self
            .checked_odometry(msg)
            .and_then(|(stamp_s, pose, twist)| self.push_odom(now_s, stamp_s, pose, twist));
        self.note(Stream::Odometry, result)
    }

    /// Wheel odometry (`node.odometry = "wheel_imu"`): its body twist updates the EKF.
    pub fn on_wheel_odometry(&mut self, now_s: f64, msg: &Odometry) -> Result<(), InputError> {
        let result = self.wheel(now_s, msg);
        self.note(Stream::Odometry, result)
    }

    /// An IMU sample (`node.odometry = "wheel_imu"`): its yaw rate, rotated into `base_link` when
    /// `/tf_static` knows the IMU's frame (else the IMU is taken as aligned with `base_link`).
    pub fn on_imu(&mut self, msg: &Imu) -> Result<(), InputError> {
        let result = self.imu(msg);
        self.note(Stream::Imu, result)
    }

    /// Wheel and IMU samples that arrived together, given to the EKF in stamp order (each list in
    /// its own arrival order); returns how many were refused (the status shows the last reason).
    pub fn on_wheel_imu_batch(&mut self, now_s: f64, wheel: &[Odometry], imu: &[Imu]) -> usize {
        let (mut w, mut g) = (wheel.iter().peekable(), imu.iter().peekable());
        let mut refused = 0;
        loop {
            let result = match (w.peek(), g.peek()) {
                (Some(a), Some(b)) if a.header.stamp.as_seconds() <= b.header.stamp.as_seconds() => {
                    w.next().map(|m| self.on_wheel_odometry(now_s, m))
                }
                (Some(_), None) => w.next().map(|m| self.on_wheel_odometry(now_s, m)),
                (_, Some(_)) => g.next().map(|m| self.on_imu(m)),
                (None, None) => break,
            };
            refused += usize::from(result.is_some_and(|r| r.is_err()));
        }
        refused
    }

    /// A scan received at `now_s`: decoded, paired with the odometry at its stamp and the mount, and
    /// given to the navigator at once; when newer odometry exists, a control step from it follows
    /// and gives the command. Returns the output (also when the watchdog holds the robot), or why
    /// the scan was not used.
    pub fn on_cloud(&mut self, now_s: f64, msg: &PointCloud2<'_>) -> Result<Output, InputError> {
        let result = self.scan(msg);
        let (stamp_s, pose, mount) = self.note(Stream::Cloud, result)?;
        // Only a usable scan feeds the watchdog: a stream of undecodable clouds must stop the robot.
        self.scan_rx_s = Some(now_s);
        if let Some(halt) = self.watchdog(now_s) {
            return Ok(self.hold(halt));
        }
        self.wake();
        let step_s = self.last_step_s.map_or(stamp_s, |t| t.max(stamp_s));
        let twist = self.odom.map_or(Twist2::ZERO, |o| o.twist);
        let input = NavInput {
            stamp_s: step_s,
            odom: pose,
            odom_twist: twist,
            scan: Some(Scan { stamp_s, points: &self.points, twist: None, attitude: self.attitude() }),
            mount: &mount,
            mpc_budget: self.budget(),
            wheel_slip: self.wheel_slip(),
        };
        let nav = self.navigator.step(input);
        let rows = nav
            .detection
            .map(|d| convert::rows(&d, self.navigator.detector().centroids(), &self.cfg.node.base_frame));
        let path = convert::path(
            self.navigator.lane_switcher().path(),
            step_s,
            &self.cfg.node.odom_frame,
            self.cfg.node.path_spacing_m,
        );
        let mut out = self.finish(nav);
        // The scan step ran from the pose at the scan's stamp, which odometry has usually passed by
        // the time the cloud arrives: the command goes out from the newest pose.
        if let Some(odom) = self.odom.filter(|o| o.stamp_s > step_s) {
            let now = self.navigator.step(NavInput {
                stamp_s: odom.stamp_s,
                odom: odom.pose,
                odom_twist: odom.twist,
                scan: None,
                mount: &mount,
                mpc_budget: self.budget(),
                wheel_slip: self.wheel_slip(),
            });
            out = self.finish(NavOutput { detection: nav.detection, ..now });
        }
        out.rows = rows;
        out.path = Some(path);
        Ok(out)
    }

    /// A control step at `now_s` between scans, from the newest odometry. With no odometry newer
    /// than the last step, the last command is repeated (the navigator would compute it again).
    pub fn tick(&mut self, now_s: f64) -> Output {
        if let Some(halt) = self.watchdog(now_s) {
            return self.hold(halt);
        }
        self.wake();
        let Some(odom) = self.odom else {
            return self.hold(Halt::NoOdometry);
        };
        if self.last_step_s.is_some_and(|t| t >= odom.stamp_s)
            && let Some(nav) = self.last_nav
        {
            return self.finish(NavOutput { detection: None, ..nav });
        }
        let nav = self.navigator.step(NavInput {
            stamp_s: odom.stamp_s,
            odom: odom.pose,
            odom_twist: odom.twist,
            scan: None,
            mount: &self.cfg.mount,
            mpc_budget: self.budget(),
            wheel_slip: self.wheel_slip(),
        });
        self.finish(nav)
    }

    /// The robot's roll and pitch from the IMU's accelerometer, once known (`wheel_imu` with
    /// `attitude.enabled`); each scan is put upright by it. An IMU that reports its acceleration with
    /// gravity removed gives none (its samples are far from gravity and skipped): `base_link` is then
    /// taken as level.
    pub fn attitude(&self) -> Option<croprow_core::Attitude> {
        self.attitude.as_ref().and_then(AttitudeFilter::attitude)
    }

    /// The slip the EKF's witness reads (wheel and IMU odometry only).
    fn wheel_slip(&self) -> Option<f64> {
        self.ekf.as_ref().and_then(Ekf::wheel_slip)
    }

    fn budget(&self) -> Option<Duration> {
        (self.cfg.node.mpc_budget_s > 0.0).then(|| Duration::from_secs_f64(self.cfg.node.mpc_budget_s))
    }

    /// Keeps the latest error per stream for the status; a good message clears its stream's error.
    fn note<T>(&mut self, stream: Stream, result: Result<T, InputError>) -> Result<T, InputError> {
        match &result {
            Ok(_) => {
                if self.input_error.as_ref().is_some_and(|(s, _)| *s == stream) {
                    self.input_error = None;
                }
            }
            Err(e) => self.input_error = Some((stream, e.to_string())),
        }
        result
    }

    fn checked_odometry(&self, msg: &Odometry) -> Result<(f64, Pose2, Twist2), InputError> {
        let stamp_s = msg.header.stamp.as_seconds();
        let (pose, twist) = convert::odometry(msg);
        if !pose.is_finite() || !twist.is_finite() {
            return Err(InputError::Odometry("pose or twist is not finite".into()));
        }
        // A zero or garbage orientation still yields some yaw: refuse it rather than drive on it.
        let q = msg.pose.pose.orientation;
        let norm = (q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w).sqrt();
        if !(0.9..=1.1).contains(&norm) {
            return Err(InputError::Odometry(format!(
                "orientation quaternion of norm {norm} is not a rotation"
            )));
        }
        let base = &self.cfg.node.base_frame;
        if !msg.child_frame_id.is_empty() && msg.child_frame_id != *base {
            return Err(InputError::Odometry(format!(
                "child frame `{}` is not node.base_frame `{base}`",
                msg.child_frame_id
            )));
        }
        Ok((stamp_s, pose, twist))
    }

    fn push_odom(&mut self, now_s: f64, stamp_s: f64, pose: Pose2, twist: Twist2) -> Result<(), InputError> {
        self.history.push(stamp_s, pose).map_err(|b| InputError::Backwards {
            what: "odometry",
            stamp_s,
            previous_s: b.previous_s,
        })?;
        self.history.forget_before(stamp_s - HISTORY_S);
        self.odom = Some(OdomSample { stamp_s, pose, twist });
        // A monotonic clock never goes back; if a caller's does, the watchdog reports it.
        self.odom_rx_s = Some(now_s);
        Ok(())
    }

    fn wheel(&mut self, now_s: f64, msg: &Odometry) -> Result<(), InputError> {
        let (stamp_s, _, twist) = self.checked_odometry(msg)?;
        let ekf = self.ekf.as_mut().ok_or(InputError::WrongSource("wheel odometry"))?;
        ekf.update_wheel(stamp_s, twist.v, twist.omega)?;
        let (pose, twist) = (ekf.pose(), ekf.twist());
        self.push_odom(now_s, stamp_s, pose, twist)
    }

    fn imu(&mut self, msg: &Imu) -> Result<(), InputError> {
        let stamp_s = msg.header.stamp.as_seconds();
        let (w, a) = (msg.angular_velocity, msg.linear_acceleration);
        let (w, a) = (nalgebra::Vector3::new(w.x, w.y, w.z), nalgebra::Vector3::new(a.x, a.y, a.z));
        let (w, a) = match self.tf.lookup(&self.cfg.node.base_frame, &msg.header.frame_id) {
            Ok(iso) => (iso.rotation * w, iso.rotation * a),
            Err(_) => (w, a),
        };
        let ekf = self.ekf.as_mut().ok_or(InputError::WrongSource("IMU"))?;
        ekf.update_imu(stamp_s, w.z)?;
        let twist = ekf.twist();
        // The IMU refines the pose between wheel samples but does not feed the watchdog: without
        // wheels the EKF only dead-reckons.
        let pose = ekf.pose();
        if self.history.latest_s().is_none_or(|t| stamp_s > t) {
            self.history.push(stamp_s, pose).map_err(|b| InputError::Backwards {
                what: "IMU",
                stamp_s,
                previous_s: b.previous_s,
            })?;
        }
        if let Some(filter) = self.attitude.as_mut() {
            filter.update(stamp_s, [a.x, a.y, a.z], twist)?;
        }
        Ok(())
    }

    fn scan(&mut self, msg: &PointCloud2<'_>) -> Result<(f64, Pose2, Mount), InputError> {
        let stamp_s = msg.header.stamp.as_seconds();
        if !stamp_s.is_finite() {
            return Err(InputError::Stamp { what: "cloud", stamp_s });
        }
        let pose = self.history.pose_at(stamp_s).map_err(|gap| InputError::NoPose { stamp_s, gap })?;
        let frame = &msg.header.frame_id;
        let mount = match self.tf.lookup(&self.cfg.node.base_frame, frame) {
            Ok(iso) => {
                self.mount_from_tf = true;
                convert::mount(&iso).map_err(|error| InputError::Mount { frame: frame.clone(), error })?
            }
            Err(_) => {
                self.mount_from_tf = false;
                self.cfg.mount
            }
        };
        cloud::decode(msg, &mut self.points)?;
        Ok((stamp_s, pose, mount))
    }

    /// The watchdog: a reason to hold the robot, judged on receive times.
    fn watchdog(&mut self, now_s: f64) -> Option<Halt> {
        if !now_s.is_finite() || self.last_now_s.is_some_and(|t| now_s < t) {
            return Some(Halt::BadClock);
        }
        self.last_now_s = Some(now_s);
        let stale = self.cfg.node.stale_after_s;
        match self.odom_rx_s {
            None => return Some(Halt::NoOdometry),
            Some(t) if now_s - t > stale => return Some(Halt::StaleOdometry),
            Some(_) => {}
        }
        match self.scan_rx_s {
            None => Some(Halt::NoScan),
            Some(t) if now_s - t > stale => Some(Halt::StaleScan),
            Some(_) => None,
        }
    }

    /// After a watchdog hold the navigator restarts from rest (its rate limits start at zero, the
    /// detector looks afresh); a latched navigator stop stays latched.
    fn wake(&mut self) {
        if self.held {
            if !matches!(self.navigator.lane_switcher().mode(), Mode::Stopped { .. }) {
                self.navigator.resume();
            }
            // The command before the hold must not be repeated.
            self.last_nav = None;
        }
        self.held = false;
    }

    fn hold(&mut self, halt: Halt) -> Output {
        self.held = true;
        let status = self.status(Twist2::ZERO, Some(halt));
        Output {
            cmd_vel: convert::twist(Twist2::ZERO),
            halt: Some(halt),
            status,
            rows: None,
            path: None,
            nav: None,
        }
    }

    fn finish(&mut self, nav: NavOutput) -> Output {
        self.last_step_s = Some(nav.stamp_s);
        self.last_nav = Some(nav);
        if let Some(d) = &nav.detection {
            self.last_rows = Some(d.status.as_str());
        }
        let halt = match (nav.input_fault, nav.mode) {
            (Some(fault), _) => Some(Halt::Refused(fault)),
            (None, Mode::Acquiring) => Some(Halt::Acquiring),
            (None, Mode::Done) => Some(Halt::Done),
            (None, Mode::Stopped { reason }) => Some(Halt::Stopped(reason)),
            (None, _) => None,
        };
        // The navigator guarantees a finite command; the node checks again, a robot must never get NaN.
        let cmd = if halt.is_none() && nav.cmd.is_finite() { nav.cmd } else { Twist2::ZERO };
        let status = self.status(cmd, halt);
        Output { cmd_vel: convert::twist(cmd), halt, status, rows: None, path: None, nav: Some(nav) }
    }

    fn status(&self, cmd: Twist2, halt: Option<Halt>) -> StringMsg {
        let now = self.last_now_s;
        let age = |rx: Option<f64>| now.zip(rx).map(|(n, r)| n - r);
        let status = Status {
            stamp: self.last_step_s.or(self.odom.map(|o| o.stamp_s)),
            v: cmd.v,
            omega: cmd.omega,
            halt: halt.map(|h| h.as_str()),
            mode: self.navigator.lane_switcher().mode().as_str(),
            rows: self.last_rows,
            solve: self.last_nav.and_then(|n| n.solve_status),
            lane: self.navigator.lane_switcher().lane(),
            lanes_completed: self.navigator.lane_switcher().lanes_completed(),
            mount: if self.mount_from_tf { "tf_static" } else { "config" },
            odom_age_s: age(self.odom_rx_s),
            scan_age_s: age(self.scan_rx_s),
            input_error: self.input_error.as_ref().map(|(_, e)| e.as_str()),
        };
        // Serialising plain numbers and strings cannot fail; should it ever, the status says so.
        StringMsg {
            data: serde_json::to_string(&status).unwrap_or_else(|e| format!("{{\"error\":\"{e}\"}}")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use croprow_io::msg::Header;

    fn odom(stamp_s: f64) -> Odometry {
        Odometry {
            header: Header {
                stamp: croprow_io::msg::Time::from_seconds(stamp_s).unwrap(),
                frame_id: "odom".into(),
            },
            child_frame_id: "base_link".into(),
            ..Odometry::default()
        }
    }

    fn following(cmd: Twist2, mode: Mode) -> NavOutput {
        NavOutput {
            stamp_s: 1.0,
            cmd,
            mode,
            detection: None,
            solve_status: Some(SolveStatus::Converged),
            solve_iterations: 3,
            tracking: None,
            lanes_completed: 0,
            lane: 0,
            input_fault: None,
        }
    }

    #[test]
    fn nothing_received_holds_for_odometry_first() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        let out = node.tick(0.0);
        assert_eq!((out.halt, out.cmd_vel), (Some(Halt::NoOdometry), Twist::default()));
        assert!(out.status.data.contains("\"halt\":\"no_odometry\""), "{}", out.status.data);
    }

    #[test]
    fn odometry_without_scans_holds_for_the_scan() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        node.on_odometry(0.0, &odom(5.0)).unwrap();
        assert_eq!(node.tick(0.1).halt, Some(Halt::NoScan));
    }

    #[test]
    fn odometry_older_than_the_window_is_stale() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        node.on_odometry(0.0, &odom(5.0)).unwrap();
        node.scan_rx_s = Some(0.6);
        assert_eq!(node.tick(0.5).halt, Some(Halt::Acquiring), "exactly 0.5 s is still fresh");
        assert_eq!(node.tick(0.51).halt, Some(Halt::StaleOdometry));
    }

    #[test]
    fn a_clock_going_backwards_holds() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        node.on_odometry(1.0, &odom(5.0)).unwrap();
        node.scan_rx_s = Some(1.0);
        assert_eq!(node.tick(1.1).halt, Some(Halt::Acquiring));
        assert_eq!(node.tick(1.0).halt, Some(Halt::BadClock));
        assert_eq!(node.tick(f64::NAN).halt, Some(Halt::BadClock));
        assert_eq!(node.tick(1.2).halt, Some(Halt::Acquiring));
    }

    #[test]
    fn a_solver_failure_commands_zero_whatever_the_command() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        let out =
            node.finish(following(Twist2::new(0.4, 0.1), Mode::Stopped { reason: StopReason::SolverFailed }));
        assert_eq!(
            (out.halt, out.cmd_vel),
            (Some(Halt::Stopped(StopReason::SolverFailed)), Twist::default())
        );
        assert!(out.status.data.contains("solver_failed"), "{}", out.status.data);
    }

    #[test]
    fn lost_rows_command_zero() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        let out =
            node.finish(following(Twist2::new(0.4, 0.0), Mode::Stopped { reason: StopReason::RowsLost }));
        assert_eq!((out.halt, out.cmd_vel.linear.x), (Some(Halt::Stopped(StopReason::RowsLost)), 0.0));
    }

    #[test]
    fn a_non_finite_command_is_never_published() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        let out = node.finish(following(Twist2::new(f64::NAN, 0.1), Mode::Following));
        assert_eq!(out.cmd_vel, Twist::default());
        let out = node.finish(following(Twist2::new(0.3, 0.1), Mode::Following));
        assert_eq!((out.cmd_vel.linear.x, out.cmd_vel.angular.z, out.halt), (0.3, 0.1, None));
    }

    #[test]
    fn messages_of_the_other_odometry_source_are_refused() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        assert!(matches!(node.on_wheel_odometry(0.0, &odom(1.0)), Err(InputError::WrongSource(_))));
        assert!(matches!(node.on_imu(&Imu::default()), Err(InputError::WrongSource(_))));
        let mut cfg = NodeConfig::default();
        cfg.node.odometry = OdometrySource::WheelImu;
        let mut node = NodeCore::new(cfg).unwrap();
        assert!(matches!(node.on_odometry(0.0, &odom(1.0)), Err(InputError::WrongSource(_))));
        node.on_wheel_odometry(0.0, &odom(1.0)).unwrap();
    }

    #[test]
    fn wheel_and_imu_samples_are_fused_in_stamp_order() {
        let mut cfg = NodeConfig::default();
        cfg.node.odometry = OdometrySource::WheelImu;
        let imu = |t: f64| Imu {
            header: Header { stamp: croprow_io::msg::Time::from_seconds(t).unwrap(), frame_id: "imu".into() },
            ..Imu::default()
        };
        let wheel = [odom(1.00), odom(1.02)];
        let gyro = [imu(0.99), imu(1.01), imu(1.03)];
        let mut node = NodeCore::new(cfg.clone()).unwrap();
        assert_eq!(node.on_wheel_imu_batch(0.0, &wheel, &gyro), 0);
        // Fed stream by stream instead, the gyro samples older than the last wheel sample are refused.
        let mut node = NodeCore::new(cfg).unwrap();
        assert_eq!(node.on_wheel_imu_batch(0.0, &wheel, &[]) + node.on_wheel_imu_batch(0.0, &[], &gyro), 2);
    }

    #[test]
    fn the_imu_accelerometer_gives_the_roll_and_pitch_scans_are_put_upright_by() {
        let mut cfg = NodeConfig::default();
        cfg.node.odometry = OdometrySource::WheelImu;
        cfg.attitude.enabled = true;
        // Rolled 3° to the left, standing still: gravity's share shows on y (REP-145 specific force).
        let roll = 3f64.to_radians();
        let imu = |t: f64, ay: f64| Imu {
            header: Header {
                stamp: croprow_io::msg::Time::from_seconds(t).unwrap(),
                frame_id: "base_link".into(),
            },
            linear_acceleration: croprow_io::msg::Vector3 { x: 0.0, y: ay, z: 9.81 * roll.cos() },
            ..Imu::default()
        };
        let mut node = NodeCore::new(cfg.clone()).unwrap();
        node.on_wheel_odometry(0.0, &odom(1.0)).unwrap();
        assert_eq!(node.attitude(), None);
        for k in 1..=100 {
            node.on_imu(&imu(1.0 + 0.01 * k as f64, 9.81 * roll.sin())).unwrap();
        }
        let a = node.attitude().expect("an attitude after a second of samples");
        // Less the deadband (`attitude.deadband_deg`, 0.3°).
        assert!((a.roll_rad - (roll - 0.3f64.to_radians())).abs() < 1e-3 && a.pitch_rad == 0.0, "{a:?}");
        // A non-finite acceleration is refused with the stream's error; the estimate stays.
        let e = node.on_imu(&imu(2.01, f64::NAN)).unwrap_err();
        assert!(e.to_string().contains("attitude: non-finite specific force"), "{e}");
        assert_eq!(node.attitude(), Some(a));
        // Off, or with filtered odometry, there is none.
        cfg.attitude.enabled = false;
        let mut node = NodeCore::new(cfg).unwrap();
        node.on_wheel_odometry(0.0, &odom(1.0)).unwrap();
        (1..=100).for_each(|k| node.on_imu(&imu(1.0 + 0.01 * k as f64, 9.81 * roll.sin())).unwrap());
        assert_eq!(node.attitude(), None);
        let mut filtered = NodeConfig::default();
        filtered.attitude.enabled = true;
        let mut node = NodeCore::new(filtered).unwrap();
        assert!(matches!(node.on_imu(&imu(1.0, 9.81 * roll.sin())), Err(InputError::WrongSource(_))));
        assert_eq!(node.attitude(), None);
    }

    #[test]
    fn a_cloud_before_any_odometry_has_no_pose() {
        let mut node = NodeCore::new(NodeConfig::default()).unwrap();
        let cloud = PointCloud2 { header: Header::default(), ..PointCloud2::default() };
        assert!(matches!(node.on_cloud(0.0, &cloud), Err(InputError::NoPose { .. })));
        assert_eq!(node.tick(0.0).halt, Some(Halt::NoOdometry));
    }
}
