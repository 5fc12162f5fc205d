//! `croprow node [--config FILE] [--set key=value ...] [--domain-id N] [--network ADDR ...]`: the live
//! ROS 2 node (built with the cargo feature `ros2`).
//!
//! The configuration is the node's TOML tree (`[detector]`, `[reference]`, `[mpc]`, `[lane_switch]`,
//! `[ekf]`, `[mount]`, `[node]`), then each `--set` in order; the same dotted names are the node's
//! ROS 2 parameters. Discovery and data stay on the given local addresses (`--network`, loopback by
//! default: every ROS 2 node on this computer); give the robot's LAN address to reach other hosts.
//! Ctrl-C or SIGTERM stops the node after a zero command. A status line goes to stderr every
//! `--log-period-s`.

use std::net::{IpAddr, Ipv4Addr};
use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::Context;
use croprow_io::overrides;
use croprow_ros2::{DdsOptions, LiveNode, NodeConfig};

/// Arguments of `croprow node`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// TOML configuration (every section optional).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Overrides one setting by its dotted name, e.g. `--set mpc.horizon_steps=30`; repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// ROS domain id (default: `ROS_DOMAIN_ID`, else 0).
    #[arg(long)]
    pub domain_id: Option<u16>,
    /// Local address whose network carries discovery and data; repeatable.
    #[arg(long = "network", value_name = "ADDR", default_values_t = [IpAddr::V4(Ipv4Addr::LOCALHOST)])]
    pub networks: Vec<IpAddr>,
    /// Node name.
    #[arg(long, default_value = "croprow")]
    pub name: String,
    /// Print the resolved configuration as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Stop by itself after this many seconds (0: run until Ctrl-C).
    #[arg(long, default_value_t = 0.0)]
    pub duration_s: f64,
    /// Seconds between status lines on stderr (0: none).
    #[arg(long, default_value_t = 1.0)]
    pub log_period_s: f64,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let mut cfg = match &args.config {
        Some(path) => {
            let text =
                std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            NodeConfig::from_toml(&text).with_context(|| format!("in {}", path.display()))?
        }
        None => NodeConfig::default(),
    };
    for item in &args.set {
        let (key, text) = overrides::split_assignment(item).with_context(|| format!("--set {item}"))?;
        cfg.set(key, text).with_context(|| format!("--set {item}"))?;
    }
    if args.print_config {
        print!("{}", toml::to_string(&cfg).context("writing the configuration")?);
        return Ok(());
    }
    anyhow::ensure!(
        args.duration_s.is_finite() && args.duration_s >= 0.0,
        "--duration-s must be a finite number of seconds >= 0"
    );
    anyhow::ensure!(
        args.log_period_s.is_finite() && args.log_period_s >= 0.0,
        "--log-period-s must be a finite number of seconds >= 0"
    );

    let domain_id = match args.domain_id {
        Some(id) => id,
        None => match std::env::var("ROS_DOMAIN_ID") {
            Ok(text) if !text.trim().is_empty() => {
                text.trim().parse().with_context(|| format!("ROS_DOMAIN_ID={text} is not a domain id"))?
            }
            _ => 0,
        },
    };
    let stop = Arc::new(AtomicBool::new(false));
    let handler_stop = Arc::clone(&stop);
    ctrlc::set_handler(move || handler_stop.store(true, Ordering::Relaxed))
        .context("installing the Ctrl-C handler")?;
    let options = DdsOptions {
        domain_id,
        networks: args.networks.clone(),
        name: args.name.clone(),
        ..DdsOptions::default()
    };
    let mut node = LiveNode::new(cfg, &options).context("starting the ROS 2 node")?;
    let w = &node.core().config().node;
    eprintln!(
        "croprow node `{}` on domain {} via {:?}: {} + {} -> {}, {}, {}, {}",
        args.name,
        domain_id,
        args.networks,
        w.cloud_topic,
        match w.odometry {
            croprow_ros2::OdometrySource::Filtered => w.odom_topic.clone(),
            croprow_ros2::OdometrySource::WheelImu => format!("{} + {}", w.wheel_odom_topic, w.imu_topic),
        },
        w.cmd_vel_topic,
        w.rows_topic,
        w.path_topic,
        w.status_topic,
    );

    let started = Instant::now();
    let until = (args.duration_s > 0.0).then(|| started + Duration::from_secs_f64(args.duration_s));
    let log_every = (args.log_period_s > 0.0).then(|| Duration::from_secs_f64(args.log_period_s));
    let mut next_log = started;
    let stop_flag = Arc::clone(&stop);
    node.run(&stop, |out| {
        let now = Instant::now();
        if let Some(every) = log_every
            && now >= next_log
        {
            eprintln!("{}", out.status.data);
            next_log = now + every;
        }
        if until.is_some_and(|u| now >= u) {
            stop_flag.store(true, Ordering::Relaxed);
        }
    })
    .context("running the ROS 2 node")?;
    let c = node.counters();
    eprintln!(
        "stopped after {:.1} s: {} clouds ({} skipped as stale), {} inputs refused, {} undecodable, {} failed publications",
        started.elapsed().as_secs_f64(),
        c.clouds,
        c.clouds_skipped,
        c.refused,
        c.undecodable,
        c.publish_failures
    );
    Ok(())
}
