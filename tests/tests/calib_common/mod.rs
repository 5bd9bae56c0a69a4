//! What the calibration tests share.

use std::path::PathBuf;

/// The shared real data (`shared/data` beside the repository).
pub fn data_dir() -> PathBuf {
    let d = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../shared/data");
    assert!(
        d.is_dir(),
        "the shared data folder is missing: {}",
        d.display()
    );
    d
}
