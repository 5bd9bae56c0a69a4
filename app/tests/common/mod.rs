//! Helpers the app's tests share.

#![allow(dead_code, clippy::unwrap_used)]

use std::path::Path;
use std::process::Command;

use rigview::eval::strategy::EvalStrategy;

/// The strategies a closed loop on brackets runs (every controller of
/// rigview's; the cameras' own AE needs the simulated camera).
pub const LOOP_STRATEGIES: [EvalStrategy; 6] = [
    EvalStrategy::Linear,
    EvalStrategy::Nonlinear,
    EvalStrategy::Fast,
    EvalStrategy::Pid,
    EvalStrategy::Mean,
    EvalStrategy::Multi,
];

/// Runs `rigview ARGS --settings DIR/settings.yaml`; returns its output,
/// after checking that it succeeded.
pub fn rigview(args: &[&str], dir: &Path) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(args)
        .arg("--settings")
        .arg(dir.join("settings.yaml"))
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "rigview {args:?}: {stdout}\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// The CSV as a header and rows of fields.
pub fn csv(path: &Path) -> (Vec<String>, Vec<Vec<String>>) {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    let header = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(str::to_owned).collect())
        .collect();
    (header, rows)
}
