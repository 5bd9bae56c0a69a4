//! The processing pipeline: the threads that take frame sets from a source,
//! control exposure and compose the view, for the app's window and its
//! headless mode.
//!
//! ```text
//!  capture thread            processing thread                        display (the app)
//!  source.next_set() ──► [DropOldest, 4] ──► meter ─► controller ─► compose ──► [DropOldest, 1] ──► texture
//!        ▲  (per-camera threads and                     │                 │
//!        │   frame-set sync live inside                 │ commands        └──► telemetry (history)
//!        └── the source: LiveSource, SimRig) ◄──────────┘
//! ```
//!
//! - The capture thread only waits on the source and pushes; a full queue
//!   drops its oldest set (counted), so capture never blocks. Exposure
//!   commands come back to it over a channel and are applied before the
//!   next set is asked for.
//! - The processing thread meters each camera (the surround view's ground
//!   only, or whole frames), steps the rig controller, composes the
//!   bird's-eye canvas and records telemetry with the time of every stage.
//! - The display takes the newest output when it paints
//!   ([`Pipeline::latest`]); a slow display skips outputs but never slows
//!   processing. It reports when it showed an output
//!   ([`Pipeline::displayed`]), which gives the end-to-end latency.
//! - Everything the operator changes (strategy, law, parameters, manual
//!   overrides, a new calibration) reaches the processing thread as a
//!   [`Control`] message and applies from the next set on.
//! - Offline sources may run in lock step ([`PipelineOptions::lockstep`]):
//!   capture then waits for room instead of dropping.
//!
//! | file | what |
//! | --- | --- |
//! | `settings.rs` | [`ProcessingSettings`], [`Strategy`], [`Control`] |
//! | `output.rs` | [`Output`]: what one set gives the display and telemetry |
//! | `processor.rs` | [`Processor`]: the per-set work, the one control loop |
//! | `lockstep.rs` | [`LockStep`]: a processor driven synchronously by its source |
//! | `threads.rs` | [`Pipeline`]: the capture and processing threads |
//! | `queue.rs` | [`DropOldest`]: the queues between the threads |
//! | `telemetry.rs` | [`Telemetry`]: the history the plots and CSV read |
//! | `view.rs` | [`View`]: the surround view or the live panorama, with its matching and refinement |

mod display;
mod lockstep;
mod output;
mod processor;
mod queue;
mod settings;
mod sink;
mod telemetry;
mod threads;
mod view;

pub use display::{
    DisplayGain, DisplayGains, DisplayInput, DisplaySettings, BRIGHT_QUANTILE, CLIP_LEVEL,
};
pub use lockstep::{LockStep, LoopStep};
pub use output::{CameraOutput, Output, Overlay, PairOutput, PatchBox};
pub use processor::{check_view, Processor};
pub use queue::{DropOldest, QueueStats};
pub use settings::{Control, MeterRoi, PanoramaSettings, ProcessingSettings, Strategy, ViewKind};
pub use sink::{Processed, SetSink};
pub use telemetry::{CameraRow, PairMatchRow, StageTimes, Telemetry, TelemetryRow, MATCH_COLUMNS};
pub use threads::{Notify, OutputWatch, Pipeline, PipelineOptions, PipelineStatus};
pub use view::{
    BowlSettings, LiveBowl, LivePanorama, PairMatchReport, PanoramaReport, SharedDetector, View,
};

#[cfg(test)]
mod tests {
    use std::sync::Arc;
    use std::time::Duration;

    use super::*;
    use crate::exposure::NeighbourGraph;
    use crate::sim::{SimConfig, SimRender, SimRig, SimRigOptions};
    use crate::source::FrameSource;
    use crate::surround::{CanvasSpec, SurroundOptions, SurroundView};

