#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! Closed loop on exposure brackets exported from the simulated rig, each
//! camera's command answered with the nearest of brackets 0.25 EV apart:
//! every strategy settles within 0.2 EV (less than a level) of where it
//! settles on the simulator itself (the level walker may rest on the
//! neighbour of the nearest level where the fixed point lies near their
//! midpoint: `core/src/exposure/levels.rs`) (the median of the last 10 of 120 frames; printed with
//! `--nocapture`). And `--source brackets:DIR` runs headless.

mod common;

use std::sync::Arc;

use rigview::eval::closed_loop::{self, LoopOptions};
use rigview::eval::strategy::EvalStrategy;
use rigview::session::brackets::{self, BracketMode, BracketOptions, ExportSpec};
use rigview::session::BRACKETS_START;
use rigview_core::sim::{SimConfig, SimRender};
use rigview_core::source::FrameSource;

/// Moments of the sequence.
const FRAMES: usize = 120;
/// Frames whose median is the settled exposure.
const TAIL: usize = 10;

#[test]
fn every_strategy_settles_on_brackets_where_it_settles_on_the_simulator() {
    let config = SimConfig {
        scale: 0.125,
        ..SimConfig::preset("reference").unwrap()
    };
    assert_eq!(
        (config.start.shutter_us, config.start.gain_db),
        (BRACKETS_START.shutter_us, BRACKETS_START.gain_db)
    );
    let render = Arc::new(SimRender::new(&config).unwrap());
    let dir = tempfile::tempdir().unwrap();
    // 2^7 to 2^13 µs in 25 brackets: 0.25 EV apart.
    let spec = ExportSpec {
        frames: FRAMES,
        levels: brackets::levels(7.0, 13.0, 25),
    };
    brackets::export(&render, &spec, dir.path(), &mut || {}).unwrap();

    let mut worst = 0.0f64;
    let mut failures = Vec::new();
    for strategy in common::LOOP_STRATEGIES {
        let sim = closed_loop::run(&render, strategy.settings(), FRAMES, &mut || {}).unwrap();
        let options = BracketOptions::new(BRACKETS_START, BracketMode::Nearest);
        let (source, rig) = brackets::open_with_rig(dir.path(), None, &options).unwrap();
        let on_brackets = closed_loop::run_source(
            source,
            &rig,
            strategy.settings(),
            LoopOptions::default(),
            &mut || {},
        )
        .unwrap();
        assert_eq!(on_brackets.log2_e[0].len(), FRAMES);
        for cam in 0..sim.log2_e.len() {
            let (a, b) = (sim.settled(cam, TAIL), on_brackets.settled(cam, TAIL));
            println!(
                "{:>10} camera {cam}: simulator 2^{a:.3}, brackets 2^{b:.3}",
                strategy.key()
            );
            // A frame's exposure on brackets is a bracket's.
            let last = *on_brackets.log2_e[cam].last().unwrap();
            assert!(
                spec.levels.iter().any(|l| (l.log2() - last).abs() < 1e-6),
                "{last}"
            );
            if (a - b).abs() > 0.2 {
                failures.push(format!(
                    "{}: camera {cam} settles at 2^{a:.3} on the simulator, 2^{b:.3} on brackets",
                    strategy.key()
                ));
            }
            worst = worst.max((a - b).abs());
        }
    }
    println!("largest difference: {worst:.3} EV");
    assert!(failures.is_empty(), "{failures:#?}");

    // The same sequence through `rigview run --headless`.
    let out = dir.path().join("run");
    let stdout = common::rigview(
        &[
            "run",
            "--headless",
            "--source",
            &format!("brackets:{}", dir.path().display()),
            "--strategy",
            "single",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert!(stdout.contains(&format!("{FRAMES} processed")), "{stdout}");
    assert!(out.join("telemetry.csv").is_file());

    // The experiments that apply, on the brackets: every settled exposure
    // and every sweep's best is a bracket's level; balancing brings the
    // overlaps closer than each camera alone, as on the simulator.
    let out = dir.path().join("eval");
    eval_quick(dir.path(), &out, &["--bracket-mode", "nearest"], dir.path());
    let is_level = |v: f64| spec.levels.iter().any(|l| (l.log2() - v).abs() < 1e-3);
    let (h, rows) = common::csv(&out.join("fig3_settled.csv"));
    assert_eq!(rows.len(), 4 * 12, "{h:?}");
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    for r in &rows {
        let num = |name: &str| r[col(name)].parse::<f64>().unwrap();
        assert!(is_level(num("best_log2_e")), "{r:?}");
        assert!(num("m_fraction_of_best") <= 1.0 + 1e-9, "{r:?}");
    }
    let (h, rows) = common::csv(&out.join("fig3_m_vs_exposure.csv"));
    assert_eq!(rows.len(), 4 * spec.levels.len(), "{h:?}");
    let (h, rows) = common::csv(&out.join("fig4_seams.csv"));
    let mean = |strategy: &str| {
        let r = rows.iter().find(|r| r[1] == strategy).unwrap();
        r[h.iter()
            .position(|c| c == "mean_abs_log2_r_images")
            .unwrap()]
        .parse::<f64>()
        .unwrap()
    };
    assert!(
        mean("multi") < mean("nonlinear"),
        "{} {}",
        mean("multi"),
        mean("nonlinear")
    );
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_eq!(html.matches("src=\"data:image/png;base64,").count(), 4);
    assert!(html.contains("bracket sequence") && !html.contains("Fig. 7"));

    emulated_evaluation(dir.path());
}

/// `rigview eval --preset quick --brackets folder --out out` with `extra`
/// options, run in `cwd`.
fn eval_quick(
    folder: &std::path::Path,
    out: &std::path::Path,
    extra: &[&str],
    cwd: &std::path::Path,
) {
    let mut args = vec![
        "eval",
        "--preset",
        "quick",
        "--brackets",
        folder.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ];
    args.extend_from_slice(extra);
    common::rigview(&args, cwd);
}

/// `rigview eval --brackets DIR` in its default mode, emulation: M(E)
/// swept densely (0.1 EV over the brackets' span widened by 1 EV each
/// side), every strategy from the common start, with the frames it took
/// to settle and its flicker at rest.
fn emulated_evaluation(dir: &std::path::Path) {
    let out = dir.join("eval-emulated");
    eval_quick(dir, &out, &[], dir);
    // 2^6 to 2^14 µs at 0.1 EV: 81 exposures per camera (fewer where the
    // last moment's radiance spans less).
    let (_, rows) = common::csv(&out.join("fig3_m_vs_exposure.csv"));
    assert!(rows.len() >= 4 * 60, "{} sweep rows", rows.len());
    let (h, rows) = common::csv(&out.join("fig3_settled.csv"));
    assert_eq!(rows.len(), 4 * 12, "{h:?}");
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    for r in &rows {
        let num = |name: &str| r[col(name)].parse::<f64>().unwrap();
        println!(
            "{:>22} {:>6}: settled 2^{:.2}, best 2^{:.2}, M {:.1} % of the best, {} corners tracked",
            r[col("strategy")],
            r[col("camera")],
            num("settled_log2_e"),
            num("best_log2_e"),
            100.0 * num("m_fraction_of_best"),
            r[col("tracked")]
        );
        assert!(num("m_fraction_of_best") <= 1.0 + 1e-9, "{r:?}");
    }
    let (h, rows) = common::csv(&out.join("brackets_start.csv"));
    assert_eq!(rows.len(), 4 * 13, "{h:?}");
    let reach = h.iter().position(|c| c == "frames_to_90pct_m").unwrap();
    for r in &rows {
        println!("{}", r.join(" "));
        // Empty (never), or a frame of the sequence.
        assert!(
            r[reach].is_empty() || r[reach].parse::<usize>().is_ok_and(|f| f < FRAMES),
            "{r:?}"
        );
    }
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("From the start") && html.contains("emulated"));
    // The surround rig has no stereo pair: no stereo file, no link to one.
    assert!(!out.join("fig3_stereo.csv").exists());
    assert!(!html.contains("fig3_stereo.csv"));
}

/// `moments` of the simulated lawn seen by a forward stereo pair
/// (`assets/sim/lawn-stereo.sim.yaml`), brackets 1 EV apart from 2^8 to
/// 2^14 µs in 12 bits, exported into `dir/brackets`.
fn lawn_pair(dir: &std::path::Path, moments: usize) -> std::path::PathBuf {
    let scenario = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../assets/sim/lawn-stereo.sim.yaml");
    let folder = dir.join("brackets");
    let moments = moments.to_string();
    common::rigview(
        &[
            "eval",
            "export-brackets",
            "--scenario",
            scenario.to_str().unwrap(),
            "--frames",
            &moments,
            "--exposures",
            "7",
            "--range-ev",
            "8:14",
            "--bits",
            "12",
            "--out",
            folder.to_str().unwrap(),
        ],
        dir,
    );
    folder
}

/// `rigview eval --brackets DIR` on a forward stereo pair (the lawn seen by
/// `assets/stereo-front.rig.yaml`, brackets 1 EV apart from 2^8 to 2^14
/// µs): the valid stereo disparities where each strategy settled are in
/// `fig3_stereo.csv`, the summary and a figure. The fixed exposure, left
/// where the sequence starts it (1.8 EV above the best M here), keeps
/// fewer than every gradient law and mean AE; the gradient laws under
/// scale-and-clip keep more than mean AE.
#[test]
fn eval_on_a_stereo_pair_reports_its_disparities() {
    let dir = tempfile::tempdir().unwrap();
    let folder = lawn_pair(dir.path(), 20);
    let out = dir.path().join("eval");
    eval_quick(&folder, &out, &[], dir.path());
    let (h, rows) = common::csv(&out.join("fig3_stereo.csv"));
    assert_eq!(
        h,
        [
            "preset",
            "strategy",
            "camera_left",
            "camera_right",
            "density"
        ]
    );
    assert_eq!(rows.len(), 12, "a row per strategy but the compensated one");
    let density = |key: &str| -> f64 {
        let r = rows.iter().find(|r| r[1] == key).unwrap();
        assert_eq!(
            (r[2].as_str(), r[3].as_str()),
            ("stereo_left", "stereo_right")
        );
        r[4].parse().unwrap()
    };
    for r in &rows {
        println!("{:>22}: {} of the view with a disparity", r[1], r[4]);
    }
    let fixed = density("fixed");
    assert!(fixed > 0.0);
    for key in [
        "linear",
        "nonlinear",
        "fast",
        "multi",
        "linear/scale-clip",
        "nonlinear/scale-clip",
        "fast/scale-clip",
        "multi/scale-clip",
        "mean",
    ] {
        let d = density(key);
        assert!(
            d <= 1.0 && d > 1.4 * fixed,
            "{key}: {d} against fixed {fixed}"
        );
    }
    // Where the gradient laws hold the lawn under scale-and-clip, more of
    // it matches than where mean AE holds it.
    let mean = density("mean");
    for key in [
        "linear/scale-clip",
        "nonlinear/scale-clip",
        "fast/scale-clip",
        "multi/scale-clip",
    ] {
        assert!(
            density(key) > mean,
            "{key}: {} against mean AE {mean}",
            density(key)
        );
    }
    let headline = std::fs::read_to_string(out.join("headline.md")).unwrap();
    assert!(headline.contains("valid stereo disparities"));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("fig3_stereo.csv") && html.contains("fig3_stereo.png"));
    // The figure: a row for each of five strategies.
    let png = image::open(out.join("fig3_stereo.png")).unwrap();
    assert!(png.height() > 5 * 161, "{}×{}", png.width(), png.height());
}

