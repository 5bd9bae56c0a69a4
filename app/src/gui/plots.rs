//! The live plots: per camera exposure time, gain, E, γ̂ and M; per
//! overlap log2 r_ij; frame-set rate and end-to-end latency; the M(γ) curve
//! of a selected camera with its anchors and fitted polynomial. Each plot
//! scrolls over the last `plot_seconds` of the telemetry history.

use egui::{Color32, Ui};
use egui_plot::{Legend, Line, Plot, PlotPoints, Points, VLine};
use rigview_core::exposure::Simulation;
use rigview_core::pipeline::{Output, StageTimes, Telemetry, TelemetryRow};

use super::{camera_colour, RigviewApp};

/// The series of one plot: a name and its points.
pub type Series = Vec<(String, Vec<[f64; 2]>)>;

/// The span over which the frame-set rate is counted, s.
pub const RATE_WINDOW_S: f64 = 1.0;

/// The frame-set rate at each of `times` (seconds, ascending: one per set),
/// over the sets within the `window_s` up to it: the intervals between
/// them per second of their span. There is no rate until a whole window
/// has passed since the first set, so the first sets, which arrive in a
/// burst, never make a rate of their own from the microseconds between
/// them.
pub fn set_rate(times: &[f64], window_s: f64) -> Vec<[f64; 2]> {
    let Some(&first) = times.first() else {
        return Vec::new();
    };
    let mut oldest = 0;
    let mut rates = Vec::new();
    for (k, &t) in times.iter().enumerate() {
        while times.get(oldest).is_some_and(|&o| o <= t - window_s) {
            oldest += 1;
        }
        let span = times.get(oldest).map_or(0.0, |&o| t - o);
        if t - first >= window_s && span > 0.0 {
            rates.push([t, (k - oldest) as f64 / span]);
        }
    }
    rates
}

/// The rows within `seconds` of the newest.
fn recent(t: &Telemetry, seconds: f64) -> impl Iterator<Item = &TelemetryRow> {
    let t_end = t.last().map_or(0.0, |r| r.time_s);
    t.rows().iter().filter(move |r| r.time_s >= t_end - seconds)
}

/// Per camera, `value(row, camera)` over the rows within `seconds` of the
/// newest.
pub fn camera_series(
    t: &Telemetry,
    seconds: f64,
    value: impl Fn(&TelemetryRow, usize) -> Option<f64>,
) -> Series {
    t.camera_names()
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let pts = recent(t, seconds)
                .filter_map(|r| value(r, k).filter(|v| v.is_finite()).map(|v| [r.time_s, v]))
                .collect();
            (name.clone(), pts)
        })
        .collect()
}

/// Per overlap, its log2 r_ij.
pub fn pair_series(t: &Telemetry, seconds: f64) -> Series {
    t.pair_names()
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let pts = recent(t, seconds)
                .filter_map(|r| r.log2_r.get(k).copied().flatten().map(|v| [r.time_s, v]))
                .collect();
            (name.clone(), pts)
        })
        .collect()
}

fn pair_colour(k: usize) -> Color32 {
    const C: [Color32; 4] = [
        Color32::from_rgb(240, 120, 160),
        Color32::from_rgb(120, 220, 230),
        Color32::from_rgb(200, 200, 90),
        Color32::from_rgb(170, 140, 250),
    ];
    C[k % C.len()]
}

fn plot(ui: &mut Ui, id: &str, title: &str, series: &Series, colour: impl Fn(usize) -> Color32) {
    plot_with(ui, Plot::new(id), title, series, colour);
}

fn plot_with(
    ui: &mut Ui,
    plot: Plot<'_>,
    title: &str,
    series: &Series,
    colour: impl Fn(usize) -> Color32,
) {
    ui.label(title);
    plot.height(110.0)
        .legend(Legend::default())
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
        .show(ui, |p| {
            for (k, (name, pts)) in series.iter().enumerate() {
                p.line(
                    Line::new(name.as_str(), PlotPoints::from(pts.clone()))
                        .color(colour(k))
                        .width(1.5),
                );
            }
        });
}

