//! A composed view's picture as a texture. Where the window has an OpenGL
//! context (eframe's glow renderer), the canvas's bytes go into a texture
//! of the window's own as they are: 8-bit grey into one red channel shown
//! as grey by the texture's swizzle, RGB as RGB. egui's own textures take
//! RGBA only, so the other path expands every pixel into a fresh
//! `ColorImage` (4 MB for a 1000×1000 view) and egui copies it once more
//! into its upload: that path remains for renderers without GL (the
//! tests' wgpu) and if the GL upload fails.
//!
//! Every GL call is `unsafe` in `glow`; the module allows it, and each
//! block says what it relies on.
#![allow(unsafe_code)]

use std::sync::Arc;

use eframe::glow::{self, HasContext};
use egui::{ColorImage, TextureHandle, TextureId, TextureOptions};
use rigview_core::surround::Canvas;

/// A texture the window made and keeps, with what it holds now.
pub struct GlTexture {
    gl: Arc<glow::Context>,
    texture: glow::Texture,
    /// Width, height and channels of what it holds.
    shape: (usize, usize, usize),
}

impl std::fmt::Debug for GlTexture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("GlTexture")
            .field("shape", &self.shape)
            .finish_non_exhaustive()
    }
}

impl GlTexture {
    /// A new, empty texture in `gl`'s context (current on this thread).
    pub fn new(gl: Arc<glow::Context>) -> Result<Self, String> {
        // SAFETY: `gl` is current on this thread (eframe's window, or a
        // test's headless context); the texture is only named here.
        let texture = unsafe { gl.create_texture()? };
        Ok(Self {
            gl,
            texture,
            shape: (0, 0, 0),
        })
    }

    /// The GL name, for egui's painter to draw it (which then owns it).
    pub fn native(&self) -> glow::Texture {
        self.texture
    }

    /// Width, height and channels of what the texture holds.
    pub fn shape(&self) -> (usize, usize, usize) {
        self.shape
    }

    /// Puts `c`'s bytes into the texture: allocated anew only when the
    /// canvas's size or channels change, otherwise written in place.
    pub fn upload(&mut self, c: &Canvas) -> Result<(), String> {
        let shape = (c.width, c.height, c.channels);
        let (internal, format) = match c.channels {
            1 => (glow::R8, glow::RED),
            3 => (glow::RGB8, glow::RGB),
            n => return Err(format!("a view of {n} channels (1 or 3 expected)")),
        };
        if c.data.len() != c.width * c.height * c.channels || c.width == 0 || c.height == 0 {
            return Err(format!(
                "a {}×{} view of {} channels with {} bytes",
                c.width,
                c.height,
                c.channels,
                c.data.len()
            ));
        }
        let (Ok(w), Ok(h)) = (i32::try_from(c.width), i32::try_from(c.height)) else {
            return Err(format!("a {}×{} view is too large", c.width, c.height));
        };
        let gl = &self.gl;
        // SAFETY: the texture is this struct's, in `gl`'s context, which
        // is current on this thread; the data was checked against the
        // size just above, and rows are tightly packed (alignment 1).
        unsafe {
            gl.bind_texture(glow::TEXTURE_2D, Some(self.texture));
            gl.pixel_store_i32(glow::UNPACK_ALIGNMENT, 1);
            if self.shape != shape {
                gl.tex_image_2d(
                    glow::TEXTURE_2D,
                    0,
                    internal as i32,
                    w,
                    h,
                    0,
                    format,
                    glow::UNSIGNED_BYTE,
                    glow::PixelUnpackData::Slice(Some(&c.data)),
                );
                // Grey: the red channel in red, green and blue.
                let swizzle = if c.channels == 1 {
                    [glow::RED, glow::RED, glow::RED, glow::ONE]
                } else {
                    [glow::RED, glow::GREEN, glow::BLUE, glow::ONE]
                };
                for (p, v) in [
                    (glow::TEXTURE_MIN_FILTER, glow::LINEAR),
                    (glow::TEXTURE_MAG_FILTER, glow::LINEAR),
                    (glow::TEXTURE_WRAP_S, glow::CLAMP_TO_EDGE),
                    (glow::TEXTURE_WRAP_T, glow::CLAMP_TO_EDGE),
                    (glow::TEXTURE_SWIZZLE_R, swizzle[0]),
                    (glow::TEXTURE_SWIZZLE_G, swizzle[1]),
                    (glow::TEXTURE_SWIZZLE_B, swizzle[2]),
                    (glow::TEXTURE_SWIZZLE_A, swizzle[3]),
                ] {
                    gl.tex_parameter_i32(glow::TEXTURE_2D, p, v as i32);
                }
            } else {
                gl.tex_sub_image_2d(
                    glow::TEXTURE_2D,
                    0,
                    0,
                    0,
                    w,
                    h,
                    format,
                    glow::UNSIGNED_BYTE,
                    glow::PixelUnpackData::Slice(Some(&c.data)),
                );
            }
            gl.bind_texture(glow::TEXTURE_2D, None);
            let e = gl.get_error();
            if e != glow::NO_ERROR {
                self.shape = (0, 0, 0);
                return Err(format!("OpenGL error 0x{e:x} uploading the view"));
            }
        }
        self.shape = shape;
        Ok(())
    }
}

