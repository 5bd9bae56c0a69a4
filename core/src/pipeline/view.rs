//! The view a [`super::Processor`] composes: the bird's-eye surround view
//! or the cylindrical panorama. Both are a [`Mosaic`] the same composer,
//! display gains and seam bands work on; they differ in what is metered
//! and where the overlap ratios `r_ij` come from.
//!
//! | | surround | panorama |
//! | --- | --- | --- |
//! | metered ([`MeterRoi::Ground`]) | the ground that reaches the canvas | every pixel that reaches the cylinder |
//! | overlap patches | fixed by the calibration, measured every set | around matched features (Harris + BRIEF + RANSAC) |
//!
//! # The live panorama
//!
//! Matching the four overlaps takes longer than a set period at 20 Hz, so
//! a [`LivePanorama`] matches on a worker thread of its own, on every
//! [`PanoramaSettings::match_every`]-th set while the worker is free, and
//! holds each pair's last matching that gave patches in between, for up to
//! [`PanoramaSettings::hold_sets`] sets: a matching with too few inliers
//! does not take a pair's ratio away at once, so that a pair on the edge
//! of the inlier count does not switch its cameras between balanced and
//! alone every few matchings (a flicker of the view). Their patches were measured at the
//! exposures of the matched set; each set sees them at its own exposures,
//! scaled by `E_now / E_matched` per camera as a linear sensor's brightness
//! scales (a patch scaled into saturation counts as saturated, one
//! saturated when matched stays so), so that the balancing never acts on
//! ratios of exposures that have since changed.
//!
//! Refinement ([`crate::panorama::refine_in_rounds`]: matching and
//! refining in [`PanoramaSettings::refine_rounds`] rounds on a cylinder
//! with a floor) runs on the same worker, when asked
//! ([`super::Control::Refine`]) or every
//! [`PanoramaSettings::refine_every`] sets, from the set at hand; the
//! worker also builds the refined panorama, which the processor takes in
//! at the start of a later set. Neither ever waits on the per-set path.

use std::sync::mpsc::{self, Receiver, Sender, TryRecvError};
use std::sync::Arc;
use std::time::Instant;

use rigview_calib::rig::Rig;

use super::{MeterRoi, PanoramaSettings, ViewKind};
use crate::error::{Error, Result};
use crate::exposure::controller::PairObservation;
use crate::exposure::metering::SATURATED_LEVEL;
use crate::exposure::{FrameView, PatchPair};
use crate::image::RoiMask;
use crate::panorama::{
    refine_in_rounds, Detector, FeatureMatch, MatchOptions, PairMatches, Panorama, PanoramaOptions,
    RefineOptions, RoundsOptions,
};
use crate::source::FrameSet;
use crate::surround::{Mosaic, SurroundView};

mod bowl;
mod worker;

#[cfg(test)]
use bowl::MOTION_FOR_TESTS;
pub use bowl::{BowlSettings, LiveBowl};

use worker::{Done, Job, Worker};

/// The corner detector of a live panorama's matching (see
/// [`crate::panorama::Detector`]), shared with its worker thread. The app
/// hands in OpenCV's Harris corners.
pub type SharedDetector =
    Arc<dyn Fn(&[u8], usize, usize, &[u8]) -> Result<Vec<[f32; 2]>> + Send + Sync>;

/// The view the processor composes.
#[derive(Debug)]
pub enum View {
    /// The bird's-eye surround view.
    Surround(Box<SurroundView>),
    /// The cylindrical panorama, with its matching and refinement.
    Panorama(Box<LivePanorama>),
    /// The bowl around the vehicle from a viewpoint, metered and balanced
    /// on the bird's-eye view.
    Bowl(Box<LiveBowl>),
}

impl From<SurroundView> for View {
    fn from(v: SurroundView) -> Self {
        Self::Surround(Box::new(v))
    }
}

impl From<LivePanorama> for View {
    fn from(p: LivePanorama) -> Self {
        Self::Panorama(Box::new(p))
    }
}

impl View {
    /// Builds the view `kind` of `rig` (poses in the vehicle frame); the
    /// surround view on `canvas`, the panorama as `panorama` says, the bowl
    /// as `bowl` says (balanced on `canvas`, its plan for `blend` built).
    pub fn build(
        kind: ViewKind,
        rig: &Rig,
        canvas: &crate::surround::CanvasSpec,
        panorama: &PanoramaSettings,
        (bowl, blend): (&BowlSettings, crate::surround::BlendMode),
        detector: SharedDetector,
    ) -> Result<Self> {
        Ok(match kind {
            ViewKind::Surround => Self::Surround(Box::new(SurroundView::build(
                rig,
                canvas,
                &crate::surround::SurroundOptions::default(),
            )?)),
            ViewKind::Panorama => Self::Panorama(Box::new(LivePanorama::new(
                rig.clone(),
                panorama,
                detector,
            )?)),
            ViewKind::Bowl => Self::Bowl(Box::new(LiveBowl::new(rig, canvas, bowl, blend)?)),
        })
    }

