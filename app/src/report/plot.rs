//! A PNG plot of the exposure state over a run (plotters): log2 E, gain, γ̂
//! and M per camera, and log2 r_ij per overlap, against time.

use std::path::Path;

use anyhow::{Context, Result};
use plotters::prelude::*;
use rigview_core::pipeline::{Telemetry, TelemetryRow};

use super::glyphs::{register_font, Glyphs, FONT};

const COLOURS: [RGBColor; 6] = [
    RGBColor(220, 70, 50),
    RGBColor(40, 120, 200),
    RGBColor(60, 160, 60),
    RGBColor(210, 150, 20),
    RGBColor(150, 80, 190),
    RGBColor(40, 170, 160),
];

type Value = fn(&TelemetryRow, usize) -> Option<f64>;

/// `log2 e` of a positive exposure.
fn log2_of(e: Option<f64>) -> Option<f64> {
    e.filter(|e| *e > 0.0).map(f64::log2)
}

/// Writes the plot of `telemetry` to `path` (`width`×`height` pixels).
pub fn write(telemetry: &Telemetry, path: &Path, width: u32, height: u32) -> Result<()> {
    write_with(telemetry, path, width, height, false)
}

/// [`write`], with a panel of the exposures the strategy commanded under
/// the exposures the frames were taken with if `commands` (a replay: the
/// recorded exposures next to what the chosen strategy would have sent).
pub fn write_with(
    telemetry: &Telemetry,
    path: &Path,
    width: u32,
    height: u32,
    commands: bool,
) -> Result<()> {
    register_font()?;
    let mut buf = vec![0u8; width as usize * height as usize * 3];
    {
        let root =
            Glyphs::new(BitMapBackend::with_buffer(&mut buf, (width, height))).into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        let panels = root.split_evenly((if commands { 6 } else { 5 }, 1));
        let cams = telemetry.camera_names().len();
        let mut camera_panels: Vec<(&str, Value)> = vec![
            ("log2 E (E = shutter_us · 10^(gain_dB/20))", |r, k| {
                log2_of(r.cameras.get(k).map(|c| c.exposure))
            }),
            ("gain (dB)", |r, k| r.cameras.get(k).map(|c| c.gain_db)),
            ("gamma-hat (γ-equivalent)", |r, k| {
                r.cameras.get(k).and_then(|c| c.gamma_hat)
            }),
            ("gradient information M", |r, k| {
                r.cameras.get(k).and_then(|c| c.m)
            }),
        ];
        if commands {
            camera_panels.insert(
                1,
                ("log2 E the strategy would command", |r, k| {
                    log2_of(r.cameras.get(k).and_then(|c| c.command))
                }),
            );
        }
        let pair_panel = camera_panels.len();
        for (area, (title, value)) in panels.iter().zip(camera_panels) {
            let series: Vec<(String, Vec<(f64, f64)>)> = (0..cams)
                .map(|k| {
                    let pts = telemetry
                        .rows()
                        .iter()
                        .filter_map(|r| {
                            value(r, k).filter(|v| v.is_finite()).map(|v| (r.time_s, v))
                        })
                        .collect();
                    (telemetry.camera_names()[k].clone(), pts)
                })
                .collect();
            panel(area, title, &series)?;
        }
        if let Some(area) = panels.get(pair_panel) {
            let series: Vec<(String, Vec<(f64, f64)>)> = telemetry
                .pair_names()
                .iter()
                .enumerate()
                .map(|(k, name)| {
                    let pts = telemetry
                        .rows()
                        .iter()
                        .filter_map(|r| r.log2_r.get(k).copied().flatten().map(|v| (r.time_s, v)))
                        .collect();
                    (name.clone(), pts)
                })
                .collect();
            panel(area, "log2 r_ij per overlap", &series)?;
        }
        root.present().map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    let img = image::RgbImage::from_raw(width, height, buf)
        .context("plot: the image buffer has the wrong size")?;
    save_png(&img, path).with_context(|| format!("writing the plot {}", path.display()))
}

/// Writes a plot as a PNG compressed harder than the default (plots are
/// flat colours: about a third smaller, which the evaluation's report,
/// with its figures inlined, carries).
pub fn save_png(img: &image::RgbImage, path: &Path) -> Result<()> {
    use image::codecs::png::{CompressionType, FilterType, PngEncoder};
    let file = std::fs::File::create(path)?;
    img.write_with_encoder(PngEncoder::new_with_quality(
        std::io::BufWriter::new(file),
        CompressionType::Best,
        FilterType::Adaptive,
    ))?;
    Ok(())
}

fn panel(
    area: &DrawingArea<Glyphs<BitMapBackend<'_>>, plotters::coord::Shift>,
    title: &str,
    series: &[(String, Vec<(f64, f64)>)],
) -> Result<()> {
    let err = |e: DrawingAreaErrorKind<_>| anyhow::anyhow!("plot \"{title}\": {e}");
    let pts = series.iter().flat_map(|s| s.1.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        (x0, x1, y0, y1) = (0.0, 1.0, 0.0, 1.0);
    }
    if x1 - x0 < 1e-9 {
        x1 = x0 + 1.0;
    }
    let pad = ((y1 - y0) * 0.08).max(1e-3);
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 16))
        .margin(6)
        .x_label_area_size(36)
        .y_label_area_size(56)
        .build_cartesian_2d(x0..x1, (y0 - pad)..(y1 + pad))
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .label_style((FONT, 12))
        .axis_desc_style((FONT, 12))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    for (k, (name, pts)) in series.iter().enumerate() {
        let c = COLOURS[k % COLOURS.len()];
        chart
            .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2)))
            .map_err(err)?
            .label(name.as_str())
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(2)));
    }
    chart
        .configure_series_labels()
        .label_font((FONT, 12))
        .background_style(WHITE.mix(0.8))
        .border_style(RGBColor(180, 180, 180))
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(err)?;
    Ok(())
}
