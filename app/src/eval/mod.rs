//! `rigview eval`: the paper's experiments on the simulated rig, as one
//! command that writes a figure (PNG), its data (CSV) and one
//! self-contained `report.html` into a folder. See `docs/evaluation.md`.
//!
//! - [`gamma`]: experiment 1, the accuracy of γ̂ against a dense search.
//! - [`steps`]: experiment 2, convergence after steps of light.
//! - [`sweep`]: experiment 3, M against exposure with every strategy's
//!   settled exposure.
//! - [`seams`]: experiment 4, the surround view's seams, and experiment 6,
//!   the views side by side.
//! - [`panorama_seams`]: experiment 5, the panorama's seams, with `r_ij`
//!   from matched patches.
//! - [`on_brackets`]: experiments 3, 4 and 6 on a bracket sequence
//!   (`--brackets DIR`).
//! - [`closed_loop`]: the app's processor in lock step on the simulated rig.
//! - [`strategy`]: the strategies compared, with their colours;
//!   [`summary`]: a row of headline figures per strategy.
//! - [`figure`]: the figures (plotters); [`html`]: the report.

pub mod closed_loop;
pub mod downstream;
pub mod figure;
pub mod gamma;
pub mod html;
pub mod on_brackets;
pub mod panorama_seams;
pub mod seams;
pub mod start;
pub mod steps;
pub mod strategy;
pub mod summary;
pub mod sweep;

use std::fmt::Write as _;
use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use rigview_core::exposure::Simulation;
use rigview_core::sim::{SimConfig, SimRender};

use figure::{Panel, Series, Style};
use gamma::{GammaPlan, GammaRow};
use panorama_seams::{PanoramaPlan, PanoramaResult};
use seams::{SeamsPlan, SeamsResult};
use steps::{StepsPlan, StepsResult};
use strategy::EvalStrategy;
use sweep::{SweepPlan, SweepResult};

/// How much the evaluation measures.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Preset {
    /// A reduced run for a quick look and the tests (see [`Plan::quick`]).
    Quick,
    /// Everything at the rig's resolution.
    #[default]
    Full,
}

/// Everything an evaluation run does.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// The preset's name.
    pub preset: &'static str,
    /// What the preset reduces, in words (the report says it).
    pub reduced: String,
    /// Render scale of the simulated rig (1: 1288×964).
    pub scale: f64,
    /// The scenario whose scene experiments 1 and 2 use.
    pub scenario: String,
    /// Experiment 1.
    pub gamma: GammaPlan,
    /// Experiment 2.
    pub steps: StepsPlan,
    /// Experiment 3.
    pub sweep: SweepPlan,
    /// Experiments 4 and 6.
    pub seams: SeamsPlan,
    /// Experiment 5.
    pub panorama: PanoramaPlan,
}

impl Plan {
    /// The quick preset: a quarter of the rig's resolution (322×241), a
    /// dense search of 121 values in experiment 1, 1.6 s between steps in
    /// experiment 2, and sweeps of 0.25 EV and loops of 80 sets in
    /// experiment 3.
    pub fn quick(scenarios: &[String]) -> Self {
        let full = Self::full(scenarios);
        let (lo, hi, steps) = (32.0, 262_144.0, 53);
        Self {
            preset: "quick",
            reduced: "a quarter of the rig's resolution (322×241 instead of 1288×964); experiment 1 with a dense search of 121 values instead of 161; experiment 2 with 1.6 s (32 frames) between steps after 2 s of lead; experiments 3 and 4 with sweeps of 0.25 EV and closed loops of 80 sets in constant light (settled: the median of the last 10; experiment 4 leaves out the first 20 sets); experiment 5 with the same loops and sets left out, on the panorama's full canvas (2048×270: at half of it, 1024×135, half or more of the overlaps found too few matches to give a ratio)".into(),
            scale: 0.25,
            gamma: GammaPlan {
                dense_steps: 121,
                ..full.gamma
            },
            steps: StepsPlan {
                lead_s: 2.0,
                hold_s: 1.6,
            },
            sweep: SweepPlan {
                presets: sweep_presets(scenarios, false),
                lo,
                hi,
                steps,
                frames: 80,
                tail: 10,
                ..full.sweep
            },
            seams: SeamsPlan {
                frames: 80,
                warmup: 20,
                tail: 10,
                sweep: (lo, hi, steps),
                ..full.seams
            },
            panorama: PanoramaPlan {
                frames: 80,
                warmup: 20,
                ..full.panorama
            },
            ..full
        }
    }

