//! The evaluation's report: one self-contained HTML page (the figures
//! inlined as base64 PNG), with the headline figures, each experiment's
//! figure and what it shows, and the versions and settings used.

use std::fmt::Write as _;
use std::path::Path;

use anyhow::{Context, Result};
use base64::Engine as _;
use rigview_core::exposure::Simulation;
use rigview_core::sim::CameraAeParams;

use super::panorama_seams::PanoramaStats;
use super::steps::{goals, STEPS};
use super::strategy::EvalStrategy;
use super::{files, gamma, summary, Results};

/// Escapes text for HTML.
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

fn figure(out: &Path, file: &str, caption: &str) -> Result<String> {
    let path = out.join(file);
    let png = std::fs::read(&path).with_context(|| format!("reading {}", path.display()))?;
    let data = base64::engine::general_purpose::STANDARD.encode(png);
    Ok(format!(
        "<figure><img alt=\"{alt}\" src=\"data:image/png;base64,{data}\"><figcaption>{cap} \
         (<code>{file}</code>)</figcaption></figure>\n",
        alt = escape(caption),
        cap = escape(caption),
    ))
}

/// A number, or "–" when it is not finite.
fn num(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "–".into()
    }
}

const STYLE: &str = "body{font-family:sans-serif;max-width:1500px;margin:1em auto;padding:0 1em;color:#222}\
table{border-collapse:collapse;margin:0.5em 0 1.5em}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}\
th{background:#eee}td:first-child,th:first-child{text-align:left}img{max-width:100%;border:1px solid #ddd}\
figure{margin:1em 0}figcaption{color:#555;font-size:90%}.met{color:#080}.missed{color:#b00}\
.swatch{display:inline-block;width:0.9em;height:0.9em;margin-right:0.4em;vertical-align:middle}";

fn swatch(s: EvalStrategy) -> String {
    let c = s.colour();
    format!(
        "<span class=\"swatch\" style=\"background:rgb({},{},{})\"></span>{}",
        c.0,
        c.1,
        c.2,
        escape(s.label())
    )
}

/// Experiment 4's section for a rig without a surround view.
const NO_VIEW_SEAMS: &str = "<h2>4. Surround seams (Figs. 18, 19)</h2>\n<p>Not measured: the rig \
     is posed relative to one of its cameras (a Kalibr camchain), so its ground and the surround \
     view are not known. Its cameras were metered over their whole frames. <code>rigview calib \
     ground</code> poses such a rig on the ground (docs/calibration.md).</p>\n";

/// The headline of experiment 4: per strategy, over the scenarios.
fn seams_headline(r: &Results) -> String {
    let warmup = r.plan.seams.warmup;
    let mut h = String::from(
        "<h3>4. Surround seams: |log2 r_ij| (mean ± SD, EV), the seam step the view shows \
         (median, EV) and M as a fraction of each camera's best (mean, lowest)</h3>\n<table><tr>\
         <th>strategy</th><th>scenario</th><th>in the images</th><th>in the view</th>\
         <th>seam step</th><th>M / best</th></tr>\n",
    );
    for s in EvalStrategy::SEAMS {
        for run in r.seams.runs.iter().filter(|x| x.strategy == s) {
            let st = run.stats(warmup);
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{} ± {}</td><td>{} ± {}</td><td>{}</td>\
                 <td>{} % ({} %)</td></tr>",
                swatch(s),
                escape(&run.scenario),
                num(st.mean_images, 2),
                num(st.sd_images, 2),
                num(st.mean_view, 2),
                num(st.sd_view, 2),
                num(st.seam_step, 3),
                num(100.0 * st.m_mean, 1),
                num(100.0 * st.m_min, 1)
            );
        }
    }
    h += "</table>\n";
    // Does balancing keep more gradient information than evening out the
    // seams afterwards?
    let mean_over = |s: EvalStrategy, f: &dyn Fn(&super::seams::SeamStats) -> f64| {
        let v: Vec<f64> = r
            .seams
            .runs
            .iter()
            .filter(|x| x.strategy == s)
            .map(|x| f(&x.stats(warmup)))
            .collect();
        v.iter().sum::<f64>() / v.len().max(1) as f64
    };
    let (mb, ab) = (
        mean_over(EvalStrategy::MultiComp, &|x| x.m_mean),
        mean_over(EvalStrategy::CameraAeComp, &|x| x.m_mean),
    );
    let (sb, sa) = (
        mean_over(EvalStrategy::MultiComp, &|x| x.seam_step),
        mean_over(EvalStrategy::CameraAeComp, &|x| x.seam_step),
    );
    let _ = writeln!(
        h,
        "<p>Balancing with display gains against the built-in AE with display gains, over the \
         scenarios: M {} % against {} % of the best ({}), and a seam step of {} against {} EV.</p>",
        num(100.0 * mb, 1),
        num(100.0 * ab, 1),
        if mb > ab {
            "balancing keeps more gradient information"
        } else {
            "balancing keeps no more gradient information"
        },
        num(sb, 3),
        num(sa, 3)
    );
    h
}

