//! The live bowl view: what is shown is the bowl from the operator's
//! viewpoint; what is metered and balanced is the bird's-eye view's ground
//! and overlaps, whatever the viewpoint (see [`crate::bowl`]). A new
//! viewpoint or bowl is built on a thread of its own and taken in at the
//! start of a later set, so that moving the viewpoint never holds up the
//! per-set path; while one is being built, only the latest request waits.
//! While the viewpoint keeps changing (an orbit), each is built at half
//! the picture's size with its maps interpolated more loosely
//! ([`BowlView::build_preview`]: a quarter of the time of the whole
//! picture), and the whole picture follows once it rests.

use std::sync::mpsc::{self, Receiver, TryRecvError};
use std::sync::Arc;
use std::time::{Duration, Instant};

use rigview_calib::rig::Rig;
use serde::{Deserialize, Serialize};

use crate::bowl::{BowlSpec, BowlView, Viewpoint};
use crate::error::{Error, Result};
use crate::surround::{BlendMode, CanvasSpec, SurroundOptions, SurroundView};

/// The bowl and the viewpoint it is seen from.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct BowlSettings {
    /// The bowl, the vehicle and the picture's size.
    pub spec: BowlSpec,
    /// Where it is seen from.
    pub viewpoint: Viewpoint,
    /// Compose the bird's-eye view too, to show beside the bowl (as
    /// production surround views do).
    pub beside: bool,
    /// The window draws the bowl itself (on the GPU): the pipeline
    /// composes no picture of it. Not a file setting: the window sets it
    /// while its renderer works.
    #[serde(skip)]
    pub gpu_draws: bool,
}

impl BowlSettings {
    /// Checks the bowl and the viewpoint; errors name the field.
    pub fn validate(&self) -> Result<()> {
        self.spec.validate()?;
        self.viewpoint.validate()
    }
}

/// A bowl being built in the background: for which settings, whether at
/// half size, and where its result arrives.
type Pending = (BowlSettings, bool, Receiver<Result<BowlView>>);

/// Requests closer together than this are a viewpoint in motion, built at
/// half size.
const MOTION: Duration = Duration::from_millis(400);

/// How long the tests wait for a viewpoint to come to rest.
#[cfg(test)]
pub(super) const MOTION_FOR_TESTS: Duration = Duration::from_millis(450);

/// The live bowl view.
#[derive(Debug)]
pub struct LiveBowl {
    rig: Arc<Rig>,
    surround: SurroundView,
    shown: Arc<BowlView>,
    /// The settings `shown` was built with.
    built: BowlSettings,
    /// Whether `shown` is a half-size preview.
    preview: bool,
    /// When the settings were last asked for.
    asked: Option<Instant>,
    /// The settings asked for last.
    wanted: BowlSettings,
    pending: Option<Pending>,
    /// The latest build's error, if it failed.
    problem: Option<String>,
    /// The blend mode whose plan a build prepares.
    blend: BlendMode,
}

impl LiveBowl {
    /// The bowl view of `rig` (poses in the vehicle frame) as `settings`
    /// say, balanced on the bird's-eye view of `canvas`, its plan for
    /// `blend` built.
    pub fn new(
        rig: &Rig,
        canvas: &CanvasSpec,
        settings: &BowlSettings,
        blend: BlendMode,
    ) -> Result<Self> {
        let surround = SurroundView::build(rig, canvas, &SurroundOptions::default())?;
        let shown = BowlView::build(rig, &settings.spec, &settings.viewpoint)?;
        shown.mosaic().prepare(blend);
        Ok(Self {
            rig: Arc::new(rig.clone()),
            surround,
            shown: Arc::new(shown),
            built: settings.clone(),
            preview: false,
            asked: None,
            wanted: settings.clone(),
            pending: None,
            problem: None,
            blend,
        })
    }

    /// The bird's-eye view the cameras are metered and balanced on.
    pub fn surround(&self) -> &SurroundView {
        &self.surround
    }

    /// The bowl shown now.
    pub fn shown(&self) -> &Arc<BowlView> {
        &self.shown
    }

    /// The settings of the bowl shown now.
    pub fn built(&self) -> &BowlSettings {
        &self.built
    }

    /// Why the latest build failed, if it did (the previous bowl stays).
    pub fn problem(&self) -> Option<&str> {
        self.problem.as_deref()
    }

