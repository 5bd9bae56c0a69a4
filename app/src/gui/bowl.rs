//! The bowl view in the window: the viewpoint buttons over it, the orbit
//! (drag to turn, scroll to zoom, double-click to go back to the preset),
//! smooth changes of viewpoint, the rear view while reversing, and the
//! bowl's parameters.
//!
//! Each new viewpoint goes to the pipeline as a setting; the pipeline
//! builds the bowl from it in the background and shows it from a later
//! set, so the picture follows the orbit a build behind (a build takes
//! about a tenth of a second at 1280 × 800 on this machine's cores).

use std::time::{Duration, Instant};

use egui::{Response, Ui};
use rigview_core::bowl::{Footprint, Viewpoint, PRESETS};

use super::RigviewApp;
use crate::settings::BowlRenderer;

/// How long a change of viewpoint takes.
const ANIMATION: Duration = Duration::from_millis(700);
/// Degrees of orbit per point dragged.
const DEG_PER_POINT: f64 = 0.3;

/// The window's state of the bowl view.
#[derive(Debug, Default)]
pub(super) struct BowlState {
    /// A change of viewpoint under way: from, to, since.
    animation: Option<(Viewpoint, Viewpoint, Instant)>,
    /// The preset chosen last, which a double-click goes back to.
    home: Option<Viewpoint>,
    /// The vehicle reverses (the operator's command: there is no vehicle
    /// bus here).
    reversing: bool,
    /// The viewpoint before the rear view took over, to go back to.
    before_reversing: Option<Viewpoint>,
}

/// Moves the viewpoint to `to`, smoothly.
fn go_to(app: &mut RigviewApp, to: Viewpoint) {
    let from = app.settings.processing.bowl.viewpoint;
    app.bowl.animation = Some((from, to, Instant::now()));
}

/// Sets the viewpoint now (an orbit step, or an animation's frame).
fn set_viewpoint(app: &mut RigviewApp, v: Viewpoint) {
    if app.settings.processing.bowl.viewpoint != v {
        app.settings.processing.bowl.viewpoint = v;
        app.settings_changed();
    }
}

/// Advances a change of viewpoint; call once per window frame.
pub(super) fn step(app: &mut RigviewApp, ctx: &egui::Context) {
    let Some((from, to, since)) = app.bowl.animation else {
        return;
    };
    let s = since.elapsed().as_secs_f64() / ANIMATION.as_secs_f64();
    set_viewpoint(app, from.towards(&to, s));
    if s >= 1.0 {
        app.bowl.animation = None;
    } else {
        ctx.request_repaint_after(Duration::from_millis(30));
    }
}

/// Tells the window whether the vehicle reverses: with the rule on, the
/// rear view while it does, and the viewpoint from before afterwards.
pub(super) fn set_reversing(app: &mut RigviewApp, on: bool) {
    if app.bowl.reversing == on {
        return;
    }
    app.bowl.reversing = on;
    if !app.settings.window.rear_when_reversing {
        return;
    }
    if on {
        app.bowl.before_reversing = Some(app.settings.processing.bowl.viewpoint);
        if let Ok(rear) = Viewpoint::preset("rear") {
            go_to(app, rear);
        }
    } else if let Some(v) = app.bowl.before_reversing.take() {
        go_to(app, v);
    }
}

