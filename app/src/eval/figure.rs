//! The evaluation's figures (plotters): panels of line and marker series
//! with labelled axes and a legend each, written as one PNG.

use std::path::Path;

use anyhow::{Context, Result};
use plotters::prelude::*;

use crate::report::glyphs::{register_font, FONT};

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Style {
    /// A line through the points.
    Line,
    /// A line with a dot at each point.
    LineDots,
    /// Thin line (a second statistic of a series drawn with [`Style::LineDots`]).
    Thin,
    /// Dots only (large, outlined: marks on a curve).
    Marks,
}

/// One series of a panel.
#[derive(Clone, Debug)]
pub struct Series {
    /// Its legend entry (`None`: not in the legend).
    pub label: Option<String>,
    /// Its colour.
    pub colour: RGBColor,
    /// How it is drawn.
    pub style: Style,
    /// Its points (non-finite points are left out).
    pub points: Vec<(f64, f64)>,
}

/// One panel: a chart with its axes.
#[derive(Clone, Debug, Default)]
pub struct Panel {
    /// The caption.
    pub title: String,
    /// The x axis's description, with its unit.
    pub x_label: String,
    /// The y axis's description, with its unit.
    pub y_label: String,
    /// The series.
    pub series: Vec<Series>,
    /// Vertical lines at these x (events: steps of light).
    pub marks_x: Vec<f64>,
}

/// Writes `panels` into a PNG of `cols` columns, each panel
/// `panel_w`×`panel_h` pixels.
pub fn write(path: &Path, panels: &[Panel], cols: usize, panel_w: u32, panel_h: u32) -> Result<()> {
    register_font()?;
    let cols = cols.clamp(1, panels.len().max(1));
    let rows = panels.len().div_ceil(cols).max(1);
    let (w, h) = (panel_w * cols as u32, panel_h * rows as u32);
    let mut buf = vec![0u8; w as usize * h as usize * 3];
    {
        let root = crate::report::glyphs::Glyphs::new(BitMapBackend::with_buffer(&mut buf, (w, h)))
            .into_drawing_area();
        root.fill(&WHITE)
            .map_err(|e| anyhow::anyhow!("figure: {e}"))?;
        let areas = root.split_evenly((rows, cols));
        for (area, panel) in areas.iter().zip(panels) {
            draw(area, panel)?;
        }
        root.present().map_err(|e| anyhow::anyhow!("figure: {e}"))?;
    }
    let img = image::RgbImage::from_raw(w, h, buf).context("figure: wrong buffer size")?;
    crate::report::plot::save_png(&img, path)
        .with_context(|| format!("writing the figure {}", path.display()))
}

fn bounds(panel: &Panel) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in panel.series.iter().flat_map(|s| s.points.iter()) {
        if x.is_finite() && y.is_finite() {
            x0 = x0.min(x);
            x1 = x1.max(x);
            y0 = y0.min(y);
            y1 = y1.max(y);
        }
    }
    if x0 > x1 {
        return (0.0, 1.0, 0.0, 1.0);
    }
    let xpad = ((x1 - x0) * 0.03).max(0.5);
    let ypad = ((y1 - y0) * 0.08).max(1e-3);
    (x0 - xpad, x1 + xpad, y0 - ypad, y1 + ypad)
}

fn draw(
    area: &DrawingArea<crate::report::glyphs::Glyphs<BitMapBackend<'_>>, plotters::coord::Shift>,
    panel: &Panel,
) -> Result<()> {
    let title = panel.title.as_str();
    let err = |e: DrawingAreaErrorKind<_>| anyhow::anyhow!("figure \"{title}\": {e}");
    let (x0, x1, y0, y1) = bounds(panel);
    let mut chart = ChartBuilder::on(area)
        .caption(title, (FONT, 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(64)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 14))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(err)?;
    for &x in &panel.marks_x {
        chart
            .draw_series(LineSeries::new(
                [(x, y0), (x, y1)],
                RGBColor(190, 190, 190).stroke_width(1),
            ))
            .map_err(err)?;
    }
    let mut legend = false;
    for s in &panel.series {
        let c = s.colour;
        let pts: Vec<(f64, f64)> = s
            .points
            .iter()
            .copied()
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .collect();
        let drawn = match s.style {
            Style::Line | Style::LineDots | Style::Thin => {
                let width = if s.style == Style::Thin { 1 } else { 2 };
                if s.style == Style::LineDots {
                    chart
                        .draw_series(pts.iter().map(|&p| Circle::new(p, 4, c.filled())))
                        .map_err(err)?;
                }
                chart
                    .draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(width)))
                    .map_err(err)?
            }
            Style::Marks => {
                chart
                    .draw_series(
                        pts.iter()
                            .map(|&p| Circle::new(p, 6, BLACK.stroke_width(1))),
                    )
                    .map_err(err)?;
                chart
                    .draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled())))
                    .map_err(err)?
            }
        };
        if let Some(label) = &s.label {
            legend = true;
            let anno = drawn.label(label.as_str());
            if s.style == Style::Marks {
                anno.legend(move |(x, y)| Circle::new((x + 8, y), 5, c.filled()));
            } else {
                let width = if s.style == Style::Thin { 1 } else { 2 };
                anno.legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 16, y)], c.stroke_width(width))
                });
            }
        }
    }
    if legend {
        chart
            .configure_series_labels()
            .label_font((FONT, 13))
            .background_style(WHITE.mix(0.85))
            .border_style(RGBColor(180, 180, 180))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(err)?;
    }
    Ok(())
}