    /// Which view this is.
    pub fn kind(&self) -> ViewKind {
        match self {
            Self::Surround(_) => ViewKind::Surround,
            Self::Panorama(_) => ViewKind::Panorama,
            Self::Bowl(_) => ViewKind::Bowl,
        }
    }

    /// The maps, weights and overlaps the cameras are metered and balanced
    /// on (the bowl's: the bird's-eye view's).
    pub fn mosaic(&self) -> &Mosaic {
        match self {
            Self::Surround(v) => v,
            Self::Panorama(p) => p.panorama.mosaic(),
            Self::Bowl(b) => b.surround(),
        }
    }

    /// The maps, weights and plans of what is shown: the bowl's picture
    /// for the bowl, otherwise [`View::mosaic`].
    pub fn display_mosaic(&self) -> &Mosaic {
        match self {
            Self::Bowl(b) => b.shown().mosaic(),
            _ => self.mosaic(),
        }
    }

    /// Per camera, the pixels [`MeterRoi::Ground`] meters: the ground that
    /// reaches the bird's-eye view, or everything that reaches the
    /// panorama.
    pub fn meter_masks(&self, roi: MeterRoi) -> Option<&[RoiMask]> {
        match (self, roi) {
            (_, MeterRoi::Full) => None,
            (Self::Surround(v), MeterRoi::Ground) => Some(v.ground_masks()),
            (Self::Panorama(p), MeterRoi::Ground) => Some(p.panorama.source_masks()),
            (Self::Bowl(b), MeterRoi::Ground) => Some(b.surround().ground_masks()),
        }
    }

    /// The surround view, if this is it.
    pub fn surround(&self) -> Option<&SurroundView> {
        match self {
            Self::Surround(v) => Some(v),
            Self::Panorama(_) | Self::Bowl(_) => None,
        }
    }

    /// The surround view, if this is it, taken out of the view.
    pub fn into_surround(self) -> Option<SurroundView> {
        match self {
            Self::Surround(v) => Some(*v),
            Self::Panorama(_) | Self::Bowl(_) => None,
        }
    }

    /// The live panorama, if this is it.
    pub fn panorama(&self) -> Option<&LivePanorama> {
        match self {
            Self::Surround(_) | Self::Bowl(_) => None,
            Self::Panorama(p) => Some(p),
        }
    }

    /// The live panorama, to change.
    pub fn panorama_mut(&mut self) -> Option<&mut LivePanorama> {
        match self {
            Self::Surround(_) | Self::Bowl(_) => None,
            Self::Panorama(p) => Some(p),
        }
    }

    /// The live bowl, if this is it.
    pub fn bowl(&self) -> Option<&LiveBowl> {
        match self {
            Self::Bowl(b) => Some(b),
            _ => None,
        }
    }

    /// The live bowl, to change.
    pub fn bowl_mut(&mut self) -> Option<&mut LiveBowl> {
        match self {
            Self::Bowl(b) => Some(b),
            _ => None,
        }
    }
}

/// One overlap of the live panorama as its latest matching and
/// refinement saw it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PairMatchReport {
    /// Camera `i`.
    pub i: usize,
    /// Camera `j`.
    pub j: usize,
    /// Mutual matches found.
    pub matches: usize,
    /// Those RANSAC kept (0 when fewer than needed).
    pub inliers: usize,
    /// The inliers' median reprojection error with the rotations in use,
    /// panorama pixels.
    pub error_px: Option<f64>,
    /// The median error of the inliers the latest refinement used, before
    /// it.
    pub refined_before_px: Option<f64>,
    /// The same after it.
    pub refined_after_px: Option<f64>,
    /// The brightness patches around the inliers.
    pub patches: usize,
    /// Why the pair gives no rotation and no ratio, if it does not.
    pub problem: Option<String>,
    /// The matches, canvas positions (inliers marked), for the overlay.
    pub lines: Vec<FeatureMatch>,
    /// The overlap's band of the canvas (column, row, width, height):
    /// where the two cameras blend and their seam lies.
    pub band: Option<[usize; 4]>,
}

