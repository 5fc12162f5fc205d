//! Map files: a small committed field per format (made by `regenerate_committed_maps`), round trips,
//! and bad files (empty, truncated, corrupt header, NaN rows) giving an error that names the file.

use std::path::{Path, PathBuf};

use croprow_io::maps::{self, Error, PlyEncoding};

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/maps").join(name)
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("croprow-maps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    dir.join(name)
}

/// A 6 m x 3 m field with a UTM-like offset: three rows 0.75 m apart along x (0.1-0.2 m tall) on a
/// ground lattice. Deterministic without a generator: 1 900 points.
fn field() -> Vec<[f64; 3]> {
    let origin = [500_123.25, 4_000_456.5, 210.0];
    let mut pts = Vec::new();
    for i in 0..48 {
        for j in 0..24 {
            pts.push([origin[0] + i as f64 * 0.125, origin[1] + j as f64 * 0.125, origin[2]]);
        }
    }
    for row in 0..3 {
        for i in 0..120 {
            let x = i as f64 * 0.05;
            let y = 0.75 + row as f64 * 0.75 + 0.01 * (x * 7.0).sin();
            for h in [0.1, 0.2] {
                pts.push([origin[0] + x, origin[1] + y, origin[2] + h]);
            }
        }
    }
    pts
}

const FILES: [&str; 6] =
    ["field.pcd", "field_ascii.pcd", "field.ply", "field_be.ply", "field_ascii.ply", "field.txt"];

#[test]
#[ignore = "rewrites the committed files; run by hand after changing field()"]
fn regenerate_committed_maps() {
    let pts = field();
    maps::write_cloud(&data("field.pcd"), &pts).unwrap();
    maps::write_pcd_ascii(&data("field_ascii.pcd"), &pts).unwrap();
    maps::write_cloud(&data("field.ply"), &pts).unwrap();
    maps::write_ply(&data("field_be.ply"), &pts, PlyEncoding::BinaryBigEndian).unwrap();
    maps::write_ply(&data("field_ascii.ply"), &pts, PlyEncoding::Ascii).unwrap();
    maps::write_cloud(&data("field.txt"), &pts).unwrap();
    maps::write_cloud(&data("field.las"), &pts).unwrap();
}

#[test]
fn committed_files_hold_the_field_exactly() {
    let want = field();
    for name in FILES {
        assert_eq!(maps::read_cloud(&data(name)).unwrap(), want, "{name}");
    }
}

#[test]
fn committed_las_holds_the_field_to_a_millimetre() {
    let got = maps::read_cloud(&data("field.las")).unwrap();
    let want = field();
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(&want) {
        assert!(g.iter().zip(w).all(|(a, b)| (a - b).abs() <= 0.0005 + 1e-9), "{g:?} vs {w:?}");
    }
}

#[test]
fn round_trip_every_format() {
    let pts = field();
    for name in ["rt.pcd", "rt.ply", "rt.txt", "rt.xyz"] {
        let path = scratch(name);
        maps::write_cloud(&path, &pts).unwrap();
        assert_eq!(maps::read_cloud(&path).unwrap(), pts, "{name}");
    }
}

