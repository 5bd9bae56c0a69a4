//! The panorama in the app: Harris corners through OpenCV (the detector
//! `rigview_core::panorama` takes), the per-pair report, and still images
//! composed into a panorama (`rigview panorama`).

use std::io::Write;

use anyhow::{Context, Result};
use rigview_calib::formats;
use rigview_calib::rig::Rig;
use rigview_calib::tools::corners::{harris_corners, HarrisParams};
use rigview_core::exposure::balance::pair_ratio;
use rigview_core::exposure::BalanceParams;
use rigview_core::panorama::{
    refine_in_rounds, MatchOptions, MatchTimes, PairMatches, Panorama, PanoramaOptions,
    RefineOptions, RoundsOptions, MATCH_WIDTH,
};
use rigview_core::pipeline::{Output, PairMatchRow};
use rigview_core::surround::{Canvas, Composer};

use crate::cli::panorama::PanoramaArgs;
use crate::stills;

/// Harris corners through OpenCV with the default spread, as the
/// panorama's matching asks for them, at positions refined to a fraction
/// of a pixel (the refinement of the rotations needs them).
pub fn detect(gray: &[u8], w: usize, h: usize, mask: &[u8]) -> rigview_core::Result<Vec<[f32; 2]>> {
    let params = HarrisParams {
        subpixel: true,
        ..HarrisParams::default()
    };
    harris_corners(gray, w, h, Some(mask), &params)
        .map_err(|e| rigview_core::Error::InvalidConfig(format!("Harris corners: {e}")))
}

/// [`detect`] as the live panorama's detector.
pub fn shared_detector() -> rigview_core::pipeline::SharedDetector {
    std::sync::Arc::new(detect)
}

/// One line per pair: corners, matches, inliers, the median error before
/// and after the pair's rotation, and r_ij, or why there is none.
pub fn pair_lines(rig: &Rig, pairs: &[PairMatches], params: &BalanceParams) -> Vec<String> {
    pairs
        .iter()
        .map(|p| {
            let (a, b) = (&rig.cameras[p.i].name, &rig.cameras[p.j].name);
            let head = format!(
                "pair {a}–{b}: {} + {} corners, {} matches, {} inliers",
                p.corners.0,
                p.corners.1,
                p.matches.len(),
                p.inliers
            );
            if let Some(problem) = &p.problem {
                return format!("{head}; no rotation and no brightness ratio: {problem}");
            }
            let error = match (p.error_before_px, p.error_after_px, p.rotation) {
                (Some(e0), Some(e1), Some(q)) => format!(
                    ", median error {e0:.2} px, {e1:.2} px after turning `{b}` by {:.3}°",
                    q.angle().to_degrees()
                ),
                _ => String::new(),
            };
            match pair_ratio(&p.patches, params) {
                Some(r) => format!(
                    "{head}{error}, brightness {b}/{a} = {r:.3} ({:+.2} EV) from {} patches",
                    r.log2(),
                    p.patches.len()
                ),
                None => format!(
                    "{head}{error}; no brightness ratio: none of the {} patches is usable (saturated or near black)",
                    p.patches.len()
                ),
            }
        })
        .collect()
}

/// The live panorama's state in `output`, a line per overlap: matches,
/// inliers, the median reprojection error (before and after the latest
/// refinement) and r_ij, or why there is none. Empty without a panorama.
pub fn live_lines(names: &[String], output: &Output) -> Vec<String> {
    let Some(report) = &output.panorama else {
        return Vec::new();
    };
    let name = |k: usize| {
        names
            .get(k)
            .cloned()
            .unwrap_or_else(|| format!("camera{k}"))
    };
    let mut lines = vec![match report.matched_trigger {
        Some(t) => format!(
            "panorama: matched on set {t} in {:.0} ms, {} refinements (the latest with the rebuild {:.0} ms){}",
            report.match_ms,
            report.refinements,
            report.refine_ms,
            report
                .problem
                .as_deref()
                .map(|p| format!("; {p}"))
                .unwrap_or_default()
        ),
        None => "panorama: not matched yet".into(),
    }];
    for p in &output.pairs {
        let Some(m) = report.pair(p.i, p.j) else {
            continue;
        };
        let row = PairMatchRow::of(m, p.log2_r);
        let mut line = format!(
            "pair {}–{}: {} matches, {} inliers, median reprojection error {}",
            name(p.i),
            name(p.j),
            row.matches,
            row.inliers,
            px(row.error_px)
        );
        if row.refined_before_px.is_some() {
            line += &format!(
                " (refined: {} before, {} after)",
                px(row.refined_before_px),
                px(row.refined_after_px)
            );
        }
        match (p.log2_r, row.no_ratio) {
            (Some(l), _) => line += &format!(", r = {:.3} ({l:+.2} EV)", l.exp2()),
            (None, Some(why)) => line += &format!("; no ratio: {why}"),
            (None, None) => {}
        }
        lines.push(line);
    }
    lines
}

