//! A camera's tone curve, for scale-and-clip on frames that are not linear.
//!
//! Scale-and-clip simulates a change of exposure as `min(1, s·I)`, which is
//! what a linear sensor does. Many 8-bit cameras (and every display-referred
//! image) pass the sensor's values through a tone curve `I = f(L)` first:
//! then scaling `I` mispredicts the frame at `s` times the exposure (on a
//! real 8-bit bracket whose curve is close to `L^(1/4.4)` it rested
//! 1.1–1.3 EV too bright, docs/exposure-results.md). With the curve known,
//! the frame at `s` is `f(min(1, s·f⁻¹(I)))`: exact for an unclipped pixel
//! up to the curve's accuracy. A pure power curve `f(L) = L^(1/p)` makes
//! this `min(1, s^(1/p)·I)`.
//!
//! The light tracking ([`super::light`]) reads values as light through the
//! same curve, under either simulation: under a tone curve `I/E` changes
//! with the exposure alone.
//!
//! The curve comes from the source where it knows it (a bracket sequence's
//! recovered response, [`crate::source::CameraInfo::tone_curve`]) or from
//! the settings (`processing.controller.estimator.tone_curve`: an exponent,
//! or a table).

use serde::{Deserialize, Serialize};

use crate::error::{Error, Result};

/// Entries of the lookup a simulated exposure change is applied through.
pub(crate) const TABLE_BINS: usize = 1024;

/// The value at `v` (clamped to `[0, 1]`) of a lookup of at least two
/// values at inputs evenly spaced over `[0, 1]`, interpolated linearly
/// ([`ToneCurve::lookup`], [`ToneCurve::linear_lookup`]).
#[inline(always)]
pub(crate) fn interpolate(table: &[f32], v: f32) -> f32 {
    let last = table.len() - 1;
    let x = v.clamp(0.0, 1.0) * last as f32;
    // `as` saturates (and maps NaN to 0); `min` keeps i + 1 in the table.
    let i = (x as usize).min(last - 1);
    let (a, b) = (table[i], table[i + 1]);
    a + (x - i as f32) * (b - a)
}

/// How a recorded value `I` in `[0, 1]` relates to the light `L` in
/// `[0, 1]` (both scaled so that full scale is 1).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum ToneCurve {
    /// `L = I^p` (`I = L^(1/p)`): a display gamma `p` (2.2 for sRGB-like
    /// curves).
    Power(f64),
    /// `L` at recorded values evenly spaced from 0 to 1 (at least two,
    /// non-decreasing, the last 1), interpolated linearly between them.
    Table(Vec<f64>),
}

impl ToneCurve {
    /// The curve of an 8-bit response: the linear value of each code
    /// 0..=255 (any scale, non-decreasing).
    pub fn from_code_values(values: &[f32]) -> Result<Self> {
        let top = values.iter().copied().fold(0.0f32, f32::max);
        if values.len() < 2 || top <= 0.0 || values.iter().any(|v| !v.is_finite()) {
            return Err(Error::invalid(
                "a tone curve",
                "values",
                "at least two finite values, one above zero",
                format_args!("{} values", values.len()),
            ));
        }
        let curve = Self::Table(
            values
                .iter()
                .map(|&v| f64::from(v.max(0.0) / top))
                .collect(),
        );
        curve.validate()?;
        Ok(curve)
    }

