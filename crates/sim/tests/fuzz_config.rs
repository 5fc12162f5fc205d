//! Fuzzing of scenario files ([`Scenario::from_toml_str`]) and of dotted overrides (what
//! `croprow simulate --set key=value` does: the scenario as a TOML tree, one leaf replaced, the tree
//! deserialized and validated). Mutated TOML must load or fail with a `ScenarioError` naming the
//! problem, never panic; a scenario that loads must hold only finite numbers, survive a TOML round
//! trip unchanged, and build its world (or refuse with an error).
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test --release -p croprow-sim --test fuzz_config -- --nocapture`

#[path = "../../io/tests/fuzzer/mod.rs"]
mod fuzzer;

use croprow_sim::{Scenario, World};
use fuzzer::{Campaign, Outcome, Verdict, toml_dictionary};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

/// Executions per campaign by default (the long run's figures are in docs/fuzzing.md).
const EXECS: usize = 3_000;

/// Builds the world of one accepted scenario in this many (field generation costs milliseconds).
const WORLD_EVERY: usize = 64;

/// Largest field (plants) whose world is built.
const MAX_WORLD_PLANTS: f64 = 5_000.0;

/// Scenario sections, added to the shared TOML tokens.
const SECTIONS: [&[u8]; 5] =
    [b"[field]\n", b"[lidar.mount]\n", b"[start]\nlane = ", b"[robot]\n", b"[[field]]\n"];

fn seeds() -> Vec<Vec<u8>> {
    Scenario::names()
        .iter()
        .filter_map(|n| Scenario::builtin_toml(n))
        .map(|t| t.as_bytes().to_vec())
        .collect()
}

/// The first non-finite float leaf of a TOML tree, by dotted name.
fn non_finite_leaf(value: &toml::Value, name: &str) -> Option<String> {
    match value {
        toml::Value::Float(f) if !f.is_finite() => Some(format!("{name} = {f}")),
        toml::Value::Table(t) => t.iter().find_map(|(k, v)| non_finite_leaf(v, &format!("{name}.{k}"))),
        toml::Value::Array(a) => {
            a.iter().enumerate().find_map(|(i, v)| non_finite_leaf(v, &format!("{name}[{i}]")))
        }
        _ => None,
    }
}

/// What must hold for every scenario that loads.
fn consistent(s: &Scenario, build_world: bool) -> Outcome {
    let tree = toml::Value::try_from(s).map_err(|e| format!("a loaded scenario does not serialize: {e}"))?;
    if let Some(leaf) = non_finite_leaf(&tree, "") {
        return Err(format!("a non-finite value was accepted: {leaf}"));
    }
    let text = toml::to_string(s).map_err(|e| format!("a loaded scenario does not serialize: {e}"))?;
    let back = Scenario::from_toml_str(&text).map_err(|e| format!("a saved scenario does not load: {e}"))?;
    if &back != s {
        return Err("a scenario changed through a TOML round trip".into());
    }
    // Field generation grows with the plant count: worlds are built for the smaller fields only.
    let plants = f64::from(s.field.rows) * s.field.length_m / s.field.plant_spacing_m;
    if build_world
        && plants <= MAX_WORLD_PLANTS
        && let Err(e) = World::new(s)
    {
        let _ = e.to_string();
    }
    Ok(Verdict::Accepted)
}

#[test]
fn fuzz_scenario_toml() {
    let mut accepted = 0usize;
    Campaign::new("scenario_toml", seeds(), EXECS).dictionary(&toml_dictionary(&SECTIONS)).run(|bytes| {
        let Ok(text) = std::str::from_utf8(bytes) else { return Ok(Verdict::Rejected) };
        match Scenario::from_toml_str(text) {
            Ok(s) => {
                accepted += 1;
                consistent(&s, accepted.is_multiple_of(WORLD_EVERY))
            }
            Err(e) => {
                let _ = e.to_string();
                Ok(Verdict::Rejected)
            }
        }
    });
}

/// Dotted names of every leaf of a TOML tree.
fn leaves(value: &toml::Value, prefix: &str, out: &mut Vec<String>) {
    if let toml::Value::Table(t) = value {
        for (k, v) in t {
            let name = if prefix.is_empty() { k.clone() } else { format!("{prefix}.{k}") };
            match v {
                toml::Value::Table(_) => leaves(v, &name, out),
                _ => out.push(name),
            }
        }
    }
}

/// A boundary value of any TOML type.
fn boundary(rng: &mut ChaCha8Rng) -> toml::Value {
    const FLOATS: [f64; 12] =
        [f64::NAN, f64::INFINITY, f64::NEG_INFINITY, 0.0, -0.0, -1.0, 1e308, -1e308, 1e-308, 0.5, 1e6, 3.0];
    const INTS: [i64; 8] = [0, -1, 1, 2, 1 << 32, i64::MAX, i64::MIN, 1000];
    match rng.random_range(0..10) {
        0..=4 => toml::Value::Float(FLOATS[rng.random_range(0..FLOATS.len())]),
        5..=6 => toml::Value::Integer(INTS[rng.random_range(0..INTS.len())]),
        7 => toml::Value::Boolean(rng.random()),
        8 => toml::Value::String(["", "x", "corn", "paper", "grown"][rng.random_range(0..5)].to_owned()),
        _ => toml::Value::Table(toml::Table::new()),
    }
}

/// Applies `key = value` to a tree as `--set` does: intermediate sections are created.
fn set(tree: &mut toml::Value, key: &str, value: toml::Value) -> bool {
    let parts: Vec<&str> = key.split('.').collect();
    let Some((last, parents)) = parts.split_last() else { return false };
    let mut node = tree;
    for part in parents {
        let Some(table) = node.as_table_mut() else { return false };
        node = table.entry(part.to_string()).or_insert_with(|| toml::Value::Table(toml::Table::new()));
    }
    let Some(table) = node.as_table_mut() else { return false };
    table.insert(last.to_string(), value);
    true
}

#[test]
fn fuzz_scenario_overrides() {
    let names = Scenario::names();
    let mut accepted = 0usize;
    fuzzer::run_generated("scenario_overrides", EXECS, |rng, input| {
        let base = Scenario::builtin(names[rng.random_range(0..names.len())]).map_err(|e| e.to_string())?;
        let mut tree = toml::Value::try_from(&base).map_err(|e| e.to_string())?;
        let mut keys = Vec::new();
        leaves(&tree, "", &mut keys);
        for _ in 0..rng.random_range(1..=3) {
            let mut key = keys[rng.random_range(0..keys.len())].clone();
            match rng.random_range(0..8) {
                0 => key.push_str(".deeper"),
                1 => key = format!("{}x", key),
                2 => key = key.split('.').next().unwrap_or("").to_owned(),
                _ => {}
            }
            let value = boundary(rng);
            input.extend_from_slice(format!("--set {key}={value}\n").as_bytes());
            set(&mut tree, &key, value);
        }
        // The override path (tree -> struct -> validate) and the file path (text -> from_toml_str)
        // must agree.
        let by_tree = tree.clone().try_into::<Scenario>().map_err(|e| e.to_string()).and_then(|s| {
            s.validate().map_err(|e| e.to_string())?;
            Ok(s)
        });
        let by_text = toml::to_string(&tree)
            .map_err(|e| e.to_string())
            .and_then(|t| Scenario::from_toml_str(&t).map_err(|e| e.to_string()));
        match (by_tree, by_text) {
            (Ok(a), Ok(b)) if a == b => {
                accepted += 1;
                consistent(&a, accepted.is_multiple_of(WORLD_EVERY))
            }
            (Ok(_), Ok(_)) => Err("override and file paths load different scenarios".into()),
            (Err(_), Err(_)) => Ok(Verdict::Rejected),
            (a, b) => Err(format!("override path {:?}, file path {:?}", a.map(|_| ()), b.map(|_| ()))),
        }
    });
}
