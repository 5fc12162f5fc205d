//! `croprow evaluate --suite soak --runs N [--seed S] --out DIR`: N randomised short fields driven end
//! to end in parallel on every core (`croprow_sim::experiment::soak`), each run watched for crop
//! contacts and unsafe commands, each run's panic caught and reported with its seed.
//!
//! Run `k` uses seed `S + k`. Writes `DIR/soak.json`:
//! `{runs, seed, distance_m, sim_time_s, wall_time_s, crop_contacts, unsafe_commands, panics, errors,
//! ends: {"done": n, "stopped: no_rows": n, ...}, failures: [{seed, scenario, what, replay}],
//! each: [{seed, crop, end, distance_m, crop_contacts, least_stem_clearance_m, unsafe_commands, faults,
//! replay?}]}` (and `near_misses`: runs that touched no plant but passed a stem under 5 cm from a
//! tyre's side), and for
//! every failing seed `DIR/fail-SEED.toml`, its scenario, so that the `replay` command
//! (`croprow simulate --scenario DIR/fail-SEED.toml --set ... --out DIR/replay-SEED`) drives it again
//! with plots and a trajectory; `croprow evaluate --suite soak --runs 1 --seed SEED` re-runs it under the
//! monitor. A run that did not fail but did not finish its lanes either (a safe stop such as
//! `stopped: wrong_lane`, or `never acquired`) gets `DIR/stop-SEED.toml` and its `replay` line in
//! `each`: a stop is safe, and still a robot standing in a field. `--set KEY=VALUE` (navigator keys
//! only) changes every run's navigator, so an opt-in can be soaked; the overrides go into each replay
//! line. `--baseline OLD/soak.json` compares the runs seed by seed with an earlier soak (the build
//! before, or the defaults against an opt-in): one sample of 1000 runs moves by chance, and a change
//! to the start or the detector reshuffles a few dozen runs, so the seeds that changed say more than
//! the totals. The comparison is printed and written as `baseline` in `soak.json`. Exits non-zero when
//! any run failed.

use std::any::Any;
use std::cell::RefCell;
use std::collections::BTreeMap;
use std::fs;
use std::panic::{self, AssertUnwindSafe};
use std::path::Path;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use anyhow::{Context, Result, bail};
use croprow_io::overrides;
use croprow_sim::experiment::soak::{Case, Outcome, run_case, soak_case};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};
use serde::{Deserialize, Serialize};

/// Most runs one command may ask for.
const MAX_RUNS: u32 = 1_000_000;

/// A run that touched no plant but passed a stem closer than this to a tyre's side is a near miss,
/// m: a sixth of the room a tyre has between two rows (0.75 m apart, tyres 0.15 m wide: stems about
/// 0.3 m from a centred tyre's side). Over the 155 runs of soak seeds 0-1999 with a wheel slide, 13
/// came this near without a contact and 3 ran over plants (session 45).
const NEAR_MISS_M: f64 = 0.05;

/// One failing run in `soak.json`.
#[derive(Debug, Clone, Serialize)]
struct Failure {
    seed: u64,
    /// The scenario's one-line description.
    scenario: String,
    what: String,
    /// The command that drives this run again.
    replay: String,
}

/// One run's result in `soak.json`.
#[derive(Debug, Clone, Serialize)]
struct RunLine {
    seed: u64,
    /// Crop and stage, e.g. `grown corn`.
    crop: String,
    /// How the run ended (`done`, `stopped: no_rows`, `never acquired`, `panic`, `error`, ...).
    end: String,
    distance_m: f64,
    crop_contacts: usize,
    /// The least clearance from a tyre's side to a stem beside it, m (negative: a contact; null: no
    /// stem passed alongside a tyre).
    least_stem_clearance_m: Option<f64>,
    unsafe_commands: usize,
    /// Faults injected, `;`-separated (empty for none).
    faults: String,
    /// The command that drives this run again, for every run that did not end `done` without a
    /// failure.
    #[serde(skip_serializing_if = "Option::is_none")]
    replay: Option<String>,
}

