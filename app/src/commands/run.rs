//! `rigview run --headless`: the pipeline on a source without the window.
//! It writes the composed views as PNG, the telemetry as CSV, a PNG plot of
//! the exposure state and a summary, with a progress bar on the terminal.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use anyhow::{Context, Result};
use rigview_core::pipeline::{Output, PipelineOptions, ProcessingSettings};
use rigview_core::surround::Canvas;

use crate::logging::{LogBuffer, StatusLog};
use crate::report::{self, CpuMeter};
use crate::session::{self, SourceSpec};

/// A headless run.
#[derive(Debug)]
pub struct HeadlessRun {
    /// Where frame sets come from.
    pub source: SourceSpec,
    /// Frame sets to run.
    pub frames: u64,
    /// The output folder (created if missing).
    pub out: PathBuf,
    /// Write the composed view of every `every`-th set (and of the last).
    pub every: u64,
    /// Record every processed set.
    pub record: Option<crate::session::RecordSpec>,
    /// Serve the live remote view.
    pub serve: Option<crate::serve::ServeOptions>,
}

fn write_canvas(c: &Canvas, path: &Path) -> Result<()> {
    let (w, h) = (
        u32::try_from(c.width).context("canvas width")?,
        u32::try_from(c.height).context("canvas height")?,
    );
    let r = if c.channels == 3 {
        image::RgbImage::from_raw(w, h, c.data.clone()).map(|i| i.save(path))
    } else {
        image::GrayImage::from_raw(w, h, c.data.clone()).map(|i| i.save(path))
    };
    r.context("the canvas has the wrong size")?
        .with_context(|| format!("writing the view {}", path.display()))
}

/// Runs `run` with the processing `settings`; returns its summary (also
/// written to `summary.txt`), which ends with the events that reached `log`
/// during the run (what the window's Messages panel shows). `progress`
/// shows a progress bar with the newest event.
pub fn run(
    run: &HeadlessRun,
    settings: &ProcessingSettings,
    log: &LogBuffer,
    progress: bool,
) -> Result<String> {
    let out = run.out.as_path();
    std::fs::create_dir_all(out.join("views"))
        .with_context(|| format!("creating the output folder {}", out.display()))?;
    let frames = run.frames;
    let spec = &run.source;
    let lockstep = match spec {
        SourceSpec::Sim(s) => !s.realtime,
        SourceSpec::Replay(_) | SourceSpec::Brackets(_) => true,
        SourceSpec::Live(_) => false,
    };
    let cpu = CpuMeter::start();
    let first = log.next_seq();
    let mut seen = first;
    let mut status_log = StatusLog::default();
    let mut session = session::start_recording(
        spec,
        settings,
        PipelineOptions {
            lockstep,
            output_queue: 8,
            history: usize::try_from(frames)
                .unwrap_or(usize::MAX)
                .saturating_add(16),
            ..Default::default()
        },
        Arc::new(|| {}),
        run.record.as_ref(),
    )?;
    if let Some(options) = &run.serve {
        session.serve(options)?;
        if let Some(s) = &session.serving {
            tracing::info!(target: crate::logging::NOTE, "remote view on ws://{} (Foxglove: Open connection, Foxglove WebSocket)", s.addr());
        }
    }
    let bar = if progress {
        indicatif::ProgressBar::new(frames)
    } else {
        indicatif::ProgressBar::hidden()
    };
    bar.set_style(
        indicatif::ProgressStyle::with_template(
            "{spinner} [{elapsed_precise}] {bar:40} {pos}/{len} sets ({per_sec}) {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let mut done = 0u64;
    let mut last: Option<Arc<Output>> = None;
    let mut written = 0usize;
    let every = run.every.max(1);
    // Processing may record the last sets before their outputs are taken:
    // the loop goes on until the output of the newest row is taken.
    let mut caught_up = true;
    while done < frames || !caught_up {
        let Some(o) = session.pipeline.next_output(Duration::from_millis(200)) else {
            if session.pipeline.is_stopped() || done >= frames {
                break;
            }
            continue;
        };
        {
            let telemetry = session.pipeline.telemetry();
            done = telemetry.total();
            caught_up = telemetry.last().is_none_or(|r| r.trigger == o.trigger);
        }
        bar.set_position(done);
        status_log.forward(&session.pipeline.status());
        if let Some(s) = &session.serving {
            bar.set_message(s.status_line());
        }
        if let Some(e) = log.read(&mut seen).last() {
            bar.set_message(e.line());
        }
        if o.trigger % every == 0 {
            if let Some(c) = &o.canvas {
                write_canvas(
                    c,
                    &out.join("views").join(format!("view_{:06}.png", o.trigger)),
                )?;
                written += 1;
            }
        }
        last = Some(o);
    }
    session.pipeline.stop();
    bar.finish_and_clear();
    let recorded = session
        .recorder()
        .map(|r| crate::session::describe(r.file(), &r.finish()));
    if let Some(o) = &last {
        if o.trigger % every != 0 {
            if let Some(c) = &o.canvas {
                write_canvas(
                    c,
                    &out.join("views").join(format!("view_{:06}.png", o.trigger)),
                )?;
                written += 1;
            }
        }
    }
    let status = session.pipeline.status();
    status_log.forward(&status);
    let telemetry = session.pipeline.telemetry().clone();
    let csv = out.join("telemetry.csv");
    {
        let f =
            std::fs::File::create(&csv).with_context(|| format!("creating {}", csv.display()))?;
        let mut w = std::io::BufWriter::new(f);
        session
            .record
            .write_csv(&telemetry, &mut w)
            .with_context(|| format!("writing {}", csv.display()))?;
        w.flush()
            .with_context(|| format!("writing {}", csv.display()))?;
    }
    // A replay's plot shows the recorded exposures next to the commands
    // the chosen strategy would have sent.
    let replay = matches!(spec, SourceSpec::Replay(_));
    let height = if replay { 1800 } else { 1500 };
    crate::report::plot::write_with(&telemetry, &out.join("exposure.png"), 1400, height, replay)?;
    let of = if frames == u64::MAX {
        "all".to_owned()
    } else {
        frames.to_string()
    };
    let mut summary = format!(
        "rigview run: {} on {}; {} of {of} sets processed; {written} views in {}, telemetry {}, plot {}\n{}",
        settings.strategy.label(),
        session.source_name,
        telemetry.total(),
        out.join("views").display(),
        csv.display(),
        out.join("exposure.png").display(),
        report::summary(&status, &telemetry)
    );
    if let Some(o) = &last {
        for line in crate::report::panorama::live_lines(telemetry.camera_names(), o) {
            summary += &format!("\n{line}");
        }
    }
    if let Some(c) = cpu.cores() {
        summary += &format!("\nCPU use: {c:.2} cores");
    }
    summary += &format!("\nkernels: {}", rigview_core::cpu::Isa::describe());
    if let Some(s) = &session.serving {
        let (server, published) = s.stats();
        summary += &format!(
            "\n{}; {} sets published, {} messages sent",
            s.status_line(),
            published.published,
            server.sent
        );
    }
    if let Some(r) = recorded {
        summary += &format!("\n{r}");
    }
    summary += &report::messages(&log.since(first));
    std::fs::write(out.join("summary.txt"), &summary)
        .with_context(|| format!("writing {}", out.join("summary.txt").display()))?;
    Ok(summary)
}
