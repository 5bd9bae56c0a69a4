#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! `rigview eval --preset quick`: every figure, its data and the report
//! are written, and what they say holds together: the CSVs have their
//! columns and rows, the numbers are finite and in range, the figures
//! agree across files (each sweep's best is the best of its own rows),
//! and the strategies follow the light where they must.

mod common;

use std::collections::HashMap;
use std::path::Path;

use common::{csv, rigview};

const STRATEGIES_STEPS: [&str; 10] = [
    "linear",
    "nonlinear",
    "fast",
    "pid",
    "linear/scale-clip",
    "nonlinear/scale-clip",
    "fast/scale-clip",
    "pid/scale-clip",
    "mean",
    "camera-ae",
];
const STRATEGIES_SETTLED: [&str; 12] = [
    "linear",
    "nonlinear",
    "fast",
    "multi",
    "pid",
    "linear/scale-clip",
    "nonlinear/scale-clip",
    "fast/scale-clip",
    "multi/scale-clip",
    "pid/scale-clip",
    "mean",
    "camera-ae",
];
const CAMERAS: usize = 4;

fn col(header: &[String], name: &str) -> usize {
    header
        .iter()
        .position(|h| h == name)
        .unwrap_or_else(|| panic!("no column {name} in {header:?}"))
}

fn num(s: &str) -> f64 {
    let v: f64 = s.parse().unwrap_or_else(|_| panic!("not a number: {s}"));
    assert!(v.is_finite(), "not finite: {s}");
    v
}

fn png(path: &Path) -> image::RgbImage {
    let img = image::open(path).unwrap().to_rgb8();
    let (w, h) = img.dimensions();
    assert!(w >= 400 && h >= 300, "{}: {w}×{h}", path.display());
    // Not blank: dark pixels (axes, labels, lines) and white ones.
    let dark = img
        .pixels()
        .filter(|p| p.0.iter().all(|&c| c < 100))
        .count();
    let white = img
        .pixels()
        .filter(|p| p.0.iter().all(|&c| c == 255))
        .count();
    assert!(
        dark > 500 && white > (w * h / 4) as usize,
        "{}",
        path.display()
    );
    img
}

