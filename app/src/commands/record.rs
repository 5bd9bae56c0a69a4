//! `rigview record`: capture into a recording without processing (or, with
//! `--brackets`, into a bracket sequence: [`crate::session::brackets`]).

use std::time::{Duration, Instant};

use anyhow::Result;

use crate::session::brackets::capture as brackets;
pub use crate::session::brackets::capture::BracketRun;
use crate::session::capture::{open, time_limit, CaptureFrom};
use crate::session::record::{describe, RecordSpec};

/// What `rigview record` writes.
#[derive(Debug)]
pub enum RecordJob {
    /// A recording (MCAP).
    Recording(CaptureRun),
    /// A bracket sequence.
    Brackets(BracketRun),
}

/// Runs `job`, printing progress to `out`; returns its summary.
pub fn run(job: &RecordJob, out: &mut dyn std::io::Write) -> Result<String> {
    match job {
        RecordJob::Recording(run) => capture(run, out),
        RecordJob::Brackets(run) => brackets::capture(run, out),
    }
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
