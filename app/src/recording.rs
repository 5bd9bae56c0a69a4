//! Recording and replay in the app: `--record FILE` (a recorder on the
//! pipeline), `--source replay:FILE` (a recording as the source, with its
//! calibration unless `--rig` overrides it), `rigview record` (capture
//! without processing), and `rigview recording info|repair`. The format and
//! its guarantees are `rigview-record`'s.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex, PoisonError};
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use rigview_calib::Rig;
use rigview_core::exposure::NeighbourGraph;
use rigview_core::pipeline::{
    Notify, Pipeline, PipelineOptions, Processed, ProcessingSettings, Processor, SetSink, Telemetry,
};
use rigview_core::sim::{Pacing, SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, SourceError, StreamHealth,
};
use rigview_record::{
    Compression, Recorder, RecorderOptions, RecorderStats, RecordingSetup, ReplaySource,
};

use crate::session::{view_for, Session};

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
        self.create_for(&RecordingSetup {
            cameras: cameras.to_vec(),
            rig: rig.cloned(),
            source: source.to_owned(),
            time_offset_ns,
        })
    }

    /// Starts the recorder for the source `setup` describes.
    pub fn create_for(&self, setup: &RecordingSetup) -> Result<Recorder> {
        let options = RecorderOptions {
            compression: self.compression,
            reserve_bytes: self.reserve_bytes,
            ..Default::default()
        };
        Recorder::create(&self.file, setup, options)
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

/// The recording a session's pipeline hands its sets to: none, or one
/// started at start-up (`--record`) or by the window's Record button and
/// stopped by it. The pipeline always has this sink; it offers a set only
/// while a recorder is in it.
#[derive(Debug, Default)]
pub struct RecordSlot {
    current: Mutex<Option<Arc<Recorder>>>,
    /// Per processed set while recording: its trigger and the sets the
    /// recorder had dropped by then (the last [`DROPS_KEPT`]).
    drops: Mutex<std::collections::VecDeque<(u64, u64)>>,
}

/// Sets whose recorder drops a [`RecordSlot`] keeps for `telemetry.csv`
/// (an hour and a half at 20 Hz).
const DROPS_KEPT: usize = 100_000;

impl RecordSlot {
    fn lock(&self) -> std::sync::MutexGuard<'_, Option<Arc<Recorder>>> {
        // The slot holds an `Option`; no update leaves it half done.
        self.current.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The recording in progress.
    pub fn recorder(&self) -> Option<Arc<Recorder>> {
        self.lock().clone()
    }

    /// Puts `recorder` in the slot; returns the one it replaces.
    pub fn replace(&self, recorder: Option<Arc<Recorder>>) -> Option<Arc<Recorder>> {
        std::mem::replace(&mut *self.lock(), recorder)
    }

    /// The sets the recorder had dropped when the set `trigger` was
    /// processed (`None`: no recording was in progress then).
    pub fn dropped_at(&self, trigger: u64) -> Option<u64> {
        let drops = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
        drops.iter().rev().find(|(t, _)| *t == trigger).map(|d| d.1)
    }

    /// Writes `telemetry` as `telemetry.csv` does, with a last column
    /// `recorder_dropped`: the sets the recorder had dropped by each set
    /// (empty while nothing was recorded).
    pub fn write_csv(&self, telemetry: &Telemetry, out: &mut dyn std::io::Write) -> Result<()> {
        let mut line = Vec::new();
        telemetry.write_csv_header(&mut line)?;
        with_column(&mut line, "recorder_dropped");
        out.write_all(&line)?;
        let drops = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
        let by_trigger: std::collections::HashMap<u64, u64> = drops.iter().copied().collect();
        for row in telemetry.rows() {
            line.clear();
            telemetry.write_csv_row(&mut line, row)?;
            let d = by_trigger
                .get(&row.trigger)
                .map_or_else(String::new, u64::to_string);
            with_column(&mut line, &d);
            out.write_all(&line)?;
        }
        Ok(())
    }
}

/// Adds `field` at the end of the CSV `line`.
fn with_column(line: &mut Vec<u8>, field: &str) {
    if line.last() == Some(&b'\n') {
        line.pop();
    }
    line.push(b',');
    line.extend_from_slice(field.as_bytes());
    line.push(b'\n');
}

impl SetSink for RecordSlot {
    fn offer(&self, set: &FrameSet, processed: Option<Processed<'_>>) {
        let Some(r) = self.recorder() else {
            return;
        };
        r.offer(set, processed);
        if let Some(p) = processed {
            let mut drops = self.drops.lock().unwrap_or_else(PoisonError::into_inner);
            drops.push_back((p.row.trigger, r.stats().dropped));
            while drops.len() > DROPS_KEPT {
                drops.pop_front();
            }
        }
    }
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
    let record_setup = RecordingSetup {
        cameras: source.cameras().to_vec(),
        rig: origin.rig.cloned(),
        source: origin.source_name.clone(),
        time_offset_ns: origin.time_offset_ns,
    };
    let slot = Arc::new(RecordSlot::default());
    if let Some(r) = record {
        slot.replace(Some(Arc::new(r.create_for(&record_setup)?)));
    }
    let camera_auto = source.has_camera_auto();
    let sink = slot.clone() as Arc<dyn SetSink>;
    let pipeline = Pipeline::start_with_sink(source, processor, options, notify, Some(sink))?;
    Ok(Session {
        pipeline,
        record: slot,
        record_setup,
        replay: None,
        source_name: origin.source_name,
        calibration: origin.calibration,
        camera_auto,
        rig: origin.rig.cloned(),
    })
}

/// A recording to replay.
#[derive(Clone, Debug, PartialEq)]
pub struct ReplaySpec {
    /// The recording.
    pub file: PathBuf,
    /// A calibration to use instead of the recording's own.
    pub rig: Option<PathBuf>,
    /// Replayed under the window's controls ([`ReplayControl`]): held at
    /// its end (paused) instead of finishing, so that it can be sought
    /// back.
    pub interactive: bool,
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
    let source = ReplaySource::open(&spec.file)
        .with_context(|| format!("cannot replay {}", spec.file.display()))?;
    let cameras = source.cameras().to_vec();
    let rig = replay_rig(spec, &source)?;
    let (view, graph, calibration) = match &rig {
        Some((rig, name)) => {
            let (v, g) = view_for(rig, &cameras, processing)
                .with_context(|| format!("the view of {name}"))?;
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
    // In the window: at the recorded rate; in lock step as fast as asked.
    let speed = (!options.lockstep).then_some(1.0);
    let (source, control) = Controlled::new(source, speed, spec.interactive);
    let mut session = start_session(source, processor, options, notify, record, origin)?;
    session.replay = Some(control);
    Ok(session)
}

/// What the window asks of a replay, and where the replay is.
#[derive(Debug, Default)]
struct ControlState {
    paused: bool,
    /// Sets to step from the last one given (negative: back).
    steps: i64,
    seek: Option<usize>,
    /// A new speed (`Some(None)`: as fast as possible).
    speed: Option<Option<f64>>,
    /// The speed in use.
    current_speed: Option<f64>,
    /// The number of the last set given.
    shown: Option<usize>,
    /// The last sets given: their triggers and numbers.
    given: std::collections::VecDeque<(u64, usize)>,
    at_end: bool,
}

/// Sets given that a [`ReplayControl`] can still number by their trigger
/// (more than the pipeline holds between the source and the window).
const GIVEN_KEPT: usize = 64;

/// The window's hold on a replay: play and pause, steps, seeks, speed,
/// and where the replay is. Requests take effect when the capture thread
/// next asks the replay for a set.
#[derive(Clone, Debug)]
pub struct ReplayControl {
    state: Arc<Mutex<ControlState>>,
    /// The sets' log times (`None`: the file has no index).
    times: Option<Arc<[u64]>>,
    file: PathBuf,
}

impl ReplayControl {
    fn lock(&self) -> std::sync::MutexGuard<'_, ControlState> {
        // Plain fields: no update leaves them half done.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// The recording.
    pub fn file(&self) -> &Path {
        &self.file
    }

    /// The sets' log times (Unix ns), if the file has its index (without
    /// one it can be played and stepped forward, not sought).
    pub fn times(&self) -> Option<&[u64]> {
        self.times.as_deref()
    }

    /// Pauses or plays (playing at the end starts again from the first
    /// set).
    pub fn set_paused(&self, paused: bool) {
        let mut s = self.lock();
        if !paused && s.at_end && self.times.is_some() {
            s.seek = Some(0);
            s.steps = 0;
        }
        s.paused = paused;
    }

    /// Whether the replay is paused (also at the end of an interactive
    /// replay).
    pub fn is_paused(&self) -> bool {
        self.lock().paused
    }

    /// Pauses and steps `n` sets from the last one given (negative: back,
    /// which needs the index).
    pub fn step(&self, n: i64) {
        let mut s = self.lock();
        s.paused = true;
        s.steps += n;
    }

    /// Goes to set number `k` (shown at once, even when paused).
    pub fn seek(&self, k: usize) {
        let mut s = self.lock();
        s.seek = Some(k);
        s.steps = 0;
    }

    /// The number of the set nearest to `log_time`, if the file has its
    /// index (and a set).
    pub fn set_at(&self, log_time: u64) -> Option<usize> {
        let times = self.times()?;
        let after = times.partition_point(|&t| t < log_time);
        let before = after.checked_sub(1);
        match (before, times.get(after)) {
            (Some(b), Some(&ta)) if log_time - times[b] < ta - log_time => Some(b),
            (_, Some(_)) => Some(after),
            (b, None) => b,
        }
    }

    /// Replays at `speed` times the recorded rate (`None`: as fast as
    /// possible).
    pub fn set_speed(&self, speed: Option<f64>) {
        let mut s = self.lock();
        s.speed = Some(speed);
        s.current_speed = speed;
    }

    /// The speed asked for.
    pub fn speed(&self) -> Option<f64> {
        self.lock().current_speed
    }

    /// The number of the last set given to processing.
    pub fn shown(&self) -> Option<usize> {
        self.lock().shown
    }

    /// The number of the set with `trigger` among the last sets given
    /// (the set the window shows lags the last one given while playing).
    pub fn number_of(&self, trigger: u64) -> Option<usize> {
        let s = self.lock();
        s.given.iter().rev().find(|g| g.0 == trigger).map(|g| g.1)
    }

    /// Whether the replay has given its last set.
    pub fn at_end(&self) -> bool {
        self.lock().at_end
    }
}

/// A [`ReplaySource`] under a [`ReplayControl`].
struct Controlled {
    inner: ReplaySource,
    control: ReplayControl,
    /// Held at the end instead of finishing.
    hold: bool,
    speed: Option<f64>,
    was_paused: bool,
    messages: Vec<String>,
}

impl Controlled {
    fn new(mut inner: ReplaySource, speed: Option<f64>, hold: bool) -> (Self, ReplayControl) {
        inner.set_speed(speed);
        let control = ReplayControl {
            state: Arc::new(Mutex::new(ControlState {
                current_speed: speed,
                ..Default::default()
            })),
            times: inner.times().map(Arc::from),
            file: inner.file().to_owned(),
        };
        let source = Self {
            inner,
            control: control.clone(),
            hold,
            speed,
            was_paused: false,
            messages: Vec::new(),
        };
        (source, control)
    }

    /// Carries out the window's requests; whether a set is to be given now
    /// even though the replay is paused.
    fn apply_requests(&mut self) -> (bool, bool) {
        let (seek, steps, speed, paused, shown) = {
            let mut s = self.control.lock();
            (
                s.seek.take(),
                std::mem::take(&mut s.steps),
                s.speed.take(),
                s.paused,
                s.shown,
            )
        };
        if let Some(speed) = speed {
            self.speed = speed;
            self.inner.set_speed(speed);
        }
        if !paused && self.was_paused {
            // The pause is not replayed: the clock starts again now.
            self.inner.set_speed(self.speed);
        }
        self.was_paused = paused;
        let mut one = false;
        if let Some(k) = seek {
            match self.inner.seek(k) {
                Ok(()) => one = true,
                Err(e) => self.messages.push(e.to_string()),
            }
        }
        if steps != 0 {
            let from = shown.map_or(-1, |k| i64::try_from(k).unwrap_or(i64::MAX));
            let target = usize::try_from(from.saturating_add(steps).max(0)).unwrap_or(0);
            if self.inner.position().is_some() {
                match self.inner.seek(target) {
                    Ok(()) => one = true,
                    Err(e) => self.messages.push(e.to_string()),
                }
            } else if steps == 1 {
                // Without the index the next set is the only one to step to.
                one = true;
            } else {
                self.messages.push(format!(
                    "{}: the file has no index, so it steps forward one set at a time only; \
                     `rigview recording repair` rewrites it with one",
                    self.inner.file().display()
                ));
            }
        }
        if one {
            // Given at once, whatever the pacing.
            self.inner.set_speed(self.speed);
        }
        (paused, one)
    }
}

impl FrameSource for Controlled {
    fn cameras(&self) -> &[CameraInfo] {
        self.inner.cameras()
    }

    fn next_set(&mut self, timeout: Duration) -> Result<Option<FrameSet>, SourceError> {
        let (paused, one) = self.apply_requests();
        if paused && !one {
            std::thread::sleep(timeout.min(Duration::from_millis(20)));
            return Ok(None);
        }
        let k = self.inner.position();
        // A paced wait is cut short, so that a pause takes effect within
        // 20 ms.
        let got = self.inner.next_set(timeout.min(Duration::from_millis(20)));
        let mut s = self.control.lock();
        match &got {
            Ok(Some(set)) => {
                let n = k.unwrap_or_else(|| s.shown.map_or(0, |n| n + 1));
                s.shown = Some(n);
                s.given.push_back((set.trigger, n));
                if s.given.len() > GIVEN_KEPT {
                    s.given.pop_front();
                }
                s.at_end = false;
            }
            Ok(None) if self.inner.is_finished() => {
                s.at_end = true;
                if self.hold {
                    s.paused = true;
                }
            }
            Ok(None) | Err(_) => {}
        }
        got
    }

    fn apply(&mut self, _commands: &[ExposureCommand]) -> Result<(), SourceError> {
        Ok(())
    }

    fn health(&self) -> Vec<StreamHealth> {
        self.inner.health()
    }

    fn is_finished(&self) -> bool {
        !self.hold && self.inner.is_finished()
    }

    fn take_messages(&mut self) -> Vec<String> {
        let mut m = std::mem::take(&mut self.messages);
        m.extend(self.inner.take_messages());
        m
    }
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
pub(crate) struct Opened {
    /// The source.
    pub source: Box<dyn FrameSource>,
    /// Its calibration, when it fits the source's cameras.
    pub rig: Option<Rig>,
    /// What it is, for the recording's metadata.
    pub what: String,
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

/// Opens what `rigview record` captures from (the simulated rig paced at
/// its trigger rate).
pub(crate) fn open(from: &CaptureFrom) -> Result<Opened> {
    Ok(match from {
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
    })
}

/// `--seconds S` as a duration.
pub(crate) fn time_limit(seconds: Option<f64>) -> Result<Option<Duration>> {
    seconds
        .map(Duration::try_from_secs_f64)
        .transpose()
        .context("--seconds: expected a number of seconds ≥ 0")
}

/// Captures `run`, printing the set count now and then; returns the
/// recording's summary.
pub fn capture(run: &CaptureRun, out: &mut dyn std::io::Write) -> Result<String> {
    let opened = open(&run.from)?;
    let recorder = run.record.create(
        opened.source.cameras(),
        opened.rig.as_ref(),
        &opened.what,
        opened.time_offset_ns,
    )?;
    let mut source = opened.source;
    let start = Instant::now();
    let limit = time_limit(run.seconds)?;
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
    let fits = view_for(&rig, source.cameras(), &ProcessingSettings::default()).is_ok();
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

#[cfg(test)]
mod tests {
    use super::*;

    fn control(times: Option<Vec<u64>>) -> ReplayControl {
        ReplayControl {
            state: Arc::default(),
            times: times.map(Arc::from),
            file: PathBuf::from("drive.mcap"),
        }
    }

    #[test]
    fn a_seek_by_time_goes_to_the_nearest_set() {
        let c = control(Some(vec![100, 200, 300]));
        assert_eq!(c.set_at(0), Some(0));
        assert_eq!(c.set_at(149), Some(0));
        assert_eq!(c.set_at(151), Some(1));
        assert_eq!(c.set_at(300), Some(2));
        assert_eq!(c.set_at(10_000), Some(2));
        assert_eq!(control(Some(Vec::new())).set_at(5), None);
        // Without the index there is nothing to seek by.
        assert_eq!(control(None).set_at(5), None);
    }

    #[test]
    fn steps_pause_and_playing_at_the_end_starts_again() {
        let c = control(Some(vec![100, 200, 300]));
        c.step(1);
        c.step(-2);
        assert!(c.is_paused());
        assert_eq!(c.lock().steps, -1);
        c.lock().at_end = true;
        c.set_paused(false);
        assert!(!c.is_paused());
        let s = c.lock();
        assert_eq!((s.seek, s.steps), (Some(0), 0));
    }
}