#[test]
fn the_quick_evaluation_writes_sane_figures_data_and_report() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("eval");
    let stdout = rigview(
        &["eval", "--preset", "quick", "--out", out.to_str().unwrap()],
        dir.path(),
    );
    assert!(stdout.contains("report.html"), "{stdout}");
    for f in rigview::eval::files::ALL {
        assert!(out.join(f).is_file(), "{f} missing");
    }
    for f in rigview::eval::files::ALL
        .iter()
        .filter(|f| f.ends_with(".png"))
    {
        png(&out.join(f));
    }

    // Experiment 1: 2 simulations × 4 cameras × 5 exposures × (13 anchor
    // counts + 5 resolutions).
    let (h, rows) = csv(&out.join(rigview::eval::files::GAMMA_CSV));
    assert_eq!(rows.len(), 2 * CAMERAS * 5 * (13 + 5), "{h:?}");
    let (g, gd, err) = (
        col(&h, "gamma_hat"),
        col(&h, "gamma_dense"),
        col(&h, "abs_error"),
    );
    for r in &rows {
        assert_eq!(r.len(), h.len());
        let (gh, gs, e) = (num(&r[g]), num(&r[gd]), num(&r[err]));
        assert!((e - (gh - gs).abs()).abs() < 1e-4, "{r:?}");
        assert!((1.0 / 1.9 - 1e-6..=1.9 + 1e-6).contains(&gs), "{r:?}");
    }
    let median = |keep: &dyn Fn(&Vec<String>) -> bool| {
        let mut v: Vec<f64> = rows
            .iter()
            .filter(|r| keep(r))
            .map(|r| num(&r[err]))
            .collect();
        assert!(!v.is_empty());
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let (series, anchors, divisor, sim) = (
        col(&h, "series"),
        col(&h, "anchors"),
        col(&h, "divisor"),
        col(&h, "simulation"),
    );
    for s in ["gamma", "scale-clip"] {
        let at = |k: &str| {
            median(&|r: &Vec<String>| r[series] == "anchors" && r[sim] == s && r[anchors] == k)
        };
        let res = |d: &str| {
            median(&|r: &Vec<String>| r[series] == "resolution" && r[sim] == s && r[divisor] == d)
        };
        // Seven anchors at full resolution find the dense search's best
        // closely, and no worse than the coarsest metering.
        assert!(at("7") < 0.1, "{s}: median error at 7 anchors {}", at("7"));
        assert!(
            res("1") <= res("16") + 1e-9,
            "{s}: {} vs {}",
            res("1"),
            res("16")
        );
    }

    // Experiment 2: every strategy, camera and step; the light's steps
    // move every camera the other way.
    let (h, rows) = csv(&out.join(rigview::eval::files::STEPS_CSV));
    assert_eq!(rows.len(), STRATEGIES_STEPS.len() * CAMERAS * 6);
    let (st, stops, start, end, settle, over, jit) = (
        col(&h, "strategy"),
        col(&h, "step_stops"),
        col(&h, "start_log2_e"),
        col(&h, "end_log2_e"),
        col(&h, "settle_frames"),
        col(&h, "overshoot_ev"),
        col(&h, "jitter_ev"),
    );
    for r in &rows {
        assert!(STRATEGIES_STEPS.contains(&r[st].as_str()), "{r:?}");
        let moved = num(&r[end]) - num(&r[start]);
        let s = num(&r[stops]);
        assert!(num(&r[settle]) <= 30.0 && num(&r[over]) >= 0.0 && num(&r[jit]) >= 0.0);
        // A mean-intensity loop on a linear sensor follows the light: a
        // step of k stops moves it by about −k EV, less where saturated
        // or black pixels do not follow (the built-in AE meters the whole
        // image, the vehicle and the black corners included). No law
        // moves the camera further than the light moved.
        let follows = -moved / s;
        match r[st].as_str() {
            "mean" => assert!((0.8..=1.1).contains(&follows), "{r:?}: {follows:.2}"),
            "camera-ae" => assert!((0.6..=1.1).contains(&follows), "{r:?}: {follows:.2}"),
            "linear" | "nonlinear" | "fast" => assert!(follows <= 1.1, "{r:?}: {follows:.2}"),
            _ => {}
        }
    }
    let (h, rows) = csv(&out.join(rigview::eval::files::STEPS_TRACE_CSV));
    assert_eq!(h.len(), 3 + CAMERAS);
    assert_eq!(rows.len() % STRATEGIES_STEPS.len(), 0);

    // Experiment 3: the sweeps, and where each strategy settled on them.
    let (h, rows) = csv(&out.join(rigview::eval::files::SWEEP_CSV));
    let (p, c, e, m) = (
        col(&h, "preset"),
        col(&h, "camera"),
        col(&h, "log2_e"),
        col(&h, "m"),
    );
    let mut best: HashMap<(String, String), (f64, f64)> = HashMap::new();
    for r in &rows {
        let (le, mv) = (num(&r[e]), num(&r[m]));
        assert!(mv >= 0.0);
        let b = best
            .entry((r[p].clone(), r[c].clone()))
            .or_insert((le, f64::MIN));
        if mv > b.1 {
            *b = (le, mv);
        }
    }
    assert_eq!(best.len(), 3 * CAMERAS, "three presets of four cameras");
    assert_eq!(rows.len(), best.len() * 53);
    let (h, rows) = csv(&out.join(rigview::eval::files::SETTLED_CSV));
    assert_eq!(rows.len(), 3 * CAMERAS * STRATEGIES_SETTLED.len());
    let (p, c, s, f, b) = (
        col(&h, "preset"),
        col(&h, "camera"),
        col(&h, "strategy"),
        col(&h, "m_fraction_of_best"),
        col(&h, "best_log2_e"),
    );
    let mut fractions: HashMap<String, Vec<f64>> = HashMap::new();
    for r in &rows {
        let fr = num(&r[f]);
        assert!(fr > 0.0 && fr <= 1.0 + 1e-9, "{r:?}");
        let (be, _) = best[&(r[p].clone(), r[c].clone())];
        assert!(
            (num(&r[b]) - be).abs() < 1e-3,
            "{r:?}: the sweep's best is {be}"
        );
        fractions.entry(r[s].clone()).or_default().push(fr);
    }
    let mean = |k: &str| {
        let v = &fractions[k];
        v.iter().sum::<f64>() / v.len() as f64
    };
    // Under constant light every gradient law settles at its estimator's
    // fixed point, whatever the law; and there the gradient information
    // is higher than where the cameras' own AE settles (50 % grey over
    // the whole image), as the paper's Fig. 11 shows. (At this quarter
    // resolution; at full resolution the γ-mapping's fixed points lie
    // about 1 EV dark and the built-in AE keeps more: docs/evaluation.md.)
    for g in ["linear", "fast"] {
        assert!(
            (mean(g) - mean("nonlinear")).abs() < 0.01,
            "{g} {:.3}",
            mean(g)
        );
    }
    assert!(
        mean("nonlinear") > mean("camera-ae"),
        "nonlinear {:.3} vs camera-ae {:.3}",
        mean("nonlinear"),
        mean("camera-ae")
    );
    // Every gradient law runs under both exposure simulations; on the
    // simulator's linear sensor scale-and-clip's fixed points keep at
    // least as much gradient information as the γ-mapping's.
    for g in ["linear", "nonlinear", "fast", "pid"] {
        let sc = format!("{g}/scale-clip");
        println!(
            "{g}: γ-mapping {:.4}, scale-and-clip {:.4}",
            mean(g),
            mean(&sc)
        );
        if g == "pid" {
            // PID overshoots, and under scale-and-clip it can come to rest
            // on a second, worse fixed point (the reference preset's back
            // camera: 92.5 % of the best M, where the laws rest at the
            // best; docs/exposure-results.md): its rest is not the
            // estimator's fixed point, so only a floor is asserted.
            assert!(mean(&sc) > 0.98, "{g}: {:.4}", mean(&sc));
            continue;
        }
        assert!(
            mean(&sc) >= mean(g) - 0.002,
            "{g}: {:.4} vs {:.4}",
            mean(&sc),
            mean(g)
        );
    }

    // Experiment 4: every scenario under every strategy. Balancing brings
    // the overlaps closer than each camera alone and than the cameras'
    // own AE on the backlight scenario; display gains even out what the
    // view shows without touching the images; fixed manual exposure,
    // equal everywhere, leaves only the scene's own ratios.
    let (h, rows) = csv(&out.join(rigview::eval::files::SEAMS_CSV));
    assert_eq!(rows.len(), 3 * 6, "{h:?}");
    let get = |scenario: &str, strategy: &str, column: &str| {
        num(&row_of(&h, &rows, scenario, strategy)[col(&h, column)])
    };
    for r in &rows {
        for v in &r[2..] {
            assert!(num(v) >= 0.0, "{r:?}");
        }
    }
    let img = "mean_abs_log2_r_images";
    multi_lowest_under_backlight(&get, img, "surround");
    for scenario in ["backlight", "tunnel", "reference"] {
        for (plain, shown) in [
            ("camera-ae", "camera-ae+display"),
            ("multi", "multi+display"),
        ] {
            // The same exposures: the same images and M.
            assert!((get(scenario, plain, img) - get(scenario, shown, img)).abs() < 1e-3);
            let m = "m_fraction_mean";
            assert!((get(scenario, plain, m) - get(scenario, shown, m)).abs() < 1e-3);
            let view = "mean_abs_log2_r_view";
            assert!(
                get(scenario, shown, view) < 0.5 * get(scenario, plain, view),
                "{scenario} {shown}"
            );
            let step = "seam_step_ev";
            assert!(get(scenario, shown, step) < get(scenario, plain, step));
        }
        assert!(
            get(scenario, "fixed", img) < 0.1,
            "{scenario}: fixed exposure"
        );
    }
    let sums = hist_sums(&out.join(rigview::eval::files::HIST_CSV));
    assert_eq!(sums.len(), 3 * 6);
    assert!(sums.values().all(|s| (s - 1.0).abs() < 1e-3), "{sums:?}");
    let (_, rows) = csv(&out.join(rigview::eval::files::PROFILE_CSV));
    assert_eq!(rows.len(), 3 * 6 * 360);
    panorama_seams(&out);
    // Features across each of the 4 overlaps, per preset and settled
    // strategy.
    let (h, rows) = csv(&out.join(rigview::eval::files::OVERLAP_FEATURES_CSV));
    assert_eq!(h.len(), 5);
    assert_eq!(
        rows.len(),
        3 * rigview::eval::strategy::EvalStrategy::SETTLED.len() * 4
    );
    assert!(rows.iter().all(|r| num(&r[4]) >= 0.0));
    let (h, rows) = csv(&out.join(rigview::eval::files::VIEWS_CSV));
    assert_eq!((h.len(), rows.len()), (3 + CAMERAS, 3 * 6));
    let views = png(&out.join(rigview::eval::files::VIEWS_PNG));
    assert!(views.width() > 6 * 200 && views.height() > 3 * 200);

    // The summary in Markdown: a row per strategy, every cell a number
    // or "·" where an experiment did not run the strategy; the panorama's
    // column for exactly its four strategies.
    let md = std::fs::read_to_string(out.join(rigview::eval::files::HEADLINE_MD)).unwrap();
    let lines: Vec<&str> = md.lines().collect();
    assert_eq!(lines.len(), 2 + 15, "{md}");
    for line in &lines[2..] {
        let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
        assert_eq!(cells.len(), 9, "{line}");
        for c in &cells[1..] {
            assert!(*c == "·" || num(c.trim_end_matches(" %")) >= 0.0, "{line}");
        }
        // Where experiment 3 settled a strategy, it counted the corners
        // tracked and matched across the overlaps there.
        assert_eq!(cells[3] != "·", cells[4] != "·", "{line}");
        assert_eq!(cells[3] != "·", cells[5] != "·", "{line}");
        if cells[4] != "·" {
            assert!(num(cells[4]) > 10.0, "{line}");
        }
        let panorama_run = [
            "fixed manual",
            "camera built-in AE (simulated)",
            "gradient, nonlinear law, γ-mapping",
            "gradient balanced (multi), γ-mapping",
        ]
        .contains(&cells[0]);
        assert_eq!(cells[8] != "·", panorama_run, "{line}");
    }

    // The report: self-contained, with its figures inlined.
    let html = std::fs::read_to_string(out.join(rigview::eval::files::REPORT)).unwrap();
    let pngs = rigview::eval::files::ALL
        .iter()
        .filter(|f| f.ends_with(".png"))
        .count();
    assert_eq!(
        html.matches("src=\"data:image/png;base64,iVBORw0KGgo")
            .count(),
        pngs
    );
    assert!(!html.contains("src=\"fig"), "figures must be inlined");
    for s in [
        "Headline figures",
        "fast law's goals",
        "Versions and settings",
        "quarter of the rig",
        "5. Panorama seams",
    ] {
        assert!(html.contains(s), "report without \"{s}\"");
    }
    // A figure that is not finite shows as "–".
    assert!(!html.contains("<td>–"), "a headline figure is not finite");

    // As a reader sees it: headless Chromium renders the page with its
    // figures. The same page with its images taken out shows only the
    // tables' colour swatches and the goals' colours.
    let report = out.join(rigview::eval::files::REPORT);
    let with = colourful(&screenshot(&report, &dir.path().join("with.png")));
    let stripped = dir.path().join("stripped.html");
    let mut text = html.clone();
    while let Some(a) = text.find("<img ") {
        let b = a + text[a..].find('>').unwrap() + 1;
        text.replace_range(a..b, "");
    }
    std::fs::write(&stripped, text).unwrap();
    let without = colourful(&screenshot(&stripped, &dir.path().join("without.png")));
    println!("colourful pixels: {with} with the figures, {without} without");
    assert!(with > 4 * without.max(1000), "{with} against {without}");
}

