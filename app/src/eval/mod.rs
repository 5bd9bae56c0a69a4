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
mod write;

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
use write::sim_label;
pub use write::write_all;

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
    /// Experiment 3's valid stereo disparities of each stereo pair where
    /// each strategy settled (not in [`ALL`]: written only for a rig with
    /// a pair).
    pub const STEREO_CSV: &str = "fig3_stereo.csv";
    /// Experiment 3's stereo pairs, rectified, with their disparities, where
    /// a few strategies settled (not in [`ALL`], as [`STEREO_CSV`]).
    pub const STEREO_PNG: &str = "fig3_stereo.png";
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
