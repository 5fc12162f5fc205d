//! A seeded, bounded, mutation-based fuzzer that runs on stable Rust as an ordinary integration test
//! (cargo-fuzz needs nightly and a sanitizer runtime; CI has neither).
//!
//! A [`Campaign`] starts from valid seed inputs and, for each execution, stacks a few random
//! mutations on one of them (bit flips, bytes and integers set to boundary values, floats set to
//! NaN/inf, length fields corrupted, truncation, extension, chunk deletion/duplication, splicing with
//! another input, dictionary tokens for text formats). The target runs under `catch_unwind`; a panic
//! or a consistency violation the target reports is a failure, kept with the execution's seed and
//! the input (hex in the message, the full bytes in a file under the temp dir) so it can be replayed
//! and turned into a regression test. Inputs the target accepts join a small pool that later
//! executions mutate further, which reaches past the first checksum or header most decoders have.
//!
//! Environment:
//! - `CROPROW_FUZZ_EXECS`: executions per campaign (the default of each test keeps the whole suite
//!   under a minute in the dev profile; long runs set 100000 or more).
//! - `CROPROW_FUZZ_SEED`: base seed (default 0x5eed); every execution derives its own seed from it,
//!   its index and the campaign name, so a failure is replayed by its index alone.
//!
//! Shared by the fuzz tests of croprow-io, croprow-sim and croprow-ros2 through `#[path]`.

#![allow(dead_code)]

use std::panic::{self, AssertUnwindSafe};
use std::sync::Once;
use std::time::{Duration, Instant};

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;

/// What a target did with an input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// Decoded, and what came out passed the target's consistency checks.
    Accepted,
    /// Refused with one of the decoder's documented errors.
    Rejected,
}

/// A target's answer: a verdict, or a consistency violation (a silent wrong answer).
pub type Outcome = Result<Verdict, String>;

/// One failing execution.
#[derive(Debug, Clone)]
pub struct Failure {
    /// Execution index (replay with the same base seed).
    pub exec: usize,
    /// What went wrong: the panic message or the violated check.
    pub what: String,
    /// The input.
    pub input: Vec<u8>,
}

/// The counts of a finished campaign.
#[derive(Debug, Clone)]
pub struct Report {
    /// Campaign name.
    pub name: String,
    /// Executions run.
    pub execs: usize,
    /// Inputs accepted.
    pub accepted: usize,
    /// Inputs rejected with a documented error.
    pub rejected: usize,
    /// Panics and consistency violations.
    pub failures: Vec<Failure>,
    /// Slowest single execution (reported, never asserted: hangs show as a test that does not end).
    pub slowest: Duration,
    /// Index of the slowest execution; its input is saved beside the failures for a look.
    pub slowest_exec: usize,
}

impl Report {
    fn new(name: &str) -> Self {
        Self {
            name: name.to_owned(),
            execs: 0,
            accepted: 0,
            rejected: 0,
            failures: Vec::new(),
            slowest: Duration::ZERO,
            slowest_exec: 0,
        }
    }

    /// Prints the counts (one line, the figures docs/fuzzing.md records) and fails the test on any
    /// failure, listing the first ten with their inputs.
    fn conclude(self) -> Self {
        println!(
            "fuzz {}: {} executions ({} accepted, {} rejected), {} failures, slowest {:.1} ms (exec {}), seed {}",
            self.name,
            self.execs,
            self.accepted,
            self.rejected,
            self.failures.len(),
            self.slowest.as_secs_f64() * 1e3,
            self.slowest_exec,
            base_seed(),
        );
        if !self.failures.is_empty() {
            let dir = std::env::temp_dir().join("croprow-fuzz-failures");
            let _ = std::fs::create_dir_all(&dir);
            let mut text = String::new();
            for f in self.failures.iter().take(10) {
                let file = dir.join(format!("{}-{}.bin", self.name, f.exec));
                let _ = std::fs::write(&file, &f.input);
                text.push_str(&format!(
                    "\n  exec {} ({} bytes, saved to {}): {}\n    {}",
                    f.exec,
                    f.input.len(),
                    file.display(),
                    f.what,
                    hex(&f.input, 256)
                ));
            }
            panic!("fuzz {}: {} failures (first 10):{text}", self.name, self.failures.len());
        }
        self
    }

