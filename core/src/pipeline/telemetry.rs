//! What the pipeline records per frame set: each camera's exposure state,
//! each overlap's brightness ratio, the set rate and the time each stage
//! took. The app plots it and writes it as CSV.

use std::collections::VecDeque;
use std::io::{self, Write};

/// Milliseconds each stage of one frame set took.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct StageTimes {
    /// The source producing the set (for the simulator, rendering it; for
    /// live cameras, waiting for the trigger and assembling it).
    pub capture_ms: f64,
    /// Waiting in the queue between capture and processing.
    pub queue_ms: f64,
    /// Metering every camera (and the overlap patches).
    pub meter_ms: f64,
    /// The controller (estimates, laws, balancing, split).
    pub control_ms: f64,
    /// Composing the view.
    pub compose_ms: f64,
    /// From the set being ready to its processing being done.
    pub total_ms: f64,
}

impl StageTimes {
    /// The stages' names, in the order of [`StageTimes::values`].
    pub const NAMES: [&'static str; 6] =
        ["capture", "queue", "meter", "control", "compose", "total"];

    /// The stages' times, in the order of [`StageTimes::NAMES`].
    pub fn values(&self) -> [f64; 6] {
        [
            self.capture_ms,
            self.queue_ms,
            self.meter_ms,
            self.control_ms,
            self.compose_ms,
            self.total_ms,
        ]
    }
}

/// The panorama's columns per overlap (after the ratios), in order.
pub const MATCH_COLUMNS: [&str; 6] = [
    "matches",
    "inliers",
    "error_px",
    "refined_before_px",
    "refined_after_px",
    "no_ratio",
];

/// One camera in one frame set.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CameraRow {
    /// Shutter the frame was taken with, µs.
    pub shutter_us: f64,
    /// Gain the frame was taken with, dB.
    pub gain_db: f64,
    /// `E = shutter_us · 10^(gain_dB/20)`.
    pub exposure: f64,
    /// The estimate γ̂ (γ-equivalent for scale-and-clip).
    pub gamma_hat: Option<f64>,
    /// The gradient information M of the frame as taken.
    pub m: Option<f64>,
    /// Mean metered luminance in [0, 1].
    pub mean: f64,
    /// The exposure level commanded after this frame, if a command was sent.
    pub command: Option<f64>,
    /// Whether the frame was taken at a probe's darker exposure.
    pub probe: bool,
}

/// One overlap of the panorama in one frame set: what its latest matching
/// found.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairMatchRow {
    /// Mutual matches.
    pub matches: usize,
    /// RANSAC's inliers (0 when fewer than needed).
    pub inliers: usize,
    /// The inliers' median reprojection error with the rotations in use,
    /// panorama pixels.
    pub error_px: Option<f64>,
    /// The latest refinement's median error before it.
    pub refined_before_px: Option<f64>,
    /// The same after it.
    pub refined_after_px: Option<f64>,
    /// Why the pair has no ratio, if it has none.
    pub no_ratio: Option<String>,
}

impl PairMatchRow {
    /// The row of pair `p`, whose ratio is `log2_r`.
    pub fn of(p: &super::PairMatchReport, log2_r: Option<f64>) -> Self {
        let no_ratio = match (log2_r, &p.problem) {
            (Some(_), _) => None,
            (None, Some(problem)) => Some(problem.clone()),
            (None, None) => Some(format!(
                "none of the {} patches around its inliers is usable (saturated or near black)",
                p.patches
            )),
        };
        Self {
            matches: p.matches,
            inliers: p.inliers,
            error_px: p.error_px,
            refined_before_px: p.refined_before_px,
            refined_after_px: p.refined_after_px,
            no_ratio,
        }
    }
}

/// One frame set.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TelemetryRow {
    /// The set's trigger number.
    pub trigger: u64,
    /// Seconds since the first set (from the sets' timestamps).
    pub time_s: f64,
    /// Per camera, in rig order.
    pub cameras: Vec<CameraRow>,
    /// Per overlap (in [`Telemetry::pair_names`] order), `log2 r_ij`.
    pub log2_r: Vec<Option<f64>>,
    /// Frame sets per second reaching processing, over the last second.
    pub set_rate_hz: f64,
    /// Stage times.
    pub times: StageTimes,
    /// Sets dropped before processing so far.
    pub dropped: u64,
    /// Per overlap, the panorama's matches (empty for the surround view).
    pub matches: Vec<PairMatchRow>,
}

