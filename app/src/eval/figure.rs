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
        let mut panels = panels.to_vec();
        place_legend(&mut panels, (panel_w, panel_h));
        for (area, panel) in areas.iter().zip(&panels) {
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

/// The corner of the plot where the legend hides the fewest points (a
/// mark, which shows where a strategy settled, counts as five), upper
/// right on a tie. The legend's size is estimated from its labels: about
/// 7 pixels a character at the legend's font, 17 pixels a line.
fn legend_corner(
    panel: &Panel,
    bounds: (f64, f64, f64, f64),
    size: (u32, u32),
) -> SeriesLabelPosition {
    legend_placement(panel, panel, bounds, size).0
}

/// Where the legend of `labelled`'s series would go on `panel` (the same
/// series in the same order), and how many points it hides there (a mark
/// counting five).
fn legend_placement(
    labelled: &Panel,
    panel: &Panel,
    (x0, x1, y0, y1): (f64, f64, f64, f64),
    (w, h): (u32, u32),
) -> (SeriesLabelPosition, usize) {
    let labels: Vec<&str> = labelled
        .series
        .iter()
        .filter_map(|s| s.label.as_deref())
        .collect();
    let chars = labels.iter().map(|l| l.chars().count()).max().unwrap_or(0);
    // The plot inside the panel: less the axes' label areas, the caption
    // and the margins.
    let plot_w = (f64::from(w) - 64.0 - 20.0).max(1.0);
    let plot_h = (f64::from(h) - 40.0 - 28.0 - 20.0).max(1.0);
    let fw = ((7.0 * chars as f64 + 40.0) / plot_w).min(1.0);
    let fh = ((17.0 * labels.len() as f64 + 14.0) / plot_h).min(1.0);
    let (xs, ys) = (x1 - x0, y1 - y0);
    let corners = [
        (SeriesLabelPosition::UpperRight, true, true),
        (SeriesLabelPosition::UpperLeft, false, true),
        (SeriesLabelPosition::LowerRight, true, false),
        (SeriesLabelPosition::LowerLeft, false, false),
    ];
    let hidden = |right: bool, upper: bool| -> usize {
        panel
            .series
            .iter()
            .map(|s| {
                let weight = if s.style == Style::Marks { 5 } else { 1 };
                let inside = s
                    .points
                    .iter()
                    .filter(|(x, y)| {
                        let fx = (x - x0) / xs;
                        let fy = (y - y0) / ys;
                        let in_x = if right { fx >= 1.0 - fw } else { fx <= fw };
                        let in_y = if upper { fy >= 1.0 - fh } else { fy <= fh };
                        in_x && in_y
                    })
                    .count();
                weight * inside
            })
            .sum()
    };
    corners
        .iter()
        .map(|(corner, right, upper)| (corner.clone(), hidden(*right, *upper)))
        .min_by_key(|c| c.1)
        .unwrap_or((SeriesLabelPosition::UpperRight, 0))
}

/// A legend that one panel of several carries for all (the same series,
/// colours and styles in every panel) moves to the panel where it hides
/// the fewest points, the first on a tie: the first panel's data may lie
/// where the legend goes (the tunnel exit's front camera peaks at its
/// right, under the legend's upper right corner).
fn place_legend(panels: &mut [Panel], size: (u32, u32)) {
    let labelled: Vec<usize> = (0..panels.len())
        .filter(|&k| panels[k].series.iter().any(|s| s.label.is_some()))
        .collect();
    let [from] = labelled[..] else {
        return;
    };
    let alike = |a: &Panel, b: &Panel| {
        a.series.len() == b.series.len()
            && a.series
                .iter()
                .zip(&b.series)
                .all(|(x, y)| x.colour == y.colour && x.style == y.style)
    };
    let source = &panels[from];
    let Some((to, _)) = panels
        .iter()
        .enumerate()
        .filter(|(_, p)| alike(source, p))
        .map(|(k, p)| (k, legend_placement(source, p, bounds(p), size).1))
        .min_by_key(|&(k, hidden)| (hidden, k != from))
    else {
        return;
    };
    if to != from {
        let labels: Vec<Option<String>> = panels[from]
            .series
            .iter_mut()
            .map(|s| s.label.take())
            .collect();
        for (s, label) in panels[to].series.iter_mut().zip(labels) {
            s.label = label;
        }
    }
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
            .position(legend_corner(panel, (x0, x1, y0, y1), area.dim_in_pixel()))
            .draw()
            .map_err(err)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn series(style: Style, label: &str, points: Vec<(f64, f64)>) -> Series {
        Series {
            label: Some(label.into()),
            colour: BLACK,
            style,
            points,
        }
    }

    /// A curve that peaks in the upper right with the settled marks there
    /// (as `M` against exposure on a sequence whose best is its longest
    /// bracket): the legend goes where the curve is low.
    #[test]
    fn the_legend_avoids_the_curves_peak_and_the_marks() {
        let curve: Vec<(f64, f64)> = (0..=100)
            .map(|i| {
                let x = f64::from(i) / 10.0;
                (x, x * x)
            })
            .collect();
        let marks = vec![(9.5, 90.0), (9.8, 96.0), (10.0, 100.0)];
        let panel = Panel {
            series: vec![
                series(Style::Line, "M", curve),
                series(Style::Marks, "gradient balanced (multi)", marks),
            ],
            ..Default::default()
        };
        let b = bounds(&panel);
        let corner = legend_corner(&panel, b, (640, 420));
        assert_eq!(corner, SeriesLabelPosition::UpperLeft);
        // Mirrored, the peak is upper left and the legend goes right.
        let mirrored = Panel {
            series: panel
                .series
                .iter()
                .map(|s| Series {
                    points: s.points.iter().map(|&(x, y)| (-x, y)).collect(),
                    ..s.clone()
                })
                .collect(),
            ..Default::default()
        };
        let b = bounds(&mirrored);
        assert_eq!(
            legend_corner(&mirrored, b, (640, 420)),
            SeriesLabelPosition::UpperRight
        );
    }

    /// A legend the first of several alike panels carries moves to the one
    /// where it hides the fewest points: here the first panel's data fill
    /// every corner, the third's none (a hump in the middle).
    #[test]
    fn a_shared_legend_moves_to_the_panel_where_it_hides_least() {
        let grid: Vec<(f64, f64)> = (0..=20)
            .flat_map(|i| (0..=20).map(move |j| (f64::from(i), f64::from(j))))
            .collect();
        let hump: Vec<(f64, f64)> = (0..=20)
            .map(|i| {
                let x = f64::from(i);
                (x, 20.0 * (-(x - 10.0).powi(2) / 8.0).exp())
            })
            .collect();
        let panel = |points: Vec<(f64, f64)>, label: bool| Panel {
            series: vec![Series {
                label: label.then(|| "M".to_string()),
                colour: BLACK,
                style: Style::LineDots,
                points,
            }],
            ..Default::default()
        };
        let mut panels = vec![
            panel(grid.clone(), true),
            panel(grid.clone(), false),
            panel(hump.clone(), false),
        ];
        place_legend(&mut panels, (400, 300));
        let labelled: Vec<bool> = panels.iter().map(|p| p.series[0].label.is_some()).collect();
        assert_eq!(labelled, [false, false, true]);
        // A panel whose series differ does not take it.
        let mut panels = vec![panel(grid, true), panel(hump, false)];
        panels[1].series[0].colour = RED;
        place_legend(&mut panels, (400, 300));
        assert!(panels[0].series[0].label.is_some());
        assert!(panels[1].series[0].label.is_none());
    }
}