    /// Counts one execution.
    fn record(&mut self, exec: usize, outcome: Outcome, input: &[u8], elapsed: Duration) {
        self.execs += 1;
        if elapsed > self.slowest {
            self.slowest = elapsed;
            self.slowest_exec = exec;
        }
        match outcome {
            Ok(Verdict::Accepted) => self.accepted += 1,
            Ok(Verdict::Rejected) => self.rejected += 1,
            Err(what) => self.failures.push(Failure { exec, what, input: input.to_vec() }),
        }
    }
}

/// Runs a generator-driven campaign: each execution gets its own seeded rng, builds an input with
/// it, writes that input into the buffer (for the failure report) and checks it. Counts and failures
/// are reported like [`Campaign::run`]'s.
pub fn run_generated(
    name: &str,
    default_execs: usize,
    mut target: impl FnMut(&mut ChaCha8Rng, &mut Vec<u8>) -> Outcome,
) -> Report {
    let name_hash = fnv(name.as_bytes());
    let mut report = Report::new(name);
    let mut input = Vec::new();
    for exec in 0..execs_or(default_execs) {
        let mut rng = ChaCha8Rng::seed_from_u64(mix(base_seed() ^ name_hash).wrapping_add(exec as u64));
        input.clear();
        let started = Instant::now();
        let outcome = catch(|| target(&mut rng, &mut input)).and_then(|o| o);
        report.record(exec, outcome, &input, started.elapsed());
    }
    report.conclude()
}

/// TOML values and syntax that break parsers and range checks, for every config fuzzer (each adds
/// its own section headers).
pub const TOML_TOKENS: [&[u8]; 25] = [
    b"nan",
    b"+nan",
    b"-nan",
    b"inf",
    b"-inf",
    b"1e309",
    b"-0.0",
    b"0",
    b"-1",
    b"1e-320",
    b"9223372036854775807",
    b"-9223372036854775808",
    b"9223372036854775808",
    b"4294967296",
    b"true",
    b"\"\"",
    b"\"x\"",
    b"[]",
    b"{}",
    b"=",
    b"\n",
    b"'''",
    b"1979-05-27T07:32:00Z",
    b"0x7fffffff",
    b"1_000",
];

/// [`TOML_TOKENS`] followed by `extra` (a config's own section headers and values).
pub fn toml_dictionary<'a>(extra: &[&'a [u8]]) -> Vec<&'a [u8]> {
    TOML_TOKENS.iter().copied().chain(extra.iter().copied()).collect()
}

/// Executions per campaign: `CROPROW_FUZZ_EXECS` or the test's default.
pub fn execs_or(default: usize) -> usize {
    std::env::var("CROPROW_FUZZ_EXECS").ok().and_then(|v| v.trim().parse().ok()).unwrap_or(default)
}

/// The base seed: `CROPROW_FUZZ_SEED` or 0x5eed.
pub fn base_seed() -> u64 {
    std::env::var("CROPROW_FUZZ_SEED").ok().and_then(|v| v.trim().parse().ok()).unwrap_or(0x5eed)
}

/// A per-test rng for structured generators, derived from the base seed and a name.
pub fn rng_for(name: &str) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix(base_seed() ^ fnv(name.as_bytes())))
}

/// A proptest runner for structured inputs: `CROPROW_FUZZ_EXECS` cases (or `default_cases`), seeded
/// from the base seed and `name`, no failure files (the failing case is printed).
pub fn proptest_runner(name: &str, default_cases: usize) -> proptest::test_runner::TestRunner {
    use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
    let cases = u32::try_from(execs_or(default_cases)).unwrap_or(u32::MAX);
    let seed = mix(base_seed() ^ fnv(name.as_bytes()));
    let config = Config { cases, failure_persistence: None, ..Config::default() };
    TestRunner::new_with_rng(config, TestRng::from_seed(RngAlgorithm::ChaCha, &seed.to_le_bytes().repeat(4)))
}

fn fnv(bytes: &[u8]) -> u64 {
    bytes.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3))
}

/// splitmix64: spreads neighbouring seeds apart.
fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

