//! The pipeline's threads: capture and processing, the queues between them
//! and the display, and what the operator sends while they run.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, Sender, TryRecvError};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::processor::ms;
use super::{
    Control, DropOldest, Output, Processed, Processor, QueueStats, SetSink, StageTimes, Strategy,
    Telemetry, TelemetryRow,
};
use crate::error::{Error, Result};
use crate::source::{
    CameraInfo, ExposureCommand, FrameSet, FrameSource, RateMeter, SetCounters, SourceError,
    StreamHealth,
};

/// A set as the capture thread hands it on.
#[derive(Debug)]
struct Captured {
    set: FrameSet,
    ready: Instant,
    capture_ms: f64,
}

/// How the pipeline runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PipelineOptions {
    /// Sets waiting between capture and processing (default 4: 200 ms at
    /// 20 Hz, enough for the first sets, which take longer).
    pub queue: usize,
    /// Outputs waiting for the display (1 for a window, which only wants the
    /// newest; more for a consumer that wants every output).
    pub output_queue: usize,
    /// Lock step (offline sources only): capture asks for the next set only
    /// when processing is done with the last one and its commands are
    /// applied, so nothing is dropped and a run is repeatable.
    pub lockstep: bool,
    /// Telemetry rows kept.
    pub history: usize,
    /// Whether views are composed.
    pub compose: bool,
}

impl Default for PipelineOptions {
    fn default() -> Self {
        Self {
            queue: 4,
            output_queue: 1,
            lockstep: false,
            history: 2400,
            compose: true,
        }
    }
}

/// The state of the pipeline as a whole.
#[derive(Clone, Debug, Default)]
pub struct PipelineStatus {
    /// Per camera, its stream health.
    pub health: Vec<StreamHealth>,
    /// How the source assembled its sets (sources that match frames into
    /// sets: live cameras).
    pub assembly: Option<SetCounters>,
    /// The queue between capture and processing (its drops are sets that
    /// processing lost).
    pub capture_queue: QueueStats,
    /// The queue between processing and the display.
    pub output_queue: QueueStats,
    /// Sets the source gave.
    pub sets: u64,
    /// Sets that were incomplete (not processed).
    pub incomplete: u64,
    /// Sets processed.
    pub processed: u64,
    /// Sets reaching processing per second, over the last second.
    pub set_rate_hz: f64,
    /// The most recent problems, newest last (the last 8).
    pub errors: VecDeque<String>,
    /// Problems so far, including those forgotten (a problem repeated at
    /// once counts once).
    pub errors_total: u64,
    /// The source's messages for the operator, newest last (the last 50).
    pub notes: VecDeque<String>,
    /// Messages so far, including those forgotten.
    pub notes_total: u64,
    /// Whether the source has ended (a replay or a bounded simulation).
    pub finished: bool,
    /// Whether both threads have stopped.
    pub stopped: bool,
    /// The last end-to-end latencies (set ready → displayed), ms, with the
    /// time of the set, s.
    pub display_latency: VecDeque<[f64; 2]>,
}

impl PipelineStatus {
    fn error(&mut self, e: String) {
        if self.errors.back() != Some(&e) {
            self.errors.push_back(e);
            self.errors_total += 1;
        }
        while self.errors.len() > 8 {
            self.errors.pop_front();
        }
    }
}

enum CaptureMsg {
    Commands(Vec<ExposureCommand>),
    CameraAuto(bool),
    /// Processing is done with a set (lock step: capture may go on).
    Done,
}

/// The newest output for a consumer beside the window or the headless
/// loop (a remote view): each processed set replaces the one before, and
/// taking it leaves the pipeline's own outputs alone.
#[derive(Debug, Default)]
pub struct OutputWatch {
    latest: Mutex<Option<Arc<Output>>>,
    ready: std::sync::Condvar,
    /// The pipeline's status when the newest output was made.
    status: Mutex<Option<PipelineStatus>>,
}

impl OutputWatch {
    fn put(&self, output: &Arc<Output>, status: &PipelineStatus) {
        *lock(&self.status) = Some(status.clone());
        *lock(&self.latest) = Some(output.clone());
        self.ready.notify_all();
    }

    /// The pipeline's status (streams, counts, drops before processing)
    /// when the newest output was made.
    pub fn status(&self) -> Option<PipelineStatus> {
        lock(&self.status).clone()
    }

