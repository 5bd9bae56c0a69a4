//! Writing an evaluation's results: each experiment's CSV and figures,
//! then the report.

use super::*;

fn write_csv(
    out: &Path,
    name: &str,
    header: &str,
    lines: impl Iterator<Item = String>,
) -> Result<()> {
    let mut s = String::from(header);
    s.push('\n');
    for l in lines {
        s += &l;
        s.push('\n');
    }
    let path = out.join(name);
    std::fs::write(&path, s).with_context(|| format!("writing {}", path.display()))
}

fn sim_colour(s: Simulation) -> plotters::style::RGBColor {
    match s {
        Simulation::Gamma => plotters::style::RGBColor(40, 120, 200),
        Simulation::ScaleClip => plotters::style::RGBColor(210, 110, 30),
    }
}

/// The γ-equivalent's label of a simulation.
pub(super) fn sim_label(s: Simulation) -> &'static str {
    match s {
        Simulation::Gamma => "γ-mapping",
        Simulation::ScaleClip => "scale-and-clip",
    }
}

/// Writes every CSV, figure and the report of `r` into `out` (the
/// experiments that were run).
pub fn write_all(r: &Results, out: &Path) -> Result<()> {
    if !r.gamma.is_empty() {
        write_gamma(r, out)?;
    }
    if !r.steps.rows.is_empty() {
        write_steps(r, out)?;
    }
    write_sweep(r, out)?;
    // (No seams without a surround view: a rig posed relative to a camera.)
    if !r.seams.runs.is_empty() {
        write_seams(r, out)?;
    }
    if !r.panorama.runs.is_empty() {
        write_panorama(r, out)?;
    }
    if !r.start.is_empty() {
        write_csv(
            out,
            files::START_CSV,
            start::StartRow::HEADER,
            r.start.iter().map(start::StartRow::csv),
        )?;
    }
    let md = out.join(files::HEADLINE_MD);
    std::fs::write(&md, summary::markdown(r))
        .with_context(|| format!("writing {}", md.display()))?;
    let html = html::report(r, out)?;
    let path = out.join(files::REPORT);
    std::fs::write(&path, html).with_context(|| format!("writing {}", path.display()))
}

/// Experiment 1's CSV and figure.
fn write_gamma(r: &Results, out: &Path) -> Result<()> {
    write_csv(
        out,
        files::GAMMA_CSV,
        GammaRow::HEADER,
        r.gamma.iter().map(GammaRow::csv),
    )?;
    let mut panels = Vec::new();
    for (series, x_label, x_of) in [
        (
            "anchors",
            "anchors (count)",
            (|row: &GammaRow| row.anchors as f64) as fn(&GammaRow) -> f64,
        ),
        (
            "resolution",
            "metered resolution: log2 of the divisor (0 = full, 4 = 1/16)",
            |row: &GammaRow| (row.divisor as f64).log2(),
        ),
    ] {
        let mut panel = Panel {
            title: format!("error of the γ estimate against the {series}"),
            x_label: x_label.into(),
            y_label: "|estimate − γ*| (γ-equivalent)".into(),
            ..Default::default()
        };
        for sim in [Simulation::Gamma, Simulation::ScaleClip] {
            let mut xs: Vec<f64> = r
                .gamma
                .iter()
                .filter(|g| g.series == series)
                .map(x_of)
                .collect();
            xs.sort_by(f64::total_cmp);
            xs.dedup();
            for (q, style, what) in [(0.5, Style::LineDots, "median"), (0.9, Style::Thin, "90 %")] {
                let points = xs
                    .iter()
                    .map(|&x| {
                        let e = gamma::error_quantile(&r.gamma, q, |g| {
                            g.series == series && g.simulation == sim && (x_of(g) - x).abs() < 1e-9
                        });
                        (x, e)
                    })
                    .collect();
                panel.series.push(Series {
                    label: Some(format!("{}, {what}", sim_label(sim))),
                    colour: sim_colour(sim),
                    style,
                    points,
                });
            }
        }
        panels.push(panel);
    }
    figure::write(&out.join(files::GAMMA_PNG), &panels, 2, 640, 420)?;

    Ok(())
}

