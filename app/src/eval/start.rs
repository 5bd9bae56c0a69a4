//! From the start to rest, on a recorded sequence: how many frames each
//! camera takes to settle from where every camera started, how far it
//! went past its rest on the way, and the flicker it shows once there.
//!
//! A bracket sequence has no known steps of light (experiment 2 needs the
//! simulator), but its start is a step: every camera begins at one fixed
//! exposure, usually far from its best. Settling is measured as
//! [`step_response`] measures it after a step of light, with the step at
//! the first frame and the last frame as the final value.
//!
//! **Reaching the best M**: the first frame from which every later frame
//! (probe frames left out) keeps at least [`REACH_FRACTION`] of the
//! camera's best M over the sweep, the issue's own measure of a start.
//!
//! **Flicker** is what the view shows of the exposure moving once the
//! camera has settled: the steps of log2 E from each frame to the next
//! (probe frames, darker or brighter on purpose, left out), as their mean
//! and their largest, EV. A camera that circles, or hops between two levels, flickers
//! even where its settled M is high.

use rigview_core::eval::dynamics::{step_response, ResponseSpec};

use super::closed_loop::Trace;
use super::strategy::EvalStrategy;

/// The share of the best M that [`StartRow::reach_frames`] counts from.
pub const REACH_FRACTION: f64 = 0.9;

/// The fewest frames at rest before the end that count as settled.
pub const MIN_REST: usize = 5;

/// One camera under one strategy, from the start.
#[derive(Clone, Debug, PartialEq)]
pub struct StartRow {
    /// The strategy.
    pub strategy: EvalStrategy,
    /// The camera's name.
    pub camera: String,
    /// log2 E of the first frame.
    pub start_log2_e: f64,
    /// log2 E of the last frame.
    pub end_log2_e: f64,
    /// Frames until log2 E stays within 0.1 EV of the last frame's
    /// (`None`: it did not for the last [`MIN_REST`] frames).
    pub settle_frames: Option<usize>,
    /// Frames until every later frame (probes left out) keeps
    /// [`REACH_FRACTION`] of the best M (`None`: the last does not, or the
    /// best is unknown).
    pub reach_frames: Option<usize>,
    /// How far past the last frame's log2 E it went, EV.
    pub overshoot_ev: f64,
    /// Mean step of log2 E from frame to frame after settling, EV.
    pub flicker_mean_ev: f64,
    /// Largest such step, EV.
    pub flicker_max_ev: f64,
}

impl StartRow {
    /// The CSV header.
    pub const HEADER: &'static str = "strategy,camera,start_log2_e,end_log2_e,settle_frames,frames_to_90pct_m,overshoot_ev,flicker_mean_ev,flicker_max_ev";

    /// A CSV line (`settle_frames` empty when the camera never settled,
    /// `frames_to_90pct_m` when it never reached 90 % of the best M).
    pub fn csv(&self) -> String {
        format!(
            "{},{},{:.4},{:.4},{},{},{:.4},{:.4},{:.4}",
            self.strategy.key(),
            self.camera,
            self.start_log2_e,
            self.end_log2_e,
            self.settle_frames
                .map(|f| f.to_string())
                .unwrap_or_default(),
            self.reach_frames.map(|f| f.to_string()).unwrap_or_default(),
            self.overshoot_ev,
            self.flicker_mean_ev,
            self.flicker_max_ev
        )
    }

    /// Per camera of `trace` (named by `names`), from its first frame;
    /// `fraction(camera, log2 E)` is M there over the camera's best (`None`
    /// where it is not known).
    pub fn of(
        strategy: EvalStrategy,
        trace: &Trace,
        names: &[String],
        fraction: impl Fn(usize, f64) -> Option<f64>,
    ) -> Vec<Self> {
        trace
            .log2_e
            .iter()
            .zip(&trace.probe)
            .enumerate()
            .filter(|(_, (e, _))| e.len() >= 2)
            .map(|(cam, (e, probe))| {
                let spec = ResponseSpec {
                    window: e.len() - 1,
                    ..ResponseSpec::default()
                };
                let response = step_response(e, probe, 0, &spec);
                let settled = response
                    .map(|r| r.settle_frames)
                    .filter(|&f| f + MIN_REST <= e.len());
                // Between frames that are both at rest.
                let steps: Vec<f64> = (settled.map_or(e.len(), |f| f + 1)..e.len())
                    .filter(|&k| !probe[k] && !probe[k - 1])
                    .map(|k| (e[k] - e[k - 1]).abs())
                    .collect();
                let good =
                    |k: usize| probe[k] || fraction(cam, e[k]).is_some_and(|f| f >= REACH_FRACTION);
                let reach_frames = (0..e.len()).rev().take_while(|&k| good(k)).last();
                StartRow {
                    strategy,
                    camera: names.get(cam).cloned().unwrap_or_else(|| cam.to_string()),
                    start_log2_e: e[0],
                    end_log2_e: e[e.len() - 1],
                    settle_frames: settled,
                    reach_frames,
                    overshoot_ev: response.map_or(f64::NAN, |r| r.overshoot_ev),
                    flicker_mean_ev: crate::report::mean(&steps),
                    flicker_max_ev: steps.iter().copied().fold(0.0, f64::max),
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trace(e: Vec<f64>) -> Trace {
        let n = e.len();
        Trace {
            log2_e: vec![e],
            probe: vec![vec![false; n]],
            ..Default::default()
        }
    }

    #[test]
    fn settling_overshoot_and_flicker_from_the_start() {
        // From 11 up past 15 to 14.5, then hopping by 0.04 EV.
        let mut e = vec![11.0, 12.0, 13.5, 15.0, 14.6];
        e.extend((0..20).map(|k| if k % 2 == 0 { 14.5 } else { 14.54 }));
        // M at 90 % or more from 13.5 on, the probe frame left out.
        let mut t = trace(e);
        t.probe[0][10] = true;
        t.log2_e[0][10] = 12.0;
        let fraction = |_: usize, e: f64| Some(if e >= 13.5 { 0.95 } else { 0.5 });
        let rows = StartRow::of(EvalStrategy::Fast, &t, &["front".into()], fraction);
        let r = &rows[0];
        assert_eq!(r.settle_frames, Some(4));
        assert_eq!(r.reach_frames, Some(2));
        assert!((r.overshoot_ev - 0.46).abs() < 1e-9, "{r:?}");
        assert!((r.flicker_mean_ev - 0.04).abs() < 0.005, "{r:?}");
        assert!((r.flicker_max_ev - 0.1).abs() < 1e-9, "{r:?}");
        // A camera still climbing at the end has not settled, and shows no
        // flicker at rest.
        let climbing: Vec<f64> = (0..10).map(|k| 10.0 + 0.5 * f64::from(k)).collect();
        let r = &StartRow::of(EvalStrategy::Mean, &trace(climbing), &[], |_, _| None)[0];
        assert_eq!(r.settle_frames, None);
        assert_eq!(r.reach_frames, None);
        assert_eq!(r.camera, "0");
        assert!(
            r.flicker_mean_ev.is_nan() && r.flicker_max_ev == 0.0,
            "{r:?}"
        );
    }
}
