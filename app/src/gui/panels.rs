//! The window's panels: menu, controls, cameras, the big view, status bar.

use egui::{Color32, ColorImage, Rect, RichText, Sense, Stroke, StrokeKind, Ui, Vec2};
use rigview_core::exposure::ProbeEvent;
use rigview_core::pipeline::CameraOutput;
use rigview_core::source::StreamState;

use super::background::Pick;
use super::{camera_colour, RigviewApp};
use crate::settings::ViewMode;

/// The thumbnail of one camera: its metered image, with the pixels that
/// are not metered dimmed and tinted blue when `show_roi`.
pub fn thumbnail_image(cam: &CameraOutput, show_roi: bool) -> ColorImage {
    let (w, h) = (cam.thumb_width, cam.thumb_height);
    let mut rgb = Vec::with_capacity(w * h * 3);
    match (&cam.metered_mask, show_roi) {
        (Some(mask), true) => {
            for (&v, &m) in cam.thumb.iter().zip(mask) {
                if m {
                    rgb.extend_from_slice(&[v, v, v]);
                } else {
                    let d = v / 3;
                    rgb.extend_from_slice(&[d, d, d.saturating_add(60)]);
                }
            }
        }
        _ => {
            for &v in &cam.thumb {
                rgb.extend_from_slice(&[v, v, v]);
            }
        }
    }
    ColorImage::from_rgb([w, h], &rgb)
}

/// A path typed into `text` and its button; the path when the button is
/// pressed with one.
fn path_entry(
    ui: &mut Ui,
    text: &mut String,
    hint: &str,
    button: &str,
) -> Option<std::path::PathBuf> {
    ui.horizontal(|ui| {
        ui.add(
            egui::TextEdit::singleline(text)
                .hint_text(hint)
                .desired_width(280.0),
        );
        let pressed = ui.button(button).clicked();
        (pressed && !text.trim().is_empty()).then(|| std::path::PathBuf::from(text.trim()))
    })
    .inner
}

pub(super) fn menu_bar(app: &mut RigviewApp, ui: &mut Ui) {
    egui::Panel::top("menu").show(ui, |ui| {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("File", |ui| {
                if ui.button("Open calibration…").clicked() {
                    app.open_dialog(Pick::Calibration);
                    ui.close();
                }
                if ui.button("Open recording…").clicked() {
                    app.open_dialog(Pick::Recording);
                    ui.close();
                }
                ui.separator();
                ui.label("Open a calibration by path:");
                if let Some(p) =
                    path_entry(ui, &mut app.open_path, "rig or calibration file", "Open")
                {
                    app.open_calibration(&p);
                    ui.close();
                }
                ui.label("Open a recording by path:");
                if let Some(p) =
                    path_entry(ui, &mut app.recording_path, "recording (.mcap)", "Replay")
                {
                    app.open_recording(&p);
                    ui.close();
                }
                if !app.settings.window.recent.is_empty() {
                    ui.separator();
                    ui.label("Recent:");
                    let recent = app.settings.window.recent.clone();
                    for p in recent {
                        if ui.button(p.display().to_string()).clicked() {
                            app.open_calibration(&p);
                            ui.close();
                        }
                    }
                }
                ui.separator();
                if ui.button("Quit").clicked() {
                    app.close();
                    ui.close();
                }
            });
            ui.menu_button("View", |ui| {
                let mut view = app.settings.window.view;
                let picked = ui
                    .radio_value(&mut view, ViewMode::Surround, "Surround view (bird's eye)")
                    .changed()
                    | ui.radio_value(&mut view, ViewMode::Panorama, "Panorama (cylindrical)")
                        .changed()
                    | ui.radio_value(&mut view, ViewMode::Bowl, "Bowl (3-D, around the vehicle)")
                        .changed();
                if picked {
                    app.switch_view(view);
                    ui.close();
                }
                let w = &mut app.settings.window;
                ui.separator();
                let mut changed = ui
                    .checkbox(&mut w.show_matches, "Matches and overlaps on the panorama")
                    .changed();
                changed |= ui
                    .checkbox(&mut w.show_roi, "Metering ROI on the cameras")
                    .changed();
                changed |= ui
                    .checkbox(&mut w.show_patches, "Overlap patches on the cameras")
                    .changed();
                if changed {
                    app.window_changed();
                }
                ui.separator();
                let display = &mut app.settings.processing.display;
                if ui
                    .checkbox(
                        &mut display.compensate,
                        "Even out the seams (display gains)",
                    )
                    .on_hover_text(
                        "per-camera display gains from the measured overlap ratios; \
                         the cameras' exposures and the telemetry are not touched",
                    )
                    .changed()
                {
                    app.settings_changed();
                }
            });
            if app.is_loading() {
                ui.spinner();
                ui.label("building the view…");
            }
        });
    });
}

