//! `croprow evaluate --suite paper --out DIR`: every simulated column of the paper's Table I (young
//! corn, grown corn, young soybean, grown soybean, curved corn), side by side with the published numbers.
//!
//! For each field and seed two runs:
//! * **detection** (paper Sec. V-A): the human-like driver wanders along the lane while the default and
//!   the `paper` detector run on the same scans
//!   (`croprow_sim::experiment::detection::run_detection`);
//! * **following** (Sec. V-B): the closed loop (EKF, default detector, MPC) drives one lane
//!   (`croprow_sim::closed_loop`); cross-track error while following.
//!
//! Both drive `--length-m` of rows (the paper drove 200 m). With `--seeds N` each run is repeated with
//! seeds `scenario seed + k`; the errors of all runs are pooled, so `mean ± std` is the mean absolute
//! error and its standard deviation over every scored sample, as the paper reports them. The runs go in
//! parallel on all cores. Writes `DIR/table.json`
//! (`{"fields": {"young-corn": {"detection", "detection_paper_mode", "following", "paper"}, ...}}`) and
//! `DIR/table.md`.
//!
//! `--set KEY=VALUE` (navigator keys, repeatable) changes the navigator of every following run and, for
//! `detector.*` keys, the default-mode detector of every detection run, so that an opt-in can be scored
//! on Table I; the table's header lists the overrides.
//!
//! `--suite soak --runs N [--seed S]` runs the soak instead (issue 6): see [`super::soak`].

use std::fmt::Write as _;
use std::fs;
use std::path::PathBuf;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

use anyhow::{Context, Result, bail};
use croprow_core::DetectorConfig;
use croprow_core::navigator::NavigatorConfig;
use croprow_sim::Scenario;
use croprow_sim::closed_loop::{self, RunConfig};
use croprow_sim::experiment::detection::{ErrorSummary, run_detection};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::Serialize;

/// The Table I simulated columns, in the paper's order.
const FIELDS: [&str; 5] = ["young-corn", "grown-corn", "young-soybean", "grown-soybean", "curved-corn"];

/// Paper Table I, simulated fields: detection distance (cm) and angle (deg) mean ± std, following
/// distance to the centre line (cm) mean ± std.
const PAPER: [(&str, [f64; 4], [f64; 2]); 5] = [
    ("young-corn", [1.67, 1.12, 0.28, 0.23], [0.97, 0.79]),
    ("grown-corn", [3.74, 2.49, 1.77, 1.51], [2.45, 1.69]),
    ("young-soybean", [1.54, 1.07, 0.49, 0.33], [0.64, 0.37]),
    ("grown-soybean", [3.04, 1.69, 1.14, 1.01], [1.24, 0.97]),
    ("curved-corn", [2.72, 1.33, 0.92, 0.71], [9.21, 7.25]),
];

/// Arguments of `croprow evaluate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Which suite: `paper` (Table I, simulated columns) or `soak` (randomised fields, safety monitor).
    #[arg(long, default_value = "paper")]
    pub suite: String,
    /// Output directory (created if needed).
    #[arg(long)]
    pub out: PathBuf,
    /// Runs per field, with seeds scenario seed + 0..N.
    #[arg(long, default_value_t = 1)]
    pub seeds: u32,
    /// Length of rows driven per run, m (the paper: 200).
    #[arg(long, default_value_t = 30.0)]
    pub length_m: f64,
    /// Soak: number of runs, with seeds `--seed` + 0..N.
    #[arg(long, default_value_t = 100)]
    pub runs: u32,
    /// Soak: seed of the first run.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Navigator override `KEY=VALUE` applied to every run (`detector.*`, `lane_switch.*`, ...; values
    /// are TOML), e.g. `--set detector.shear_window_m=0` to run with the slide test off. In the paper
    /// suite `detector.*` keys also change the default-mode detector of the detection runs. Repeatable.
    #[arg(long = "set", value_name = "KEY=VALUE")]
    pub set: Vec<String>,
    /// Soak: a previous run's `soak.json` to compare with seed by seed (plants run over, runs that
    /// touched plants, runs done, and each seed that changed), e.g. the run of the build before.
    #[arg(long, value_name = "SOAK_JSON")]
    pub baseline: Option<PathBuf>,
}

/// Detection errors as in Table I.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct DetectionRow {
    dist_cm_mean: f64,
    dist_cm_std: f64,
    ang_deg_mean: f64,
    ang_deg_std: f64,
}

/// Following error as in Table I.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct FollowingRow {
    cross_track_cm_mean: f64,
    cross_track_cm_std: f64,
}

/// The published numbers of one column.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct PaperRow {
    dist_cm_mean: f64,
    dist_cm_std: f64,
    ang_deg_mean: f64,
    ang_deg_std: f64,
    cross_track_cm_mean: f64,
    cross_track_cm_std: f64,
}

