//! Recording and replay in the app: `--record FILE` (a recorder on the
//! pipeline), `--source replay:FILE` (a recording as the source, with its
//! calibration unless `--rig` overrides it), `rigview record` (capture
//! without processing), and `rigview recording info|repair`. The format and
//! its guarantees are `rigview-record`'s.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rigview_calib::Rig;
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{
    Notify, Pipeline, PipelineOptions, ProcessingSettings, Processor, SetSink,
};
use rigview_core::sim::{Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::{CameraInfo, FrameSource};
use rigview_record::{
    Compression, Recorder, RecorderOptions, RecorderStats, RecordingSetup, ReplaySource,
};

use crate::session::{view_of, Session};

/// Where and how to record.
#[derive(Clone, Debug, PartialEq)]
pub struct RecordSpec {
    /// The MCAP file to write.
    pub file: PathBuf,
    /// How chunks are compressed.
    pub compression: Compression,
    /// Free space to leave on the disk, bytes.
    pub reserve_bytes: u64,
}

impl RecordSpec {
    /// A recording into `file` with the defaults (no compression, a 2 GiB
    /// reserve).
    pub fn new(file: PathBuf) -> Self {
        Self {
            file,
            compression: Compression::None,
            reserve_bytes: RecorderOptions::default().reserve_bytes,
        }
    }

    /// Starts the recorder for `cameras` with the calibration `rig`.
    pub fn create(
        &self,
        cameras: &[CameraInfo],
        rig: Option<&Rig>,
        source: &str,
        time_offset_ns: u64,
    ) -> Result<Recorder> {
        let setup = RecordingSetup {
            cameras: cameras.to_vec(),
            rig: rig.cloned(),
            source: source.to_owned(),
            time_offset_ns,
        };
        let options = RecorderOptions {
            compression: self.compression,
            reserve_bytes: self.reserve_bytes,
            ..Default::default()
        };
        Recorder::create(&self.file, &setup, options)
            .with_context(|| format!("cannot record into {}", self.file.display()))
    }
}

/// What a recording did, in one line.
pub fn describe(file: &Path, stats: &RecorderStats) -> String {
    let mut s = format!(
        "recording {}: {} sets ({:.1} MB of frames), {} dropped",
        file.display(),
        stats.sets,
        stats.bytes as f64 / 1e6,
        stats.dropped
    );
    match &stats.stopped {
        Some(why) => {
            let _ = write!(s, "; STOPPED EARLY: {why}");
        }
        None if !stats.finished => s += "; not closed properly",
        None => {}
    }
    s
}

/// What a session's source is, for its summary and its recording.
#[derive(Debug)]
pub struct Origin<'a> {
    /// The source, in words.
    pub source_name: String,
    /// Where the calibration came from, in words.
    pub calibration: String,
    /// The calibration (a recording's `rig.yaml` attachment and
    /// `camera_info`).
    pub rig: Option<&'a Rig>,
    /// Added to the source's timestamps to make Unix time.
    pub time_offset_ns: u64,
}

/// Starts the pipeline on `source` and, if `record` says, a recorder on it.
pub fn start_session<S: FrameSource + 'static>(
    source: S,
    processor: Processor,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
    origin: Origin<'_>,
) -> Result<Session> {
    let recorder = match record {
        Some(r) => Some(Arc::new(r.create(
            source.cameras(),
            origin.rig,
            &origin.source_name,
            origin.time_offset_ns,
        )?)),
        None => None,
    };
    let camera_auto = source.has_camera_auto();
    let sink = recorder.clone().map(|r| r as Arc<dyn SetSink>);
    let pipeline = Pipeline::start_with_sink(source, processor, options, notify, sink)?;
    Ok(Session {
        pipeline,
        recorder,
        source_name: origin.source_name,
        calibration: origin.calibration,
        camera_auto,
    })
}

/// A recording to replay.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplaySpec {
    /// The recording.
    pub file: PathBuf,
    /// A calibration to use instead of the recording's own.
    pub rig: Option<PathBuf>,
}