    /// The full preset: the rig's resolution, every anchor count from 3 to
    /// 15, 5 exposures per camera, 2 s between steps after 3 s of lead,
    /// sweeps of 0.1 EV and loops of 200 sets.
    pub fn full(scenarios: &[String]) -> Self {
        Self {
            preset: "full",
            reduced: "nothing: the rig's resolution (1288×964, metered at 322×241 as the app meters it; experiment 1's full resolution is 1288×964)".into(),
            scale: 1.0,
            scenario: scenarios.first().cloned().unwrap_or_else(|| "reference".into()),
            gamma: GammaPlan {
                anchors: (3..=15).collect(),
                divisors: vec![1, 2, 4, 8, 16],
                offsets_ev: vec![-2.0, -1.0, 0.0, 1.0, 2.0],
                dense_steps: 161,
            },
            steps: StepsPlan {
                lead_s: 3.0,
                hold_s: 2.0,
            },
            sweep: SweepPlan {
                presets: sweep_presets(scenarios, true),
                whole_frames: vec!["sky".into()],
                lo: 16.0,
                hi: 1_048_576.0,
                steps: 161,
                frames: 200,
                tail: 20,
                canvas: (2048, 270),
            },
            seams: SeamsPlan {
                scenarios: seam_scenarios(scenarios),
                frames: 200,
                warmup: 40,
                tail: 20,
                sweep: (16.0, 1_048_576.0, 161),
            },
            panorama: PanoramaPlan {
                scenarios: seam_scenarios(scenarios),
                frames: 200,
                warmup: 40,
                canvas: (2048, 270),
                match_every: 5,
            },
        }
    }

    /// The plan of `preset`.
    pub fn of(preset: Preset, scenarios: &[String]) -> Self {
        match preset {
            Preset::Quick => Self::quick(scenarios),
            Preset::Full => Self::full(scenarios),
        }
    }

    /// The metering of the sweeps (the controller's).
    pub fn sweep_metering(&self) -> rigview_core::exposure::MeteringConfig {
        rigview_core::exposure::MeteringConfig::default()
    }

    /// The simulation of `name` at the plan's scale.
    pub fn sim(&self, name: &str) -> Result<SimConfig> {
        let c = SimConfig::named(name).with_context(|| format!("scenario \"{name}\""))?;
        Ok(SimConfig {
            scale: self.scale,
            ..c
        })
    }
}

/// The presets of experiment 3: the scenarios given, or the three of
/// constant light, and with `hard` the four where mean-intensity AE should
/// lose (`sky`, `tunnel-exit`, `snow`, `lawn`).
fn sweep_presets(scenarios: &[String], hard: bool) -> Vec<String> {
    if !scenarios.is_empty() {
        return scenarios.to_vec();
    }
    let mut presets = vec!["reference", "backlight", "overcast"];
    if hard {
        presets.extend(["sky", "tunnel-exit", "snow", "lawn"]);
    }
    presets.into_iter().map(String::from).collect()
}

/// The scenarios of the seams: the scenarios given, or a low sun, a
/// tunnel and the reference.
fn seam_scenarios(scenarios: &[String]) -> Vec<String> {
    if scenarios.is_empty() {
        ["backlight", "tunnel", "reference"]
            .map(String::from)
            .to_vec()
    } else {
        scenarios.to_vec()
    }
}

