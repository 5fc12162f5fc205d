//! The DDS shell: a ROS 2 node (pure-Rust `ros2-client` on RustDDS, no ROS install) that moves
//! messages between the network and a [`NodeCore`]. No decision is made here.
//!
//! The participant is built with an explicit network list ([`DdsOptions::networks`], loopback by
//! default): discovery is announced to those interfaces and to the same-host loopback peers only,
//! so a test never sends a packet off 127.0.0.1. Give the robot's LAN address to reach nodes on
//! other computers.
//!
//! QoS: the sensor inputs (cloud, odometry, IMU) are best effort, keep last (a stale sample is
//! worthless and a best-effort reader matches both kinds of publisher); `/tf_static` is reliable and
//! transient local (late joiners get the mount); the command and the other outputs are reliable.
//!
//! The loop wakes on data or at the next control step (`node.control_period_s`): it drains every
//! input (transforms, then odometry and IMU, then only the newest cloud), runs one step per cloud
//! and one per control period, and publishes each step's messages. On stop it publishes a zero
//! command.

use std::borrow::Cow;
use std::net::{IpAddr, Ipv4Addr};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use croprow_core::Twist2;
use croprow_io::msg::{
    Imu, MarkerArray, Odometry, Path, PointCloud2, RosMessage, StringMsg, TfMessage, Twist,
};
use ros2_client::qos::{Durability, History, WhenFull};
use ros2_client::{
    Context, MessageTypeName, Name, Node, NodeName, NodeOptions, ParameterValue, Publisher, QosProfile,
    Subscription,
};
use rustdds::mio1::{Events, Interest, Poll, Token};
use serde::Deserialize;
use thiserror::Error;

use crate::config::{NodeConfig, OdometrySource};
use crate::convert;
use crate::logic::{NodeCore, Output};

/// The DDS side could not be set up or failed while running.
#[derive(Debug, Error)]
#[non_exhaustive]
pub enum DdsError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] croprow_core::ConfigError),
    /// A participant, node, topic, reader or writer could not be created.
    #[error("cannot create the DDS {what}: {reason}")]
    Create {
        /// What was being created.
        what: String,
        /// The middleware's reason.
        reason: String,
    },
    /// A command could not be published: the robot would not hear a stop.
    #[error("cannot publish on {topic}: {reason}")]
    Publish {
        /// The topic.
        topic: String,
        /// The middleware's reason.
        reason: String,
    },
    /// Waiting for input failed.
    #[error("polling the DDS readers: {0}")]
    Poll(#[from] std::io::Error),
}

fn create_err(what: impl Into<String>) -> impl FnOnce(&dyn std::fmt::Debug) -> DdsError {
    let what = what.into();
    move |e| DdsError::Create { what, reason: format!("{e:?}") }
}

/// Where and as whom the node joins ROS 2.
#[derive(Debug, Clone, PartialEq)]
pub struct DdsOptions {
    /// ROS domain id (`ROS_DOMAIN_ID`). Default 0.
    pub domain_id: u16,
    /// Local addresses whose interfaces carry discovery and data. Default `[127.0.0.1]`: this computer
    /// only.
    pub networks: Vec<IpAddr>,
    /// Node name. Default `croprow`.
    pub name: String,
    /// Node namespace. Default `/`.
    pub namespace: String,
}

impl Default for DdsOptions {
    fn default() -> Self {
        Self {
            domain_id: 0,
            networks: vec![IpAddr::V4(Ipv4Addr::LOCALHOST)],
            name: "croprow".into(),
            namespace: "/".into(),
        }
    }
}

/// A ROS 2 context on a participant restricted to `networks` (never the library's default
/// participant, which announces itself by multicast on every interface).
pub fn context(domain_id: u16, networks: &[IpAddr]) -> Result<Context, DdsError> {
    let participant = rustdds::DomainParticipantBuilder::new(domain_id)
        .with_only_networks(networks.iter().copied())
        .same_host_loopback(true)
        .build()
        .map_err(|e| create_err("participant")(&e))?;
    Context::from_domain_participant(participant).map_err(|e| create_err("context")(&e))
}