/// The M(γ) or M(s) curve of one camera's newest estimate: the anchors,
/// the fitted polynomial and γ̂ or ŝ.
pub fn curve_plot(ui: &mut Ui, out: Option<&Output>, camera: usize, name: &str) {
    let est = out
        .and_then(|o| o.cameras.get(camera))
        .and_then(|c| c.estimate.as_ref());
    ui.label(match est.map(|e| e.simulation) {
        Some(Simulation::ScaleClip) => {
            format!("M(s) of {name} (s: exposure scale): anchors, 5th-order fit, estimate")
        }
        _ => format!("M(γ) of {name}: anchors, 5th-order fit, estimate"),
    });
    Plot::new("curve")
        .height(150.0)
        .legend(Legend::default())
        .allow_drag(false)
        .allow_zoom(false)
        .allow_scroll(false)
        .show(ui, |p| {
            let Some(e) = est else {
                return;
            };
            let anchors: Vec<[f64; 2]> = e.anchors.iter().map(|a| [a.x, a.m]).collect();
            p.points(
                Points::new("anchors", PlotPoints::from(anchors))
                    .radius(4.0)
                    .color(Color32::from_rgb(250, 200, 80)),
            );
            p.line(
                Line::new("fit", PlotPoints::from(e.poly.sample(100)))
                    .color(Color32::from_rgb(90, 170, 240))
                    .width(1.5),
            );
            p.vline(
                VLine::new(format!("estimate {:.2}", e.x_hat), e.x_hat)
                    .color(Color32::from_rgb(240, 90, 80)),
            );
        });
}

/// The exposure plots over the last `secs` of `t`: per camera exposure
/// time, gain, log2 E, γ̂ and M, and per overlap log2 r_ij.
pub fn exposure_plots(ui: &mut Ui, t: &Telemetry, secs: f64) {
    let shutter = camera_series(t, secs, |r, k| r.cameras.get(k).map(|c| c.shutter_us));
    let gain = camera_series(t, secs, |r, k| r.cameras.get(k).map(|c| c.gain_db));
    let exposure = camera_series(t, secs, |r, k| {
        r.cameras
            .get(k)
            .map(|c| c.exposure)
            .filter(|e| *e > 0.0)
            .map(f64::log2)
    });
    let gamma = camera_series(t, secs, |r, k| r.cameras.get(k).and_then(|c| c.gamma_hat));
    let m = camera_series(t, secs, |r, k| r.cameras.get(k).and_then(|c| c.m));
    let pairs = pair_series(t, secs);
    plot(ui, "shutter", "exposure time (µs)", &shutter, camera_colour);
    plot(ui, "gain", "gain (dB)", &gain, camera_colour);
    plot(
        ui,
        "exposure",
        "log2 E (E = t · 10^(gain/20))",
        &exposure,
        camera_colour,
    );
    plot(
        ui,
        "gamma",
        "γ estimate (γ-equivalent)",
        &gamma,
        camera_colour,
    );
    plot(ui, "m", "gradient information M", &m, camera_colour);
    plot(ui, "pairs", "log2 r_ij per overlap", &pairs, pair_colour);
}

/// Per camera, log2 of the exposure commanded after each set (a replay's
/// open-loop commands).
pub fn command_series(t: &Telemetry, secs: f64) -> Series {
    camera_series(t, secs, |r, k| {
        r.cameras
            .get(k)
            .and_then(|c| c.command)
            .filter(|e| *e > 0.0)
            .map(f64::log2)
    })
}

pub(super) fn plot_panel(app: &mut RigviewApp, ui: &mut Ui) {
    egui::Panel::right("plots")
        .resizable(true)
        .default_size(430.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| plots_inner(app, ui));
        });
}

