//! `croprow simulate --scenario NAME|FILE.toml --out DIR`: one closed-loop run of the simulator
//! (`croprow_sim::closed_loop`): the EKF, the detector, the MPC and lane switching drive the
//! simulated robot. Writes into DIR:
//!
//! * `metrics.json`: the run's [`croprow_sim::Metrics`] (SI units);
//! * `trajectory.csv`: one row per control step, true pose in the field frame and believed pose in
//!   `odom` (the same frame at the start), command, mode, errors to the true lane centre line;
//! * `detections.jsonl`: the in-process detector's output per scan, in `croprow detect`'s format
//!   (without `latency_us`);
//! * `top_view.png` (field, trajectory, detected rows) and `errors.png` (lateral and heading error
//!   against distance while following).
//!
//! `--set key=value` overrides any scenario key (`field.length_m=20`), navigator key
//! (`mpc.horizon_steps=30`, `detector.mode="paper"`) or run key (`run.lanes=1`); values are TOML.
//! `--mcap FILE` records the run as ROS 2 messages (see [`Recorder`]).

use std::fmt::Write as _;
use std::fs;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use croprow_core::navigator::NavigatorConfig;
use croprow_core::{Detection, Pose2};
use croprow_io::{RecordingWriter, overrides};
use croprow_sim::closed_loop::{ClosedLoop, Run, RunConfig, Sample, Tick};
use croprow_sim::{Metrics, Scenario};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

use crate::plot;

/// Arguments of `croprow simulate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A built-in scenario (`croprow scenarios` lists them) or a scenario TOML file.
    #[arg(long, default_value = "full-field")]
    pub scenario: String,
    /// Output directory (created if needed).
    #[arg(long)]
    pub out: PathBuf,
    /// Master seed (overrides the scenario's).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Override a setting: `section.key=value` (TOML value); repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Also record the run as a ROS 2 MCAP file (open it in Foxglove).
    #[arg(long, value_name = "FILE")]
    pub mcap: Option<PathBuf>,
}

/// Everything one run needs: the scenario, the navigator and the run settings.
#[derive(Debug, Clone)]
pub struct Setup {
    /// The simulated experiment.
    pub scenario: Scenario,
    /// The navigation stack's configuration.
    pub navigator: NavigatorConfig,
    /// Closed-loop settings.
    pub run: RunConfig,
}

/// Sections of `--set` keys that belong to the navigator.
pub(crate) const NAV_SECTIONS: [&str; 7] =
    ["detector", "reference", "mpc", "lane_switch", "ekf", "drift", "attitude"];

/// Whether a dotted `--set` key belongs to the navigator (`mpc.horizon_steps`), not to the
/// scenario or the run.
pub(crate) fn is_navigator_key(key: &str) -> bool {
    key.split_once('.').is_some_and(|(section, _)| NAV_SECTIONS.contains(&section))
}

/// `navigator` with the navigator overrides `sets` (`KEY=VALUE`, values TOML) applied, validated. A
/// key outside the navigator is refused, the message saying why (`only_navigator`: "the soak draws
/// its own fields").
pub(crate) fn navigator_with_sets(
    navigator: &NavigatorConfig,
    sets: &[String],
    only_navigator: &str,
) -> Result<NavigatorConfig> {
    let mut navigator = navigator.clone();
    for item in sets {
        let (key, text) = overrides::split_assignment(item).with_context(|| format!("--set {item}"))?;
        if !is_navigator_key(key) {
            bail!(
                "--set {item}: {only_navigator}; only navigator keys ({}) can be set",
                NAV_SECTIONS.join(", ")
            );
        }
        navigator = overrides::set(&navigator, key, overrides::parse_literal(text))
            .with_context(|| format!("--set {item}"))?;
    }
    navigator.validate().context("the navigator with the --set overrides")?;
    Ok(navigator)
}