/// The calibration a replay uses: `--rig` if given (it must fit the
/// recording), else the recording's attachment.
fn replay_rig(spec: &ReplaySpec, source: &ReplaySource) -> Result<Option<(Rig, String)>> {
    let file = &spec.file;
    if let Some(path) = &spec.rig {
        let rig = rigview_calib::formats::load(path, None, None)
            .with_context(|| format!("cannot load the calibration {}", path.display()))?
            .rig;
        let cameras = source.cameras();
        if rig.cameras.len() != cameras.len() {
            anyhow::bail!(
                "the calibration {} has {} cameras, the recording {} has {}",
                path.display(),
                rig.cameras.len(),
                file.display(),
                cameras.len()
            );
        }
        for (r, c) in rig.cameras.iter().zip(cameras) {
            let size = (r.intrinsics.width as usize, r.intrinsics.height as usize);
            if size != (c.width, c.height) {
                anyhow::bail!(
                    "the calibration {} has camera \"{}\" at {}×{}, the recording {} has \"{}\" at {}×{}",
                    path.display(),
                    r.name,
                    size.0,
                    size.1,
                    file.display(),
                    c.name,
                    c.width,
                    c.height
                );
            }
        }
        return Ok(Some((rig, path.display().to_string())));
    }
    match &source.meta().rig_yaml {
        Some(text) => {
            let name = format!("{} (attachment rig.yaml)", file.display());
            let rig = rigview_calib::formats::rig_yaml::parse(text, &name)
                .with_context(|| format!("the rig recorded in {}", file.display()))?;
            Ok(Some((rig, name)))
        }
        None => Ok(None),
    }
}

/// Starts a session on a recording: open loop, the recorded frames through
/// the processing of `processing` (and into `record`, if given).
pub fn start_replay(
    spec: &ReplaySpec,
    processing: &ProcessingSettings,
    options: PipelineOptions,
    notify: Notify,
    record: Option<&RecordSpec>,
) -> Result<Session> {
    let mut source = ReplaySource::open(&spec.file)
        .with_context(|| format!("cannot replay {}", spec.file.display()))?;
    if !options.lockstep {
        // In the window: at the recorded rate.
        source.set_speed(Some(1.0));
    }
    let cameras = source.cameras().to_vec();
    let rig = replay_rig(spec, &source)?;
    let (view, graph, calibration) = match &rig {
        Some((rig, name)) => {
            let (v, g) =
                view_of(rig, &cameras).with_context(|| format!("the surround view of {name}"))?;
            (Some(v), g, name.clone())
        }
        None => (
            None,
            NeighbourGraph::new(cameras.len(), &[])?,
            "none".into(),
        ),
    };
    let processor = Processor::new(cameras.clone(), view, graph, processing.clone())?;
    let origin = Origin {
        source_name: format!(
            "replay of {} ({} cameras)",
            spec.file.display(),
            cameras.len()
        ),
        calibration,
        rig: rig.as_ref().map(|(r, _)| r),
        time_offset_ns: source.meta().time_offset_ns,
    };
    start_session(source, processor, options, notify, record, origin)
}

/// What `rigview record` captures from.
#[derive(Debug)]
pub enum CaptureFrom {
    /// The simulated rig at its trigger rate.
    Sim {
        /// A preset or simulation file.
        scenario: String,
        /// Render scale.
        scale: f64,
    },
    /// Live cameras.
    Live(Box<crate::live::LiveSpec>),
}

/// A source opened for `rigview record`.
struct Opened {
    source: Box<dyn FrameSource>,
    rig: Option<Rig>,
    what: String,
    time_offset_ns: u64,
}

/// `rigview record`: capture into a recording without processing.
#[derive(Debug)]
pub struct CaptureRun {
    /// Where from.
    pub from: CaptureFrom,
    /// Where to.
    pub record: RecordSpec,
    /// How long (`None`: until the source ends).
    pub seconds: Option<f64>,
}

