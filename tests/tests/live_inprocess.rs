//! Live capture against four of Aravis's in-process fake cameras showing
//! the simulated rig (the `reference` preset: a sunny car park with a
//! building's shadow, constant light, at a quarter of the reference
//! resolution, 322×241): each fake camera's fill callback renders its
//! simulated camera at the exposure time and gain its registers hold, so
//! exposure commands sent through the real Aravis API change the pixels.
//!
//! Checked:
//! - every frame that reaches the controller is, byte for byte, the
//!   simulator's render of its camera at its frame id, its timestamp and the
//!   `taken` setting it arrived with, noise included (a frame is a pure
//!   function of those): the setting tracking is exact;
//! - the app's processor in lock step through Aravis settles where it
//!   settles on the same simulated rig without Aravis (`SimRig` in a
//!   `LockStep`: same start, same whole-frame metering, same ranges), and
//!   at a stable fixed point of the estimator (`sim::truth::fixed_points`
//!   on the noise-free renders, reading the darker frame the loop's last
//!   estimate read, if it read one), every camera having moved more than
//!   1 EV.
//!   (Metered over whole frames, the cameras have one to three stable fixed
//!   points each, at least 0.7 EV apart; from the same start both loops
//!   reach the same one.)
//!
//! Run with `--nocapture` to see the figures.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use rigview::live::fake::{clock_ns, render_into, FakeView};
use rigview::live::{CameraSpec, CaptureConfig, DeviceSpec, LiveSource, TriggerMode};
use rigview_core::exposure::{ExposureSetting, Hold, NeighbourGraph, PixelFormat, RigStep};
use rigview_core::pipeline::{LockStep, ProcessingSettings, Processor, Strategy};
use rigview_core::sim::truth::{self, FixedPointSearch};
use rigview_core::sim::{SimConfig, SimRender, SimRig, SimRigOptions};
use rigview_core::source::{CameraInfo, ExposureCommand, FrameSource};

/// Complete sets fed to the controller.
const SETS: usize = 80;
/// The sets over which a loop is judged settled.
const TAIL: usize = 20;
/// Where every camera starts: 2.5 to 6.1 EV below where it settles.
const START: ExposureSetting = ExposureSetting {
    shutter_us: 100.0,
    gain_db: 0.0,
};
/// How close (EV) the loop through Aravis must settle to the loop without
/// it and to the estimator's fixed point. Both loops see noisy frames (with
/// different noise: their frame ids differ), which moves γ̂ a little.
const AGREE_EV: f64 = 0.05;

fn render() -> Arc<SimRender> {
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::preset("reference").unwrap()
    };
    Arc::new(SimRender::new(&config).unwrap())
}

fn mean(px: &[u8]) -> f64 {
    px.iter().map(|&v| f64::from(v)).sum::<f64>() / px.len() as f64
}

fn holds(step: &RigStep) -> usize {
    step.cameras
        .iter()
        .filter(|c| c.hold == Some(Hold::AwaitingCommand))
        .count()
}

/// One loop's exposures (log2 E of each camera's frames, set by set) and
/// the camera-sets in which its controller waited for a command to show.
struct Run {
    log2_e: Vec<Vec<f64>>,
    awaiting: usize,
}

/// Where the loop settled: the band and the middle of the last [`TAIL`]
/// values, and the first set from which the values stay within the band.
struct Settled {
    lo: f64,
    hi: f64,
    mid: f64,
    after: usize,
}

fn settled(t: &[f64]) -> Settled {
    let last = &t[t.len() - TAIL..];
    let lo = last.iter().copied().fold(f64::MAX, f64::min);
    let hi = last.iter().copied().fold(f64::MIN, f64::max);
    let after = t
        .iter()
        .rposition(|l| *l < lo - 0.05 || *l > hi + 0.05)
        .map_or(0, |k| k + 1);
    Settled {
        lo,
        hi,
        mid: last.iter().sum::<f64>() / TAIL as f64,
        after,
    }
}

/// The app's processor, each camera under its own gradient law, metering
/// whole frames (no calibration), its cameras synced to [`START`].
fn processor(cameras: &[CameraInfo]) -> Processor {
    let settings = ProcessingSettings {
        strategy: Strategy::Single,
        ..Default::default()
    };
    let graph = NeighbourGraph::new(cameras.len(), &[]).unwrap();
    let mut p = Processor::new(cameras.to_vec(), None, graph, settings).unwrap();
    p.sync(&vec![START; cameras.len()]).unwrap();
    p
}