/// Mean ± SD of `|log2 r_ij|`, or that no overlap gave a ratio.
/// From the start to rest on a bracket sequence, per strategy.
fn start_headline(r: &Results) -> String {
    let mut h = String::from(
        "<h3>From the start: frames to settle within 0.1 EV (median over cameras; cameras that \
         never settled), frames until M stays at 90 % of the best or more (largest over cameras; \
         cameras that never did), largest overshoot (EV), flicker at rest (mean and largest step \
         of log2 E from frame to frame, EV)</h3>\n<table><tr><th>strategy</th>\
         <th>frames to settle</th><th>never settled</th><th>frames to 90 % of the best M</th>\
         <th>never</th><th>overshoot</th><th>flicker, mean</th><th>flicker, largest</th></tr>\n",
    );
    for s in EvalStrategy::ALL {
        let rows: Vec<_> = r.start.iter().filter(|x| x.strategy == s).collect();
        if rows.is_empty() {
            continue;
        }
        let mut settle: Vec<f64> = rows
            .iter()
            .filter_map(|x| x.settle_frames)
            .map(|f| f as f64)
            .collect();
        let never = rows.len() - settle.len();
        let settle = crate::report::quantile(&mut settle, 0.5);
        let reach: Vec<usize> = rows.iter().filter_map(|x| x.reach_frames).collect();
        let never_reach = rows.len() - reach.len();
        let reach = reach.iter().max().map_or(f64::NAN, |&f| f as f64);
        let max = |f: fn(&super::start::StartRow) -> f64| {
            rows.iter()
                .map(|x| f(x))
                .filter(|v| v.is_finite())
                .fold(0.0, f64::max)
        };
        let flicker: Vec<f64> = rows
            .iter()
            .map(|x| x.flicker_mean_ev)
            .filter(|v| v.is_finite())
            .collect();
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{never}</td><td>{}</td><td>{never_reach}</td>\
             <td>{}</td><td>{}</td><td>{}</td></tr>",
            swatch(s),
            num(settle, 0),
            num(reach, 0),
            num(max(|x| x.overshoot_ev), 2),
            num(crate::report::mean(&flicker), 3),
            num(max(|x| x.flicker_max_ev), 3)
        );
    }
    h += "</table>\n";
    h
}

fn mean_sd(st: &PanoramaStats) -> String {
    if st.with_ratio == 0 {
        "no ratio".into()
    } else {
        format!("{} ± {}", num(st.mean, 2), num(st.sd, 2))
    }
}

