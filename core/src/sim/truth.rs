//! Ground truth for evaluating exposure control on the simulated rig.
//!
//! - [`sweep`]: for one camera at one moment, the gradient metric `M` of the
//!   noise-free render over a dense, log-spaced sweep of exposures (161 by
//!   default, 0.1 EV apart), and the exposure where it is largest.
//! - [`fixed_points`]: the exposures where the estimator's `γ̂` crosses 1
//!   from below (the stable fixed points of a gradient controller), found
//!   on the noise-free render by a scan and bisection, each with the size of
//!   the jump of `γ̂` across it.
//! - [`overlap_ratios`]: the true brightness ratio of each overlap at equal
//!   exposure, from the noise-free irradiance over the surround view's
//!   overlap patches (the same patches the balancing measures).
//! - [`dynamic_range`]: the scene's dynamic range as the cameras see it.
//!
//! Exposures are levels `E = t_us · 10^(gain_dB/20)`; the renders use
//! `t = E` at 0 dB (the mean does not depend on the split).

use super::render::{FillRequest, SimRender};
use crate::error::{Error, Result};
use crate::exposure::{
    Darker, EstimateOptions, Estimator, EstimatorConfig, ExposureSetting, FrameView, Meter,
    Metered, MeteringConfig, MetricParams, RoiMask,
};
use crate::stats::median;
use crate::surround::SurroundView;

/// What a sweep covers and how it meters.
#[derive(Clone, Debug, PartialEq)]
pub struct SweepOptions {
    /// Lowest exposure level.
    pub lo: f64,
    /// Highest exposure level.
    pub hi: f64,
    /// Number of log-spaced levels (the ends included).
    pub steps: usize,
    /// Metering.
    pub metering: MeteringConfig,
    /// The metric.
    pub metric: MetricParams,
}

impl Default for SweepOptions {
    /// 2⁴ to 2²⁰ µs in 161 steps of 0.1 EV, metered at 320×240, the paper's
    /// metric.
    fn default() -> Self {
        Self {
            lo: 16.0,
            hi: 1_048_576.0,
            steps: 161,
            metering: MeteringConfig::default(),
            metric: MetricParams::default(),
        }
    }
}

/// The result of a sweep.
#[derive(Clone, Debug, PartialEq)]
pub struct Sweep {
    /// The exposure levels.
    pub exposures: Vec<f64>,
    /// `M` at each.
    pub scores: Vec<f64>,
    /// The level with the largest `M`.
    pub best: f64,
    /// That `M`.
    pub best_score: f64,
}

impl Sweep {
    /// `M` at `e`, interpolated in log exposure (clamped to the sweep).
    pub fn score_at(&self, e: f64) -> f64 {
        let l = e.log2();
        let xs: Vec<f64> = self.exposures.iter().map(|x| x.log2()).collect();
        match xs.iter().position(|&x| x >= l) {
            None => self.scores.last().copied().unwrap_or(0.0),
            Some(0) => self.scores.first().copied().unwrap_or(0.0),
            Some(k) => {
                let t = (l - xs[k - 1]) / (xs[k] - xs[k - 1]);
                self.scores[k - 1] + t * (self.scores[k] - self.scores[k - 1])
            }
        }
    }
}

/// Renders (noise-free) and meters one camera at level `e`.
pub fn meter_noise_free(
    render: &SimRender,
    camera: usize,
    t: f64,
    e: f64,
    meter: &Meter,
    mask: Option<&RoiMask>,
) -> Result<Metered> {
    let info = render.cameras().get(camera).ok_or(Error::CameraIndex {
        index: camera,
        count: render.cameras().len(),
    })?;
    let setting = ExposureSetting {
        shutter_us: e,
        gain_db: 0.0,
    };
    let req = FillRequest {
        time_s: Some(t),
        noise: false,
        ..FillRequest::new(camera, 0, setting, info.format, info.width, info.height)
    };
    let mut buf = vec![0u8; req.buffer_len()];
    render.fill(&req, &mut buf)?;
    let view = FrameView::new(info.format, info.width, info.height, &buf)?;
    meter.meter(&view, mask)
}