/// The same processor on the same simulated rig without Aravis, from the
/// same start, with the cameras' ranges as Aravis reports them.
fn without_aravis(render: &Arc<SimRender>, cameras: &[CameraInfo]) -> Run {
    let n = cameras.len();
    // The fake cameras show each command from the next frame on (the test
    // counts how often).
    let options = SimRigOptions {
        latency: Some(0),
        ..Default::default()
    };
    let mut source = SimRig::new(render.clone(), options).unwrap();
    source.force_all(START);
    let mut with_ranges = source.cameras().to_vec();
    for (c, live) in with_ranges.iter_mut().zip(cameras) {
        c.range = live.range;
    }
    let mut lp = LockStep::new(source, processor(&with_ranges)).unwrap();
    let mut run = Run {
        log2_e: vec![Vec::new(); n],
        awaiting: 0,
    };
    for _ in 0..SETS {
        let step = lp.step().unwrap().unwrap();
        for f in step.set.frames.iter().flatten() {
            run.log2_e[f.meta.camera].push(f.meta.taken.exposure().log2());
        }
        run.awaiting += step.output.as_ref().map_or(0, |o| holds(&o.step));
    }
    run
}

/// One in-process fake camera per view, named `names`, with serial numbers
/// `serial` + index, each camera's start-up auto-exposure running for
/// `settle`. In trigger mode the fake camera fires on its own clock (it does
/// not wait for software triggers): a trigger box at the simulation's 20 Hz.
fn open_fakes(views: &[FakeView], names: &[String], serial: &str, settle: Duration) -> LiveSource {
    let specs: Vec<CameraSpec> = views
        .iter()
        .zip(names)
        .enumerate()
        .map(|(i, (view, name))| CameraSpec {
            name: name.clone(),
            device: DeviceSpec::Fake {
                serial: format!("{serial}{i}"),
                view: view.clone(),
            },
        })
        .collect();
    let config = CaptureConfig {
        trigger: TriggerMode::Hardware {
            line: "Line0".into(),
        },
        auto_settle: settle,
        open_timeout: Duration::from_secs(5),
        ..Default::default()
    };
    LiveSource::open(specs, config).unwrap()
}

