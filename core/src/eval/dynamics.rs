//! How a camera's exposure answers a change of light: frames to settle,
//! overshoot and jitter, measured on a trace of log2 exposure, one value
//! per frame.
//!
//! - **Frames to settle** after a step at frame `s`: the frames until log2
//!   E stays within `tolerance_ev` of its value `window` frames after the
//!   step (the final value), up to that frame.
//! - **Overshoot**: how far log2 E went past the final value, in the
//!   direction of the move, over the window (0 when it never did).
//! - **Jitter**: the standard deviation of log2 E over the last
//!   `jitter_frames` frames of the window.
//!
//! Frames marked excluded (probe frames, which are darker on purpose) are
//! left out of all three.

/// How a step response is measured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ResponseSpec {
    /// Frames after the step whose value counts as final.
    pub window: usize,
    /// Within this of the final value (EV) counts as settled.
    pub tolerance_ev: f64,
    /// Frames at the end of the window the jitter is measured over.
    pub jitter_frames: usize,
}

impl Default for ResponseSpec {
    fn default() -> Self {
        Self {
            window: 30,
            tolerance_ev: 0.1,
            jitter_frames: 20,
        }
    }
}

/// A measured step response.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepResponse {
    /// The frame of the step (the first taken in the new light).
    pub step: usize,
    /// log2 E at the step.
    pub start: f64,
    /// log2 E `window` frames after it.
    pub end: f64,
    /// Frames until it stays within the tolerance of `end`.
    pub settle_frames: usize,
    /// EV past `end` in the direction of the move.
    pub overshoot_ev: f64,
    /// Standard deviation of log2 E at the end of the window, EV.
    pub jitter_ev: f64,
}

/// The response to a step at frame `step` of `log2_e`, leaving out the
/// frames where `excluded` is true; `None` when the trace ends before the
/// window does or every frame of it is excluded.
pub fn step_response(
    log2_e: &[f64],
    excluded: &[bool],
    step: usize,
    spec: &ResponseSpec,
) -> Option<StepResponse> {
    let last = step.checked_add(spec.window)?;
    if last >= log2_e.len() {
        return None;
    }
    let kept = |k: usize| !excluded.get(k).copied().unwrap_or(false);
    let end_frame = (step..=last).rev().find(|&k| kept(k))?;
    let end = log2_e[end_frame];
    let start = log2_e[step];
    let settled_from = (step..=last)
        .rev()
        .take_while(|&k| !kept(k) || (log2_e[k] - end).abs() <= spec.tolerance_ev)
        .last()
        .unwrap_or(last + 1);
    let dir = (end - start).signum();
    let overshoot_ev = (step..=last)
        .filter(|&k| kept(k))
        .map(|k| (log2_e[k] - end) * dir)
        .fold(0.0, f64::max);
    let tail: Vec<f64> = (last + 1 - spec.jitter_frames.min(spec.window + 1)..=last)
        .filter(|&k| kept(k))
        .map(|k| log2_e[k])
        .collect();
    Some(StepResponse {
        step,
        start,
        end,
        settle_frames: settled_from - step,
        overshoot_ev,
        jitter_ev: std_dev(&tail),
    })
}

/// The population standard deviation (0 for fewer than two values).
pub fn std_dev(values: &[f64]) -> f64 {
    if values.len() < 2 {
        return 0.0;
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    (values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// The runs of frames over which `level(frame)` stays the same: `(first,
/// last)` inclusive, for frames `0..frames`.
pub fn constant_runs(frames: usize, level: impl Fn(usize) -> f64) -> Vec<(usize, usize)> {
    let mut runs = Vec::new();
    let mut first = 0;
    for k in 1..=frames {
        if k == frames || (level(k) - level(k - 1)).abs() > 1e-12 {
            if k > first {
                runs.push((first, k - 1));
            }
            first = k;
        }
    }
    runs
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact values of exact traces
mod tests {
    use super::*;

    #[test]
    fn a_first_order_response_settles_where_it_should() {
        // From 10 to 8 EV, halving the distance every frame.
        let mut t = vec![10.0; 5];
        let mut x = 10.0;
        for _ in 0..40 {
            x = 8.0 + (x - 8.0) * 0.5;
            t.push(x);
        }
        let r = step_response(&t, &[], 4, &ResponseSpec::default()).unwrap();
        // 2·0.5^k ≤ 0.1 from k = 5 (frame 4 + 5 = 9; frame 4 is the step).
        assert_eq!(r.settle_frames, 5, "{r:?}");
        assert_eq!(r.overshoot_ev, 0.0);
        assert!(r.jitter_ev < 1e-3, "{r:?}");
        assert!((r.end - 8.0).abs() < 1e-6 && r.start == 10.0);
    }

    #[test]
    fn overshoot_and_excluded_frames() {
        let mut t = vec![8.0, 8.0, 9.5, 9.0, 9.0];
        t.extend(std::iter::repeat_n(9.0, 30));
        // A probe frame, 1 EV dark, late in the window.
        t[20] = 8.0;
        let mut ex = vec![false; t.len()];
        ex[20] = true;
        let spec = ResponseSpec::default();
        let r = step_response(&t, &ex, 1, &spec).unwrap();
        assert!((r.overshoot_ev - 0.5).abs() < 1e-12, "{r:?}");
        assert_eq!(r.settle_frames, 2);
        assert_eq!(r.jitter_ev, 0.0);
        // Counted, the probe frame delays settling to after it.
        let r = step_response(&t, &[], 1, &spec).unwrap();
        assert_eq!(r.settle_frames, 20);
        assert!(step_response(&t, &[], 10, &spec).is_none());
    }

    #[test]
    fn runs_of_constant_light() {
        let level = |k: usize| if (10..20).contains(&k) { 1.0 } else { 0.0 };
        assert_eq!(constant_runs(30, level), vec![(0, 9), (10, 19), (20, 29)]);
        assert_eq!(constant_runs(0, level), vec![]);
    }
}