/// QoS of sensor inputs: best effort, keep last `depth`, volatile.
pub fn sensor_qos(depth: usize) -> QosProfile {
    QosProfile::subscription_default().history(History::KeepLast { depth })
}

/// QoS of commands and outputs: reliable, keep last `depth`, volatile.
pub fn reliable_qos(depth: usize) -> QosProfile {
    QosProfile::publisher_default()
        .reliability_reliable(WhenFull::Wait(Duration::from_millis(20)))
        .history(History::KeepLast { depth })
}

/// QoS of `/tf_static`: reliable, transient local (the publisher keeps the last transforms for
/// late joiners).
pub fn tf_static_qos() -> QosProfile {
    reliable_qos(100).durability(Durability::TransientLocal)
}

/// The ROS 2 type name of a message struct (`sensor_msgs/msg/PointCloud2` -> `sensor_msgs`, `PointCloud2`).
pub fn type_name<M: RosMessage>() -> MessageTypeName {
    let mut parts = M::TYPE_NAME.split('/');
    let package = parts.next().unwrap_or_default();
    let name = parts.next_back().unwrap_or_default();
    MessageTypeName::new(package, name)
}

/// The topic of message type `M` on an absolute topic name.
fn topic<M: RosMessage>(node: &Node, topic: &str, qos: &QosProfile) -> Result<rustdds::Topic, DdsError> {
    let name = Name::parse(topic).map_err(|e| create_err(format!("topic name {topic}"))(&e))?;
    node.create_topic(&name, type_name::<M>(), qos).map_err(|e| create_err(format!("topic {topic}"))(&e))
}

/// Creates a subscription on an absolute topic name.
pub fn subscribe<M: RosMessage + 'static>(
    node: &mut Node,
    name: &str,
    qos: QosProfile,
) -> Result<Subscription<M>, DdsError> {
    let t = topic::<M>(node, name, &qos)?;
    node.create_subscription(&t, Some(qos)).map_err(|e| create_err(format!("reader of {name}"))(&e))
}

/// Creates a publisher on an absolute topic name.
pub fn advertise<M: RosMessage + serde::Serialize>(
    node: &mut Node,
    name: &str,
    qos: QosProfile,
) -> Result<Publisher<M>, DdsError> {
    let t = topic::<M>(node, name, &qos)?;
    node.create_publisher(&t, Some(qos)).map_err(|e| create_err(format!("writer of {name}"))(&e))
}

/// A received cloud that owns its data (the reader's buffer is not kept), so that its reader can
/// take samples without a borrow and wake the poll loop.
#[derive(Debug, Clone, PartialEq)]
pub struct OwnedCloud(pub PointCloud2<'static>);

impl<'de> Deserialize<'de> for OwnedCloud {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let c = PointCloud2::deserialize(d)?;
        Ok(Self(PointCloud2 {
            header: c.header,
            height: c.height,
            width: c.width,
            fields: c.fields,
            is_bigendian: c.is_bigendian,
            point_step: c.point_step,
            row_step: c.row_step,
            data: Cow::Owned(c.data.into_owned()),
            is_dense: c.is_dense,
        }))
    }
}

impl RosMessage for OwnedCloud {
    const TYPE_NAME: &'static str = <PointCloud2<'static> as RosMessage>::TYPE_NAME;

    fn definition() -> String {
        <PointCloud2<'static> as RosMessage>::definition()
    }
}

/// Takes every waiting sample, keeping the count of read errors (undecodable samples).
fn drain<M: serde::de::DeserializeOwned + 'static>(
    sub: &Subscription<M>,
    errors: &mut u64,
    mut each: impl FnMut(M),
) {
    loop {
        match sub.take() {
            Ok(Some((m, _))) => each(m),
            Ok(None) => break,
            Err(_) => *errors += 1,
        }
    }
}