thread_local! {
    /// Set while a fuzz target runs: its panics are caught and reported, not printed.
    static QUIET: std::cell::Cell<bool> = const { std::cell::Cell::new(false) };
    /// Where the last quiet panic happened.
    static LOCATION: std::cell::RefCell<String> = const { std::cell::RefCell::new(String::new()) };
}

/// Installs (once) a panic hook that stays silent inside fuzz targets and defers to the previous
/// hook everywhere else, so other tests' panics still print.
fn install_quiet_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let previous = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            if QUIET.with(|q| q.get()) {
                let at = info.location().map(|l| format!("{}:{}", l.file(), l.line())).unwrap_or_default();
                LOCATION.with(|l| *l.borrow_mut() = at);
            } else {
                previous(info);
            }
        }));
    });
}

/// Runs `f` under `catch_unwind` with the quiet hook; a panic becomes `Err(message)`.
pub fn catch<T>(f: impl FnOnce() -> T) -> Result<T, String> {
    install_quiet_hook();
    QUIET.with(|q| q.set(true));
    let result = panic::catch_unwind(AssertUnwindSafe(f));
    QUIET.with(|q| q.set(false));
    result.map_err(|payload| {
        let msg = payload
            .downcast_ref::<&str>()
            .map(|s| (*s).to_owned())
            .or_else(|| payload.downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "non-string panic payload".to_owned());
        format!("panic at {}: {msg}", LOCATION.with(|l| l.borrow().clone()))
    })
}

/// Boundary bytes.
const BYTES: [u8; 12] = [0, 1, 2, 0x0f, 0x10, 0x7f, 0x80, 0xfe, 0xff, b'0', b' ', b'\n'];
/// Boundary integers, written as u16/u32/u64 in either byte order.
const INTS: [u64; 16] =
    [0, 1, 2, 3, 4, 7, 8, 16, 255, 256, 0x7fff, 0xffff, 0x7fff_ffff, 0x8000_0000, 0xffff_ffff, u64::MAX];
/// Boundary floats.
const FLOATS: [f64; 12] = [
    f64::NAN,
    f64::INFINITY,
    f64::NEG_INFINITY,
    f64::MAX,
    f64::MIN,
    f64::MIN_POSITIVE,
    -0.0,
    0.0,
    1e300,
    -1e300,
    1e-310,
    3.4e38,
];

/// A fuzzing campaign over one target.
pub struct Campaign {
    name: String,
    seeds: Vec<Vec<u8>>,
    dictionary: Vec<Vec<u8>>,
    execs: usize,
    max_len: usize,
}

impl Campaign {
    /// A campaign named `name` (printed, and part of every execution's seed) over `seeds`.
    ///
    /// # Panics
    /// With no seed: a campaign needs at least one valid input.
    pub fn new(name: &str, seeds: Vec<Vec<u8>>, default_execs: usize) -> Self {
        assert!(!seeds.is_empty(), "campaign {name} has no seed input");
        let largest = seeds.iter().map(Vec::len).max().unwrap_or(0);
        Self {
            name: name.to_owned(),
            seeds,
            dictionary: Vec::new(),
            execs: execs_or(default_execs),
            max_len: (largest * 2).max(256),
        }
    }

    /// Runs `1 / divisor` of the executions (at least one): for seeds that cost more per execution.
    pub fn scaled_down(mut self, divisor: usize) -> Self {
        self.execs = (self.execs / divisor.max(1)).max(1);
        self
    }

    /// Tokens inserted whole (keywords, numbers, separators of text formats).
    pub fn dictionary(mut self, tokens: &[&[u8]]) -> Self {
        self.dictionary = tokens.iter().map(|t| t.to_vec()).collect();
        self
    }

    /// Runs the campaign, prints its counts, and fails the test on any panic or violation.
    pub fn run(self, mut target: impl FnMut(&[u8]) -> Outcome) -> Report {
        let report = self.run_quietly(&mut target);
        report.conclude()
    }