    /// Checks the curve: a power in (0, 10], or a table as described.
    pub fn validate(&self) -> Result<()> {
        match self {
            Self::Power(p) => {
                if !(p.is_finite() && *p > 0.0 && *p <= 10.0) {
                    return Err(Error::InvalidParameter {
                        name: "tone_curve",
                        value: *p,
                        expected: "a power in (0, 10] (2.2 for an sRGB-like curve)",
                    });
                }
            }
            Self::Table(t) => {
                let ordered = t.windows(2).all(|w| w[0] <= w[1]);
                let finite = t.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v));
                let ends = t.last().is_some_and(|&v| (v - 1.0).abs() < 1e-9);
                if t.len() < 2 || !ordered || !finite || !ends {
                    return Err(Error::invalid(
                        "estimator",
                        "tone_curve",
                        "a table of at least two non-decreasing linear values in [0, 1] \
                         ending at 1, or a power",
                        format_args!("{} values", t.len()),
                    ));
                }
            }
        }
        Ok(())
    }

    /// The light of a recorded value.
    pub fn linear(&self, recorded: f64) -> f64 {
        let v = recorded.clamp(0.0, 1.0);
        match self {
            Self::Power(p) => v.powf(*p),
            Self::Table(t) => {
                let last = t.len() - 1;
                let x = v * last as f64;
                let i = (x.floor() as usize).min(last - 1);
                let f = x - i as f64;
                t[i] + f * (t[i + 1] - t[i])
            }
        }
    }

    /// The recorded value of the light `linear` (the first, where the
    /// table is flat).
    pub fn recorded(&self, linear: f64) -> f64 {
        let l = linear.clamp(0.0, 1.0);
        match self {
            Self::Power(p) => l.powf(1.0 / *p),
            Self::Table(t) => {
                let last = t.len() - 1;
                // The first entry at or above `l`; `t[last] = 1 ≥ l`.
                let above = t.partition_point(|&v| v < l).clamp(1, last);
                let (a, b) = (t[above - 1], t[above]);
                let f = if b > a { (l - a) / (b - a) } else { 0.0 };
                ((above - 1) as f64 + f.clamp(0.0, 1.0)) / last as f64
            }
        }
    }

    /// The curve of a GenICam camera whose gamma correction is on with
    /// `Gamma = gamma`: the SFNC outputs each normalised pixel value `P` as
    /// `P^Gamma` (0.4545 for sRGB output), so `L = I^(1/gamma)`. `None` at
    /// 1 (no change). A gamma that is not a positive number is refused,
    /// named as the camera's `Gamma` feature.
    pub fn from_genicam_gamma(gamma: f64) -> Result<Option<Self>> {
        if !(gamma.is_finite() && gamma > 0.0) {
            return Err(Error::InvalidParameter {
                name: "Gamma",
                value: gamma,
                expected: "a positive GenICam gamma (each pixel P output as P^Gamma)",
            });
        }
        if (gamma - 1.0).abs() < 1e-6 {
            return Ok(None);
        }
        let curve = Self::Power(1.0 / gamma);
        curve.validate()?;
        Ok(Some(curve))
    }

    /// The curve of a GenICam camera whose pixel lookup table is on
    /// (`LUTEnable`), read as `lut`: pairs of an input and its output value,
    /// both normalised to `[0, 1]`, inputs increasing (the camera's
    /// `LUTIndex` and `LUTValue` over their ranges). The SFNC applies the
    /// table after the gamma correction, so with `gamma` (the curve of the
    /// camera's gamma where it is on, [`ToneCurve::from_genicam_gamma`])
    /// the recorded value is `lut(gamma(L))`. The
    /// table's outputs must not fall (a falling table has no inverse: the
    /// error names `LUTValue`); recorded values below its first output are
    /// black and above its last full light. A table of `TABLE_BINS` light
    /// values at evenly spaced recorded values; `None` where the table and
    /// the gamma change nothing.
    pub fn from_genicam_lut(lut: &[(f64, f64)], gamma: Option<&Self>) -> Result<Option<Self>> {
        let bad = |what: String| {
            Err(Error::invalid(
                "camera",
                "LUTValue",
                "a pixel lookup table whose outputs do not fall as its inputs rise, \
                 over at least two entries in [0, 1]",
                what,
            ))
        };
        let finite = lut
            .iter()
            .all(|&(i, o)| (0.0..=1.0).contains(&i) && (0.0..=1.0).contains(&o));
        if lut.len() < 2 || !finite {
            return bad(format!("{} entries", lut.len()));
        }
        if let Some(w) = lut.windows(2).find(|w| w[1].0 <= w[0].0 || w[1].1 < w[0].1) {
            return bad(format!(
                "{:.4} at {:.4}, then {:.4} at {:.4}",
                w[0].1, w[0].0, w[1].1, w[1].0
            ));
        }
        let identity = lut.iter().all(|&(i, o)| (i - o).abs() < 1e-6)
            && lut.first().is_some_and(|f| f.0.abs() < 1e-9)
            && lut.last().is_some_and(|l| (l.0 - 1.0).abs() < 1e-9);
        if identity {
            return Ok(gamma.cloned());
        }
        // The table's input where its output reaches `r` (the first, where
        // it is flat), then the light of that input through the gamma.
        let input_of = |r: f64| -> f64 {
            let above = lut.partition_point(|&(_, o)| o < r);
            if above == 0 {
                return lut[0].0 * f64::from(u8::from(r >= lut[0].1));
            }
            let Some(&(i1, o1)) = lut.get(above) else {
                return 1.0;
            };
            let (i0, o0) = lut[above - 1];
            i0 + (i1 - i0) * if o1 > o0 { (r - o0) / (o1 - o0) } else { 0.0 }
        };
        let light = |input: f64| gamma.map_or(input, |g| g.linear(input));
        let last = (TABLE_BINS - 1) as f64;
        let mut table: Vec<f64> = (0..TABLE_BINS)
            .map(|k| light(input_of(k as f64 / last)).clamp(0.0, 1.0))
            .collect();
        // The top recorded value is full light, whatever the table reaches.
        if let Some(top) = table.last_mut() {
            *top = 1.0;
        }
        let curve = Self::Table(table);
        curve.validate()?;
        Ok(Some(curve))
    }

    /// The exponent `p` of the power curve `L = I^p` nearest the curve, by
    /// least squares in logarithms over recorded values from 32/255 to
    /// 224/255 (2.2 for a display gamma, 1 for a linear response); `None`
    /// for a table without such values above zero.
    pub fn nearest_power(&self) -> Option<f64> {
        let t = match self {
            Self::Power(p) => return Some(*p),
            Self::Table(t) => t,
        };
        let last = (t.len() - 1) as f64;
        let (mut sxx, mut sxy) = (0.0f64, 0.0f64);
        for (i, &l) in t.iter().enumerate() {
            let v = i as f64 / last;
            if !(32.0 / 255.0 - 1e-9..=224.0 / 255.0 + 1e-9).contains(&v) || l <= 0.0 {
                continue;
            }
            sxx += v.ln() * v.ln();
            sxy += v.ln() * l.ln();
        }
        (sxx > 0.0).then(|| sxy / sxx)
    }

    /// The light of [`TABLE_BINS`] recorded values evenly spaced over
    /// `[0, 1]`, for interpolating it pixel by pixel.
    pub(crate) fn linear_lookup(&self) -> Vec<f32> {
        (0..TABLE_BINS)
            .map(|i| self.linear(i as f64 / (TABLE_BINS - 1) as f64) as f32)
            .collect()
    }

    /// The lookup the kernels map a frame through to simulate `s` times
    /// its exposure: [`TABLE_BINS`] values at recorded values evenly spaced
    /// over `[0, 1]`, `f(min(1, s·f⁻¹(I)))`. With `hold`, values at or above
    /// it stay as they are (saturated pixels held under a darkening).
    pub(crate) fn lookup(&self, s: f64, hold: Option<f32>, out: &mut Vec<f32>) {
        out.clear();
        out.extend((0..TABLE_BINS).map(|i| {
            let v = i as f64 / (TABLE_BINS - 1) as f64;
            if hold.is_some_and(|h| v as f32 >= h) {
                v as f32
            } else {
                self.recorded((s * self.linear(v)).min(1.0)) as f32
            }
        }));
    }
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // exact values: the held and clipped ends
mod tests {
    use super::*;

