//! Every camera model through the simulated rig and the surround view: a
//! rig whose cameras use the double-sphere, the extended unified or the
//! unified (Mei) model renders, and the surround view built from the same
//! rig lines neighbouring cameras up in their overlaps; a view built with
//! one model parameter wrong does not.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use rigview_calib::{Distortion, Rig};
use rigview_core::image::FrameView;
use rigview_core::sim::{reference_rig, SimConfig, SimRender};
use rigview_core::source::Frame;
use rigview_core::surround::{CanvasSpec, Composer, SurroundOptions, SurroundView};

/// The reference rig's poses with every camera's lens replaced by
/// `distortion` at focal length `f` (pixels of the full-size image).
fn rig_with(distortion: Distortion, f: f64) -> Rig {
    let mut rig = reference_rig().unwrap();
    for c in &mut rig.cameras {
        c.intrinsics.distortion = distortion;
        c.intrinsics.fx = f;
        c.intrinsics.fy = f;
    }
    rig
}

/// The relative mean absolute difference between neighbours' warps where
/// both show the ground, over every neighbour pair, of the frames rendered
/// through `rendered` and warped through `viewed` (the same rig but for
/// the lens, scaled as the render's).
fn overlap_difference(render: &SimRender, viewed: &Rig) -> f64 {
    let spec = CanvasSpec {
        px_per_m: 25.0,
        ..CanvasSpec::default()
    };
    let view = SurroundView::build(viewed, &spec, &SurroundOptions::default()).unwrap();
    let setting = render.config().start;
    let frames: Vec<Frame> = render
        .cameras()
        .iter()
        .enumerate()
        .map(|(i, info)| {
            let req = rigview_core::sim::FillRequest::new(
                i,
                0,
                setting,
                info.format,
                info.width,
                info.height,
            );
            let mut buf = vec![0u8; req.buffer_len()];
            let meta = render.fill(&req, &mut buf).unwrap();
            Frame::new(meta, buf.into()).unwrap()
        })
        .collect();
    let views: Vec<FrameView<'_>> = frames.iter().map(|f| f.view().unwrap()).collect();
    let mut composer = Composer::new();
    let warps: Vec<_> = (0..views.len())
        .map(|k| composer.warp_camera(view.mosaic(), k, &views[k]).unwrap())
        .collect();
    let (mut diff, mut sum, mut n) = (0.0, 0.0, 0usize);
    for &(i, j) in &viewed.neighbours {
        for (a, b) in warps[i].data.iter().zip(&warps[j].data) {
            if *a > 0 && *b > 0 {
                diff += f64::from(a.abs_diff(*b));
                sum += 0.5 * (f64::from(*a) + f64::from(*b));
                n += 1;
            }
        }
    }
    assert!(n > 2000, "only {n} overlap pixels");
    diff / sum
}

#[test]
fn every_sphere_model_renders_and_its_surround_view_lines_neighbours_up() {
    // Lenses of about the reference camera's field of view.
    let cases = [
        (Distortion::DoubleSphere([-0.2, 0.6]), 250.0, 1, 0.05),
        (Distortion::Eucm([0.6, 1.1]), 260.0, 0, 0.05),
        (
            Distortion::Omni([0.9, -0.05, 0.004, 0.0005, -0.0005]),
            420.0,
            0,
            0.1,
        ),
    ];
    let config = SimConfig {
        scale: 0.25,
        ..SimConfig::preset("overcast").unwrap()
    };
    // What neighbours differ by through the reference rig's own lens (the
    // Kannala–Brandt fisheye): the ground seen from two angles, noise and
    // each camera's vignetting.
    let reference = SimRender::with_rig(&config, reference_rig().unwrap()).unwrap();
    let baseline = overlap_difference(&reference, reference.rig());
    println!("fisheye: overlap difference {baseline:.4}");
    for (distortion, f, wrong_at, delta) in cases {
        let name = distortion.model_name();
        let render = SimRender::with_rig(&config, rig_with(distortion, f)).unwrap();
        let same = overlap_difference(&render, render.rig());
        // The same rig with one parameter of the lens off by `delta`.
        let mut wrong = render.rig().clone();
        for c in &mut wrong.cameras {
            let mut k = c.intrinsics.distortion.coefficients().to_vec();
            k[wrong_at] += delta;
            c.intrinsics.distortion = Distortion::from_name(name, &k).unwrap();
        }
        let off = overlap_difference(&render, &wrong);
        println!("{name}: overlap difference {same:.4} with the rig rendered, {off:.4} with a wrong lens");
        // The lenses here spread the overlaps over fewer pixels than the
        // reference lens (0.16–0.17 against 0.13); one parameter off by a
        // few hundredths gives 0.5 and more.
        assert!(same < 1.4 * baseline, "{name}: {same} against {baseline}");
        assert!(
            off > 2.5 * same,
            "{name}: {same} against {off} with a wrong lens"
        );
    }
}
