//! `rigview record --brackets N`: the cameras cycle through N exposures
//! per moment, and every frame that shows a commanded exposure is written
//! into a bracket sequence (see [`super`] and
//! `docs/brackets.md`).
//!
//! Each step of a bracket commands one exposure on every camera, then reads
//! frame sets until each camera's frame reports that exposure in its
//! metadata: how long a command takes to show (the actuation latency) and
//! how the cameras are triggered (free running, software or hardware
//! trigger) do not matter, because what a frame was taken with is read from
//! the frame itself, and the manifest records exactly that. A moment is
//! written once every camera's bracket is complete, so a capture cut short
//! keeps every moment before it.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use rigview_core::exposure::{ExposureSetting, SplitParams, Splitter};
use rigview_core::source::{ExposureCommand, Frame};

use super::export::{levels, BracketFrame, BracketWriter};
use crate::session::capture::{self, CaptureFrom};

/// A frame is taken as showing a commanded exposure when its own exposure
/// lies this close to it (EV): cameras round the exposure time to their
/// line period.
const SHOWN_EV: f64 = 0.05;
/// Frame sets to wait for a command to show before the camera is reported
/// as not applying it.
const WAIT_SETS: usize = 40;
/// How long one frame set may take.
const SET_TIMEOUT: Duration = Duration::from_secs(2);
/// Without `--range-ev`, the brackets span this much (EV) on either side of
/// each camera's exposure at the start.
const DEFAULT_HALF_SPAN_EV: f64 = 3.0;

/// What `rigview record --brackets` captures.
#[derive(Debug)]
pub struct BracketRun {
    /// Where from.
    pub from: CaptureFrom,
    /// The folder of the sequence.
    pub dir: PathBuf,
    /// Exposures per moment.
    pub exposures: usize,
    /// The exposures' range, log2 µs at 0 dB (`None`: ±3 EV around each
    /// camera's exposure at the start).
    pub range_ev: Option<(f64, f64)>,
    /// Moments to capture (`None`: until `seconds` or the source ends).
    pub moments: Option<usize>,
    /// How long (`None`: until `moments` or the source ends).
    pub seconds: Option<f64>,
}

/// Captures `run`, printing each moment; returns a summary.
pub fn capture(run: &BracketRun, out: &mut dyn std::io::Write) -> Result<String> {
    if !(2..=64).contains(&run.exposures) {
        bail!(
            "--brackets {}: expected 2 to 64 exposures per moment",
            run.exposures
        );
    }
    let opened = capture::open(&run.from)?;
    let mut source = opened.source;
    let cameras = source.cameras().to_vec();
    let names: Vec<String> = cameras.iter().map(|c| c.name.clone()).collect();
    // Each camera's exposures, as settings within its ranges (shutter
    // first, then gain).
    let first = loop {
        match source.next_set(SET_TIMEOUT)? {
            Some(set) if set.is_complete() => break set,
            Some(_) => {}
            None if source.is_finished() => bail!("the source ended before its first frame set"),
            None => bail!(
                "no frame set within {} s: are the cameras triggered?",
                SET_TIMEOUT.as_secs()
            ),
        }
    };
    let mut plans = Vec::with_capacity(cameras.len());
    for (cam, frame) in cameras.iter().zip(&first.frames) {
        let start = frame
            .as_ref()
            .map_or(1000.0, |f| f.meta.taken.exposure())
            .log2();
        let (lo, hi) = run
            .range_ev
            .unwrap_or((start - DEFAULT_HALF_SPAN_EV, start + DEFAULT_HALF_SPAN_EV));
        let mut splitter = Splitter::new(cam.range, SplitParams::default())
            .with_context(|| format!("camera \"{}\": its exposure ranges", cam.name))?;
        let (min, max) = (splitter.min_exposure(), splitter.max_exposure());
        let settings: Vec<ExposureSetting> = levels(lo, hi, run.exposures)
            .into_iter()
            .map(|level| splitter.split(level.clamp(min, max)).0)
            .collect();
        plans.push(settings);
    }
    let title = format!(
        "rigview exposure brackets of {}: {} exposures per moment",
        opened.what, run.exposures
    );
    let mut writer = BracketWriter::create(&run.dir, opened.rig.as_ref(), &names, &title)?;
    let started = Instant::now();
    let limit = capture::time_limit(run.seconds)?;
    let mut t0 = None;
    'moments: while run.moments.is_none_or(|m| writer.moments() < m)
        && limit.is_none_or(|l| started.elapsed() < l)
    {
        // Per camera, the frames of this moment's bracket.
        let mut taken: Vec<Vec<Frame>> = vec![Vec::new(); cameras.len()];
        let mut moment_ns = None;
        for k in 0..run.exposures {
            let commands: Vec<ExposureCommand> = plans
                .iter()
                .enumerate()
                .map(|(camera, s)| ExposureCommand {
                    camera,
                    setting: s[k],
                })
                .collect();
            source.apply(&commands)?;
            let mut waiting: Vec<usize> = (0..cameras.len()).collect();
            let mut sets = 0;
            while !waiting.is_empty() {
                let Some(set) = source.next_set(SET_TIMEOUT)? else {
                    if source.is_finished() {
                        break 'moments;
                    }
                    bail!(
                        "no frame set within {} s while waiting for exposure {} of moment {}",
                        SET_TIMEOUT.as_secs(),
                        k,
                        writer.moments()
                    );
                };
                moment_ns.get_or_insert(set.timestamp_ns);
                for m in source.take_messages() {
                    tracing::warn!("{m}");
                }
                waiting.retain(|&cam| {
                    let wanted = plans[cam][k].exposure();
                    match set.frames.get(cam).and_then(Option::as_ref) {
                        Some(f)
                            if f.is_complete()
                                && (f.meta.taken.exposure() / wanted).log2().abs() <= SHOWN_EV =>
                        {
                            taken[cam].push(f.clone());
                            false
                        }
                        _ => true,
                    }
                });
                sets += 1;
                if sets >= WAIT_SETS && !waiting.is_empty() {
                    let who: Vec<String> = waiting
                        .iter()
                        .map(|&c| {
                            let s = plans[c][k];
                            format!(
                                "\"{}\" ({:.1} µs at {:.2} dB)",
                                names[c], s.shutter_us, s.gain_db
                            )
                        })
                        .collect();
                    bail!(
                        "after {WAIT_SETS} frame sets, no frame of camera {} shows the exposure commanded; {} moments were written to {}",
                        who.join(", "),
                        writer.moments(),
                        run.dir.display()
                    );
                }
            }
        }
        let ns = moment_ns.unwrap_or(0);
        let t = ns.saturating_sub(*t0.get_or_insert(ns)) as f64 * 1e-9;
        let frames: Vec<BracketFrame<'_>> = taken
            .iter()
            .enumerate()
            .flat_map(|(camera, frames)| {
                frames.iter().map(move |f| BracketFrame {
                    camera,
                    setting: f.meta.taken,
                    format: f.meta.format,
                    width: f.meta.width,
                    height: f.meta.height,
                    data: &f.data,
                })
            })
            .collect();
        writer.write_moment(t, &frames)?;
        writeln!(
            out,
            "moment {} at {t:.2} s: {} images",
            writer.moments() - 1,
            frames.len()
        )?;
    }
    Ok(format!(
        "{}: {} moments of {} exposures per camera in {:.1} s",
        run.dir.display(),
        writer.moments(),
        run.exposures,
        started.elapsed().as_secs_f64()
    ))
}
