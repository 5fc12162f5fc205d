//! `croprow detect` as a user runs it: the built binary on recordings written with `croprow-io`.

use std::io::Cursor;
use std::path::PathBuf;
use std::process::Command;

use croprow_core::{Mount, Point3, Pose2, Twist2};
use croprow_io::RecordingWriter;

fn temp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("croprow-cli-{}-{name}", std::process::id()))
}

/// Ten 10 Hz scans of a regular grid of points with odometry at 50 Hz, in small chunks.
fn recording() -> Vec<u8> {
    let mut rec = RecordingWriter::with_chunk_size(Cursor::new(Vec::new()), 16 * 1024).unwrap();
    let t0 = 100.0;
    rec.write_tf_static(t0, "velodyne", &Mount::default()).unwrap();
    for ms in (0..=1200u32).step_by(20) {
        let t = t0 + f64::from(ms) / 1000.0;
        rec.write_odometry(
            "/odometry/filtered",
            t,
            Pose2::new(0.5 * (t - t0), 0.0, 0.0),
            Twist2::new(0.5, 0.0),
        )
        .unwrap();
        if ms >= 100 && ms % 100 == 0 && ms <= 1000 {
            let points: Vec<Point3> = (0..3000)
                .map(|i| Point3::new(1.0 + (i % 50) as f32 * 0.05, -1.5 + (i / 50) as f32 * 0.05, -1.4))
                .collect();
            rec.write_cloud("/velodyne_points", t, "velodyne", &points, &[], &[]).unwrap();
        }
    }
    rec.finish().unwrap().into_inner()
}

fn run(input: &std::path::Path, out: &std::path::Path) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_croprow"))
        .args(["detect", input.to_str().unwrap(), "--out", out.to_str().unwrap()])
        .output()
        .unwrap()
}

#[test]
fn writes_one_exact_json_object_per_scan() {
    let (input, out) = (temp("ok.mcap"), temp("ok.jsonl"));
    std::fs::write(&input, recording()).unwrap();
    let o = run(&input, &out);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{stderr}");
    assert!(stderr.contains("10 scans") && stderr.contains("median"), "{stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    let lines: Vec<serde_json::Value> = text.lines().map(|l| serde_json::from_str(l).unwrap()).collect();
    assert_eq!(lines.len(), 10);
    for (k, v) in lines.iter().enumerate() {
        let keys: Vec<&String> = v.as_object().unwrap().keys().collect();
        assert_eq!(keys, ["latency_us", "left", "right", "stamp", "status"], "serde_json sorts keys");
        assert!((v["stamp"].as_f64().unwrap() - (100.1 + 0.1 * k as f64)).abs() < 1e-6);
        assert!(v["status"].is_string() && v["latency_us"].is_u64());
    }
    for v in &lines {
        for side in ["left", "right"] {
            let row = &v[side];
            assert!(
                row.is_null() || row.as_array().is_some_and(|a| a.len() == 4 && a.iter().all(|c| c.is_f64()))
            );
        }
    }
}

#[test]
fn truncated_recording_keeps_earlier_lines_and_fails() {
    let bytes = recording();
    let (input, out) = (temp("cut.mcap"), temp("cut.jsonl"));
    std::fs::write(&input, &bytes[..bytes.len() * 6 / 10]).unwrap();
    let o = run(&input, &out);
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success(), "a truncated file must fail: {stderr}");
    assert!(stderr.contains("truncated"), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let text = std::fs::read_to_string(&out).unwrap();
    let n = text.lines().count();
    assert!((2..10).contains(&n), "{n} lines written before the fault:\n{text}");
    assert!(
        text.lines().all(|l| serde_json::from_str::<serde_json::Value>(l).is_ok()),
        "every line complete"
    );
}

#[test]
fn empty_and_foreign_files_fail_with_a_message() {
    for (name, bytes, expect) in
        [("empty.mcap", &b""[..], "empty"), ("foreign.mcap", &b"ply\nformat ascii 1.0\n"[..], "not an MCAP")]
    {
        let (input, out) = (temp(name), temp("x.jsonl"));
        std::fs::write(&input, bytes).unwrap();
        let o = run(&input, &out);
        let stderr = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && stderr.contains(expect), "{name}: {stderr}");
    }
}

#[test]
fn config_file_sections_apply_and_bad_values_name_the_field() {
    let (input, out, config) = (temp("cfg.mcap"), temp("cfg.jsonl"), temp("cfg.toml"));
    std::fs::write(&input, recording()).unwrap();
    // A topic that is not in the file proves [replay] is read.
    std::fs::write(&config, "[detector]\nmode = \"paper\"\n[replay]\ncloud_topic = \"/points\"\n").unwrap();
    let detect = || {
        let args = [
            "detect",
            input.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--config",
            config.to_str().unwrap(),
        ];
        let o = Command::new(env!("CARGO_BIN_EXE_croprow")).args(args).output().unwrap();
        (o.status.success(), String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (ok, stderr) = detect();
    assert!(!ok && stderr.contains("`/points` is not in the recording"), "{stderr}");

    std::fs::write(&config, "[detector]\nrange_m = -3.0\n").unwrap();
    let (ok, stderr) = detect();
    assert!(!ok && stderr.contains("detector.range_m"), "{stderr}");
}
