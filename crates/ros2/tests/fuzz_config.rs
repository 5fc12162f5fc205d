//! Fuzzing of the node's configuration: TOML files ([`NodeConfig::from_toml`]) and dotted overrides
//! ([`NodeConfig::set`], what `--set key=value` and ROS 2 parameter updates call). Mutated files and
//! arbitrary keys and texts must load or fail with a `ConfigError`, never panic; a refused override
//! leaves the config unchanged; anything accepted validates, holds only finite numbers, survives a
//! TOML round trip and builds a [`NodeCore`].
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test --release -p croprow-ros2 --test fuzz_config -- --nocapture`

#[path = "../../io/tests/fuzzer/mod.rs"]
mod fuzzer;

use croprow_ros2::{NodeConfig, NodeCore};
use fuzzer::{Campaign, Outcome, Verdict, toml_dictionary};
use rand::RngExt;

/// Executions per campaign by default (the long run's figures are in docs/fuzzing.md).
const EXECS: usize = 3_000;

/// Node config sections and values, added to the shared TOML tokens.
const SECTIONS: [&[u8]; 6] =
    [b"\"wheel_imu\"", b"[node]\n", b"[mpc]\nhorizon_steps = ", b"[mount]\n", b"[detector]\n", b"[[mpc]]\n"];

/// The first non-finite float leaf, by dotted name.
fn non_finite_leaf(cfg: &NodeConfig) -> Option<String> {
    cfg.leaves().into_iter().find_map(|(name, v)| match v {
        toml::Value::Float(f) if !f.is_finite() => Some(format!("{name} = {f}")),
        _ => None,
    })
}

/// What must hold for every accepted config.
fn consistent(cfg: &NodeConfig) -> Outcome {
    cfg.validate().map_err(|e| format!("an accepted config does not validate: {e}"))?;
    if let Some(leaf) = non_finite_leaf(cfg) {
        return Err(format!("a non-finite value was accepted: {leaf}"));
    }
    let text = toml::to_string(cfg).map_err(|e| format!("an accepted config does not serialize: {e}"))?;
    let back = NodeConfig::from_toml(&text).map_err(|e| format!("a saved config does not load: {e}"))?;
    if &back != cfg {
        return Err("a config changed through a TOML round trip".into());
    }
    NodeCore::new(cfg.clone()).map_err(|e| format!("an accepted config does not build a node: {e}"))?;
    Ok(Verdict::Accepted)
}

#[test]
fn fuzz_node_config_toml() {
    let default = toml::to_string(&NodeConfig::default()).expect("serializes");
    let sample = "[node]\nodometry = \"wheel_imu\"\nstale_after_s = 0.3\n[mpc]\nhorizon_steps = 25\n\
[mount]\nz_m = 1.5\npitch_rad = 0.5\n";
    let seeds = vec![default.into_bytes(), sample.as_bytes().to_vec(), b"".to_vec()];
    Campaign::new("node_config_toml", seeds, EXECS).dictionary(&toml_dictionary(&SECTIONS)).run(|bytes| {
        let Ok(text) = std::str::from_utf8(bytes) else { return Ok(Verdict::Rejected) };
        match NodeConfig::from_toml(text) {
            Ok(cfg) => consistent(&cfg),
            Err(e) => {
                let _ = e.to_string();
                Ok(Verdict::Rejected)
            }
        }
    });
}

#[test]
fn fuzz_node_config_set() {
    const TEXTS: [&str; 22] = [
        "nan",
        "inf",
        "-inf",
        "1e309",
        "-0",
        "0",
        "-1",
        "0.5",
        "3",
        "30",
        "1000000",
        "9223372036854775808",
        "true",
        "false",
        "",
        " ",
        "wheel_imu",
        "filtered",
        "/points",
        "1.5e-3",
        "0x10",
        "1_000",
    ];
    let keys: Vec<String> = NodeConfig::default().leaves().into_iter().map(|(k, _)| k).collect();
    fuzzer::run_generated("node_config_set", EXECS, |rng, input| {
        let mut cfg = NodeConfig::default();
        for _ in 0..rng.random_range(1..=4) {
            let mut key = keys[rng.random_range(0..keys.len())].clone();
            match rng.random_range(0..10) {
                0 => key.push_str(".x"),
                1 => key = key.split('.').next().unwrap_or("").to_owned(),
                2 => key = format!(".{key}"),
                3 => key.clear(),
                _ => {}
            }
            let text = if rng.random_range(0..4) == 0 {
                format!("{}", rng.random::<f64>() * 10f64.powi(rng.random_range(-5..7)))
            } else {
                TEXTS[rng.random_range(0..TEXTS.len())].to_owned()
            };
            input.extend_from_slice(format!("--set {key}={text}\n").as_bytes());
            let before = cfg.clone();
            match cfg.set(&key, &text) {
                Err(e) => {
                    let _ = e.to_string();
                    if cfg != before {
                        return Err(format!("a refused `{key}={text}` changed the config"));
                    }
                }
                Ok(()) => {
                    let leaf =
                        cfg.leaf(&key).map_err(|e| format!("`{key}` was set but cannot be read: {e}"))?;
                    if let (toml::Value::Float(f), Ok(want)) = (&leaf, text.trim().parse::<f64>())
                        && f.to_bits() != want.to_bits()
                    {
                        return Err(format!("`{key}={text}` stored {f}"));
                    }
                }
            }
        }
        if cfg == NodeConfig::default() { Ok(Verdict::Rejected) } else { consistent(&cfg) }
    });
}
