//! Fuzzing of the point-cloud map readers ([`croprow_io::maps::read`]): PCD ascii and binary, PLY
//! ascii, binary little and big endian (with list properties and other elements), LAS, and text.
//! Mutated files must read or fail with a `maps::Error` naming the file, never panic, and a file that
//! reads must give at least one point with every coordinate finite (NaN points are skipped and
//! counted, as documented).
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test --release -p croprow-io --test fuzz_maps -- --nocapture`

mod fuzzer;

use std::path::{Path, PathBuf};

use croprow_io::maps::{self, PlyEncoding};
use fuzzer::{Campaign, Outcome, Verdict};

/// Executions per format by default (the long run's figures are in docs/fuzzing.md).
const EXECS: usize = 5_000;

/// Tokens of the text headers and of numbers that break parsers.
const DICTIONARY: [&[u8]; 36] = [
    b"nan",
    b"-nan",
    b"inf",
    b"-inf",
    b"1e309",
    b"-0",
    b"0",
    b"-1",
    b"4294967295",
    b"4294967296",
    b"18446744073709551615",
    b"18446744073709551616",
    b"99999999999999999999999",
    b"\n",
    b"\r\n",
    b" ",
    b"#",
    b"end_header\n",
    b"element vertex ",
    b"element face ",
    b"property float x\n",
    b"property double z\n",
    b"property list uchar int vertex_indices\n",
    b"property list uint float extra\n",
    b"format binary_little_endian 1.0\n",
    b"format binary_big_endian 1.0\n",
    b"format ascii 1.0\n",
    b"DATA ascii\n",
    b"DATA binary\n",
    b"DATA binary_compressed\n",
    b"FIELDS x y z\n",
    b"SIZE 4 4 4\n",
    b"TYPE F F F\n",
    b"COUNT 1 1 1\n",
    b"WIDTH ",
    b"POINTS ",
];

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("croprow-fuzz-maps-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    dir.join(name)
}

/// A small cloud with a UTM-like offset, a NaN point and extreme-but-finite values.
fn points() -> Vec<[f64; 3]> {
    let mut p: Vec<[f64; 3]> = (0..12)
        .map(|i| [500_000.0 + 0.25 * i as f64, 4_000_000.0 - 0.5 * i as f64, 0.1 * (i % 3) as f64])
        .collect();
    p.push([f64::NAN, 1.0, 2.0]);
    p.push([-1e6, 1e-300, 3.5]);
    p
}

/// Writes the seed with `write` and returns its bytes.
fn written(name: &str, write: impl FnOnce(&Path) -> Result<(), maps::Error>) -> Vec<u8> {
    let path = scratch(name);
    write(&path).expect("seed written");
    std::fs::read(&path).expect("seed read")
}

/// Reads `bytes` as a file named `name` and checks the result.
fn read_as(path: &Path) -> impl FnMut(&[u8]) -> Outcome + '_ {
    move |bytes| {
        std::fs::write(path, bytes).map_err(|e| format!("scratch file: {e}"))?;
        match maps::read(path) {
            Ok(cloud) => {
                if cloud.points.is_empty() {
                    return Err("a cloud was read without a single point".into());
                }
                if let Some(p) = cloud.points.iter().find(|p| !p.iter().all(|v| v.is_finite())) {
                    return Err(format!("a non-finite point {p:?} was returned"));
                }
                Ok(Verdict::Accepted)
            }
            Err(e) => {
                let text = e.to_string();
                if !text.contains(&*path.to_string_lossy()) {
                    return Err(format!("the error does not name the file: {text}"));
                }
                Ok(Verdict::Rejected)
            }
        }
    }
}

fn committed(name: &str) -> Vec<u8> {
    std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/maps").join(name))
        .expect("committed map")
}

#[test]
fn fuzz_maps_pcd() {
    let p = points();
    let organised = b"# .PCD v0.7\nVERSION 0.7\nFIELDS x y z rgb\nSIZE 4 4 4 4\nTYPE F F F U\nCOUNT 1 1 1 1\n\
WIDTH 2\nHEIGHT 2\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 4\nDATA ascii\n1 2 3 7\nnan nan nan 0\n4 5 6 9\n-1 -2 -3 1\n"
        .to_vec();
    let seeds = vec![
        written("seed.pcd", |path| maps::write_cloud(path, &p)),
        written("seed_ascii.pcd", |path| maps::write_pcd_ascii(path, &p)),
        organised,
    ];
    let path = scratch("fuzz.pcd");
    Campaign::new("maps_pcd", seeds, EXECS).dictionary(&DICTIONARY).run(read_as(&path));
}

#[test]
fn fuzz_maps_ply() {
    let p = points();
    let with_lists =
        b"ply\nformat ascii 1.0\ncomment lists\nelement face 1\nproperty list uchar int vertex_indices\n\
element vertex 3\nproperty float y\nproperty list uchar float normals\nproperty float x\nproperty uchar red\n\
property float z\nend_header\n3 0 1 2\n1 2 1 0.5 2 5 3\n4 0 5 255 6\n7 1 0.1 8 0 9\n"
            .to_vec();
    let mut binary_lists = b"ply\nformat binary_little_endian 1.0\nelement vertex 2\nproperty float x\n\
property list uchar short extra\nproperty float y\nproperty float z\nelement face 0\nend_header\n"
        .to_vec();
    for v in [[1.0f32, 2.0, 3.0], [4.0, 5.0, 6.0]] {
        binary_lists.extend(v[0].to_le_bytes());
        binary_lists.extend([2u8, 1, 0, 2, 0]);
        binary_lists.extend(v[1].to_le_bytes());
        binary_lists.extend(v[2].to_le_bytes());
    }
    let seeds = vec![
        written("seed.ply", |path| maps::write_cloud(path, &p)),
        written("seed_be.ply", |path| maps::write_ply(path, &p, PlyEncoding::BinaryBigEndian)),
        written("seed_ascii.ply", |path| maps::write_ply(path, &p, PlyEncoding::Ascii)),
        with_lists,
        binary_lists,
    ];
    let path = scratch("fuzz.ply");
    Campaign::new("maps_ply", seeds, EXECS).dictionary(&DICTIONARY).run(read_as(&path));
}

#[test]
fn fuzz_maps_las() {
    let p: Vec<[f64; 3]> = points().into_iter().filter(|v| v.iter().all(|c| c.is_finite())).collect();
    let seeds = vec![written("seed.las", |path| maps::write_cloud(path, &p[..12])), committed("field.las")];
    let path = scratch("fuzz.las");
    Campaign::new("maps_las", seeds, EXECS).run(read_as(&path));
}

#[test]
fn fuzz_maps_text() {
    let p = points();
    let seeds = vec![
        written("seed.txt", |path| maps::write_cloud(path, &p)),
        b"# x y z intensity\n1 2 3 4\n\n  5\t6 7 # comment\n8 9 10 11 12\r\n".to_vec(),
    ];
    let path = scratch("fuzz.xyz");
    Campaign::new("maps_text", seeds, EXECS).dictionary(&DICTIONARY).run(read_as(&path));
}
