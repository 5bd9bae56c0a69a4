//! Order statistics of samples: the median and nearest-rank quantiles.
//!
//! One definition for every part that summarises a sample (balancing's
//! patch ratios, the panorama's epipolar errors, the light tracker's pixel
//! ratios, the app's reports), so that a median means the same thing
//! everywhere:
//!
//! - [`median`] is the middle value, or the mean of the two middle values
//!   for an even count;
//! - [`quantile`] is the nearest rank: the value at position
//!   `round((n − 1)·q)` of the sorted sample, `q` clamped to [0, 1] (so
//!   `quantile(v, 0.5)` of an even count is the upper middle value, not
//!   the median's mean).
//!
//! [`quantiles`] gives several quantiles of one sample, each selected
//! among the values the last one left above it.
//!
//! All order by `total_cmp`, so a NaN in the sample sorts to one end
//! (above every number when positive, below when negative) instead of
//! making the order depend on where it sits. All reorder the slice they
//! are given (a selection, O(n), not a sort) and give `None` for an empty
//! one, so that each caller says what an empty sample means to it.

use std::cmp::Ordering;

/// A sample value with a total order (`f32`, `f64`).
pub trait Sample: Copy {
    /// IEEE 754 `totalOrder`, as `f64::total_cmp`.
    fn total_cmp(&self, other: &Self) -> Ordering;
}

impl Sample for f32 {
    fn total_cmp(&self, other: &Self) -> Ordering {
        f32::total_cmp(self, other)
    }
}

impl Sample for f64 {
    fn total_cmp(&self, other: &Self) -> Ordering {
        f64::total_cmp(self, other)
    }
}

/// The `k`-th smallest of `values` (reordered around it); `k` < len.
fn select<T: Sample>(values: &mut [T], k: usize) -> T {
    *values.select_nth_unstable_by(k, T::total_cmp).1
}

/// The median of `values` (reordered): the middle value, or the mean of
/// the two middle values for an even count; `None` when empty.
pub fn median(values: &mut [f64]) -> Option<f64> {
    let n = values.len();
    if n == 0 {
        return None;
    }
    let upper = select(values, n / 2);
    if n % 2 == 1 {
        return Some(upper);
    }
    // After the selection every value left of n/2 is at most `upper`: the
    // lower middle value is the largest of them.
    let lower = values[..n / 2]
        .iter()
        .copied()
        .max_by(f64::total_cmp)
        .unwrap_or(upper);
    Some(0.5 * (lower + upper))
}

/// The `q`-quantile of `values` (reordered) by nearest rank: the value at
/// position `round((n − 1)·q)` in sorted order, `q` clamped to [0, 1];
/// `None` when empty.
pub fn quantile<T: Sample>(values: &mut [T], q: f64) -> Option<T> {
    let last = values.len().checked_sub(1)?;
    let k = (last as f64 * q.clamp(0.0, 1.0)).round() as usize;
    Some(select(values, k.min(last)))
}

/// The `qs`-quantiles of `values` (reordered) by nearest rank, as
/// [`quantile`] gives each; `None` when empty. In ascending order each
/// selection is made among the values above the last one's rank only.
pub fn quantiles<T: Sample, const N: usize>(values: &mut [T], qs: [f64; N]) -> Option<[T; N]> {
    let last = values.len().checked_sub(1)?;
    let mut out = [*values.first()?; N];
    // The rank selected last, and its value: every value before it is at
    // most that, every value after it at least.
    let mut prev: Option<(usize, T)> = None;
    for (o, q) in out.iter_mut().zip(qs) {
        let k = ((last as f64 * q.clamp(0.0, 1.0)).round() as usize).min(last);
        *o = match prev {
            Some((p, v)) if p == k => v,
            Some((p, _)) if p < k => select(&mut values[p + 1..], k - p - 1),
            _ => select(values, k),
        };
        prev = Some((k, *o));
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The definitions these replace, sorting a copy: the median with the
    /// mean of the middle pair, the quantile by nearest rank.
    fn sorted_median(v: &[f64]) -> Option<f64> {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        let n = v.len();
        (n > 0).then(|| {
            if n % 2 == 1 {
                v[n / 2]
            } else {
                0.5 * (v[n / 2 - 1] + v[n / 2])
            }
        })
    }

    fn sorted_quantile(v: &[f64], q: f64) -> Option<f64> {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        (!v.is_empty()).then(|| v[((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize])
    }

    #[test]
    fn known_samples() {
        assert_eq!(median(&mut [3.0, 1.0, 2.0]), Some(2.0));
        assert_eq!(median(&mut [4.0, 1.0, 3.0, 2.0]), Some(2.5));
        assert_eq!(median(&mut []), None);
        let mut v = [5.0, 1.0, 4.0, 2.0, 3.0];
        assert_eq!(quantile(&mut v, 0.5), Some(3.0));
        assert_eq!(quantile(&mut v, 1.0), Some(5.0));
        assert_eq!(quantile(&mut v, 7.0), Some(5.0));
        assert_eq!(quantile(&mut v, -1.0), Some(1.0));
        // Nearest rank: the upper middle value of an even count.
        assert_eq!(quantile(&mut [1.0, 2.0, 3.0, 4.0], 0.5), Some(3.0));
        assert_eq!(quantile::<f32>(&mut [], 0.5), None);
        assert_eq!(quantile(&mut [2.0f32, 1.0, 3.0], 0.25), Some(2.0));
    }

    #[test]
    fn the_selection_gives_the_sorts_values_bit_for_bit() {
        // Pseudo-random samples of every length up to 40, with repeats,
        // signed zeros and NaNs of both signs.
        let mut state = 0x2545_f491_4f6c_dd1d_u64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state
        };
        for n in 0..40 {
            for _ in 0..20 {
                let v: Vec<f64> = (0..n)
                    .map(|_| match next() % 16 {
                        0 => f64::NAN,
                        1 => -f64::NAN,
                        2 => 0.0,
                        3 => -0.0,
                        4 => 1.0,
                        r => (r as f64 - 8.0) * (next() % 1000) as f64 / 7.0,
                    })
                    .collect();
                let bits = |x: Option<f64>| x.map(f64::to_bits);
                assert_eq!(bits(median(&mut v.clone())), bits(sorted_median(&v)));
                for q in [0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 0.95, 0.99, 1.0] {
                    assert_eq!(
                        bits(quantile(&mut v.clone(), q)),
                        bits(sorted_quantile(&v, q))
                    );
                }
                // Several at once, ascending, repeated and out of order.
                for qs in [
                    [0.25, 0.5, 0.75],
                    [0.1, 0.1, 0.9],
                    [0.75, 0.25, 0.5],
                    [0.0, 1.0, 0.99],
                ] {
                    let got = quantiles(&mut v.clone(), qs).map(|q| q.map(f64::to_bits));
                    let want =
                        (n > 0).then(|| qs.map(|q| sorted_quantile(&v, q).map_or(0, f64::to_bits)));
                    assert_eq!(got, want, "{qs:?} of {n}");
                }
            }
        }
    }
}