/// The files an evaluation writes, relative to its folder.
pub mod files {
    /// Experiment 1's figure and data.
    pub const GAMMA_PNG: &str = "fig1_gamma_accuracy.png";
    /// Experiment 1's data.
    pub const GAMMA_CSV: &str = "fig1_gamma_accuracy.csv";
    /// Experiment 2's traces.
    pub const STEPS_TRACE_PNG: &str = "fig2_step_traces.png";
    /// Experiment 2's traces, data.
    pub const STEPS_TRACE_CSV: &str = "fig2_step_traces.csv";
    /// Experiment 2's responses.
    pub const STEPS_PNG: &str = "fig2_step_responses.png";
    /// Experiment 2's responses, data.
    pub const STEPS_CSV: &str = "fig2_step_responses.csv";
    /// Experiment 3's figure.
    pub const SWEEP_PNG: &str = "fig3_m_vs_exposure.png";
    /// Experiment 3's sweeps.
    pub const SWEEP_CSV: &str = "fig3_m_vs_exposure.csv";
    /// Experiment 3's settled exposures.
    pub const SETTLED_CSV: &str = "fig3_settled.csv";
    /// Experiment 3's features matched across the overlaps where each
    /// strategy settled.
    pub const OVERLAP_FEATURES_CSV: &str = "fig3_overlap_features.csv";
    /// Experiment 4's histograms.
    pub const HIST_PNG: &str = "fig4_seam_histograms.png";
    /// Experiment 4's histograms, data.
    pub const HIST_CSV: &str = "fig4_seam_histograms.csv";
    /// Experiment 4's profiles.
    pub const PROFILE_PNG: &str = "fig4_seam_profiles.png";
    /// Experiment 4's profiles, data.
    pub const PROFILE_CSV: &str = "fig4_seam_profiles.csv";
    /// Experiment 4's summary figures.
    pub const SEAMS_CSV: &str = "fig4_seams.csv";
    /// Experiment 5's histograms.
    pub const PANORAMA_HIST_PNG: &str = "fig5_panorama_histograms.png";
    /// Experiment 5's histograms, data.
    pub const PANORAMA_HIST_CSV: &str = "fig5_panorama_histograms.csv";
    /// Experiment 5's summary figures.
    pub const PANORAMA_CSV: &str = "fig5_panorama.csv";
    /// Experiment 5's measurements: every overlap of every measured set.
    pub const PANORAMA_PAIRS_CSV: &str = "fig5_panorama_pairs.csv";
    /// From the start to rest on a bracket sequence (not in [`ALL`]: the
    /// simulator's evaluation does not write it).
    pub const START_CSV: &str = "brackets_start.csv";
    /// Experiment 6's views.
    pub const VIEWS_PNG: &str = "fig6_views.png";
    /// Experiment 6's views: the exposures they were taken with.
    pub const VIEWS_CSV: &str = "fig6_views.csv";
    /// The report.
    pub const REPORT: &str = "report.html";
    /// The report's summary table, in Markdown.
    pub const HEADLINE_MD: &str = "headline.md";
    /// Every file.
    pub const ALL: [&str; 23] = [
        GAMMA_PNG,
        GAMMA_CSV,
        STEPS_TRACE_PNG,
        STEPS_TRACE_CSV,
        STEPS_PNG,
        STEPS_CSV,
        SWEEP_PNG,
        SWEEP_CSV,
        SETTLED_CSV,
        OVERLAP_FEATURES_CSV,
        HIST_PNG,
        HIST_CSV,
        PROFILE_PNG,
        PROFILE_CSV,
        SEAMS_CSV,
        PANORAMA_HIST_PNG,
        PANORAMA_HIST_CSV,
        PANORAMA_CSV,
        PANORAMA_PAIRS_CSV,
        VIEWS_PNG,
        VIEWS_CSV,
        REPORT,
        HEADLINE_MD,
    ];
}

/// What a run measured, for the report.
#[derive(Debug)]
pub struct Results {
    /// The plan.
    pub plan: Plan,
    /// Experiment 1.
    pub gamma: Vec<GammaRow>,
    /// Experiment 2.
    pub steps: StepsResult,
    /// Experiment 3.
    pub sweep: SweepResult,
    /// Experiments 4 and 6.
    pub seams: SeamsResult,
    /// Experiment 5 (empty where it was not run).
    pub panorama: PanoramaResult,
    /// From the start to rest, per strategy and camera (a bracket
    /// sequence only).
    pub start: Vec<start::StartRow>,
    /// Seconds per experiment.
    pub seconds: Vec<(&'static str, f64)>,
    /// What ran, in words (the simulated rig and its scenario, or a
    /// bracket sequence).
    pub source: String,
}

/// Runs the evaluation of `plan` into `out` (created if needed); a
/// progress bar on stderr while it runs (hidden when stderr is not a
/// terminal). Returns what it measured.
pub fn run(plan: &Plan, out: &Path) -> Result<Results> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let base = plan.sim(&plan.scenario)?;
    let steps_config = plan.steps.config(&base);
    let render = SimRender::new(&base).context("building the simulated rig")?;
    let cameras = render.cameras().len();
    let frames_of = |scenarios: &[String], constant: usize| {
        scenarios
            .iter()
            .map(|s| Ok(seams::frames_of(&plan.sim(s)?, constant)))
            .collect::<Result<Vec<_>>>()
    };
    let seam_frames = frames_of(&plan.seams.scenarios, plan.seams.frames)?;
    let panorama_frames = frames_of(&plan.panorama.scenarios, plan.panorama.frames)?;
    let total = gamma::units(&plan.gamma, cameras)
        + (EvalStrategy::STEPS.len() * plan.steps.frames(&steps_config)) as u64
        + plan.sweep.presets.len() as u64 * sweep::units(&plan.sweep, cameras)
        + seams::units(&plan.seams, &seam_frames, cameras)
        + panorama_seams::units(&panorama_frames);
    let bar = progress_bar(total)?;
    let mut seconds = Vec::new();