/// What the live panorama's matching and refinement found, as the latest
/// output shows it.
#[derive(Clone, Debug, Default)]
pub struct PanoramaReport {
    /// The set the latest matches come from (`None`: none yet).
    pub matched_trigger: Option<u64>,
    /// How long the latest matching took on its worker, ms.
    pub match_ms: f64,
    /// Per rig neighbour pair.
    pub pairs: Vec<PairMatchReport>,
    /// Refinements applied so far.
    pub refinements: u32,
    /// How long the latest refinement took on the worker, with the
    /// rebuild of the panorama, ms.
    pub refine_ms: f64,
    /// Whether a refinement is running or waiting for matches.
    pub refining: bool,
    /// The latest problem of the matching or the refinement.
    pub problem: Option<String>,
    /// The rig the panorama is built from (refined rotations included):
    /// what "save rig" writes.
    pub rig: Option<Arc<Rig>>,
}

impl PanoramaReport {
    /// The report's line for pair `(i, j)`.
    pub fn pair(&self, i: usize, j: usize) -> Option<&PairMatchReport> {
        self.pairs.iter().find(|p| (p.i, p.j) == (i, j))
    }
}

/// The latest matches and what they give each set: per pair, its latest
/// matching that gave patches, held for up to
/// [`PanoramaSettings::hold_sets`] sets.
#[derive(Debug, Default)]
struct Held {
    pairs: Vec<HeldPair>,
}

/// One pair's held matching.
#[derive(Debug)]
struct HeldPair {
    pair: PairMatches,
    /// The exposures of cameras `i` and `j` in the matched frames.
    taken: (f64, f64),
    /// The set count ([`LivePanorama::sets`]) when it was matched.
    at: u64,
}

impl Held {
    /// Takes a matching in: a pair that gave patches replaces what was held
    /// for it; a pair that gave none (too few inliers) keeps its held
    /// matching, which then ages out. A pair whose ratio comes and goes
    /// with an inlier or two would otherwise switch its cameras between
    /// balanced and alone every few matchings: a flicker of the view.
    fn take(&mut self, matches: Vec<PairMatches>, taken: &[f64], at: u64) {
        let exposure = |k: usize| taken.get(k).copied().unwrap_or(0.0);
        for pair in matches {
            if pair.problem.is_some() || pair.patches.is_empty() {
                continue;
            }
            let held = HeldPair {
                taken: (exposure(pair.i), exposure(pair.j)),
                at,
                pair,
            };
            match self
                .pairs
                .iter_mut()
                .find(|h| (h.pair.i, h.pair.j) == (held.pair.i, held.pair.j))
            {
                Some(h) => *h = held,
                None => self.pairs.push(held),
            }
        }
    }

    /// The pairs held at set count `now`: matched within `hold` sets.
    fn current(&self, now: u64, hold: u64) -> impl Iterator<Item = &HeldPair> {
        self.pairs
            .iter()
            .filter(move |h| now.saturating_sub(h.at) <= hold)
    }
}

/// The panorama in the pipeline: the view, its rig, and the matching and
/// refinement that run beside the per-set path (see the module
/// documentation).
pub struct LivePanorama {
    panorama: Arc<Panorama>,
    rig: Arc<Rig>,
    settings: PanoramaSettings,
    options: PanoramaOptions,
    match_options: MatchOptions,
    detector: SharedDetector,
    worker: Option<Worker>,
    /// Whether a job is on the worker.
    busy: bool,
    /// Bumped by every refinement: the worker's results for an older
    /// panorama are dropped.
    generation: u64,
    held: Option<Held>,
    /// Sets scheduled so far.
    sets: u64,
    sets_since_match: u64,
    sets_since_refine: u64,
    refine_wanted: bool,
    report: Arc<PanoramaReport>,
}

impl std::fmt::Debug for LivePanorama {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LivePanorama")
            .field("spec", self.panorama.spec())
            .field("generation", &self.generation)
            .field("busy", &self.busy)
            .field("report", &self.report)
            .finish_non_exhaustive()
    }
}

impl LivePanorama {
    /// Builds the panorama of `rig` (poses in the vehicle frame) as
    /// `settings` say. A rig whose neighbours share no pixel of the
    /// cylinder is an error naming them.
    pub fn new(rig: Rig, settings: &PanoramaSettings, detector: SharedDetector) -> Result<Self> {
        settings.validate()?;
        let options = PanoramaOptions::default();
        let panorama = Panorama::build(&rig, &settings.spec(), &options)?;
        let rig = Arc::new(rig);
        let report = PanoramaReport {
            pairs: pair_reports(&rig, &panorama, None),
            rig: Some(rig.clone()),
            ..PanoramaReport::default()
        };
        Ok(Self {
            panorama: Arc::new(panorama),
            rig,
            settings: settings.clone(),
            options,
            match_options: MatchOptions::default(),
            detector,
            worker: None,
            busy: false,
            generation: 0,
            held: None,
            sets: 0,
            sets_since_match: 0,
            sets_since_refine: 0,
            refine_wanted: false,
            report: Arc::new(report),
        })
    }

