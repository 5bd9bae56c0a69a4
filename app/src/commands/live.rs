//! `rigview live --headless`: the rig's cameras in closed-loop exposure
//! control without the window, with a status block per second.

use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::Result;
use rigview_core::pipeline::{Output, PipelineOptions, PipelineStatus, ProcessingSettings};
use rigview_core::source::StreamState;

use crate::live::LiveSpec;
use crate::logging::{LogBuffer, StatusLog};
use crate::session::{self, SourceSpec};

fn state_word(s: StreamState) -> &'static str {
    match s {
        StreamState::Streaming => "streaming",
        StreamState::Lost => "LOST",
        StreamState::Reconnecting => "reconnecting",
    }
}

/// The status block printed once a second: one line for the sets, one per
/// camera (its stream, the exposure its last frame was taken with, γ̂, the
/// command sent and, when balanced, α of Eq. 6), and one for the overlaps'
/// brightness ratios.
pub fn format_status(
    elapsed: Duration,
    names: &[String],
    status: &PipelineStatus,
    last: Option<&Output>,
) -> String {
    let mut s = format!(
        "[{:7.1} s] sets: {} from the cameras, {} processed, {} incomplete, {} dropped (processing behind)",
        elapsed.as_secs_f64(),
        status.sets,
        status.processed,
        status.incomplete,
        status.capture_queue.dropped,
    );
    if let Some(a) = &status.assembly {
        s += &format!(
            "; {} frames broken, {} missing; skew last {:.2} ms, max {:.2} ms",
            a.broken_frames,
            a.missing_frames,
            a.last_skew_ns as f64 / 1e6,
            a.max_skew_ns as f64 / 1e6,
        );
    }
    s.push('\n');
    for (i, name) in names.iter().enumerate() {
        let h = status.health.get(i).cloned().unwrap_or_default();
        let cam = last.and_then(|o| o.cameras.get(i));
        let step = last.and_then(|o| o.step.cameras.get(i));
        let (e, gain) = cam.map_or((f64::NAN, f64::NAN), |c| {
            (c.taken.exposure(), c.taken.gain_db)
        });
        let gamma = cam
            .and_then(|c| c.estimate.as_ref())
            .map_or(f64::NAN, |e| e.gamma_hat);
        let command = match cam.and_then(|c| c.command) {
            Some(c) => format!("→ {:>9.0}", c.exposure()),
            None => format!("{:>11}", "no command"),
        };
        let alpha = step
            .and_then(|c| c.alpha)
            .map_or_else(String::new, |a| format!("  balanced α {a:.2}"));
        s += &format!(
            "  {name:<10} {:<12} {:5.1} fps  E {e:>9.0}  gain {gain:5.2} dB  γ̂ {gamma:5.2}  {command}{alpha}  completed {:>6} failed {:>4} underruns {:>3} packets missing {:>5} resent {:>5}\n",
            state_word(h.state),
            h.fps,
            h.completed,
            h.failed,
            h.underruns,
            h.missing_packets,
            h.resent_packets,
        );
    }
    if let Some(o) = last.filter(|o| !o.pairs.is_empty()) {
        let pairs: Vec<String> = o
            .pairs
            .iter()
            .map(|p| {
                let label = format!(
                    "{}-{}",
                    names.get(p.i).map_or("?", String::as_str),
                    names.get(p.j).map_or("?", String::as_str)
                );
                match p.log2_r {
                    Some(r) => format!("{label} {r:+.2}"),
                    None => format!("{label} n/a"),
                }
            })
            .collect();
        s += &format!("  overlaps, log2 r_ij: {}\n", pairs.join(", "));
    }
    s
}

/// Runs the live cameras of `spec` headless, with the processing
/// `settings` (the same processor as the window), for `limit` or until the
/// source ends; prints a status block per second, the events that reach
/// `log` as they come (what the window's Messages panel shows), and a last
/// block and a summary at the end.
pub fn run(
    spec: &LiveSpec,
    limit: Option<Duration>,
    settings: &ProcessingSettings,
    log: &LogBuffer,
    record: Option<&crate::session::RecordSpec>,
    serve: Option<&crate::serve::ServeOptions>,
    out: &mut dyn Write,
) -> Result<()> {
    writeln!(
        out,
        "rigview live: {}; {}; opening the cameras one after another…",
        crate::report::control(settings),
        spec.capture.trigger.describe()
    )?;
    let t0 = Instant::now();
    let mut seen = log.next_seq();
    let mut session = session::start_recording(
        &SourceSpec::Live(spec.clone()),
        settings,
        PipelineOptions::default(),
        Arc::new(|| {}),
        record,
    )?;
    let recorder = session.recorder();
    if let Some(options) = serve {
        session.serve(options)?;
    }
    writeln!(
        out,
        "{}; calibration: {}",
        session.source_name, session.calibration
    )?;
    if let Some(s) = &session.serving {
        writeln!(out, "remote view on ws://{}", s.addr())?;
    }
    let serving = session.serving.take();
    for e in log.read(&mut seen) {
        writeln!(out, "  {}", e.line())?;
    }
    let names = session.camera_names();
    let pipeline = &mut session.pipeline;
    let mut next_print = Instant::now() + Duration::from_secs(1);
    let mut last = None;
    let mut status_log = StatusLog::default();
    // The newest output, the status, and the new messages from the cameras
    // and new problems, printed as they come.
    let mut poll = |pipeline: &mut rigview_core::pipeline::Pipeline,
                    last: &mut Option<Arc<Output>>,
                    out: &mut dyn Write|
     -> Result<PipelineStatus> {
        if let Some(o) = pipeline.latest() {
            *last = Some(o);
        }
        let status = pipeline.status();
        status_log.forward(&status);
        let at = t0.elapsed().as_secs_f64();
        for e in log.read(&mut seen) {
            writeln!(out, "  [{at:7.1} s] {}", e.line())?;
        }
        Ok(status)
    };
    loop {
        let status = poll(pipeline, &mut last, out)?;
        if status.stopped || limit.is_some_and(|l| t0.elapsed() >= l) {
            break;
        }
        if Instant::now() >= next_print {
            let block = format_status(t0.elapsed(), &names, &status, last.as_deref());
            write!(out, "{block}")?;
            if let Some(r) = &recorder {
                writeln!(out, "  {}", crate::session::describe(r.file(), &r.stats()))?;
            }
            if let Some(s) = &serving {
                writeln!(out, "  {}", s.status_line())?;
            }
            next_print += Duration::from_secs(1);
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    pipeline.stop();
    let status = poll(pipeline, &mut last, out)?;
    write!(
        out,
        "{}",
        format_status(t0.elapsed(), &names, &status, last.as_deref())
    )?;
    writeln!(
        out,
        "done: {} frame sets, {} fed to the controller, {} incomplete kept from it, {} dropped",
        status.sets, status.processed, status.incomplete, status.capture_queue.dropped
    )?;
    if let Some(r) = &recorder {
        writeln!(out, "{}", crate::session::describe(r.file(), &r.finish()))?;
    }
    Ok(())
}