/// ROS 2 parameter value of a config leaf (the config has scalars only).
pub fn parameter(value: &toml::Value) -> Option<ParameterValue> {
    match value {
        toml::Value::Boolean(b) => Some(ParameterValue::Boolean(*b)),
        toml::Value::Integer(i) => Some(ParameterValue::Integer(*i)),
        toml::Value::Float(f) => Some(ParameterValue::Double(*f)),
        toml::Value::String(s) => Some(ParameterValue::String(s.clone())),
        _ => None,
    }
}

/// Applies a ROS 2 parameter to a config with the same checks as a config file; returns whether the
/// value changed. The topics and the odometry source are fixed once the node runs (their readers
/// and writers exist).
pub fn apply_parameter(cfg: &mut NodeConfig, name: &str, value: &ParameterValue) -> Result<bool, String> {
    let value = match value {
        ParameterValue::Boolean(b) => toml::Value::Boolean(*b),
        ParameterValue::Integer(i) => toml::Value::Integer(*i),
        ParameterValue::Double(f) => toml::Value::Float(*f),
        ParameterValue::String(s) => toml::Value::String(s.clone()),
        other => return Err(format!("{name}: unsupported parameter type {other:?}")),
    };
    if cfg.leaf(name).map_err(|e| e.to_string())? == value {
        return Ok(false);
    }
    if name.starts_with("node.") && (name.ends_with("_topic") || name == "node.odometry") {
        return Err(format!("{name} is fixed while the node runs; restart the node to change it"));
    }
    cfg.set_value(name, value).map_err(|e| e.to_string())?;
    Ok(true)
}

struct Inputs {
    tf_static: Subscription<TfMessage>,
    odom: Subscription<Odometry>,
    imu: Option<Subscription<Imu>>,
    cloud: Subscription<OwnedCloud>,
    resume: Subscription<StringMsg>,
}

struct Outputs {
    cmd_vel: Publisher<Twist>,
    rows: Publisher<MarkerArray>,
    path: Publisher<Path>,
    status: Publisher<StringMsg>,
}

/// Counters of the shell, for the caller's log.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Counters {
    /// Clouds given to the core.
    pub clouds: u64,
    /// Clouds dropped unprocessed because a newer one was waiting.
    pub clouds_skipped: u64,
    /// Input messages the core refused (see the status' `input_error`).
    pub refused: u64,
    /// Samples the middleware could not decode.
    pub undecodable: u64,
    /// Outputs (rows, path, status) that could not be published.
    pub publish_failures: u64,
}

/// The running ROS 2 node: a [`NodeCore`] behind DDS readers and writers.
pub struct LiveNode {
    core: NodeCore,
    node: Node,
    inputs: Inputs,
    outputs: Outputs,
    poll: Poll,
    epoch: Instant,
    parameters: Receiver<(String, ParameterValue)>,
    shared_cfg: Arc<Mutex<NodeConfig>>,
    spinner: Option<JoinHandle<()>>,
    counters: Counters,
}

impl std::fmt::Debug for LiveNode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LiveNode").field("core", &self.core).field("counters", &self.counters).finish()
    }
}