    #[test]
    fn a_genicam_gamma_is_the_curves_reciprocal_power() {
        // sRGB output (Gamma 1/2.2): light is the recorded value to 2.2.
        let c = ToneCurve::from_genicam_gamma(1.0 / 2.2).unwrap().unwrap();
        assert!((c.nearest_power().unwrap() - 2.2).abs() < 1e-9);
        assert!((c.linear(0.5) - 0.5f64.powf(2.2)).abs() < 1e-12);
        // A gamma of 1 changes nothing; a gamma above 1 darkens.
        assert_eq!(ToneCurve::from_genicam_gamma(1.0).unwrap(), None);
        let dark = ToneCurve::from_genicam_gamma(2.0).unwrap().unwrap();
        assert!((dark.linear(0.25) - 0.5).abs() < 1e-12);
        for bad in [0.0, -0.45, f64::NAN, f64::INFINITY] {
            let e = ToneCurve::from_genicam_gamma(bad).unwrap_err().to_string();
            assert!(e.contains("Gamma"), "{e}");
        }
    }

    #[test]
    fn a_genicam_lut_composes_with_the_gamma_and_is_inverted() {
        // A table squaring its input: light is the recorded value's root.
        let square: Vec<(f64, f64)> = (0..=255)
            .map(|i| {
                let x = f64::from(i) / 255.0;
                (x, (x * x * 255.0).floor() / 255.0)
            })
            .collect();
        let c = ToneCurve::from_genicam_lut(&square, None).unwrap().unwrap();
        assert!((c.nearest_power().unwrap() - 0.5).abs() < 0.02, "{c:?}");
        for r in [0.1, 0.25, 0.5, 0.9] {
            assert!((c.linear(r) - r.sqrt()).abs() < 0.01, "{r}");
        }
        // After a gamma of 0.5 (I = L^0.5, then squared): linear again.
        let half = ToneCurve::from_genicam_gamma(0.5).unwrap();
        let both = ToneCurve::from_genicam_lut(&square, half.as_ref())
            .unwrap()
            .unwrap();
        for r in [0.1, 0.25, 0.5, 0.9] {
            assert!((both.linear(r) - r).abs() < 0.01, "{r}");
        }
        // An identity table changes nothing but the gamma's curve.
        let identity: Vec<(f64, f64)> = (0..=8)
            .map(|i| (f64::from(i) / 8.0, f64::from(i) / 8.0))
            .collect();
        assert_eq!(ToneCurve::from_genicam_lut(&identity, None).unwrap(), None);
        assert_eq!(
            ToneCurve::from_genicam_lut(
                &identity,
                ToneCurve::from_genicam_gamma(0.45).unwrap().as_ref()
            )
            .unwrap(),
            ToneCurve::from_genicam_gamma(0.45).unwrap()
        );
        // A table that stops at half scale: recorded values above it are
        // full light; one with an offset: below it, black.
        let half: Vec<(f64, f64)> = vec![(0.0, 0.0), (1.0, 0.5)];
        let c = ToneCurve::from_genicam_lut(&half, None).unwrap().unwrap();
        assert!((c.linear(0.25) - 0.5).abs() < 1e-3 && c.linear(0.75) == 1.0);
        let offset: Vec<(f64, f64)> = vec![(0.0, 0.2), (1.0, 1.0)];
        let c = ToneCurve::from_genicam_lut(&offset, None).unwrap().unwrap();
        assert!(c.linear(0.1) == 0.0 && (c.linear(0.6) - 0.5).abs() < 1e-3);
        // A falling table, or too short a one, is refused naming LUTValue.
        for bad in [vec![(0.0, 0.0), (0.5, 0.6), (1.0, 0.4)], vec![(0.0, 0.0)]] {
            let e = ToneCurve::from_genicam_lut(&bad, None)
                .unwrap_err()
                .to_string();
            assert!(e.contains("LUTValue"), "{e}");
        }
    }

