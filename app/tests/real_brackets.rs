#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! The live pipeline on real frames: the four fisheye frames of a real car
//! rig (`tests/data/surround-nz`, MIT) as a bracket sequence of one image a
//! camera (grey, at 2 ms), every command answered by emulation from it.
//! One bracket of 8-bit frames is not a scene's radiance (the clipped
//! pixels stay clipped at any exposure), so this checks what an operator
//! sees on real textures, not where the controller ends: under balancing
//! no camera circles by more than a tenth of a stop, and the bird's-eye
//! view, display gains applied, keeps its 90th percentile under 0.95 and
//! shows less near white than the frames hold.

mod common;

use std::path::Path;

use common::{csv, rigview};

const CAMERAS: [&str; 4] = ["front", "left", "back", "right"];
/// Moments of the sequence, and those whose exposures are compared.
const MOMENTS: usize = 80;
const TAIL: usize = 30;

/// Near white: at or above this byte.
const WHITE: u8 = 250;

/// Writes the bracket folder (grey frames, the manifest, the rig); returns
/// the frames' share of near-white pixels.
fn real_folder(dir: &Path) -> f64 {
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz");
    let (mut white, mut all) = (0usize, 0usize);
    for cam in CAMERAS {
        let grey = image::open(data.join(format!("{cam}.png")))
            .unwrap()
            .to_luma8();
        white += grey.pixels().filter(|p| p.0[0] >= WHITE).count();
        all += grey.len();
        grey.save(dir.join(format!("{cam}.png"))).unwrap();
    }
    let mut manifest =
        String::from("# response: linear\ncamera,moment,time_s,exposure_us,gain_db,file\n");
    for m in 0..MOMENTS {
        for cam in CAMERAS {
            manifest += &format!("{cam},{m},{:.6},2000,0,{cam}.png\n", m as f64 * 0.05);
        }
    }
    std::fs::write(dir.join("brackets.csv"), manifest).unwrap();
    rigview(
        &[
            "calib",
            "convert",
            data.to_str().unwrap(),
            dir.join("rig.yaml").to_str().unwrap(),
        ],
        dir,
    );
    white as f64 / all as f64
}

#[test]
fn real_frames_under_balancing_neither_circle_nor_whiten_the_view() {
    let dir = tempfile::tempdir().unwrap();
    let seq = dir.path().join("seq");
    std::fs::create_dir_all(&seq).unwrap();
    let frames_white = real_folder(&seq);
    let out = dir.path().join("out");
    let source = format!("brackets:{}", seq.display());
    rigview(
        &[
            "run",
            "--headless",
            "--source",
            &source,
            "--strategy",
            "multi",
            "--frames",
            &MOMENTS.to_string(),
            "--every",
            "1000",
            "--out",
            out.to_str().unwrap(),
        ],
        dir.path(),
    );
    let (header, rows) = csv(&out.join("telemetry.csv"));
    assert_eq!(rows.len(), MOMENTS);
    let col = |name: &str| header.iter().position(|h| h == name).unwrap();
    for cam in CAMERAS {
        let (e, probe) = (
            col(&format!("{cam}.exposure")),
            col(&format!("{cam}.probe")),
        );
        // A probe's frame is darker on purpose for one frame.
        let tail: Vec<f64> = rows[MOMENTS - TAIL..]
            .iter()
            .filter(|r| r[probe] == "0")
            .map(|r| r[e].parse::<f64>().unwrap().log2())
            .collect();
        assert!(
            tail.len() >= TAIL - 4,
            "{cam}: {} probes",
            TAIL - tail.len()
        );
        let lo = tail.iter().copied().fold(f64::INFINITY, f64::min);
        let hi = tail.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let gamma: Vec<f64> = rows[MOMENTS - TAIL..]
            .iter()
            .filter_map(|r| r[col(&format!("{cam}.gamma_hat"))].parse().ok())
            .collect();
        println!(
            "{cam}: last {TAIL} exposures 2^{lo:.3}..2^{hi:.3} µs ({:.3} EV), γ̂ {:.2}..{:.2}, {} probes",
            hi - lo,
            gamma.iter().copied().fold(f64::INFINITY, f64::min),
            gamma.iter().copied().fold(f64::NEG_INFINITY, f64::max),
            TAIL - tail.len()
        );
        assert!(hi - lo <= 0.1, "{cam} circles over {:.3} EV", hi - lo);
    }
    // The last view, as the window shows it (display gains applied).
    let view = std::fs::read_dir(out.join("views"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .max()
        .unwrap();
    let canvas = image::open(&view).unwrap().to_luma8();
    let mut lit: Vec<u8> = canvas.pixels().map(|p| p.0[0]).filter(|&v| v > 0).collect();
    let white = lit.iter().filter(|&&v| v >= WHITE).count() as f64 / lit.len() as f64;
    let mean = lit.iter().map(|&v| f64::from(v)).sum::<f64>() / lit.len() as f64;
    lit.sort_unstable();
    let pct = |q: f64| lit[((lit.len() - 1) as f64 * q) as usize];
    println!(
        "view {}: mean {mean:.1}, 90th percentile {}, 99th {}; {:.2} % of the shown pixels near white, against {:.2} % of the frames' pixels",
        view.display(),
        pct(0.9),
        pct(0.99),
        100.0 * white,
        100.0 * frames_white
    );
    assert!(lit.len() > canvas.len() / 2, "most of the canvas is shown");
    // The display gains keep the 90th percentile at or below 0.95 (they
    // move down together rather than wash a camera out), and the view
    // shows less near white than the frames themselves hold (their white
    // calibration mat clips in the camera).
    assert!(pct(0.9) <= 242, "90th percentile {}", pct(0.9));
    assert!(
        white < frames_white,
        "{:.2} % near white in the view, {:.2} % in the frames",
        100.0 * white,
        100.0 * frames_white
    );
    assert!((90.0..200.0).contains(&mean), "mean {mean:.1}");
}