/// Where a view's picture goes: the window's GL texture where it has one,
/// egui's texture otherwise.
#[derive(Default)]
pub struct ViewTexture {
    /// The window's texture and egui's name for it.
    gl: Option<(GlTexture, TextureId)>,
    /// Set once the GL upload failed: egui's textures from then on.
    gl_failed: Option<String>,
    egui: Option<TextureHandle>,
    /// What is shown now: the texture and its size.
    shown: Option<(TextureId, [usize; 2])>,
}

impl std::fmt::Debug for ViewTexture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ViewTexture")
            .field("gl", &self.gl)
            .field("gl_failed", &self.gl_failed)
            .field("shown", &self.shown)
            .finish_non_exhaustive()
    }
}

impl ViewTexture {
    /// Whether a GL texture should be made for it (none yet, none failed).
    pub fn wants_gl(&self) -> bool {
        self.gl.is_none() && self.gl_failed.is_none()
    }

    /// Hands it the window's texture, registered with egui's painter as
    /// `id`.
    pub fn set_gl(&mut self, texture: GlTexture, id: TextureId) {
        self.gl = Some((texture, id));
    }

    /// Gives up the GL path before it started, for `why`.
    pub fn refuse_gl(&mut self, why: String) {
        self.gl_failed = Some(why);
    }

    /// Shows `c`: written into the GL texture, or copied into egui's.
    /// Returns the GL path's failure, the first time it fails (egui's
    /// texture shows the view from then on).
    pub fn upload(&mut self, ctx: &egui::Context, name: &str, c: &Canvas) -> Option<String> {
        let mut failure = None;
        if let Some((texture, id)) = &mut self.gl {
            match texture.upload(c) {
                Ok(()) => {
                    self.shown = Some((*id, [c.width, c.height]));
                    return None;
                }
                Err(e) => {
                    let e = format!("the {name} view's texture: {e}; egui's textures take over");
                    self.gl = None;
                    self.gl_failed = Some(e.clone());
                    failure = Some(e);
                }
            }
        }
        let image = if c.channels == 3 {
            ColorImage::from_rgb([c.width, c.height], &c.data)
        } else {
            ColorImage::from_gray([c.width, c.height], &c.data)
        };
        let t = match &mut self.egui {
            Some(t) => {
                t.set(image, TextureOptions::LINEAR);
                t
            }
            None => self
                .egui
                .insert(ctx.load_texture(name, image, TextureOptions::LINEAR)),
        };
        self.shown = Some((t.id(), t.size()));
        failure
    }

    /// Shows nothing until the next upload.
    pub fn clear(&mut self) {
        self.shown = None;
    }