    /// The newest output of a set after trigger `after` (`None`: any),
    /// waiting up to `timeout` for one.
    pub fn newer(&self, after: Option<u64>, timeout: Duration) -> Option<Arc<Output>> {
        let fresh = |o: &Option<Arc<Output>>| {
            o.as_ref()
                .filter(|o| after.is_none_or(|t| o.trigger > t))
                .cloned()
        };
        let guard = lock(&self.latest);
        if let Some(o) = fresh(&guard) {
            return Some(o);
        }
        let (guard, _) = self
            .ready
            .wait_timeout_while(guard, timeout, |o| fresh(o).is_none())
            .unwrap_or_else(PoisonError::into_inner);
        fresh(&guard)
    }
}

#[derive(Debug)]
struct Shared {
    stop: AtomicBool,
    watches: Mutex<Vec<Arc<OutputWatch>>>,
    telemetry: Mutex<Telemetry>,
    status: Mutex<PipelineStatus>,
    t0_ns: Mutex<Option<u64>>,
}

fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    // Every update under these locks leaves the data consistent, so a
    // poisoned lock still holds good data.
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// The running pipeline (see the module documentation). Dropping it stops
/// its threads.
#[derive(Debug)]
pub struct Pipeline {
    cameras: Vec<CameraInfo>,
    control: Sender<Control>,
    shared: Arc<Shared>,
    captured: Arc<DropOldest<Captured>>,
    output: Arc<DropOldest<Arc<Output>>>,
    threads: Vec<JoinHandle<()>>,
    started: Instant,
}

/// Called after each output is queued (a window asks for a repaint).
pub type Notify = Arc<dyn Fn() + Send + Sync>;

impl Pipeline {
    /// Starts the threads on `source`.
    pub fn start<S: FrameSource + 'static>(
        source: S,
        processor: Processor,
        options: PipelineOptions,
        notify: Notify,
    ) -> Result<Self> {
        Self::start_with_sink(source, processor, options, notify, None)
    }

    /// Starts the threads on `source`; every set the processing thread
    /// takes also goes to `sink` (a recorder).
    pub fn start_with_sink<S: FrameSource + 'static>(
        source: S,
        processor: Processor,
        options: PipelineOptions,
        notify: Notify,
        sink: Option<Arc<dyn SetSink>>,
    ) -> Result<Self> {
        let cameras = source.cameras().to_vec();
        if cameras.len() != processor.cameras().len() {
            return Err(Error::invalid(
                "pipeline",
                "the source's cameras",
                format!("the processor's {}", processor.cameras().len()),
                cameras.len(),
            ));
        }
        let names = cameras.iter().map(|c| c.name.clone()).collect();
        let shared = Arc::new(Shared {
            stop: AtomicBool::new(false),
            watches: Mutex::new(Vec::new()),
            telemetry: Mutex::new(Telemetry::new(names, &processor.pairs(), options.history)),
            status: Mutex::new(PipelineStatus {
                health: source.health(),
                ..Default::default()
            }),
            t0_ns: Mutex::new(None),
        });
        let captured = Arc::new(DropOldest::new(options.queue));
        let output = Arc::new(DropOldest::new(options.output_queue));
        let (control_tx, control_rx) = mpsc::channel();
        let (capture_tx, capture_rx) = mpsc::channel();
        let mut processor = processor;
        processor.set_compose(options.compose);
        if processor.settings().strategy == Strategy::CameraAuto {
            let _ = capture_tx.send(CaptureMsg::CameraAuto(true));
        }
        let capture = {
            let (shared, captured) = (shared.clone(), captured.clone());
            let lockstep = options.lockstep;
            std::thread::Builder::new()
                .name("rigview-capture".into())
                .spawn(move || capture_loop(source, &shared, &captured, &capture_rx, lockstep))
                .map_err(|e| Error::ThreadStart {
                    thread: "capture",
                    source: e,
                })?
        };
        let processing = {
            let (shared, captured, output) = (shared.clone(), captured.clone(), output.clone());
            std::thread::Builder::new()
                .name("rigview-processing".into())
                .spawn(move || {
                    let mut ctx = ProcessingLoop {
                        processor,
                        shared: &shared,
                        captured: &captured,
                        output: &output,
                        control: &control_rx,
                        capture: &capture_tx,
                        notify: &notify,
                        recent: RateMeter::default(),
                        sink,
                    };
                    ctx.run();
                    output.close();
                    lock(&shared.status).stopped = true;
                    notify();
                })
                .map_err(|e| Error::ThreadStart {
                    thread: "processing",
                    source: e,
                })?
        };
        Ok(Self {
            cameras,
            control: control_tx,
            shared,
            captured,
            output,
            threads: vec![capture, processing],
            started: Instant::now(),
        })
    }

    /// The source's cameras.
    pub fn cameras(&self) -> &[CameraInfo] {
        &self.cameras
    }

    /// Sends a change to the processing thread.
    pub fn send(&self, control: Control) -> Result<()> {
        self.control
            .send(control)
            .map_err(|_| Error::PipelineStopped)
    }

    /// A watch of the newest output, beside the pipeline's own outputs.
    pub fn watch(&self) -> Arc<OutputWatch> {
        let w = Arc::new(OutputWatch::default());
        lock(&self.shared.watches).push(w.clone());
        w
    }

    /// The newest output not yet taken (older ones are skipped).
    pub fn latest(&self) -> Option<Arc<Output>> {
        self.output.take_latest()
    }

    /// The next output in order, waiting up to `timeout` (for consumers
    /// that want every output; start with a long output queue).
    pub fn next_output(&self, timeout: Duration) -> Option<Arc<Output>> {
        self.output.pop(timeout)
    }

    /// Records that `output` was shown now: the end-to-end latency.
    pub fn displayed(&self, output: &Output) {
        let latency = ms(Instant::now().saturating_duration_since(output.ready));
        let t = self.started.elapsed().as_secs_f64();
        let mut s = lock(&self.shared.status);
        s.display_latency.push_back([t, latency]);
        while s.display_latency.len() > 2400 {
            s.display_latency.pop_front();
        }
    }

    /// The telemetry history (hold the guard briefly: processing waits for
    /// it to record the next set).
    pub fn telemetry(&self) -> MutexGuard<'_, Telemetry> {
        lock(&self.shared.telemetry)
    }

    /// The pipeline's state.
    pub fn status(&self) -> PipelineStatus {
        let mut s = lock(&self.shared.status).clone();
        s.capture_queue = self.captured.stats();
        s.output_queue = self.output.stats();
        s
    }

    /// Whether the threads have stopped (the source ended or failed).
    pub fn is_stopped(&self) -> bool {
        lock(&self.shared.status).stopped
    }

    /// Stops the threads and waits for them.
    pub fn stop(&mut self) {
        self.shared.stop.store(true, Ordering::SeqCst);
        self.captured.close();
        self.output.close();
        for t in self.threads.drain(..) {
            // A thread that panicked has nothing more to give; its panic
            // message went to stderr.
            let _ = t.join();
        }
    }
}