/// Under backlight, balanced control's `column` (by `get`: scenario,
/// strategy, column) is below single's and the built-in AE's.
fn multi_lowest_under_backlight(get: &dyn Fn(&str, &str, &str) -> f64, column: &str, view: &str) {
    for other in ["nonlinear", "camera-ae"] {
        let (multi, theirs) = (
            get("backlight", "multi", column),
            get("backlight", other, column),
        );
        assert!(
            multi < theirs,
            "backlight, {view}: {column} of multi {multi} against {other} {theirs}"
        );
    }
}

/// The row of `scenario` and `strategy` of a CSV with those columns.
fn row_of<'a>(
    header: &[String],
    rows: &'a [Vec<String>],
    scenario: &str,
    strategy: &str,
) -> &'a [String] {
    let (sc, st) = (col(header, "scenario"), col(header, "strategy"));
    rows.iter()
        .find(|r| r[sc] == scenario && r[st] == strategy)
        .unwrap_or_else(|| panic!("no row {scenario} {strategy}"))
}

/// Per scenario and strategy, the sum of a histogram CSV's fractions.
fn hist_sums(path: &Path) -> HashMap<(String, String), f64> {
    let (h, rows) = csv(path);
    let (f, sc, st) = (
        col(&h, "fraction"),
        col(&h, "scenario"),
        col(&h, "strategy"),
    );
    let mut sums: HashMap<(String, String), f64> = HashMap::new();
    for r in &rows {
        *sums.entry((r[sc].clone(), r[st].clone())).or_default() += num(&r[f]);
    }
    sums
}