/// One column of the table.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
struct FieldRow {
    detection: DetectionRow,
    detection_paper_mode: DetectionRow,
    following: FollowingRow,
    paper: PaperRow,
}

/// `table.json`.
#[derive(Debug, Serialize)]
struct Table {
    fields: std::collections::BTreeMap<String, FieldRow>,
}

/// One unit of work.
#[derive(Debug, Clone, Copy)]
enum Job {
    Detection { field: usize, seed: u64 },
    Following { field: usize, seed: u64 },
}

/// What a job produced: pooled error summaries.
#[derive(Debug, Clone, Copy)]
enum Outcome {
    /// Default mode (distance, angle), paper mode (distance, angle).
    Detection([Pooled; 4]),
    /// Cross-track, cm.
    Following(Pooled),
}

/// Running pool of (count, mean, std) summaries: the mean and std of the union of the samples.
#[derive(Debug, Clone, Copy, Default)]
struct Pooled {
    count: f64,
    sum: f64,
    sum_sq: f64,
}

impl Pooled {
    fn of(count: usize, mean: f64, std: f64) -> Self {
        let n = count as f64;
        Self { count: n, sum: n * mean, sum_sq: n * (std * std + mean * mean) }
    }

    fn from_summary(s: &ErrorSummary) -> Self {
        Self::of(s.count, s.mean, s.std)
    }

    fn add(&mut self, o: &Pooled) {
        self.count += o.count;
        self.sum += o.sum;
        self.sum_sq += o.sum_sq;
    }

    fn mean(&self) -> f64 {
        if self.count > 0.0 { self.sum / self.count } else { f64::NAN }
    }

    fn std(&self) -> f64 {
        if self.count > 0.0 {
            let m = self.mean();
            (self.sum_sq / self.count - m * m).max(0.0).sqrt()
        } else {
            f64::NAN
        }
    }
}

/// Runs the subcommand.
pub fn run(args: Args) -> Result<()> {
    match args.suite.as_str() {
        "paper" if args.baseline.is_some() => bail!("--baseline goes with --suite soak"),
        "paper" => {}
        "soak" => {
            return super::soak::run(args.runs, args.seed, &args.set, &args.out, args.baseline.as_deref());
        }
        other => bail!("unknown suite `{other}` (known: paper, soak)"),
    }
    let navigator = super::simulate::navigator_with_sets(
        &closed_loop::sim_navigator(),
        &args.set,
        "Table I runs its own fields",
    )?;
    if args.seeds == 0 || args.seeds > 1000 {
        bail!("--seeds must be in 1..=1000");
    }
    if !(args.length_m.is_finite() && (1.0..=2000.0).contains(&args.length_m)) {
        bail!("--length-m must be in [1, 2000] m");
    }
    fs::create_dir_all(&args.out).with_context(|| format!("creating {}", args.out.display()))?;
    let scenarios: Vec<Scenario> = FIELDS.iter().map(|n| Scenario::builtin(n)).collect::<Result<_, _>>()?;
    let mut jobs = Vec::new();
    for (field, scenario) in scenarios.iter().enumerate() {
        for k in 0..u64::from(args.seeds) {
            let seed = scenario.seed.wrapping_add(k);
            jobs.push(Job::Following { field, seed });
            jobs.push(Job::Detection { field, seed });
        }
    }
    let bar = ProgressBar::with_draw_target(Some(jobs.len() as u64), ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("evaluate [{elapsed_precise}] {bar:30} {pos}/{len} runs {msg}")
    {
        bar.set_style(style);
    }
    let next = AtomicUsize::new(0);
    let results: Mutex<Vec<Option<Result<Outcome, String>>>> = Mutex::new(vec![None; jobs.len()]);
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get()).min(jobs.len());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                loop {
                    let i = next.fetch_add(1, Ordering::Relaxed);
                    let Some(job) = jobs.get(i) else { break };
                    let outcome =
                        run_job(*job, &scenarios, &navigator, args.length_m).map_err(|e| format!("{e:#}"));
                    if let Ok(mut r) = results.lock()
                        && let Some(slot) = r.get_mut(i)
                    {
                        *slot = Some(outcome);
                    }
                    bar.inc(1);
                }
            });
        }
    });
    bar.finish_and_clear();
    let results = results.into_inner().map_err(|_| anyhow::anyhow!("a worker panicked"))?;

    let mut table = Table { fields: Default::default() };
    for (f, name) in FIELDS.iter().enumerate() {
        let mut det = [Pooled::default(); 4];
        let mut follow = Pooled::default();
        for (job, result) in jobs.iter().zip(&results) {
            let field = match job {
                Job::Detection { field, .. } | Job::Following { field, .. } => *field,
            };
            if field != f {
                continue;
            }
            match result {
                Some(Ok(Outcome::Detection(p))) => det.iter_mut().zip(p).for_each(|(a, b)| a.add(b)),
                Some(Ok(Outcome::Following(p))) => follow.add(p),
                Some(Err(e)) => bail!("{name}: {e}"),
                None => bail!("{name}: a run did not finish"),
            }
        }
        let (_, d, fl) = PAPER[f];
        let detection = |a: &Pooled, b: &Pooled| DetectionRow {
            dist_cm_mean: a.mean(),
            dist_cm_std: a.std(),
            ang_deg_mean: b.mean(),
            ang_deg_std: b.std(),
        };
        table.fields.insert(
            (*name).to_owned(),
            FieldRow {
                detection: detection(&det[0], &det[1]),
                detection_paper_mode: detection(&det[2], &det[3]),
                following: FollowingRow {
                    cross_track_cm_mean: follow.mean(),
                    cross_track_cm_std: follow.std(),
                },
                paper: PaperRow {
                    dist_cm_mean: d[0],
                    dist_cm_std: d[1],
                    ang_deg_mean: d[2],
                    ang_deg_std: d[3],
                    cross_track_cm_mean: fl[0],
                    cross_track_cm_std: fl[1],
                },
            },
        );
    }
    let json = serde_json::to_string_pretty(&table)?;
    fs::write(args.out.join("table.json"), json + "\n").context("writing table.json")?;
    let md = markdown(&table, &args);
    fs::write(args.out.join("table.md"), &md).context("writing table.md")?;
    print!("{md}");
    Ok(())
}

