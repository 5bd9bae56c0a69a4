//! Text in the PNG plots: the font every plot is drawn in ([`FONT`],
//! registered with plotters once), drawn where its glyphs belong.
//!
//! plotters' `ab_glyph` backend (0.3) draws each glyph at its advance
//! position without the glyph's left side bearing, so that every letter
//! sits up to a pixel or two left of its place and a space before a letter
//! with a wide bearing all but vanishes ("the ratios" read "theratios").
//! [`Glyphs`] wraps a drawing backend and draws the text of [`FONT`] itself:
//! the same layout (advances and kerning) with each glyph at its bounds.
//! Text in any other font is drawn by the wrapped backend.

use std::sync::Once;

use ab_glyph::{Font, FontRef, ScaleFont};
use anyhow::Result;
use plotters::prelude::*;
use plotters_backend::{
    text_anchor::{HPos, VPos},
    BackendColor, BackendCoord, BackendStyle, BackendTextStyle, DrawingErrorKind, FontFamily,
};

/// The font every plot is drawn in.
pub const FONT: &str = "rigview-sans";

/// Registers [`FONT`] with plotters (once).
pub fn register_font() -> Result<()> {
    static ONCE: Once = Once::new();
    let mut result = Ok(());
    ONCE.call_once(|| {
        result = plotters::style::register_font(
            FONT,
            FontStyle::Normal,
            epaint_default_fonts::UBUNTU_LIGHT,
        )
        .map_err(|_| anyhow::anyhow!("the plot font cannot be read"));
    });
    result
}

/// A drawing backend whose text in [`FONT`] is drawn glyph by glyph at the
/// glyphs' bounds (see the module documentation).
pub struct Glyphs<B> {
    inner: B,
    font: Option<FontRef<'static>>,
}

impl<B> std::fmt::Debug for Glyphs<B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Glyphs").finish_non_exhaustive()
    }
}

impl<B> Glyphs<B> {
    /// Wraps `inner`.
    pub fn new(inner: B) -> Self {
        Self {
            inner,
            font: FontRef::try_from_slice(epaint_default_fonts::UBUNTU_LIGHT).ok(),
        }
    }
}

/// Lays `text` out in `font` at a scale of `size` pixels, its baseline
/// `size / 2` below the origin (where plotters puts it), and calls `put`
/// with each covered pixel and its coverage.
fn layout(font: &FontRef<'_>, size: f32, text: &str, mut put: impl FnMut(i32, i32, f32)) {
    let scaled = font.as_scaled(size);
    let mut x = 0.0f32;
    let mut prev = None;
    for c in text.chars() {
        let id = scaled.glyph_id(c);
        if let Some(p) = prev {
            x += scaled.kern(p, id);
        }
        prev = Some(id);
        let glyph = id.with_scale_and_position(size, ab_glyph::point(x, size / 2.0));
        if let Some(outline) = scaled.outline_glyph(glyph) {
            let b = outline.px_bounds();
            let (x0, y0) = (b.min.x as i32, b.min.y as i32);
            outline.draw(|gx, gy, a| put(x0 + gx as i32, y0 + gy as i32, a));
        }
        x += scaled.h_advance(id);
    }
}

impl<B: DrawingBackend> DrawingBackend for Glyphs<B> {
    type ErrorType = B::ErrorType;

    fn get_size(&self) -> (u32, u32) {
        self.inner.get_size()
    }

    fn ensure_prepared(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.ensure_prepared()
    }