/// Experiment 5's rows of one run, counted.
#[derive(Default)]
struct RunCounts {
    /// The sets measured.
    sets: Vec<usize>,
    /// Overlaps × sets.
    pairs: usize,
    /// Those with a ratio.
    with_ratio: usize,
    /// Those with too few matches.
    too_few: usize,
}

/// Experiment 5: every overlap of every measured set is in the data,
/// with a ratio or a reason; the summary agrees with it; balancing gives
/// the smallest ratios from matched patches under backlight.
fn panorama_seams(out: &Path) {
    use rigview::eval::files;
    let quick = rigview::eval::Plan::quick(&[]);
    let plan = &quick.panorama;
    let strategies = ["fixed", "camera-ae", "nonlinear", "multi"];
    let (h, rows) = csv(&out.join(files::PANORAMA_PAIRS_CSV));
    let (sc, st, set, r, outcome) = (
        col(&h, "scenario"),
        col(&h, "strategy"),
        col(&h, "set"),
        col(&h, "log2_r"),
        col(&h, "outcome"),
    );
    let (matches, inliers) = (col(&h, "matches"), col(&h, "inliers"));
    let mut runs: HashMap<(String, String), RunCounts> = HashMap::new();
    for row in &rows {
        assert_eq!(row.len(), h.len(), "{row:?}");
        assert!(strategies.contains(&row[st].as_str()), "{row:?}");
        let k = num(&row[set]) as usize;
        assert!(
            k >= plan.warmup && (k - plan.warmup).is_multiple_of(plan.match_every),
            "{row:?}"
        );
        let e = runs.entry((row[sc].clone(), row[st].clone())).or_default();
        if !e.sets.contains(&k) {
            e.sets.push(k);
        }
        e.pairs += 1;
        match row[outcome].as_str() {
            "ratio" => {
                assert!(num(&row[r]).abs() < 8.0, "{row:?}");
                assert!(num(&row[inliers]) >= 6.0, "{row:?}");
                e.with_ratio += 1;
            }
            "too_few_matches" => {
                assert!(row[r].is_empty(), "a ratio from too few matches: {row:?}");
                e.too_few += 1;
            }
            "no_usable_patch" => assert!(row[r].is_empty(), "{row:?}"),
            o => panic!("unknown outcome {o}: {row:?}"),
        }
        assert!(num(&row[inliers]) <= num(&row[matches]), "{row:?}");
    }
    assert_eq!(runs.len(), 3 * strategies.len(), "{:?}", runs.keys());
    for ((scenario, strategy), RunCounts { sets, pairs, .. }) in &runs {
        let frames = rigview::eval::seams::frames_of(&quick.sim(scenario).unwrap(), plan.frames);
        let measured = (frames - plan.warmup).div_ceil(plan.match_every);
        assert_eq!(sets.len(), measured, "{scenario} {strategy}");
        assert_eq!(
            *pairs,
            CAMERAS * measured,
            "{scenario} {strategy}: one row per overlap"
        );
    }

    let (h, rows) = csv(&out.join(files::PANORAMA_CSV));
    assert_eq!(rows.len(), 3 * strategies.len(), "{h:?}");
    let (sc, st) = (col(&h, "scenario"), col(&h, "strategy"));
    let get = |scenario: &str, strategy: &str, column: &str| {
        num(&row_of(&h, &rows, scenario, strategy)[col(&h, column)])
    };
    for row in &rows {
        let RunCounts {
            pairs,
            with_ratio: with,
            too_few: few,
            ..
        } = &runs[&(row[sc].clone(), row[st].clone())];
        let with_ratio = get(&row[sc], &row[st], "pairs_with_ratio");
        assert_eq!(with_ratio as usize, *with, "{row:?}");
        assert_eq!(
            get(&row[sc], &row[st], "pairs_too_few_matches") as usize,
            *few
        );
        let unusable = get(&row[sc], &row[st], "pairs_no_usable_patch") as usize;
        assert_eq!(*with + *few + unusable, *pairs, "{row:?}");
        // A run without a ratio has no mean; every other mean is finite.
        let (mean, sd) = (
            &row[col(&h, "mean_abs_log2_r")],
            &row[col(&h, "sd_abs_log2_r")],
        );
        if *with == 0 {
            assert!(mean.is_empty() && sd.is_empty(), "{row:?}");
        } else {
            assert!((0.0..4.0).contains(&num(mean)) && num(sd) >= 0.0, "{row:?}");
        }
        // Under backlight the gradient laws' overlaps mostly give a ratio
        // (the quick panorama is detailed enough to match on).
        if row[sc] == "backlight" && ["nonlinear", "multi"].contains(&row[st].as_str()) {
            assert!(
                2 * *with > *pairs,
                "{row:?}: {with} of {pairs} with a ratio"
            );
        }
    }
    // Balancing with the neighbours brings the matched patches closer
    // than each camera under its own law, and than the cameras' own AE.
    multi_lowest_under_backlight(&get, "mean_abs_log2_r", "panorama");

    let sums = hist_sums(&out.join(files::PANORAMA_HIST_CSV));
    assert_eq!(sums.len(), 3 * strategies.len());
    for (run, sum) in &sums {
        // A run without a ratio has an empty histogram.
        let expected = if runs[run].with_ratio == 0 { 0.0 } else { 1.0 };
        assert!((sum - expected).abs() < 1e-3, "{run:?}: {sum}");
    }
}

/// A screenshot of `page` in headless Chromium (Debian's `chromium`,
/// which `scripts/setup` installs), 1400×14000 pixels (the whole report).
fn screenshot(page: &Path, png_path: &Path) -> image::RgbImage {
    let out = std::process::Command::new("timeout")
        .arg("120")
        .arg("chromium")
        .args([
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--hide-scrollbars",
            "--window-size=1400,14000",
        ])
        .arg(format!("--screenshot={}", png_path.display()))
        .arg(format!("file://{}", page.display()))
        .output()
        .expect("chromium (scripts/setup installs Debian's chromium package)");
    assert!(
        png_path.is_file(),
        "chromium wrote no screenshot: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    image::open(png_path).unwrap().to_rgb8()
}

/// Pixels of a saturated colour (the figures' series), not grey or white.
fn colourful(img: &image::RgbImage) -> usize {
    img.pixels()
        .filter(|p| {
            let (lo, hi) = (p.0.iter().min().unwrap(), p.0.iter().max().unwrap());
            hi - lo > 80
        })
        .count()
}