/// Experiment 2's CSVs and figures.
fn write_steps(r: &Results, out: &Path) -> Result<()> {
    let st = &r.steps;
    write_csv(
        out,
        files::STEPS_CSV,
        steps::StepRow::HEADER,
        st.rows.iter().map(steps::StepRow::csv),
    )?;
    let mut header = String::from("strategy,frame,time_s");
    for c in &st.cameras {
        let _ = write!(header, ",{c}_log2_e");
    }
    let trace_lines = st.traces.iter().flat_map(|(s, t)| {
        let frames = t.log2_e.first().map_or(0, Vec::len);
        (0..frames).map(move |f| {
            let mut l = format!("{},{f},{:.3}", s.key(), f as f64 / st.trigger_hz);
            for cam in &t.log2_e {
                let _ = write!(l, ",{:.4}", cam[f]);
            }
            l
        })
    });
    write_csv(out, files::STEPS_TRACE_CSV, &header, trace_lines)?;
    let marks: Vec<f64> = st
        .step_frames
        .iter()
        .map(|&f| f as f64 / st.trigger_hz)
        .collect();
    let panels: Vec<Panel> = st
        .cameras
        .iter()
        .enumerate()
        .map(|(k, cam)| Panel {
            title: format!("{cam} camera: exposure over the steps of light"),
            x_label: "time (s)".into(),
            y_label: "log2 E (E = shutter µs · gain)".into(),
            marks_x: marks.clone(),
            series: st
                .traces
                .iter()
                .map(|(s, t)| Series {
                    label: (k == 0).then(|| s.label().to_string()),
                    colour: s.colour(),
                    style: Style::Line,
                    points: t.log2_e[k]
                        .iter()
                        .enumerate()
                        .map(|(f, &e)| (f as f64 / st.trigger_hz, e))
                        .collect(),
                })
                .collect(),
        })
        .collect();
    figure::write(&out.join(files::STEPS_TRACE_PNG), &panels, 2, 720, 420)?;
    let mut panels = Vec::new();
    type Stat = fn(&[&rigview_core::eval::dynamics::StepResponse]) -> f64;
    let stats: [(&str, &str, Stat); 3] = [
        (
            "frames to settle within 0.1 EV (median over cameras)",
            "frames",
            |v| {
                let mut x: Vec<f64> = v.iter().map(|r| r.settle_frames as f64).collect();
                crate::report::quantile(&mut x, 0.5)
            },
        ),
        ("overshoot (largest over cameras)", "overshoot (EV)", |v| {
            v.iter().map(|r| r.overshoot_ev).fold(0.0, f64::max)
        }),
        (
            "jitter over the last 20 frames (largest)",
            "standard deviation of log2 E (EV)",
            |v| v.iter().map(|r| r.jitter_ev).fold(0.0, f64::max),
        ),
    ];
    let mut sorted_steps = steps::STEPS.to_vec();
    sorted_steps.sort_by(f64::total_cmp);
    for (title, y_label, stat) in stats {
        panels.push(Panel {
            title: title.into(),
            x_label: "step of light (stops)".into(),
            y_label: y_label.into(),
            marks_x: Vec::new(),
            series: EvalStrategy::STEPS
                .iter()
                .map(|&s| Series {
                    label: Some(s.label().into()),
                    colour: s.colour(),
                    style: Style::LineDots,
                    points: sorted_steps
                        .iter()
                        .map(|&stops| (stops, stat(&st.responses(s, stops))))
                        .collect(),
                })
                .collect(),
        });
    }
    figure::write(&out.join(files::STEPS_PNG), &panels, 3, 560, 440)?;

    Ok(())
}

/// Experiment 3's CSVs and figure.
fn write_sweep(r: &Results, out: &Path) -> Result<()> {
    let sw = &r.sweep;
    let sweep_lines = sw.sweeps.iter().flat_map(|s| {
        s.sweep
            .exposures
            .iter()
            .zip(&s.sweep.scores)
            .map(move |(e, m)| format!("{},{},{:.4},{:.3}", s.preset, s.camera, e.log2(), m))
    });
    write_csv(out, files::SWEEP_CSV, "preset,camera,log2_e,m", sweep_lines)?;
    write_csv(
        out,
        files::SETTLED_CSV,
        sweep::Settled::HEADER,
        sw.settled.iter().map(sweep::Settled::csv),
    )?;
    write_csv(
        out,
        files::OVERLAP_FEATURES_CSV,
        downstream::OverlapFeatures::HEADER,
        sw.overlaps.iter().map(downstream::OverlapFeatures::csv),
    )?;
    if !sw.stereo_views.is_empty() {
        downstream::write_stereo_views(&sw.stereo_views, &out.join(files::STEREO_PNG))?;
    }
    if !sw.stereo.is_empty() {
        write_csv(
            out,
            files::STEREO_CSV,
            downstream::StereoDensity::HEADER,
            sw.stereo.iter().map(downstream::StereoDensity::csv),
        )?;
    }
    let panels: Vec<Panel> = sw
        .sweeps
        .iter()
        .enumerate()
        .map(|(k, s)| {
            let mut series = vec![Series {
                label: (k == 0).then(|| "M(E), dense sweep".to_string()),
                colour: plotters::style::RGBColor(30, 30, 30),
                style: Style::Line,
                points: s
                    .sweep
                    .exposures
                    .iter()
                    .zip(&s.sweep.scores)
                    .map(|(e, m)| (e.log2(), *m))
                    .collect(),
            }];
            for st in sw
                .settled
                .iter()
                .filter(|x| x.preset == s.preset && x.camera == s.camera)
            {
                series.push(Series {
                    label: (k == 0).then(|| st.strategy.label().to_string()),
                    colour: st.strategy.colour(),
                    style: Style::Marks,
                    points: vec![(st.log2_e, st.m)],
                });
            }
            Panel {
                title: format!("{}: {} camera", s.preset, s.camera),
                x_label: "log2 E (E = shutter µs · gain)".into(),
                y_label: "gradient information M".into(),
                series,
                marks_x: Vec::new(),
            }
        })
        .collect();
    figure::write(&out.join(files::SWEEP_PNG), &panels, 4, 480, 360)?;
    Ok(())
}