/// `rigview eval --brackets DIR` on a rig posed relative to a camera, as
/// public stereo datasets give it (the lawn pair's rig converted to a
/// Kalibr camchain, cameras `cam0` and `cam1`): no ground and no surround
/// view, so the cameras are metered over their whole frames and the seams
/// and views are left out, while M, the tracked corners and the stereo
/// disparities are measured. Scale-and-clip's laws settle near the best M
/// of the whole frames, above mean AE, which the sky in the frame pulls
/// down, and mean AE above the fixed exposure.
#[test]
fn eval_on_a_camera_frame_rig_meters_whole_frames() {
    let dir = tempfile::tempdir().unwrap();
    let folder = lawn_pair(dir.path(), 12);
    let rig = folder.join("rig.yaml");
    let camchain = dir.path().join("camchain.yaml");
    common::rigview(
        &[
            "calib",
            "convert",
            rig.to_str().unwrap(),
            camchain.to_str().unwrap(),
            "--to",
            "kalibr",
        ],
        dir.path(),
    );
    std::fs::copy(&camchain, &rig).unwrap();
    let manifest = folder.join("brackets.csv");
    let renamed: String = std::fs::read_to_string(&manifest)
        .unwrap()
        .lines()
        .map(|l| {
            let l = l
                .strip_prefix("stereo_left,")
                .map_or(l.to_string(), |rest| format!("cam0,{rest}"));
            let l = l
                .strip_prefix("stereo_right,")
                .map_or(l.clone(), |rest| format!("cam1,{rest}"));
            l + "\n"
        })
        .collect();
    std::fs::write(&manifest, renamed).unwrap();

    let out = dir.path().join("eval");
    eval_quick(&folder, &out, &[], dir.path());
    for absent in [
        "fig4_seams.csv",
        "fig4_seam_histograms.csv",
        "fig6_views.png",
    ] {
        assert!(!out.join(absent).exists(), "{absent} without a view");
    }
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert!(html.contains("posed relative to one of its cameras"));
    assert!(html.contains("whole frames metered, no surround view"));
    let (_, overlaps) = common::csv(&out.join("fig3_overlap_features.csv"));
    assert!(overlaps.is_empty(), "no panorama, no overlaps matched");
    let (_, stereo) = common::csv(&out.join("fig3_stereo.csv"));
    assert_eq!(
        stereo.len(),
        12,
        "a row per strategy but the compensated one"
    );
    assert!(stereo
        .iter()
        .all(|r| (r[2].as_str(), r[3].as_str()) == ("cam0", "cam1")));
    // Per strategy, M where it settled over the best, mean of the cameras.
    let (h, settled) = common::csv(&out.join("fig3_settled.csv"));
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let (strategy, fraction, tracked) =
        (col("strategy"), col("m_fraction_of_best"), col("tracked"));
    let mean = |key: &str, c: usize| -> f64 {
        let v: Vec<f64> = settled
            .iter()
            .filter(|r| r[strategy] == key)
            .map(|r| r[c].parse().unwrap())
            .collect();
        assert_eq!(v.len(), 2, "{key}: both cameras");
        v.iter().sum::<f64>() / 2.0
    };
    let mut keys: Vec<&str> = settled.iter().map(|r| r[strategy].as_str()).collect();
    keys.dedup();
    for key in keys {
        println!(
            "{key:>22}: M / best {:.3}, {:.0} corners tracked",
            mean(key, fraction),
            mean(key, tracked)
        );
    }
    let (ae, fixed) = (mean("mean", fraction), mean("fixed", fraction));
    assert!(ae > fixed, "mean AE {ae} against fixed {fixed}");
    for key in [
        "linear/scale-clip",
        "nonlinear/scale-clip",
        "fast/scale-clip",
        "multi/scale-clip",
    ] {
        let m = mean(key, fraction);
        assert!(m >= 0.95 && m > ae, "{key}: {m} against mean AE {ae}");
        assert!(mean(key, tracked) > 0.0);
    }
    // `rigview run` replays it too, without a view: every moment
    // processed, the cameras controlled (moved from their start).
    let stdout = run_headless(&folder, dir.path());
    assert!(stdout.contains("12 processed"), "{stdout}");
    let (h, rows) = common::csv(&folder.join("run").join("telemetry.csv"));
    let e = h.iter().position(|c| c == "cam0.exposure").unwrap();
    let first: f64 = rows[0][e].parse().unwrap();
    let last: f64 = rows[rows.len() - 1][e].parse().unwrap();
    assert!((last / first).log2().abs() > 0.5, "{first} -> {last}");
}

