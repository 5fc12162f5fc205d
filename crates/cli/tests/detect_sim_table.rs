//! `croprow detect-sim`: prints both modes next to the paper's published numbers and writes the report.

use std::process::Command;

#[test]
fn detect_sim_prints_both_modes_and_the_published_numbers() {
    let json = std::env::temp_dir().join(format!("croprow-detect-sim-{}.json", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["detect-sim", "--scenario", "young-soybean", "--length-m", "4", "--seed", "3", "--json"])
        .arg(&json)
        .output()
        .expect("runs");
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let table = String::from_utf8_lossy(&out.stdout);
    for needle in ["default", "paper", "paper, published", "1.54 ± 1.07", "0.49 ± 0.33"] {
        assert!(table.contains(needle), "`{needle}` missing from:\n{table}");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).expect("report written")).expect("JSON");
    let _ = std::fs::remove_file(&json);
    assert_eq!(report["seed"], 3);
    assert_eq!(report["modes"].as_array().map(Vec::len), Some(2));
    assert!(report["modes"][0]["distance_cm"]["mean"].as_f64().is_some_and(f64::is_finite), "{report}");
}

#[test]
fn detect_sim_refuses_an_unknown_scenario_by_name() {
    let out = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["detect-sim", "--scenario", "moon-corn"])
        .output()
        .expect("runs");
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("moon-corn") && err.contains("grown-corn"), "{err}");
}

#[test]
fn detect_sim_refuses_an_absurd_length() {
    let out = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["detect-sim", "--scenario", "young-corn", "--length-m=-3"])
        .output()
        .expect("runs");
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("length_m"));
}

#[test]
fn errors_print_their_cause_chain_without_a_backtrace() {
    // A user's mistake is not a crash: one line with its causes, even where RUST_BACKTRACE is set.
    let out = Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["scenarios", "--show", "moon-corn"])
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("runs");
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.starts_with("error: unknown scenario `moon-corn`"), "{err}");
    assert!(!err.contains("backtrace") && err.lines().count() == 1, "{err}");
}
