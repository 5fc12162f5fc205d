//! Inputs the fuzzers (`tests/fuzz_*.rs`) found failing, kept as they were found
//! (`tests/data/fuzz/`), each test named after what it guards. docs/fuzzing.md lists them with the
//! commit that fixed them.

use std::path::{Path, PathBuf};

use croprow_io::maps;
use croprow_io::msg::{self, TfMessage};
use croprow_io::read::{Recording, RecordingError, ReplayConfig};
use croprow_io::tf::{LookupError, TransformBuffer};

fn input(name: &str) -> Vec<u8> {
    let path: PathBuf = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz").join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

/// A `/tf_static` whose `base_footprint -> velodyne` translation is -1.5e308: each edge is finite, but
/// the lookup `velodyne <- base_footprint` composed to `[-inf, inf, inf]` and was returned as valid.
#[test]
fn tf_lookup_of_an_overflowing_chain_is_an_error_not_infinity() {
    let message: TfMessage = msg::decode_owned(&input("tf_static_overflowing_translation.cdr")).unwrap();
    let mut buffer = TransformBuffer::new();
    for t in &message.transforms {
        buffer.insert(t);
    }
    let lookup = buffer.lookup("velodyne", "base_footprint");
    assert!(matches!(lookup, Err(LookupError::NonFinite { .. })), "{lookup:?}");
}

/// An MCAP file read front to back (no chunk index) whose uncompressed chunk holds a record longer
/// than what is left of the chunk: mcap 0.26's linear reader underflowed a counter and panicked
/// ("attempt to subtract with overflow"). The replay now ends with a `Corrupt` error instead.
#[test]
fn mcap_record_longer_than_its_chunk_is_corrupt_not_a_panic() {
    let path = std::env::temp_dir().join(format!("croprow-regression-{}-chunk.mcap", std::process::id()));
    std::fs::write(&path, input("mcap_record_longer_than_its_chunk.mcap")).unwrap();
    let mut replay = Recording::open(&path).unwrap().replay(&ReplayConfig::default()).unwrap();
    let mut items = Vec::new();
    while let Some(item) = replay.next_scan() {
        items.push(item.map(|f| f.stamp_s));
        assert!(items.len() < 100, "the replay ends");
    }
    let _ = std::fs::remove_file(&path);
    let last = items.last().expect("an error ends the replay");
    assert!(
        matches!(last, Err(RecordingError::Corrupt { detail, .. }) if detail.contains("chunk")),
        "{last:?}"
    );
}

/// A LAS header claiming 100 663 317 points of 63 744 bytes each in a 4 KiB file: the reader asked
/// the `las` crate for 65 536 points at a time and so allocated (and zeroed) 4 GiB per read, seconds
/// of page faults for a file it then refused. Chunks are now sized in bytes (2 MiB); the file is
/// still refused, at its first point.
#[test]
fn las_with_a_huge_record_length_is_refused_without_a_huge_chunk() {
    let path = std::env::temp_dir().join(format!("croprow-regression-{}-reclen.las", std::process::id()));
    std::fs::write(&path, input("las_record_length_63744.las")).unwrap();
    let err = maps::read(&path).unwrap_err().to_string();
    let _ = std::fs::remove_file(&path);
    assert!(err.contains("LAS point 0"), "{err}");
}

/// An ascii PLY vertex whose list property says it has 18 446 744 073 709 551 616 items: the count
/// was turned into a token index with `as usize` (saturating) and `1 + usize::MAX` overflowed, a
/// panic in builds with overflow checks. A list count must now be a whole number that fits its line.
#[test]
fn ply_ascii_list_length_past_its_line_is_refused_not_a_panic() {
    let path = std::env::temp_dir().join(format!("croprow-regression-{}-list.ply", std::process::id()));
    std::fs::write(&path, input("ply_ascii_list_length_2e19.ply")).unwrap();
    let err = maps::read(&path).unwrap_err().to_string();
    let _ = std::fs::remove_file(&path);
    assert!(err.contains("PLY vertex 1: list length `18446744073709551616`"), "{err}");
}

/// A chunk index entry whose length runs past the end of the file: the indexed reader sized a
/// buffer for it (up to 256 MiB) before the read failed. Now refused as `Corrupt` first. Found while
/// reading the code behind the slowest `fuzz_mcap` executions, built here from a committed recording.
#[test]
fn mcap_chunk_index_past_the_end_of_the_file_is_corrupt() {
    let mut bytes =
        std::fs::read(Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/xyz_f32.mcap")).unwrap();
    // Walk the top-level records (opcode u8, length u64 LE) to the first chunk index (0x08). Its body:
    // 4 u64 (times, chunk offset, chunk length), the message index offsets (u32 byte length, then
    // entries), the message index length (u64), the compression (u32 length, then text), and the
    // compressed size (u64): the length the reader asks for.
    let u32_at = |b: &[u8], i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap()) as usize;
    let mut at = 8;
    let patched = loop {
        let Some(&opcode) = bytes.get(at) else { break false };
        let len = u64::from_le_bytes(bytes[at + 1..at + 9].try_into().unwrap()) as usize;
        if opcode == 0x08 {
            let offsets = at + 9 + 32;
            let compression = offsets + 4 + u32_at(&bytes, offsets) + 8;
            let size = compression + 4 + u32_at(&bytes, compression);
            bytes[size..size + 8].copy_from_slice(&(200u64 << 20).to_le_bytes());
            break true;
        }
        at += 9 + len;
    };
    assert!(patched, "the recording has a chunk index");
    let path = std::env::temp_dir().join(format!("croprow-regression-{}-index.mcap", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let recording = Recording::open(&path).unwrap();
    assert!(recording.is_indexed());
    let result = recording.replay(&ReplayConfig::default()).map(|mut r| r.next_scan().map(|s| s.map(|_| ())));
    let _ = std::fs::remove_file(&path);
    let detail = match result {
        Err(RecordingError::Corrupt { detail, .. })
        | Ok(Some(Err(RecordingError::Corrupt { detail, .. }))) => detail,
        other => panic!("{other:?}"),
    };
    assert!(detail.contains("past the end of the"), "{detail}");
}