    #[test]
    fn a_table_and_its_power_agree() {
        let p = 2.2;
        let table = ToneCurve::Table((0..=255).map(|c| (f64::from(c) / 255.0).powf(p)).collect());
        let power = ToneCurve::Power(p);
        table.validate().unwrap();
        for k in 0..=100 {
            let v = f64::from(k) / 100.0;
            assert!((table.linear(v) - power.linear(v)).abs() < 2e-3, "{v}");
            // The inverse of the interpolated table is exact on it.
            assert!((table.recorded(table.linear(v)) - v).abs() < 1e-9, "{v}");
            assert!((power.recorded(power.linear(v)) - v).abs() < 1e-12, "{v}");
        }
    }

    #[test]
    fn a_power_curve_scales_by_the_root() {
        // f(min(1, s·f⁻¹(I))) = min(1, s^(1/p)·I) for f(L) = L^(1/p).
        let mut lut = Vec::new();
        let (p, s) = (2.2, 0.6);
        ToneCurve::Power(p).lookup(s, None, &mut lut);
        assert_eq!(lut.len(), TABLE_BINS);
        for (i, &v) in lut.iter().enumerate() {
            let x = i as f64 / (TABLE_BINS - 1) as f64;
            assert!((f64::from(v) - (s.powf(1.0 / p) * x).min(1.0)).abs() < 1e-6);
        }
        // Held values stay.
        ToneCurve::Power(p).lookup(s, Some(0.99), &mut lut);
        assert_eq!(lut[TABLE_BINS - 1], 1.0);
        assert!(lut[TABLE_BINS - 20] < 0.99);
        // Brighter clips at 1.
        ToneCurve::Power(p).lookup(3.0, None, &mut lut);
        assert_eq!(lut[TABLE_BINS - 1], 1.0);
        assert!((f64::from(lut[100]) - 3f64.powf(1.0 / p) * 100.0 / 1023.0).abs() < 1e-6);
    }

