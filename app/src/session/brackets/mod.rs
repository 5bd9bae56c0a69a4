//! Exposure brackets: for every moment and camera, images of the same
//! scene at several exposures, and a frame source that answers each
//! camera's command with a frame at that exposure, so that a controller can
//! be run in closed loop on real scenes (the paper's protocol). See
//! `docs/brackets.md` for the folder layout.
//!
//! ```text
//! DIR/
//!   brackets.csv          the manifest: camera,moment,time_s,exposure_us,gain_db,file[,pattern][,bits]
//!   rig.yaml              the rig's calibration (any format `rigview calib` reads)
//!   front/000000_00.png   the images (8-bit or 16-bit grey PNG, grey or a Bayer mosaic)
//! ```
//!
//! [`BracketSource`] gives one set per moment. Each camera's command takes
//! effect after one frame of latency, as on the simulated rig, and is
//! answered in one of two ways ([`BracketMode`]):
//!
//! - `emulate` (the default): the frame at the exposure asked, synthesised
//!   from the moment's brackets of that camera (`rigview_core::hdr`: the
//!   radiance merged once per moment and camera, then scaled, given the
//!   sensor's noise, clipped and quantised), the level clamped to the
//!   brackets' span widened by [`MARGIN_EV`] on each side;
//! - `nearest`: the bracket whose exposure level `shutter · gain` is
//!   nearest in log exposure; the camera reports the brackets' levels as
//!   its only ones.
//!
//! Either way the frame's metadata carries the exposure the frame was
//! made at, so the controller sees what it got.
//!
//! The folder's manifest is `manifest.rs`, the emulation's cache
//! `emulate.rs`, the leave-one-out check (`rigview eval check-emulation`)
//! `check.rs`, the writer and the export from the simulated rig
//! `export.rs`, and the capture from cameras (`rigview record --brackets`)
//! [`capture`].

pub mod capture;
mod check;
mod emulate;
mod export;
mod import;
mod manifest;

use std::path::Path;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use rigview_core::exposure::{ExposureRange, ExposureSetting};
use rigview_core::source::{
    check_command, wait_until, CameraInfo, ExposureCommand, Frame, FrameMeta, FrameSet,
    FrameSource, FrameStatus, RateMeter, SourceError, StreamHealth,
};

pub use check::{check_emulation, CheckOptions, CheckReport, LevelFigures};
pub use emulate::{Emulator, MARGIN_EV};
pub use export::{export, levels, parse_range_ev, BracketFrame, BracketWriter, ExportSpec};
pub use import::{import, parse_exposure, ImportSpec, Imported};
pub use manifest::{
    read_image, read_manifest, read_png, BracketImage, Decoded, Layout, Manifest, Moment,
    ResponseKind, SensorNotes, COLUMNS, MANIFEST, OPTIONAL, RIG,
};

/// How a bracket source answers a command.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum BracketMode {
    /// The bracket nearest in log exposure.
    Nearest,
    /// A frame synthesised at the exposure asked (docs/brackets.md).
    #[default]
    Emulate,
}

/// How to open a bracket sequence.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BracketOptions {
    /// Where every camera starts.
    pub start: ExposureSetting,
    /// Nearest bracket or emulation.
    pub mode: BracketMode,
    /// The seed of the emulated frames' noise.
    pub seed: u64,
    /// Serve each moment at its time (`time_s`, from the first moment's)
    /// on the wall clock, as cameras would; otherwise whenever asked (the
    /// evaluation and headless runs, in lock step).
    pub realtime: bool,
}

impl BracketOptions {
    /// `mode`, starting at `start`, with the default seed, served whenever
    /// asked.
    pub fn new(start: ExposureSetting, mode: BracketMode) -> Self {
        Self {
            start,
            mode,
            seed: 0x0b2a_c4e7,
            realtime: false,
        }
    }
}

