//! The live panorama's worker thread: matching and refinement off the
//! processing thread, at a lower priority, one job at a time.

use super::*;

pub(super) enum Job {
    Match {
        generation: u64,
        panorama: Arc<Panorama>,
        set: FrameSet,
        options: MatchOptions,
    },
    Refine {
        generation: u64,
        rig: Arc<Rig>,
        set: FrameSet,
        options: RoundsOptions,
    },
}

pub(super) enum Done {
    Matched {
        generation: u64,
        trigger: u64,
        /// Per camera, the exposure its frame was taken with.
        taken: Vec<f64>,
        matches: Vec<PairMatches>,
        ms: f64,
    },
    Refined {
        generation: u64,
        /// Per pair: cameras, and the median error before and after.
        errors: Vec<(usize, usize, Option<f64>, Option<f64>)>,
        rig: Rig,
        panorama: Box<Panorama>,
        ms: f64,
    },
    Failed {
        what: &'static str,
        error: String,
    },
}

/// The worker thread of a live panorama.
///
/// Dropping it closes its queue: the thread ends after the job it is on,
/// without anyone waiting for it (a rebuild takes up to a second, and the
/// processing thread drops the view when the operator switches views).
pub(super) struct Worker {
    jobs: Sender<Job>,
    pub(super) done: Receiver<Done>,
}

impl std::fmt::Debug for Worker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Worker").finish_non_exhaustive()
    }
}

impl Worker {
    pub(super) fn start(
        spec: crate::panorama::CylinderSpec,
        options: PanoramaOptions,
        detector: SharedDetector,
    ) -> Result<Self> {
        let (jobs, rx) = mpsc::channel::<Job>();
        let (tx, done) = mpsc::channel();
        std::thread::Builder::new()
            .name("rigview-panorama".into())
            .spawn(move || {
                lower_priority();
                for job in rx {
                    if tx.send(work(job, &spec, &options, &*detector)).is_err() {
                        break;
                    }
                }
            })
            .map_err(|source| Error::ThreadStart {
                thread: "panorama worker",
                source,
            })?;
        Ok(Self { jobs, done })
    }

    pub(super) fn send(&self, job: Job) -> bool {
        self.jobs.send(job).is_ok()
    }
}

/// The niceness the worker runs at: matching and rebuilding the panorama
/// (which spreads over every core) give way to the per-set path.
const WORKER_NICE: i32 = 10;

/// Lowers the calling thread's scheduling priority by [`WORKER_NICE`]
/// (threads it starts inherit it); where that is not possible it runs at
/// the process's priority.
fn lower_priority() {
    #[cfg(target_os = "linux")]
    {
        // SAFETY: setpriority only reads its integer arguments; on Linux,
        // PRIO_PROCESS with `who` 0 applies to the calling thread alone.
        #[allow(unsafe_code)]
        let current = unsafe { libc::getpriority(libc::PRIO_PROCESS, 0) };
        #[allow(unsafe_code)]
        let _ = unsafe { libc::setpriority(libc::PRIO_PROCESS, 0, current + WORKER_NICE) };
    }
}

fn work(
    job: Job,
    spec: &crate::panorama::CylinderSpec,
    options: &PanoramaOptions,
    detector: &Detector<'_>,
) -> Done {
    match job {
        Job::Match {
            generation,
            panorama,
            set,
            options: match_options,
        } => {
            let t = Instant::now();
            let frames = views(&set);
            let taken = set
                .frames
                .iter()
                .flatten()
                .map(|f| f.meta.taken.exposure())
                .collect();
            match frames.and_then(|f| panorama.match_pairs(&f, detector, &match_options)) {
                Ok((matches, _)) => Done::Matched {
                    generation,
                    trigger: set.trigger,
                    taken,
                    matches,
                    ms: t.elapsed().as_secs_f64() * 1e3,
                },
                Err(e) => Done::Failed {
                    what: "matching",
                    error: e.to_string(),
                },
            }
        }
        Job::Refine {
            generation,
            rig,
            set,
            options: rounds,
        } => {
            let t = Instant::now();
            let refined = views(&set)
                .and_then(|frames| {
                    refine_in_rounds(&rig, spec, options, &frames, detector, &rounds)
                })
                .and_then(|r| Ok((Panorama::build(&r.rig, spec, options)?, r)));
            match refined {
                Ok((panorama, r)) => Done::Refined {
                    generation,
                    errors: r.errors,
                    rig: r.rig,
                    panorama: Box::new(panorama),
                    ms: t.elapsed().as_secs_f64() * 1e3,
                },
                Err(e) => Done::Failed {
                    what: "refinement",
                    error: e.to_string(),
                },
            }
        }
    }
}

/// The views of a set's frames, in rig order.
fn views(set: &FrameSet) -> Result<Vec<FrameView<'_>>> {
    set.frames.iter().flatten().map(|f| f.view()).collect()
}