/// The time split of the matching, as a line.
pub fn times_line(t: &MatchTimes) -> String {
    let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
    format!(
        "matching: warp {:.1} ms, detect {:.1} ms, describe {:.1} ms, match {:.1} ms, RANSAC and patches {:.1} ms",
        ms(t.warp),
        ms(t.detect),
        ms(t.describe),
        ms(t.matching),
        ms(t.ransac)
    )
}

/// Draws each pair's matches on an RGB canvas: a line from camera `i`'s
/// corner to camera `j`'s, green for inliers and red for outliers, and a
/// dot at `i`'s corner.
pub fn draw_matches(canvas: &mut Canvas, pairs: &[PairMatches]) {
    let (w, h) = (canvas.width, canvas.height);
    let mut put = |x: f64, y: f64, rgb: [u8; 3]| {
        if x >= 0.0 && y >= 0.0 && (x as usize) < w && (y as usize) < h && canvas.channels == 3 {
            let i = 3 * (y as usize * w + x as usize);
            canvas.data[i..i + 3].copy_from_slice(&rgb);
        }
    };
    for p in pairs {
        for m in &p.matches {
            let rgb = if m.inlier { [0, 255, 0] } else { [255, 0, 0] };
            let [x0, y0] = m.at_i;
            let [x1, y1] = m.at_j;
            let steps = (x1 - x0).abs().max((y1 - y0).abs()).ceil().max(1.0) as usize;
            if steps > w / 2 {
                continue;
            }
            for s in 0..=steps {
                let t = s as f64 / steps as f64;
                put(x0 + t * (x1 - x0), y0 + t * (y1 - y0), rgb);
            }
            for dy in -1..=1 {
                for dx in -1..=1 {
                    put(x0 + f64::from(dx), y0 + f64::from(dy), rgb);
                }
            }
        }
    }
}

/// A reprojection error in pixels, or "-" without one.
fn px(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2} px"))
}