/// The index of the image of `bracket` (ascending exposure) nearest to
/// `exposure` in log exposure (the darker of two equally near).
pub fn nearest(bracket: &[BracketImage], exposure: f64) -> usize {
    let target = exposure.max(f64::MIN_POSITIVE).ln();
    let mut best = (0, f64::INFINITY);
    for (k, b) in bracket.iter().enumerate() {
        let d = (b.setting.exposure().ln() - target).abs();
        if d < best.1 - 1e-12 {
            best = (k, d);
        }
    }
    best.0
}

/// The exposure levels of camera `cam`'s brackets when every moment has
/// the same (within 0.01 EV); `None` when they vary.
fn common_levels(manifest: &Manifest, cam: usize) -> Option<Vec<f64>> {
    let levels = |m: &Moment| -> Vec<f64> {
        m.cameras
            .get(cam)
            .map(|b| b.iter().map(|i| i.setting.exposure()).collect())
            .unwrap_or_default()
    };
    let first = levels(manifest.moments.first()?);
    manifest
        .moments
        .iter()
        .all(|m| {
            let l = levels(m);
            l.len() == first.len()
                && l.iter()
                    .zip(&first)
                    .all(|(a, b)| (a / b).log2().abs() <= 0.01)
        })
        .then_some(first)
}

/// A bracket sequence as a frame source (see the module documentation).
#[derive(Debug)]
pub struct BracketSource {
    cameras: Vec<CameraInfo>,
    manifest: Manifest,
    settings: Vec<ExposureSetting>,
    queued: Vec<(u64, ExposureCommand)>,
    next: u64,
    health: Vec<StreamHealth>,
    /// Sets served per second (the window's stream rates).
    rate: RateMeter,
    emulator: Option<Emulator>,
    /// [`BracketOptions::realtime`]: when the first moment was served.
    realtime: bool,
    started: Option<Instant>,
}

/// Frames between a command and the first frame that shows it.
const LATENCY: u64 = 1;

impl BracketSource {
    /// The sequence in `dir` for a rig of `names` (rig order).
    pub fn open(dir: &Path, names: &[String], options: &BracketOptions) -> Result<Self> {
        let manifest = read_manifest(dir, names)?;
        let first = &manifest.moments[0];
        let emulator = match options.mode {
            BracketMode::Nearest => None,
            BracketMode::Emulate => Some(Emulator::new(&manifest, options.seed)?),
        };
        // Each camera's tone curve, for scale-and-clip: from its response
        // (the emulator's, or recovered here for `nearest`).
        let responses = match &emulator {
            Some(e) => (0..names.len()).map(|c| e.response(c).clone()).collect(),
            // (A sequence the recovery cannot solve, e.g. one exposure a
            // moment, is taken as linear, as `nearest` took every one.)
            None => emulate::responses(&manifest).unwrap_or_default(),
        };
        let cameras = names
            .iter()
            .zip(&first.cameras)
            .enumerate()
            .map(|(cam, (name, images))| {
                let d = read_image(&manifest, &images[0])?;
                let (range, levels) = match &emulator {
                    Some(e) => (e.range(cam), None),
                    None => (ExposureRange::default(), common_levels(&manifest, cam)),
                };
                Ok(CameraInfo {
                    name: name.clone(),
                    format: d.format,
                    width: d.width,
                    height: d.height,
                    range,
                    levels,
                    tone_curve: responses
                        .get(cam)
                        .map(emulate::tone_curve)
                        .transpose()?
                        .flatten(),
                })
            })
            .collect::<Result<Vec<_>>>()?;
        Ok(Self {
            settings: vec![options.start; cameras.len()],
            health: vec![StreamHealth::default(); cameras.len()],
            rate: RateMeter::default(),
            cameras,
            manifest,
            queued: Vec::new(),
            next: 0,
            emulator,
            realtime: options.realtime,
            started: None,
        })
    }

    /// The manifest.
    pub fn manifest(&self) -> &Manifest {
        &self.manifest
    }

