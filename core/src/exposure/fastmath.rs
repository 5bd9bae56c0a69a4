//! Branch-free `ln` and `exp` for `f32` slices, written so that the compiler
//! vectorises the loops that call them. The metric evaluates a logarithm per
//! pixel per anchor; these keep that within a few nanoseconds per pixel.
//! Accuracy (checked against `std` by the tests below): better than 5e-7
//! relative for [`ln`] on normal positive inputs, better than 4e-6 relative
//! for [`exp2_in_range`] on [-120, 0].

const LN_2: f32 = std::f32::consts::LN_2;
const SQRT_2: f32 = std::f32::consts::SQRT_2;

/// `a·b + c`, fused into one instruction when `FMA` (only where the CPU has
/// it: without hardware support `mul_add` is a slow library call).
#[inline(always)]
pub(crate) fn madd<const FMA: bool>(a: f32, b: f32, c: f32) -> f32 {
    if FMA {
        a.mul_add(b, c)
    } else {
        a * b + c
    }
}

/// Natural logarithm of a positive, normal `x`.
#[cfg(test)]
pub(crate) fn ln(x: f32) -> f32 {
    ln_with::<false>(x)
}

/// `x = m·2^e` with the mantissa `m` in [√½, √2) (where the series below
/// converge fast), for a positive, normal `x`.
#[inline(always)]
fn reduce(x: f32) -> (f32, f32) {
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let m = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000);
    let big = m > SQRT_2;
    let m = if big { m * 0.5 } else { m };
    (m, (e + i32::from(big)) as f32)
}

/// [`ln`], with fused multiply-adds when `FMA`.
#[inline(always)]
pub(crate) fn ln_with<const FMA: bool>(x: f32) -> f32 {
    let (m, e) = reduce(x);
    let u = (m - 1.0) / (m + 1.0);
    let u2 = u * u;
    let series = madd::<FMA>(u2, 1.0 / 9.0, 1.0 / 7.0);
    let series = madd::<FMA>(u2, series, 1.0 / 5.0);
    let series = madd::<FMA>(u2, series, 1.0 / 3.0);
    let series = madd::<FMA>(u2, series, 1.0);
    madd::<FMA>(e, LN_2, 2.0 * u * series)
}

/// `log₂ x` of a positive, normal `x`, to about 1.5e-4 absolute, and exactly
/// 0 at `x = 1`: the exponent plus a degree-4 Chebyshev fit of `log₂ m` on
/// the mantissa `m ∈ [1, 2)` (its constant dropped so that `log₂ 1 = 0`).
/// No division, so it is cheap where that accuracy is enough.
#[inline(always)]
pub(crate) fn log2_approx<const FMA: bool>(x: f32) -> f32 {
    let bits = x.to_bits();
    let e = ((bits >> 23) & 0xff) as i32 - 127;
    let t = f32::from_bits((bits & 0x007f_ffff) | 0x3f80_0000) - 1.0;
    let poly = madd::<FMA>(t, -0.080_010_876, 0.315_467_6);
    let poly = madd::<FMA>(t, poly, -0.672_934_2);
    let poly = madd::<FMA>(t, poly, 1.437_302_1);
    madd::<FMA>(t, poly, e as f32)
}

/// `log₂ x` of a positive, normal `x`, to about 2e-7 absolute, with no
/// division: the exponent, plus `t·P(t)` for the mantissa brought into
/// [√½, √2) (`t = m − 1`), `P` a degree-7 least-squares fit of
/// `log₂(1 + t)/t` on Chebyshev nodes (5.4e-8 in exact arithmetic).
#[inline(always)]
pub(crate) fn log2<const FMA: bool>(x: f32) -> f32 {
    const C: [f32; 8] = [
        1.442_694_8,
        -0.721_357_6,
        0.480_932_3,
        -0.360_064_66,
        0.286_885_1,
        -0.250_497_35,
        0.235_715_54,
        -0.143_023_83,
    ];
    let (m, e) = reduce(x);
    let t = m - 1.0;
    let poly = madd::<FMA>(t, C[7], C[6]);
    let poly = madd::<FMA>(t, poly, C[5]);
    let poly = madd::<FMA>(t, poly, C[4]);
    let poly = madd::<FMA>(t, poly, C[3]);
    let poly = madd::<FMA>(t, poly, C[2]);
    let poly = madd::<FMA>(t, poly, C[1]);
    let poly = madd::<FMA>(t, poly, C[0]);
    madd::<FMA>(t, poly, e)
}

/// `2^z` for `z ≤ 0` (inputs below −126 give 2^−126), vectorisable: the
/// rounding uses the `1.5·2²³` trick rather than a float-to-int cast.
#[cfg(test)]
pub(crate) fn exp2_nonpositive(z: f32) -> f32 {
    exp2_in_range::<false>(z.clamp(-126.0, 0.0))
}

/// `2^z` for `z` in [−126, 0] (the caller guarantees the range; outside it
/// the result is meaningless), with fused multiply-adds when `FMA`.
#[cfg(test)]
pub(crate) fn exp2_in_range<const FMA: bool>(z: f32) -> f32 {
    Exp2::scaled(1.0).product::<FMA>(1.0, z)
}