fn state_word(s: StreamState) -> (&'static str, Color32) {
    match s {
        StreamState::Streaming => ("streaming", Color32::from_rgb(110, 200, 110)),
        StreamState::Lost => ("LOST", Color32::from_rgb(240, 80, 70)),
        StreamState::Reconnecting => ("reconnecting", Color32::from_rgb(240, 180, 60)),
    }
}

pub(super) fn status_bar(app: &mut RigviewApp, ui: &mut Ui) {
    egui::Panel::bottom("status").show(ui, |ui| {
        ui.horizontal_wrapped(|ui| {
            let Some(s) = &app.session else {
                ui.colored_label(Color32::from_rgb(240, 80, 70), "no source");
                return;
            };
            let Some(st) = &app.status else {
                return;
            };
            let names = s.camera_names();
            let mut lost = 0;
            for (name, h) in names.iter().zip(&st.health) {
                let (word, colour) = state_word(h.state);
                lost += usize::from(h.state != StreamState::Streaming);
                ui.label(format!("{name}:"));
                ui.colored_label(colour, word);
                ui.label(format!("{:.1} fps", h.fps));
                ui.separator();
            }
            ui.label(format!("lost cameras: {lost}"));
            ui.separator();
            ui.label(format!("source: {}", s.source_name));
            ui.separator();
            ui.label(format!("{:.1} sets/s", st.set_rate_hz));
            ui.separator();
            ui.label(format!(
                "processed {} · dropped before processing {} · incomplete {}",
                st.processed, st.capture_queue.dropped, st.incomplete
            ));
            if let Some([_, l]) = st.display_latency.back() {
                ui.separator();
                ui.label(format!("latency {l:.0} ms"));
            }
            if st.stopped {
                ui.separator();
                ui.colored_label(Color32::from_rgb(240, 180, 60), "source ended");
            }
            if let Some(serving) = &s.serving {
                ui.separator();
                ui.label(serving.status_line());
            }
            if let Some(r) = app.recorder() {
                let stats = r.stats();
                ui.separator();
                let text = format!(
                    "recording: {} sets · recorder dropped {}",
                    stats.sets, stats.dropped
                );
                match &stats.stopped {
                    Some(why) => {
                        ui.colored_label(WARN, format!("{text} · STOPPED: {why}"));
                    }
                    None if stats.dropped > 0 => {
                        ui.colored_label(WARN, text);
                    }
                    None => {
                        ui.label(text);
                    }
                }
            }
        });
    });
}

const WARN: Color32 = Color32::from_rgb(240, 180, 60);

/// The replay's speeds: multiples of the recorded rate, and as fast as
/// possible.
const SPEEDS: [(Option<f64>, &str); 6] = [
    (Some(0.25), "0.25×"),
    (Some(0.5), "0.5×"),
    (Some(1.0), "1×"),
    (Some(2.0), "2×"),
    (Some(4.0), "4×"),
    (None, "as fast as possible"),
];

fn speed_name(speed: Option<f64>) -> String {
    SPEEDS.iter().find(|(s, _)| *s == speed).map_or_else(
        || format!("{:.2}×", speed.unwrap_or(0.0)),
        |(_, n)| (*n).to_owned(),
    )
}

