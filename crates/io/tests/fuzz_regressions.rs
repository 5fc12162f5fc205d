//! Inputs the fuzzers (`tests/fuzz_*.rs`) found failing, kept as they were found
//! (`tests/data/fuzz/`), each test named after what it guards. docs/fuzzing.md lists them with the
//! commit that fixed them.

use std::path::{Path, PathBuf};

use croprow_io::msg::{self, TfMessage};
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