    /// How it answers commands.
    pub fn mode(&self) -> BracketMode {
        if self.emulator.is_some() {
            BracketMode::Emulate
        } else {
            BracketMode::Nearest
        }
    }

    fn produce(&mut self) -> Result<FrameSet> {
        let n = self.next;
        let (due, later): (Vec<_>, Vec<_>) = self.queued.drain(..).partition(|(at, _)| *at <= n);
        self.queued = later;
        for (_, c) in due {
            self.settings[c.camera] = c.setting;
        }
        let moment = &self.manifest.moments[n as usize];
        let timestamp_ns = (moment.time_s * 1e9).round().max(0.0) as u64;
        let mut frames = Vec::with_capacity(self.cameras.len());
        for (i, info) in self.cameras.iter().enumerate() {
            let bracket = &moment.cameras[i];
            let (taken, d) = match &mut self.emulator {
                Some(e) => e.frame(&self.manifest, n as usize, i, &self.settings[i])?,
                None => {
                    let image = &bracket[nearest(bracket, self.settings[i].exposure())];
                    (image.setting, read_image(&self.manifest, image)?)
                }
            };
            if (d.format, d.width, d.height) != (info.format, info.width, info.height) {
                bail!(
                    "moment {n}: a {}×{} {} image of camera {}, but its first image is {}×{} {}",
                    d.width,
                    d.height,
                    d.format.genicam_name(),
                    info.name,
                    info.width,
                    info.height,
                    info.format.genicam_name()
                );
            }
            let meta = FrameMeta {
                camera: i,
                format: d.format,
                width: d.width,
                height: d.height,
                taken,
                timestamp_ns,
                frame_id: n,
                status: FrameStatus::Complete,
            };
            frames.push(Some(Frame::new(meta, d.data.into())?));
        }
        let fps = self.rate.tick();
        for h in &mut self.health {
            h.completed += 1;
            h.fps = fps;
        }
        self.next += 1;
        Ok(FrameSet {
            trigger: n,
            timestamp_ns,
            frames,
        })
    }
}

impl FrameSource for BracketSource {
    fn cameras(&self) -> &[CameraInfo] {
        &self.cameras
    }

    fn next_set(&mut self, timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        if self.is_finished() {
            return Ok(None);
        }
        if self.realtime {
            let moments = &self.manifest.moments;
            let since_first = moments[self.next as usize].time_s - moments[0].time_s;
            let start = *self.started.get_or_insert_with(Instant::now);
            let due = start + Duration::from_secs_f64(since_first.max(0.0));
            if !wait_until(due, timeout) {
                return Ok(None);
            }
        }
        self.produce()
            .map(Some)
            .map_err(|e| SourceError::Failed(format!("{e:#}")))
    }

    fn apply(&mut self, commands: &[ExposureCommand]) -> Result<(), SourceError> {
        for c in commands {
            check_command(c, self.cameras.len())?;
            self.queued.push((self.next + LATENCY, *c));
        }
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.health.clone()
    }

    fn is_finished(&self) -> bool {
        self.next as usize >= self.manifest.moments.len()
    }
}

/// Opens the bracket sequence in `dir` with its calibration `dir/rig.yaml`
/// (or `rig`): the source and the rig.
pub fn open_with_rig(
    dir: &Path,
    rig: Option<&Path>,
    options: &BracketOptions,
) -> Result<(BracketSource, rigview_calib::rig::Rig)> {
    let rig_file = rig.map_or_else(|| dir.join(RIG), Path::to_path_buf);
    let loaded = rigview_calib::formats::load(&rig_file, None, None)
        .with_context(|| format!("loading the calibration {}", rig_file.display()))?;
    let names: Vec<String> = loaded.rig.cameras.iter().map(|c| c.name.clone()).collect();
    let source = BracketSource::open(dir, &names, options)?;
    Ok((source, loaded.rig))
}

#[cfg(test)]
mod tests;