fn write_seams(r: &Results, out: &Path) -> Result<()> {
    let se = &r.seams;
    let warmup = r.plan.seams.warmup;
    let scenarios = &r.plan.seams.scenarios;
    write_csv(
        out,
        files::HIST_CSV,
        HIST_HEADER,
        se.runs
            .iter()
            .flat_map(|run| hist_lines(&run.scenario, run.strategy, run.histogram(warmup))),
    )?;
    write_csv(
        out,
        files::PROFILE_CSV,
        "scenario,strategy,angle_deg,intensity",
        se.runs.iter().flat_map(|run| {
            run.profile
                .iter()
                .map(move |(a, v)| format!("{},{},{a:.0},{v:.2}", run.scenario, run.strategy.key()))
        }),
    )?;
    write_csv(
        out,
        files::SEAMS_CSV,
        "scenario,strategy,mean_abs_log2_r_images,sd_abs_log2_r_images,mean_abs_log2_r_view,sd_abs_log2_r_view,seam_step_ev,m_fraction_mean,m_fraction_min",
        se.runs.iter().map(|run| {
            let s = run.stats(warmup);
            format!(
                "{},{},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4},{:.4}",
                run.scenario,
                run.strategy.key(),
                s.mean_images,
                s.sd_images,
                s.mean_view,
                s.sd_view,
                s.seam_step,
                s.m_mean,
                s.m_min
            )
        }),
    )?;
    let mut header = String::from("scenario,strategy,set");
    let names = &r.steps.cameras;
    for c in names {
        let _ = write!(header, ",{c}_log2_e");
    }
    write_csv(
        out,
        files::VIEWS_CSV,
        &header,
        se.runs.iter().map(|run| {
            let t = &run.trace;
            let last = t.log2_e.first().map_or(0, Vec::len).saturating_sub(1);
            let mut l = format!("{},{},{last}", run.scenario, run.strategy.key());
            for cam in &t.log2_e {
                let _ = write!(l, ",{:.4}", cam.get(last).copied().unwrap_or(f64::NAN));
            }
            l
        }),
    )?;
    let hist = per_scenario(
        &se.runs,
        |run| (&run.scenario, run.strategy),
        scenarios,
        ("log2 r_ij (EV)", "fraction of the samples"),
        |sc| {
            (
                format!("{sc}: log2 r_ij over every overlap and set, as the view shows it"),
                vec![0.0],
            )
        },
        |run| hist_points(run.histogram(warmup)),
    );
    figure::write(&out.join(files::HIST_PNG), &hist, 3, 560, 420)?;
    let profiles = per_scenario(
        &se.runs,
        |run| (&run.scenario, run.strategy),
        scenarios,
        (
            "angle clockwise from ahead (degrees; grey: seams)",
            "intensity in the view (0–255)",
        ),
        |sc| {
            (
                format!(
                    "{sc}: the last view along a circle of {} m around the car",
                    seams::PROFILE_RADIUS_M
                ),
                se.seam_angles
                    .iter()
                    .find(|(s, _)| s == sc)
                    .map(|(_, a)| a.clone())
                    .unwrap_or_default(),
            )
        },
        |run| run.profile.clone(),
    );
    figure::write(&out.join(files::PROFILE_PNG), &profiles, 1, 1100, 380)?;
    seams::write_views(se, scenarios, &out.join(files::VIEWS_PNG))
}

/// The header of the histograms' CSVs.
const HIST_HEADER: &str = "scenario,strategy,bin_lo_ev,bin_hi_ev,fraction";