/// The dense sweep of `M` for one camera at `t` seconds (see the module
/// documentation); `mask` restricts the metering as the controller's does.
pub fn sweep(
    render: &SimRender,
    camera: usize,
    t: f64,
    options: &SweepOptions,
    mask: Option<&RoiMask>,
) -> Result<Sweep> {
    if !(options.lo > 0.0 && options.hi > options.lo && options.steps >= 2) {
        return Err(Error::invalid(
            "sweep",
            "range and steps",
            "0 < lo < hi and at least 2 steps",
            format_args!(
                "from {} to {} in {} steps",
                options.lo, options.hi, options.steps
            ),
        ));
    }
    let meter = Meter::new(options.metering)?;
    let mut est = Estimator::new(EstimatorConfig {
        metric: options.metric,
        ..Default::default()
    })?;
    let (l0, l1) = (options.lo.log2(), options.hi.log2());
    let mut exposures = Vec::with_capacity(options.steps);
    let mut scores = Vec::with_capacity(options.steps);
    for k in 0..options.steps {
        let e = (l0 + (l1 - l0) * k as f64 / (options.steps - 1) as f64).exp2();
        let m = est.score(&meter_noise_free(render, camera, t, e, &meter, mask)?);
        exposures.push(e);
        scores.push(m);
    }
    let (kbest, best_score) = scores
        .iter()
        .copied()
        .enumerate()
        .fold((0, f64::MIN), |a, (k, m)| if m > a.1 { (k, m) } else { a });
    Ok(Sweep {
        best: exposures[kbest],
        best_score,
        exposures,
        scores,
    })
}

/// Where and how finely [`fixed_points`] searches.
#[derive(Clone, Debug, PartialEq)]
pub struct FixedPointSearch {
    /// The estimator.
    pub estimator: EstimatorConfig,
    /// Metering.
    pub metering: MeteringConfig,
    /// Lowest exposure level.
    pub lo: f64,
    /// Highest exposure level.
    pub hi: f64,
    /// Scan step, EV.
    pub step_ev: f64,
    /// The exposure of a darker frame of the same moment the estimator
    /// reads saturated pixels from ([`crate::exposure::Darker`]; as after a
    /// probe that measured no better), if any.
    pub darker: Option<f64>,
}

impl Default for FixedPointSearch {
    /// The default estimator and metering, 2⁴ to 2²⁰ µs in steps of 0.1 EV.
    fn default() -> Self {
        Self {
            estimator: EstimatorConfig::default(),
            metering: MeteringConfig::default(),
            lo: 16.0,
            hi: 1_048_576.0,
            step_ev: 0.1,
            darker: None,
        }
    }
}

/// A stable fixed point of the estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FixedPoint {
    /// The exposure level where `γ̂` crosses 1 from below.
    pub exposure: f64,
    /// `γ̂` just above minus just below it: small where `γ̂` crosses 1
    /// smoothly (a loop converges there), large where it jumps across 1 (a
    /// loop with a finite step circles it).
    pub jump: f64,
}

/// The stable fixed points of the estimator for one camera at `t` seconds:
/// the levels in `[lo, hi]` where `γ̂` (γ-equivalent) crosses 1 from below
/// as the exposure grows, scanned every `step_ev` and refined by bisection
/// to about 0.001 EV, on the noise-free render metered like the controller
/// (`mask`).
pub fn fixed_points(
    render: &SimRender,
    camera: usize,
    t: f64,
    mask: Option<&RoiMask>,
    search: &FixedPointSearch,
) -> Result<Vec<FixedPoint>> {
    if !(search.lo > 0.0 && search.hi > search.lo && search.step_ev > 0.0) {
        return Err(Error::invalid(
            "fixed-point search",
            "range and step",
            "0 < lo < hi and a positive step",
            format_args!(
                "from {} to {} in steps of {} EV",
                search.lo, search.hi, search.step_ev
            ),
        ));
    }
    let meter = Meter::new(search.metering)?;
    let mut est = Estimator::new(search.estimator.clone())?;
    let darker = search
        .darker
        .map(|e| meter_noise_free(render, camera, t, e, &meter, mask))
        .transpose()?;
    let mut g = |l: f64| -> Result<f64> {
        let e = l.exp2();
        let m = meter_noise_free(render, camera, t, e, &meter, mask)?;
        let options = EstimateOptions {
            darker: darker.as_ref().zip(search.darker).map(|(image, d)| Darker {
                image,
                ratio: d / e,
            }),
            ..Default::default()
        };
        Ok(est.estimate_with(&m, options)?.gamma_hat - 1.0)
    };
    let (l0, l1) = (search.lo.log2(), search.hi.log2());
    let n = ((l1 - l0) / search.step_ev).ceil().max(1.0) as usize;
    let mut out = Vec::new();
    let mut prev = (l0, g(l0)?);
    for k in 1..=n {
        let l = l0 + (l1 - l0) * k as f64 / n as f64;
        let v = g(l)?;
        if prev.1 < 0.0 && v >= 0.0 {
            let (mut a, mut b) = ((prev.0, prev.1), (l, v));
            while b.0 - a.0 > 1e-3 {
                let m = 0.5 * (a.0 + b.0);
                let gm = g(m)?;
                if gm < 0.0 {
                    a = (m, gm);
                } else {
                    b = (m, gm);
                }
            }
            out.push(FixedPoint {
                exposure: (0.5 * (a.0 + b.0)).exp2(),
                jump: b.1 - a.1,
            });
        }
        prev = (l, v);
    }
    Ok(out)
}

