//! UI tests of the desktop app with egui_kittest, on the simulated rig (at
//! quarter resolution, in lock step), rendered through wgpu on Mesa's
//! software rasteriser: no display needed.
//!
//! Also record and replay in the window: the Record button writes a
//! recording that reads back whole, and a recording opened in the window
//! pauses, steps and seeks.
//!
//! Snapshots live in `app/tests/snapshots/`; `UPDATE_SNAPSHOTS=1 cargo test
//! -p rigview --test gui` rewrites them after a deliberate change.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

use egui_kittest::kittest::{NodeT, Queryable};
use egui_kittest::{Harness, SnapshotOptions, SnapshotResults};
use rigview::commands::run::{self as headless, HeadlessRun};
use rigview::gui::{panels, plots, AppOptions, RigviewApp};
use rigview::logging::{self, LogBuffer};
use rigview::session::RecordSpec;
use rigview::session::{self, SimSpec, SourceSpec};
use rigview_core::exposure::{LawKind, NeighbourGraph, ToneCurve};
use rigview_core::pipeline::{
    Output, PipelineOptions, ProcessingSettings, Processor, StageTimes, Strategy, Telemetry,
    TelemetryRow,
};
use rigview_core::sim::{SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::FrameSource;
use rigview_record::IndexedRecording;

fn sim(frames: Option<u64>) -> SourceSpec {
    SourceSpec::Sim(SimSpec {
        scenario: "reference".into(),
        scale: 0.25,
        realtime: false,
        frames,
    })
}

/// The app on the quarter-resolution simulated rig; its Messages panel
/// shows the events of this thread (the window's own, the session's).
fn app(dir: &Path, frames: Option<u64>, log: &LogBuffer) -> RigviewApp {
    app_recording(dir, frames, log, None)
}

/// [`app`], recording from the start into `record` (`--record`).
fn app_recording(
    dir: &Path,
    frames: Option<u64>,
    log: &LogBuffer,
    record: Option<RecordSpec>,
) -> RigviewApp {
    app_on(dir, sim(frames), log, record)
}

/// The app on `source`, in lock step.
fn app_on(
    dir: &Path,
    source: SourceSpec,
    log: &LogBuffer,
    record: Option<RecordSpec>,
) -> RigviewApp {
    let ctx = egui::Context::default();
    RigviewApp::new(
        &ctx,
        AppOptions {
            source,
            settings: Some(dir.join("settings.yaml")),
            quit_after: None,
            screenshot: None,
            window_size: None,
            serve: None,
            pipeline: PipelineOptions {
                lockstep: true,
                ..Default::default()
            },
            log: log.clone(),
            record,
        },
    )
}

fn harness(app: RigviewApp) -> Harness<'static, RigviewApp> {
    Harness::builder()
        .with_size([1600.0, 1000.0])
        .build_ui_state(|ui, app: &mut RigviewApp| app.show(ui), app)
}