/// The replay's controls under the menu: play and pause, steps, speed, and
/// a seek slider over the recording's time.
pub(super) fn replay_bar(app: &mut RigviewApp, ui: &mut Ui) {
    let Some(control) = app.replay().cloned() else {
        return;
    };
    egui::Panel::top("replay").show(ui, |ui| {
        ui.horizontal_wrapped(|ui| {
            let paused = control.is_paused();
            if ui.button(if paused { "Play" } else { "Pause" }).clicked() {
                control.set_paused(!paused);
            }
            let indexed = control.times().is_some();
            let back = ui.add_enabled(indexed, egui::Button::new("Step back"));
            if back.on_disabled_hover_text(NO_INDEX).clicked() {
                control.step(-1);
            }
            if ui.button("Step forward").clicked() {
                control.step(1);
            }
            let l = ui.label("Speed");
            let mut speed = control.speed();
            egui::ComboBox::from_id_salt("replay_speed")
                .selected_text(speed_name(speed))
                .show_ui(ui, |ui| {
                    for (s, name) in SPEEDS {
                        if ui.selectable_value(&mut speed, s, name).changed() {
                            control.set_speed(s);
                        }
                    }
                })
                .response
                .labelled_by(l.id);
            ui.separator();
            // The set the window shows (the source may be a few sets on).
            let shown = app
                .latest
                .as_ref()
                .and_then(|o| control.number_of(o.trigger))
                .or_else(|| control.shown());
            match control.times() {
                Some(times) if !times.is_empty() => {
                    let t0 = times[0];
                    let secs = |t: u64| t.saturating_sub(t0) as f64 * 1e-9;
                    let end = secs(times[times.len() - 1]);
                    let mut at = shown.and_then(|k| times.get(k)).map_or(0.0, |&t| secs(t));
                    let l = ui.label("time (s)");
                    let slider = ui
                        .add(egui::Slider::new(&mut at, 0.0..=end.max(1e-3)).show_value(true))
                        .labelled_by(l.id);
                    if slider.changed() {
                        // Whole nanoseconds from the recording's start.
                        let t = t0.saturating_add((at.max(0.0) * 1e9).round() as u64);
                        // Only a move to another set seeks (not the slider
                        // following the replay).
                        if let Some(k) = control.set_at(t).filter(|k| Some(*k) != shown) {
                            control.seek(k);
                        }
                    }
                    ui.label(format!(
                        "{} / {} sets",
                        shown.map_or(0, |k| k + 1),
                        times.len()
                    ));
                }
                _ => {
                    ui.add_enabled(false, egui::Slider::new(&mut 0.0, 0.0..=1.0))
                        .on_disabled_hover_text(NO_INDEX);
                    ui.colored_label(WARN, NO_INDEX);
                }
            }
            if control.at_end() {
                ui.separator();
                ui.colored_label(WARN, "end of the recording");
            }
        });
    });
}

/// Why a replay cannot seek.
const NO_INDEX: &str = "no index (the recording was not closed): it plays forward only; \
                        `rigview recording repair IN OUT` rewrites it with one to seek";