    fn run_quietly(&self, target: &mut impl FnMut(&[u8]) -> Outcome) -> Report {
        let name_hash = fnv(self.name.as_bytes());
        let mut pool: Vec<Vec<u8>> = self.seeds.clone();
        let pool_cap = self.seeds.len() + 64;
        let mut report = Report::new(&self.name);
        let mut slowest_input = Vec::new();
        let mut input = Vec::new();
        for exec in 0..self.execs {
            let mut rng = ChaCha8Rng::seed_from_u64(mix(base_seed() ^ name_hash).wrapping_add(exec as u64));
            input.clear();
            // One execution in 16 runs a pool input as it is: valid inputs must always pass.
            let from = rng.random_range(0..pool.len());
            input.extend_from_slice(&pool[from]);
            let mutated = !exec.is_multiple_of(16);
            if mutated {
                let stacked = 1 + (rng.random_range(0u32..64)).trailing_zeros().min(7) as usize;
                for _ in 0..stacked {
                    mutate(&mut rng, &mut input, &pool, &self.dictionary);
                }
                input.truncate(self.max_len);
            }
            let started = Instant::now();
            let outcome = catch(|| target(&input)).and_then(|o| o);
            let elapsed = started.elapsed();
            if elapsed > report.slowest {
                slowest_input.clone_from(&input);
            }
            // An accepted mutant joins the pool: later executions build on what got past the checks.
            if mutated && outcome == Ok(Verdict::Accepted) {
                if pool.len() < pool_cap {
                    pool.push(input.clone());
                } else {
                    let at = rng.random_range(self.seeds.len()..pool.len());
                    pool[at].clone_from(&input);
                }
            }
            let outcome = match outcome {
                Err(what) if !mutated => Err(format!("a valid input failed unchanged: {what}")),
                other => other,
            };
            report.record(exec, outcome, &input, elapsed);
        }
        let dir = std::env::temp_dir().join("croprow-fuzz-failures");
        if std::fs::create_dir_all(&dir).is_ok() {
            let _ = std::fs::write(dir.join(format!("{}-slowest.bin", self.name)), &slowest_input);
        }
        report
    }
}

/// The first `max` bytes as hex.
pub fn hex(bytes: &[u8], max: usize) -> String {
    let mut s: String = bytes.iter().take(max).map(|b| format!("{b:02x}")).collect();
    if bytes.len() > max {
        s.push_str("...");
    }
    s
}