/// The bar over the bowl: a button per preset, the reversing command and
/// rule, and what the mouse does.
pub(super) fn bar(app: &mut RigviewApp, ui: &mut Ui) {
    ui.horizontal_wrapped(|ui| {
        ui.label("Viewpoint:");
        for name in PRESETS {
            if ui.button(name).clicked() {
                if let Ok(v) = Viewpoint::preset(name) {
                    app.bowl.home = Some(v);
                    go_to(app, v);
                }
            }
        }
        ui.separator();
        let mut reversing = app.bowl.reversing;
        if ui
            .toggle_value(&mut reversing, "Reversing (R)")
            .on_hover_text("The vehicle reverses: with the rule on, the rear view until it stops")
            .changed()
        {
            set_reversing(app, reversing);
        }
        if ui
            .checkbox(
                &mut app.settings.window.rear_when_reversing,
                "Rear view when reversing",
            )
            .changed()
        {
            app.window_changed();
        }
        if ui
            .checkbox(
                &mut app.settings.processing.bowl.beside,
                "Bird's-eye view beside",
            )
            .changed()
        {
            app.settings_changed();
        }
        let gl = app
            .gpu_bowl
            .gl_renderer
            .clone()
            .unwrap_or_else(|| "no OpenGL".into());
        let before = app.settings.window.bowl_renderer;
        egui::ComboBox::from_label("drawn by")
            .selected_text(before.label())
            .show_ui(ui, |ui| {
                for r in BowlRenderer::ALL {
                    ui.selectable_value(&mut app.settings.window.bowl_renderer, r, r.label());
                }
            })
            .response
            .on_hover_text(format!(
                "GPU: a new viewpoint at once; CPU: the pipeline composes the bowl and rebuilds it for a new viewpoint; auto: the GPU unless the OpenGL is a software renderer (this window's: {gl})"
            ));
        if app.settings.window.bowl_renderer != before {
            app.window_changed();
        }
        ui.separator();
        if let Some(why) = app.gpu_bowl.failure() {
            ui.label(format!("on the CPU: {why}"));
        } else if let Some(why) = app
            .latest
            .as_ref()
            .filter(|_| super::bowl_gpu_chosen(app) && app.gpu_bowl.available)
            .and_then(|o| super::bowl_gpu::unsuited(o))
        {
            ui.label(format!("on the CPU: {why}"));
        }
        let building = app
            .latest
            .as_ref()
            .and_then(|o| o.bowl)
            .is_some_and(|(_, b)| b);
        let gpu = app.settings.processing.bowl.gpu_draws;
        ui.label(if building && !gpu {
            "building the new viewpoint…"
        } else {
            "drag: orbit · scroll: zoom · double-click: back to the preset"
        });
    });
    if ui.input(|i| i.key_pressed(egui::Key::R)) && !ui.ctx().egui_wants_keyboard_input() {
        let on = !app.bowl.reversing;
        set_reversing(app, on);
    }
}

/// The orbit on the bowl's picture: drag, scroll and double-click.
pub(super) fn interact(app: &mut RigviewApp, ui: &Ui, response: &Response) {
    let v = app.settings.processing.bowl.viewpoint;
    if response.double_clicked() {
        go_to(app, app.bowl.home.unwrap_or_default());
        return;
    }
    let drag = response.drag_delta();
    let scroll = if response.hovered() {
        ui.input(|i| i.smooth_scroll_delta.y)
    } else {
        0.0
    };
    if drag != egui::Vec2::ZERO || scroll != 0.0 {
        app.bowl.animation = None;
        let orbited = v.orbited(
            -f64::from(drag.x) * DEG_PER_POINT,
            f64::from(drag.y) * DEG_PER_POINT,
            (f64::from(scroll) / 200.0).exp(),
        );
        // The eye stays over the bowl: within 0.9 of its radius,
        // horizontally.
        let spec = &app.settings.processing.bowl.spec;
        let level = orbited.pitch_deg.to_radians().cos().max(0.05);
        let keep = Viewpoint {
            distance_m: orbited.distance_m.min(0.9 * spec.radius_m / level),
            ..orbited
        };
        set_viewpoint(app, keep);
    }
}

/// The bowl's parameters, in the controls panel.
pub(super) fn parameters(app: &mut RigviewApp, ui: &mut Ui) {
    let spec = &mut app.settings.processing.bowl.spec;
    let mut changed = false;
    let mut row = |ui: &mut Ui, label: &str, v: &mut f64, range: std::ops::RangeInclusive<f64>| {
        ui.horizontal(|ui| {
            ui.label(label);
            changed |= ui
                .add(egui::DragValue::new(v).speed(0.05).range(range))
                .changed();
        });
    };
    let flat_max = spec.radius_m - 0.5;
    row(ui, "flat ground (m)", &mut spec.flat_m, 0.0..=flat_max);
    let radius_min = spec.flat_m + 0.5;
    row(ui, "bowl radius (m)", &mut spec.radius_m, radius_min..=60.0);
    row(ui, "wall height (m)", &mut spec.wall_height_m, 0.0..=20.0);
    row(ui, "wall steepness", &mut spec.steepness, 0.5..=8.0);
    ui.horizontal(|ui| {
        ui.label("footprint");
        changed |= ui
            .radio_value(&mut spec.footprint, Footprint::RoundedRectangle, "rounded")
            .changed();
        changed |= ui
            .radio_value(&mut spec.footprint, Footprint::Round, "round")
            .changed();
    });
    if changed {
        app.settings_changed();
    }
}