    /// The panorama in use.
    pub fn panorama(&self) -> &Panorama {
        &self.panorama
    }

    /// The rig in use (refined rotations included).
    pub fn rig(&self) -> &Arc<Rig> {
        &self.rig
    }

    /// The latest matching and refinement.
    pub fn report(&self) -> &Arc<PanoramaReport> {
        &self.report
    }

    /// New schedule settings (a new cylinder applies when the view is
    /// next built).
    pub fn set_settings(&mut self, settings: &PanoramaSettings) {
        self.settings = settings.clone();
    }

    /// Asks for a refinement ([`crate::panorama::refine_in_rounds`]) from
    /// the next set the worker is free for.
    pub fn request_refine(&mut self) {
        self.refine_wanted = true;
        Arc::make_mut(&mut self.report).refining = true;
    }

    /// Takes what the worker finished. Returns whether the panorama was
    /// rebuilt (a refinement), which changes its maps and masks.
    pub fn poll(&mut self) -> bool {
        let mut rebuilt = false;
        while let Some(done) = self.next_done() {
            self.busy = false;
            match done {
                Done::Matched {
                    generation,
                    trigger,
                    taken,
                    matches,
                    ms,
                } => {
                    if generation != self.generation {
                        continue;
                    }
                    let report = Arc::make_mut(&mut self.report);
                    report.matched_trigger = Some(trigger);
                    report.match_ms = ms;
                    let refined: Vec<_> = report
                        .pairs
                        .iter()
                        .map(|p| (p.i, p.j, p.refined_before_px, p.refined_after_px))
                        .collect();
                    report.pairs = pair_reports(&self.rig, &self.panorama, Some(&matches));
                    for (p, (_, _, before, after)) in report.pairs.iter_mut().zip(refined) {
                        p.refined_before_px = before;
                        p.refined_after_px = after;
                    }
                    if report
                        .problem
                        .as_deref()
                        .is_some_and(|p| p.starts_with("matching"))
                    {
                        report.problem = None;
                    }
                    self.held
                        .get_or_insert_with(Held::default)
                        .take(matches, &taken, self.sets);
                }
                Done::Refined {
                    generation,
                    errors,
                    rig,
                    panorama,
                    ms,
                } => {
                    if generation != self.generation {
                        continue;
                    }
                    self.generation += 1;
                    self.rig = Arc::new(rig);
                    self.panorama = Arc::from(panorama);
                    let report = Arc::make_mut(&mut self.report);
                    report.refinements += 1;
                    report.refine_ms = ms;
                    report.refining = self.refine_wanted;
                    report.rig = Some(self.rig.clone());
                    report.problem = None;
                    for p in &mut report.pairs {
                        let r = errors.iter().find(|r| (r.0, r.1) == (p.i, p.j));
                        p.refined_before_px = r.and_then(|r| r.2);
                        p.refined_after_px = r.and_then(|r| r.3);
                    }
                    rebuilt = true;
                }
                Done::Failed { what, error } => {
                    let report = Arc::make_mut(&mut self.report);
                    report.problem = Some(format!("{what}: {error}"));
                    if what == "refinement" {
                        report.refining = self.refine_wanted;
                    }
                }
            }
        }
        rebuilt
    }

    /// The worker's next finished job, if any.
    fn next_done(&mut self) -> Option<Done> {
        let w = self.worker.as_ref()?;
        match w.done.try_recv() {
            Ok(d) => Some(d),
            Err(TryRecvError::Empty) => None,
            Err(TryRecvError::Disconnected) => {
                self.worker = None;
                self.busy = false;
                None
            }
        }
    }

