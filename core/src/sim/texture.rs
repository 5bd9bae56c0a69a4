//! Procedural textures: hashed value noise with level of detail.
//!
//! Every texture is a pure function of the surface point and a seed, so a
//! scene renders the same on every run and in every thread. Each octave of
//! noise fades out when the pixel footprint (the size of the surface patch a
//! pixel sees) approaches its scale: far surfaces show their mean instead of
//! aliasing into per-pixel noise.

/// SplitMix64's finaliser: a good 64-bit mix.
pub(crate) fn mix(mut z: u64) -> u64 {
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A hash of a seed and two integers, uniform in [0, 1).
pub(crate) fn hash2(seed: u64, i: i64, j: i64) -> f64 {
    let h = mix(seed ^ mix((i as u64).wrapping_add(mix(j as u64 ^ 0x9e37_79b9_7f4a_7c15))));
    (h >> 11) as f64 / (1u64 << 53) as f64
}

fn smooth(t: f64) -> f64 {
    t * t * (3.0 - 2.0 * t)
}

/// Smooth value noise in [-1, 1] on a unit lattice.
pub(crate) fn value_noise(seed: u64, x: f64, y: f64) -> f64 {
    let (fx, fy) = (x.floor(), y.floor());
    let (i, j) = (fx as i64, fy as i64);
    let (tx, ty) = (smooth(x - fx), smooth(y - fy));
    let at = |di: i64, dj: i64| 2.0 * hash2(seed, i + di, j + dj) - 1.0;
    let top = at(0, 0) + (at(1, 0) - at(0, 0)) * tx;
    let bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * tx;
    top + (bottom - top) * ty
}

/// How much of a feature of size `scale` survives a pixel footprint of
/// `footprint` (same units): 1 for fine pixels, 0 once a pixel covers the
/// feature.
pub(crate) fn detail(footprint: f64, scale: f64) -> f64 {
    (1.0 - footprint / scale).clamp(0.0, 1.0)
}

/// Fractal value noise in about [-1, 1]: `octaves` octaves from `scale`
/// down by halves, each faded by the footprint.
pub(crate) fn fbm(seed: u64, x: f64, y: f64, scale: f64, octaves: u32, footprint: f64) -> f64 {
    let (mut sum, mut amp, mut s, mut norm) = (0.0, 1.0, scale, 0.0);
    for o in 0..octaves {
        norm += amp;
        let keep = detail(footprint, s);
        if keep > 0.0 {
            sum += amp * keep * value_noise(seed.wrapping_add(u64::from(o)), x / s, y / s);
        }
        amp *= 0.55;
        s *= 0.5;
    }
    sum / norm
}

/// A periodic band with soft edges: 1 inside `[start, start + width)` of
/// every `period`, 0 outside, blended over the footprint.
pub(crate) fn band(x: f64, period: f64, start: f64, width: f64, footprint: f64) -> f64 {
    let p = (x - start).rem_euclid(period);
    let f = footprint.max(1e-9);
    let rise = ((p + f * 0.5) / f).clamp(0.0, 1.0);
    let fall = ((width - p + f * 0.5) / f).clamp(0.0, 1.0);
    let inside = rise.min(fall);
    // Far away the band averages to its duty cycle.
    let k = detail(footprint, width.min(period - width).max(1e-9) * 2.0);
    inside * k + (width / period) * (1.0 - k)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_deterministic_bounded_and_seeded() {
        let a: Vec<f64> = (0..200)
            .map(|i| value_noise(3, f64::from(i) * 0.37, 1.3))
            .collect();
        let b: Vec<f64> = (0..200)
            .map(|i| value_noise(3, f64::from(i) * 0.37, 1.3))
            .collect();
        let c: Vec<f64> = (0..200)
            .map(|i| value_noise(4, f64::from(i) * 0.37, 1.3))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|v| (-1.0..=1.0).contains(v)));
        let mean = a.iter().sum::<f64>() / a.len() as f64;
        assert!(mean.abs() < 0.2, "mean {mean}");
    }

    #[test]
    fn detail_fades_with_the_footprint() {
        let near = fbm(1, 3.3, 4.4, 1.0, 4, 0.0);
        let far = fbm(1, 3.3, 4.4, 1.0, 4, 10.0);
        assert!(near.abs() > 0.0);
        assert!(far.abs() < 1e-12);
        // A band seen from far away is its duty cycle.
        assert!((band(0.1, 1.0, 0.0, 0.25, 100.0) - 0.25).abs() < 1e-12);
        assert!((band(0.1, 1.0, 0.0, 0.25, 0.0) - 1.0).abs() < 1e-12);
        assert!(band(0.5, 1.0, 0.0, 0.25, 0.0).abs() < 1e-12);
    }
}
