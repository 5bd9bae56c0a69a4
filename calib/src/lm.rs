//! A small Levenberg–Marquardt least-squares solver with a numerical
//! Jacobian, for refining poses: one camera's (six parameters, a few dozen
//! residuals) and a panorama's small rotations of every camera but one (a
//! few parameters a camera, some hundred residuals).

use nalgebra::{DMatrix, DVector};

/// Minimises `Σ r(x)²` from `x0`; `r` returns `None` where the model is not
/// defined (the step is then rejected). Returns the best `x` and its cost,
/// once a step no longer lowers the cost (to machine precision) or after
/// `iterations`.
pub fn minimise<F>(x0: &[f64], r: F, iterations: usize) -> (Vec<f64>, f64)
where
    F: FnMut(&[f64]) -> Option<Vec<f64>>,
{
    minimise_to(x0, r, iterations, 1e-15)
}

/// [`minimise`], stopping once a step lowers the cost by less than
/// `rel_tol` of it: a first solution whose last digits do not matter.
pub fn minimise_to<F>(x0: &[f64], mut r: F, iterations: usize, rel_tol: f64) -> (Vec<f64>, f64)
where
    F: FnMut(&[f64]) -> Option<Vec<f64>>,
{
    let n = x0.len();
    let mut x = x0.to_vec();
    let Some(mut res) = r(&x) else {
        return (x, f64::INFINITY);
    };
    let mut cost: f64 = res.iter().map(|v| v * v).sum();
    let mut lambda = 1e-3;
    for _ in 0..iterations {
        let m = res.len();
        let mut jac = DMatrix::<f64>::zeros(m, n);
        let mut ok = true;
        for j in 0..n {
            let h = 1e-7 * x[j].abs().max(1e-3);
            let mut xp = x.clone();
            let mut xm = x.clone();
            xp[j] += h;
            xm[j] -= h;
            match (r(&xp), r(&xm)) {
                (Some(a), Some(b)) if a.len() == m && b.len() == m => {
                    for i in 0..m {
                        jac[(i, j)] = (a[i] - b[i]) / (2.0 * h);
                    }
                }
                _ => ok = false,
            }
        }
        if !ok {
            break;
        }
        let rv = DVector::from_vec(res.clone());
        let jt = jac.transpose();
        let jtj = &jt * &jac;
        let g = &jt * &rv;
        let mut improved = false;
        for _ in 0..20 {
            let mut a = jtj.clone();
            for d in 0..n {
                a[(d, d)] += lambda * jtj[(d, d)].max(1e-12);
            }
            let Some(step) = a.lu().solve(&(-&g)) else {
                lambda *= 10.0;
                continue;
            };
            let xn: Vec<f64> = x.iter().zip(step.iter()).map(|(a, b)| a + b).collect();
            if let Some(rn) = r(&xn) {
                let cn: f64 = rn.iter().map(|v| v * v).sum();
                if cn < cost {
                    let small = step.norm() <= 1e-14 * (1.0 + DVector::from_vec(x.clone()).norm());
                    x = xn;
                    res = rn;
                    let rel = (cost - cn) / cost.max(1e-300);
                    cost = cn;
                    lambda = (lambda / 10.0).max(1e-12);
                    improved = !(small || rel < rel_tol);
                    break;
                }
            }
            lambda *= 10.0;
        }
        if !improved {
            break;
        }
    }
    (x, cost)
}

#[cfg(test)]
mod tests {
    #[test]
    fn fits_a_curve() {
        // y = a·exp(b·t) through exact data.
        let t: Vec<f64> = (0..10).map(f64::from).map(|v| v * 0.1).collect();
        let y: Vec<f64> = t.iter().map(|t| 2.0 * (0.5 * t).exp()).collect();
        let (x, cost) = super::minimise(
            &[1.0, 0.0],
            |p| {
                Some(
                    t.iter()
                        .zip(&y)
                        .map(|(t, y)| p[0] * (p[1] * t).exp() - y)
                        .collect(),
                )
            },
            100,
        );
        assert!(
            (x[0] - 2.0).abs() < 1e-8 && (x[1] - 0.5).abs() < 1e-8,
            "{x:?}"
        );
        assert!(cost < 1e-16);
    }
}