    /// Counts a set and starts the worker's next job if it is free: a
    /// refinement of `set` if one is wanted, otherwise a
    /// matching of `set` when one is due. Never waits; a worker that
    /// cannot start or stopped is a problem in the report.
    pub fn schedule(&mut self, set: &FrameSet) {
        self.sets += 1;
        self.sets_since_match += 1;
        self.sets_since_refine += 1;
        if self.settings.refine_every > 0 && self.sets_since_refine >= self.settings.refine_every {
            self.sets_since_refine = 0;
            self.request_refine();
        }
        if self.busy {
            return;
        }
        if self.worker.is_none() {
            match Worker::start(
                self.panorama.spec().clone(),
                self.options.clone(),
                self.detector.clone(),
            ) {
                Ok(w) => self.worker = Some(w),
                Err(e) => {
                    Arc::make_mut(&mut self.report).problem = Some(e.to_string());
                    return;
                }
            }
        }
        let Some(worker) = &self.worker else {
            return;
        };
        let job = if self.refine_wanted {
            self.refine_wanted = false;
            Job::Refine {
                generation: self.generation,
                rig: self.rig.clone(),
                set: set.clone(),
                options: RoundsOptions {
                    rounds: self.settings.refine_rounds,
                    refine: RefineOptions {
                        bound_deg: self.settings.refine_bound_deg,
                        ..RefineOptions::default()
                    },
                    matching: self.match_options.clone(),
                },
            }
        } else if self.held.is_none() || self.sets_since_match >= self.settings.match_every {
            // The first set is matched at once, then one every
            // `match_every` sets (the next free set after a busy worker).
            self.sets_since_match = 0;
            Job::Match {
                generation: self.generation,
                panorama: self.panorama.clone(),
                set: set.clone(),
                options: self.match_options.clone(),
            }
        } else {
            return;
        };
        self.busy = worker.send(job);
        if !self.busy {
            // A new worker is started on the next set.
            self.worker = None;
            Arc::make_mut(&mut self.report).problem =
                Some("the panorama worker stopped; it is restarted".into());
        }
    }

    /// The held matches' patches as seen at the exposures `taken` (per
    /// camera, the set's), one observation per pair with matches.
    pub fn observations(&self, taken: &[f64]) -> Vec<PairObservation> {
        let Some(held) = &self.held else {
            return Vec::new();
        };
        let scale = |k: usize, then: f64| -> f32 {
            match taken.get(k) {
                Some(&now) if now > 0.0 && then > 0.0 => (now / then) as f32,
                _ => 1.0,
            }
        };
        held.current(self.sets, self.settings.hold_sets)
            .map(|h| {
                let p = &h.pair;
                let (si, sj) = (scale(p.i, h.taken.0), scale(p.j, h.taken.1));
                PairObservation {
                    i: p.i,
                    j: p.j,
                    patches: p.patches.iter().map(|q| rescaled(q, si, sj)).collect(),
                }
            })
            .collect()
    }
}

/// One patch pair as seen with each camera's exposure scaled by `si` and
/// `sj`: means scale, a mean scaled into saturation counts as saturated
/// and a saturated patch stays so.
fn rescaled(p: &PatchPair, si: f32, sj: f32) -> PatchPair {
    let one = |mean: f32, saturated: f32, s: f32| {
        let m = mean * s;
        if m >= SATURATED_LEVEL {
            (m.min(1.0), 1.0)
        } else {
            (m, saturated)
        }
    };
    let (mean_i, saturated_i) = one(p.mean_i, p.saturated_i, si);
    let (mean_j, saturated_j) = one(p.mean_j, p.saturated_j, sj);
    PatchPair {
        mean_i,
        saturated_i,
        mean_j,
        saturated_j,
    }
}

/// Per rig neighbour pair, its report from `matches` (none yet: no
/// matches).
fn pair_reports(
    rig: &Rig,
    panorama: &Panorama,
    matches: Option<&[PairMatches]>,
) -> Vec<PairMatchReport> {
    rig.neighbours
        .iter()
        .map(|&(i, j)| {
            let band = panorama
                .bands()
                .iter()
                .find(|b| (b.i, b.j) == (i, j))
                .map(|b| b.rect);
            let found = matches.and_then(|m| m.iter().find(|p| (p.i, p.j) == (i, j)));
            match found {
                Some(p) => PairMatchReport {
                    i,
                    j,
                    matches: p.matches.len(),
                    inliers: p.inliers,
                    error_px: p.error_before_px,
                    refined_before_px: None,
                    refined_after_px: None,
                    patches: p.patches.len(),
                    problem: p.problem.clone(),
                    lines: p.matches.clone(),
                    band,
                },
                None => PairMatchReport {
                    i,
                    j,
                    problem: Some(match matches {
                        Some(_) => "the cameras share no band of the cylinder".into(),
                        None => "not matched yet".into(),
                    }),
                    band,
                    ..PairMatchReport::default()
                },
            }
        })
        .collect()
}

#[cfg(test)]
mod tests;
