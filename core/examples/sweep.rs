//! Prints M, γ̂ and ŝ over an exposure sweep of a synthetic scene:
//! `cargo run --release -p rigview-core --example sweep [LEFT RIGHT]`.
use rigview_core::exposure::*;
use rigview_core::synth::*;

fn main() -> rigview_core::Result<()> {
    let levels: Vec<f32> = std::env::args()
        .skip(1)
        .filter_map(|s| s.parse().ok())
        .collect();
    let illum = if levels.len() == 2 {
        Illumination::Split {
            left: levels[0],
            right: levels[1],
            boundary: 0.5,
        }
    } else {
        Illumination::Uniform(1.0)
    };
    let scene = HdrScene::generate(640, 480, 7, &illum)?;
    let cam = LinearCamera::default();
    let meter = Meter::new(MeteringConfig::default())?;
    let mut eg = Estimator::new(EstimatorConfig::default())?;
    let mut es = Estimator::new(EstimatorConfig {
        simulation: Simulation::ScaleClip,
        ..Default::default()
    })?;
    for k in 0..48 {
        let e = 1000.0 * 2f64.powf(f64::from(k) * 0.25);
        let f = cam.render_mono8(scene.radiance(), e, 0);
        let v = FrameView::new(PixelFormat::Mono8, 640, 480, &f)?;
        let m = meter.meter(&v, None)?;
        let g = eg.estimate(&m)?;
        let s = es.estimate(&m)?;
        println!(
            "log2 E {:6.2}  M {:8.1}  gamma-hat {:.3}  s-hat {:.3}  mean {:.3}",
            e.log2(),
            g.m_current,
            g.gamma_hat,
            s.x_hat,
            m.stats().mean
        );
    }
    Ok(())
}
