//! Exposure balancing between cameras that overlap (Eq. 5 and 6).
//!
//! For camera `i` with neighbours `G(i)`:
//!
//! ```text
//! E*_{t+1,i} = argmin_X α_i·(X − E_{t+1,i})² + (1 − α_i)/N · Σ_j (X − r_ij·E*_{t,i})²
//!            = α_i·E_{t+1,i} + (1 − α_i)·mean_j(r_ij)·E*_{t,i}
//! r_ij       = median over overlap patches p of mean(p_j) / (mean(p_i) + ε)
//! α_i        = (1 − R_i) + 0.5 if R_i < 1,   R_i / 2 otherwise,
//! R_i        = E_{t+1,i} / E_{t,i} clamped to [0.5, 2]
//! ```
//!
//! Patches in which either camera is saturated or nearly black say nothing
//! about the brightness ratio and are left out.

use serde::{Deserialize, Serialize};

use crate::error::{check_range, Error, Result};

/// Parameters of the balancing.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct BalanceParams {
    /// ε of Eq. 5, in intensity units.
    pub epsilon: f64,
    /// A patch whose saturated fraction exceeds this in either camera is left out.
    pub max_saturated: f64,
    /// A patch whose mean is below this in either camera is left out.
    pub min_mean: f64,
    /// A pair needs at least this many usable patches to give `r_ij`.
    pub min_patches: usize,
}

impl Default for BalanceParams {
    fn default() -> Self {
        Self {
            epsilon: 1e-3,
            max_saturated: 0.05,
            min_mean: 0.01,
            min_patches: 1,
        }
    }
}

impl BalanceParams {
    /// Checks the parameters.
    pub fn validate(&self) -> Result<()> {
        check_range(
            "balance.epsilon",
            self.epsilon,
            0.0,
            0.5,
            "a number in [0, 0.5]",
        )?;
        check_range(
            "balance.max_saturated",
            self.max_saturated,
            0.0,
            1.0,
            "a fraction in [0, 1]",
        )?;
        check_range(
            "balance.min_mean",
            self.min_mean,
            0.0,
            0.5,
            "a mean in [0, 0.5]",
        )?;
        if self.min_patches == 0 {
            return Err(Error::InvalidParameter {
                name: "balance.min_patches",
                value: 0.0,
                expected: "at least 1",
            });
        }
        Ok(())
    }
}

/// One overlap patch as both cameras see it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct PatchPair {
    /// Mean intensity in camera `i`.
    pub mean_i: f32,
    /// Saturated fraction in camera `i`.
    pub saturated_i: f32,
    /// Mean intensity in camera `j`.
    pub mean_j: f32,
    /// Saturated fraction in camera `j`.
    pub saturated_j: f32,
}

/// `r_ij` (Eq. 5) from the patches of one pair, or `None` when fewer than
/// `min_patches` are usable.
pub fn pair_ratio(patches: &[PatchPair], params: &BalanceParams) -> Option<f64> {
    let mut ratios: Vec<f64> = patches
        .iter()
        .filter(|p| {
            f64::from(p.saturated_i) <= params.max_saturated
                && f64::from(p.saturated_j) <= params.max_saturated
                && f64::from(p.mean_i) >= params.min_mean
                && f64::from(p.mean_j) >= params.min_mean
        })
        .map(|p| f64::from(p.mean_j) / (f64::from(p.mean_i) + params.epsilon))
        .filter(|r| r.is_finite())
        .collect();
    if ratios.len() < params.min_patches {
        return None;
    }
    Some(median(&mut ratios))
}

/// The median (mean of the two middle values for an even count).
pub fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n == 0 {
        return f64::NAN;
    }
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// α of Eq. 6 for the unary ratio `R = E_{t+1}/E_t` (clamped to [0.5, 2]).
pub fn alpha(unary_ratio: f64) -> f64 {
    let r = if unary_ratio.is_nan() {
        1.0
    } else {
        unary_ratio.clamp(0.5, 2.0)
    };
    if r < 1.0 {
        (1.0 - r) + 0.5
    } else {
        r / 2.0
    }
}

/// The closed-form minimiser of Eq. 5.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Balanced {
    /// The balanced exposure `E*_{t+1}`.
    pub exposure: f64,
    /// α used.
    pub alpha: f64,
    /// Mean of the neighbours' `r_ij`.
    pub mean_ratio: f64,
}

/// Solves Eq. 5 for one camera: `unary` is `E_{t+1,i}`, `current` is
/// `E*_{t,i}` (the exposure its frame was taken with), `ratios` the `r_ij`
/// of its neighbours that have one. With no ratios the unary stands.
pub fn balance(unary: f64, current: f64, ratios: &[f64]) -> Balanced {
    if ratios.is_empty() || current <= 0.0 {
        return Balanced {
            exposure: unary,
            alpha: 1.0,
            mean_ratio: 1.0,
        };
    }
    let a = alpha(unary / current);
    let mean_ratio = ratios.iter().sum::<f64>() / ratios.len() as f64;
    Balanced {
        exposure: a * unary + (1.0 - a) * mean_ratio * current,
        alpha: a,
        mean_ratio,
    }
}

/// Which cameras overlap: an undirected graph over camera indices.
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub struct NeighbourGraph {
    cameras: usize,
    edges: Vec<(usize, usize)>,
}

impl NeighbourGraph {
    /// A graph over `cameras` cameras; each edge `(i, j)` with `i ≠ j`,
    /// both in range. Duplicate edges (in either order) are merged.
    pub fn new(cameras: usize, edges: &[(usize, usize)]) -> Result<Self> {
        let mut out: Vec<(usize, usize)> = Vec::with_capacity(edges.len());
        for &(i, j) in edges {
            for k in [i, j] {
                if k >= cameras {
                    return Err(Error::CameraIndex {
                        index: k,
                        count: cameras,
                    });
                }
            }
            if i == j {
                return Err(Error::InvalidConfig(format!(
                    "neighbour graph: camera {i} cannot be its own neighbour"
                )));
            }
            let e = (i.min(j), i.max(j));
            if !out.contains(&e) {
                out.push(e);
            }
        }
        Ok(Self {
            cameras,
            edges: out,
        })
    }

    /// A ring `0–1–…–(n−1)–0` (the reference rig's four cameras).
    pub fn ring(cameras: usize) -> Result<Self> {
        let edges: Vec<(usize, usize)> = match cameras {
            0 | 1 => Vec::new(),
            2 => vec![(0, 1)],
            n => (0..n).map(|i| (i, (i + 1) % n)).collect(),
        };
        Self::new(cameras, &edges)
    }

    /// Number of cameras.
    pub fn cameras(&self) -> usize {
        self.cameras
    }

    /// The edges, each once with `i < j`.
    pub fn edges(&self) -> &[(usize, usize)] {
        &self.edges
    }

    /// The neighbours of camera `i`.
    pub fn neighbours(&self, i: usize) -> impl Iterator<Item = usize> + '_ {
        self.edges.iter().filter_map(move |&(a, b)| {
            if a == i {
                Some(b)
            } else if b == i {
                Some(a)
            } else {
                None
            }
        })
    }
}