/// `rigview panorama`: composes the images, writes the panorama, and
/// reports each pair's matches and brightness ratio.
pub fn run_stills(args: &PanoramaArgs, out: &mut dyn Write) -> Result<()> {
    let (mut rig, images) = stills::load(&args.input.rig, &args.input.images)?;
    let mut pano = Panorama::build(&rig, &args.spec(), &PanoramaOptions::default())
        .context("building the panorama")?;
    let frames = stills::frames(&images)?;
    let (mut pairs, times) = pano
        .match_pairs(&frames, &detect, &MatchOptions::default())
        .context("matching features in the overlaps")?;
    for line in pair_lines(&rig, &pairs, &BalanceParams::default()) {
        writeln!(out, "{line}")?;
    }
    writeln!(out, "{}", times_line(&times))?;
    if args.refine {
        let options = RoundsOptions {
            rounds: args.rounds,
            refine: RefineOptions {
                bound_deg: args.refine_bound_deg,
                ..RefineOptions::default()
            },
            ..RoundsOptions::default()
        };
        let refined = refine_in_rounds(
            &rig,
            &args.spec(),
            &PanoramaOptions::default(),
            &frames,
            &detect,
            &options,
        )
        .context("refining the cameras' rotations")?;
        for (k, (matches, r)) in refined.rounds.iter().enumerate() {
            let inliers: usize = matches.iter().map(|p| p.inliers).sum();
            let on_ground: usize = r.pairs.iter().map(|p| p.on_ground).sum();
            writeln!(
                out,
                "refinement round {}: {inliers} inliers matched, {} refined from ({on_ground} on the ground)",
                k + 1,
                r.pairs.iter().map(|p| p.inliers).sum::<usize>()
            )?;
        }
        for &(i, j, before, after) in &refined.errors {
            writeln!(
                out,
                "refined pair {}–{}: median reprojection error {} before, {} after (on the {}-column matching cylinder)",
                rig.cameras[i].name,
                rig.cameras[j].name,
                px(before),
                px(after),
                MATCH_WIDTH
            )?;
        }
        if let Some(why) = &refined.stopped {
            writeln!(out, "refinement stopped: {why}")?;
        }
        for (cam, q) in rig.cameras.iter().zip(&refined.rotations) {
            writeln!(
                out,
                "refined {}: turned by {:.3}°",
                cam.name,
                q.angle().to_degrees()
            )?;
        }
        rig = refined.rig;
        pano = Panorama::build(&rig, &args.spec(), &PanoramaOptions::default())
            .context("building the refined panorama")?;
        pairs = pano
            .match_pairs(&frames, &detect, &MatchOptions::default())
            .context("matching features with the refined rotations")?
            .0;
        if let Some(path) = &args.save_rig {
            let written = formats::save(&rig, path, None)
                .with_context(|| format!("saving the refined rig to {}", path.display()))?;
            for p in written {
                writeln!(out, "wrote the refined rig to {}", p.display())?;
            }
        }
    }
    let mut canvas = Canvas::new(0, 0, 3);
    Composer::new().compose(&pano, &frames, args.input.blend, &mut canvas)?;
    stills::save(&canvas, &args.out)?;
    let spec = pano.spec();
    writeln!(
        out,
        "wrote {} ({}×{} px, radius {} m, {}° below to {}° above the horizon, {} blending)",
        args.out.display(),
        canvas.width,
        canvas.height,
        spec.radius_m,
        spec.below_deg,
        spec.above_deg,
        args.input.blend.name()
    )?;
    for (cam, mask) in rig.cameras.iter().zip(pano.source_masks()) {
        writeln!(
            out,
            "{}: {:.1} % of the image reaches the panorama",
            cam.name,
            100.0 * mask.coverage()
        )?;
    }
    if let Some(path) = &args.matches_out {
        draw_matches(&mut canvas, &pairs);
        stills::save(&canvas, path)?;
        writeln!(
            out,
            "wrote the matches over the panorama to {}",
            path.display()
        )?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use clap::Parser;

    use super::*;
    use crate::cli::{Cli, Command};

    fn data() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../tests/data/surround-nz")
    }

    fn args(extra: &[&str]) -> PanoramaArgs {
        let d = data();
        let mut argv: Vec<String> = vec!["rigview".into(), "panorama".into(), "--rig".into()];
        argv.push(d.display().to_string());
        argv.push("--images".into());
        for n in ["front", "left", "back", "right"] {
            argv.push(format!("{n}={}", d.join(format!("{n}.png")).display()));
        }
        argv.extend(extra.iter().map(|s| s.to_string()));
        match Cli::try_parse_from(argv).unwrap().command {
            Some(Command::Panorama(a)) => a,
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn composes_the_real_rig_and_reports_every_pair() {
        let dir = std::env::temp_dir().join(format!("rigview-panorama-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let (png, overlay) = (dir.join("pano.png"), dir.join("matches.png"));
        let rig_out = dir.join("refined.rig.yaml");
        let a = args(&[
            "--out",
            png.to_str().unwrap(),
            "--matches-out",
            overlay.to_str().unwrap(),
            "--width",
            "2048",
            "--height",
            "380",
            "--blend",
            "seams",
            "--radius-m",
            "8",
            "--refine",
            "--save-rig",
            rig_out.to_str().unwrap(),
        ]);
        let mut report = Vec::new();
        run_stills(&a, &mut report).unwrap();
        let report = String::from_utf8(report).unwrap();
        println!("{report}");
        for pair in ["front–left", "front–right", "back–left", "back–right"] {
            // The rig file's neighbour order, either way round.
            let (x, y) = pair.split_once('–').unwrap();
            assert!(
                report.contains(&format!("pair {x}–{y}"))
                    || report.contains(&format!("pair {y}–{x}")),
                "{pair}: {report}"
            );
        }
        assert!(report.contains("radius 8 m"), "{report}");
        assert!(report.contains("refined pair front–left"), "{report}");
        // The refined rig reads back, every camera within the bound.
        let refined = formats::load(&rig_out, None, None).unwrap().rig;
        let original = formats::load(&data(), None, None).unwrap().rig;
        let turn = |k: usize| {
            original.cameras[k]
                .pose
                .unwrap()
                .rotation_angle_to(&refined.cameras[k].pose.unwrap())
                .to_degrees()
        };
        assert!((0..4).all(|k| turn(k) <= 3.0 + 1e-6));
        assert!((0..4).any(|k| turn(k) > 0.0));
        for p in [&png, &overlay] {
            let img = image::open(p).unwrap();
            assert_eq!((img.width(), img.height()), (2048, 380));
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_wrong_image_size_names_the_file_and_the_camera() {
        let d = data();
        let mut a = args(&["--out", "/nonexistent/never.png"]);
        a.input.images[1] = format!("left={}", d.join("car.png").display());
        let e = run_stills(&a, &mut Vec::new()).unwrap_err();
        let e = format!("{e:#}");
        assert!(e.contains("car.png") && e.contains("camera `left`"), "{e}");
    }
}
