#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The `rigview` binary's default command runs the closed-loop demo on the
//! simulated rig.

use std::process::Command;

fn rigview(args: &[&str]) -> (bool, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(args)
        .output()
        .unwrap();
    (
        out.status.success(),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The lines of frame sets: they start with the set's number.
fn set_lines(stdout: &str) -> Vec<&str> {
    stdout
        .lines()
        .filter(|l| {
            l.split_whitespace()
                .next()
                .is_some_and(|w| w.parse::<u64>().is_ok())
        })
        .collect()
}

#[test]
fn the_default_command_runs_the_simulated_rig() {
    let (ok, stdout, stderr) = rigview(&[]);
    assert!(ok, "{stderr}");
    assert!(
        stdout.contains("simulated rig, scenario \"reference\""),
        "{stdout}"
    );
    assert!(
        stdout.contains("4 cameras 1288×964 Mono8 (185° fisheye)"),
        "{stdout}"
    );
    // The reference scenario lasts 2 s at 20 Hz: 40 frame sets, each
    // printed with the four cameras and the four overlaps.
    let sets = set_lines(&stdout);
    assert_eq!(sets.len(), 40, "{stdout}");
    assert!(sets.iter().all(|l| l.matches('|').count() == 5), "{stdout}");
    assert!(stdout.contains("median |log2 r_ij|"), "{stdout}");
}

#[test]
fn the_demo_takes_scenarios_and_options() {
    let (ok, stdout, stderr) = rigview(&[
        "demo",
        "--scenario",
        "tunnel",
        "--frames",
        "3",
        "--scale",
        "0.25",
        "--bits",
        "12",
        "--law",
        "fast",
        "--mode",
        "single",
        "--roi",
        "full",
    ]);
    assert!(ok, "{stderr}");
    assert!(stdout.contains("322×241 Mono12"), "{stdout}");
    assert_eq!(set_lines(&stdout).len(), 3, "{stdout}");
}

#[test]
fn a_bad_scenario_is_a_clear_error() {
    let (ok, _, stderr) = rigview(&["demo", "--scenario", "no-such-scenario.sim.yaml"]);
    assert!(!ok);
    assert!(stderr.contains("no-such-scenario.sim.yaml"), "{stderr}");
    let dir = std::env::temp_dir().join(format!("rigview-demo-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let file = dir.join("bad.sim.yaml");
    std::fs::write(
        &file,
        "format: rigview-sim\nversion: 1\nscene: {sun: {elevation_deg: 120}}\n",
    )
    .unwrap();
    let (ok, _, stderr) = rigview(&["demo", "--scenario", file.to_str().unwrap()]);
    assert!(!ok);
    assert!(
        stderr.contains("bad.sim.yaml") && stderr.contains("scene.sun.elevation_deg"),
        "{stderr}"
    );
    let (ok, _, stderr) = rigview(&["demo", "--latency", "3", "--scale", "0.25"]);
    assert!(!ok);
    assert!(stderr.contains("latency_frames"), "{stderr}");
    std::fs::remove_dir_all(&dir).unwrap();
}