/// `k·2^z`, vectorisable: `2^z = 2^n · 2^f` with `n` the nearest integer
/// (found with the `1.5·2²³` rounding trick rather than a float-to-int
/// cast, which also leaves `2^n`'s exponent bits in place) and a degree-4
/// Chebyshev fit of `2^f` on [−½, ½] (3.6e-6 relative), whose coefficients
/// carry the factor `k` for free.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Exp2 {
    c: [f32; 5],
}

impl Exp2 {
    /// The coefficients of `2^f` (the constant rounded to 1, so `2^0 = 1`).
    const COEFFICIENTS: [f32; 5] = [1.0, 0.693_121, 0.240_221_07, 0.055_922_035, 0.009_676_037];

    /// `k·2^z`.
    #[inline(always)]
    pub(crate) fn scaled(k: f32) -> Self {
        Self {
            c: Self::COEFFICIENTS.map(|c| c * k),
        }
    }

    /// `k·2^(a·b)` for `a·b` in [−126, 0] (the caller guarantees the
    /// range); with `FMA` the product is not rounded before use.
    #[inline(always)]
    pub(crate) fn product<const FMA: bool>(&self, a: f32, b: f32) -> f32 {
        // Adding 1.5·2²³ + 127 rounds z = a·b to the nearest integer n and
        // leaves n + 127 (the biased exponent of 2^n) in the low mantissa
        // bits, so a shift by 23 alone makes 2^n: the bits above are those
        // of 1.5·2²³, whose lowest nine are zero and shift out.
        const ROUND: f32 = 12_583_039.0; // 1.5·2²³ + 127
        let shifted = madd::<FMA>(a, b, ROUND);
        let f = madd::<FMA>(a, b, -(shifted - ROUND)); // z − n, in [−½, ½]
        let c = &self.c;
        let poly = madd::<FMA>(f, c[4], c[3]);
        let poly = madd::<FMA>(f, poly, c[2]);
        let poly = madd::<FMA>(f, poly, c[1]);
        let poly = madd::<FMA>(f, poly, c[0]);
        poly * f32::from_bits(shifted.to_bits() << 23)
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact values: zero, one and powers of two
mod tests {
    use super::*;

    #[test]
    fn ln_matches_std() {
        let mut worst = 0.0f32;
        let mut x = 1.0e-6f32;
        while x < 1.0e4 {
            let err = (ln(x) - x.ln()).abs() / x.ln().abs().max(1.0);
            worst = worst.max(err);
            x *= 1.0007;
        }
        assert!(worst < 5e-7, "worst relative error {worst}");
        for i in 1..100_000 {
            let x = i as f32 * 0.01;
            let err = (ln_with::<true>(x) - x.ln()).abs() / x.ln().abs().max(1.0);
            assert!(err < 5e-7, "ln_with::<true>({x}) error {err}");
        }
    }

    #[test]
    fn log2_matches_std() {
        // Absolute near 1, relative (to the f32 rounding of the result)
        // far from it.
        let mut worst = 0.0f64;
        let mut x = 1.0e-30f32;
        while x < 1.0e4 {
            let want = f64::from(x).log2();
            for v in [log2::<false>(x), log2::<true>(x)] {
                worst = worst.max((f64::from(v) - want).abs() / (1.0 + want.abs()));
            }
            x *= 1.000_13;
        }
        assert!(worst < 3e-7, "worst error {worst}");
        assert_eq!(log2::<false>(1.0), 0.0);
        assert_eq!(log2::<true>(1.0), 0.0);
        assert_eq!(log2::<true>(0.25), -2.0);
    }

    #[test]
    fn log2_approx_matches_std() {
        let mut worst = 0.0f32;
        let mut x = 1.0f32;
        while x < 1.0e4 {
            for v in [log2_approx::<false>(x), log2_approx::<true>(x)] {
                worst = worst.max((v - x.log2()).abs());
            }
            x *= 1.0003;
        }
        assert!(worst < 2e-4, "worst absolute error {worst}");
        assert_eq!(log2_approx::<false>(1.0), 0.0);
        assert_eq!(log2_approx::<true>(1.0), 0.0);
    }

    #[test]
    fn exp2_matches_std() {
        let mut worst = 0.0f32;
        let mut z = -120.0f32;
        while z <= 0.0 {
            let err = (exp2_nonpositive(z) - z.exp2()).abs() / z.exp2();
            worst = worst.max(err);
            z += 0.00137;
        }
        assert!(worst < 4e-6, "worst relative error {worst}");
        let mut worst_fma = 0.0f32;
        for i in 0..100_000 {
            let z = -(i as f32) * 1.2e-3;
            let err = (exp2_in_range::<true>(z.max(-126.0)) - z.exp2()).abs() / z.exp2();
            worst_fma = worst_fma.max(err);
        }
        assert!(
            worst_fma < 4e-6,
            "worst relative error with FMA {worst_fma}"
        );
        assert_eq!(exp2_nonpositive(0.0), 1.0);
        assert_eq!(exp2_nonpositive(-3.0), 0.125);
        assert!(exp2_nonpositive(-1e6) <= 2f32.powi(-126));
    }
}