impl LiveNode {
    /// Validates the configuration, joins the domain and creates every reader and writer. Each
    /// configuration leaf is declared as a ROS 2 parameter of the same dotted name; setting one
    /// rebuilds the core (the robot stops and looks for the rows again).
    pub fn new(cfg: NodeConfig, options: &DdsOptions) -> Result<Self, DdsError> {
        let core = NodeCore::new(cfg.clone())?;
        let context = context(options.domain_id, &options.networks)?;
        let shared_cfg = Arc::new(Mutex::new(cfg.clone()));
        let (tx, parameters) = mpsc::channel();
        let mut node_options = NodeOptions::new().enable_rosout(false);
        for (name, value) in cfg.leaves() {
            if let Some(v) = parameter(&value) {
                node_options = node_options.declare_parameter(&name, v);
            }
        }
        let check = Arc::clone(&shared_cfg);
        let apply = Arc::clone(&shared_cfg);
        let tx = Mutex::new(tx);
        node_options = node_options
            .parameter_validator(Box::new(move |name, value| {
                let mut cfg = check.lock().map_err(|_| "configuration lock poisoned".to_owned())?.clone();
                apply_parameter(&mut cfg, name, value).map(|_| ())
            }))
            .parameter_set_action(Box::new(move |name, value| {
                let mut cfg = apply.lock().map_err(|_| "configuration lock poisoned".to_owned())?;
                if !apply_parameter(&mut cfg, name, value)? {
                    return Ok(());
                }
                let tx = tx.lock().map_err(|_| "parameter channel lock poisoned".to_owned())?;
                tx.send((name.to_owned(), value.clone())).map_err(|_| "the node has stopped".to_owned())
            }));
        let node_name =
            NodeName::new(&options.namespace, &options.name).map_err(|e| create_err("node name")(&e))?;
        let mut node = context.new_node(node_name, node_options).map_err(|e| create_err("node")(&e))?;

        let w = &cfg.node;
        let odom_topic = match w.odometry {
            OdometrySource::Filtered => &w.odom_topic,
            OdometrySource::WheelImu => &w.wheel_odom_topic,
        };
        let mut inputs = Inputs {
            tf_static: subscribe(&mut node, "/tf_static", tf_static_qos())?,
            odom: subscribe(&mut node, odom_topic, sensor_qos(50))?,
            imu: match w.odometry {
                OdometrySource::Filtered => None,
                OdometrySource::WheelImu => Some(subscribe(&mut node, &w.imu_topic, sensor_qos(100))?),
            },
            cloud: subscribe(&mut node, &w.cloud_topic, sensor_qos(2))?,
            resume: subscribe(&mut node, &w.resume_topic, reliable_qos(1))?,
        };
        let outputs = Outputs {
            cmd_vel: advertise(&mut node, &w.cmd_vel_topic, reliable_qos(1))?,
            rows: advertise(&mut node, &w.rows_topic, reliable_qos(1))?,
            path: advertise(&mut node, &w.path_topic, reliable_qos(1))?,
            status: advertise(&mut node, &w.status_topic, reliable_qos(10))?,
        };
        let poll = Poll::new()?;
        let registry = poll.registry();
        registry.register(&mut inputs.tf_static, Token(0), Interest::READABLE)?;
        registry.register(&mut inputs.odom, Token(1), Interest::READABLE)?;
        if let Some(imu) = inputs.imu.as_mut() {
            registry.register(imu, Token(2), Interest::READABLE)?;
        }
        registry.register(&mut inputs.cloud, Token(3), Interest::READABLE)?;
        registry.register(&mut inputs.resume, Token(4), Interest::READABLE)?;

        // The spinner serves the parameter services and tracks the ROS graph; it runs until stopped.
        let spinner = node.spinner().map_err(|e| create_err("spinner")(&e))?;
        let spinner = std::thread::Builder::new()
            .name("croprow-spinner".into())
            .spawn(move || {
                // A spinner error only ends the parameter services; the node's data flow goes on.
                let _ = futures::executor::block_on(spinner.spin());
            })
            .map_err(DdsError::Poll)?;

        Ok(Self {
            core,
            node,
            inputs,
            outputs,
            poll,
            epoch: Instant::now(),
            parameters,
            shared_cfg,
            spinner: Some(spinner),
            counters: Counters::default(),
        })
    }

    /// The core (state, configuration).
    pub fn core(&self) -> &NodeCore {
        &self.core
    }