impl TelemetryRow {
    /// The row of one processed set: `time_s` since the first set, the set
    /// rate and the drops so far.
    pub fn of(output: &super::Output, time_s: f64, set_rate_hz: f64, dropped: u64) -> Self {
        Self {
            trigger: output.trigger,
            time_s,
            cameras: output
                .cameras
                .iter()
                .map(|c| CameraRow {
                    shutter_us: c.taken.shutter_us,
                    gain_db: c.taken.gain_db,
                    exposure: c.taken.exposure(),
                    gamma_hat: c.estimate.as_ref().map(|e| e.gamma_hat),
                    m: c.estimate.as_ref().map(|e| e.m_current),
                    mean: f64::from(c.mean),
                    command: c.command.map(|s| s.exposure()),
                    probe: c.probe_frame,
                })
                .collect(),
            log2_r: output.pairs.iter().map(|p| p.log2_r).collect(),
            set_rate_hz,
            times: output.times,
            dropped,
            matches: output
                .panorama
                .as_ref()
                .map(|r| {
                    output
                        .pairs
                        .iter()
                        .map(|p| {
                            r.pair(p.i, p.j)
                                .map(|m| PairMatchRow::of(m, p.log2_r))
                                .unwrap_or_default()
                        })
                        .collect()
                })
                .unwrap_or_default(),
        }
    }
}

/// The most recent rows, a bounded history.
#[derive(Clone, Debug)]
pub struct Telemetry {
    camera_names: Vec<String>,
    pair_names: Vec<String>,
    pairs: Vec<(usize, usize)>,
    rows: VecDeque<TelemetryRow>,
    capacity: usize,
    total: u64,
    /// Whether a row has the panorama's matches (the CSV then has their
    /// columns).
    matched: bool,
}

impl Telemetry {
    /// An empty history of at most `capacity` rows for these cameras and
    /// overlaps (`pairs` are camera index pairs).
    pub fn new(camera_names: Vec<String>, pairs: &[(usize, usize)], capacity: usize) -> Self {
        let mut t = Self {
            camera_names,
            pair_names: Vec::new(),
            pairs: Vec::new(),
            rows: VecDeque::new(),
            capacity: capacity.max(1),
            total: 0,
            matched: false,
        };
        t.set_pairs(pairs);
        t
    }

    /// Replaces the overlaps (after a new calibration); the history stays,
    /// and rows recorded before have the old overlaps' ratios.
    pub fn set_pairs(&mut self, pairs: &[(usize, usize)]) {
        self.pairs = pairs.to_vec();
        self.pair_names = pairs
            .iter()
            .map(|&(i, j)| format!("{}-{}", self.name(i), self.name(j)))
            .collect();
    }

    fn name(&self, i: usize) -> String {
        self.camera_names
            .get(i)
            .cloned()
            .unwrap_or_else(|| format!("camera{i}"))
    }

    /// The cameras' names.
    pub fn camera_names(&self) -> &[String] {
        &self.camera_names
    }

    /// The overlaps' names, "front-left" and so on.
    pub fn pair_names(&self) -> &[String] {
        &self.pair_names
    }

    /// The overlaps as camera index pairs.
    pub fn pairs(&self) -> &[(usize, usize)] {
        &self.pairs
    }

    /// Adds a row, forgetting the oldest when full.
    pub fn push(&mut self, row: TelemetryRow) {
        if self.rows.len() >= self.capacity {
            self.rows.pop_front();
        }
        self.matched |= !row.matches.is_empty();
        self.rows.push_back(row);
        self.total += 1;
    }

    /// The rows kept, oldest first.
    pub fn rows(&self) -> &VecDeque<TelemetryRow> {
        &self.rows
    }

    /// The newest row.
    pub fn last(&self) -> Option<&TelemetryRow> {
        self.rows.back()
    }

    /// Rows pushed since the start, including those forgotten.
    pub fn total(&self) -> u64 {
        self.total
    }

    /// The CSV header of [`Telemetry::write_csv_row`].
    pub fn write_csv_header(&self, out: &mut impl Write) -> io::Result<()> {
        let mut cols = vec![
            "trigger".to_owned(),
            "time_s".to_owned(),
            "set_rate_hz".to_owned(),
            "dropped".to_owned(),
        ];
        for n in StageTimes::NAMES {
            cols.push(format!("{n}_ms"));
        }
        for c in &self.camera_names {
            for f in [
                "shutter_us",
                "gain_db",
                "exposure",
                "gamma_hat",
                "m",
                "mean",
                "command",
                "probe",
            ] {
                cols.push(format!("{c}.{f}"));
            }
        }
        for p in &self.pair_names {
            cols.push(format!("log2_r.{p}"));
        }
        if self.matched {
            for p in &self.pair_names {
                for f in MATCH_COLUMNS {
                    cols.push(format!("{f}.{p}"));
                }
            }
        }
        writeln!(out, "{}", cols.join(","))
    }