/// Steps the window until `done` holds (or panics after `secs`).
fn step_until(
    h: &mut Harness<'_, RigviewApp>,
    secs: f64,
    what: &str,
    done: impl Fn(&RigviewApp) -> bool,
) {
    let t = std::time::Instant::now();
    while !done(h.state()) {
        assert!(
            t.elapsed().as_secs_f64() < secs,
            "{what}: not within {secs} s; messages: {:?}",
            h.state().messages()
        );
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

#[test]
fn the_main_view_cameras_and_plots_show_data() {
    let dir = tempfile::tempdir().unwrap();
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let mut h = harness(app(dir.path(), None, &log));
    step_until(&mut h, 120.0, "ten frame sets shown", |a| a.shown() >= 10);
    h.step();
    let app = h.state();
    let out = app.latest().unwrap();
    // The big view: a composed canvas that is not black.
    let canvas = out.canvas.as_ref().expect("no surround canvas");
    let mean = canvas.data.iter().map(|&v| f64::from(v)).sum::<f64>() / canvas.data.len() as f64;
    assert!(mean > 10.0, "the surround view is black (mean {mean:.1})");
    // Every camera has a thumbnail, a histogram with pixels and an estimate.
    assert_eq!(out.cameras.len(), 4);
    for c in &out.cameras {
        assert!(c.histogram.iter().sum::<u32>() > 1000);
        assert!(c.estimate.is_some());
    }
    // The plots have points for every camera and overlap.
    {
        let t = app.session().unwrap().pipeline.telemetry();
        for s in plots::camera_series(&t, 60.0, |r, k| r.cameras.get(k).map(|c| c.exposure)) {
            assert!(s.1.len() >= 5, "{}: {} points", s.0, s.1.len());
        }
        let pairs = plots::pair_series(&t, 60.0);
        assert_eq!(pairs.len(), 4);
        assert!(
            pairs.iter().all(|p| !p.1.is_empty()),
            "an overlap has no ratio"
        );
    }
    // What the window shows.
    for label in [
        "exposure time (µs)",
        "gain (dB)",
        "γ estimate (γ-equivalent)",
        "gradient information M",
        "log2 r_ij per overlap",
        "frame-set rate (sets/s)",
        "end-to-end latency (ms)",
        "time per stage (ms)",
        "Exposure control",
        "Per-camera override",
    ] {
        assert!(
            h.query_by_label(label).is_some(),
            "no \"{label}\" in the window"
        );
    }
    // Scale-and-clip by default: the curve is M over the exposure scale.
    assert!(h.query_by_label_contains("M(s) of front").is_some());
    assert_eq!(
        h.query_all_by_label_contains(" · gain ").count(),
        4,
        "a camera readout is missing"
    );
    assert_eq!(
        h.query_all_by_label("streaming").count(),
        4,
        "no stream health"
    );
    assert!(
        h.query_by_label_contains("source: simulated rig").is_some(),
        "no source in the status bar"
    );
    // The session's start-up note, an event, is in the Messages panel.
    assert!(
        h.query_by_label_contains("scene traced in").is_some(),
        "no start-up note in the Messages panel: {:?}",
        h.state().messages()
    );
}

#[test]
fn switching_the_strategy_and_parameters_changes_the_controller() {
    let dir = tempfile::tempdir().unwrap();
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let mut h = harness(app(dir.path(), None, &log));
    step_until(&mut h, 120.0, "first set", |a| a.shown() >= 2);
    // Fixed manual: every camera goes to the manual level.
    h.get_by_label("fixed manual").click();
    step_until(&mut h, 60.0, "strategy reaches processing", |a| {
        a.latest()
            .is_some_and(|o| o.settings.strategy == Strategy::Manual)
    });
    let level = h.state().settings().processing.controller.fixed_exposure;
    step_until(&mut h, 60.0, "cameras at the manual level", |a| {
        a.latest().is_some_and(|o| {
            o.cameras
                .iter()
                .all(|c| (c.taken.exposure() / level - 1.0).abs() < 0.01)
        })
    });
    // The update law, through its combo box.
    h.get_by_label("gradient AE (single)").click();
    h.step();
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "Update law")
        .click();
    for _ in 0..3 {
        h.step();
    }
    h.get_by_label("fast (rigview)").click();
    step_until(&mut h, 60.0, "law reaches processing", |a| {
        a.latest().is_some_and(|o| {
            o.settings.strategy == Strategy::Single
                && o.settings.controller.law.kind == LawKind::Fast
        })
    });
    // Probing darker is on by default; its check box turns it off.
    assert!(h.state().settings().processing.controller.probe.is_some());
    h.get_by_label("probe darker or brighter").click();
    step_until(&mut h, 60.0, "probe setting reaches processing", |a| {
        a.latest()
            .is_some_and(|o| o.settings.controller.probe.is_none())
    });
    // Scale-and-clip through a tone curve: its check box gives a gamma of
    // 2.2, which reaches every camera's estimator.
    assert_eq!(
        h.state()
            .settings()
            .processing
            .controller
            .estimator
            .tone_curve,
        None
    );
    h.get_by_label("frames through a tone curve").click();
    step_until(&mut h, 60.0, "tone curve reaches processing", |a| {
        a.latest().is_some_and(|o| {
            o.settings.controller.estimator.tone_curve == Some(ToneCurve::Power(2.2))
        })
    });
    assert!(h.query_by_label("display gamma").is_some());
    // The gradient controller moves the cameras off the manual level.
    step_until(&mut h, 60.0, "gradient control moves a camera", |a| {
        a.latest().is_some_and(|o| {
            o.cameras
                .iter()
                .any(|c| (c.taken.exposure() / level - 1.0).abs() > 0.05)
        })
    });
    // The change persists.
    let saved = h.state_mut().finish();
    assert!(saved.contains("processed"), "{saved}");
    let again = app(dir.path(), Some(1), &log);
    assert_eq!(again.settings().processing.strategy, Strategy::Single);
    assert_eq!(
        again.settings().processing.controller.law.kind,
        LawKind::Fast
    );
    assert_eq!(again.settings().processing.controller.probe, None);
    assert_eq!(
        again.settings().processing.controller.estimator.tone_curve,
        Some(ToneCurve::Power(2.2))
    );
}

#[test]
fn a_bad_calibration_file_shows_an_error_and_the_app_keeps_running() {
    let dir = tempfile::tempdir().unwrap();
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let mut h = harness(app(dir.path(), None, &log));
    step_until(&mut h, 120.0, "first set", |a| a.shown() >= 2);
    // A rig file with a broken field: the reference rig with a word for a
    // focal length.
    let reference = Path::new(env!("CARGO_MANIFEST_DIR")).join("../assets/reference.rig.yaml");
    let text = std::fs::read_to_string(&reference).unwrap();
    let bad = dir.path().join("broken.rig.yaml");
    std::fs::write(&bad, text.replacen("  - 380.0", "  - wide", 1)).unwrap();
    h.state_mut().open_calibration(&bad);
    step_until(&mut h, 30.0, "the error", |a| {
        !a.is_loading() && a.messages().iter().any(|m| m.error)
    });
    let err = h
        .state()
        .messages()
        .iter()
        .rfind(|m| m.error)
        .unwrap()
        .text
        .clone();
    assert!(err.contains("broken.rig.yaml"), "{err}");
    assert!(
        err.contains("focal_px"),
        "the error does not name the field: {err}"
    );
    h.step();
    assert!(
        h.query_by_label_contains("broken.rig.yaml").is_some(),
        "the error is not in the window"
    );
    // The reference rig is for 1288×964 images, the running cameras give
    // 322×241: refused, naming both.
    h.state_mut().open_calibration(&reference);
    step_until(&mut h, 60.0, "the size error", |a| {
        !a.is_loading()
            && a.messages()
                .iter()
                .any(|m| m.error && m.text.contains("1288"))
    });
    // The app goes on showing new sets.
    let before = h.state().shown();
    step_until(&mut h, 60.0, "more sets after the errors", |a| {
        a.shown() >= before + 3
    });
    assert_eq!(
        h.state().calibration(),
        "the simulated rig's exact calibration"
    );
    // A good calibration (the running rig's own, written as a rig file)
    // takes effect without a restart.
    let good = dir.path().join("quarter.rig.yaml");
    let render = SimRender::new(&SimConfig {
        scale: 0.25,
        ..SimConfig::default()
    })
    .unwrap();
    std::fs::write(
        &good,
        rigview_calib::formats::rig_yaml::to_string(render.rig()).unwrap(),
    )
    .unwrap();
    h.state_mut().open_calibration(&good);
    step_until(&mut h, 60.0, "the new calibration", |a| {
        !a.is_loading() && a.calibration().ends_with("quarter.rig.yaml")
    });
    let before = h.state().shown();
    step_until(&mut h, 60.0, "sets with the new calibration", |a| {
        a.shown() >= before + 3
    });
    assert!(h.state().latest().unwrap().canvas.is_some());
}

/// Ten sets through a processor on one thread: repeatable to the bit.
fn deterministic_run() -> (Vec<String>, Vec<Arc<Output>>, Telemetry) {
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::default()
    };
    let render = Arc::new(SimRender::new(&config).unwrap());
    let cams = render.cameras().to_vec();
    let (view, graph): (_, NeighbourGraph) =
        session::view_for(render.rig(), &cams, &ProcessingSettings::default()).unwrap();
    let mut p = Processor::new(
        cams.clone(),
        Some(view),
        graph,
        ProcessingSettings::default(),
    )
    .unwrap();
    let mut rig = SimRig::new(render, SimRigOptions::default()).unwrap();
    let names: Vec<String> = cams.iter().map(|c| c.name.clone()).collect();
    let mut t = Telemetry::new(names.clone(), &p.pairs(), 100);
    let mut outs = Vec::new();
    for k in 0..10 {
        let set = rig.next_set(Duration::from_secs(1)).unwrap().unwrap();
        let (out, commands) = p
            .process(&set, std::time::Instant::now(), StageTimes::default())
            .unwrap();
        rig.apply(&commands).unwrap();
        t.push(TelemetryRow::of(&out, f64::from(k) * 0.05, 20.0, 0));
        outs.push(Arc::new(out));
    }
    (names, outs, t)
}

