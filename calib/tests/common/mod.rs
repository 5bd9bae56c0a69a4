//! What the calibration crate's test files share.

use std::path::{Path, PathBuf};

/// A file of `calib/tests/data`: its path and text.
pub fn fixture(name: &str) -> (PathBuf, String) {
    let p = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data")
        .join(name);
    let text =
        std::fs::read_to_string(&p).unwrap_or_else(|e| panic!("test data {}: {e}", p.display()));
    (p, text)
}
