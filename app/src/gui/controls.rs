//! The controls panel (left): recording, the exposure control's strategy,
//! law and parameters, a manual override per camera, the calibration in
//! use and the messages; each section its own function.

use egui::{Color32, Ui};
use rigview_core::exposure::{LawKind, ProbeParams, Simulation, ToneCurve};
use rigview_core::pipeline::{MeterRoi, ProcessingSettings, Strategy};
use rigview_core::surround::BlendMode;

use super::recording::recording_text;
use super::RigviewApp;
use crate::session::{RecordSpec, Session};

/// The Record button, its file, and the recording's progress.
fn record_controls(app: &mut RigviewApp, ui: &mut Ui) {
    ui.heading("Recording");
    if app.replay().is_some() {
        ui.label("replaying a recording");
        return;
    }
    let recording = app.record.current.is_some();
    ui.horizontal(|ui| {
        let l = ui.label("file");
        ui.add_enabled(
            !recording,
            egui::TextEdit::singleline(&mut app.record.path)
                .hint_text("a new .mcap file")
                .desired_width(170.0),
        )
        .labelled_by(l.id);
    });
    if recording {
        if ui.button("Stop recording").clicked() {
            app.stop_recording();
        }
    } else {
        let record = ui.add_enabled(
            app.session.is_some() && !app.record.path.trim().is_empty(),
            egui::Button::new("Record"),
        );
        if record.clicked() {
            let spec = RecordSpec::new(app.record.path.trim().into());
            app.start_recording(&spec);
        }
    }
    if let Some(rec) = &app.record.current {
        let stats = rec.recorder.stats();
        let text = recording_text(
            rec.started.elapsed(),
            stats.bytes,
            rec.rate_mb_s,
            stats.dropped,
        );
        match &stats.stopped {
            Some(why) => {
                ui.colored_label(
                    Color32::from_rgb(240, 90, 80),
                    format!("{text}\nSTOPPED: {why}"),
                );
            }
            None => {
                ui.colored_label(Color32::from_rgb(240, 90, 80), text);
            }
        }
    }
}

fn law_name(k: LawKind) -> &'static str {
    match k {
        LawKind::Linear => "linear (Eq. 3)",
        LawKind::Nonlinear => "nonlinear (Eq. 4)",
        LawKind::Fast => "fast (rigview)",
    }
}

/// A labelled number in a two-column grid; whether it changed.
fn drag_row(
    ui: &mut Ui,
    label: &str,
    value: &mut f64,
    range: std::ops::RangeInclusive<f64>,
    speed: f64,
) -> bool {
    let l = ui.label(label);
    let changed = ui
        .add(egui::DragValue::new(value).range(range).speed(speed))
        .labelled_by(l.id)
        .changed();
    ui.end_row();
    changed
}

pub(super) fn controls(app: &mut RigviewApp, ui: &mut Ui) {
    egui::Panel::left("controls")
        .resizable(true)
        .default_size(270.0)
        .show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| controls_inner(app, ui));
        });
}

/// The controls, section by section.
fn controls_inner(app: &mut RigviewApp, ui: &mut Ui) {
    record_controls(app, ui);
    ui.separator();
    ui.heading("Exposure control");
    let camera_auto = app.session.as_ref().is_some_and(|s| s.camera_auto);
    let p = &mut app.settings.processing;
    let mut changed = strategy_section(ui, p, camera_auto);
    ui.separator();
    changed |= law_section(ui, p);
    changed |= parameters_section(ui, p);
    if ui.button("Reset to defaults").clicked() {
        *p = Default::default();
        changed = true;
    }
    if changed {
        app.settings_changed();
    }
    if app.settings.window.view == crate::settings::ViewMode::Bowl {
        ui.separator();
        ui.heading("Bowl");
        super::bowl::parameters(app, ui);
    }
    ui.separator();
    ui.heading("Per-camera override");
    override_section(app, ui);
    ui.separator();
    ui.heading("Calibration");
    ui.label(&app.calibration);
    ui.separator();
    ui.heading("Messages");
    messages_section(app, ui);
}