/// One camera: thumbnail with ROI and patches, histogram, readout.
#[allow(clippy::too_many_arguments)]
pub fn camera_card(
    ui: &mut Ui,
    name: &str,
    k: usize,
    cam: &CameraOutput,
    texture: Option<&egui::TextureHandle>,
    overlay: Option<&rigview_core::pipeline::Overlay>,
    show_patches: bool,
    width: f32,
) {
    ui.vertical(|ui| {
        ui.label(RichText::new(name).strong().color(camera_colour(k)));
        let aspect = cam.thumb_height as f32 / cam.thumb_width.max(1) as f32;
        let size = Vec2::new(width, width * aspect);
        let (rect, _) = ui.allocate_exact_size(size, Sense::hover());
        if let Some(t) = texture {
            egui::Image::new(egui::load::SizedTexture::new(t.id(), size)).paint_at(ui, rect);
        }
        if let (Some(o), true) = (overlay, show_patches) {
            let painter = ui.painter_at(rect);
            for p in o.patches.get(k).into_iter().flatten() {
                let other = o
                    .pairs
                    .get(p.pair)
                    .map_or(k, |&(i, j)| if i == k { j } else { i });
                let r = Rect::from_min_max(
                    rect.lerp_inside(Vec2::new(p.rect[0], p.rect[1])),
                    rect.lerp_inside(Vec2::new(p.rect[2], p.rect[3])),
                );
                painter.rect_stroke(
                    r,
                    0.0,
                    Stroke::new(1.0, camera_colour(other)),
                    StrokeKind::Inside,
                );
            }
        }
        histogram(ui, &cam.histogram, width);
        let (g, m) = cam
            .estimate
            .as_ref()
            .map_or((f64::NAN, f64::NAN), |e| (e.gamma_hat, e.m_current));
        ui.label(format!(
            "t {:.0} µs · gain {:.1} dB\nγ est. {g:.2} · M {m:.0} · mean {:.2}{}{}",
            cam.taken.shutter_us,
            cam.taken.gain_db,
            cam.mean,
            if cam.manual.is_some() {
                " · manual"
            } else {
                ""
            },
            probe_text(
                cam.last_probe,
                cam.last_probe_brighter,
                cam.estimate.as_ref().is_some_and(|e| e.declipped)
            )
        ));
    });
}

/// The latest probe, darker or `brighter`, for the camera's label: what
/// `M` did there, and whether the estimate read saturated pixels from a
/// darker frame of the scene (`read`: a darker probe's, or the one the law
/// left going brighter).
fn probe_text(p: Option<ProbeEvent>, brighter: bool, read: bool) -> String {
    let way = if brighter { "brighter" } else { "darker" };
    let outcome = match p {
        Some(ProbeEvent::Taken { gain }) => {
            format!("\nprobe {way}: M {:+.1} %, taken", gain * 100.0)
        }
        Some(ProbeEvent::Rejected { gain }) => {
            format!("\nprobe {way}: M {:+.1} %, stayed", gain * 100.0)
        }
        Some(ProbeEvent::Known { gain }) => {
            format!("\n{way} seen: M {:+.1} %, no probe", gain * 100.0)
        }
        Some(ProbeEvent::Abandoned) => format!("\nprobe {way}: abandoned"),
        Some(ProbeEvent::Sent { .. }) | None => String::new(),
    };
    if read {
        outcome + "\nsaturation read from a darker frame"
    } else {
        outcome
    }
}

fn histogram(ui: &mut Ui, bins: &[u32], width: f32) {
    let (rect, _) = ui.allocate_exact_size(Vec2::new(width, 40.0), Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 2.0, Color32::from_gray(25));
    let max = bins.iter().copied().max().unwrap_or(0).max(1) as f32;
    let n = bins.len().max(1) as f32;
    let bw = rect.width() / n;
    for (i, &c) in bins.iter().enumerate() {
        // Square-root scale, so that small bins stay visible.
        let hgt = (c as f32 / max).sqrt() * rect.height();
        let x = rect.left() + i as f32 * bw;
        let bar = Rect::from_min_max(
            egui::pos2(x, rect.bottom() - hgt),
            egui::pos2(x + bw.max(1.0), rect.bottom()),
        );
        painter.rect_filled(bar, 0.0, Color32::from_gray(200));
    }
}

pub(super) fn cameras_panel(app: &mut RigviewApp, ui: &mut Ui) {
    egui::Panel::bottom("cameras")
        .resizable(true)
        .default_size(300.0)
        .show(ui, |ui| {
            let Some(out) = app.latest.clone() else {
                ui.label("waiting for the first frame set…");
                return;
            };
            let names = app.camera_names();
            let n = out.cameras.len().max(1) as f32;
            let width = ((ui.available_width() - 12.0 * n) / n).clamp(80.0, 360.0);
            egui::ScrollArea::horizontal().show(ui, |ui| {
                ui.horizontal_top(|ui| {
                    for (k, cam) in out.cameras.iter().enumerate() {
                        let name = names.get(k).map_or("camera", String::as_str);
                        camera_card(
                            ui,
                            name,
                            k,
                            cam,
                            app.thumb_tex.get(k).and_then(Option::as_ref),
                            Some(&out.overlay),
                            app.settings.window.show_patches,
                            width,
                        );
                    }
                });
            });
        });
}