/// The CSV lines of one run's histogram (see [`seams::histogram`]).
fn hist_lines(
    scenario: &str,
    strategy: EvalStrategy,
    hist: Vec<(f64, f64)>,
) -> impl Iterator<Item = String> + '_ {
    hist.into_iter().map(move |(lo, f)| {
        format!(
            "{scenario},{},{lo:.2},{:.2},{f:.5}",
            strategy.key(),
            lo + seams::BIN_EV
        )
    })
}

/// A histogram's line: each bin at its centre.
fn hist_points(hist: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    hist.into_iter()
        .map(|(lo, f)| (lo + seams::BIN_EV / 2.0, f))
        .collect()
}

/// Experiment 5's CSVs and figure.
fn write_panorama(r: &Results, out: &Path) -> Result<()> {
    let pa = &r.panorama;
    let name = |k: usize| pa.cameras.get(k).map_or("?", String::as_str);
    write_csv(
        out,
        files::PANORAMA_PAIRS_CSV,
        "scenario,strategy,set,camera_i,camera_j,matches,inliers,patches,mostly_saturated,log2_r,outcome",
        pa.runs.iter().flat_map(|run| {
            run.samples.iter().map(move |p| {
                format!(
                    "{},{},{},{},{},{},{},{},{},{},{}",
                    run.scenario,
                    run.strategy.key(),
                    p.set,
                    name(p.i),
                    name(p.j),
                    p.matches,
                    p.inliers,
                    p.patches,
                    u8::from(p.saturated),
                    p.log2_r.map(|v| format!("{v:.4}")).unwrap_or_default(),
                    match (p.log2_r, p.too_few) {
                        (Some(_), _) => "ratio",
                        (None, true) => "too_few_matches",
                        (None, false) => "no_usable_patch",
                    }
                )
            })
        }),
    )?;
    write_csv(
        out,
        files::PANORAMA_CSV,
        "scenario,strategy,mean_abs_log2_r,sd_abs_log2_r,pairs_with_ratio,pairs_too_few_matches,pairs_no_usable_patch",
        pa.runs.iter().map(|run| {
            let s = run.stats();
            let finite = |v: f64| {
                if v.is_finite() {
                    format!("{v:.4}")
                } else {
                    String::new()
                }
            };
            format!(
                "{},{},{},{},{},{},{}",
                run.scenario,
                run.strategy.key(),
                finite(s.mean),
                finite(s.sd),
                s.with_ratio,
                s.too_few,
                s.unusable
            )
        }),
    )?;
    write_csv(
        out,
        files::PANORAMA_HIST_CSV,
        HIST_HEADER,
        pa.runs
            .iter()
            .flat_map(|run| hist_lines(&run.scenario, run.strategy, run.histogram())),
    )?;
    let hist = per_scenario(
        &pa.runs,
        |run| (&run.scenario, run.strategy),
        &r.plan.panorama.scenarios,
        ("log2 r_ij (EV)", "fraction of the ratios"),
        |sc| {
            // A strategy without a ratio has no line: the title says so.
            let none: Vec<&str> = pa
                .runs
                .iter()
                .filter(|run| run.scenario == sc && run.stats().with_ratio == 0)
                .map(|run| run.strategy.label())
                .collect();
            let title = format!("{sc}: log2 r_ij of matched patches");
            (
                if none.is_empty() {
                    title
                } else {
                    format!("{title}; none for {}", none.join(", "))
                },
                vec![0.0],
            )
        },
        |run| hist_points(run.histogram()),
    );
    figure::write(&out.join(files::PANORAMA_HIST_PNG), &hist, 3, 560, 420)
}

/// One panel per scenario with a line per strategy (the legend in the
/// first): `id` gives a run's scenario and strategy, `axes` are the x and
/// y descriptions, `head` gives a scenario's title and vertical marks,
/// `points` a run's line.
fn per_scenario<R>(
    runs: &[R],
    id: impl Fn(&R) -> (&String, EvalStrategy),
    scenarios: &[String],
    axes: (&str, &str),
    head: impl Fn(&str) -> (String, Vec<f64>),
    points: impl Fn(&R) -> Vec<(f64, f64)>,
) -> Vec<Panel> {
    scenarios
        .iter()
        .enumerate()
        .map(|(k, sc)| {
            let (title, marks_x) = head(sc);
            Panel {
                title,
                x_label: axes.0.into(),
                y_label: axes.1.into(),
                marks_x,
                series: runs
                    .iter()
                    .filter(|run| id(run).0 == sc)
                    .map(|run| {
                        let strategy = id(run).1;
                        Series {
                            label: (k == 0).then(|| strategy.label().to_string()),
                            colour: strategy.colour(),
                            style: Style::Line,
                            points: points(run),
                        }
                    })
                    .collect(),
            }
        })
        .collect()
}
