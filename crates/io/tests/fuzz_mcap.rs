//! Fuzzing of whole MCAP recordings through [`Recording`] and [`Replay`]: mutated files (the committed
//! recordings of every point layout, plus re-writes of one with uncompressed, CRC-less chunks and
//! without chunks, so that mutations reach the records and CDR messages instead of stopping at a
//! zstd frame or a checksum) must open and replay, or end with one `RecordingError`. Never a panic,
//! never an endless replay, and every scan released must be consistent: finite stamp, a mount that
//! passes [`croprow_core::Mount::validate`], an odometry pose that is finite when present, nothing
//! after the error.
//!
//! `CROPROW_FUZZ_EXECS=100000 cargo test --release -p croprow-io --test fuzz_mcap -- --nocapture`

mod fuzzer;
mod support;

use std::io::Cursor;
use std::path::{Path, PathBuf};

use croprow_core::Mount;
use croprow_io::read::{Recording, ReplayConfig};
use fuzzer::{Campaign, Outcome, Verdict};

/// Executions per campaign by default (the long run's figures are in docs/fuzzing.md).
const EXECS: usize = 4_000;

fn committed(name: &str) -> Vec<u8> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// The messages of `bytes` written again with the given options.
fn rewrite(bytes: &[u8], options: mcap::WriteOptions) -> Vec<u8> {
    let mut writer = options.create(Cursor::new(Vec::new())).expect("writer");
    for message in mcap::MessageStream::new(bytes).expect("a valid recording") {
        writer.write(&message.expect("a valid message")).expect("written");
    }
    writer.finish().expect("finished");
    writer.into_inner().into_inner()
}

fn seeds() -> Vec<Vec<u8>> {
    let mut seeds: Vec<Vec<u8>> = support::layouts().iter().map(|(name, _)| committed(name)).collect();
    let plain =
        mcap::WriteOptions::new().compression(None).calculate_chunk_crcs(false).chunk_size(Some(4096));
    seeds.push(rewrite(&seeds[0], plain.clone()));
    seeds.push(rewrite(&seeds[4], plain.use_chunks(false)));
    seeds
}

/// Replays `path` to the end, checking every scan. `Accepted` when at least one scan came out.
fn replay(path: &Path, config: &ReplayConfig, file_len: usize) -> Outcome {
    let recording = match Recording::open(path) {
        Ok(r) => r,
        Err(e) => {
            let _ = e.to_string();
            return Ok(Verdict::Rejected);
        }
    };
    let _ = recording.topics();
    let mut replay = match recording.replay(config) {
        Ok(r) => r,
        Err(e) => {
            let _ = e.to_string();
            return Ok(Verdict::Rejected);
        }
    };
    let mut scans = 0usize;
    let mut failed = false;
    while let Some(item) = replay.next_scan() {
        if failed {
            return Err("the replay went on after its error".into());
        }
        match item {
            Ok(frame) => {
                scans += 1;
                if !frame.stamp_s.is_finite() {
                    return Err(format!("scan stamp {} is not finite", frame.stamp_s));
                }
                if let Err(e) = frame.mount.validate() {
                    return Err(format!("scan {scans} has an implausible mount {:?}: {e}", frame.mount));
                }
                if let Ok(p) = frame.odom_pose
                    && !p.is_finite()
                {
                    return Err(format!("scan {scans} has a non-finite odometry pose {p:?}"));
                }
            }
            Err(e) => {
                let _ = e.to_string();
                failed = true;
            }
        }
        // Each scan is one message record of at least a few dozen bytes: more scans than that is a
        // replay that does not end.
        if scans > file_len / 16 + 1 {
            return Err(format!("{scans} scans from a {file_len}-byte file: the replay does not end"));
        }
    }
    Ok(if scans > 0 { Verdict::Accepted } else { Verdict::Rejected })
}

fn scratch(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("croprow-fuzz-{}-{name}.mcap", std::process::id()))
}

#[test]
fn fuzz_mcap_replay() {
    let path = scratch("replay");
    let config = ReplayConfig::default();
    Campaign::new("mcap_replay", seeds(), EXECS).run(|bytes| {
        std::fs::write(&path, bytes).map_err(|e| format!("scratch file: {e}"))?;
        replay(&path, &config, bytes.len())
    });
    let _ = std::fs::remove_file(&path);
}

/// With a fallback mount, a damaged `/tf_static` does not end the replay early, so mutations reach
/// further into the clouds and odometry.
#[test]
fn fuzz_mcap_replay_with_fallback_mount() {
    let path = scratch("fallback");
    let mount = Mount { x_m: 0.5, y_m: 0.0, z_m: 1.2, roll_rad: 0.0, pitch_rad: 0.4, yaw_rad: 0.0 };
    let config = ReplayConfig { fallback_mount: Some(mount), ..ReplayConfig::default() };
    Campaign::new("mcap_replay_fallback", seeds(), EXECS).run(|bytes| {
        std::fs::write(&path, bytes).map_err(|e| format!("scratch file: {e}"))?;
        replay(&path, &config, bytes.len())
    });
    let _ = std::fs::remove_file(&path);
}

/// The recording of an independent field recorder (rosbag2 layout, 4 MB), when the shared data is
/// next to the repository (`../shared/data` or `$CROPROW_SHARED_DATA`; CI runs without it): one
/// execution in 40 of the others' count, as each reads the whole file.
#[test]
fn fuzz_mcap_shared_recording() {
    let dir = std::env::var_os("CROPROW_SHARED_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data"));
    let Ok(seed) = std::fs::read(dir.join("sample-young-corn.mcap")) else {
        println!("fuzz mcap_shared_recording: skipped, no {}", dir.join("sample-young-corn.mcap").display());
        return;
    };
    let path = scratch("shared");
    let config = ReplayConfig::default();
    Campaign::new("mcap_shared_recording", vec![seed], EXECS).scaled_down(40).run(|bytes| {
        std::fs::write(&path, bytes).map_err(|e| format!("scratch file: {e}"))?;
        replay(&path, &config, bytes.len())
    });
    let _ = std::fs::remove_file(&path);
}
