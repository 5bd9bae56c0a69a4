//! The exposure simulations: where the rows of the image to score come
//! from, mapped row by row into the pass's ring.

use super::super::{fastmath, tone};

/// Where the rows of the image to score come from.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Source<'a> {
    /// The image as it is.
    Plain(&'a [f32]),
    /// The γ-mapping `I^γ = 2^(γ·log₂ I)`, from `log₂ I` (each value in
    /// `[−126/γ, 0]`, as [`log2_map`] makes them).
    Gamma { log2: &'a [f32], gamma: f32 },
    /// Scale-and-clip `min(1, s·I)`.
    Scale { luma: &'a [f32], s: f32 },
    /// Scale-and-hold: `s·I` below `level`, `I` (held) at or above it: a
    /// darkening `s < 1` that leaves saturated pixels saturated.
    Hold { luma: &'a [f32], s: f32, level: f32 },
    /// Scale-and-clip of a block average whose fraction `f` of samples is
    /// saturated: those are held at 1 and the rest, `I − f`, scaled and
    /// clipped as a block, `f + min(1 − f, s·(I − f))`.
    Blocks {
        luma: &'a [f32],
        saturated: &'a [f32],
        s: f32,
    },
    /// Scale-and-clip of a pixel whose saturated part is known from a
    /// darker frame: the part below saturation `u` scales, the saturated
    /// part `f` (the fraction of samples at full well) comes back below it
    /// once its true level `t` (what those samples sum to without the
    /// clip) scaled falls under it: `s·u + min(f, s·t)`.
    Declipped {
        unsaturated: &'a [f32],
        saturated: &'a [f32],
        hidden: &'a [f32],
        s: f32,
    },
    /// Each value through a lookup of values at inputs evenly spaced over
    /// `[0, 1]`, interpolated linearly (a tone curve's simulated exposure
    /// change, [`crate::exposure::tone::ToneCurve::lookup`]).
    Table { luma: &'a [f32], table: &'a [f32] },
}

impl Source<'_> {
    pub(super) fn covers(&self, len: usize) -> bool {
        match self {
            Source::Plain(v) => v.len() >= len,
            Source::Gamma { log2, .. } => log2.len() >= len,
            Source::Scale { luma, .. } | Source::Hold { luma, .. } => luma.len() >= len,
            Source::Table { luma, table } => luma.len() >= len && table.len() >= 2,
            Source::Blocks {
                luma, saturated, ..
            } => luma.len() >= len && saturated.len() >= len,
            Source::Declipped {
                unsaturated,
                saturated,
                hidden,
                ..
            } => unsaturated.len() >= len && saturated.len() >= len && hidden.len() >= len,
        }
    }

    /// Row `r` (of width `w`) of the simulated image, clamped to [0, 1]
    /// and multiplied by `scale`, into `out`.
    #[inline(always)]
    pub(super) fn map_row<const FMA: bool>(&self, r: usize, w: usize, scale: f32, out: &mut [f32]) {
        let span = r * w..(r + 1) * w;
        match *self {
            Source::Plain(v) => {
                for (o, &v) in out.iter_mut().zip(&v[span]) {
                    *o = (scale * v).clamp(0.0, scale);
                }
            }
            Source::Gamma { log2, gamma } => {
                let exp2 = fastmath::Exp2::scaled(scale);
                for (o, &l) in out.iter_mut().zip(&log2[span]) {
                    *o = exp2.product::<FMA>(gamma, l);
                }
            }
            Source::Scale { luma, s } => {
                let s = s * scale;
                for (o, &v) in out.iter_mut().zip(&luma[span]) {
                    *o = (s * v).clamp(0.0, scale);
                }
            }
            Source::Hold { luma, s, level } => {
                let s = s * scale;
                for (o, &v) in out.iter_mut().zip(&luma[span]) {
                    let k = if v >= level { scale } else { s };
                    *o = (k * v).clamp(0.0, scale);
                }
            }
            Source::Blocks { luma, saturated, s } => {
                for ((o, &v), &f) in out
                    .iter_mut()
                    .zip(&luma[span.clone()])
                    .zip(&saturated[span])
                {
                    let rest = (s * (v - f).max(0.0)).min(1.0 - f);
                    *o = (scale * (f + rest)).clamp(0.0, scale);
                }
            }
            Source::Declipped {
                unsaturated,
                saturated,
                hidden,
                s,
            } => {
                for (((o, &u), &f), &t) in out
                    .iter_mut()
                    .zip(&unsaturated[span.clone()])
                    .zip(&saturated[span.clone()])
                    .zip(&hidden[span])
                {
                    *o = (scale * (s * u + f.min(s * t))).clamp(0.0, scale);
                }
            }
            Source::Table { luma, table } => {
                for (o, &v) in out.iter_mut().zip(&luma[span]) {
                    *o = (scale * tone::interpolate(table, v)).clamp(0.0, scale);
                }
            }
        }
    }
}