/// The strategies (the cameras' own auto-exposure only where the cameras
/// have it); whether the choice changed.
fn strategy_section(ui: &mut Ui, p: &mut ProcessingSettings, camera_auto: bool) -> bool {
    let mut changed = false;
    for s in Strategy::ALL {
        let enabled = s != Strategy::CameraAuto || camera_auto;
        let r = ui.add_enabled(enabled, egui::RadioButton::new(p.strategy == s, s.label()));
        let r = r.on_disabled_hover_text(
            "cameras with their own auto-exposure only (live, or the simulated rig)",
        );
        if r.clicked() && p.strategy != s {
            p.strategy = s;
            changed = true;
        }
    }
    changed
}

/// The update law, the exposure simulation and probing; whether any
/// changed.
fn law_section(ui: &mut Ui, p: &mut ProcessingSettings) -> bool {
    let mut changed = false;
    let law_label = ui.label("Update law");
    egui::ComboBox::from_id_salt("law")
        .selected_text(law_name(p.controller.law.kind))
        .show_ui(ui, |ui| {
            for k in [LawKind::Linear, LawKind::Nonlinear, LawKind::Fast] {
                changed |= ui
                    .selectable_value(&mut p.controller.law.kind, k, law_name(k))
                    .changed();
            }
        })
        .response
        .labelled_by(law_label.id);
    let sim_label = ui.label("Exposure simulation");
    egui::ComboBox::from_id_salt("simulation")
        .selected_text(match p.controller.estimator.simulation {
            Simulation::Gamma => "γ-mapping (paper)",
            Simulation::ScaleClip => "scale-and-clip",
        })
        .show_ui(ui, |ui| {
            changed |= ui
                .selectable_value(
                    &mut p.controller.estimator.simulation,
                    Simulation::Gamma,
                    "γ-mapping (paper)",
                )
                .changed();
            changed |= ui
                .selectable_value(
                    &mut p.controller.estimator.simulation,
                    Simulation::ScaleClip,
                    "scale-and-clip",
                )
                .changed();
        })
        .response
        .labelled_by(sim_label.id);
    if p.controller.estimator.simulation == Simulation::ScaleClip {
        changed |= tone_curve_row(ui, &mut p.controller.estimator.tone_curve);
    }
    let mut probe = p.controller.probe.is_some();
    let r = ui
        .checkbox(&mut probe, "probe darker or brighter")
        .on_hover_text(
            "a settled camera with saturated pixels takes one frame 0.93 EV darker \
             (balanced cameras too, under scale-and-clip; not PID), one alone (PID \
             too) with half its pixels black up to three frames 1.5 EV brighter \
             each; it stays where M measures higher",
        );
    if r.changed() {
        p.controller.probe = probe.then(ProbeParams::default);
        changed = true;
    }
    changed
}

/// Whether the cameras' frames went through a tone curve (scale-and-clip
/// then simulates exposure under it), and its gamma; whether it changed.
/// A table from the settings file is shown, and kept until unticked.
fn tone_curve_row(ui: &mut Ui, curve: &mut Option<ToneCurve>) -> bool {
    let mut changed = false;
    let mut toned = curve.is_some();
    let r = ui
        .checkbox(&mut toned, "frames through a tone curve")
        .on_hover_text(
            "for cameras whose gamma or tone curve is on: scale-and-clip scales the \
             light under the curve, not the recorded values (a bracket sequence's \
             recovered response is used by itself)",
        );
    if r.changed() {
        *curve = toned.then_some(ToneCurve::Power(DEFAULT_DISPLAY_GAMMA));
        changed = true;
    }
    match curve {
        Some(ToneCurve::Power(g)) => {
            ui.horizontal(|ui| {
                let label = ui.label("display gamma");
                changed |= ui
                    .add(egui::DragValue::new(g).range(1.0..=5.0).speed(0.01))
                    .labelled_by(label.id)
                    .changed();
            });
        }
        Some(ToneCurve::Table(t)) => {
            ui.label(format!("a table of {} values (settings file)", t.len()));
        }
        None => {}
    }
    changed
}

/// The curve the tone-curve check box starts with: an sRGB-like gamma.
const DEFAULT_DISPLAY_GAMMA: f64 = 2.2;