/// The true brightness ratio of one overlap.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OverlapTruth {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// At equal exposure, how much brighter `j` sees the overlap than `i`:
    /// the median over the overlap's patches of the mean irradiance in `j`
    /// over that in `i` (`None`: no patch). At exposures `E_i`, `E_j` below
    /// saturation the frames' `r_ij` should be `ratio · E_j / E_i`.
    pub ratio: Option<f64>,
    /// The median over the patches of `|log2(patch ratio / ratio)|`: how much
    /// the patches disagree. Near 0 when both cameras see the same ground in
    /// every patch (the calibration lines up); large when they do not.
    pub spread: Option<f64>,
    /// Patches used.
    pub patches: usize,
}

/// The true ratios of every overlap of `view` (built on `render.rig()`) at
/// `t` seconds.
pub fn overlap_ratios(
    render: &SimRender,
    view: &SurroundView,
    t: f64,
) -> Result<Vec<OverlapTruth>> {
    let n = render.cameras().len();
    for layer in view.layers() {
        let info = render
            .cameras()
            .get(layer.camera)
            .ok_or(Error::CameraIndex {
                index: layer.camera,
                count: n,
            })?;
        if layer.source != (info.width, info.height) {
            return Err(Error::SizeMismatch {
                what: "surround view against the simulated camera",
                expected_width: info.width,
                expected_height: info.height,
                width: layer.source.0,
                height: layer.source.1,
            });
        }
    }
    let irr = (0..n)
        .map(|c| render.irradiance(c, t))
        .collect::<Result<Vec<_>>>()?;
    let mean = |c: usize, px: &[u32]| {
        let s: f64 = px.iter().map(|&k| f64::from(irr[c][k as usize])).sum();
        s / px.len().max(1) as f64
    };
    Ok(view
        .overlaps()
        .iter()
        .map(|o| {
            let mut r: Vec<f64> = o
                .patches
                .iter()
                .filter(|p| !p.pixels_i.is_empty() && !p.pixels_j.is_empty())
                .map(|p| mean(o.j, &p.pixels_j) / mean(o.i, &p.pixels_i).max(1e-30))
                .collect();
            let ratio = median(&mut r);
            let spread = ratio.and_then(|m| {
                let mut d: Vec<f64> = r.iter().map(|p| (p / m).log2().abs()).collect();
                median(&mut d)
            });
            OverlapTruth {
                i: o.i,
                j: o.j,
                patches: r.len(),
                ratio,
                spread,
            }
        })
        .collect())
}

/// The dynamic range of the scene as the cameras see it at one moment.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DynamicRange {
    /// The darkest lit pixel's irradiance.
    pub darkest: f64,
    /// The brightest pixel's irradiance (the sun's disc, if seen).
    pub brightest: f64,
    /// The 0.01 % quantile.
    pub low: f64,
    /// The 99.99 % quantile.
    pub high: f64,
}

impl DynamicRange {
    /// `high / low`: the range that all but one pixel in 10⁴ at either end
    /// span (so neither a few stray pixels nor the sun's disc count).
    pub fn ratio(&self) -> f64 {
        self.high / self.low.max(1e-30)
    }
}

/// The irradiance quantiles over every pixel of every camera that sees
/// anything (inside the lens's image circle) at `t` seconds.
pub fn dynamic_range(render: &SimRender, t: f64) -> Result<DynamicRange> {
    let mut all = Vec::new();
    for c in 0..render.cameras().len() {
        all.extend(render.irradiance(c, t)?.into_iter().filter(|&v| v > 0.0));
    }
    if all.is_empty() {
        return Err(Error::invalid(
            "dynamic range",
            "lit pixels",
            "a camera that sees something lit",
            "none",
        ));
    }
    let n = all.len();
    let q = |all: &mut Vec<f32>, f: f64| {
        let k = ((n - 1) as f64 * f).round() as usize;
        f64::from(*all.select_nth_unstable_by(k, f32::total_cmp).1)
    };
    Ok(DynamicRange {
        low: q(&mut all, 1e-4),
        high: q(&mut all, 1.0 - 1e-4),
        darkest: q(&mut all, 0.0),
        brightest: q(&mut all, 1.0),
    })
}