pub(super) fn central(app: &mut RigviewApp, ui: &mut Ui) {
    egui::CentralPanel::default_margins().show(ui, |ui| {
        let mode = app.settings.window.view;
        let panorama = mode == ViewMode::Panorama;
        let bowl = mode == ViewMode::Bowl;
        if panorama {
            panorama_bar(app, ui);
        }
        if bowl {
            super::bowl::bar(app, ui);
        }
        let what = match mode {
            ViewMode::Panorama => "panorama",
            ViewMode::Bowl => "bowl view",
            ViewMode::Surround => "surround view",
        };
        // The bowl on the GPU where the window can draw it; the pipeline
        // then composes no picture of it.
        let gpu = bowl && super::bowl_gpu_usable(app);
        // (Unless the remote view serves it: then the pipeline composes it
        // still, for the remote view.)
        let serving = app.session.as_ref().is_some_and(|s| s.serving.is_some());
        let gpu_draws = gpu && !serving;
        if app.settings.processing.bowl.gpu_draws != gpu_draws {
            app.settings.processing.bowl.gpu_draws = gpu_draws;
            app.settings_changed();
        }
        // The output shows the view the pipeline composed: while the
        // chosen one is being built, the other one goes on.
        let shown = app.latest.as_ref().map(|o| o.view);
        let picture = if gpu {
            let [w, h] = app.settings.processing.bowl.spec.size_px;
            Some((None, [w, h]))
        } else {
            app.canvas_tex
                .shown()
                .filter(|_| shown == Some(Some(mode.kind())))
                .map(|(id, size)| (Some(id), size))
        };
        let Some((id, [w, h])) = picture else {
            let msg = match &app.latest {
                _ if app.is_loading() => format!("building the {what}…"),
                Some(out) => match &out.compose_error {
                    Some(e) => format!("no {what}: {e}"),
                    None => format!("no {what}: open a calibration whose poses are in the vehicle frame (File, Open calibration)"),
                },
                None => "waiting for the first frame set…".to_owned(),
            };
            ui.centered_and_justified(|ui| ui.label(msg));
            return;
        };
        // The caption is a line of its own above the view, never over
        // its pixels.
        let renderer = match (bowl, gpu, app.gpu_bowl.times()) {
            (true, true, Some((upload, draw))) => {
                format!(" · drawn on the GPU (upload {upload:.1} ms, draw {draw:.1} ms)")
            }
            (true, true, None) => " · drawn on the GPU".to_owned(),
            (true, false, _) => " · composed on the CPU".to_owned(),
            _ => String::new(),
        };
        let caption = app.latest.as_ref().map(|out| {
            format!(
                "set {} · {} · {}{renderer}",
                out.trigger,
                out.settings.strategy.label(),
                out.settings.blend.name()
            )
        });
        let caption_h =
            ui.text_style_height(&egui::TextStyle::Body) + ui.spacing().item_spacing.y;
        let mut avail = ui.available_size() - Vec2::new(0.0, caption_h);
        let gap = ui.spacing().item_spacing.y;
        // The bird's-eye view beside the bowl: its own share of the width.
        let beside = app
            .beside_tex
            .shown()
            .filter(|_| bowl);
        let beside_share = beside.map(|(_, [bw, bh])| {
            let share = (avail.y * bw as f32 / bh as f32).min(0.4 * avail.x);
            avail.x -= share + gap;
            share
        });
        let layout = Layout::fit(avail, [w as f32, h as f32], panorama, gap);
        // The bowl as the window draws it: on the GPU, or the pipeline's
        // picture.
        let draw_bowl = |app: &RigviewApp, ui: &mut Ui, area: Rect| match (id, &app.latest) {
            (Some(id), _) => {
                egui::Image::new(egui::load::SizedTexture::new(id, area.size())).paint_at(ui, area);
            }
            (None, Some(out)) => app.gpu_bowl.paint(
                ui,
                area,
                out,
                app.settings.processing.bowl.viewpoint,
                app.settings.processing.blend,
            ),
            (None, None) => {}
        };
        ui.vertical_centered(|ui| {
            ui.add(egui::Label::new(caption.unwrap_or_default()).truncate());
            if let (Some((beside_id, [bw, bh])), Some(share)) = (beside, beside_share) {
                ui.horizontal_top(|ui| {
                    let (area, response) =
                        ui.allocate_exact_size(layout.size, Sense::click_and_drag());
                    draw_bowl(app, ui, area);
                    let scale = (share / bw as f32).min(avail.y / bh as f32);
                    let size = Vec2::new(bw as f32 * scale, bh as f32 * scale);
                    let (right, _) = ui.allocate_exact_size(size, Sense::hover());
                    egui::Image::new(egui::load::SizedTexture::new(beside_id, size))
                        .paint_at(ui, right);
                    super::bowl::interact(app, ui, &response);
                });
                return;
            }
            let sense = if bowl {
                Sense::click_and_drag()
            } else {
                Sense::hover()
            };
            let (area, response) = ui.allocate_exact_size(layout.size, sense);
            if bowl {
                draw_bowl(app, ui, area);
                super::bowl::interact(app, ui, &response);
                return;
            }
            let Some(id) = id else {
                return;
            };
            for piece in &layout.pieces {
                let rect = layout.rect(area, piece);
                let uv = Rect::from_min_max(
                    egui::pos2(piece.x0 / w as f32, 0.0),
                    egui::pos2(piece.x1 / w as f32, 1.0),
                );
                egui::Image::new(egui::load::SizedTexture::new(id, rect.size()))
                    .uv(uv)
                    .paint_at(ui, rect);
            }
            if panorama && app.settings.window.show_matches {
                if let Some(out) = &app.latest {
                    draw_matches(ui, area, &layout, out);
                }
            }
        });
    });
}

