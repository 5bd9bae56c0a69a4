//! The panorama's report: one line per overlap (matches, inliers, the
//! epipolar error before and after refinement, r_ij or why there is none),
//! the matching's times, and the matches drawn over the panorama. The
//! window, `rigview run --headless` and `rigview panorama` print these.

use rigview_calib::rig::Rig;
use rigview_core::exposure::balance::pair_ratio;
use rigview_core::exposure::BalanceParams;
use rigview_core::panorama::{MatchTimes, PairMatches};
use rigview_core::pipeline::{Output, PairMatchRow};
use rigview_core::surround::Canvas;

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
pub fn px(v: Option<f64>) -> String {
    v.map_or("-".into(), |v| format!("{v:.2} px"))
}
