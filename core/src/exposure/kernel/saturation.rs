//! The saturation kernel: the sums over saturated pixels and their
//! neighbourhoods that scale-and-clip's assumed recovery needs.

use super::{dispatch, total, Isa, Kernel};

/// What scale-and-clip's assumed recovery needs to know about the
/// saturated pixels of a `w×h` image (interior pixels only, each counted
/// with its weight): the weight of the saturated ones (at or above
/// `level`), of those in each band `[s, level)` for the `levels` below 1
/// (0 for the others), and the weight and summed `info` of the pixels whose
/// whole 3×3 neighbourhood lies in `[widest, level)`.
#[derive(Clone, Debug, Default, PartialEq)]
pub(crate) struct SaturationSums {
    pub(crate) saturated: f64,
    pub(crate) bands: Vec<f64>,
    pub(crate) texture_weight: f64,
    pub(crate) texture_info: f64,
}

/// [`SaturationSums`] of `luma` (`w×h`, with `info` per pixel and optional
/// weights; empty sums if a buffer is short).
#[allow(clippy::too_many_arguments)]
pub(crate) fn saturation_sums(
    isa: Isa,
    luma: &[f32],
    weight: Option<&[f32]>,
    info: &[f32],
    w: usize,
    h: usize,
    levels: &[f32],
    widest: f32,
    level: f32,
) -> SaturationSums {
    let short = |v: &[f32]| v.len() < w * h;
    if w < 3 || h < 3 || short(luma) || short(info) || weight.is_some_and(short) {
        return SaturationSums {
            bands: vec![0.0; levels.len()],
            ..Default::default()
        };
    }
    dispatch(
        isa,
        Saturation {
            luma,
            weight,
            info,
            w,
            h,
            levels,
            widest,
            level,
        },
    )
}

struct Saturation<'a> {
    luma: &'a [f32],
    weight: Option<&'a [f32]>,
    info: &'a [f32],
    w: usize,
    h: usize,
    levels: &'a [f32],
    widest: f32,
    level: f32,
}

impl Kernel for Saturation<'_> {
    type Output = SaturationSums;

    #[inline(always)]
    fn run<const L: usize, const FMA: bool>(self) -> SaturationSums {
        let (luma, weight, info, levels) = (self.luma, self.weight, self.info, self.levels);
        let (w, h, widest, level) = (self.w, self.h, self.widest, self.level);
        let n = w - 2;
        let mut out = SaturationSums {
            bands: vec![0.0; levels.len()],
            ..Default::default()
        };
        // Each row's extremes over three columns, for the last three rows.
        let mut lo = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        let mut hi = [vec![0.0f32; n], vec![0.0f32; n], vec![0.0f32; n]];
        let extremes = |y: usize, lo: &mut [f32], hi: &mut [f32]| {
            let row = &luma[y * w..(y + 1) * w];
            let (a, b, c) = (&row[..n], &row[1..n + 1], &row[2..n + 2]);
            for ((((lo, hi), &a), &b), &c) in lo.iter_mut().zip(hi.iter_mut()).zip(a).zip(b).zip(c)
            {
                *lo = a.min(b).min(c);
                *hi = a.max(b).max(c);
            }
        };
        let ones = vec![1.0f32; n];
        let mut nmin = vec![0.0f32; n];
        let mut nmax = vec![0.0f32; n];
        let mut bands = vec![[0.0f32; L]; levels.len()];
        for y in 0..h {
            extremes(y, &mut lo[y % 3], &mut hi[y % 3]);
            if y < 2 {
                continue;
            }
            // Row `y − 1` now has all three rows of its neighbourhoods.
            for (((mn, mx), (&l0, &h0)), ((&l1, &h1), (&l2, &h2))) in nmin
                .iter_mut()
                .zip(nmax.iter_mut())
                .zip(lo[0].iter().zip(&hi[0]))
                .zip(lo[1].iter().zip(&hi[1]).zip(lo[2].iter().zip(&hi[2])))
            {
                *mn = l0.min(l1).min(l2);
                *mx = h0.max(h1).max(h2);
            }
            let span = (y - 1) * w + 1..(y - 1) * w + 1 + n;
            let v = &luma[span.clone()];
            let wt = weight.map_or(&ones[..], |wt| &wt[span.clone()]);
            let inf = &info[span];
            let mut sat = [0.0f32; L];
            let (mut tw, mut ti) = ([0.0f32; L], [0.0f32; L]);
            let (vc, _) = v.as_chunks::<L>();
            let (wc, _) = wt.as_chunks::<L>();
            let (ic, _) = inf.as_chunks::<L>();
            let (nc, _) = nmin.as_chunks::<L>();
            let (xc, _) = nmax.as_chunks::<L>();
            // Each condition as a factor of 0 or 1 (exact: weights and
            // information are finite and not negative), not a branch or a
            // select: LLVM made the selects masked stores to the stack,
            // which stall on every next load.
            let one = |c: bool| f32::from(u8::from(c));
            for ((((v, wt), inf), mn), mx) in vc.iter().zip(wc).zip(ic).zip(nc).zip(xc) {
                for l in 0..L {
                    sat[l] += wt[l] * one(v[l] >= level);
                    let texture = one((mn[l] >= widest) & (mx[l] < level));
                    tw[l] += wt[l] * texture;
                    ti[l] += inf[l] * texture;
                }
            }
            for (acc, &s) in bands.iter_mut().zip(levels) {
                let mut a = [0.0f32; L];
                if s < 1.0 {
                    for (v, wt) in vc.iter().zip(wc) {
                        for l in 0..L {
                            a[l] += wt[l] * one((v[l] >= s) & (v[l] < level));
                        }
                    }
                }
                *acc = a;
            }
            // The row's last, partial vector.
            let tail = vc.len() * L..n;
            for x in tail {
                sat[0] += if v[x] >= level { wt[x] } else { 0.0 };
                let texture = nmin[x] >= widest && nmax[x] < level;
                tw[0] += if texture { wt[x] } else { 0.0 };
                ti[0] += if texture { inf[x] } else { 0.0 };
                for (acc, &s) in bands.iter_mut().zip(levels) {
                    acc[0] += if s < 1.0 && v[x] >= s && v[x] < level {
                        wt[x]
                    } else {
                        0.0
                    };
                }
            }
            out.saturated += total(&sat);
            out.texture_weight += total(&tw);
            out.texture_info += total(&ti);
            for (b, acc) in out.bands.iter_mut().zip(&bands) {
                *b += total(acc);
            }
        }
        out
    }
}