fn plots_inner(app: &mut RigviewApp, ui: &mut Ui) {
    if app.session.is_none() {
        ui.label("no source");
        return;
    }
    ui.horizontal(|ui| {
        let l = ui.label("history (s)");
        if ui
            .add(egui::DragValue::new(&mut app.settings.window.plot_seconds).range(1.0..=600.0))
            .labelled_by(l.id)
            .changed()
        {
            app.window_changed();
        }
    });
    let secs = app.settings.window.plot_seconds;
    let Some(s) = &app.session else {
        return;
    };
    let (rate, stages): (Series, Series) = {
        let t = s.pipeline.telemetry();
        exposure_plots(ui, &t, secs);
        if s.replay.is_some() {
            // Open loop: the frames keep their recorded exposure (log2 E
            // above); these are the commands the strategy would have sent.
            let commands = command_series(&t, secs);
            plot(
                ui,
                "commands",
                "log2 E the strategy would command (not applied)",
                &commands,
                camera_colour,
            );
        }
        let rows: Vec<_> = recent(&t, secs).collect();
        let times: Vec<f64> = t.rows().iter().map(|r| r.time_s).collect();
        let t_start = rows.first().map_or(f64::INFINITY, |r| r.time_s);
        let stages = StageTimes::NAMES
            .iter()
            .enumerate()
            .map(|(k, name)| {
                (
                    (*name).to_owned(),
                    rows.iter()
                        .map(|r| [r.time_s, r.times.values()[k]])
                        .collect(),
                )
            })
            .collect();
        let rate = vec![(
            "sets/s".to_owned(),
            set_rate(&times, RATE_WINDOW_S)
                .into_iter()
                .filter(|p| p[0] >= t_start)
                .collect(),
        )];
        (rate, stages)
    };
    let latency: Series = vec![(
        "set ready to displayed (ms)".to_owned(),
        app.status
            .as_ref()
            .map(|st| st.display_latency.iter().copied().collect())
            .unwrap_or_default(),
    )];
    // From 0, so that the rate's small changes look small.
    plot_with(
        ui,
        Plot::new("rate").include_y(0.0),
        "frame-set rate (sets/s)",
        &rate,
        |_| Color32::LIGHT_GREEN,
    );
    plot(ui, "latency", "end-to-end latency (ms)", &latency, |_| {
        Color32::LIGHT_RED
    });
    plot(ui, "stages", "time per stage (ms)", &stages, camera_colour);
    let names = s.camera_names();
    let sel = &mut app.settings.window.selected_camera;
    if *sel >= names.len() {
        *sel = 0;
    }
    let mut changed = false;
    let l = ui.label("camera of the M curve");
    egui::ComboBox::from_id_salt("curve_camera")
        .selected_text(names.get(*sel).map_or("camera", String::as_str))
        .show_ui(ui, |ui| {
            for (k, n) in names.iter().enumerate() {
                changed |= ui.selectable_value(sel, k, n.as_str()).changed();
            }
        })
        .response
        .labelled_by(l.id);
    let sel = *sel;
    if changed {
        app.window_changed();
    }
    curve_plot(
        ui,
        app.latest.as_deref(),
        sel,
        names.get(sel).map_or("camera", String::as_str),
    );
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_leaves_out_the_start_up_burst() {
        // Ten sets within a millisecond, then one every 50 ms for 3 s, each
        // up to 5 ms late.
        let late = |k: u32| f64::from(k * 7 % 11) * 0.0005;
        let mut times: Vec<f64> = (0..10).map(|k| f64::from(k) * 1e-4).collect();
        times.extend((1..=60).map(|k| 0.001 + f64::from(k) * 0.05 + late(k)));
        let rates = set_rate(&times, 1.0);
        assert!(rates.len() > 35, "{rates:?}");
        // Nothing before a whole window has passed, and then 20/s within
        // the lateness.
        assert!(rates.iter().all(|p| p[0] >= 1.0), "{rates:?}");
        assert!(
            rates.iter().all(|p| (19.5..=20.5).contains(&p[1])),
            "{rates:?}"
        );
    }

    #[test]
    fn the_rate_counts_the_sets_of_the_last_window() {
        // 10 sets/s for 2 s, then 5 sets/s.
        let mut times: Vec<f64> = (0..20).map(|k| f64::from(k) * 0.1).collect();
        times.extend((0..20).map(|k| 2.0 + f64::from(k) * 0.2));
        let rates = set_rate(&times, 1.0);
        let at = |t: f64| {
            rates
                .iter()
                .find(|p| (p[0] - t).abs() < 1e-9)
                .map(|p| p[1])
                .unwrap()
        };
        assert!((at(1.5) - 10.0).abs() < 1e-9, "{rates:?}");
        assert!((at(5.0) - 5.0).abs() < 1e-9, "{rates:?}");
        assert!(set_rate(&[], 1.0).is_empty());
        assert!(set_rate(&[0.0, 0.5], 1.0).is_empty());
        // A set alone in its window has no rate.
        assert!(set_rate(&[0.0, 3.0], 1.0).is_empty());
    }
}
