//! `croprow rows` end to end: the built binary on the committed field maps.

use std::path::{Path, PathBuf};
use std::process::Command;

fn map(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../io/tests/data/maps").join(name)
}

fn out(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("croprow-rows-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

fn rows(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_croprow")).arg("rows").args(args).output().unwrap()
}

#[test]
fn committed_ply_gives_three_rows_in_geojson() {
    let geojson = out("field.geojson");
    let o = rows(&[map("field.ply").as_os_str(), "--out".as_ref(), geojson.as_os_str()]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&geojson).unwrap()).unwrap();
    assert_eq!(v["type"], "FeatureCollection");
    let features = v["features"].as_array().unwrap();
    assert_eq!(features.len(), 3);
    for (i, f) in features.iter().enumerate() {
        assert_eq!(f["geometry"]["type"], "LineString");
        assert_eq!(f["properties"]["index"], i);
        // The file's rows are 0.75 m apart (1 cm) along x at y = origin + 0.75 (i + 1), in the file's frame.
        assert!((f["properties"]["spacing_m"].as_f64().unwrap() - 0.75).abs() < 0.01);
        let coords = f["geometry"]["coordinates"].as_array().unwrap();
        assert!(coords.len() >= 8, "row {i} has {} vertices", coords.len());
        for c in coords {
            let (x, y) = (c[0].as_f64().unwrap(), c[1].as_f64().unwrap());
            assert!((500_123.0..500_130.0).contains(&x), "{x}");
            // Rows wiggle ±1 cm; centres within 2 cm.
            let want = 4_000_456.5 + 0.75 * (i as f64 + 1.0);
            assert!((y - want).abs() < 0.02, "row {i}: y {y} vs {want}");
        }
    }
}

#[test]
fn every_committed_format_gives_the_same_rows() {
    let mut counts = Vec::new();
    for name in ["field.pcd", "field_ascii.pcd", "field_be.ply", "field_ascii.ply", "field.las", "field.txt"]
    {
        let geojson = out(&format!("{name}.geojson"));
        let o = rows(&[map(name).as_os_str(), "--out".as_ref(), geojson.as_os_str()]);
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let v: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&geojson).unwrap()).unwrap();
        counts.push(v["features"].as_array().unwrap().len());
    }
    assert!(counts.iter().all(|c| *c == 3), "{counts:?}");
}

#[test]
fn a_bad_file_fails_cleanly_naming_it() {
    let bad = out("broken.ply");
    std::fs::write(&bad, b"ply\nformat ascii 1.0\nelement vertex 5\nproperty float x\n").unwrap();
    let never = out("never.geojson");
    let o = rows(&[bad.as_os_str(), "--out".as_ref(), never.as_os_str()]);
    assert!(!o.status.success());
    assert!(!never.exists(), "an empty output was left behind");
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("broken.ply") && !stderr.contains("panicked"), "{stderr}");
}

#[test]
fn a_bad_config_names_the_field() {
    let config = out("bad.toml");
    std::fs::write(&config, "[mapping]\ntile_m = 0.5\n").unwrap();
    let o = rows(&[
        map("field.ply").as_os_str(),
        "--out".as_ref(),
        out("x.geojson").as_os_str(),
        "--config".as_ref(),
        config.as_os_str(),
    ]);
    assert!(!o.status.success());
    assert!(String::from_utf8_lossy(&o.stderr).contains("mapping.tile_m"));
}
