//! `croprow bench --json` prints one JSON object whose figures are positive finite numbers (their
//! speed is not asserted: that is the benchmark's job, not a test's).

use std::process::Command;

#[test]
fn bench_json_has_every_key_as_a_positive_number() {
    let out = Command::new(env!("CARGO_BIN_EXE_croprow")).args(["bench", "--json"]).output().expect("runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).expect("one JSON object");
    let keys = ["detect_us_median", "detect_us_mean", "detect_paper_us_median", "detect_paper_us_mean"];
    for key in keys.into_iter().chain(["sim_realtime_factor", "mpc_solve_us_median"]) {
        let x = v[key].as_f64().unwrap_or_else(|| panic!("`{key}` missing or not a number: {v}"));
        assert!(x.is_finite() && x > 0.0, "{key} = {x}");
    }
    let factor = |key: &str| v[key].as_f64().unwrap_or_else(|| panic!("`{key}` missing: {v}"));
    let (min, median, max) =
        (factor("sim_realtime_factor_min"), factor("sim_realtime_factor"), factor("sim_realtime_factor_max"));
    assert!(0.0 < min && min <= median && median <= max && max.is_finite(), "{min} {median} {max}");
    for key in ["detect", "detect_paper", "sim_scans", "sim_loops", "mpc"] {
        assert!(v["runs"][key].as_u64().is_some_and(|n| n > 0), "runs.{key}: {v}");
    }
    assert!(v["machine"]["cores"].as_u64().is_some_and(|n| n > 0), "{v}");
    assert!(v["machine"]["cpu"].as_str().is_some_and(|s| !s.is_empty()), "{v}");
}