#[test]
fn four_in_process_fake_cameras_converge_on_the_simulated_rig_through_aravis() {
    let t0 = Instant::now();
    let render = render();
    let traced = t0.elapsed().as_secs_f64();
    let views = FakeView::rig(&render, PixelFormat::Mono8, clock_ns()).unwrap();
    let names: Vec<String> = render.cameras().iter().map(|c| c.name.clone()).collect();
    let t1 = Instant::now();
    let mut source = open_fakes(&views, &names, "RVINPROC", Duration::from_millis(200));
    let opened = t1.elapsed().as_secs_f64();
    let cameras = source.cameras().to_vec();
    // Start far from the optimum, commanded through Aravis; wait for a set
    // whose every frame shows it.
    let commands: Vec<ExposureCommand> = (0..4)
        .map(|camera| ExposureCommand {
            camera,
            setting: START,
        })
        .collect();
    source.apply(&commands).unwrap();
    loop {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the start command never showed"
        );
        let Some(set) = source.next_set(Duration::from_millis(500)).unwrap() else {
            continue;
        };
        if set.is_complete() && set.frames.iter().flatten().all(|f| f.meta.taken == START) {
            break;
        }
    }
    let mut lp = LockStep::new(source, processor(&cameras)).unwrap();
    let mut last: Option<RigStep> = None;

    let t2 = Instant::now();
    let mut live = Run {
        log2_e: vec![Vec::new(); 4],
        awaiting: 0,
    };
    let mut first_means = None;
    let (mut frames, mut identical, mut worst_px) = (0usize, 0usize, 0u8);
    let mut expect = Vec::new();
    // Commands not shown yet (set index, setting); for each command shown,
    // the sets it took after the next one, and the largest gap between a
    // command and the setting the camera made of it.
    let mut pending: Vec<Option<(usize, ExposureSetting)>> = vec![None; 4];
    let (mut shown_after, mut worst_gap) = (Vec::new(), 0f64);
    let mut index = 0usize;
    let deadline = Instant::now() + Duration::from_secs(20);
    while lp.processed() < SETS as u64 && Instant::now() < deadline {
        let Some(step) = lp.step().unwrap() else {
            continue;
        };
        let set = &step.set;
        if set.is_complete() {
            first_means.get_or_insert_with(|| {
                set.frames
                    .iter()
                    .flatten()
                    .map(|f| mean(&f.data))
                    .collect::<Vec<_>>()
            });
            for f in set.frames.iter().flatten() {
                let m = &f.meta;
                live.log2_e[m.camera].push(m.taken.exposure().log2());
                if let Some((at, s)) = pending[m.camera] {
                    let gap = (m.taken.exposure() / s.exposure() - 1.0).abs();
                    if gap < 0.01 {
                        shown_after.push(index - at - 1);
                        worst_gap = worst_gap.max(gap);
                        pending[m.camera] = None;
                    }
                }
                // The frame is the simulator's render at its id and setting.
                let view = &views[m.camera];
                expect.resize(view.buffer_len(), 0);
                render_into(
                    view,
                    m.frame_id,
                    m.timestamp_ns,
                    m.taken.shutter_us,
                    m.taken.gain_db,
                    &mut expect,
                )
                .unwrap();
                frames += 1;
                identical += usize::from(f.data[..] == expect[..]);
                let px = f.data.iter().zip(&expect).map(|(a, b)| a.abs_diff(*b));
                worst_px = worst_px.max(px.max().unwrap_or(0));
            }
        }
        if let Some(output) = step.output {
            live.awaiting += holds(&output.step);
            for c in &output.step.cameras {
                if let Some(s) = c.command {
                    pending[c.camera] = Some((index, s));
                }
            }
            last = Some(output.step);
        }
        index += 1;
    }
    let looped = t2.elapsed().as_secs_f64();
    let status = lp.source().status();
    let health = lp.source().health();
    let fed = lp.processed();
    let last = last.unwrap();
    // Scale-and-clip reads what the saturated pixels hide from a darker
    // frame of the same scene when the loop kept one: its fixed point is
    // the estimator's reading that frame.
    let darker: Vec<Option<f64>> = last
        .cameras
        .iter()
        .map(|c| {
            let declipped = c.estimate.as_ref().is_some_and(|e| e.declipped);
            let controller = lp.processor_mut().controller_mut();
            declipped
                .then(|| controller.camera_mut(c.camera).ok()?.darker_frame())
                .flatten()
        })
        .collect();
    let first_means = first_means.unwrap();
    drop(lp);

    let t3 = Instant::now();
    let reference = without_aravis(&render, &cameras);
    let referenced = t3.elapsed().as_secs_f64();

    println!(
        "simulation traced in {traced:.2} s ({}×{} Mono8 per camera); cameras opened in {opened:.2} s",
        views[0].width, views[0].height
    );
    println!(
        "{} complete sets fed in {looped:.1} s ({} complete, {} incomplete assembled)",
        fed, status.sets.complete, status.sets.incomplete,
    );
    println!(
        "frames identical to the simulator's render at their frame id, timestamp and taken setting: {identical} of {frames} (largest pixel difference {worst_px} DN)"
    );
    let late = shown_after.iter().filter(|&&k| k > 0).count();
    println!(
        "commands: {} shown, {} in the next set, {late} later; largest gap between a command and the camera's setting {:.2} % (ExposureTimeAbs is whole µs); the controller awaited a command in {} camera-sets (without Aravis: {})",
        shown_after.len(),
        shown_after.len() - late,
        worst_gap * 100.0,
        live.awaiting,
        reference.awaiting
    );
    println!("the same loop without Aravis ran in {referenced:.2} s");
    println!(
        "{:>6} | {:>16} | {:>24} | {:>24} | {:>8} | {:>19} | {:>5}",
        "camera",
        "start log2 E",
        "through Aravis (settled)",
        "without Aravis (settled)",
        "diff EV",
        "fixed point (jump)",
        "γ̂"
    );
    let mut outcomes = Vec::new();
    for (cam, name) in names.iter().enumerate() {
        let a = settled(&live.log2_e[cam]);
        let b = settled(&reference.log2_e[cam]);
        let search = FixedPointSearch {
            lo: (a.lo.min(b.lo) - 1.0).exp2(),
            hi: (a.hi.max(b.hi) + 1.0).exp2(),
            step_ev: 0.05,
            darker: darker[cam],
            ..Default::default()
        };
        let nearest = truth::fixed_points(&render, cam, 0.0, None, &search)
            .unwrap()
            .into_iter()
            .map(|f| (f.exposure.log2(), f.jump))
            .min_by(|x, y| (x.0 - a.mid).abs().total_cmp(&(y.0 - a.mid).abs()));
        println!(
            "{name:>6} | {:>5.2} ({:>5.1} DN) | {:>6.3}–{:<6.3} ({:>2} sets) | {:>6.3}–{:<6.3} ({:>2} sets) | {:>+8.3} | {:>19} | {:>5.3}",
            START.exposure().log2(),
            first_means[cam],
            a.lo,
            a.hi,
            a.after,
            b.lo,
            b.hi,
            b.after,
            a.mid - b.mid,
            nearest.map_or("none".into(), |(f, j)| format!("{f:.3} ({j:.2})")),
            last.cameras[cam]
                .estimate
                .as_ref()
                .map_or(f64::NAN, |e| e.gamma_hat),
        );
        outcomes.push((a, b, nearest));
    }
    println!("total {:.1} s", t0.elapsed().as_secs_f64());

    assert!(fed >= SETS as u64, "only {} complete sets", fed);
    assert_eq!(
        identical, frames,
        "frames differ from the render at their id, timestamp and taken setting (largest pixel difference {worst_px} DN)"
    );
    for (name, (a, b, nearest)) in names.iter().zip(outcomes) {
        assert!(
            a.hi - a.lo <= 0.25,
            "{name}: not settled, {:.2}–{:.2}",
            a.lo,
            a.hi
        );
        assert!(
            (a.mid - b.mid).abs() <= AGREE_EV,
            "{name}: through Aravis settled at {:.3}, without at {:.3}",
            a.mid,
            b.mid
        );
        let (f, _) = nearest.unwrap_or_else(|| panic!("{name}: no fixed point near {:.2}", a.mid));
        assert!(
            (a.mid - f).abs() <= AGREE_EV,
            "{name}: settled at {:.3}, the fixed point is at {f:.3}",
            a.mid
        );
        // The loop moved the exposure a long way: the commands reached the
        // pixels.
        let moved = a.mid - START.exposure().log2();
        assert!(moved > 1.0, "{name}: moved only {moved:.2} EV");
    }
    for h in &health {
        assert!(h.completed >= SETS as u64, "{h:?}");
        assert_eq!(h.failed, 0, "{h:?}");
    }
}