/// One run of canvas columns `x0..x1` shown at `at` (relative to the
/// view's area, screen points).
#[derive(Clone, Copy, Debug, PartialEq)]
struct Piece {
    x0: f32,
    x1: f32,
    at: Vec2,
}

/// How the view fills its panel: the canvas whole, or a panorama in two
/// rows when that shows it larger (a 360° strip in a panel of ordinary
/// shape leaves most of it empty): above, the front half (from the left
/// camera's heading through the front to the right's); below, the back
/// half (from the right's through the back to the left's). The rows meet
/// at the side cameras' headings, away from every overlap.
#[derive(Clone, Debug, PartialEq)]
struct Layout {
    /// Screen points per canvas pixel.
    scale: f32,
    /// The area the pieces take.
    size: Vec2,
    /// The height of a piece, points.
    row_h: f32,
    pieces: Vec<Piece>,
}

impl Layout {
    /// The layout of a `w`×`h` canvas in `avail` (two rows only for a
    /// panorama, `gap` points apart).
    fn fit(avail: Vec2, [w, h]: [f32; 2], panorama: bool, gap: f32) -> Self {
        let one = (avail.x / w).min(avail.y / h).max(0.05);
        let two = (avail.x / (w / 2.0))
            .min((avail.y - gap) / (2.0 * h))
            .max(0.05);
        if !panorama || two <= one * 1.1 {
            return Self {
                scale: one,
                size: Vec2::new(w * one, h * one),
                row_h: h * one,
                pieces: vec![Piece {
                    x0: 0.0,
                    x1: w,
                    at: Vec2::ZERO,
                }],
            };
        }
        let (q, row) = (w / 4.0, h * two + gap);
        Self {
            scale: two,
            size: Vec2::new(w / 2.0 * two, 2.0 * h * two + gap),
            row_h: h * two,
            pieces: vec![
                Piece {
                    x0: q,
                    x1: 3.0 * q,
                    at: Vec2::ZERO,
                },
                Piece {
                    x0: 3.0 * q,
                    x1: w,
                    at: Vec2::new(0.0, row),
                },
                Piece {
                    x0: 0.0,
                    x1: q,
                    at: Vec2::new(q * two, row),
                },
            ],
        }
    }

