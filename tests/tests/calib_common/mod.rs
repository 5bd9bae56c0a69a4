//! What the calibration tests share.

use std::path::PathBuf;

/// The real test data (`tests/data`, with its licences).
pub fn data_dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data");
    assert!(
        d.is_dir(),
        "the test data folder is missing: {}",
        d.display()
    );
    d
}
