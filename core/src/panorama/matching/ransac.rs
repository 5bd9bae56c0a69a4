//! RANSAC over a band's matches: a model of the two cameras' relative
//! rotation (their centres known), scored by the epipolar error of each
//! match and, for matches on the ground, by where the ground puts them.

use super::*;

/// A match as two rays: camera `i`'s and camera `j`'s (unit, vehicle
/// frame).
pub(in crate::panorama) type RayPair = (Vector3<f64>, Vector3<f64>);

/// Two cameras' centres, for the epipolar error of their matches.
#[derive(Clone, Copy, Debug)]
pub(in crate::panorama) struct PairGeometry {
    pub(super) o_i: Vector3<f64>,
    pub(super) o_j: Vector3<f64>,
    /// Canvas pixels per radian of azimuth.
    pub(super) px_per_rad: f64,
}

impl PairGeometry {
    /// The unit normal of the epipolar plane of ray `f_i`, or `None` along
    /// the baseline.
    fn normal(&self, f_i: &Vector3<f64>) -> Option<Vector3<f64>> {
        let n = (self.o_j - self.o_i).cross(f_i);
        let norm = n.norm();
        (norm > 1e-9).then(|| n / norm)
    }

    /// The reprojection error of rays `f_i` and `f_j`: the angle of `f_j`
    /// from the epipolar plane of `f_i`, canvas pixels; `None` when the
    /// rays meet behind a camera.
    pub(in crate::panorama) fn error_px(
        &self,
        f_i: &Vector3<f64>,
        f_j: &Vector3<f64>,
    ) -> Option<f64> {
        if !self.in_front(f_i, f_j) {
            return None;
        }
        self.signed_error_px(f_i, f_j).map(f64::abs)
    }

    /// The same with its sign (which side of the plane), whether or not
    /// the rays meet in front of the cameras.
    pub(in crate::panorama) fn signed_error_px(
        &self,
        f_i: &Vector3<f64>,
        f_j: &Vector3<f64>,
    ) -> Option<f64> {
        let n = self.normal(f_i)?;
        Some(n.dot(f_j).clamp(-1.0, 1.0).asin() * self.px_per_rad)
    }

    /// The two-dimensional errors of rays `f_i` and `f_j` as a point on the
    /// ground (z = 0): where each meets the ground, seen from the other
    /// camera, against the other's ray (`f × d`, canvas pixels per
    /// radian). `None` unless both rays meet the ground within
    /// [`GROUND_REACH_M`].
    pub(in crate::panorama) fn ground_errors_px(
        &self,
        f_i: &Vector3<f64>,
        f_j: &Vector3<f64>,
    ) -> Option<[Vector3<f64>; 2]> {
        let x_i = ground_hit(&self.o_i, f_i)?;
        let x_j = ground_hit(&self.o_j, f_j)?;
        let seen = |f: &Vector3<f64>, o: &Vector3<f64>, x: &Vector3<f64>| {
            f.cross(&(x - o).normalize()) * self.px_per_rad
        };
        Some([seen(f_j, &self.o_j, &x_i), seen(f_i, &self.o_i, &x_j)])
    }

    /// The larger of [`PairGeometry::ground_errors_px`]'s two errors'
    /// lengths.
    pub(in crate::panorama) fn ground_error_px(
        &self,
        f_i: &Vector3<f64>,
        f_j: &Vector3<f64>,
    ) -> Option<f64> {
        let [a, b] = self.ground_errors_px(f_i, f_j)?;
        Some(a.norm().max(b.norm()))
    }

    /// Whether the rays' closest points lie ahead of both cameras (rays
    /// parallel within 10⁻⁹, or meeting beyond 1 km, count as ahead: a
    /// point at infinity).
    fn in_front(&self, f_i: &Vector3<f64>, f_j: &Vector3<f64>) -> bool {
        let w = self.o_i - self.o_j;
        let b = f_i.dot(f_j);
        let (d, e) = (f_i.dot(&w), f_j.dot(&w));
        let denom = 1.0 - b * b;
        if denom < 1e-9 {
            return true;
        }
        let s = (b * e - d) / denom;
        let u = (e - b * d) / denom;
        let far = |v: f64| v.abs() > 1e3;
        (s > 0.0 || far(s)) && (u > 0.0 || far(u))
    }
}

/// How far from its camera (metres) a ray may meet the ground to be taken
/// for a point on it.
pub(in crate::panorama) const GROUND_REACH_M: f64 = 30.0;

