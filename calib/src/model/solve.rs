//! The numerical tools every model shares: where a mapping stops
//! increasing (its validity limit, kept per thread), and its inversion by
//! a safeguarded Newton's method.

/// The first root in (0, limit] of an increasing-at-zero function's
/// derivative `d`, or `limit` if it has none there: scanned in `steps`
/// steps, then bisected to full precision.
pub(super) fn first_stationary(d: impl Fn(f64) -> f64, limit: f64, steps: usize) -> f64 {
    let mut prev = 0.0;
    for i in 1..=steps {
        let x = limit * i as f64 / steps as f64;
        if d(x) <= 0.0 {
            let (mut lo, mut hi) = (prev, x);
            for _ in 0..200 {
                let mid = 0.5 * (lo + hi);
                if mid <= lo || mid >= hi {
                    break;
                }
                if d(mid) > 0.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
            return lo;
        }
        prev = x;
    }
    limit
}

/// How many validity limits each thread keeps: a rig's cameras, projected
/// in turn (as the surround view does, point by point), each scan once.
const LIMIT_SLOTS: usize = 8;

type LimitSlots = ([(Family, [u64; 8], f64); LIMIT_SLOTS], usize);

thread_local! {
    /// The validity limits last computed on this thread, by model family
    /// and coefficient bits, and the slot to fill next.
    static LIMIT_CACHE: std::cell::RefCell<LimitSlots> = const {
        std::cell::RefCell::new(([(Family::Fisheye, [0; 8], f64::NAN); LIMIT_SLOTS], 0))
    };
}

/// Which validity limit a cache entry holds.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(super) enum Family {
    Fisheye,
    Pinhole,
    Poly,
    Ocam,
}

pub(super) fn cached(family: Family, k: &[f64], compute: impl FnOnce() -> f64) -> f64 {
    let mut key = [0; 8];
    for (b, v) in key.iter_mut().zip(k) {
        *b = v.to_bits();
    }
    let hit = LIMIT_CACHE.with_borrow(|(slots, _)| {
        slots
            .iter()
            .find(|(f, bits, v)| *f == family && *bits == key && !v.is_nan())
            .map(|s| s.2)
    });
    if let Some(v) = hit {
        return v;
    }
    let v = compute();
    LIMIT_CACHE.with_borrow_mut(|(slots, next)| {
        slots[*next] = (family, key, v);
        *next = (*next + 1) % LIMIT_SLOTS;
    });
    v
}

/// The x in [0, hi] where an increasing function `f` (giving its value and
/// derivative) reaches `target` (safeguarded Newton, bisecting whenever a
/// step leaves the bracket); `hi` if `target` is beyond `f(hi)`.
///
/// It stops when `f(x)` is `target` or a step is within 4 ε of x (relative,
/// or absolute below 1): Newton's last steps then only move between a few
/// neighbouring floats. A tolerance below one unit in the last place is
/// never met in [0.5, 1), and the loop would bisect its wide bracket again
/// and again: up to 60 steps on the surround-nz lens, against 2 to 6.
pub(super) fn invert_increasing(f: impl Fn(f64) -> (f64, f64), target: f64, hi: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, hi);
    let mut t = target.min(hi);
    for _ in 0..100 {
        let (v, d) = f(t);
        let e = v - target;
        if e == 0.0 {
            return t;
        }
        if e > 0.0 {
            hi = t;
        } else {
            lo = t;
        }
        let mut next = t - e / d;
        if !(next > lo && next < hi) || d <= 0.0 {
            next = 0.5 * (lo + hi);
        }
        if (next - t).abs() <= 4.0 * f64::EPSILON * t.max(1.0) {
            return next;
        }
        t = next;
    }
    t
}
