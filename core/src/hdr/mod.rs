//! Exposure emulation from brackets (Gamache et al., "Exposing the
//! Unseen", IROS 2024): a moment's images of one camera at several
//! exposures are merged into each sample's radiance, and a frame is then
//! synthesised at any exposure a controller asks for, with the sensor's
//! noise, clipping and quantisation.
//!
//! # Merge ([`merge`])
//!
//! Every image `k` was taken at the exposure level `E_k = t_k · 10^(g_k/20)`
//! (µs at 0 dB). Each sample's value is first linearised by the
//! [`Response`] (the identity for raw data; an inverse response curve for
//! 8-bit non-linear data, [`Response::recover`]). Its radiance per unit
//! exposure level is then
//!
//! ```text
//! x = Σ_k w_k · v_k / E_k / Σ_k w_k,      w_k = E_k² / σ_k²(μ_k),     var(x) = 1 / Σ_k w_k
//! ```
//!
//! over the images `k` where the sample is neither clipped (`v_k` at or
//! above [`MergeConfig::clip_fraction`] of the image's top value) nor in
//! the noise floor (its predicted mean `μ_k = x₀·E_k` below
//! [`MergeConfig::floor_dn`]). `σ_k²(μ) = K g_k·μ + (K g_k σ_read)² + 1/12`
//! is the sensor's noise at that mean (EMVA 1288, [`crate::sim::Sensor`]:
//! `K = (2^bits − 1) / full_well` DN per electron), so the weights are the
//! inverse variances of `v_k / E_k`: the optimal linear merge, which leans on
//! the longest unclipped exposures. `x₀` is the pilot estimate from the
//! longest unclipped image, which also decides the floor, so the choice of
//! images does not depend on each image's own noise (no truncation bias).
//! A sample clipped in every image keeps the shortest image's `v / E` (a
//! lower bound: it stays clipped at every exposure at or above the
//! shortest); one in the floor everywhere keeps the longest image's.
//!
//! # Emulation ([`Radiance::emulate`])
//!
//! At a setting `(t, g)` with `E = t·10^(g/20)`, each sample's mean is
//! `μ = x·E` DN. The frame adds zero-mean Gaussian noise of variance
//! `max(0, σ²(μ) − E²·var(x))`, the sensor's noise at that mean less what
//! the estimate already carries (so an exposure equal to a bracket's is
//! not noisier than the bracket), with `σ²(μ) = K g·min(μ, K g·full_well) +
//! (K g σ_read)²`, clips at `min(2^bits − 1, K g·full_well)` and rounds to
//! the nearest integer (for a non-linear response, the linear value goes
//! through the forward response first). The noise comes from the
//! simulator's table of standard normal samples, read from a random offset
//! per row, the offsets drawn from a stream seeded by (seed, camera,
//! frame): an emulated frame is a pure function of its inputs.
//!
//! The per-command cost is one pass over the samples (a multiply, a square
//! root, a clamp and a store); the merge runs once per moment and camera.

mod emulate;
mod merge;
mod response;

pub use emulate::{EmulateOptions, Radiance};
pub use merge::{merge, MergeConfig, Shot};
pub use response::Response;

/// The noise of a sensor as the merge and the emulation use it: the
/// EMVA 1288 model of [`crate::sim::Sensor`] at a bit depth.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SensorNoise {
    /// DN per electron at 0 dB: `(2^bits − 1) / full_well`.
    pub k: f64,
    /// Read noise, electrons (rms).
    pub read_noise_e: f64,
    /// Full-well capacity, electrons.
    pub full_well_e: f64,
    /// The largest value: `2^bits − 1`.
    pub max_dn: f64,
    /// Bits of the values (8 to 16).
    pub bits: u32,
}

impl SensorNoise {
    /// The noise of `sensor` read out at `bits` bits (8 to 16).
    pub fn of(sensor: &crate::sim::Sensor, bits: u32) -> crate::Result<Self> {
        if !(1..=16).contains(&bits) {
            return Err(crate::Error::InvalidParameter {
                name: "bits",
                value: f64::from(bits),
                expected: "a bit depth from 1 to 16",
            });
        }
        if !(sensor.full_well_e.is_finite()
            && sensor.full_well_e >= 1.0
            && sensor.read_noise_e.is_finite()
            && sensor.read_noise_e >= 0.0)
        {
            return Err(crate::Error::invalid(
                "sensor noise",
                "full well and read noise",
                "a full well ≥ 1 e⁻ and a read noise ≥ 0",
                format_args!("{} e⁻ and {} e⁻", sensor.full_well_e, sensor.read_noise_e),
            ));
        }
        let max_dn = f64::from((1u32 << bits) - 1);
        Ok(Self {
            k: max_dn / sensor.full_well_e,
            read_noise_e: sensor.read_noise_e,
            full_well_e: sensor.full_well_e,
            max_dn,
            bits,
        })
    }

    /// At gain `gain_db`: DN per electron, the read noise's variance (DN²),
    /// full well in DN and the largest value the frame can hold (full well
    /// or the converter's top, whichever comes first).
    pub fn at_gain(&self, gain_db: f64) -> (f64, f64, f64, f64) {
        let kg = self.k * crate::exposure::split::gain_factor(gain_db);
        let read_var = (kg * self.read_noise_e).powi(2);
        let full = kg * self.full_well_e;
        (kg, read_var, full, full.min(self.max_dn))
    }
}

#[cfg(test)]
mod tests;