#[test]
fn ply_with_extra_properties_in_any_order_and_other_elements() {
    let path = scratch("odd.ply");
    let mut bytes = b"ply\r\nformat binary_little_endian 1.0\r\ncomment x\r\nelement camera 1\r\nproperty list uchar int ids\r\n\
element vertex 2\r\nproperty uchar red\r\nproperty float z\r\nproperty double y\r\nproperty list uchar int idx\r\nproperty float x\r\n\
element face 0\r\nproperty list uchar int vertex_indices\r\nend_header\r\n"
        .to_vec();
    bytes.extend([2u8]);
    bytes.extend(7i32.to_le_bytes());
    bytes.extend(8i32.to_le_bytes());
    for (r, z, y, x) in [(1u8, 3.0f32, 2.0f64, 1.0f32), (2, 6.0, 5.0, 4.0)] {
        bytes.push(r);
        bytes.extend(z.to_le_bytes());
        bytes.extend(y.to_le_bytes());
        bytes.push(1);
        bytes.extend(9i32.to_le_bytes());
        bytes.extend(x.to_le_bytes());
    }
    std::fs::write(&path, bytes).unwrap();
    assert_eq!(maps::read_cloud(&path).unwrap(), vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
}

/// Reads `bytes` as `name` and returns the error text, which must name the file.
fn error_of(name: &str, bytes: &[u8]) -> String {
    let path = scratch(name);
    std::fs::write(&path, bytes).unwrap();
    let err = maps::read_cloud(&path).unwrap_err().to_string();
    assert!(err.contains(name), "error does not name the file: {err}");
    err
}

#[test]
fn empty_files_are_refused() {
    for name in ["empty.pcd", "empty.ply", "empty.las", "empty.txt"] {
        error_of(name, b"");
    }
    assert!(error_of("comments.txt", b"# nothing\n\n").contains("no points"));
}

#[test]
fn truncated_files_are_refused() {
    for name in ["field.pcd", "field.ply", "field_be.ply", "field_ascii.ply", "field.las"] {
        let bytes = std::fs::read(data(name)).unwrap();
        error_of(&format!("cut_{name}"), &bytes[..bytes.len() - 20]);
    }
}

#[test]
fn corrupt_headers_are_refused() {
    assert!(
        error_of("bad.ply", b"ply\nformat binary_middle_endian 1.0\nend_header\n").contains("unknown format")
    );
    assert!(
        error_of("novertex.ply", b"ply\nformat ascii 1.0\nelement face 0\nend_header\n").contains("vertex")
    );
    assert!(
        error_of(
            "noz.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nend_header\n1 2\n"
        )
        .contains("`z`")
    );
    error_of("garbage.pcd", b"this is not a pcd file\n");
    error_of("garbage.las", &[0u8; 400]);
    assert!(error_of("short.txt", b"1 2 3\n4 5\n").contains("line 2"));
    assert!(error_of("word.txt", b"1 2 three\n").contains("three"));
}

#[test]
fn ply_counts_that_lie_are_refused_without_allocating_for_them() {
    let mut bytes =
        b"ply\nformat binary_big_endian 1.0\nelement vertex 4000000000\nproperty float x\nproperty float y\n\
property float z\nend_header\n"
            .to_vec();
    bytes.extend([1.0f32, 2.0, 3.0].iter().flat_map(|v| v.to_be_bytes()));
    assert!(error_of("liar.ply", &bytes).contains("truncated in vertex 1"));
    // An element without properties takes no bytes, whatever its count.
    let mut ok = b"ply\nformat binary_little_endian 1.0\nelement marker 999999999999\nelement vertex 1\n\
property float x\nproperty float y\nproperty float z\nend_header\n"
        .to_vec();
    ok.extend([1.0f32, 2.0, 3.0].iter().flat_map(|v| v.to_le_bytes()));
    let path = scratch("marker.ply");
    std::fs::write(&path, ok).unwrap();
    assert_eq!(maps::read_cloud(&path).unwrap(), vec![[1.0, 2.0, 3.0]]);
}

#[test]
fn nan_rows_are_skipped_and_counted() {
    let path = scratch("nan.txt");
    std::fs::write(&path, b"1 2 3\nnan 2 3\n4 inf 6\n7 8 9\n").unwrap();
    let cloud = maps::read(&path).unwrap();
    assert_eq!(cloud.points, vec![[1.0, 2.0, 3.0], [7.0, 8.0, 9.0]]);
    assert_eq!(cloud.non_finite, 2);
    let path = scratch("nan.ply");
    maps::write_ply(&path, &[[0.0, 0.0, 0.0], [f64::NAN, 1.0, 2.0]], PlyEncoding::Ascii).unwrap();
    assert_eq!(maps::read(&path).unwrap(), maps::Cloud { points: vec![[0.0; 3]], non_finite: 1 });
}

/// PCL writes an organised cloud (one entry per beam, `HEIGHT` > 1) with NaN for missing returns.
#[test]
fn organised_pcd_with_missing_returns_is_read() {
    let text = "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\n\
TYPE F F F\nCOUNT 1 1 1\nWIDTH 3\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 6\nDATA ascii\n\
1 2 3\nnan nan nan\n4 5 6\nnan nan nan\nnan nan nan\n7 8 9\n";
    let path = scratch("organised.pcd");
    std::fs::write(&path, text).unwrap();
    let cloud = maps::read(&path).unwrap();
    assert_eq!(cloud.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]);
    assert_eq!(cloud.non_finite, 3);
}

#[test]
fn a_cloud_of_only_missing_returns_is_refused() {
    let err = error_of("allnan.txt", b"nan nan nan\nnan 1 2\n");
    assert!(err.contains("no finite point (2 with NaN"), "{err}");
}

#[test]
fn unknown_extension_and_missing_file() {
    assert!(matches!(maps::read_cloud(Path::new("field.obj")), Err(Error::UnknownFormat { .. })));
    let err = maps::read_cloud(Path::new("/nonexistent/field.ply")).unwrap_err().to_string();
    assert!(err.contains("/nonexistent/field.ply"), "{err}");
}