impl Drop for Pipeline {
    fn drop(&mut self) {
        self.stop();
    }
}

fn capture_loop<S: FrameSource>(
    mut source: S,
    shared: &Shared,
    captured: &DropOldest<Captured>,
    messages: &Receiver<CaptureMsg>,
    lockstep: bool,
) {
    let mut last_health = Instant::now();
    // Lock step: sets handed on that processing has not finished.
    let mut in_flight = 0usize;
    while !shared.stop.load(Ordering::SeqCst) {
        loop {
            let msg = if lockstep && in_flight > 0 {
                match messages.recv_timeout(Duration::from_millis(100)) {
                    Ok(m) => m,
                    Err(mpsc::RecvTimeoutError::Timeout) => {
                        if shared.stop.load(Ordering::SeqCst) {
                            return;
                        }
                        continue;
                    }
                    Err(mpsc::RecvTimeoutError::Disconnected) => return,
                }
            } else {
                match messages.try_recv() {
                    Ok(m) => m,
                    Err(TryRecvError::Empty | TryRecvError::Disconnected) => break,
                }
            };
            let result = match msg {
                CaptureMsg::Commands(c) => source.apply(&c),
                CaptureMsg::CameraAuto(on) => source.set_camera_auto(on),
                CaptureMsg::Done => {
                    in_flight = in_flight.saturating_sub(1);
                    Ok(())
                }
            };
            if let Err(e) = result {
                lock(&shared.status).error(e.to_string());
            }
        }
        let t = Instant::now();
        let got = source.next_set(Duration::from_millis(100));
        let ready = Instant::now();
        if last_health.elapsed() >= Duration::from_millis(250) {
            let notes = source.take_messages();
            let mut s = lock(&shared.status);
            s.health = source.health();
            s.assembly = source.set_counters();
            s.notes_total += notes.len() as u64;
            s.notes.extend(notes);
            while s.notes.len() > 50 {
                s.notes.pop_front();
            }
            last_health = Instant::now();
        }
        match got {
            Ok(Some(set)) => {
                lock(&shared.status).sets += 1;
                let item = Captured {
                    set,
                    ready,
                    capture_ms: ms(ready - t),
                };
                if lockstep {
                    in_flight += 1;
                    let mut item = item;
                    loop {
                        match captured.push_wait(item, Duration::from_millis(100)) {
                            Ok(()) => break,
                            Err(back) => {
                                if shared.stop.load(Ordering::SeqCst) || captured.is_closed() {
                                    return;
                                }
                                item = back;
                            }
                        }
                    }
                } else {
                    captured.push(item);
                }
            }
            Ok(None) => {
                if source.is_finished() {
                    break;
                }
            }
            Err(e) => {
                let fatal = matches!(e, SourceError::Failed(_));
                lock(&shared.status).error(e.to_string());
                if fatal {
                    std::thread::sleep(Duration::from_millis(200));
                }
            }
        }
    }
    {
        let notes = source.take_messages();
        let mut s = lock(&shared.status);
        s.health = source.health();
        s.assembly = source.set_counters();
        s.finished = source.is_finished();
        s.notes_total += notes.len() as u64;
        s.notes.extend(notes);
    }
    captured.close();
}