/// Applies one random mutation to `data`.
pub fn mutate(rng: &mut ChaCha8Rng, data: &mut Vec<u8>, pool: &[Vec<u8>], dictionary: &[Vec<u8>]) {
    let len = data.len();
    let kinds = if dictionary.is_empty() { 13 } else { 15 };
    match rng.random_range(0..kinds) {
        // Bit flip.
        0 if len > 0 => {
            let at = rng.random_range(0..len);
            data[at] ^= 1 << rng.random_range(0..8);
        }
        // Byte set to a boundary value.
        1 if len > 0 => {
            let at = rng.random_range(0..len);
            data[at] = BYTES[rng.random_range(0..BYTES.len())];
        }
        // Byte set at random.
        2 if len > 0 => {
            let at = rng.random_range(0..len);
            data[at] = rng.random();
        }
        // Small arithmetic on a byte.
        3 if len > 0 => {
            let at = rng.random_range(0..len);
            data[at] = data[at].wrapping_add(rng.random_range(1u8..=16).wrapping_mul(if rng.random() {
                1
            } else {
                0xff
            }));
        }
        // A u16/u32/u64 set to a boundary value, either byte order.
        4 => {
            let v = INTS[rng.random_range(0..INTS.len())];
            let width = [2usize, 4, 8][rng.random_range(0..3)];
            // The low `width` bytes of the value, in the chosen order.
            let bytes = if rng.random() {
                v.to_le_bytes()[..width].to_vec()
            } else {
                v.to_be_bytes()[8 - width..].to_vec()
            };
            overwrite(rng, data, &bytes);
        }
        // A float set to NaN, inf, huge or subnormal (f32 or f64, either byte order).
        5 => {
            let v = FLOATS[rng.random_range(0..FLOATS.len())];
            let bytes = match (rng.random::<bool>(), rng.random::<bool>()) {
                (true, true) => v.to_le_bytes().to_vec(),
                (true, false) => v.to_be_bytes().to_vec(),
                (false, true) => (v as f32).to_le_bytes().to_vec(),
                (false, false) => (v as f32).to_be_bytes().to_vec(),
            };
            overwrite(rng, data, &bytes);
        }
        // A length field (a u32 or u64 little endian that fits the input) made to lie.
        6 => corrupt_length(rng, data),
        // Truncation.
        7 if len > 0 => data.truncate(rng.random_range(0..len)),
        // Extension with random or repeated bytes.
        8 => {
            let n = rng.random_range(1..64);
            if rng.random() {
                data.extend((0..n).map(|_| rng.random::<u8>()));
            } else {
                let b = BYTES[rng.random_range(0..BYTES.len())];
                data.extend(std::iter::repeat_n(b, n));
            }
        }
        // Chunk deletion.
        9 if len > 1 => {
            let (a, b) = range(rng, len);
            data.drain(a..b);
        }
        // Chunk duplication (inserted elsewhere).
        10 if len > 1 => {
            let (a, b) = range(rng, len);
            let chunk = data[a..b].to_vec();
            let at = rng.random_range(0..=len);
            data.splice(at..at, chunk);
        }
        // Splice: our head with another input's tail.
        11 if !pool.is_empty() => {
            let other = &pool[rng.random_range(0..pool.len())];
            let cut = rng.random_range(0..=len);
            let from = rng.random_range(0..=other.len());
            data.truncate(cut);
            data.extend_from_slice(&other[from..]);
        }
        // Two bytes swapped (reorders records and fields).
        12 if len > 1 => {
            let (a, b) = (rng.random_range(0..len), rng.random_range(0..len));
            data.swap(a, b);
        }
        // A dictionary token inserted.
        13 => {
            let token = &dictionary[rng.random_range(0..dictionary.len())];
            let at = rng.random_range(0..=len);
            data.splice(at..at, token.iter().copied());
        }
        // A whitespace-separated token replaced by a dictionary token.
        14 if len > 0 => {
            let token = &dictionary[rng.random_range(0..dictionary.len())];
            let mut a = rng.random_range(0..len);
            while a < len && data[a].is_ascii_whitespace() {
                a += 1;
            }
            let mut b = a;
            while b < len && !data[b].is_ascii_whitespace() {
                b += 1;
            }
            data.splice(a..b, token.iter().copied());
        }
        // Mutations that need more bytes than there are: grow instead.
        _ => data.push(rng.random()),
    }
}

fn overwrite(rng: &mut ChaCha8Rng, data: &mut [u8], bytes: &[u8]) {
    if data.len() >= bytes.len() {
        let at = rng.random_range(0..=data.len() - bytes.len());
        data[at..at + bytes.len()].copy_from_slice(bytes);
    }
}

fn range(rng: &mut ChaCha8Rng, len: usize) -> (usize, usize) {
    let a = rng.random_range(0..len);
    let longest = if rng.random() { 16 } else { 1024 };
    let n = rng.random_range(1..=(len - a).min(longest));
    (a, a + n)
}

fn corrupt_length(rng: &mut ChaCha8Rng, data: &mut [u8]) {
    let len = data.len();
    if len < 8 {
        return;
    }
    for _ in 0..32 {
        let at = rng.random_range(0..len - 7);
        let wide = rng.random::<bool>();
        let v = if wide {
            u64::from_le_bytes(data[at..at + 8].try_into().unwrap_or([0; 8]))
        } else {
            u64::from(u32::from_le_bytes(data[at..at + 4].try_into().unwrap_or([0; 4])))
        };
        if v == 0 || v > len as u64 {
            continue;
        }
        let new = match rng.random_range(0..5) {
            0 => v.wrapping_add(rng.random_range(1..=16)),
            1 => v.saturating_sub(rng.random_range(1..=16)),
            2 => v.wrapping_mul(2),
            3 => 0,
            _ => {
                if wide {
                    u64::MAX
                } else {
                    u64::from(u32::MAX)
                }
            }
        };
        if wide {
            data[at..at + 8].copy_from_slice(&new.to_le_bytes());
        } else {
            data[at..at + 4].copy_from_slice(&(new as u32).to_le_bytes());
        }
        return;
    }
}