    /// One row as CSV; a value that is not known is an empty field.
    pub fn write_csv_row(&self, out: &mut impl Write, row: &TelemetryRow) -> io::Result<()> {
        fn opt(v: Option<f64>) -> String {
            v.map_or_else(String::new, |v| format!("{v}"))
        }
        let mut f = vec![
            row.trigger.to_string(),
            format!("{:.6}", row.time_s),
            format!("{:.3}", row.set_rate_hz),
            row.dropped.to_string(),
        ];
        f.extend(row.times.values().iter().map(|v| format!("{v:.3}")));
        for k in 0..self.camera_names.len() {
            let c = row.cameras.get(k).copied().unwrap_or_default();
            f.push(format!("{}", c.shutter_us));
            f.push(format!("{}", c.gain_db));
            f.push(format!("{}", c.exposure));
            f.push(opt(c.gamma_hat));
            f.push(opt(c.m));
            f.push(format!("{}", c.mean));
            f.push(opt(c.command));
            f.push(u8::from(c.probe).to_string());
        }
        for k in 0..self.pair_names.len() {
            f.push(opt(row.log2_r.get(k).copied().flatten()));
        }
        if self.matched {
            for k in 0..self.pair_names.len() {
                match row.matches.get(k) {
                    Some(m) => {
                        f.push(m.matches.to_string());
                        f.push(m.inliers.to_string());
                        f.push(opt(m.error_px));
                        f.push(opt(m.refined_before_px));
                        f.push(opt(m.refined_after_px));
                        // A reason is one field: no commas or quotes.
                        f.push(
                            m.no_ratio
                                .as_deref()
                                .unwrap_or_default()
                                .replace([',', '"', '\n'], ";"),
                        );
                    }
                    None => f.extend(std::iter::repeat_n(String::new(), MATCH_COLUMNS.len())),
                }
            }
        }
        writeln!(out, "{}", f.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(trigger: u64) -> TelemetryRow {
        TelemetryRow {
            trigger,
            time_s: trigger as f64 * 0.05,
            cameras: vec![
                CameraRow {
                    shutter_us: 1000.0,
                    gain_db: 0.0,
                    exposure: 1000.0,
                    gamma_hat: Some(1.25),
                    m: Some(3000.0),
                    mean: 0.4,
                    command: None,
                    probe: true,
                };
                2
            ],
            log2_r: vec![Some(-0.5)],
            ..Default::default()
        }
    }

    #[test]
    fn the_history_keeps_the_newest_rows() {
        let mut t = Telemetry::new(vec!["front".into(), "left".into()], &[(0, 1)], 3);
        for k in 0..5 {
            t.push(row(k));
        }
        let kept: Vec<u64> = t.rows().iter().map(|r| r.trigger).collect();
        assert_eq!(kept, vec![2, 3, 4]);
        assert_eq!(t.total(), 5);
        assert_eq!(t.pair_names(), ["front-left"]);
    }

    #[test]
    fn csv_rows_have_as_many_fields_as_the_header() {
        let t = Telemetry::new(vec!["front".into(), "left".into()], &[(0, 1)], 3);
        let mut out = Vec::new();
        t.write_csv_header(&mut out).ok();
        t.write_csv_row(&mut out, &row(7)).ok();
        let text = String::from_utf8(out).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 2);
        let header: Vec<&str> = lines[0].split(',').collect();
        let fields: Vec<&str> = lines[1].split(',').collect();
        assert_eq!(header.len(), fields.len());
        let at = |name: &str| header.iter().position(|h| *h == name);
        assert_eq!(at("front.gamma_hat").map(|k| fields[k]), Some("1.25"));
        assert_eq!(at("left.command").map(|k| fields[k]), Some(""));
        assert_eq!(at("left.probe").map(|k| fields[k]), Some("1"));
        assert_eq!(at("log2_r.front-left").map(|k| fields[k]), Some("-0.5"));
        assert_eq!(fields[0], "7");
        assert!(!header.iter().any(|h| h.starts_with("inliers.")));
    }

    #[test]
    fn the_panoramas_matches_have_columns_and_a_reason_is_one_field() {
        let mut t = Telemetry::new(vec!["front".into(), "left".into()], &[(0, 1)], 3);
        let mut r = row(3);
        r.matches = vec![PairMatchRow {
            matches: 40,
            inliers: 31,
            error_px: Some(0.4),
            no_ratio: Some("3 matches, 2 inliers: too few".into()),
            ..Default::default()
        }];
        t.push(r.clone());
        let mut out = Vec::new();
        t.write_csv_header(&mut out).ok();
        t.write_csv_row(&mut out, &r).ok();
        let text = String::from_utf8(out).unwrap_or_default();
        let lines: Vec<&str> = text.lines().collect();
        let header: Vec<&str> = lines[0].split(',').collect();
        let fields: Vec<&str> = lines[1].split(',').collect();
        assert_eq!(header.len(), fields.len());
        let at = |name: &str| header.iter().position(|h| *h == name).map(|k| fields[k]);
        assert_eq!(at("matches.front-left"), Some("40"));
        assert_eq!(at("inliers.front-left"), Some("31"));
        assert_eq!(at("error_px.front-left"), Some("0.4"));
        assert_eq!(
            at("no_ratio.front-left"),
            Some("3 matches; 2 inliers: too few")
        );
    }
}