    /// Whether a build is under way.
    pub fn building(&self) -> bool {
        self.pending.is_some()
    }

    /// Asks for the bowl as `settings` say, composed in `blend`: built
    /// (with its plan for `blend`) in the background, after the one under
    /// way if there is one. While the window draws the bowl itself
    /// ([`BowlSettings::gpu_draws`]), a new viewpoint builds nothing (the
    /// window's renderer takes it as a matrix); a new bowl still does (the
    /// renderer needs its ground plan).
    pub fn set_wanted(&mut self, settings: &BowlSettings, blend: BlendMode) {
        let mut settings = settings.clone();
        if settings.gpu_draws {
            settings.viewpoint = self.wanted.viewpoint;
        }
        if !same_bowl(&settings, &self.wanted) {
            self.asked = Some(Instant::now());
        }
        self.wanted = settings;
        self.blend = blend;
        self.start();
    }

    /// Whether the bowl shown is a half-size preview of a viewpoint in
    /// motion.
    pub fn is_preview(&self) -> bool {
        self.preview
    }

    /// Takes in a finished build; returns whether the bowl shown changed.
    pub fn poll(&mut self) -> bool {
        let result = match &self.pending {
            None => {
                // A preview whose viewpoint has come to rest: the full
                // size now.
                self.start();
                return false;
            }
            Some((_, _, rx)) => match rx.try_recv() {
                Ok(r) => r,
                Err(TryRecvError::Empty) => return false,
                Err(TryRecvError::Disconnected) => Err(stopped()),
            },
        };
        self.take_in(result)
    }

    /// Waits for the builds asked for so far (tests, offline tools).
    pub fn settle(&mut self) {
        while let Some((_, _, rx)) = &self.pending {
            let result = rx.recv().unwrap_or_else(|_| Err(stopped()));
            self.take_in(result);
        }
    }

    /// Takes in the pending build's result and starts the next one;
    /// returns whether the bowl shown changed.
    fn take_in(&mut self, result: Result<BowlView>) -> bool {
        let Some((settings, preview, _)) = self.pending.take() else {
            return false;
        };
        let changed = match result {
            Ok(view) => {
                self.shown = Arc::new(view);
                self.built = settings;
                self.preview = preview;
                self.problem = None;
                true
            }
            Err(e) => {
                self.problem = Some(e.to_string());
                // Not again for the same settings.
                self.wanted = self.built.clone();
                false
            }
        };
        self.start();
        changed
    }

    /// Starts building what is wanted, if it is not shown and nothing is
    /// under way.
    fn start(&mut self) {
        let moving = self.asked.is_some_and(|t| t.elapsed() < MOTION);
        // Shown as asked, and whole unless still in motion.
        let done = same_bowl(&self.wanted, &self.built) && (moving || !self.preview);
        if self.pending.is_some() || done {
            return;
        }
        let (tx, rx) = mpsc::channel();
        let (rig, settings, previous) = (self.rig.clone(), self.wanted.clone(), self.shown.clone());
        let (mut job, blend) = (settings.clone(), self.blend);
        if moving {
            job.spec.size_px = job.spec.size_px.map(|n| (n / 2).max(16));
        }
        let spawned = std::thread::Builder::new()
            .name("rigview-bowl".into())
            .spawn(move || {
                let built =
                    BowlView::build_after(&rig, &job.spec, &job.viewpoint, moving, Some(&previous));
                if let Ok(view) = &built {
                    view.mosaic().prepare(blend);
                }
                let _ = tx.send(built);
            });
        match spawned {
            Ok(_) => self.pending = Some((settings, moving, rx)),
            Err(e) => {
                self.problem = Some(format!("cannot start the bowl's build thread: {e}"));
                self.wanted = self.built.clone();
            }
        }
    }
}

/// Whether two settings give the same bowl picture (what is composed
/// beside it does not change it).
fn same_bowl(a: &BowlSettings, b: &BowlSettings) -> bool {
    a.spec == b.spec && a.viewpoint == b.viewpoint
}

/// The error of a build thread that ended without a result.
fn stopped() -> Error {
    Error::invalid(
        "bowl view",
        "its build",
        "a bowl",
        "a build thread that stopped",
    )
}