    bar.set_message("1/5 γ̂ accuracy");
    let t = Instant::now();
    let gamma = gamma::run(&render, &plan.gamma, &mut || bar.inc(1))?;
    seconds.push(("1. γ̂ accuracy", t.elapsed().as_secs_f64()));

    bar.set_message("2/5 steps of light");
    let t = Instant::now();
    let render = Arc::new(SimRender::new(&steps_config).context("building the simulated rig")?);
    let steps = steps::run(&render, &mut || bar.inc(1))?;
    seconds.push(("2. steps of light", t.elapsed().as_secs_f64()));

    bar.set_message("3/5 M against exposure");
    let t = Instant::now();
    let sweep = sweep::run(&plan.sweep, &|p| plan.sim(p), &mut |k| bar.inc(k))?;
    seconds.push(("3. M against exposure", t.elapsed().as_secs_f64()));

    bar.set_message("4/5 surround seams");
    let t = Instant::now();
    let seams = seams::run(&plan.seams, &|p| plan.sim(p), &mut |k| bar.inc(k))?;
    seconds.push(("4, 6. surround seams and views", t.elapsed().as_secs_f64()));

    bar.set_message("5/5 panorama seams");
    let t = Instant::now();
    let panorama = panorama_seams::run(
        &plan.panorama,
        &|p| plan.sim(p),
        &crate::session::view::shared_detector(),
        &mut |k| bar.inc(k),
    )?;
    seconds.push(("5. panorama seams", t.elapsed().as_secs_f64()));
    bar.finish_and_clear();

    let results = Results {
        plan: plan.clone(),
        gamma,
        steps,
        sweep,
        seams,
        panorama,
        start: Vec::new(),
        seconds,
        source: format!("simulated rig, scenario {}", plan.scenario),
    };
    write_all(&results, out)?;
    Ok(results)
}

/// The evaluation's progress bar on stderr (hidden when stderr is not a
/// terminal), of `total` units.
pub fn progress_bar(total: u64) -> Result<ProgressBar> {
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template(
            "{msg:<34} [{bar:40}] {percent:>3}% {elapsed_precise} (eta {eta})",
        )
        .context("the progress bar's template")?
        .progress_chars("=> "),
    );
    Ok(bar)
}

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
fn sim_label(s: Simulation) -> &'static str {
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
    write_seams(r, out)?;
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_scenarios_given_replace_the_defaults_of_every_experiment() {
        let given = vec!["overcast".to_string(), "tunnel".to_string()];
        for plan in [Plan::quick(&given), Plan::full(&given)] {
            assert_eq!(plan.scenario, "overcast");
            assert_eq!(plan.sweep.presets, given);
            assert_eq!(plan.seams.scenarios, given);
            assert_eq!(plan.panorama.scenarios, given);
        }
        let plan = Plan::quick(&[]);
        assert_eq!(plan.scenario, "reference");
        assert_eq!(plan.sweep.presets, ["reference", "backlight", "overcast"]);
        assert_eq!(
            Plan::full(&[]).sweep.presets,
            [
                "reference",
                "backlight",
                "overcast",
                "sky",
                "tunnel-exit",
                "snow",
                "lawn"
            ]
        );
        assert_eq!(plan.seams.scenarios, ["backlight", "tunnel", "reference"]);
        assert_eq!(plan.panorama.scenarios, plan.seams.scenarios);
    }
}