    /// The shell's counters.
    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Runs until `stop` is set (checked at least every control period), calling `observe` with every
    /// step's output after it is published. Publishes a zero command before returning.
    pub fn run(&mut self, stop: &AtomicBool, mut observe: impl FnMut(&Output)) -> Result<(), DdsError> {
        let period = Duration::from_secs_f64(self.core.config().node.control_period_s);
        let mut events = Events::with_capacity(16);
        let mut next_tick = Instant::now();
        let result = loop {
            if stop.load(Ordering::Relaxed) {
                break Ok(());
            }
            let timeout = next_tick.saturating_duration_since(Instant::now());
            if let Err(e) = self.poll.poll(&mut events, Some(timeout))
                && e.kind() != std::io::ErrorKind::Interrupted
            {
                break Err(DdsError::Poll(e));
            }
            if let Err(e) = self.apply_parameters().and_then(|()| self.drain_inputs(&mut observe)) {
                break Err(e);
            }
            let now = Instant::now();
            if now >= next_tick {
                let out = self.core.tick(self.now_s());
                if let Err(e) = self.publish(&out) {
                    break Err(e);
                }
                observe(&out);
                next_tick += period;
                if next_tick < now {
                    // Fell behind (a long step or a suspended process): no burst of catch-up steps.
                    next_tick = now + period;
                }
            }
        };
        let zero = self.outputs.cmd_vel.publish(convert::twist(Twist2::ZERO));
        result.and(zero.map_err(|e| DdsError::Publish {
            topic: self.core.config().node.cmd_vel_topic.clone(),
            reason: format!("{e:?}"),
        }))
    }

    fn now_s(&self) -> f64 {
        self.epoch.elapsed().as_secs_f64()
    }

    fn apply_parameters(&mut self) -> Result<(), DdsError> {
        let mut changed = false;
        while self.parameters.try_recv().is_ok() {
            changed = true;
        }
        if changed {
            // The shared configuration already holds every accepted change.
            let cfg = self.shared_cfg.lock().map(|c| c.clone()).unwrap_or_else(|p| p.into_inner().clone());
            let mut core = NodeCore::new(cfg)?;
            core.adopt_transforms(&self.core);
            self.core = core;
        }
        Ok(())
    }

    fn drain_inputs(&mut self, observe: &mut impl FnMut(&Output)) -> Result<(), DdsError> {
        let Self { core, inputs, counters, .. } = self;
        let now_s = self.epoch.elapsed().as_secs_f64();
        let mut errors = 0;
        drain(&inputs.tf_static, &mut errors, |m| core.on_tf_static(&m));
        let mut refused = 0;
        if let Some(imu) = &inputs.imu {
            let (mut wheel, mut gyro) = (Vec::new(), Vec::new());
            drain(&inputs.odom, &mut errors, |m| wheel.push(m));
            drain(imu, &mut errors, |m| gyro.push(m));
            refused += core.on_wheel_imu_batch(now_s, &wheel, &gyro) as u64;
        } else {
            drain(&inputs.odom, &mut errors, |m| refused += u64::from(core.on_odometry(now_s, &m).is_err()));
        }
        let mut resume = false;
        drain(&inputs.resume, &mut errors, |_| resume = true);
        if resume {
            core.resume();
        }
        let mut newest = None;
        drain(&inputs.cloud, &mut errors, |OwnedCloud(m)| {
            if newest.replace(m).is_some() {
                counters.clouds_skipped += 1;
            }
        });
        counters.undecodable += errors;
        counters.refused += refused;
        if let Some(cloud) = newest {
            counters.clouds += 1;
            match self.core.on_cloud(now_s, &cloud) {
                Ok(out) => {
                    self.publish(&out)?;
                    observe(&out);
                }
                Err(_) => self.counters.refused += 1,
            }
        }
        Ok(())
    }

    fn publish(&mut self, out: &Output) -> Result<(), DdsError> {
        self.outputs.cmd_vel.publish(out.cmd_vel).map_err(|e| DdsError::Publish {
            topic: self.core.config().node.cmd_vel_topic.clone(),
            reason: format!("{e:?}"),
        })?;
        let mut failures = u64::from(self.outputs.status.publish(out.status.clone()).is_err());
        if let Some(rows) = &out.rows {
            failures += u64::from(self.outputs.rows.publish(rows.clone()).is_err());
        }
        if let Some(path) = &out.path {
            failures += u64::from(self.outputs.path.publish(path.clone()).is_err());
        }
        self.counters.publish_failures += failures;
        Ok(())
    }
}

impl Drop for LiveNode {
    fn drop(&mut self) {
        self.node.stop_spinner();
        if let Some(handle) = self.spinner.take() {
            let _ = handle.join();
        }
    }
}