/// Captures `run`, printing the set count now and then; returns the
/// recording's summary.
pub fn capture(run: &CaptureRun, out: &mut dyn std::io::Write) -> Result<String> {
    let opened = match &run.from {
        CaptureFrom::Sim { scenario, scale } => {
            let mut config = SimConfig::named(scenario)
                .with_context(|| format!("loading the simulation \"{scenario}\""))?;
            config.scale = *scale;
            let render = Arc::new(SimRender::new(&config).context("building the simulated rig")?);
            let rig = render.rig().clone();
            let source = SimRig::new(
                render,
                SimRigOptions {
                    pacing: Pacing::Realtime,
                    ..Default::default()
                },
            )?;
            Opened {
                source: Box::new(source),
                rig: Some(rig),
                what: format!("simulated rig \"{scenario}\""),
                // The simulation's clock starts at 0.
                time_offset_ns: rigview_record::writer::unix_now_ns(),
            }
        }
        CaptureFrom::Live(spec) => open_live(spec)?,
    };
    let recorder = run.record.create(
        opened.source.cameras(),
        opened.rig.as_ref(),
        &opened.what,
        opened.time_offset_ns,
    )?;
    let mut source = opened.source;
    let start = Instant::now();
    let limit = run
        .seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .context("--seconds: expected a number of seconds ≥ 0")?;
    let mut last_print = Instant::now();
    loop {
        if limit.is_some_and(|l| start.elapsed() >= l) || recorder.is_stopped() {
            break;
        }
        match source.next_set(Duration::from_millis(100)) {
            Ok(Some(set)) => {
                recorder.offer(&set, None);
            }
            Ok(None) if source.is_finished() => break,
            Ok(None) => {}
            Err(e) => tracing::warn!("{e}"),
        }
        for m in source.take_messages() {
            tracing::warn!("{m}");
        }
        if last_print.elapsed() >= Duration::from_secs(1) {
            let s = recorder.stats();
            writeln!(
                out,
                "{:.0} s: {} sets, {} dropped",
                start.elapsed().as_secs_f64(),
                s.sets,
                s.dropped
            )?;
            last_print = Instant::now();
        }
    }
    let stats = recorder.finish();
    Ok(describe(&run.record.file, &stats))
}

#[cfg(feature = "aravis")]
fn open_live(spec: &crate::live::LiveSpec) -> Result<Opened> {
    let crate::live::Opened { source, rig } = crate::live::open(spec)?;
    let fits = view_of(&rig, source.cameras()).is_ok();
    Ok(Opened {
        source: Box::new(source),
        rig: fits.then_some(rig),
        what: spec.describe(),
        // Live sets are stamped with the host's Unix time.
        time_offset_ns: 0,
    })
}

#[cfg(not(feature = "aravis"))]
fn open_live(_spec: &crate::live::LiveSpec) -> Result<Opened> {
    Err(crate::live::LiveError::NoAravis.into())
}

/// `rigview recording info`: duration, sets, topics and drops.
pub fn info_text(file: &Path) -> Result<String> {
    let i = rigview_record::info(file)?;
    let cameras: Vec<_> = i
        .meta
        .cameras
        .iter()
        .map(|c| {
            format!(
                "{} ({}×{} {})",
                c.name,
                c.width,
                c.height,
                c.format.genicam_name()
            )
        })
        .collect();
    let mut s = format!(
        "{}\n  recorded by rigview {} from {}\n  cameras: {}\n  {} complete sets over {:.2} s; {} sets dropped while recording\n",
        file.display(),
        i.meta.version,
        i.meta.source,
        cameras.join(", "),
        i.sets,
        i.duration_s(),
        i.dropped,
    );
    let rig = if i.meta.rig_yaml.is_some() {
        "attached (rig.yaml)"
    } else {
        "none"
    };
    let _ = writeln!(s, "  calibration: {rig}");
    match (&i.end, &i.tail) {
        (Some(e), None) => {
            let _ = writeln!(s, "  ended: {}", e.stopped);
        }
        (_, Some(t)) => {
            let _ = writeln!(
                s,
                "  NOT CLOSED ({t}): replays up to its last complete set; \
                 `rigview recording repair` rewrites it with an index"
            );
        }
        (None, None) => s += "  ended without its end record\n",
    }
    s += "  topics:\n";
    for (topic, (schema, n)) in &i.topics {
        let _ = writeln!(s, "    {topic}  {schema}  {n} messages");
    }
    Ok(s)
}

/// `rigview recording repair`: rewrites `input` with its indexes.
pub fn repair_text(input: &Path, output: &Path) -> Result<String> {
    if input == output {
        anyhow::bail!(
            "repair writes a new file: give an output other than {}",
            input.display()
        );
    }
    let r = rigview_record::repair(input, output)?;
    let tail = r
        .tail
        .map(|t| format!("; the input ended early ({t})"))
        .unwrap_or_default();
    Ok(format!(
        "{} → {}: {} complete sets{tail}",
        input.display(),
        output.display(),
        r.sets
    ))
}