    /// The texture to draw and its size, if a view is shown.
    pub fn shown(&self) -> Option<(TextureId, [usize; 2])> {
        self.shown
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::gui::bowl_gl::headless_context;

    /// Reads level 0 of `t` back through a framebuffer: its stored
    /// channels (red only for grey).
    fn read_back(gl: &glow::Context, t: &GlTexture) -> Vec<u8> {
        let (w, h, ch) = t.shape();
        let format = if ch == 1 { glow::RED } else { glow::RGB };
        let mut out = vec![0u8; w * h * ch];
        // SAFETY: the headless context is current on this thread; the
        // buffer holds exactly the texture's pixels at alignment 1.
        unsafe {
            let fb = gl.create_framebuffer().unwrap();
            gl.bind_framebuffer(glow::FRAMEBUFFER, Some(fb));
            gl.framebuffer_texture_2d(
                glow::FRAMEBUFFER,
                glow::COLOR_ATTACHMENT0,
                glow::TEXTURE_2D,
                Some(t.native()),
                0,
            );
            gl.pixel_store_i32(glow::PACK_ALIGNMENT, 1);
            gl.read_pixels(
                0,
                0,
                w as i32,
                h as i32,
                format,
                glow::UNSIGNED_BYTE,
                glow::PixelPackData::Slice(Some(&mut out)),
            );
            gl.bind_framebuffer(glow::FRAMEBUFFER, None);
            gl.delete_framebuffer(fb);
        }
        out
    }

    fn swizzle(gl: &glow::Context, t: &GlTexture) -> [u32; 4] {
        // SAFETY: as in `read_back`.
        unsafe {
            gl.bind_texture(glow::TEXTURE_2D, Some(t.native()));
            let s = [
                glow::TEXTURE_SWIZZLE_R,
                glow::TEXTURE_SWIZZLE_G,
                glow::TEXTURE_SWIZZLE_B,
                glow::TEXTURE_SWIZZLE_A,
            ]
            .map(|p| gl.get_tex_parameter_i32(glow::TEXTURE_2D, p) as u32);
            gl.bind_texture(glow::TEXTURE_2D, None);
            s
        }
    }

    fn canvas(width: usize, height: usize, channels: usize, seed: u8) -> Canvas {
        let mut c = Canvas::new(width, height, channels);
        for (k, b) in c.data.iter_mut().enumerate() {
            *b = (k as u8).wrapping_mul(31).wrapping_add(seed);
        }
        c
    }

    #[test]
    fn views_go_into_the_texture_byte_for_byte_and_grey_shows_as_grey() {
        let gl = match headless_context() {
            Ok(gl) => Arc::new(gl),
            Err(e) => panic!("{e}"),
        };
        let mut t = GlTexture::new(gl.clone()).unwrap();
        // An odd width: rows are not 4-byte aligned.
        let grey = canvas(101, 37, 1, 3);
        t.upload(&grey).unwrap();
        assert_eq!(t.shape(), (101, 37, 1));
        assert_eq!(read_back(&gl, &t), grey.data);
        assert_eq!(
            swizzle(&gl, &t),
            [glow::RED, glow::RED, glow::RED, glow::ONE]
        );
        // The next set of the same size is written in place.
        let next = canvas(101, 37, 1, 77);
        t.upload(&next).unwrap();
        assert_eq!(read_back(&gl, &t), next.data);
        // A colour view of another size makes the texture anew.
        let rgb = canvas(53, 29, 3, 5);
        t.upload(&rgb).unwrap();
        assert_eq!(t.shape(), (53, 29, 3));
        assert_eq!(read_back(&gl, &t), rgb.data);
        assert_eq!(
            swizzle(&gl, &t),
            [glow::RED, glow::GREEN, glow::BLUE, glow::ONE]
        );
        // A canvas whose bytes do not fit its size is refused, and the
        // texture keeps what it showed.
        let mut bad = canvas(53, 29, 3, 9);
        bad.data.pop();
        let e = t.upload(&bad).unwrap_err();
        assert!(e.contains("53×29"), "{e}");
        assert_eq!(read_back(&gl, &t), rgb.data);
    }
}