/// `soak.json`.
#[derive(Debug, Serialize)]
struct Report {
    runs: u32,
    seed: u64,
    distance_m: f64,
    sim_time_s: f64,
    wall_time_s: f64,
    crop_contacts: usize,
    /// Runs without a contact whose least stem clearance was under [`NEAR_MISS_M`].
    near_misses: usize,
    unsafe_commands: usize,
    panics: usize,
    errors: usize,
    /// How the runs ended, counted by label.
    ends: BTreeMap<String, usize>,
    failures: Vec<Failure>,
    /// Every run, in seed order.
    each: Vec<RunLine>,
    /// The comparison with `--baseline`, when given.
    #[serde(skip_serializing_if = "Option::is_none")]
    baseline: Option<Comparison>,
}

/// What `--baseline` reads of an earlier `soak.json`: each run's seed, end and contacts, and its
/// least stem clearance when it has one (soaks before session 45 do not).
#[derive(Debug, Clone, Deserialize)]
struct BaselineRun {
    seed: u64,
    end: String,
    crop_contacts: usize,
    #[serde(default)]
    least_stem_clearance_m: Option<f64>,
}

#[derive(Debug, Deserialize)]
struct BaselineFile {
    each: Vec<BaselineRun>,
}

/// A seed whose plants run over changed against the baseline.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct SeedChange {
    seed: u64,
    before: usize,
    after: usize,
}

/// This soak against `--baseline`, over the seeds both ran: `[before, after]` pairs.
#[derive(Debug, Clone, PartialEq, Serialize)]
struct Comparison {
    file: String,
    /// Seeds both soaks ran.
    common_runs: usize,
    crop_contacts: [usize; 2],
    runs_touching: [usize; 2],
    done: [usize; 2],
    /// Near misses (see [`NEAR_MISS_M`]) over the seeds both soaks ran that have a clearance in
    /// both (none in a baseline from before session 45).
    near_misses: [usize; 2],
    /// Seeds that ran over fewer plants now, and over more.
    fewer: Vec<SeedChange>,
    more: Vec<SeedChange>,
    /// Seeds whose end (`done`, `stopped: ...`) changed.
    ends_changed: usize,
}

/// Reads the runs of an earlier `soak.json`.
fn load_baseline(path: &Path) -> Result<Vec<BaselineRun>> {
    let text = fs::read_to_string(path).with_context(|| format!("reading --baseline {}", path.display()))?;
    let file: BaselineFile = serde_json::from_str(&text)
        .with_context(|| format!("--baseline {} is not a soak.json with an `each` list", path.display()))?;
    Ok(file.each)
}

/// Compares the runs `now` with the `before` ones seed by seed, over the seeds both hold.
fn compare(file: &Path, before: &[BaselineRun], now: &[RunLine]) -> Comparison {
    let old: BTreeMap<u64, &BaselineRun> = before.iter().map(|r| (r.seed, r)).collect();
    let mut c = Comparison {
        file: file.display().to_string(),
        common_runs: 0,
        crop_contacts: [0; 2],
        runs_touching: [0; 2],
        done: [0; 2],
        near_misses: [0; 2],
        fewer: Vec::new(),
        more: Vec::new(),
        ends_changed: 0,
    };
    for run in now {
        let Some(was) = old.get(&run.seed) else { continue };
        c.common_runs += 1;
        for (k, (plants, end)) in
            [(was.crop_contacts, &was.end), (run.crop_contacts, &run.end)].into_iter().enumerate()
        {
            c.crop_contacts[k] += plants;
            c.runs_touching[k] += usize::from(plants > 0);
            c.done[k] += usize::from(end == "done");
        }
        if let (Some(a), Some(b)) = (was.least_stem_clearance_m, run.least_stem_clearance_m) {
            c.near_misses[0] += usize::from(near_miss(was.crop_contacts, a));
            c.near_misses[1] += usize::from(near_miss(run.crop_contacts, b));
        }
        let change = SeedChange { seed: run.seed, before: was.crop_contacts, after: run.crop_contacts };
        match run.crop_contacts.cmp(&was.crop_contacts) {
            std::cmp::Ordering::Less => c.fewer.push(change),
            std::cmp::Ordering::Greater => c.more.push(change),
            std::cmp::Ordering::Equal => {}
        }
        c.ends_changed += usize::from(run.end != was.end);
    }
    c
}

