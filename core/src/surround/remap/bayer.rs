//! Bayer mosaics in the remap: the colour order, the per-tap site table and
//! the scalar sample (see the module documentation of [`super`]).

use super::Plan;
use crate::image::PixelFormat;

/// The colour order of a Bayer mosaic, as the site of its top-left pixel:
/// 0 red, 1 green on a red row, 2 green on a blue row, 3 blue. The site of
/// pixel (x, y) is `order ^ (x & 1) ^ (y & 1) << 1`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Cfa(u8);

impl Cfa {
    /// The order of a Bayer format (any depth), or `None` for the others.
    pub(crate) fn of(format: PixelFormat) -> Option<Self> {
        match format.to_8bit() {
            PixelFormat::BayerRg8 => Some(Self(0)),
            PixelFormat::BayerGr8 => Some(Self(1)),
            PixelFormat::BayerGb8 => Some(Self(2)),
            PixelFormat::BayerBg8 => Some(Self(3)),
            _ => None,
        }
    }

    /// The site code of the top-left pixel (0 to 3).
    #[inline(always)]
    pub(crate) fn code(self) -> u8 {
        self.0
    }
}

/// The bit of a site code that marks a tap whose 4×4 neighbourhood leaves
/// the image.
pub(crate) const BORDER: u8 = 4;

/// Per tap of `plan`, its site code: `(x0 & 1) | (y0 & 1) << 1` of its
/// top-left pixel (x0, y0), with [`BORDER`] where the 4×4 neighbourhood
/// `x0 − 1 ..= x0 + 2`, `y0 − 1 ..= y0 + 2` is not inside the image.
pub(super) fn sites(plan: &Plan) -> Vec<u8> {
    let mut out = vec![BORDER; plan.index.len()];
    for run in &plan.runs {
        let (len, first) = (run.len as usize, run.taps as usize);
        let Some(cams) = plan.run_cameras(run) else {
            continue;
        };
        for (j, &c) in cams.iter().enumerate() {
            let Some(&(w, h)) = plan.sources().get(c as usize) else {
                continue;
            };
            let range = first + j * len..first + (j + 1) * len;
            let (Some(index), Some(dst)) = (plan.index.get(range.clone()), out.get_mut(range))
            else {
                continue;
            };
            for (d, &i) in dst.iter_mut().zip(index) {
                let (x, y) = (i as usize % w.max(1), i as usize / w.max(1));
                let border = x == 0 || x + 3 > w || y == 0 || y + 3 > h;
                *d = (x & 1) as u8 | ((y & 1) as u8) << 1 | if border { BORDER } else { 0 };
            }
        }
    }
    out
}

/// 4 bytes of `src` at `o` (little-endian), or 0 past the end (which the
/// site table keeps the interior reads from).
#[inline(always)]
fn load4(src: &[u8], o: usize) -> u32 {
    src.get(o..)
        .and_then(|s| s.first_chunk::<4>())
        .map_or(0, |b| u32::from_le_bytes(*b))
}

/// Reflects `v` (at most one pixel outside `[0, n)`) into it without
/// repeating the edge (…, 1, 0, 1, …, n − 2, n − 1, n − 2): the Bayer
/// phase of the reflected pixel is that of `v`.
#[inline]
fn reflect(v: isize, n: usize) -> usize {
    let n = n as isize;
    let r = if v < 0 {
        -v
    } else if v >= n {
        2 * (n - 1) - v
    } else {
        v
    };
    r.clamp(0, (n - 1).max(0)) as usize
}

/// The 4×4 neighbourhood of the tap at top-left pixel `index` of a
/// `width`-wide mosaic, one row a `u32` (column `x0 − 1` in the low byte),
/// with the edge reflected where it leaves the image.
#[inline(never)]
fn border_rows(bytes: &[u8], width: usize, height: usize, index: u32) -> [u32; 4] {
    let width = width.max(1);
    let (x0, y0) = (
        (index as usize % width) as isize,
        (index as usize / width) as isize,
    );
    std::array::from_fn(|r| {
        let y = reflect(y0 - 1 + r as isize, height);
        (0..4).fold(0u32, |acc, c| {
            let x = reflect(x0 - 1 + c as isize, width);
            let v = bytes.get(y * width + x).copied().unwrap_or(0);
            acc | u32::from(v) << (8 * c)
        })
    })
}

/// One Bayer tap: per channel (R, G, B) `Σ w·S` over the tap's four
/// pixels, where `S` is 4× the pixel's bilinear demosaic (scale 4·4096, not
/// yet rounded). `site` is the tap's entry in the site table.
///
/// The neighbourhood is first turned so that the top-left pixel is a red
/// site (mirrored left–right when it is on an odd site column, top–bottom
/// on an odd site row, the weights with it); then, with `n[r][c]` the
/// neighbourhood from (x0 − 1, y0 − 1) and the tap's pixels `n[1..=2][1..=2]`:
///
/// ```text
/// R: 4·n11        2·(n11 + n13)    2·(n11 + n31)    n11 + n13 + n31 + n33
/// G: n01 + n10 + n12 + n21    4·n12    4·n21    n12 + n21 + n23 + n32
/// B: n00 + n02 + n20 + n22    2·(n02 + n22)    2·(n20 + n22)    4·n22
/// ```
///
/// for the top-left, top-right, bottom-left and bottom-right pixels.
#[inline(always)]
pub(super) fn sample(
    bytes: &[u8],
    width: usize,
    height: usize,
    cfa: Cfa,
    index: u32,
    w: u64,
    site: u8,
) -> [u32; 3] {
    let rows = if site & BORDER == 0 {
        // x0 ≥ 1 and y0 ≥ 1: the neighbourhood starts one row and one
        // column earlier.
        let o = (index as usize).wrapping_sub(width + 1);
        [
            load4(bytes, o),
            load4(bytes, o.wrapping_add(width)),
            load4(bytes, o.wrapping_add(2 * width)),
            load4(bytes, o.wrapping_add(3 * width)),
        ]
    } else {
        border_rows(bytes, width, height, index)
    };
    let t = (site ^ cfa.code()) & 3;
    let mut w = [
        (w & 0xffff) as u32,
        (w >> 16 & 0xffff) as u32,
        (w >> 32 & 0xffff) as u32,
        (w >> 48) as u32,
    ];
    let mut rows = rows;
    if t & 2 != 0 {
        rows.reverse();
        w = [w[2], w[3], w[0], w[1]];
    }
    if t & 1 != 0 {
        rows = rows.map(u32::swap_bytes);
        w = [w[1], w[0], w[3], w[2]];
    }
    let n = |r: usize, c: usize| rows[r] >> (8 * c) & 0xff;
    let sum = |s: [u32; 4]| w[0] * s[0] + w[1] * s[1] + w[2] * s[2] + w[3] * s[3];
    let (n11, n13, n31, n33) = (n(1, 1), n(1, 3), n(3, 1), n(3, 3));
    let (n00, n02, n20, n22) = (n(0, 0), n(0, 2), n(2, 0), n(2, 2));
    let (n12, n21) = (n(1, 2), n(2, 1));
    [
        sum([
            4 * n11,
            2 * (n11 + n13),
            2 * (n11 + n31),
            n11 + n13 + n31 + n33,
        ]),
        sum([
            n(0, 1) + n(1, 0) + n12 + n21,
            4 * n12,
            4 * n21,
            n12 + n21 + n(2, 3) + n(3, 2),
        ]),
        sum([
            n00 + n02 + n20 + n22,
            2 * (n02 + n22),
            2 * (n20 + n22),
            4 * n22,
        ]),
    ]
}