#[test]
fn snapshots_of_the_cameras_and_plots() {
    let (names, outs, telemetry) = deterministic_run();
    let last = outs.last().unwrap().clone();
    let opts = SnapshotOptions::new();
    let mut results = SnapshotResults::new();

    let cams = last.clone();
    let mut textures: Vec<egui::TextureHandle> = Vec::new();
    let mut h = Harness::builder()
        .with_size([1300.0, 360.0])
        .build_ui(move |ui| {
            if textures.is_empty() {
                textures = cams
                    .cameras
                    .iter()
                    .enumerate()
                    .map(|(k, c)| {
                        ui.ctx().load_texture(
                            format!("t{k}"),
                            panels::thumbnail_image(c, true),
                            egui::TextureOptions::LINEAR,
                        )
                    })
                    .collect();
            }
            ui.horizontal_top(|ui| {
                for (k, c) in cams.cameras.iter().enumerate() {
                    panels::camera_card(
                        ui,
                        &names[k],
                        k,
                        c,
                        Some(&textures[k]),
                        Some(&cams.overlay),
                        true,
                        310.0,
                    );
                }
            });
        });
    h.run();
    h.snapshot_options("cameras", &opts);
    results.extend_harness(&mut h);

    let mut h = Harness::builder()
        .with_size([450.0, 760.0])
        .build_ui(move |ui| {
            plots::exposure_plots(ui, &telemetry, 60.0);
        });
    h.run();
    h.snapshot_options("exposure_plots", &opts);
    results.extend_harness(&mut h);

    let mut h = Harness::builder()
        .with_size([450.0, 200.0])
        .build_ui(move |ui| {
            plots::curve_plot(ui, Some(&last), 0, "front");
        });
    h.run();
    h.snapshot_options("curve", &opts);
    results.extend_harness(&mut h);
    results.unwrap();
}

