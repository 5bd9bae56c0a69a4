//! Live capture against four of Aravis's in-process fake cameras, each
//! rendering a synthetic high-dynamic-range scene at the exposure time and
//! gain its registers hold: the closed loop converges through the real
//! Aravis API (exposure commands change the pixels), and every frame's
//! `taken` setting is the one it was rendered with. Run with `--nocapture`
//! to see the figures.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::time::{Duration, Instant};

use rigview::live::cmd::LiveLoop;
use rigview::live::fake::{render_into, FakeView};
use rigview::live::{CameraSpec, CaptureConfig, DeviceSpec, LiveSource, TriggerMode};
use rigview_core::exposure::{ControllerConfig, ExposureSetting, MeteringConfig, RigController};
use rigview_core::exposure::{ExposureRange, NeighbourGraph};
use rigview_core::source::{ExposureCommand, FrameSource};
use rigview_core::synth::{LinearCamera, StripHarness, StripRig};

const LEVELS: [f32; 4] = [1.0, 1.0, 16.0, 1.0];
const W: usize = 320;
const H: usize = 240;
const SEED: u64 = 11;

fn views(noise_dn: f32) -> Vec<FakeView> {
    FakeView::strip(
        W,
        H,
        &LEVELS,
        SEED,
        LinearCamera {
            noise_dn,
            ..Default::default()
        },
    )
    .unwrap()
}

fn mean(px: &[u8]) -> f64 {
    px.iter().map(|&v| f64::from(v)).sum::<f64>() / px.len() as f64
}

/// Where the same controller settles on the same scenes without Aravis.
fn reference(start: &[ExposureSetting], ranges: &[ExposureRange], sets: usize) -> Vec<f64> {
    let rig = StripRig::new(W, H, W / 4, &LEVELS, SEED).unwrap();
    let mut harness = StripHarness::new(
        rig,
        LinearCamera::default(),
        MeteringConfig::default(),
        1,
        start[0],
    )
    .unwrap();
    for (i, s) in start.iter().enumerate() {
        harness.force(i, *s);
    }
    let config = ControllerConfig {
        balancing: None,
        ..Default::default()
    };
    let mut controller =
        RigController::new(config, ranges, NeighbourGraph::new(4, &[]).unwrap()).unwrap();
    let mut last = Vec::new();
    for _ in 0..sets {
        let (set, _) = harness.step(&mut controller).unwrap();
        last = set.infos.iter().map(|i| i.taken.exposure()).collect();
    }
    last
}

#[test]
fn four_in_process_fake_cameras_converge_through_aravis() {
    let views = views(1.0);
    let specs: Vec<CameraSpec> = views
        .iter()
        .enumerate()
        .map(|(i, v)| CameraSpec {
            name: format!("cam{i}"),
            device: DeviceSpec::Fake {
                serial: format!("RVINPROC{i}"),
                view: v.clone(),
            },
        })
        .collect();
    let config = CaptureConfig {
        // The in-process fake camera fires on its own clock in trigger mode
        // (it does not wait for software triggers): a trigger box at 20 Hz (its default here).
        trigger: TriggerMode::Hardware {
            line: "Line0".into(),
        },
        auto_settle: Duration::from_millis(200),
        open_timeout: Duration::from_secs(5),
        ..Default::default()
    };
    let t0 = Instant::now();
    let mut source = LiveSource::open(specs, config).unwrap();
    println!("opened in {:.2} s", t0.elapsed().as_secs_f64());
    println!("cameras' own settings: {:?}", source.start_settings());
    let ranges: Vec<_> = source.cameras().iter().map(|c| c.range).collect();
    // Start far from the optimum: 500 µs, commanded through Aravis; wait
    // for a set whose every frame shows it.
    let dark = ExposureSetting {
        shutter_us: 500.0,
        gain_db: 0.0,
    };
    let commands: Vec<ExposureCommand> = (0..4)
        .map(|camera| ExposureCommand {
            camera,
            setting: dark,
        })
        .collect();
    source.apply(&commands).unwrap();
    let start = loop {
        assert!(
            t0.elapsed() < Duration::from_secs(10),
            "the start command never showed"
        );
        let Some(set) = source.next_set(Duration::from_millis(500)).unwrap() else {
            continue;
        };
        if set.is_complete() && set.frames.iter().flatten().all(|f| f.meta.taken == dark) {
            break vec![dark; 4];
        }
    };
    let mut control = LiveLoop::new(&source, ControllerConfig::default(), &start).unwrap();

    let mut first_means = None;
    let mut sets = 0;
    let mut worst_render_gap: f64 = 0.0;
    let deadline = Instant::now() + Duration::from_secs(20);
    while control.fed() < 120 && Instant::now() < deadline {
        let Some(set) = source.next_set(Duration::from_millis(500)).unwrap() else {
            continue;
        };
        sets += 1;
        if set.is_complete() {
            let means: Vec<f64> = set.frames.iter().flatten().map(|f| mean(&f.data)).collect();
            first_means.get_or_insert(means);
            // Every frame shows the setting it says it was taken with.
            for f in set.frames.iter().flatten() {
                let mut expect = vec![0u8; W * H];
                let noiseless = FakeView {
                    camera: LinearCamera::default(),
                    ..views[f.meta.camera].clone()
                };
                render_into(
                    &noiseless,
                    f.meta.taken.shutter_us,
                    f.meta.taken.gain_db,
                    &mut expect,
                );
                let (m, e) = (mean(&f.data), mean(&expect));
                worst_render_gap = worst_render_gap.max((m - e).abs());
            }
        }
        control.step(&mut source, &set).unwrap();
    }
    let status = source.status();
    let last = control.last().unwrap();
    let live: Vec<f64> = last.cameras.iter().map(|c| c.taken.exposure()).collect();
    let reference = reference(&start, &ranges, 120);
    let first_means = first_means.unwrap();
    let last_means: Vec<f64> = last.cameras.iter().map(|c| f64::from(c.mean)).collect();
    println!(
        "{sets} sets in {:.1} s: {} complete, {} incomplete; fed {}",
        t0.elapsed().as_secs_f64(),
        status.sets.complete,
        status.sets.incomplete,
        control.fed()
    );
    for i in 0..4 {
        println!(
            "cam{i}: start E {:.0} (mean {:.1} DN) → live E {:.0} (metered mean {:.3}), reference E {:.0}, ratio {:.3}; γ̂ {:.2}",
            start[i].exposure(),
            first_means[i],
            live[i],
            last_means[i],
            reference[i],
            live[i] / reference[i],
            last.cameras[i].estimate.as_ref().map_or(f64::NAN, |e| e.gamma_hat)
        );
    }
    println!(
        "largest gap between a frame and a render at its taken setting: {worst_render_gap:.2} DN"
    );
    assert!(control.fed() >= 120, "only {} complete sets", control.fed());
    for i in 0..4 {
        let r = live[i] / reference[i];
        assert!(
            (0.8..1.25).contains(&r),
            "cam{i}: live E {} vs reference {}",
            live[i],
            reference[i]
        );
        // The loop moved the exposure a long way: the commands reached the
        // pixels.
        let moved = (live[i] / start[i].exposure()).log2().abs();
        assert!(moved > 1.0, "cam{i} moved only {moved:.2} EV");
    }
    assert!(
        worst_render_gap < 3.0,
        "a frame's pixels do not match its taken setting ({worst_render_gap:.2} DN)"
    );
    let health = source.health();
    for h in &health {
        assert!(h.completed >= 120, "{h:?}");
        assert_eq!(h.failed, 0, "{h:?}");
    }
}
