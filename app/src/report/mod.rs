//! What runs report: the summary of a run (sets, drops, latency
//! percentiles and CPU use) here; the panorama's per-pair lines
//! ([`panorama`]); the PNG plot of the exposure state ([`plot`]) and the
//! plots' font and text ([`glyphs`]).

pub mod glyphs;
pub mod panorama;
pub mod plot;

use std::time::Instant;

use rigview_core::pipeline::{PipelineStatus, ProcessingSettings, Telemetry};

use crate::logging::Entry;

/// How exposure is controlled, in a few words: the strategy, the update
/// law and the estimator's exposure simulation.
pub fn control(settings: &ProcessingSettings) -> String {
    format!(
        "{}, {} law, {} simulation",
        settings.strategy.label(),
        settings.controller.law.kind.name(),
        settings.controller.estimator.simulation.name()
    )
}

/// The `q`-quantile of `values` by nearest rank
/// ([`rigview_core::stats::quantile`], reordering them), NaN when empty:
/// the reports' tables print a missing figure as NaN.
pub fn quantile(values: &mut [f64], q: f64) -> f64 {
    rigview_core::stats::quantile(values, q).unwrap_or(f64::NAN)
}

/// The mean of `values`, NaN when empty (as [`quantile`]).
pub fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        f64::NAN
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

/// CPU time this process has used (user + system), seconds, from
/// `/proc/self/stat` (Linux; `None` elsewhere).
pub fn cpu_seconds() -> Option<f64> {
    parse_stat(&std::fs::read_to_string("/proc/self/stat").ok()?)
}

fn parse_stat(text: &str) -> Option<f64> {
    // The command name is in parentheses and may hold spaces.
    let rest = text.rsplit_once(')')?.1;
    let fields: Vec<&str> = rest.split_whitespace().collect();
    // After the name: state is field 3; utime and stime are fields 14, 15.
    let utime: f64 = fields.get(11)?.parse().ok()?;
    let stime: f64 = fields.get(12)?.parse().ok()?;
    // USER_HZ is 100 on every Linux target rigview builds for.
    Some((utime + stime) / 100.0)
}

/// CPU use between two points of a run.
#[derive(Clone, Copy, Debug)]
pub struct CpuMeter {
    wall: Instant,
    cpu: Option<f64>,
}

impl CpuMeter {
    /// Starts measuring.
    pub fn start() -> Self {
        Self {
            wall: Instant::now(),
            cpu: cpu_seconds(),
        }
    }

    /// Seconds since the start.
    pub fn seconds(&self) -> f64 {
        self.wall.elapsed().as_secs_f64()
    }

    /// CPU use since the start, in cores (1.0 = one core busy).
    pub fn cores(&self) -> Option<f64> {
        let wall = self.wall.elapsed().as_secs_f64();
        let used = cpu_seconds()? - self.cpu?;
        (wall > 0.0).then(|| used / wall)
    }
}

/// The events of a run, a line each after a line `messages:` (nothing
/// when there are none).
pub fn messages(entries: &[Entry]) -> String {
    let mut s = String::new();
    if !entries.is_empty() {
        s += "\nmessages:";
        for e in entries {
            s += &format!("\n  {}", e.line());
        }
    }
    s
}

/// A few lines on a finished run.
pub fn summary(status: &PipelineStatus, telemetry: &Telemetry) -> String {
    let mut processing: Vec<f64> = telemetry.rows().iter().map(|r| r.times.total_ms).collect();
    let mut display: Vec<f64> = status.display_latency.iter().map(|l| l[1]).collect();
    let mut s = format!(
        "frame sets: {} from the source, {} processed, {} dropped before processing, {} incomplete",
        status.sets, status.processed, status.capture_queue.dropped, status.incomplete
    );
    if !processing.is_empty() {
        s += &format!(
            "\nset ready → processed: median {:.1} ms, 95 % {:.1} ms, max {:.1} ms (last {} sets)",
            quantile(&mut processing, 0.5),
            quantile(&mut processing, 0.95),
            quantile(&mut processing, 1.0),
            processing.len()
        );
    }
    if !display.is_empty() {
        let over = display.iter().filter(|&&l| l > 100.0).count();
        s += &format!(
            "\nset ready → displayed: median {:.1} ms, 95 % {:.1} ms, 99 % {:.1} ms, max {:.1} ms ({} displayed, {over} over 100 ms)",
            quantile(&mut display, 0.5),
            quantile(&mut display, 0.95),
            quantile(&mut display, 0.99),
            quantile(&mut display, 1.0),
            display.len()
        );
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_known_sample() {
        let mut v = vec![5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(quantile(&mut v, 0.5).to_bits(), 3.0f64.to_bits());
        assert_eq!(quantile(&mut v, 1.0).to_bits(), 5.0f64.to_bits());
        assert!(quantile(&mut [], 0.5).is_nan());
    }

    #[test]
    fn cpu_time_is_read_past_a_name_with_spaces_and_parentheses() {
        let line = "4242 (rig (view) x) S 1 2 3 4 5 6 7 8 9 10 250 130 0 0 20 0 9 0";
        let t = parse_stat(line).unwrap();
        assert!((t - 3.8).abs() < 1e-9, "{t}");
        assert_eq!(parse_stat("garbage"), None);
    }
}