    #[test]
    fn the_nearest_power_of_a_table() {
        for p in [1.0, 2.2, 4.4] {
            let t = ToneCurve::Table((0..=255).map(|c| (f64::from(c) / 255.0).powf(p)).collect());
            let got = t.nearest_power().unwrap();
            assert!((got - p).abs() < 1e-9, "{p}: {got}");
        }
        assert_eq!(ToneCurve::Power(1.8).nearest_power(), Some(1.8));
        let flat = ToneCurve::Table(vec![0.0, 0.0, 1.0]);
        assert_eq!(flat.nearest_power(), None);
    }

    #[test]
    fn bad_curves_are_refused() {
        for bad in [
            ToneCurve::Power(0.0),
            ToneCurve::Power(f64::NAN),
            ToneCurve::Power(11.0),
            ToneCurve::Table(vec![1.0]),
            ToneCurve::Table(vec![0.0, 0.5, 0.4, 1.0]),
            ToneCurve::Table(vec![0.0, 0.5]),
            ToneCurve::Table(vec![-0.1, 1.0]),
        ] {
            let e = bad.validate().unwrap_err().to_string();
            assert!(e.contains("tone_curve"), "{bad:?}: {e}");
        }
        assert!(ToneCurve::from_code_values(&[0.0; 256]).is_err());
        let c = ToneCurve::from_code_values(&[0.0, 2.0, 4.0]).unwrap();
        assert_eq!(c, ToneCurve::Table(vec![0.0, 0.5, 1.0]));
    }

    #[test]
    fn the_settings_name_a_power_or_a_table() {
        let p: ToneCurve = serde_norway::from_str("2.2").unwrap();
        assert_eq!(p, ToneCurve::Power(2.2));
        let t: ToneCurve = serde_norway::from_str("[0.0, 0.2, 1.0]").unwrap();
        assert_eq!(t, ToneCurve::Table(vec![0.0, 0.2, 1.0]));
    }
}