    /// The screen rectangle of `piece` in `area`.
    fn rect(&self, area: Rect, piece: &Piece) -> Rect {
        Rect::from_min_size(
            area.min + piece.at,
            Vec2::new((piece.x1 - piece.x0) * self.scale, self.row_h),
        )
    }

    /// The piece showing canvas column `x`, if any.
    fn piece(&self, x: f32) -> Option<usize> {
        self.pieces.iter().position(|p| (p.x0..p.x1).contains(&x))
    }

    /// Where canvas position `p` is shown in `area`, and in which piece.
    fn to_screen(&self, area: Rect, p: [f64; 2]) -> Option<(usize, egui::Pos2)> {
        let k = self.piece(p[0] as f32)?;
        let piece = &self.pieces[k];
        Some((
            k,
            area.min
                + piece.at
                + Vec2::new(
                    (p[0] as f32 - piece.x0) * self.scale,
                    p[1] as f32 * self.scale,
                ),
        ))
    }
}

/// The panorama's line above it: the overlay switch, Refine and Save rig,
/// and per overlap its matches, inliers, reprojection error (before and
/// after the latest refinement) and r_ij, or why it has none.
fn panorama_bar(app: &mut RigviewApp, ui: &mut Ui) {
    let out = app.latest.clone();
    let report = out.as_ref().and_then(|o| o.panorama.clone());
    ui.horizontal(|ui| {
        if ui
            .checkbox(
                &mut app.settings.window.show_matches,
                "matches and overlaps",
            )
            .changed()
        {
            app.window_changed();
        }
        let refining = report.as_ref().is_some_and(|r| r.refining);
        if ui
            .add_enabled(report.is_some() && !refining, egui::Button::new("Refine"))
            .on_hover_text(
                "refine the cameras' rotations from the current frame set, in rounds of \
                 matching on a cylinder with a floor, in the background (at most 3° each); \
                 the panorama is rebuilt with them",
            )
            .clicked()
        {
            app.refine();
        }
        if refining {
            ui.spinner();
            ui.label("refining…");
        }
        if ui
            .add_enabled(
                report.as_ref().is_some_and(|r| r.rig.is_some()),
                egui::Button::new("Save rig…"),
            )
            .on_hover_text("save the rig with the refined rotations")
            .clicked()
        {
            app.open_dialog(Pick::SaveRig);
        }
        if let Some(r) = &report {
            ui.label(match r.matched_trigger {
                Some(t) => format!(
                    "matched on set {t} in {:.0} ms · {} refinements",
                    r.match_ms, r.refinements
                ),
                None => "matching…".into(),
            });
            if let Some(p) = &r.problem {
                ui.colored_label(Color32::from_rgb(240, 80, 70), p);
            }
        }
    });
    let Some(out) = out else {
        return;
    };
    // The first line (when the matching ran) is in the bar above.
    let lines = crate::report::panorama::live_lines(&app.camera_names(), &out);
    ui.horizontal_wrapped(|ui| {
        for line in lines.iter().skip(1) {
            ui.label(RichText::new(line).small());
            ui.separator();
        }
    });
}

