//! Experiment 1, the accuracy of γ̂ (the paper's Fig. 7): the estimator's
//! γ̂ against a dense search over γ, as the number of anchors and the
//! metered resolution change, for both exposure simulations.
//!
//! For each camera of the scene (noise-free renders at its first moment),
//! at exposures offset from the camera's best (the maximum of a coarse
//! sweep of M), the **dense search** scores the image at full resolution
//! (one metered pixel per sensor pixel) after the simulated exposure
//! change at `dense_steps` log-spaced values over the anchors' span
//! (1/1.9 to 1.9) and takes the best: γ* (as a γ-equivalent, so that
//! scale-and-clip's ŝ reads as 1/ŝ). Then:
//!
//! - **anchors**: γ̂ from `k` anchors, log-spaced over the same span, with
//!   a polynomial of order `min(5, k − 1)`, at full resolution;
//! - **resolution**: γ̂ from 7 anchors on the image metered at 1/d of the
//!   full width and height (block means of d×d pixels).
//!
//! The error is `|γ̂ − γ*|`.

use anyhow::Result;
use rigview_core::exposure::{Estimator, EstimatorConfig, Meter, MeteringConfig, Simulation};
use rigview_core::sim::truth::{self, SweepOptions};
use rigview_core::sim::SimRender;

/// The span of the anchors: `[1/SPAN, SPAN]`.
const SPAN: f64 = 1.9;
/// The anchors of the resolution series.
const RESOLUTION_ANCHORS: usize = 7;

/// What experiment 1 measures.
#[derive(Clone, Debug, PartialEq)]
pub struct GammaPlan {
    /// Anchor counts.
    pub anchors: Vec<usize>,
    /// Resolution divisors (1: full).
    pub divisors: Vec<usize>,
    /// Exposure offsets from each camera's best, EV.
    pub offsets_ev: Vec<f64>,
    /// Values of the dense search.
    pub dense_steps: usize,
}

/// One estimate against the dense search.
#[derive(Clone, Debug, PartialEq)]
pub struct GammaRow {
    /// The series: `anchors` or `resolution`.
    pub series: &'static str,
    /// The exposure simulation.
    pub simulation: Simulation,
    /// The camera's name.
    pub camera: String,
    /// The exposure's offset from the camera's best, EV.
    pub offset_ev: f64,
    /// Anchors used.
    pub anchors: usize,
    /// Resolution divisor.
    pub divisor: usize,
    /// The metered size.
    pub width: usize,
    /// The metered size.
    pub height: usize,
    /// The estimate (γ-equivalent).
    pub gamma_hat: f64,
    /// The dense search's best (γ-equivalent).
    pub gamma_dense: f64,
}

impl GammaRow {
    /// `|γ̂ − γ*|`.
    pub fn error(&self) -> f64 {
        (self.gamma_hat - self.gamma_dense).abs()
    }

    /// The CSV header.
    pub const HEADER: &'static str = "series,simulation,camera,offset_ev,anchors,divisor,width,height,gamma_hat,gamma_dense,abs_error";

    /// A CSV line.
    pub fn csv(&self) -> String {
        format!(
            "{},{},{},{:.2},{},{},{},{},{:.5},{:.5},{:.5}",
            self.series,
            self.simulation.name(),
            self.camera,
            self.offset_ev,
            self.anchors,
            self.divisor,
            self.width,
            self.height,
            self.gamma_hat,
            self.gamma_dense,
            self.error()
        )
    }
}

/// `k` anchors log-spaced over `[1/SPAN, SPAN]`.
pub fn anchors(k: usize) -> Vec<f64> {
    let k = k.max(2);
    (0..k)
        .map(|i| (SPAN.ln() * (2.0 * i as f64 / (k - 1) as f64 - 1.0)).exp())
        .collect()
}

fn estimator(simulation: Simulation, k: usize) -> Result<Estimator> {
    Ok(Estimator::new(EstimatorConfig {
        simulation,
        anchors: anchors(k),
        degree: 5.min(k.saturating_sub(1)).max(1),
        ..Default::default()
    })?)
}

/// Work units of [`run`] (one per camera, offset and simulation).
pub fn units(plan: &GammaPlan, cameras: usize) -> u64 {
    (2 * cameras * plan.offsets_ev.len()) as u64
}

/// Runs experiment 1 on `render`; `tick` is called after each unit.
pub fn run(render: &SimRender, plan: &GammaPlan, tick: &mut dyn FnMut()) -> Result<Vec<GammaRow>> {
    let mut rows = Vec::new();
    for (cam, info) in render.cameras().iter().enumerate() {
        let (w, h) = (info.width, info.height);
        let meter_at = |d: usize| {
            Meter::new(MeteringConfig {
                target_width: (w / d).max(3),
                target_height: (h / d).max(3),
            })
        };
        let full = meter_at(1)?;
        let coarse = truth::sweep(
            render,
            cam,
            0.0,
            &SweepOptions {
                lo: 32.0,
                hi: 262_144.0,
                steps: 27,
                ..Default::default()
            },
            None,
        )?;
        for &offset in &plan.offsets_ev {
            let e = coarse.best * offset.exp2();
            let image = truth::meter_noise_free(render, cam, 0.0, e, &full, None)?;
            let reduced: Vec<_> = plan
                .divisors
                .iter()
                .map(|&d| {
                    let m = meter_at(d)?;
                    Ok((d, truth::meter_noise_free(render, cam, 0.0, e, &m, None)?))
                })
                .collect::<Result<_>>()?;
            for simulation in [Simulation::Gamma, Simulation::ScaleClip] {
                let mut dense = estimator(simulation, RESOLUTION_ANCHORS)?;
                let n = plan.dense_steps.max(2);
                let (mut best_x, mut best_m) = (1.0, f64::MIN);
                for i in 0..n {
                    let x = (SPAN.ln() * (2.0 * i as f64 / (n - 1) as f64 - 1.0)).exp();
                    let m = dense.score_at(&image, x);
                    if m > best_m {
                        (best_x, best_m) = (x, m);
                    }
                }
                let gamma_dense = simulation.gamma_equivalent(best_x);
                let row = |series, anchors, divisor, width, height, gamma_hat| GammaRow {
                    series,
                    simulation,
                    camera: info.name.clone(),
                    offset_ev: offset,
                    anchors,
                    divisor,
                    width,
                    height,
                    gamma_hat,
                    gamma_dense,
                };
                for &k in &plan.anchors {
                    let g = estimator(simulation, k)?.estimate(&image)?.gamma_hat;
                    rows.push(row("anchors", k, 1, image.width(), image.height(), g));
                }
                let mut est = estimator(simulation, RESOLUTION_ANCHORS)?;
                for (d, m) in &reduced {
                    let g = est.estimate(m)?.gamma_hat;
                    rows.push(row(
                        "resolution",
                        RESOLUTION_ANCHORS,
                        *d,
                        m.width(),
                        m.height(),
                        g,
                    ));
                }
                tick();
            }
        }
    }
    Ok(rows)
}

/// The `q`-quantile of the errors of the rows `keep` selects (NaN when
/// none).
pub fn error_quantile(rows: &[GammaRow], q: f64, keep: impl Fn(&GammaRow) -> bool) -> f64 {
    let mut v: Vec<f64> = rows
        .iter()
        .filter(|r| keep(r))
        .map(GammaRow::error)
        .collect();
    crate::report::quantile(&mut v, q)
}