/// The trigger numbers of a recording's sets, in order, read by its index.
fn recorded_triggers(file: &Path) -> Vec<u64> {
    let mut r = IndexedRecording::open(file).unwrap();
    (0..r.len())
        .map(|k| r.set(k).unwrap().unwrap().set.trigger)
        .collect()
}

/// Whether the window shows set `trigger`: the newest output is that set,
/// and the big view's caption names it.
fn shows(h: &Harness<'_, RigviewApp>, trigger: u64) -> bool {
    h.state().latest().is_some_and(|o| o.trigger == trigger)
        && h.query_by_label_contains(&format!("set {trigger} · "))
            .is_some()
}

/// Steps the window until it shows `trigger` (or panics after `secs`).
fn step_until_shown(h: &mut Harness<'_, RigviewApp>, secs: f64, what: &str, trigger: u64) {
    let t = std::time::Instant::now();
    while !shows(h, trigger) {
        assert!(
            t.elapsed().as_secs_f64() < secs,
            "{what}: set {trigger} not shown within {secs} s (shown: {:?}, replay at {:?}); messages: {:?}",
            h.state().latest().map(|o| o.trigger),
            h.state().replay().and_then(|r| r.shown()),
            h.state().messages()
        );
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// After a pause: lets a set the replay was already waiting for arrive
/// (its wait is cut at 20 ms), then returns the number of the set the
/// replay stopped at.
fn settle(h: &mut Harness<'_, RigviewApp>) -> usize {
    for _ in 0..10 {
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    h.state().replay().and_then(|r| r.shown()).unwrap()
}

#[test]
fn the_record_button_writes_a_recording_of_the_sets_that_follow() {
    const SETS: u64 = 40;
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("button.mcap");
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let mut h = harness(app(dir.path(), Some(SETS), &log));
    step_until(&mut h, 120.0, "first sets", |a| a.shown() >= 2);
    assert!(h.state().recorder().is_none());
    h.state_mut().set_record_path(&file);
    h.step();
    h.get_by_label("Record").click();
    step_until(&mut h, 30.0, "the recording starts", |a| {
        a.recorder().is_some()
    });
    let recorder = h.state().recorder().unwrap().clone();
    h.step();
    assert!(
        h.query_by_label_contains("REC 00:").is_some(),
        "no recording line under the Record button"
    );
    // The source ends after SETS sets; every set processed from the press
    // on is offered to the recorder.
    step_until(&mut h, 120.0, "the source ends", |a| {
        a.session().unwrap().pipeline.is_stopped()
    });
    h.get_by_label("Stop recording").click();
    step_until(&mut h, 30.0, "the recording closed", |a| {
        a.recorder().is_none() && !a.is_finishing_recording()
    });
    let stats = recorder.stats();
    assert!(stats.finished, "{stats:?}");
    assert_eq!(stats.stopped, None);
    let summary = h
        .state()
        .messages()
        .iter()
        .rfind(|m| m.text.contains("button.mcap:"))
        .unwrap()
        .text
        .clone();
    assert!(
        summary.contains(&format!("{} sets", stats.sets)),
        "{summary}"
    );
    // The file reads back by its index, with every set the recorder wrote:
    // consecutive triggers up to the source's last.
    let triggers = recorded_triggers(&file);
    assert_eq!(triggers.len() as u64, stats.sets);
    assert!(stats.sets >= 5, "{stats:?}");
    let first = triggers[0];
    assert!(first >= 1, "sets before the press were recorded: {first}");
    assert_eq!(stats.sets + stats.dropped, SETS - first, "{stats:?}");
    if stats.dropped == 0 {
        assert_eq!(triggers, (first..SETS).collect::<Vec<_>>());
    }
}

#[test]
fn record_at_start_up_records_every_set() {
    const SETS: u64 = 12;
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("start.mcap");
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let app = app_recording(
        dir.path(),
        Some(SETS),
        &log,
        Some(RecordSpec::new(file.clone())),
    );
    let mut h = harness(app);
    assert!(h.state().recorder().is_some(), "{:?}", h.state().messages());
    h.step();
    // The Record button's file is the one recorded into, and it says so.
    assert!(h.query_by_label_contains("recording into").is_some());
    assert!(h.query_by_label("Stop recording").is_some());
    step_until(&mut h, 120.0, "the source ends", |a| {
        a.session().unwrap().pipeline.is_stopped()
    });
    let summary = h.state_mut().finish();
    assert!(
        summary.contains(&format!("start.mcap: {SETS} sets")),
        "{summary}"
    );
    assert_eq!(recorded_triggers(&file), (0..SETS).collect::<Vec<_>>());
    // A file that exists is never written over: the view goes on without
    // the recording, and the operator is told why.
    let again = app_recording(
        dir.path(),
        Some(3),
        &log,
        Some(RecordSpec::new(file.clone())),
    );
    assert!(again.recorder().is_none());
    assert!(again.session().is_some());
    assert!(
        again
            .messages()
            .iter()
            .any(|m| m.error && m.text.contains("start.mcap")),
        "{:?}",
        again.messages()
    );
}

#[test]
fn a_recording_opened_in_the_window_pauses_steps_and_seeks() {
    const SETS: u64 = 40;
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("drive.mcap");
    let run = HeadlessRun {
        source: SourceSpec::Sim(SimSpec {
            scenario: "steps".into(),
            scale: 0.25,
            realtime: false,
            frames: Some(SETS),
        }),
        frames: SETS,
        out: dir.path().join("live"),
        every: 1000,
        record: Some(RecordSpec::new(file.clone())),
        serve: None,
    };
    headless::run(
        &run,
        &ProcessingSettings::default(),
        &LogBuffer::default(),
        false,
    )
    .unwrap();
    let triggers = recorded_triggers(&file);
    assert_eq!(triggers.len() as u64, SETS);
    let times = IndexedRecording::open(&file).unwrap().times().to_vec();

    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let mut h = harness(app(dir.path(), None, &log));
    step_until(&mut h, 120.0, "first set", |a| a.shown() >= 1);
    // A file that is not a recording is refused; the source goes on.
    let not_mcap = dir.path().join("settings.yaml");
    h.state_mut().open_recording(&not_mcap);
    assert!(h.state().replay().is_none());
    assert!(
        h.state()
            .messages()
            .iter()
            .any(|m| m.error && m.text.contains("settings.yaml")),
        "{:?}",
        h.state().messages()
    );
    h.state_mut().open_recording(&file);
    let control = h.state().replay().expect("not replaying").clone();
    assert_eq!(
        h.state().calibration(),
        format!("{} (attachment rig.yaml)", file.display())
    );
    assert!(
        control.times().is_some(),
        "a closed recording has its index"
    );
    // At a quarter of the recorded rate (5 sets/s), then paused.
    h.step();
    h.get_by_role_and_label(egui::accesskit::Role::ComboBox, "Speed")
        .click();
    for _ in 0..3 {
        h.step();
    }
    h.get_by_label("0.25×").click();
    h.step();
    assert_eq!(control.speed(), Some(0.25));
    step_until(&mut h, 60.0, "a replayed set", |a| {
        a.latest().is_some_and(|o| triggers.contains(&o.trigger))
    });
    h.get_by_label("Pause").click();
    h.step();
    assert!(control.is_paused());
    h.step();
    assert!(h.query_by_label("Play").is_some());
    let k = settle(&mut h);
    step_until_shown(&mut h, 30.0, "the set paused at", triggers[k]);
    // Paused: the set stays.
    for _ in 0..20 {
        h.step();
        std::thread::sleep(Duration::from_millis(10));
    }
    assert_eq!(control.shown(), Some(k));
    assert!(shows(&h, triggers[k]));
    // The slider seeks by time to set 20; then steps.
    h.get_by_role_and_label(egui::accesskit::Role::Slider, "time (s)")
        .set_value_accesskit((times[20] - times[0]) as f64 * 1e-9);
    step_until_shown(&mut h, 30.0, "seek to set 20", triggers[20]);
    assert!(h.query_by_label("21 / 40 sets").is_some());
    h.get_by_label("Step forward").click();
    step_until_shown(&mut h, 30.0, "one step forward", triggers[21]);
    h.get_by_label("Step back").click();
    h.step();
    h.get_by_label("Step back").click();
    step_until_shown(&mut h, 30.0, "two steps back", triggers[19]);
    assert_eq!(control.shown(), Some(19));
    // A time between two sets seeks to the nearer one.
    control.seek(control.set_at(times[32] - 1).unwrap());
    step_until_shown(&mut h, 30.0, "seek to set 32", triggers[32]);
    // Played to the end: held there, paused, with the last set shown.
    control.set_speed(None);
    h.get_by_label("Play").click();
    step_until_shown(&mut h, 60.0, "the last set", triggers[39]);
    step_until(&mut h, 30.0, "held at the end", |_| {
        control.at_end() && control.is_paused()
    });
    assert!(h
        .state()
        .session()
        .is_some_and(|s| !s.pipeline.is_stopped()));
    h.step();
    assert!(h.query_by_label("end of the recording").is_some());
    // The open-loop commands are plotted beside the recorded exposure.
    assert!(h
        .query_by_label("log2 E the strategy would command (not applied)")
        .is_some());

    // A file cut before its summary (killed while recording) has no
    // index: it plays and steps forward, and says to repair it to seek.
    let bytes = std::fs::read(&file).unwrap();
    let cut = dir.path().join("cut.mcap");
    std::fs::write(&cut, &bytes[..bytes.len() * 97 / 100]).unwrap();
    h.state_mut().open_recording(&cut);
    let control = h.state().replay().expect("not replaying").clone();
    assert!(control.times().is_none());
    control.set_speed(Some(0.25));
    step_until(&mut h, 30.0, "a set of the cut file shown", |a| {
        a.latest().is_some()
    });
    h.get_by_label("Pause").click();
    h.step();
    h.step();
    assert!(h
        .query_by_label_contains("recording repair IN OUT")
        .is_some());
    assert!(h.get_by_label("Step back").accesskit_node().is_disabled());
    let k = settle(&mut h);
    step_until_shown(&mut h, 30.0, "the set paused at", triggers[k]);
    h.get_by_label("Step forward").click();
    step_until_shown(
        &mut h,
        30.0,
        "a step forward without the index",
        triggers[k + 1],
    );
}

#[test]
fn a_recording_that_stops_on_its_own_is_told_and_the_view_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("full.mcap");
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let mut h = harness(app(dir.path(), None, &log));
    step_until(&mut h, 120.0, "first sets", |a| a.shown() >= 2);
    // A reserve no disk has: the recorder stops at its first check.
    let spec = RecordSpec {
        reserve_bytes: u64::MAX,
        ..RecordSpec::new(file.clone())
    };
    h.state_mut().start_recording(&spec);
    step_until(&mut h, 60.0, "the stop told", |a| {
        a.messages()
            .iter()
            .any(|m| m.error && m.text.contains("full.mcap") && m.text.contains("reserve"))
    });
    h.step();
    // Under the Record button and in the status bar.
    assert_eq!(
        h.query_all_by_label_contains("STOPPED: stopped:").count(),
        2,
        "the stop is not in the window"
    );
    let before = h.state().shown();
    step_until(&mut h, 60.0, "more sets after the stop", |a| {
        a.shown() >= before + 3
    });
    // The file is still a recording: its start, readable, with no set.
    h.get_by_label("Stop recording").click();
    step_until(&mut h, 30.0, "the recording closed", |a| {
        !a.is_finishing_recording() && a.recorder().is_none()
    });
    assert!(recorded_triggers(&file).is_empty());
}

#[test]
fn view_panorama_shows_a_composed_panorama_with_match_counts() {
    let dir = tempfile::tempdir().unwrap();
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    // The half-resolution rig: enough detail in the overlaps for matches.
    let source = SourceSpec::Sim(SimSpec {
        scenario: "reference".into(),
        scale: 0.5,
        realtime: false,
        frames: None,
    });
    let app = app_on(dir.path(), source, &log, None);
    let mut h = harness(app);
    step_until(&mut h, 120.0, "first sets", |a| a.shown() >= 2);
    assert!(h.state().latest().unwrap().panorama.is_none());
    // View → Panorama.
    h.get_by_label("View").click();
    for _ in 0..3 {
        h.step();
    }
    h.get_by_label("Panorama (cylindrical)").click();
    // The window keeps showing sets while the panorama is built.
    let before = h.state().shown();
    step_until(&mut h, 120.0, "a matched panorama", |a| {
        a.latest()
            .and_then(|o| o.panorama.as_ref())
            .is_some_and(|r| r.matched_trigger.is_some())
    });
    assert!(h.state().shown() > before, "the window froze");
    h.step();
    let out = h.state().latest().unwrap().clone();
    // A composed panorama: the cylinder's canvas, not black.
    let canvas = out.canvas.as_ref().expect("no panorama canvas");
    assert_eq!((canvas.width, canvas.height), (2048, 270));
    let mean = canvas.data.iter().map(|&v| f64::from(v)).sum::<f64>() / canvas.data.len() as f64;
    assert!(mean > 10.0, "the panorama is black (mean {mean:.1})");
    let report = out.panorama.as_ref().unwrap();
    assert_eq!(report.pairs.len(), 4);
    assert!(
        report.pairs.iter().any(|p| p.inliers > 0),
        "no pair has inliers: {:?}",
        report.pairs
    );
    // The window shows each pair's matches and the Refine and Save rig
    // actions.
    assert_eq!(
        h.query_all_by_label_contains(" matches, ").count(),
        4,
        "the pairs' match counts are not shown"
    );
    assert!(h.query_by_label_contains("front–left: ").is_some());
    assert!(h.query_by_label("Refine").is_some());
    assert!(h.query_by_label("Save rig…").is_some());
    // Refine: the rotations are refined in the background and the
    // panorama rebuilt; the refined rig saves as a rig file.
    h.get_by_label("Refine").click();
    step_until(&mut h, 120.0, "a refinement", |a| {
        a.latest()
            .and_then(|o| o.panorama.as_ref())
            .is_some_and(|r| r.refinements >= 1)
    });
    let saved = dir.path().join("refined.rig.yaml");
    h.state_mut().save_rig(&saved);
    let rig = rigview_calib::formats::load(&saved, None, None)
        .unwrap()
        .rig;
    assert_eq!(rig.cameras.len(), 4);
    h.step();
    assert!(h.query_all_by_label_contains("(refined: ").count() >= 1);
    // The choice persists.
    h.state_mut().finish();
    let again = app_recording(dir.path(), Some(1), &log, None);
    assert_eq!(
        again.settings().window.view,
        rigview::settings::ViewMode::Panorama
    );
}

#[test]
fn view_bowl_shows_the_bowl_and_the_operator_moves_the_viewpoint() {
    use rigview_core::bowl::Viewpoint;
    use rigview_core::pipeline::ViewKind;
    let dir = tempfile::tempdir().unwrap();
    let log = LogBuffer::new();
    let _events = logging::capture(&log);
    let app = app(dir.path(), None, &log);
    let mut h = harness(app);
    step_until(&mut h, 120.0, "first sets", |a| a.shown() >= 2);
    // View → Bowl.
    h.get_by_label("View").click();
    for _ in 0..3 {
        h.step();
    }
    h.get_by_label("Bowl (3-D, around the vehicle)").click();
    let before = h.state().shown();
    step_until(&mut h, 120.0, "the bowl", |a| {
        a.latest().is_some_and(|o| o.view == Some(ViewKind::Bowl))
    });
    assert!(h.state().shown() > before, "the window froze");
    let out = h.state().latest().unwrap().clone();
    let canvas = out.canvas.as_ref().expect("no bowl picture");
    assert_eq!((canvas.width, canvas.height), (1280, 800));
    let mean = canvas.data.iter().map(|&v| f64::from(v)).sum::<f64>() / canvas.data.len() as f64;
    assert!(mean > 20.0, "the bowl is black (mean {mean:.1})");
    // A preset: the viewpoint moves there smoothly (through viewpoints in
    // between) and the picture follows.
    let top = Viewpoint::preset("top").unwrap();
    h.get_by_label("top").click();
    let mut seen = Vec::new();
    step_until(&mut h, 120.0, "the top view", |a| {
        a.latest()
            .and_then(|o| o.bowl)
            .is_some_and(|(v, building)| v == top && !building)
    });
    for _ in 0..3 {
        h.step();
        seen.push(h.state().settings().processing.bowl.viewpoint);
    }
    assert!(seen.iter().all(|v| *v == top), "{seen:?}");
    // A drag up and to the right orbits: the azimuth turns, the eye
    // comes down from the top.
    // The middle of the central panel, on the picture.
    let canvas_at = egui::pos2(700.0, 350.0);
    h.drag_at(canvas_at);
    for k in 1..=5 {
        h.hover_at(canvas_at + egui::vec2(10.0 * k as f32, -20.0 * k as f32));
        h.step();
    }
    h.drop_at(canvas_at + egui::vec2(50.0, -100.0));
    h.step();
    let orbited = h.state().settings().processing.bowl.viewpoint;
    assert!(orbited.pitch_deg < 80.0, "{orbited:?}");
    assert!(
        (orbited.distance_m - top.distance_m).abs() < 1e-9,
        "{orbited:?}"
    );
    assert!((orbited.yaw_deg - top.yaw_deg).abs() > 5.0, "{orbited:?}");
    // Reversing: the rear view while it lasts, then back.
    h.get_by_label("Reversing (R)").click();
    let rear = Viewpoint::preset("rear").unwrap();
    step_until(&mut h, 20.0, "the rear view", |a| {
        a.settings().processing.bowl.viewpoint == rear
    });
    h.get_by_label("Reversing (R)").click();
    step_until(&mut h, 20.0, "the viewpoint from before", |a| {
        a.settings().processing.bowl.viewpoint == orbited
    });
    // The bird's-eye view beside the bowl.
    assert!(h.state().latest().unwrap().beside.is_none());
    h.get_by_label("Bird's-eye view beside").click();
    step_until(&mut h, 60.0, "the bird's-eye view beside", |a| {
        a.latest().is_some_and(|o| o.beside.is_some())
    });
    let out = h.state().latest().unwrap().clone();
    let beside = out.beside.as_ref().unwrap();
    assert_eq!((beside.width, beside.height), (1000, 1000));
    // The view and the viewpoint persist.
    h.state_mut().finish();
    let again = app_recording(dir.path(), Some(1), &log, None);
    assert_eq!(
        again.settings().window.view,
        rigview::settings::ViewMode::Bowl
    );
    assert_eq!(again.settings().processing.bowl.viewpoint, orbited);
    assert!(again.settings().processing.bowl.beside);
}

/// The bowl of the simulated rig (quarter resolution, ten sets in lock
/// step) from three presets, as golden images.
#[test]
fn snapshots_of_the_bowl_from_three_viewpoints() {
    use rigview_core::bowl::Viewpoint;
    use rigview_core::pipeline::ViewKind;
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::default()
    };
    let render = Arc::new(SimRender::new(&config).unwrap());
    let cams = render.cameras().to_vec();
    let mut results = SnapshotResults::new();
    for name in ["top", "behind-left", "left"] {
        let mut settings = ProcessingSettings {
            view: ViewKind::Bowl,
            ..ProcessingSettings::default()
        };
        settings.bowl.spec.size_px = [640, 400];
        settings.bowl.viewpoint = Viewpoint::preset(name).unwrap();
        let (view, graph) = session::view_for(render.rig(), &cams, &settings).unwrap();
        let mut p = Processor::new(cams.clone(), Some(view), graph, settings).unwrap();
        let mut rig = SimRig::new(render.clone(), SimRigOptions::default()).unwrap();
        let mut last = None;
        for _ in 0..10 {
            let set = rig.next_set(Duration::from_secs(1)).unwrap().unwrap();
            let (out, commands) = p
                .process(&set, std::time::Instant::now(), StageTimes::default())
                .unwrap();
            rig.apply(&commands).unwrap();
            last = Some(out);
        }
        let canvas = last.unwrap().canvas.unwrap();
        assert_eq!((canvas.width, canvas.height), (640, 400));
        let image = if canvas.channels == 3 {
            egui::ColorImage::from_rgb([canvas.width, canvas.height], &canvas.data)
        } else {
            egui::ColorImage::from_gray([canvas.width, canvas.height], &canvas.data)
        };
        let mut texture: Option<egui::TextureHandle> = None;
        let mut h = Harness::builder()
            .with_size([640.0, 400.0])
            .build_ui(move |ui| {
                let t = texture.get_or_insert_with(|| {
                    ui.ctx()
                        .load_texture("bowl", image.clone(), egui::TextureOptions::LINEAR)
                });
                ui.add(egui::Image::new(egui::load::SizedTexture::new(
                    t.id(),
                    egui::vec2(640.0, 400.0),
                )));
            });
        h.run();
        h.snapshot_options(format!("bowl_{name}"), &SnapshotOptions::new());
        results.extend_harness(&mut h);
    }
    results.unwrap();
}