/// A run that ran over no plant but passed one nearer than [`NEAR_MISS_M`] to a tyre's side.
fn near_miss(crop_contacts: usize, least_clearance_m: f64) -> bool {
    crop_contacts == 0 && least_clearance_m < NEAR_MISS_M
}

/// What one worker made of one run.
enum Verdict {
    Ran(Outcome),
    Error(String),
    Panic(String),
}

thread_local! {
    /// The last panic's message and location on this thread, set by the soak's panic hook.
    static LAST_PANIC: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// Runs the soak suite, every run's navigator changed by `sets` (`KEY=VALUE`, navigator keys).
pub fn run(runs: u32, seed: u64, sets: &[String], out: &Path, baseline: Option<&Path>) -> Result<()> {
    if runs == 0 || runs > MAX_RUNS {
        bail!("--runs must be in 1..={MAX_RUNS}");
    }
    // A bad override or baseline is refused before any run, not after an hour of them.
    case_of(seed, sets)?;
    let before = baseline.map(load_baseline).transpose()?;
    fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let seeds: Vec<u64> = (0..u64::from(runs)).map(|k| seed.wrapping_add(k)).collect();
    let bar = ProgressBar::with_draw_target(Some(seeds.len() as u64), ProgressDrawTarget::stderr());
    if let Ok(style) =
        ProgressStyle::with_template("soak [{elapsed_precise}] {bar:30} {pos}/{len} runs, eta {eta} {msg}")
    {
        bar.set_style(style);
    }
    // Panics are caught per run: their message goes into the report, not over the progress bar.
    let default_hook = panic::take_hook();
    panic::set_hook(Box::new(|info| {
        LAST_PANIC.with(|p| *p.borrow_mut() = Some(info.to_string()));
    }));
    let started = Instant::now();
    let next = AtomicUsize::new(0);
    let failed = AtomicUsize::new(0);
    let verdicts: Mutex<Vec<Option<Verdict>>> = Mutex::new((0..seeds.len()).map(|_| None).collect());
    let workers = std::thread::available_parallelism().map_or(1, |n| n.get()).min(seeds.len());
    std::thread::scope(|scope| {
        for _ in 0..workers {
            scope.spawn(|| {
                while let Some(&s) = seeds.get(next.fetch_add(1, Ordering::Relaxed)) {
                    let verdict = run_one(s, sets);
                    let bad = match &verdict {
                        Verdict::Ran(o) => !o.failures().is_empty(),
                        Verdict::Error(_) | Verdict::Panic(_) => true,
                    };
                    if bad {
                        let n = failed.fetch_add(1, Ordering::Relaxed) + 1;
                        bar.set_message(format!("{n} failed"));
                    }
                    let i = s.wrapping_sub(seed) as usize;
                    if let Ok(mut v) = verdicts.lock()
                        && let Some(slot) = v.get_mut(i)
                    {
                        *slot = Some(verdict);
                    }
                    bar.inc(1);
                }
            });
        }
    });
    let wall_time_s = started.elapsed().as_secs_f64();
    panic::set_hook(default_hook);
    bar.finish_and_clear();
    let verdicts = verdicts.into_inner().map_err(|_| anyhow::anyhow!("a soak worker died"))?;

    let mut report = Report {
        runs,
        seed,
        distance_m: 0.0,
        sim_time_s: 0.0,
        wall_time_s,
        crop_contacts: 0,
        near_misses: 0,
        unsafe_commands: 0,
        panics: 0,
        errors: 0,
        ends: BTreeMap::new(),
        failures: Vec::new(),
        each: Vec::with_capacity(seeds.len()),
        baseline: None,
    };
    for (&s, verdict) in seeds.iter().zip(verdicts) {
        let case = case_of(s, sets)?;
        let summary = &case.scenario.summary;
        let mut line = RunLine {
            seed: s,
            crop: summary.split_whitespace().take(2).collect::<Vec<_>>().join(" "),
            end: String::new(),
            distance_m: 0.0,
            crop_contacts: 0,
            least_stem_clearance_m: None,
            unsafe_commands: 0,
            faults: summary.split_once("; faults: ").map_or(String::new(), |(_, f)| f.replace(", ", "; ")),
            replay: None,
        };
        let whats = match verdict {
            Some(Verdict::Ran(o)) => {
                line.end = o.end.clone();
                (line.distance_m, line.crop_contacts, line.unsafe_commands) =
                    (o.distance_m, o.crop_contacts, o.unsafe_commands);
                line.least_stem_clearance_m = o.least_stem_clearance_m;
                report.near_misses +=
                    usize::from(o.least_stem_clearance_m.is_some_and(|c| near_miss(o.crop_contacts, c)));
                report.distance_m += o.distance_m;
                report.sim_time_s += o.sim_time_s;
                report.crop_contacts += o.crop_contacts;
                report.unsafe_commands += o.unsafe_commands;
                *report.ends.entry(o.end.clone()).or_default() += 1;
                o.failures()
            }
            Some(Verdict::Error(e)) => {
                line.end = "error".into();
                report.errors += 1;
                vec![format!("error: {e}")]
            }
            Some(Verdict::Panic(p)) => {
                line.end = "panic".into();
                report.panics += 1;
                vec![format!("panic: {p}")]
            }
            None => bail!("seed {s}: the run did not finish"),
        };
        if whats.is_empty() {
            if line.end != "done" {
                line.replay = Some(write_replay(&case, out, "stop")?);
            }
            report.each.push(line);
            continue;
        }
        let replay = write_replay(&case, out, "fail")?;
        line.replay = Some(replay.clone());
        report.each.push(line);
        for what in whats {
            report.failures.push(Failure {
                seed: s,
                scenario: case.scenario.summary.clone(),
                what,
                replay: replay.clone(),
            });
        }
    }
    report.baseline = baseline.zip(before.as_deref()).map(|(file, runs)| compare(file, runs, &report.each));
    let json = serde_json::to_string_pretty(&report)?;
    fs::write(out.join("soak.json"), json + "\n").context("writing soak.json")?;
    print_summary(&report, out);
    if !report.failures.is_empty() {
        bail!(
            "soak: {} failure(s) in {} runs (see {})",
            report.failures.len(),
            runs,
            out.join("soak.json").display()
        );
    }
    Ok(())
}

/// The soak case of `seed` with the navigator overrides `sets` applied and added to its replay line.
fn case_of(seed: u64, sets: &[String]) -> Result<Case> {
    let mut case = soak_case(seed);
    case.navigator = super::simulate::navigator_with_sets(
        &case.navigator,
        sets,
        "the soak draws its own fields and runs",
    )?;
    for item in sets {
        let (key, text) = overrides::split_assignment(item).with_context(|| format!("--set {item}"))?;
        case.overrides.push(format!("{key}={text}"));
    }
    Ok(case)
}

/// Draws and runs one case; a panic anywhere in it is caught and reported with the seed.
fn run_one(seed: u64, sets: &[String]) -> Verdict {
    LAST_PANIC.with(|p| p.borrow_mut().take());
    let ran = panic::catch_unwind(AssertUnwindSafe(|| -> Result<Outcome, String> {
        let case = case_of(seed, sets).map_err(|e| format!("{e:#}"))?;
        run_case(&case).map_err(|e| e.to_string())
    }));
    match ran {
        Ok(Ok(outcome)) => Verdict::Ran(outcome),
        Ok(Err(e)) => Verdict::Error(e),
        Err(payload) => {
            let hooked = LAST_PANIC.with(|p| p.borrow_mut().take());
            Verdict::Panic(hooked.unwrap_or_else(|| payload_text(payload.as_ref())))
        }
    }
}

fn payload_text(payload: &(dyn Any + Send)) -> String {
    payload
        .downcast_ref::<&str>()
        .map(|s| (*s).to_owned())
        .or_else(|| payload.downcast_ref::<String>().cloned())
        .unwrap_or_else(|| "a panic without a message".to_owned())
}

/// Writes the case's scenario to `DIR/KIND-SEED.toml` (`fail`, `stop`) and returns the command that
/// replays it.
fn write_replay(case: &Case, out: &Path, kind: &str) -> Result<String> {
    let path = out.join(format!("{kind}-{}.toml", case.seed));
    let text = toml::to_string(&case.scenario).context("serialising the scenario")?;
    let header = format!("# soak seed {}: {}\n", case.seed, case.scenario.summary);
    fs::write(&path, header + &text).with_context(|| format!("writing {}", path.display()))?;
    let sets: String = case.overrides.iter().map(|s| format!(" --set {s}")).collect();
    Ok(format!(
        "croprow simulate --scenario {}{sets} --out {}",
        path.display(),
        out.join(format!("replay-{}", case.seed)).display()
    ))
}

fn print_summary(r: &Report, out: &Path) {
    println!(
        "soak: {} runs from seed {}, {:.0} m driven in {:.0} s simulated ({:.0} s wall)",
        r.runs, r.seed, r.distance_m, r.sim_time_s, r.wall_time_s
    );
    println!(
        "  crop contacts {}, near misses {} (a stem under {:.0} cm from a tyre), unsafe commands {}, panics {}, errors {}",
        r.crop_contacts,
        r.near_misses,
        NEAR_MISS_M * 100.0,
        r.unsafe_commands,
        r.panics,
        r.errors
    );
    let ends: Vec<String> = r.ends.iter().map(|(k, v)| format!("{k} {v}")).collect();
    println!("  ends: {}", ends.join(", "));
    let failed = |seed: u64| r.failures.iter().any(|f| f.seed == seed);
    let stopped = r.each.iter().filter(|l| l.replay.is_some() && !failed(l.seed)).count();
    if stopped > 0 {
        println!(
            "  {stopped} run(s) stopped short without a failure: their replay lines are in soak.json (`each`)"
        );
    }
    for f in &r.failures {
        println!("  FAIL seed {}: {}\n    {}\n    replay: {}", f.seed, f.what, f.scenario, f.replay);
    }
    if let Some(c) = &r.baseline {
        print_comparison(c);
    }
    println!("  wrote {}", out.join("soak.json").display());
}

fn print_comparison(c: &Comparison) {
    let [p0, p1] = c.crop_contacts;
    let [t0, t1] = c.runs_touching;
    let [d0, d1] = c.done;
    let [n0, n1] = c.near_misses;
    println!(
        "  against {} ({} seeds in common): {p0} -> {p1} plants run over, {t0} -> {t1} runs touching plants, \
         {n0} -> {n1} near misses, {d0} -> {d1} done, {} ends changed",
        c.file, c.common_runs, c.ends_changed
    );
    let list = |changes: &[SeedChange]| {
        let items: Vec<String> =
            changes.iter().map(|s| format!("{} ({} -> {})", s.seed, s.before, s.after)).collect();
        if items.is_empty() { "none".to_owned() } else { items.join(", ") }
    };
    println!("    fewer plants: {}", list(&c.fewer));
    println!("    more plants: {}", list(&c.more));
}
