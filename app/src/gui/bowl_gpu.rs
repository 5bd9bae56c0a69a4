//! The bowl drawn by the window on the GPU ([`super::bowl_gl`] through
//! eframe's glow paint callback): a new viewpoint is a new matrix, so the
//! orbit follows the mouse at the display's rate with no rebuild; each new
//! frame set is uploaded once. While it draws, the pipeline composes no
//! picture of the bowl ([`rigview_core::pipeline::BowlSettings::gpu_draws`]).
//!
//! It steps aside for the CPU's picture where it cannot draw: no GL
//! context (the UI tests' renderer), frames that are not 8-bit grey or
//! RGB (Bayer mosaics and 12- or 16-bit frames compose on the CPU), more
//! than four cameras, a shader or framebuffer the driver refuses, or the
//! operator's choice (View → Draw the bowl on the GPU).

use std::sync::{Arc, Mutex};
use std::time::Instant;

use eframe::egui_glow;
use eframe::glow;
use rigview_core::bowl::{SurfaceMesh, VehicleTriangles, Viewpoint, MAX_GPU_CAMERAS};
use rigview_core::image::PixelFormat;
use rigview_core::pipeline::Output;
use rigview_core::surround::BlendMode;

use super::bowl_gl::{BowlGl, Shot, TextureFrame};

/// The window's GPU bowl.
#[derive(Debug, Default)]
pub(super) struct GpuBowl {
    /// The window has a glow context (eframe's glow back end).
    pub available: bool,
    /// The GL's renderer (`GL_RENDERER`), asked once.
    pub gl_renderer: Option<String>,
    shared: Arc<Mutex<Shared>>,
}

/// What a picture shows: the set, viewpoint, size, blend and gains.
type PictureKey = (u64, Viewpoint, (usize, usize), BlendMode, Vec<[f32; 2]>);

/// What the paint callback keeps between frames.
#[derive(Debug, Default)]
struct Shared {
    renderer: Option<BowlGl>,
    /// Why it cannot draw (the CPU's picture is shown instead).
    failed: Option<String>,
    /// The surface it holds.
    mesh: Option<Arc<SurfaceMesh>>,
    /// The set whose frames it holds.
    uploaded: Option<u64>,
    /// Milliseconds of the latest upload and draw (the calls' time on the
    /// UI thread).
    upload_ms: f32,
    draw_ms: f32,
    /// What the last picture showed: the set, viewpoint, size, blend and
    /// gains (the same again is only copied into the window).
    last: Option<PictureKey>,
    /// Every picture drawn: when, and its upload (of a new set; 0 for the
    /// same set again) and draw times, ms (for the run's summary).
    drawn: Vec<(Instant, f32, f32)>,
}

/// Whether `GL_RENDERER` names a software rasteriser (Mesa's llvmpipe,
/// softpipe or swrast, or Microsoft's WARP).
pub(super) fn is_software(renderer: &str) -> bool {
    let r = renderer.to_ascii_lowercase();
    ["llvmpipe", "softpipe", "swrast", "software", "warp"]
        .iter()
        .any(|s| r.contains(s))
}

/// Why `out`'s bowl cannot go to the GPU, if it cannot.
pub(super) fn unsuited(out: &Output) -> Option<String> {
    let view = out.bowl_view.as_ref()?;
    if let Err(e) = view.plan().mesh() {
        return Some(e.to_owned());
    }
    if out.frames.len() > MAX_GPU_CAMERAS || out.frames.is_empty() {
        return Some(format!(
            "{} cameras (the GPU's bowl shows 1 to {MAX_GPU_CAMERAS})",
            out.frames.len()
        ));
    }
    out.frames
        .iter()
        .find(|f| !matches!(f.meta.format, PixelFormat::Mono8 | PixelFormat::Rgb8))
        .map(|f| {
            format!(
                "{:?} frames (the GPU's bowl takes Mono8 and RGB8)",
                f.meta.format
            )
        })
}

impl GpuBowl {
    /// Why the GPU cannot draw, if a draw failed.
    pub(super) fn failure(&self) -> Option<String> {
        self.shared.lock().ok().and_then(|s| s.failed.clone())
    }

    /// The run's summary of the GPU's pictures, if it drew any.
    pub(super) fn summary(&self) -> Option<String> {
        let s = self.shared.lock().ok()?;
        let (first, last) = (s.drawn.first()?.0, s.drawn.last()?.0);
        let secs = (last - first).as_secs_f64().max(1e-3);
        let median = |mut v: Vec<f32>| {
            v.sort_by(f32::total_cmp);
            v.get(v.len() / 2).copied().unwrap_or(0.0)
        };
        let uploads: Vec<f32> = s.drawn.iter().map(|d| d.1).filter(|&u| u > 0.0).collect();
        let n_up = uploads.len();
        let draws: Vec<f32> = s.drawn.iter().map(|d| d.2).collect();
        Some(format!(
            "bowl on the GPU: {} pictures in {secs:.1} s ({:.1} per second); on the UI thread, {n_up} uploads of a set: median {:.1} ms; draws: median {:.1} ms",
            s.drawn.len(),
            (s.drawn.len() - 1) as f64 / secs,
            median(uploads),
            median(draws),
        ))
    }