/// Each overlap's band outlined (its seam lies inside, where the cameras
/// hand over) and its matches: a line from camera i's corner to camera
/// j's, green for inliers and red for outliers (a band or match across two
/// pieces of the layout is not drawn).
fn draw_matches(ui: &Ui, area: Rect, layout: &Layout, out: &rigview_core::pipeline::Output) {
    let Some(report) = &out.panorama else {
        return;
    };
    let painter = ui.painter_at(area);
    let both =
        |a: [f64; 2], b: [f64; 2]| match (layout.to_screen(area, a), layout.to_screen(area, b)) {
            (Some((k, a)), Some((l, b))) if k == l => Some((a, b)),
            _ => None,
        };
    for p in &report.pairs {
        if let Some([x, y, w, h]) = p.band {
            let (x0, y0) = (x as f64, y as f64);
            // The band's last column, inside it.
            let far = [x0 + w as f64 - 0.5, y0 + h as f64];
            if let Some((a, b)) = both([x0, y0], far) {
                painter.rect_stroke(
                    Rect::from_min_max(a, b),
                    0.0,
                    Stroke::new(1.0, Color32::from_rgb(250, 210, 60)),
                    StrokeKind::Inside,
                );
            }
        }
        for m in &p.lines {
            let Some((a, b)) = both(m.at_i, m.at_j) else {
                continue;
            };
            let colour = if m.inlier {
                Color32::from_rgb(60, 230, 60)
            } else {
                Color32::from_rgb(240, 60, 50)
            };
            painter.line_segment([a, b], Stroke::new(1.0, colour));
            painter.circle_filled(a, 1.5, colour);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panorama_strip_takes_two_rows_where_they_show_it_larger() {
        // A 2048×270 strip in a panel of 760×560 points: one row would be
        // 0.37 points a pixel, two rows 0.74.
        let l = Layout::fit(Vec2::new(760.0, 560.0), [2048.0, 270.0], true, 4.0);
        assert_eq!(l.pieces.len(), 3);
        assert!((l.scale - 760.0 / 1024.0).abs() < 1e-4, "{l:?}");
        let area = Rect::from_min_size(egui::pos2(10.0, 20.0), l.size);
        // The front (the canvas's middle) is in the middle of the top row,
        // the back (its ends) in the middle of the bottom row, and the
        // right camera's heading starts the bottom row.
        let (k, front) = l.to_screen(area, [1024.0, 0.0]).unwrap();
        assert_eq!(k, 0);
        assert!((front.x - (10.0 + 380.0)).abs() < 1e-3 && (front.y - 20.0).abs() < 1e-3);
        let (_, back) = l.to_screen(area, [2047.9, 135.0]).unwrap();
        assert!((back.x - (10.0 + 380.0)).abs() < 0.1, "{back:?}");
        assert!((back.y - (20.0 + l.row_h + 4.0 + 135.0 * l.scale)).abs() < 1e-3);
        let (k, right) = l.to_screen(area, [1536.0, 0.0]).unwrap();
        assert_eq!((k, right.x), (1, 10.0));
        // The pieces cover the canvas once, and fit the area.
        let covered: f32 = l.pieces.iter().map(|p| p.x1 - p.x0).sum();
        assert!((covered - 2048.0).abs() < 1e-3);
        for p in &l.pieces {
            assert!(area.expand(1e-3).contains_rect(l.rect(area, p)));
        }
        // A panel as wide as the strip keeps one row, and so does the
        // surround view.
        let wide = Layout::fit(Vec2::new(2000.0, 300.0), [2048.0, 270.0], true, 4.0);
        assert_eq!(wide.pieces.len(), 1);
        let surround = Layout::fit(Vec2::new(760.0, 560.0), [2048.0, 270.0], false, 4.0);
        assert_eq!(surround.pieces.len(), 1);
    }

    #[test]
    fn the_probe_text_says_what_the_probe_did_and_whether_its_frame_is_read() {
        let stayed = Some(ProbeEvent::Rejected { gain: -0.027 });
        assert_eq!(
            probe_text(stayed, false, false),
            "\nprobe darker: M -2.7 %, stayed"
        );
        assert_eq!(
            probe_text(stayed, false, true),
            "\nprobe darker: M -2.7 %, stayed\nsaturation read from a darker frame"
        );
        assert_eq!(probe_text(None, false, false), "");
        assert_eq!(
            probe_text(Some(ProbeEvent::Taken { gain: 0.016 }), false, false),
            "\nprobe darker: M +1.6 %, taken"
        );
        // A brighter probe (a mostly dark camera's ladder) says so.
        assert_eq!(
            probe_text(Some(ProbeEvent::Taken { gain: 0.9 }), true, false),
            "\nprobe brighter: M +90.0 %, taken"
        );
    }
}
