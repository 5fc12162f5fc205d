//! `croprow evaluate --suite soak`: a small soak writes `soak.json` with every documented key, one
//! replay scenario per failing seed, and exits non-zero exactly when a run failed.

use std::process::Command;

#[test]
fn small_soak_writes_the_report_and_its_exit_code_tells_failures() {
    let out = std::env::temp_dir().join(format!("croprow-soak-cli-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    let run = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["evaluate", "--suite", "soak", "--runs", "4", "--seed", "0", "--out"])
        .arg(&out)
        .output()
        .expect("runs");
    let text = std::fs::read_to_string(out.join("soak.json")).expect("soak.json written");
    let v: serde_json::Value = serde_json::from_str(&text).expect("soak.json is JSON");
    assert_eq!(v["runs"].as_u64(), Some(4), "{v}");
    assert!(v["distance_m"].as_f64().is_some_and(|d| d > 4.0 * 10.0), "each run drives a lane: {v}");
    for key in ["crop_contacts", "unsafe_commands", "panics", "errors"] {
        assert!(v[key].as_u64().is_some(), "`{key}` missing: {v}");
    }
    let each = v["each"].as_array().expect("each is a list");
    assert_eq!(each.len(), 4, "one line per run: {v}");
    assert!(each.iter().all(|r| r["end"].as_str().is_some_and(|e| !e.is_empty())), "{v}");
    let failures = v["failures"].as_array().expect("failures is a list");
    for f in failures {
        let seed = f["seed"].as_u64().expect("seed");
        assert!(f["scenario"].as_str().is_some_and(|s| !s.is_empty()), "{f}");
        assert!(f["what"].as_str().is_some_and(|s| !s.is_empty()), "{f}");
        assert!(f["replay"].as_str().is_some_and(|s| s.contains("croprow simulate --scenario")), "{f}");
        assert!(out.join(format!("fail-{seed}.toml")).exists(), "no replay scenario for seed {seed}");
    }
    assert_eq!(
        run.status.success(),
        failures.is_empty(),
        "exit code must tell failures: {}",
        String::from_utf8_lossy(&run.stderr)
    );
    let _ = std::fs::remove_dir_all(&out);
}

#[test]
fn unknown_suite_and_zero_runs_are_refused() {
    let out = std::env::temp_dir().join(format!("croprow-soak-cli-bad-{}", std::process::id()));
    let bad = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["evaluate", "--suite", "moon", "--out"])
        .arg(&out)
        .output()
        .expect("runs");
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("unknown suite"));
    let zero = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["evaluate", "--suite", "soak", "--runs", "0", "--out"])
        .arg(&out)
        .output()
        .expect("runs");
    assert!(!zero.status.success());
    assert!(String::from_utf8_lossy(&zero.stderr).contains("--runs"));
    let _ = std::fs::remove_dir_all(&out);
}