/// The headline of experiment 5: a row per strategy, its mean ± SD per
/// scenario and over them, and its pairs × sets with and without a ratio.
fn panorama_headline(r: &Results) -> String {
    let pa = &r.panorama;
    let scenarios = &r.plan.panorama.scenarios;
    let mut h = String::from(
        "<h3>5. Panorama seams: |log2 r_ij| from matched patches (mean ± SD, EV), and the \
         overlaps × measured sets with a ratio and without one</h3>\n<table><tr><th>strategy</th>",
    );
    for sc in scenarios {
        let _ = write!(h, "<th>{}</th>", escape(sc));
    }
    h += "<th>all</th><th>with a ratio</th><th>too few matches</th><th>no usable patch</th></tr>\n";
    for s in EvalStrategy::PANORAMA {
        let _ = write!(h, "<tr><td>{}</td>", swatch(s));
        for sc in scenarios {
            let st = PanoramaStats::of(
                pa.runs
                    .iter()
                    .filter(|x| x.strategy == s && &x.scenario == sc),
            );
            let _ = write!(h, "<td>{}</td>", mean_sd(&st));
        }
        let st = PanoramaStats::of(pa.runs.iter().filter(|x| x.strategy == s));
        let _ = writeln!(
            h,
            "<td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
            mean_sd(&st),
            st.with_ratio,
            st.too_few,
            st.unusable
        );
    }
    h += "</table>\n<p>A pair without a ratio is counted, never given one: too few matches \
          (fewer RANSAC inliers than a rotation and its patches need), or no usable patch (every \
          patch around the inliers saturated or near black in either camera; \
          <code>fig5_panorama_pairs.csv</code> says which).</p>\n";
    h
}