fn run_job(job: Job, scenarios: &[Scenario], navigator: &NavigatorConfig, length_m: f64) -> Result<Outcome> {
    match job {
        Job::Detection { field, seed } => {
            let mut s = scenarios.get(field).context("field")?.clone();
            s.seed = seed;
            let modes = [navigator.detector.clone(), DetectorConfig::paper()];
            let report = run_detection(&s, length_m, &modes, &mut |_| {})?;
            let [ours, paper] = report.modes.as_slice() else { bail!("expected two detector modes") };
            Ok(Outcome::Detection([
                Pooled::from_summary(&ours.distance_cm),
                Pooled::from_summary(&ours.angle_deg),
                Pooled::from_summary(&paper.distance_cm),
                Pooled::from_summary(&paper.angle_deg),
            ]))
        }
        Job::Following { field, seed } => {
            let mut s = scenarios.get(field).context("field")?.clone();
            s.seed = seed;
            s.field.length_m = s.field.length_m.min(s.start.x_m + length_m);
            let cfg = RunConfig { lanes: 1, ..RunConfig::default() };
            let run = closed_loop::run(&s, navigator.clone(), cfg, |_| {})?;
            let m = &run.metrics;
            Ok(Outcome::Following(Pooled::of(
                m.following_samples,
                m.cross_track_mean_m * 100.0,
                m.cross_track_std_m * 100.0,
            )))
        }
    }
}

fn markdown(table: &Table, args: &Args) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "# Table I, simulated fields: croprow vs the paper\n\n{} m of rows per run, {} seed(s) per field; mean ± std of the absolute error over every scored sample (the paper drove 200 m).\n",
        args.length_m, args.seeds
    );
    if !args.set.is_empty() {
        let _ = writeln!(s, "Navigator overrides: `{}`.\n", args.set.join("`, `"));
    }
    let _ = writeln!(
        s,
        "| field | detection dist (cm) | detection angle (°) | paper-mode dist (cm) | paper-mode angle (°) | following (cm) | paper: dist (cm) | paper: angle (°) | paper: following (cm) |"
    );
    let _ = writeln!(s, "|---|---|---|---|---|---|---|---|---|");
    let pm = |m: f64, sd: f64| format!("{m:.2} ± {sd:.2}");
    for name in FIELDS {
        let Some(r) = table.fields.get(name) else { continue };
        let _ = writeln!(
            s,
            "| {name} | {} | {} | {} | {} | {} | {} | {} | {} |",
            pm(r.detection.dist_cm_mean, r.detection.dist_cm_std),
            pm(r.detection.ang_deg_mean, r.detection.ang_deg_std),
            pm(r.detection_paper_mode.dist_cm_mean, r.detection_paper_mode.dist_cm_std),
            pm(r.detection_paper_mode.ang_deg_mean, r.detection_paper_mode.ang_deg_std),
            pm(r.following.cross_track_cm_mean, r.following.cross_track_cm_std),
            pm(r.paper.dist_cm_mean, r.paper.dist_cm_std),
            pm(r.paper.ang_deg_mean, r.paper.ang_deg_std),
            pm(r.paper.cross_track_cm_mean, r.paper.cross_track_cm_std),
        );
    }
    s
}