impl Setup {
    /// Loads a built-in scenario or a TOML file, applies the seed and the overrides.
    pub fn load(scenario: &str, seed: Option<u64>, sets: &[String]) -> Result<Self> {
        let scenario = if Scenario::names().contains(&scenario) {
            Scenario::builtin(scenario)?
        } else {
            let path = Path::new(scenario);
            if !path.exists() {
                bail!(
                    "`{scenario}` is neither a built-in scenario ({}) nor a file",
                    Scenario::names().join(", ")
                );
            }
            let text = fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
            Scenario::from_toml_str(&text).with_context(|| format!("scenario {}", path.display()))?
        };
        let mut setup = Self {
            scenario,
            navigator: croprow_sim::closed_loop::sim_navigator(),
            run: RunConfig::default(),
        };
        if let Some(seed) = seed {
            setup.scenario.seed = seed;
        }
        for item in sets {
            setup.apply(item).with_context(|| format!("--set {item}"))?;
        }
        setup.scenario.validate()?;
        setup.navigator.validate()?;
        setup.run.validate()?;
        Ok(setup)
    }

    /// Applies one `key=value` override.
    fn apply(&mut self, item: &str) -> Result<()> {
        let (key, text) = overrides::split_assignment(item)?;
        let value = overrides::parse_literal(text);
        if let Some(rest) = key.strip_prefix("run.") {
            self.run = overrides::set(&self.run, rest, value)?;
        } else if is_navigator_key(key) {
            self.navigator = overrides::set(&self.navigator, key, value)?;
        } else {
            self.scenario = overrides::set(&self.scenario, key, value)?;
        }
        Ok(())
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    let setup = Setup::load(&args.scenario, args.seed, &args.set)?;
    let record = simulate(&setup, &args.out, args.mcap.as_deref())?;
    print_summary(&record, &args.out, args.mcap.as_deref());
    Ok(())
}

/// Runs one closed loop with a progress bar and writes every output into `out`.
pub fn simulate(setup: &Setup, out: &Path, mcap: Option<&Path>) -> Result<Run> {
    fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut lp = ClosedLoop::new(&setup.scenario, &setup.navigator, setup.run.clone())?;
    let mut recorder = mcap.map(|p| Recorder::create(p, &setup.scenario)).transpose()?;
    let mut detections = Vec::new();
    let bar = progress_bar(&setup.scenario.name, lp.progress().max_time_s);
    while !lp.is_finished() {
        lp.step()?;
        let Some(tick) = lp.last_tick() else { continue };
        if let Some(d) = tick.nav.and_then(|n| n.detection) {
            detections.push(d);
        }
        let ran = tick.nav.is_some();
        if let Some(rec) = recorder.as_mut() {
            rec.record(&tick, &lp)?;
        }
        if ran {
            let p = lp.progress();
            bar.set_position((p.sim_time_s * 10.0) as u64);
            bar.set_message(format!("{} lanes {}/{}", p.mode.as_str(), p.lanes_completed, p.lanes_planned));
        }
    }
    bar.finish_and_clear();
    let record = lp.finish();
    if let Some(rec) = recorder {
        rec.finish()?;
    }
    write_outputs(&record, &detections, out)?;
    Ok(record)
}

fn progress_bar(name: &str, max_time_s: f64) -> ProgressBar {
    // stderr, hidden when stderr is not a terminal.
    let bar = ProgressBar::with_draw_target(Some((max_time_s * 10.0) as u64), ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("{prefix} [{elapsed_precise}] {bar:30} sim {pos}/{len} ds {msg}")
    {
        bar.set_style(style);
    }
    bar.set_prefix(name.to_owned());
    bar
}

/// Writes metrics.json, trajectory.csv, detections.jsonl and the plots.
pub fn write_outputs(record: &Run, detections: &[Detection], out: &Path) -> Result<()> {
    let json = serde_json::to_string_pretty(&record.metrics)?;
    fs::write(out.join("metrics.json"), json + "\n").context("writing metrics.json")?;
    fs::write(out.join("trajectory.csv"), trajectory_csv(&record.samples))
        .context("writing trajectory.csv")?;
    let mut lines = String::new();
    for d in detections {
        let line = serde_json::json!({
            "stamp": d.stamp_s,
            "left": d.left.map(|r| r.line),
            "right": d.right.map(|r| r.line),
            "status": d.status.as_str(),
        });
        let _ = writeln!(lines, "{line}");
    }
    fs::write(out.join("detections.jsonl"), lines).context("writing detections.jsonl")?;
    let trajectory: Vec<[f64; 2]> = record.samples.iter().map(|s| [s.truth.x, s.truth.y]).collect();
    let title = format!("{}: true trajectory and detected rows (field frame)", record.scenario);
    plot::top_view(
        &out.join("top_view.png"),
        &plot::TopView {
            title: &title,
            rows: &record.true_rows,
            trajectory: &trajectory,
            detected: &record.detected_rows,
        },
    )?;
    let following: Vec<&Sample> = record
        .samples
        .iter()
        .filter(|s| s.mode == croprow_core::control::lane_switch::Mode::Following)
        .filter(|s| s.cross_track_m.is_finite())
        .collect();
    let distance: Vec<f64> = following.iter().map(|s| s.distance_m).collect();
    let lateral: Vec<f64> = following.iter().map(|s| s.cross_track_m * 100.0).collect();
    let heading: Vec<f64> = following.iter().map(|s| s.heading_err_rad.to_degrees()).collect();
    let title = format!("{}: errors to the true centre line while following", record.scenario);
    plot::errors_vs_distance(
        &out.join("errors.png"),
        &plot::ErrorSeries {
            title: &title,
            distance_m: &distance,
            lateral_cm: &lateral,
            heading_deg: &heading,
        },
    )?;
    Ok(())
}

/// The trajectory as CSV (header row; field frame = `odom` at the start; SI units).
fn trajectory_csv(samples: &[Sample]) -> String {
    let mut s = String::from(
        "t_s,field_x_m,field_y_m,field_yaw_rad,odom_x_m,odom_y_m,odom_yaw_rad,cmd_v_mps,cmd_omega_radps,mode,lane,cross_track_m,heading_err_rad,distance_m,detection,crop_contacts\n",
    );
    for p in samples {
        let _ = writeln!(
            s,
            "{:.3},{:.4},{:.4},{:.5},{:.4},{:.4},{:.5},{:.4},{:.4},{},{},{:.4},{:.5},{:.3},{},{}",
            p.t_s,
            p.truth.x,
            p.truth.y,
            p.truth.yaw,
            p.odom.x,
            p.odom.y,
            p.odom.yaw,
            p.cmd.v,
            p.cmd.omega,
            p.mode.as_str(),
            p.lane,
            p.cross_track_m,
            p.heading_err_rad,
            p.distance_m,
            p.detection.map_or("", |d| d.as_str()),
            p.crop_contacts,
        );
    }
    s
}

/// Prints the summary table of a run.
pub fn print_summary(record: &Run, out: &Path, mcap: Option<&Path>) {
    let m: &Metrics = &record.metrics;
    let settle = m.settle_distance_m.map_or("never".to_owned(), |d| format!("{d:.2} m"));
    let rows = [
        ("scenario", record.scenario.clone()),
        ("final mode", m.final_mode.as_str().to_owned()),
        ("lanes completed", format!("{} / {}", m.lanes_completed, m.lanes_planned)),
        ("rows covered", m.rows_covered.to_string()),
        (
            "cross-track mean ± std",
            format!("{:.2} ± {:.2} cm", m.cross_track_mean_m * 100.0, m.cross_track_std_m * 100.0),
        ),
        ("cross-track max", format!("{:.2} cm", m.cross_track_max_m * 100.0)),
        ("heading error mean", format!("{:.2}°", m.heading_err_mean_deg)),
        ("settle distance (< 2 cm)", settle),
        ("crop contacts", m.crop_contacts.to_string()),
        (
            "least stem clearance",
            m.least_stem_clearance_m.map_or("no stem passed a tyre".to_owned(), |c| {
                format!("{:.1} cm from a tyre's side", c * 100.0)
            }),
        ),
        (
            "max headland excursion",
            format!("{:.2} m (wheels {:.2} m)", m.max_headland_excursion_m, m.max_wheel_excursion_m),
        ),
        ("distance / sim time", format!("{:.1} m / {:.1} s", m.distance_m, m.sim_time_s)),
        ("command violations", m.command_violations.to_string()),
    ];
    let width = rows.iter().map(|(k, _)| k.len()).max().unwrap_or(0);
    println!();
    for (k, v) in rows {
        println!("  {k:width$}  {v}");
    }
    println!(
        "\n  outputs in {}: metrics.json trajectory.csv detections.jsonl top_view.png errors.png",
        out.display()
    );
    if let Some(p) = mcap {
        println!("  recording: {} (open it in Foxglove)", p.display());
    }
}

/// Records a run as ROS 2 messages: `/velodyne_points` (PointCloud2, frame `velodyne`),
/// `/odometry/filtered` (Odometry, `odom` -> `base_link`), `/tf`, `/tf_static` (the LiDAR mount),
/// `/imu/data` (Imu, `base_link`, gravity added on z), `/cmd_vel` (Twist), `/croprow/rows`
/// (MarkerArray: rows and centroids in `base_link`), `/croprow/centre_line` (Path in `odom`) and
/// `/croprow/status` (String: the mission mode).
pub struct Recorder {
    writer: RecordingWriter,
    path: Vec<Pose2>,
}

impl Recorder {
    const CLOUD: &'static str = "/velodyne_points";
    const SENSOR_FRAME: &'static str = "velodyne";

    /// Creates the file and writes the static transform.
    pub fn create(path: &Path, scenario: &Scenario) -> Result<Self> {
        let mut writer =
            RecordingWriter::create(path).with_context(|| format!("creating {}", path.display()))?;
        writer.write_tf_static(0.0, Self::SENSOR_FRAME, &scenario.lidar.mount)?;
        Ok(Self { writer, path: Vec::with_capacity(64) })
    }

    /// Records what one step produced.
    pub fn record(&mut self, tick: &Tick<'_>, lp: &ClosedLoop) -> Result<()> {
        let t = tick.step.stamp_s;
        let w = &mut self.writer;
        if tick.step.wheel.is_some() || tick.scan.is_some() {
            w.write_odometry("/odometry/filtered", t, tick.odom, tick.odom_twist)?;
            w.write_tf(t, tick.odom)?;
        }
        if let Some(imu) = tick.step.imu {
            w.write_imu(
                "/imu/data",
                imu.stamp_s,
                "base_link",
                [0.0, 0.0, imu.gyro_z_rad_s],
                [imu.accel_x_m_s2, imu.accel_y_m_s2, imu.accel_z_m_s2],
            )?;
        }
        if let Some(scan) = tick.scan {
            w.write_cloud(Self::CLOUD, scan.stamp_s, Self::SENSOR_FRAME, scan.points, &[], &[])?;
        }
        if let Some(nav) = tick.nav {
            w.write_cmd_vel("/cmd_vel", t, nav.cmd)?;
            if let Some(d) = nav.detection {
                w.write_rows("/croprow/rows", &d, lp.navigator().detector().centroids())?;
                w.write_status("/croprow/status", t, nav.mode.as_str())?;
                if let Some(path) = lp.navigator().lane_switcher().path() {
                    let length = path.length_m();
                    let n = (length / 0.25).ceil().clamp(1.0, 400.0) as usize;
                    self.path.clear();
                    self.path.extend((0..=n).map(|i| path.pose_at(length * i as f64 / n as f64)));
                    w.write_path("/croprow/centre_line", t, "odom", &self.path)?;
                }
            }
        }
        Ok(())
    }

    /// Writes the summary and closes the file.
    pub fn finish(self) -> Result<()> {
        self.writer.finish()?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overrides_reach_the_scenario_the_navigator_and_the_run() {
        let sets = ["field.length_m=12".to_owned(), "mpc.horizon_steps=25".into(), "run.lanes=1".into()];
        let s = Setup::load("young-corn", Some(9), &sets).unwrap();
        assert_eq!((s.scenario.field.length_m, s.scenario.seed), (12.0, 9));
        assert_eq!(s.navigator.mpc.horizon_steps, 25);
        assert_eq!(s.run.lanes, 1);
        // Bare words are strings; optional keys can be set.
        let s =
            Setup::load("young-corn", None, &["detector.mode=paper".into(), "start.lane=3".into()]).unwrap();
        assert_eq!(s.navigator.detector.mode, croprow_core::DetectorMode::Paper);
        assert_eq!(s.scenario.lane(), 3);
    }

    #[test]
    fn bad_overrides_name_the_key() {
        let e = Setup::load("young-corn", None, &["field.lenght_m=3".into()]).unwrap_err();
        assert!(format!("{e:#}").contains("lenght_m"), "{e:#}");
        let e = Setup::load("young-corn", None, &["mpc.horizon_steps=-1".into()]).unwrap_err();
        assert!(format!("{e:#}").contains("mpc.horizon_steps"), "{e:#}");
        assert!(Setup::load("young-corn", None, &["nokey".into()]).is_err());
        assert!(Setup::load("no-such-field", None, &[]).is_err());
    }
}