/// `rigview run --headless --source brackets:DIR` (emulated, the default)
/// into `DIR/run`: its standard output.
fn run_headless(out: &std::path::Path, cwd: &std::path::Path) -> String {
    let run = out.join("run");
    common::rigview(
        &[
            "run",
            "--headless",
            "--source",
            &format!("brackets:{}", out.display()),
            "--out",
            run.to_str().unwrap(),
        ],
        cwd,
    )
}

/// `rigview record --brackets N` on the simulated rig and on Aravis's fake
/// cameras: every moment holds N images of every camera at the exposures
/// asked for (as each frame reports them), brighter with each exposure,
/// and the folder replays through `--source brackets:DIR`.
#[test]
fn record_brackets_writes_a_sequence_that_replays() {
    let dir = tempfile::tempdir().unwrap();
    for (what, source) in [("sim", "--sim"), ("fake", "--fake")] {
        let out = dir.path().join(what);
        let stdout = common::rigview(
            &[
                "record",
                source,
                "--scale",
                "0.25",
                "--brackets",
                "5",
                "--range-ev",
                "8:12",
                "--moments",
                "3",
                "--out",
                out.to_str().unwrap(),
            ],
            dir.path(),
        );
        assert!(stdout.contains("3 moments of 5 exposures"), "{stdout}");
        let names: Vec<String> = ["front", "left", "back", "right"]
            .map(String::from)
            .to_vec();
        let manifest = brackets::read_manifest(&out, &names).unwrap();
        assert_eq!(manifest.moments.len(), 3, "{what}");
        for m in &manifest.moments {
            for (cam, images) in m.cameras.iter().enumerate() {
                assert_eq!(images.len(), 5, "{what} camera {cam}");
                let mut last_mean = -1.0;
                for (k, image) in images.iter().enumerate() {
                    // 2^8 to 2^12 µs, 1 EV apart, within the cameras'
                    // rounding of the exposure time.
                    let ev = image.setting.exposure().log2();
                    assert!((ev - (8.0 + k as f64)).abs() < 0.05, "{what}: {ev}");
                    let px = brackets::read_image(&manifest, image).unwrap().data;
                    let mean = px.iter().map(|&v| f64::from(v)).sum::<f64>() / px.len() as f64;
                    assert!(mean > last_mean, "{what}: {mean} after {last_mean}");
                    last_mean = mean;
                }
            }
        }
        let stdout = run_headless(&out, dir.path());
        assert!(stdout.contains("3 processed"), "{what}: {stdout}");
    }
    // Writing into a sequence already there is refused, naming the file.
    let again = std::process::Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(["record", "--sim", "--scale", "0.25", "--brackets", "3"])
        .args(["--moments", "1", "--out"])
        .arg(dir.path().join("sim"))
        .arg("--settings")
        .arg(dir.path().join("settings.yaml"))
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&again.stderr);
    assert!(!again.status.success());
    assert!(err.contains("brackets.csv exists already"), "{err}");
}

