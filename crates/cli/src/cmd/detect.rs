//! `croprow detect INPUT.mcap --out rows.jsonl`: runs the row detector over a ROS 2 recording.
//!
//! Each scan of the cloud topic is decoded, paired with the odometry pose interpolated to its stamp and
//! the sensor mount from `/tf_static` (else the config's `[mount]`, the paper's by default), and given
//! to [`RowDetector`] alone: its centroid map lives in the recording's `odom` (the navigator's drift
//! estimator, which maps in `odom` minus a learned wheel slide, is not run). One JSON object per scan is written and flushed at once, so a fault part-way
//! keeps every line before it; the fault then ends the command with a non-zero exit.
//!
//! Output line (rows in `base_link`, m):
//! `{"stamp":1717000000.1,"left":[x1,y1,x2,y2]|null,"right":...|null,"status":"tracking","latency_us":312}`.
//! A scan outside the odometry's coverage is written with status `invalid_input` and no rows
//! (the detector is not run: it has no pose).
//!
//! The config file (TOML) may hold `[detector]` (the detector config), `[replay]` (topics, frames,
//! interpolation limits of `croprow_io::ReplayConfig`) and `[mount]` (fallback sensor mount).

use std::fs::File;
use std::io::Write;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use croprow_core::{DetectorConfig, DetectorMode, Mount, RowDetector};
use croprow_io::{Recording, ReplayConfig};
use serde::{Deserialize, Serialize};

/// Arguments of `croprow detect`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The ROS 2 recording (MCAP, CDR messages).
    pub input: PathBuf,
    /// Output file: one JSON object per scan.
    #[arg(long)]
    pub out: PathBuf,
    /// `sensor_msgs/msg/PointCloud2` topic (overrides `replay.cloud_topic`).
    #[arg(long)]
    pub cloud_topic: Option<String>,
    /// `nav_msgs/msg/Odometry` topic (overrides `replay.odom_topic`).
    #[arg(long)]
    pub odom_topic: Option<String>,
    /// Detector pipeline (overrides `detector.mode`).
    #[arg(long, value_enum)]
    pub mode: Option<Mode>,
    /// TOML config with optional `[detector]`, `[replay]` and `[mount]` sections.
    #[arg(long)]
    pub config: Option<PathBuf>,
}

/// Detector pipeline as spelled on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// The paper's method.
    Paper,
    /// Croprow's default method.
    Default,
}

/// The config file of `croprow detect`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
struct DetectConfig {
    detector: Option<DetectorConfig>,
    replay: ReplayConfig,
    /// Sensor mount used when the recording has no `/tf_static` for the cloud's frame.
    mount: Option<Mount>,
}

/// One output line.
#[derive(Debug, Serialize)]
struct Line<'a> {
    stamp: f64,
    left: Option<[f64; 4]>,
    right: Option<[f64; 4]>,
    status: &'a str,
    latency_us: u64,
}

/// Runs the subcommand.
pub fn run(args: Args) -> anyhow::Result<()> {
    let file_config: DetectConfig = match &args.config {
        Some(path) => {
            let text =
                std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?
        }
        None => DetectConfig::default(),
    };
    let mode = args.mode.map(|m| match m {
        Mode::Paper => DetectorMode::Paper,
        Mode::Default => DetectorMode::Default,
    });
    let mut detector_config = match (file_config.detector, mode) {
        (Some(c), _) => c,
        (None, Some(DetectorMode::Paper)) => DetectorConfig::paper(),
        (None, _) => DetectorConfig::default(),
    };
    if let Some(mode) = mode {
        detector_config.mode = mode;
    }
    let mut replay_config = file_config.replay;
    if let Some(t) = args.cloud_topic {
        replay_config.cloud_topic = t;
    }
    if let Some(t) = args.odom_topic {
        replay_config.odom_topic = t;
    }
    replay_config.fallback_mount = Some(file_config.mount.unwrap_or_default());

    let mut detector = RowDetector::new(detector_config).context("invalid detector config")?;
    let mut replay = Recording::open(&args.input)?.replay(&replay_config)?;
    let mut out = File::create(&args.out).with_context(|| format!("creating {}", args.out.display()))?;

    let mut stats = Stats::default();
    let mut line = Vec::with_capacity(256);
    let result = loop {
        let read_start = Instant::now();
        let frame = match replay.next_scan() {
            None => break Ok(()),
            Some(Err(e)) => break Err(anyhow::Error::new(e)),
            Some(Ok(frame)) => frame,
        };
        stats.read_us.push(read_start.elapsed().as_secs_f64() * 1e6);
        let record = match frame.odom_pose {
            Ok(pose) => {
                let start = Instant::now();
                let d = detector.detect(frame.scan(), pose, &frame.mount);
                let latency = start.elapsed().as_secs_f64() * 1e6;
                stats.latency_us.push(latency);
                Line {
                    stamp: frame.stamp_s,
                    left: d.left.map(|r| r.line),
                    right: d.right.map(|r| r.line),
                    status: d.status.as_str(),
                    latency_us: latency.round() as u64,
                }
            }
            Err(_) => {
                stats.without_pose += 1;
                Line {
                    stamp: frame.stamp_s,
                    left: None,
                    right: None,
                    status: croprow_core::RowStatus::InvalidInput.as_str(),
                    latency_us: 0,
                }
            }
        };
        stats.scans += 1;
        stats.detections += usize::from(record.left.is_some() || record.right.is_some());
        line.clear();
        serde_json::to_writer(&mut line, &record)?;
        line.push(b'\n');
        // One write per line, straight to the file: a later fault cannot lose it.
        out.write_all(&line).with_context(|| format!("writing {}", args.out.display()))?;
    };
    out.flush()?;
    stats.print(&args.out);
    result.with_context(|| format!("replaying {} stopped after {} scans", args.input.display(), stats.scans))
}

#[derive(Debug, Default)]
struct Stats {
    scans: usize,
    detections: usize,
    without_pose: usize,
    latency_us: Vec<f64>,
    read_us: Vec<f64>,
}

impl Stats {
    fn print(&mut self, out: &std::path::Path) {
        let (med, p95) = percentiles(&mut self.latency_us);
        let (read_med, read_p95) = percentiles(&mut self.read_us);
        eprintln!(
            "croprow detect: {} scans, {} with a row, {} without odometry -> {}\n  detector latency: median {med:.0} µs, p95 {p95:.0} µs\n  read + decode per scan: median {read_med:.0} µs, p95 {read_p95:.0} µs",
            self.scans,
            self.detections,
            self.without_pose,
            out.display()
        );
    }
}

/// Median and 95th percentile (nearest rank); zeros when empty.
fn percentiles(v: &mut [f64]) -> (f64, f64) {
    if v.is_empty() {
        return (0.0, 0.0);
    }
    v.sort_by(f64::total_cmp);
    let at = |q: f64| v[((v.len() - 1) as f64 * q).round() as usize];
    (at(0.5), at(0.95))
}
