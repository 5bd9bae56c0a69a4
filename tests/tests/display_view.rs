#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! What the operator sees of the control: the composed view through the
//! app's processor on the simulated rig (reference preset, a quarter of the
//! resolution), in lock step: the display gains even out the seams that
//! balancing leaves, without touching the cameras' exposures.

use std::sync::Arc;

use rigview_core::pipeline::{DisplaySettings, LockStep, ProcessingSettings};
use rigview_core::sim::{SimConfig, SimRender, SimRig};
use rigview_core::surround::{SeamBands, SurroundView};

fn render() -> Arc<SimRender> {
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::preset("reference").unwrap()
    };
    Arc::new(SimRender::new(&config).unwrap())
}

fn view(render: &SimRender) -> SurroundView {
    rigview_tests::test_view(render).unwrap()
}

fn composing(render: &Arc<SimRender>, settings: ProcessingSettings) -> LockStep<SimRig> {
    let mut lp =
        rigview_tests::sim_loop(render, view(render), settings, &render.rig().neighbours).unwrap();
    lp.processor_mut().set_compose(true);
    lp
}

/// The default mode (balanced) leaves brightness steps at the seams; the
/// display gains remove them (median step below 0.1 EV on every seam)
/// while every camera's exposure stays exactly as without them.
#[test]
fn display_gains_even_out_the_seams_and_leave_the_exposures_alone() {
    let render = render();
    let run = |compensate: bool| {
        let settings = ProcessingSettings {
            display: DisplaySettings {
                compensate,
                ..Default::default()
            },
            ..Default::default()
        };
        let mut lp = composing(&render, settings);
        let seams = SeamBands::new(lp.processor().view().unwrap(), 3);
        assert!(
            seams.sizes().iter().all(|&n| n > 100),
            "{:?}",
            seams.sizes()
        );
        let mut exposures = Vec::new();
        let mut steps = Vec::new();
        for _ in 0..80 {
            let step = lp.step().unwrap().unwrap();
            let out = step.output.unwrap();
            exposures.push(
                out.cameras
                    .iter()
                    .map(|c| c.taken.exposure())
                    .collect::<Vec<_>>(),
            );
            let frames: Vec<_> = step
                .set
                .frames
                .iter()
                .map(|f| f.as_ref().unwrap().view().unwrap())
                .collect();
            steps = seams
                .steps(&frames, Some(&out.display_gains))
                .unwrap()
                .into_iter()
                .map(|s| s.step_ev.unwrap())
                .collect::<Vec<f64>>();
        }
        (exposures, steps)
    };
    let (e_off, off) = run(false);
    let (e_on, on) = run(true);
    println!("seam steps (EV) without display gains {off:.3?}, with {on:.3?}");
    assert_eq!(e_on, e_off, "display gains changed the exposures");
    assert!(
        off.iter().any(|&s| s > 0.2),
        "balancing left no seam to even out: {off:.3?}"
    );
    for s in &on {
        assert!(*s < 0.1, "seam steps with display gains {on:.3?}");
    }
}