/// Leave-one-out on 12-bit brackets exported from the simulated rig (an
/// eighth of the resolution, four moments, 2^8 to 2^13 µs 1 EV apart):
/// every interior bracket emulated from the others is within 0.05 EV of
/// itself (median over its unclipped samples), noise-free and with the
/// sensor's noise; and the emulation repeats to the bit.
#[test]
fn emulated_brackets_match_the_ones_left_out() {
    let mut config = SimConfig {
        scale: 0.125,
        ..SimConfig::preset("reference").unwrap()
    };
    config.sensor.bits = 12;
    let render = SimRender::new(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let spec = ExportSpec {
        frames: 4,
        levels: brackets::levels(8.0, 13.0, 6),
    };
    brackets::export(&render, &spec, dir.path(), &mut || {}).unwrap();
    let options = brackets::CheckOptions {
        moments: None,
        seed: 1,
    };
    let report = brackets::check_emulation(dir.path(), &options).unwrap();
    for f in report.levels.iter().chain([&report.all]) {
        println!(
            "level {:?}: {} images, {} samples, median |error| {:.4} EV ({:.4} with noise), PSNR {:.2} dB ({:.2})",
            f.level, f.images, f.samples, f.median_ev, f.median_ev_noisy, f.psnr_db, f.psnr_db_noisy
        );
    }
    assert_eq!(report.moments, 4);
    // Four interior levels, each emulated for 4 moments × 4 cameras.
    assert_eq!(report.levels.len(), 4);
    assert!(report.levels.iter().all(|f| f.images == 16));
    assert!(report.all.samples > 100_000, "{}", report.all.samples);
    assert!(report.all.median_ev <= 0.05, "{:?}", report.all);
    assert!(report.all.median_ev_noisy <= 0.05, "{:?}", report.all);
    assert!(report.all.psnr_db > 40.0, "{:?}", report.all);
    assert_eq!(
        report,
        brackets::check_emulation(dir.path(), &options).unwrap()
    );
}

/// `rigview record --brackets` on Aravis's fake cameras in BayerRG8 writes
/// the mosaics as they are (8-bit PNGs, `RGGB` and 8 bits on every line),
/// which read back as BayerRG8 and replay, emulated, through
/// `--source brackets:DIR` with the view composed.
#[test]
fn record_brackets_of_a_bayer_camera_writes_its_mosaic() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("bayer");
    let stdout = common::rigview(
        &[
            "record",
            "--fake",
            "--pixel-format",
            "BayerRG8",
            "--scale",
            "0.5",
            "--brackets",
            "3",
            "--range-ev",
            "9:11",
            "--moments",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    assert!(stdout.contains("2 moments of 3 exposures"), "{stdout}");
    let text = std::fs::read_to_string(out.join(brackets::MANIFEST)).unwrap();
    assert!(text.contains("# response: linear"), "{text}");
    let names: Vec<String> = ["front", "left", "back", "right"]
        .map(String::from)
        .to_vec();
    let manifest = brackets::read_manifest(&out, &names).unwrap();
    for images in &manifest.moments[0].cameras {
        for image in images {
            assert_eq!(image.layout.pattern, Some("RGGB"));
            assert_eq!(image.layout.bits, Some(8));
            let d = brackets::read_image(&manifest, image).unwrap();
            assert_eq!(d.format, rigview_core::exposure::PixelFormat::BayerRg8);
        }
    }
    let stdout = run_headless(&out, dir.path());
    assert!(stdout.contains("2 processed"), "{stdout}");
}

/// A 12-bit Bayer bracket sequence (the simulated rig at half resolution,
/// 644×482, its 12-bit frames written as BayerRG12 mosaics of its grey
/// scene) runs closed loop, emulated, with the view composed: metering
/// reads the 12-bit quads, the view demosaics them, and the cameras move
/// from their start towards the scene's exposure.
#[test]
fn a_12_bit_bayer_sequence_runs_with_its_view() {
    let mut config = SimConfig {
        scale: 0.5,
        ..SimConfig::preset("reference").unwrap()
    };
    config.sensor.bits = 12;
    let render = SimRender::new(&config).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let names: Vec<String> = render.cameras().iter().map(|c| c.name.clone()).collect();
    let mut writer =
        brackets::BracketWriter::create(dir.path(), Some(render.rig()), &names, "12-bit Bayer")
            .unwrap();
    let levels = brackets::levels(8.0, 13.0, 6);
    for n in 0..6u64 {
        let mut images = Vec::new();
        for (i, info) in render.cameras().iter().enumerate() {
            assert_eq!((info.width % 2, info.height % 2), (0, 0));
            for &level in &levels {
                let setting = rigview_core::exposure::ExposureSetting {
                    shutter_us: level,
                    gain_db: 0.0,
                };
                images.push((i, render.render(i, n, setting, true).unwrap()));
            }
        }
        let frames: Vec<brackets::BracketFrame<'_>> = images
            .iter()
            .map(|(i, f)| brackets::BracketFrame {
                camera: *i,
                setting: f.meta.taken,
                format: rigview_core::exposure::PixelFormat::BayerRg12,
                width: f.meta.width,
                height: f.meta.height,
                data: &f.data,
            })
            .collect();
        writer.write_moment(render.time_of(n), &frames).unwrap();
    }
    let options = BracketOptions::new(BRACKETS_START, BracketMode::Emulate);
    let (source, rig) = brackets::open_with_rig(dir.path(), None, &options).unwrap();
    assert!(source
        .cameras()
        .iter()
        .all(|c| c.format == rigview_core::exposure::PixelFormat::BayerRg12 && c.levels.is_none()));
    let trace = closed_loop::run_source(
        source,
        &rig,
        EvalStrategy::Nonlinear.settings(),
        LoopOptions { view: true },
        &mut || {},
    )
    .unwrap();
    let canvas = trace.canvas.as_ref().unwrap();
    // A colour view with something in it.
    assert_eq!(canvas.channels, 3);
    let lit = canvas.data.iter().filter(|&&v| v > 10).count();
    assert!(
        lit > canvas.data.len() / 4,
        "{lit} of {}",
        canvas.data.len()
    );
    // Every camera was commanded away from its start, to exposures no
    // bracket has.
    for (cam, e) in trace.log2_e.iter().enumerate() {
        let last = *e.last().unwrap();
        assert!(
            (last - BRACKETS_START.exposure().log2()).abs() > 0.05,
            "camera {cam}: {e:?}"
        );
        assert!(
            levels.iter().all(|l| (l.log2() - last).abs() > 1e-3),
            "camera {cam}: {e:?}"
        );
    }
}

/// `rigview eval import-brackets` on a dataset laid out as
/// `SRC/<camera>/<exposure>/<image>.png`: the folder it makes holds the
/// same images at the same exposures as the sequence they were laid out
/// from; a folder with an image missing is refused, naming it.
#[test]
fn import_brackets_makes_a_bracket_folder_of_a_dataset() {
    let config = SimConfig {
        scale: 0.125,
        ..SimConfig::preset("reference").unwrap()
    };
    let render = Arc::new(SimRender::new(&config).unwrap());
    let exported = tempfile::tempdir().unwrap();
    let spec = ExportSpec {
        frames: 3,
        levels: brackets::levels(8.0, 12.0, 3),
    };
    brackets::export(&render, &spec, exported.path(), &mut || {}).unwrap();
    let names: Vec<String> = render.cameras().iter().map(|c| c.name.clone()).collect();
    let manifest = brackets::read_manifest(exported.path(), &names).unwrap();

    // The dataset: one folder per camera and exposure (in ms, as datasets
    // name them), the moments' images in each.
    let src = tempfile::tempdir().unwrap();
    for (k, moment) in manifest.moments.iter().enumerate() {
        for (cam, images) in moment.cameras.iter().enumerate() {
            for image in images {
                let folder = src
                    .path()
                    .join(&names[cam])
                    .join(format!("{}ms", image.setting.exposure() / 1000.0));
                std::fs::create_dir_all(&folder).unwrap();
                std::fs::copy(&image.file, folder.join(format!("frame{k:04}.png"))).unwrap();
            }
        }
    }
    let rig = exported.path().join("rig.yaml");
    let stdout = common::rigview(
        &[
            "eval",
            "import-brackets",
            src.path().to_str().unwrap(),
            "--rig",
            rig.to_str().unwrap(),
            "--bits",
            "8",
        ],
        src.path(),
    );
    assert!(stdout.contains("3 moments × 4 cameras"), "{stdout}");
    let imported = brackets::read_manifest(src.path(), &names).unwrap();
    assert_eq!(imported.moments.len(), 3);
    for (a, b) in manifest.moments.iter().zip(&imported.moments) {
        for (ia, ib) in a.cameras.iter().zip(&b.cameras) {
            assert_eq!(ia.len(), 3);
            for (x, y) in ia.iter().zip(ib) {
                assert!((x.setting.exposure() / y.setting.exposure() - 1.0).abs() < 1e-6);
                let (dx, dy) = (
                    brackets::read_image(&manifest, x).unwrap(),
                    brackets::read_image(&imported, y).unwrap(),
                );
                assert_eq!(dx.data, dy.data);
            }
        }
    }
    // It runs as a bracket source.
    let out = exported.path().join("run-imported");
    let stdout = common::rigview(
        &[
            "run",
            "--headless",
            "--source",
            &format!("brackets:{}", src.path().display()),
            "--out",
            out.to_str().unwrap(),
        ],
        src.path(),
    );
    assert!(stdout.contains("3 processed"), "{stdout}");

    // One image fewer in one folder.
    let folder = src.path().join(&names[1]).join("1.024ms");
    std::fs::remove_file(folder.join("frame0002.png")).unwrap();
    let output = std::process::Command::new(env!("CARGO_BIN_EXE_rigview"))
        .args(["eval", "import-brackets", src.path().to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!output.status.success());
    let err = String::from_utf8_lossy(&output.stderr);
    assert!(err.contains("1.024ms") && err.contains("2 images"), "{err}");
}
