//! Renders every camera of a simulation (a preset or a file) to PNG files,
//! at one exposure level, with the time the precomputation took:
//! `cargo run --release -p rigview-core --example sim_preview [PRESET|FILE] [E_us] [SCALE] [T_s]`
//! (defaults: reference, 1000, 1, 0). Files go to `sim-<camera>.png` in the
//! current folder.

use std::time::Instant;

use rigview_calib::tools::GrayImage;
use rigview_core::exposure::{ExposureSetting, PixelFormat};
use rigview_core::sim::{truth, FillRequest, SimConfig, SimRender};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let name = args.first().map_or("reference", String::as_str);
    let e: f64 = args.get(1).map_or(Ok(1000.0), |s| s.parse())?;
    let scale: f64 = args.get(2).map_or(Ok(1.0), |s| s.parse())?;
    let t: f64 = args.get(3).map_or(Ok(0.0), |s| s.parse())?;
    let config = SimConfig {
        scale,
        ..SimConfig::named(name)?
    };
    let start = Instant::now();
    let render = SimRender::new(&config)?;
    println!(
        "{name}: traced {} cameras in {:.2} s",
        render.cameras().len(),
        start.elapsed().as_secs_f64()
    );
    let dr = truth::dynamic_range(&render, t)?;
    println!(
        "dynamic range at t = {t} s: 0.01–99.99 % quantiles {:.3e} … {:.3e} (ratio {:.0}), darkest {:.3e}, brightest {:.3e}",
        dr.low,
        dr.high,
        dr.ratio(),
        dr.darkest,
        dr.brightest
    );
    for (i, info) in render.cameras().iter().enumerate() {
        let setting = ExposureSetting {
            shutter_us: e,
            gain_db: 0.0,
        };
        let mut req = FillRequest::new(i, 0, setting, PixelFormat::Mono8, info.width, info.height);
        req.time_s = Some(t);
        let mut data = vec![0u8; req.buffer_len()];
        render.fill(&req, &mut data)?;
        let path = format!("sim-{}.png", info.name);
        GrayImage {
            width: info.width as u32,
            height: info.height as u32,
            data,
        }
        .save_png(std::path::Path::new(&path))?;
        println!("wrote {path}");
    }
    Ok(())
}