/// The law's parameters, metering, blending and the manual level; whether
/// any changed.
fn parameters_section(ui: &mut Ui, p: &mut ProcessingSettings) -> bool {
    let mut changed = false;
    egui::Grid::new("params").num_columns(2).show(ui, |ui| {
        let m = &mut p.controller.estimator.metric;
        changed |= drag_row(ui, "δ", &mut m.delta, 0.001..=0.5, 0.001);
        changed |= drag_row(ui, "λ", &mut m.lambda, 1.0..=1e5, 10.0);
        let law = &mut p.controller.law;
        changed |= drag_row(ui, "Kp", &mut law.kp, 0.01..=20.0, 0.01);
        changed |= drag_row(ui, "d", &mut law.d, 0.01..=100.0, 0.01);
        let mut ms = p.controller.split.max_shutter_us / 1000.0;
        if drag_row(ui, "max shutter (ms)", &mut ms, 0.01..=1000.0, 0.1) {
            p.controller.split.max_shutter_us = ms * 1000.0;
            changed = true;
        }
        ui.label("metering size");
        ui.horizontal(|ui| {
            let w = ui.label("w");
            changed |= ui
                .add(egui::DragValue::new(&mut p.metering.target_width).range(16..=1288))
                .labelled_by(w.id)
                .changed();
            let l = ui.label("h");
            changed |= ui
                .add(egui::DragValue::new(&mut p.metering.target_height).range(12..=964))
                .labelled_by(l.id)
                .changed();
        });
        ui.end_row();
        let l = ui.label("metering");
        egui::ComboBox::from_id_salt("roi")
            .selected_text(match p.roi {
                MeterRoi::Ground => "ground only",
                MeterRoi::Full => "whole frames",
            })
            .show_ui(ui, |ui| {
                changed |= ui
                    .selectable_value(&mut p.roi, MeterRoi::Ground, "ground only")
                    .changed();
                changed |= ui
                    .selectable_value(&mut p.roi, MeterRoi::Full, "whole frames")
                    .changed();
            })
            .response
            .labelled_by(l.id);
        ui.end_row();
        let l = ui.label("blending");
        egui::ComboBox::from_id_salt("blend")
            .selected_text(p.blend.name())
            .show_ui(ui, |ui| {
                for b in BlendMode::ALL {
                    changed |= ui.selectable_value(&mut p.blend, b, b.name()).changed();
                }
            })
            .response
            .labelled_by(l.id);
        ui.end_row();
        if p.strategy == Strategy::Manual {
            changed |= drag_row(
                ui,
                "manual E (µs at 0 dB)",
                &mut p.controller.fixed_exposure,
                1.0..=1e7,
                10.0,
            );
        }
    });
    changed
}

/// A manual exposure per camera, sent as it changes.
fn override_section(app: &mut RigviewApp, ui: &mut Ui) {
    let names: Vec<String> = app
        .session
        .as_ref()
        .map(Session::camera_names)
        .unwrap_or_default();
    let mut sends = Vec::new();
    egui::Grid::new("manual").num_columns(2).show(ui, |ui| {
        for (k, name) in names.iter().enumerate() {
            let Some((on, level)) = app.manual.get_mut(k) else {
                continue;
            };
            let check = ui.checkbox(on, name.as_str());
            let toggled = check.changed();
            let moved = ui
                .add_enabled(
                    *on,
                    egui::DragValue::new(level)
                        .range(1.0..=1e7)
                        .speed(10.0)
                        .suffix(" E"),
                )
                .labelled_by(check.id)
                .changed();
            if toggled || (moved && *on) {
                sends.push((k, on.then_some(*level)));
            }
            ui.end_row();
        }
    });
    for (k, e) in sends {
        app.set_manual(k, e);
    }
}

/// The messages, newest first, each dismissable.
fn messages_section(app: &mut RigviewApp, ui: &mut Ui) {
    let mut dismiss = None;
    for (k, m) in app.messages.list().iter().enumerate().rev() {
        ui.horizontal_wrapped(|ui| {
            if m.error {
                ui.colored_label(Color32::from_rgb(240, 90, 80), &m.text);
            } else {
                ui.label(&m.text);
            }
            if ui.small_button("×").clicked() {
                dismiss = Some(k);
            }
        });
    }
    if let Some(k) = dismiss {
        app.messages.dismiss(k);
    }
}