struct ProcessingLoop<'a> {
    processor: Processor,
    shared: &'a Shared,
    captured: &'a DropOldest<Captured>,
    output: &'a DropOldest<Arc<Output>>,
    control: &'a Receiver<Control>,
    capture: &'a Sender<CaptureMsg>,
    notify: &'a Notify,
    recent: RateMeter,
    sink: Option<Arc<dyn SetSink>>,
}

impl ProcessingLoop<'_> {
    fn run(&mut self) {
        loop {
            self.apply_controls();
            if self.shared.stop.load(Ordering::SeqCst) {
                return;
            }
            let Some(item) = self.captured.pop(Duration::from_millis(50)) else {
                if self.captured.is_closed() && self.captured.is_empty() {
                    return;
                }
                continue;
            };
            self.one(item);
            // Lock step: the commands went first, so the next set shows them.
            let _ = self.capture.send(CaptureMsg::Done);
        }
    }

    fn error(&self, e: impl ToString) {
        lock(&self.shared.status).error(e.to_string());
    }

    fn apply_controls(&mut self) {
        while let Ok(c) = self.control.try_recv() {
            let result = match c {
                Control::Settings(s) => match self.processor.set_settings(*s) {
                    Ok(Some(on)) => {
                        let _ = self.capture.send(CaptureMsg::CameraAuto(on));
                        Ok(())
                    }
                    Ok(None) => Ok(()),
                    Err(e) => Err(e),
                },
                Control::Manual { camera, exposure } => self.processor.set_manual(camera, exposure),
                Control::Refine => self.processor.refine(),
                Control::Calibration { view, graph } => {
                    let r = self.processor.set_calibration(view.map(|v| *v), graph);
                    if r.is_ok() {
                        lock(&self.shared.telemetry).set_pairs(&self.processor.pairs());
                    }
                    r
                }
            };
            if let Err(e) = result {
                self.error(e);
            }
        }
    }

    fn one(&mut self, item: Captured) {
        let popped = Instant::now();
        let Captured {
            set,
            ready,
            capture_ms,
        } = item;
        if !set.is_complete() {
            lock(&self.shared.status).incomplete += 1;
            if let Some(sink) = &self.sink {
                sink.offer(&set, None);
            }
            return;
        }
        let rate = self.recent.tick_at(ready);
        let times = StageTimes {
            capture_ms,
            queue_ms: ms(popped.saturating_duration_since(ready)),
            ..Default::default()
        };
        match self.processor.process(&set, ready, times) {
            Ok((output, commands)) => {
                if !commands.is_empty() {
                    let _ = self.capture.send(CaptureMsg::Commands(commands));
                }
                if let Some(e) = &output.compose_error {
                    self.error(format!("the view cannot be composed: {e}"));
                }
                let dropped = self.captured.stats().dropped;
                let time_s = {
                    let mut t0 = lock(&self.shared.t0_ns);
                    let base = *t0.get_or_insert(set.timestamp_ns);
                    set.timestamp_ns.saturating_sub(base) as f64 * 1e-9
                };
                let row = TelemetryRow::of(&output, time_s, rate, dropped);
                if let Some(sink) = &self.sink {
                    let pair_names = lock(&self.shared.telemetry).pair_names().to_vec();
                    sink.offer(
                        &set,
                        Some(Processed {
                            row: &row,
                            settings: self.processor.settings(),
                            pair_names: &pair_names,
                        }),
                    );
                }
                lock(&self.shared.telemetry).push(row);
                {
                    let mut s = lock(&self.shared.status);
                    s.processed += 1;
                    s.set_rate_hz = rate;
                }
                let output = Arc::new(output);
                let watches = lock(&self.shared.watches);
                if !watches.is_empty() {
                    let mut status = lock(&self.shared.status).clone();
                    status.capture_queue = self.captured.stats();
                    for w in watches.iter() {
                        w.put(&output, &status);
                    }
                }
                drop(watches);
                self.output.push(output);
                (self.notify)();
            }
            Err(e) => self.error(format!("frame set {}: {e}", set.trigger)),
        }
    }
}