    fn present(&mut self) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.present()
    }

    fn draw_pixel(
        &mut self,
        point: BackendCoord,
        color: BackendColor,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_pixel(point, color)
    }

    fn draw_line<S: BackendStyle>(
        &mut self,
        from: BackendCoord,
        to: BackendCoord,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_line(from, to, style)
    }

    fn draw_rect<S: BackendStyle>(
        &mut self,
        upper_left: BackendCoord,
        bottom_right: BackendCoord,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_rect(upper_left, bottom_right, style, fill)
    }

    fn draw_path<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        path: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_path(path, style)
    }

    fn draw_circle<S: BackendStyle>(
        &mut self,
        center: BackendCoord,
        radius: u32,
        style: &S,
        fill: bool,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.draw_circle(center, radius, style, fill)
    }

    fn fill_polygon<S: BackendStyle, I: IntoIterator<Item = BackendCoord>>(
        &mut self,
        vert: I,
        style: &S,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.fill_polygon(vert, style)
    }

    fn blit_bitmap(
        &mut self,
        pos: BackendCoord,
        (iw, ih): (u32, u32),
        src: &[u8],
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        self.inner.blit_bitmap(pos, (iw, ih), src)
    }

    fn estimate_text_size<S: BackendTextStyle>(
        &self,
        text: &str,
        style: &S,
    ) -> Result<(u32, u32), DrawingErrorKind<Self::ErrorType>> {
        self.inner.estimate_text_size(text, style)
    }

    fn draw_text<S: BackendTextStyle>(
        &mut self,
        text: &str,
        style: &S,
        pos: BackendCoord,
    ) -> Result<(), DrawingErrorKind<Self::ErrorType>> {
        let ours = matches!(style.family(), FontFamily::Name(n) if n == FONT);
        let (Some(font), true) = (self.font.clone(), ours) else {
            return self.inner.draw_text(text, style, pos);
        };
        let color = style.color();
        if color.alpha == 0.0 {
            return Ok(());
        }
        // plotters' own box for the anchor, so that text lands where the
        // chart's layout expects it.
        let ((min_x, min_y), (max_x, max_y)) = style
            .layout_box(text)
            .map_err(|e| DrawingErrorKind::FontError(Box::new(e)))?;
        let (width, height) = (max_x - min_x, max_y - min_y);
        let dx = match style.anchor().h_pos {
            HPos::Left => 0,
            HPos::Right => -width,
            HPos::Center => -width / 2,
        };
        let dy = match style.anchor().v_pos {
            VPos::Top => 0,
            VPos::Center => -height / 2,
            VPos::Bottom => -height,
        };
        let trans = style.transform();
        let (w, h) = self.get_size();
        let mut pixels = Vec::new();
        layout(&font, style.size() as f32, text, |x, y, a| {
            pixels.push((x, y, a));
        });
        for (x, y, a) in pixels {
            let (x, y) = trans.transform(x + dx - min_x, y + dy - min_y);
            let (x, y) = (pos.0 + x, pos.1 + y);
            if x >= 0 && y >= 0 && (x as u32) < w && (y as u32) < h {
                let c = BackendColor {
                    alpha: color.alpha * f64::from(a.clamp(0.0, 1.0)),
                    rgb: color.rgb,
                };
                self.inner.draw_pixel((x, y), c)?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// The first column with ink of a `w`-wide RGB buffer on white.
    fn first_inked(buf: &[u8], w: usize) -> Option<usize> {
        let h = buf.len() / (3 * w);
        (0..w).find(|&x| (0..h).any(|y| buf[3 * (y * w + x)] < 200))
    }

    /// A glyph is drawn from its left side bearing on, where the font puts
    /// it (plotters' own drawing puts every glyph's ink at its advance
    /// position, which runs the letters of a word together).
    #[test]
    fn a_glyph_is_drawn_at_its_bearing() {
        register_font().unwrap();
        let font = FontRef::try_from_slice(epaint_default_fonts::UBUNTU_LIGHT).unwrap();
        let size = 60.0;
        let scaled = font.as_scaled(size);
        let glyph = scaled
            .glyph_id('r')
            .with_scale_and_position(size, ab_glyph::point(0.0, size / 2.0));
        let bearing = scaled.outline_glyph(glyph).unwrap().px_bounds().min.x as usize;
        assert!(bearing >= 3, "the bearing of r at 60 px: {bearing} px");
        let (w, h) = (120usize, 90usize);
        let mut buf = vec![255u8; w * h * 3];
        {
            let root = Glyphs::new(BitMapBackend::with_buffer(&mut buf, (w as u32, h as u32)))
                .into_drawing_area();
            let style = TextStyle::from((FONT, f64::from(size))).color(&BLACK);
            root.draw_text("r", &style, (10, 10)).unwrap();
        }
        let first = first_inked(&buf, w).unwrap();
        assert!(
            first.abs_diff(10 + bearing) <= 1,
            "ink from column {first}, bearing {bearing}"
        );
    }
}