/// The fill callback writes whole frames of every pixel format the fake
/// camera offers (1, 2 and 3 bytes a pixel), and at another size than the
/// simulated camera's (resampled); the light follows the script by the
/// frames' timestamps. Each camera here has its own format and size, the
/// simulation is the `ramp` preset (the light falls 0.4 stops a second from
/// 1 s to 11 s; its script started 2 s before the cameras), and every frame
/// arrives as the simulator renders it at its frame id, timestamp and
/// setting.
#[test]
fn fake_cameras_in_other_formats_and_sizes_deliver_the_render() {
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::preset("ramp").unwrap()
    };
    let render = Arc::new(SimRender::new(&config).unwrap());
    let epoch_ns = clock_ns() - 2_000_000_000;
    let cases = [
        (PixelFormat::Mono16, 322, 241),
        (PixelFormat::Rgb8, 322, 241),
        (PixelFormat::BayerRg8, 200, 150),
        (PixelFormat::Mono8, 640, 480),
    ];
    let views: Vec<FakeView> = cases
        .iter()
        .enumerate()
        .map(|(i, &(format, w, h))| {
            FakeView::sized(render.clone(), i, format, (w, h), epoch_ns).unwrap()
        })
        .collect();
    let names: Vec<String> = views
        .iter()
        .zip(render.cameras())
        .map(|(v, c)| format!("{}-{}", c.name, v.format.genicam_name()))
        .collect();
    let mut source = open_fakes(&views, &names, "RVFORMAT", Duration::ZERO);
    for (info, (format, w, h)) in source.cameras().iter().zip(cases) {
        assert_eq!((info.format, info.width, info.height), (format, w, h));
    }
    let (mut sets, mut frames, mut identical, mut moved) = (0, 0, 0, 0);
    let (mut first, mut last) = (f64::MAX, f64::MIN);
    let mut expect = Vec::new();
    let mut earlier = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(10);
    while sets < 10 && Instant::now() < deadline {
        let Some(set) = source.next_set(Duration::from_millis(500)).unwrap() else {
            continue;
        };
        if !set.is_complete() {
            continue;
        }
        sets += 1;
        for f in set.frames.iter().flatten() {
            let view = &views[f.meta.camera];
            expect.resize(view.buffer_len(), 0);
            let (m, t) = (&f.meta, f.meta.taken);
            let at = |ts: u64, out: &mut Vec<u8>| {
                out.resize(view.buffer_len(), 0);
                render_into(view, m.frame_id, ts, t.shutter_us, t.gain_db, out).unwrap();
            };
            at(m.timestamp_ns, &mut expect);
            frames += 1;
            identical += usize::from(f.data[..] == expect[..]);
            assert!(f.data.iter().any(|&b| b != f.data[0]), "a flat frame");
            // The same frame a trigger earlier in the script looks different.
            at(m.timestamp_ns - 50_000_000, &mut earlier);
            moved += usize::from(earlier != expect);
            first = first.min(view.moment(m.timestamp_ns));
            last = last.max(view.moment(m.timestamp_ns));
        }
    }
    println!(
        "{sets} sets at {first:.2}–{last:.2} s of the ramp: {identical} of {frames} frames identical to the render at their frame id, timestamp and setting; {moved} differ from the render 50 ms earlier"
    );
    assert_eq!(sets, 10, "only {sets} complete sets");
    assert_eq!(identical, frames);
    assert_eq!(moved, frames);
}