/// Where ray `f` from `o` meets the ground (z = 0), within
/// [`GROUND_REACH_M`] ahead.
fn ground_hit(o: &Vector3<f64>, f: &Vector3<f64>) -> Option<Vector3<f64>> {
    if f.z >= 0.0 || o.z <= 0.0 {
        return None;
    }
    let s = -o.z / f.z;
    (s <= GROUND_REACH_M).then(|| o + f * s)
}

/// The prior's standard deviation on a pair's rotation, degrees.
const PRIOR_DEG: f64 = 0.5;

/// The rotation of camera `j` that puts the matches `rays` (pairs of rays
/// `f_i`, `f_j`) on their epipolar planes, by robust least squares (a
/// Cauchy loss) with a prior towards no rotation, from `start` (four
/// reweighted Gauss–Newton steps); `None` when a ray lies along the
/// baseline.
pub(super) fn fit_rotation(
    geometry: &PairGeometry,
    rays: &[RayPair],
    start: Rotation3<f64>,
) -> Option<Rotation3<f64>> {
    // Matches in one narrow overlap at similar depths fix some rotations
    // far better than others (a turn about the overlap's own direction
    // hardly moves a ray off its plane): a prior of σ = PRIOR_DEG on the
    // rotation keeps the weakly seen ones near none, against errors of
    // σ = 1 canvas pixel.
    // Each match is weighed by the Cauchy loss of its error (scale: one
    // canvas pixel), so that a few matches a pixel or two off do not turn
    // the camera.
    let prior = (1.0 / (geometry.px_per_rad * PRIOR_DEG.to_radians())).powi(2);
    let scale = 1.0 / geometry.px_per_rad;
    let mut q = start;
    for _ in 0..4 {
        let mut jtj = Matrix3::identity() * prior;
        let mut jtr = q.scaled_axis() * prior;
        for (f_i, f_j) in rays {
            let n = geometry.normal(f_i)?;
            let f = q * f_j;
            let row = f.cross(&n);
            let r = n.dot(&f);
            let weight = 1.0 / (1.0 + (r / scale).powi(2));
            jtj += weight * row * row.transpose();
            jtr += weight * row * r;
        }
        let omega = jtj.try_inverse()? * -jtr;
        if !omega.iter().all(|v| v.is_finite()) {
            return None;
        }
        q = Rotation3::new(omega) * q;
    }
    Some(q)
}

/// RANSAC of camera `j`'s rotation over the matches (`rays` of each), with
/// the inliers marked in `matches`.
pub(super) fn ransac(
    geometry: &PairGeometry,
    rays: &[RayPair],
    matches: &mut [FeatureMatch],
    options: &MatchOptions,
) -> Option<Rotation3<f64>> {
    let n = rays.len();
    if n < 3 {
        return None;
    }
    let inlier = |q: &Rotation3<f64>, (f_i, f_j): &RayPair| {
        geometry
            .error_px(f_i, &(q * f_j))
            .filter(|&e| e <= options.ransac_px)
    };
    let score = |q: &Rotation3<f64>| -> (usize, f64) {
        rays.iter().fold((0, 0.0), |(c, s), r| match inlier(q, r) {
            Some(e) => (c + 1, s + e),
            None => (c, s),
        })
    };
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(options.seed);
    let mut best: Option<(Rotation3<f64>, (usize, f64))> = None;
    for _ in 0..options.iterations {
        let sample = [
            rng.gen_range(0..n),
            rng.gen_range(0..n),
            rng.gen_range(0..n),
        ];
        if sample[0] == sample[1] || sample[1] == sample[2] || sample[0] == sample[2] {
            continue;
        }
        let picked = sample.map(|k| rays[k]);
        let Some(q) = fit_rotation(geometry, &picked, Rotation3::identity()) else {
            continue;
        };
        let s = score(&q);
        if best
            .as_ref()
            .is_none_or(|(_, b)| s.0 > b.0 || (s.0 == b.0 && s.1 < b.1))
        {
            best = Some((q, s));
        }
    }
    let (mut q, _) = best?;
    for _ in 0..2 {
        let kept: Vec<_> = rays
            .iter()
            .filter(|r| inlier(&q, r).is_some())
            .copied()
            .collect();
        match fit_rotation(geometry, &kept, q) {
            Some(refit) if kept.len() >= 3 => q = refit,
            _ => break,
        }
    }
    for (m, r) in matches.iter_mut().zip(rays) {
        m.inlier = inlier(&q, r).is_some();
    }
    Some(q)
}