    fn small_rig(frames: impl Into<Option<u64>>) -> (SimRig, SurroundView, NeighbourGraph) {
        let mut config = SimConfig::preset("reference").unwrap_or_default();
        config.scale = 0.25;
        let render = Arc::new(SimRender::new(&config).unwrap_or_else(|e| panic!("{e}")));
        let spec = CanvasSpec {
            px_per_m: 20.0,
            ..CanvasSpec::default()
        };
        let view = SurroundView::build(render.rig(), &spec, &SurroundOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let graph = NeighbourGraph::new(render.cameras().len(), &render.rig().neighbours)
            .unwrap_or_else(|e| panic!("{e}"));
        let rig = SimRig::new(
            render,
            SimRigOptions {
                frames: frames.into(),
                ..Default::default()
            },
        )
        .unwrap_or_else(|e| panic!("{e}"));
        (rig, view, graph)
    }

    /// The processor under the default settings for `rig`.
    fn default_processor(rig: &SimRig, view: SurroundView, graph: NeighbourGraph) -> Processor {
        Processor::new(
            rig.cameras().to_vec(),
            Some(view.into()),
            graph,
            ProcessingSettings::default(),
        )
        .unwrap_or_else(|e| panic!("{e}"))
    }

    #[test]
    fn a_budget_ends_an_endless_source_after_its_sets() {
        use crate::source::Budget;
        let (rig, view, graph) = small_rig(None);
        let processor = default_processor(&rig, view, graph);
        let mut lp =
            LockStep::new(Budget::new(rig, 5), processor).unwrap_or_else(|e| panic!("{e}"));
        let mut triggers = Vec::new();
        while let Some(step) = lp.step().unwrap_or_else(|e| panic!("{e}")) {
            assert!(step.output.is_some(), "set {} incomplete", step.set.trigger);
            triggers.push(step.set.trigger);
        }
        assert_eq!(triggers, (0..5).collect::<Vec<_>>());
        assert!(lp.source().is_finished());
        assert_eq!(lp.processed(), 5);
        // A source that ends first ends the budget with it.
        let (rig, _, _) = small_rig(2);
        let mut short = Budget::new(rig, 5);
        let mut n = 0;
        while short
            .next_set(Duration::from_secs(5))
            .unwrap_or_else(|e| panic!("{e}"))
            .is_some()
        {
            n += 1;
        }
        assert_eq!(n, 2);
        assert!(short.is_finished());
    }

    #[test]
    fn in_lock_step_every_set_is_processed_and_composed() {
        let (rig, view, graph) = small_rig(12);
        let processor = default_processor(&rig, view, graph);
        let mut p = Pipeline::start(
            rig,
            processor,
            PipelineOptions {
                lockstep: true,
                output_queue: 64,
                ..Default::default()
            },
            Arc::new(|| {}),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let mut triggers = Vec::new();
        while let Some(out) = p.next_output(Duration::from_secs(30)) {
            assert!(out.canvas.is_some(), "set {} has no canvas", out.trigger);
            assert_eq!(out.cameras.len(), 4);
            assert_eq!(out.pairs.len(), 4);
            triggers.push(out.trigger);
        }
        p.stop();
        assert_eq!(triggers, (0..12).collect::<Vec<_>>());
        let s = p.status();
        assert_eq!(s.capture_queue.dropped, 0);
        assert_eq!(s.processed, 12);
        assert!(s.finished);
        assert_eq!(p.telemetry().total(), 12);
    }

    #[test]
    fn a_manual_override_reaches_the_camera() {
        let (rig, view, graph) = small_rig(20);
        let processor = default_processor(&rig, view, graph);
        let p = Pipeline::start(
            rig,
            processor,
            PipelineOptions {
                lockstep: true,
                output_queue: 64,
                ..Default::default()
            },
            Arc::new(|| {}),
        )
        .unwrap_or_else(|e| panic!("{e}"));
        p.send(Control::Manual {
            camera: 2,
            exposure: Some(777.0),
        })
        .unwrap_or_else(|e| panic!("{e}"));
        let mut last = None;
        while let Some(out) = p.next_output(Duration::from_secs(30)) {
            last = Some(out);
        }
        let last = last.unwrap_or_else(|| panic!("no output"));
        let e = last.cameras[2].taken.exposure();
        assert!((e / 777.0 - 1.0).abs() < 0.01, "camera 2 at {e}, not 777");
        assert_eq!(last.cameras[2].manual, Some(777.0));
    }

    /// The thumbnail's bytes: intensities times 255, rounded, clamped.
    #[test]
    fn thumbnail_bytes_round_and_clamp() {
        let cases = [
            (0.0, 0),
            (1.0, 255),
            (100.0 / 255.0, 100),
            (100.4 / 255.0, 100),
            (100.6 / 255.0, 101),
            (0.5, 128),
            (-1.0, 0),
            (2.0, 255),
            (f32::NAN, 0),
        ];
        for (v, want) in cases {
            assert_eq!(processor::thumb_byte(v), want, "{v}");
        }
        for k in 0..=255u8 {
            assert_eq!(processor::thumb_byte(f32::from(k) / 255.0), k);
        }
    }

    /// A processor whose pictures are let go takes their canvases again
    /// (the same buffers), and its pictures are those of a processor whose
    /// pictures are all held (new canvases every set): a reused canvas is
    /// written whole.
    #[test]
    fn released_canvases_are_reused_and_written_whole() {
        let run = |hold: bool| {
            let (rig, view, graph) = small_rig(8);
            let processor = default_processor(&rig, view, graph);
            let mut lp = LockStep::new(rig, processor).unwrap_or_else(|e| panic!("{e}"));
            let (mut pictures, mut buffers, mut held) = (Vec::new(), Vec::new(), Vec::new());
            while let Some(step) = lp.step().unwrap_or_else(|e| panic!("{e}")) {
                let out = step.output.unwrap_or_else(|| panic!("incomplete set"));
                let canvas = out.canvas.unwrap_or_else(|| panic!("no picture"));
                pictures.push(canvas.data.clone());
                buffers.push(canvas.data.as_ptr() as usize);
                if hold {
                    held.push(canvas);
                }
            }
            (pictures, buffers)
        };
        let (reused, reused_at) = run(false);
        let (fresh, fresh_at) = run(true);
        assert_eq!(reused.len(), 8);
        for (k, (a, b)) in reused.iter().zip(&fresh).enumerate() {
            assert!(a == b, "set {k}: the reused canvas differs");
        }
        // Held pictures each have a buffer of their own; released ones
        // come back.
        let distinct = |at: &[usize]| at.iter().collect::<std::collections::HashSet<_>>().len();
        assert_eq!(distinct(&fresh_at), 8);
        assert!(distinct(&reused_at) < 8, "{reused_at:?}");
        // The sets differ, so equal pictures are no accident of a still
        // scene.
        assert!(reused.windows(2).any(|w| w[0] != w[1]));
    }

    #[test]
    fn refinement_without_a_panorama_says_so() {
        let (rig, view, graph) = small_rig(1);
        let mut p = default_processor(&rig, view, graph);
        let e = p.refine().err().map(|e| e.to_string()).unwrap_or_default();
        assert!(e.contains("switch the view to the panorama"), "{e}");
    }

    #[test]
    fn a_view_of_another_rig_is_refused() {
        let (rig, view, graph) = small_rig(1);
        let mut cams = rig.cameras().to_vec();
        cams[1].width += 2;
        let e = Processor::new(
            cams,
            Some(view.into()),
            graph,
            ProcessingSettings::default(),
        );
        let msg = e
            .map(|_| ())
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(msg.contains("the calibration is for"), "{msg}");
    }
}
