#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! `rigview run --headless`: the pipeline without the window writes the
//! composed views, the telemetry CSV, the exposure plot and a summary.

mod common;

use std::path::Path;
use std::process::Command;

use common::{csv, rigview};

fn run(args: &[&str], dir: &Path) -> String {
    let out = dir.join("out");
    let mut all = vec!["run", "--headless", "--out", out.to_str().unwrap()];
    all.extend(args);
    rigview(&all, dir)
}

#[test]
fn a_headless_run_on_the_simulated_rig_writes_all_its_outputs() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = run(
        &[
            "--scale",
            "0.25",
            "--frames",
            "30",
            "--every",
            "10",
            "--strategy",
            "multi",
        ],
        dir.path(),
    );
    let out = dir.path().join("out");
    assert!(stdout.contains("30 of 30 sets processed"), "{stdout}");
    assert!(stdout.contains("0 dropped before processing"), "{stdout}");

    // Views of sets 0, 10, 20 and the last, 29: 1000×1000 grey, not black,
    // with the vehicle's rectangle black in the middle.
    let mut views: Vec<_> = std::fs::read_dir(out.join("views"))
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    views.sort();
    assert_eq!(
        views,
        [
            "view_000000.png",
            "view_000010.png",
            "view_000020.png",
            "view_000029.png"
        ]
    );
    let img = image::open(out.join("views/view_000029.png"))
        .unwrap()
        .to_luma8();
    assert_eq!(img.dimensions(), (1000, 1000));
    let mean = img.pixels().map(|p| f64::from(p.0[0])).sum::<f64>() / 1e6;
    assert!(mean > 20.0, "the view is black (mean {mean:.1})");
    assert_eq!(img.get_pixel(500, 500).0[0], 0, "the vehicle is not black");

    // The telemetry: a row per set, every camera's exposure, and a ratio per
    // overlap.
    let (header, rows) = csv(&out.join("telemetry.csv"));
    assert_eq!(rows.len(), 30);
    assert!(rows.iter().all(|r| r.len() == header.len()));
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    let triggers: Vec<u64> = rows.iter().map(|r| r[0].parse().unwrap()).collect();
    assert_eq!(triggers, (0..30).collect::<Vec<_>>());
    for cam in ["front", "left", "back", "right"] {
        let e: Vec<f64> = rows
            .iter()
            .map(|r| r[col(&format!("{cam}.exposure"))].parse().unwrap())
            .collect();
        assert!(e.iter().all(|&v| v > 0.0), "{cam}: {e:?}");
        let g: f64 = rows[29][col(&format!("{cam}.gamma_hat"))].parse().unwrap();
        assert!((0.5..=2.0).contains(&g), "{cam}: γ̂ {g}");
    }
    // The controller acted: some camera's exposure changed from the start.
    let front: Vec<f64> = rows
        .iter()
        .map(|r| r[col("front.exposure")].parse().unwrap())
        .collect();
    assert!(
        front.iter().any(|&e| (e / front[0] - 1.0).abs() > 0.05),
        "{front:?}"
    );
    for pair in ["front-left", "front-right", "left-back", "back-right"] {
        let k = col(&format!("log2_r.{pair}"));
        assert!(
            rows[29][k].parse::<f64>().is_ok(),
            "{pair}: {:?}",
            rows[29][k]
        );
    }
    let dropped: Vec<u64> = rows
        .iter()
        .map(|r| r[col("dropped")].parse().unwrap())
        .collect();
    assert!(dropped.iter().all(|&d| d == 0));

    // The plot: a 1400×1500 PNG with the cameras' line colours in it.
    let plot = image::open(out.join("exposure.png")).unwrap().to_rgb8();
    assert_eq!(plot.dimensions(), (1400, 1500));
    for colour in [
        [220u8, 70, 50],
        [40, 120, 200],
        [60, 160, 60],
        [210, 150, 20],
    ] {
        let n = plot.pixels().filter(|p| p.0 == colour).count();
        assert!(n > 200, "colour {colour:?}: {n} pixels");
    }
    let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
    assert!(
        summary.contains("set ready → processed: median"),
        "{summary}"
    );
}

/// `RIGVIEW_ISA` caps the kernels' instruction set (to measure what a
/// narrower CPU runs), and the summary says which ran; a value that names
/// no set is reported and ignored.
#[test]
fn the_instruction_set_can_be_capped_and_is_reported() {
    let dir = tempfile::tempdir().unwrap();
    let cap = |value: &str| {
        let out = dir.path().join(value);
        let o = Command::new(env!("CARGO_BIN_EXE_rigview"))
            .args(["run", "--headless", "--scale", "0.25", "--frames", "3"])
            .args(["--settings", dir.path().join("none.toml").to_str().unwrap()])
            .args(["--out", out.to_str().unwrap()])
            .env("RIGVIEW_ISA", value)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let summary = std::fs::read_to_string(out.join("summary.txt")).unwrap();
        let kernels = summary
            .lines()
            .find_map(|l| l.strip_prefix("kernels: "))
            .unwrap_or_else(|| panic!("{summary}"))
            .to_owned();
        (kernels, String::from_utf8_lossy(&o.stderr).into_owned())
    };
    let (kernels, _) = cap("baseline");
    assert!(kernels.starts_with("baseline"), "{kernels}");
    let (kernels, stderr) = cap("sse9");
    // Not capped: no note of the CPU's own set beside it.
    assert!(!kernels.contains("RIGVIEW_ISA"), "{kernels}");
    assert!(
        stderr.contains("RIGVIEW_ISA=\"sse9\" is not an instruction set"),
        "{stderr}"
    );
}