    /// The latest upload and draw times, ms.
    pub(super) fn times(&self) -> Option<(f32, f32)> {
        let s = self.shared.lock().ok()?;
        s.renderer.as_ref().map(|_| (s.upload_ms, s.draw_ms))
    }

    /// Paints `out`'s frames as the bowl from `viewpoint` into `rect`.
    pub(super) fn paint(
        &self,
        ui: &egui::Ui,
        rect: egui::Rect,
        out: &Arc<Output>,
        viewpoint: Viewpoint,
        mode: BlendMode,
    ) {
        let shared = self.shared.clone();
        let out = out.clone();
        let callback = egui_glow::CallbackFn::new(move |info, painter| {
            let Ok(mut s) = shared.lock() else {
                return;
            };
            if s.failed.is_some() {
                return;
            }
            let gl = painter.gl();
            if let Err(e) = s.draw(gl, &info, &out, viewpoint, mode) {
                tracing::warn!("the bowl on the GPU: {e}; the CPU draws it instead");
                s.failed = Some(e);
            }
        });
        ui.painter().add(egui::PaintCallback {
            rect,
            callback: Arc::new(callback),
        });
    }
}

impl Shared {
    fn draw(
        &mut self,
        gl: &glow::Context,
        info: &egui::PaintCallbackInfo,
        out: &Output,
        viewpoint: Viewpoint,
        mode: BlendMode,
    ) -> Result<(), String> {
        let Some(view) = out.bowl_view.as_ref() else {
            return Ok(());
        };
        let mesh = view.plan().mesh().map_err(str::to_owned)?;
        if self.renderer.is_none() {
            self.renderer = Some(BowlGl::new(gl)?);
        }
        let Some(renderer) = self.renderer.as_mut() else {
            return Ok(());
        };
        if !self.mesh.as_ref().is_some_and(|m| Arc::ptr_eq(m, mesh)) {
            let car = VehicleTriangles::of(view.spec(), view.vehicle_mesh().map(|m| &**m));
            renderer.set_geometry(gl, mesh, &car);
            self.mesh = Some(mesh.clone());
        }
        let mut upload_ms = 0.0;
        if self.uploaded != Some(out.trigger) {
            let t = Instant::now();
            let frames: Vec<TextureFrame<'_>> = out
                .frames
                .iter()
                .map(|f| TextureFrame {
                    width: f.meta.width,
                    height: f.meta.height,
                    channels: if f.meta.format == PixelFormat::Rgb8 {
                        3
                    } else {
                        1
                    },
                    data: &f.data,
                })
                .collect();
            renderer.upload(gl, &frames)?;
            self.uploaded = Some(out.trigger);
            upload_ms = t.elapsed().as_secs_f32() * 1e3;
            self.upload_ms = upload_ms;
        }
        let px = info.viewport_in_pixels();
        let size = (px.width_px.max(1) as usize, px.height_px.max(1) as usize);
        let rect = [px.left_px, px.from_bottom_px, px.width_px, px.height_px];
        let key = (out.trigger, viewpoint, size, mode, out.gain_parts.clone());
        if self.last.as_ref() == Some(&key) {
            // Nothing changed (the window repaints for another reason).
            renderer.blit(gl, None, rect);
            return Ok(());
        }
        let t = Instant::now();
        renderer.draw(
            gl,
            &Shot {
                camera: viewpoint.camera(size.0, size.1),
                size,
                gains: out.gain_parts.clone(),
                mode,
            },
        )?;
        renderer.blit(gl, None, rect);
        self.last = Some(key);
        self.draw_ms = t.elapsed().as_secs_f32() * 1e3;
        if self.drawn.len() < 100_000 {
            self.drawn.push((Instant::now(), upload_ms, self.draw_ms));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn software_renderers_are_told_from_gpus() {
        for software in [
            "llvmpipe (LLVM 15.0.6, 256 bits)",
            "softpipe",
            "Mesa X11 swrast",
            "Microsoft Basic Render Driver (WARP)",
        ] {
            assert!(is_software(software), "{software}");
        }
        for gpu in [
            "NVIDIA GeForce RTX 3060/PCIe/SSE2",
            "Mesa Intel(R) UHD Graphics 620 (KBL GT2)",
            "AMD Radeon RX 6600 (radeonsi, navi23, LLVM 15.0.6, DRM 3.49)",
            "NVIDIA Tegra Orin (nvgpu)/integrated",
        ] {
            assert!(!is_software(gpu), "{gpu}");
        }
    }
}