/// The report's HTML; the figures are read from `out`.
pub fn report(r: &Results, out: &Path) -> Result<String> {
    let p = &r.plan;
    let mut h = String::new();
    let total: f64 = r.seconds.iter().map(|s| s.1).sum();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>rigview evaluation ({preset})</title><style>{STYLE}</style></head><body>\n\
         <h1>rigview evaluation</h1>\n<p>rigview {version}, preset <b>{preset}</b>, \
         {source}; {total:.0} s in all.</p>\n",
        source = escape(&r.source),
        version = env!("CARGO_PKG_VERSION"),
        preset = p.preset,
    );

    // Headline table.
    h += "<h2>Headline figures</h2>\n<h3>Summary: one row per strategy (· where an experiment \
          did not run it; the tables below break each figure down)</h3>\n<table><tr><th>strategy</th>";
    let (columns, rows) = summary::shown(r);
    for c in columns {
        let _ = write!(h, "<th>{}</th>", escape(c));
    }
    h += "</tr>\n";
    for (s, cells) in rows {
        let _ = write!(h, "<tr><td>{}</td>", swatch(s));
        for c in cells {
            let _ = write!(h, "<td>{}</td>", escape(&c));
        }
        h += "</tr>\n";
    }
    let _ = writeln!(
        h,
        "</table>\n<p>Steps of light: over every step and camera; M: over the cameras of {}; \
         seams: over the scenarios' overlaps after the warm-up (the panorama's: every overlap \
         with a ratio).</p>",
        escape(&p.sweep.presets.join(", "))
    );
    if !r.gamma.is_empty() {
        h += "<h3>1. γ̂ accuracy: median |γ̂ − γ*| (γ-equivalent)</h3>\n<table><tr><th>simulation</th>\
          <th>3 anchors</th><th>7 anchors</th><th>15 anchors</th><th>7 anchors, 1/4 resolution</th>\
          <th>7 anchors, 1/16 resolution</th></tr>\n";
        for sim in [Simulation::Gamma, Simulation::ScaleClip] {
            let a = |k: usize| {
                gamma::error_quantile(&r.gamma, 0.5, |g| {
                    g.series == "anchors" && g.simulation == sim && g.anchors == k
                })
            };
            let d = |d: usize| {
                gamma::error_quantile(&r.gamma, 0.5, |g| {
                    g.series == "resolution" && g.simulation == sim && g.divisor == d
                })
            };
            let _ = writeln!(
                h,
                "<tr><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td></tr>",
                super::sim_label(sim),
                num(a(3), 3),
                num(a(7), 3),
                num(a(15), 3),
                num(d(4), 3),
                num(d(16), 3)
            );
        }
        h += "</table>\n";
    }
    if !r.steps.rows.is_empty() {
        h += "<h3>2. Steps of light: frames to settle within 0.1 EV (median over cameras), largest overshoot and jitter</h3>\n\
          <table><tr><th>strategy</th>";
        let mut sorted_steps = STEPS.to_vec();
        sorted_steps.sort_by(f64::total_cmp);
        for s in &sorted_steps {
            let _ = write!(h, "<th>{s:+} stops</th>");
        }
        h += "<th>overshoot (EV)</th><th>jitter (EV)</th></tr>\n";
        for s in EvalStrategy::STEPS {
            let _ = write!(h, "<tr><td>{}</td>", swatch(s));
            let mut over = 0.0f64;
            let mut jitter = 0.0f64;
            for &stops in &sorted_steps {
                let v = r.steps.responses(s, stops);
                let mut f: Vec<f64> = v.iter().map(|x| x.settle_frames as f64).collect();
                over = v.iter().map(|x| x.overshoot_ev).fold(over, f64::max);
                jitter = v.iter().map(|x| x.jitter_ev).fold(jitter, f64::max);
                let _ = write!(
                    h,
                    "<td>{}</td>",
                    num(crate::report::quantile(&mut f, 0.5), 1)
                );
            }
            let _ = writeln!(
                h,
                "<td>{}</td><td>{}</td></tr>",
                num(over, 2),
                num(jitter, 3)
            );
        }
        h += "</table>\n";
        let (met, judged) = r.steps.goals_met();
        let _ = writeln!(
            h,
            "<p>The fast law's goals (settled within {} frames after ±2 stops and {} after ±4, \
         overshoot at most {} EV, jitter at most {} EV) are <span class=\"{}\">met by {met} of \
         its {judged} responses</span> to ±2 and ±4 stops (every camera, every step).</p>",
            goals::SETTLE_2,
            goals::SETTLE_4,
            goals::OVERSHOOT_EV,
            goals::JITTER_EV,
            if met == judged { "met" } else { "missed" }
        );
        h += "<table><tr><th>fast law: camera</th>";
        for s in &sorted_steps {
            let _ = write!(h, "<th>{s:+} stops</th>");
        }
        h += "</tr>\n";
        for cam in &r.steps.cameras {
            let _ = write!(h, "<tr><td>{}</td>", escape(cam));
            for &stops in &sorted_steps {
                let row = r.steps.rows.iter().find(|x| {
                    x.strategy == EvalStrategy::Fast
                        && &x.camera == cam
                        && (x.stops - stops).abs() < 1e-9
                });
                match row {
                    Some(x) => {
                        let class = match x.meets_goals() {
                            Some(true) => "met",
                            Some(false) => "missed",
                            None => "",
                        };
                        let _ = write!(
                            h,
                            "<td class=\"{class}\">{} fr / {:.2} / {:.3}</td>",
                            x.response.settle_frames, x.response.overshoot_ev, x.response.jitter_ev
                        );
                    }
                    None => h += "<td>–</td>",
                }
            }
            h += "</tr>\n";
        }
        h += "</table><p>Each cell: frames to settle / overshoot (EV) / jitter (EV); green: the goals are met, red: missed (±1 stop has no goal).</p>\n";
    }
    h += "<h3>3. Settled exposure: M as a fraction of each camera's best</h3>\n<table><tr><th>strategy</th>\
          <th>mean</th><th>lowest</th><th>mean gap to the best (EV)</th></tr>\n";
    for s in EvalStrategy::SETTLED {
        let v: Vec<&super::sweep::Settled> =
            r.sweep.settled.iter().filter(|x| x.strategy == s).collect();
        if v.is_empty() {
            continue;
        }
        let low = v.iter().map(|x| x.fraction).fold(f64::INFINITY, f64::min);
        let gap = v.iter().map(|x| x.log2_e - x.best_log2_e).sum::<f64>() / v.len().max(1) as f64;
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{} %</td><td>{} %</td><td>{}</td></tr>",
            swatch(s),
            num(100.0 * r.sweep.mean_fraction(s), 1),
            num(100.0 * low, 1),
            num(gap, 2)
        );
    }
    let _ = writeln!(
        h,
        "</table><p>Over the cameras of {}.</p>",
        escape(&p.sweep.presets.join(", "))
    );

    if !r.start.is_empty() {
        h += &start_headline(r);
    }
    if !r.seams.runs.is_empty() {
        h += &seams_headline(r);
    }
    if !r.panorama.runs.is_empty() {
        h += &panorama_headline(r);
    }

    // The experiments.
    if !r.gamma.is_empty() {
        h += "<h2>1. γ̂ accuracy (Fig. 7)</h2>\n<p>For each camera (noise-free renders of the scenario's \
          first moment) at exposures around its best, γ̂ against γ*, the best of a dense search over the \
          anchors' span (1/1.9 to 1.9) on the image at full resolution. Left: k anchors log-spaced over \
          the span, a polynomial of order min(5, k − 1), full resolution. Right: 7 anchors on the image \
          metered at a fraction of its width and height. Scale-and-clip's ŝ is shown as its \
          γ-equivalent 1/ŝ.</p>\n";
        h += &figure(
            out,
            files::GAMMA_PNG,
            "|γ̂ − γ*| against the anchors and the metered resolution",
        )?;
    }
    if !r.steps.rows.is_empty() {
        h += "<h2>2. Convergence after steps of light (Fig. 9)</h2>\n<p>The light steps by +1, −1, +2, −2, \
          +4 and −4 stops (grey lines); one frame of actuation latency, a command every frame, each \
          camera alone except the built-in AE, which runs in the simulated cameras (rigview only \
          watches). Settled: within 0.1 EV of the exposure 30 frames after the step; jitter: the \
          standard deviation of log2 E over the last 20 of those frames.</p>\n";
        h += &figure(
            out,
            files::STEPS_TRACE_PNG,
            "log2 E of every camera under every strategy",
        )?;
        h += &figure(
            out,
            files::STEPS_PNG,
            "frames to settle, overshoot and jitter per step",
        )?;
    }
    h += "<h2>3. M against exposure (Fig. 11)</h2>\n<p>The dense sweep of M over exposure for each camera \
          of each preset (noise-free, the ground the surround view shows metered as the controller \
          meters it), with the exposure each strategy settles at (the median of the last frames of a \
          closed loop in the preset's constant light).</p>\n";
    h += &figure(
        out,
        files::SWEEP_PNG,
        "M(E) per camera and preset, with each strategy's settled exposure",
    )?;
    if !r.sweep.stereo_views.is_empty() {
        h += "<p>Each stereo pair of the rig (two cameras side by side), rectified through its \
              lens models, and the disparities OpenCV's <code>StereoSGBM</code> finds where a few \
              strategies settled (the last set measured): the share of valid disparities is in the \
              summary and <code>fig3_stereo.csv</code>.</p>\n";
        h += &figure(
            out,
            files::STEREO_PNG,
            "stereo pairs, rectified, with their disparities",
        )?;
    }
    if r.seams.runs.is_empty() {
        h += NO_VIEW_SEAMS;
    } else {
        h += "<h2>4. Surround seams (Figs. 18, 19)</h2>\n<p>Each scenario under each strategy, the view \
              composed every set (display gains only where the strategy has them). The histograms hold \
              log2 r_ij of every overlap and set after the warm-up, as the view shows it (the display \
              gains applied); the profiles follow the last view along a circle around the car that \
              crosses every seam (grey lines).</p>\n";
        h += &figure(
            out,
            files::HIST_PNG,
            "histograms of log2 r_ij per scenario and strategy",
        )?;
        h += &figure(
            out,
            files::PROFILE_PNG,
            "intensity profiles across the seams",
        )?;
    }
    h += "<h2>5. Panorama seams</h2>\n";
    if r.panorama.runs.is_empty() {
        h += "<p>Not measured here: the panorama's closed loop runs on the simulated rig only.</p>\n";
    } else {
        let pp = &r.plan.panorama;
        let _ = writeln!(
            h,
            "<p>Each scenario under each strategy that sets its own exposures, in closed loop with \
             the cylindrical panorama ({w}×{hh} pixels) as the view: every pixel that reaches the \
             cylinder metered, the balancing's ratios from the panorama's matching (Harris corners, \
             BRIEF, RANSAC on each pair's rotation, 15×15 patches around the inliers) every {every} \
             sets. Measured on every {every}th set after the first {warmup}: a matching of that set \
             of its own; each overlap gives log2 r_ij (the median ratio of its usable patches, in \
             the cameras' images) or none, counted by why (too few matches for RANSAC, or every \
             patch saturated or near black). The display gains change no image and are left out.</p>",
            w = pp.canvas.0,
            hh = pp.canvas.1,
            every = pp.match_every,
            warmup = pp.warmup,
        );
        h += &figure(
            out,
            files::PANORAMA_HIST_PNG,
            "histograms of log2 r_ij from matched patches per scenario and strategy",
        )?;
    }
    if r.seams.runs.is_empty() {
        h += "<h2>6. Visual comparison</h2>\n<p>Not shown: no surround view (above).</p>\n";
    } else {
        h += "<h2>6. Visual comparison</h2>\n<p>The last view of each scenario under each \
              strategy (the exposures it was taken with: <code>fig6_views.csv</code>).</p>\n";
        h += &figure(out, files::VIEWS_PNG, "the bird's-eye views side by side")?;
    }

    // Settings.
    let ae = CameraAeParams::default();
    let law = rigview_core::exposure::LawParams::default();
    let _ = write!(
        h,
        "<h2>Versions and settings</h2>\n<table>\
         <tr><td>rigview</td><td>{version}</td></tr>\
         <tr><td>preset</td><td>{preset}</td></tr>\
         <tr><td>what the preset reduces</td><td>{reduced}</td></tr>\
         <tr><td>render scale</td><td>{scale}</td></tr>\
         <tr><td>scenario of experiments 1 and 2</td><td>{scenario}</td></tr>\
         <tr><td>presets of experiment 3</td><td>{presets}</td></tr>\
         <tr><td>exposure simulation of the closed loops</td><td>γ-mapping, probes off</td></tr>\
         <tr><td>update laws</td><td>K<sub>p</sub> = {kp}, d = {d}, fast law β = {beta}, at most ×{max_step} per frame</td></tr>\
         <tr><td>simulated built-in AE</td><td>target {target} mean grey over the whole image, {damp} of the error per frame, at most {rate} EV per frame, dead band {band} EV, shutter up to {shutter} µs before gain</td></tr>\
         </table>\n<table><tr><th>experiment</th><th>seconds</th></tr>",
        version = env!("CARGO_PKG_VERSION"),
        preset = p.preset,
        reduced = escape(&p.reduced),
        scale = p.scale,
        scenario = escape(&p.scenario),
        presets = escape(&p.sweep.presets.join(", ")),
        kp = law.kp,
        d = law.d,
        beta = law.damping,
        max_step = law.max_step,
        target = ae.target,
        damp = ae.damping,
        rate = ae.max_step_ev,
        band = ae.dead_band_ev,
        shutter = ae.max_shutter_us,
    );
    for (what, s) in &r.seconds {
        let _ = write!(h, "<tr><td>{}</td><td>{s:.1}</td></tr>", escape(what));
    }
    let _ = writeln!(h, "<tr><td>in all</td><td>{total:.1}</td></tr></table>");
    h += "<p>Data: ";
    for f in files::ALL.iter().filter(|f| f.ends_with(".csv")) {
        let _ = write!(h, "<a href=\"{f}\">{f}</a> ");
    }
    if !r.sweep.stereo.is_empty() {
        let f = files::STEREO_CSV;
        let _ = write!(h, "<a href=\"{f}\">{f}</a> ");
    }
    h += "</p>\n</body></html>\n";
    Ok(h)
}