#[test]
fn a_headless_run_is_repeatable_in_lock_step() {
    let a = tempfile::tempdir().unwrap();
    let b = tempfile::tempdir().unwrap();
    let args = ["--scale", "0.25", "--frames", "12", "--law", "fast"];
    run(&args, a.path());
    run(&args, b.path());
    let strip = |p: &Path| {
        // Everything but the wall-clock columns.
        let (header, rows) = csv(&p.join("out/telemetry.csv"));
        let keep: Vec<usize> = (0..header.len())
            .filter(|&k| !header[k].ends_with("_ms") && header[k] != "set_rate_hz")
            .collect();
        rows.into_iter()
            .map(|r| keep.iter().map(|&k| r[k].clone()).collect::<Vec<_>>())
            .collect::<Vec<_>>()
    };
    assert_eq!(strip(a.path()), strip(b.path()));
}

#[test]
fn a_headless_run_on_fake_live_cameras_goes_through_aravis() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = run(
        &[
            "--source", "live", "--fake", "--scale", "0.25", "--frames", "15",
        ],
        dir.path(),
    );
    assert!(stdout.contains("Aravis fake cameras"), "{stdout}");
    let (_, rows) = csv(&dir.path().join("out/telemetry.csv"));
    assert!(rows.len() >= 15, "{stdout}");
}

#[test]
fn bad_options_are_refused_with_what_to_give() {
    let dir = tempfile::tempdir().unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(["run", "--headless", "--source", "live", "--out"])
        .arg(dir.path())
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("--rig FILE or --fake"), "{err}");
}

#[test]
fn the_cameras_own_auto_exposure_is_switched_on_and_rigview_sends_no_commands() {
    let dir = tempfile::tempdir().unwrap();
    let stdout = run(
        &[
            "--source",
            "live",
            "--fake",
            "--scale",
            "0.25",
            "--frames",
            "15",
            "--strategy",
            "camera-auto",
        ],
        dir.path(),
    );
    for cam in ["front", "left", "back", "right"] {
        assert!(
            stdout.contains(&format!("{cam}: its own auto-exposure is on")),
            "{stdout}"
        );
    }
    let (header, rows) = csv(&dir.path().join("out/telemetry.csv"));
    let k = header.iter().position(|h| h == "front.command").unwrap();
    assert!(rows.iter().all(|r| r[k].is_empty()), "a command was sent");
    let g = header.iter().position(|h| h == "front.gamma_hat").unwrap();
    assert!(rows.iter().all(|r| !r[g].is_empty()), "no estimate to show");
}

#[test]
fn a_headless_panorama_run_writes_panoramas_and_each_pairs_matches() {
    let dir = tempfile::tempdir().unwrap();
    // At the trigger rate, so that the matching (on its worker thread)
    // keeps up with the sets as it does live.
    let stdout = run(
        &[
            "--view",
            "panorama",
            "--scale",
            "0.5",
            "--realtime",
            "--frames",
            "40",
            "--every",
            "20",
            "--match-every",
            "5",
        ],
        dir.path(),
    );
    let out = dir.path().join("out");
    // At the trigger rate a loaded machine may drop a set.
    assert!(stdout.contains("of 40 sets processed"), "{stdout}");
    let mut views: Vec<_> = std::fs::read_dir(out.join("views"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    views.sort();
    assert!(views.len() >= 2, "{views:?}");
    // The panorama: 2048×270 (the live default), the cylinder seen all
    // round its horizon (a few black pixels are dark things: shadows under
    // the cars), and not black.
    let img = image::open(views.last().unwrap()).unwrap().to_luma8();
    assert_eq!(img.dimensions(), (2048, 270));
    let horizon_black = (0..2048)
        .filter(|&x| img.get_pixel(x, 135).0[0] == 0)
        .count();
    assert!(
        horizon_black < 2048 / 20,
        "{horizon_black} black pixels on the horizon"
    );
    let mean = img.pixels().map(|p| f64::from(p.0[0])).sum::<f64>() / (2048.0 * 270.0);
    assert!(mean > 20.0, "the panorama is black (mean {mean:.1})");

    // Per pair: matches, inliers, the reprojection error and r_ij, or why
    // there is no ratio.
    let (header, rows) = csv(&out.join("telemetry.csv"));
    assert!(rows.len() >= 30, "{} rows", rows.len());
    assert!(rows.iter().all(|r| r.len() == header.len()));
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h == name)
            .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
    };
    let last = &rows[rows.len() - 1];
    let pairs = ["front-left", "front-right", "left-back", "back-right"];
    let mut with_inliers = 0;
    for p in pairs {
        let matches: usize = last[col(&format!("matches.{p}"))].parse().unwrap();
        let inliers: usize = last[col(&format!("inliers.{p}"))].parse().unwrap();
        let ratio = &last[col(&format!("log2_r.{p}"))];
        let why = &last[col(&format!("no_ratio.{p}"))];
        println!("{p}: {matches} matches, {inliers} inliers, log2 r {ratio:?}, {why:?}");
        assert!(inliers <= matches);
        // A pair has a ratio or says why it has none.
        assert!(ratio.is_empty() != why.is_empty(), "{p}: {ratio:?} {why:?}");
        if inliers > 0 {
            with_inliers += 1;
            assert!(!last[col(&format!("error_px.{p}"))].is_empty(), "{p}");
        }
    }
    assert!(with_inliers >= 2, "{with_inliers} pairs with inliers");
    assert!(stdout.contains("pair front–left:"), "{stdout}");
}
