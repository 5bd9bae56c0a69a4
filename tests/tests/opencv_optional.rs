//! OpenCV is optional: `rigview-core` builds without it (it depends on
//! `rigview-calib` without its `opencv` feature), and `rigview-calib`
//! without the feature builds, reads and writes every other format, and
//! refuses OpenCV files with an error that names the file and the feature.
//!
//! Within the workspace, the app turns the feature on for every crate that
//! is built with it, so these checks ask cargo itself: `cargo tree` for the
//! dependencies, and `cargo test` of `rigview-calib` alone, without its
//! default features, in a target folder of its own (the first run builds
//! the crate's few dependencies there: a few minutes on one core).

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::Command;

fn workspace() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("..")
}

/// `cargo ARGS` in the workspace, offline; its stdout and stderr.
fn cargo(args: &[&str]) -> (bool, String, String) {
    let cargo = std::env::var_os("CARGO").unwrap_or_else(|| "cargo".into());
    let out = Command::new(cargo)
        .arg("--offline")
        .args(args)
        .current_dir(workspace())
        .output()
        .expect("cargo runs");
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The packages of `cargo tree ARGS` (one per line, no duplicates).
fn tree(args: &[&str]) -> Vec<String> {
    let mut all = vec![
        "tree",
        "--edges",
        "normal",
        "--prefix",
        "none",
        "--no-dedupe",
    ];
    all.extend(args);
    let (ok, stdout, stderr) = cargo(&all);
    assert!(ok, "cargo {all:?} failed:\n{stderr}");
    let mut packages: Vec<String> = stdout
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .map(str::to_owned)
        .collect();
    packages.sort();
    packages.dedup();
    packages
}

#[test]
fn core_and_calib_without_its_feature_depend_on_no_opencv() {
    let core = tree(&["--package", "rigview-core"]);
    assert!(core.iter().any(|p| p == "rigview-calib"), "{core:?}");
    assert!(!core.iter().any(|p| p.contains("opencv")), "{core:?}");
    let calib = tree(&["--package", "rigview-calib", "--no-default-features"]);
    assert!(!calib.iter().any(|p| p.contains("opencv")), "{calib:?}");
    // The check can fail: with its default features calib has OpenCV.
    let with = tree(&["--package", "rigview-calib"]);
    assert!(with.iter().any(|p| p == "opencv"), "{with:?}");
}

#[test]
fn calib_without_opencv_refuses_opencv_files_naming_them() {
    let target = Path::new(env!("CARGO_TARGET_TMPDIR")).join("calib-without-opencv");
    let target = target.display().to_string();
    let test =
        "formats::without_opencv::opencv_files_need_the_opencv_feature_and_other_formats_work";
    let (ok, stdout, stderr) = cargo(&[
        "test",
        "--package",
        "rigview-calib",
        "--no-default-features",
        "--lib",
        "--target-dir",
        &target,
        "--",
        "--exact",
        test,
    ]);
    assert!(ok, "{stdout}\n{stderr}");
    assert!(
        stdout.contains(&format!("test {test} ... ok")) && stdout.contains("1 passed"),
        "the test without OpenCV did not run:\n{stdout}"
    );
}
