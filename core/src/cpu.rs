//! The vector instruction sets the crate's kernels are compiled for, and
//! which of them this CPU runs (detected once).
//!
//! The sets form a ladder, each holding the ones before it, so that a
//! kernel compiled for a narrower set runs on every CPU that has a wider
//! one:
//!
//! | [`Isa`] | x86-64 features | used by |
//! | --- | --- | --- |
//! | `Baseline` | SSE2 (any x86-64, or another target) | every kernel's portable code |
//! | `Bmi2` | + BMI2 | the remap's RGB lanes (`pdep`/`pext`) |
//! | `Avx2` | + AVX2, FMA | the remap's gathers; the exposure kernels' 16-lane FMA code |
//! | `Avx512` | + AVX-512F | the exposure kernels' AVX-512 code and row loop |
//!
//! A kernel runs with the widest set it has code for at or below the one
//! asked for ([`Isa::supported`] caps the request at what the CPU has):
//! the exposure kernels run `Bmi2` as `Baseline`, the remap runs `Avx512`
//! as `Avx2`. Tests and benchmarks force a narrower set to compare the
//! code of every set ([`Isa::available`]); the environment variable
//! `RIGVIEW_ISA` caps the set a whole process detects ([`Isa::detect`]),
//! to measure on a wide machine what a narrower one runs.

use std::sync::OnceLock;

/// The environment variable that caps the detected set ([`Isa::detect`]).
pub const ISA_VAR: &str = "RIGVIEW_ISA";

/// A vector instruction set; narrower sets order first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum Isa {
    /// Baseline x86-64 (SSE2) or a non-x86 target.
    Baseline,
    /// Baseline and BMI2.
    Bmi2,
    /// BMI2, AVX2 and FMA.
    Avx2,
    /// AVX2's and AVX-512 (F).
    Avx512,
}

impl Isa {
    /// Every set, narrowest first.
    pub const ALL: [Isa; 4] = [Isa::Baseline, Isa::Bmi2, Isa::Avx2, Isa::Avx512];

    /// The widest set this CPU supports (detected once), capped by the
    /// environment variable `RIGVIEW_ISA` when it names a set (`baseline`,
    /// `bmi2`, `avx2`, `avx512`): an AVX-512 machine then runs, and
    /// measures, what an AVX2-only one would. Another value is reported
    /// on standard error and ignored.
    pub fn detect() -> Self {
        static DETECTED: OnceLock<Isa> = OnceLock::new();
        *DETECTED.get_or_init(|| {
            let cpu = Self::detect_cpu();
            match std::env::var(ISA_VAR) {
                Ok(v) => match Self::from_name(v.trim()) {
                    Some(cap) => cpu.min(cap),
                    None => {
                        eprintln!(
                            "rigview: {ISA_VAR}={v:?} is not an instruction set (baseline, bmi2, avx2 or avx512); using {}",
                            cpu.name()
                        );
                        cpu
                    }
                },
                Err(_) => cpu,
            }
        })
    }

    /// The set named `name` ([`Isa::name`], any case).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|isa| isa.name().eq_ignore_ascii_case(name))
    }

    /// The widest set the CPU has, whatever `RIGVIEW_ISA` says.
    pub fn detect_cpu() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            let bmi2 = has!("bmi2");
            let avx2 = bmi2 && has!("avx2") && has!("fma");
            if avx2 && has!("avx512f") {
                return Isa::Avx512;
            }
            if avx2 {
                return Isa::Avx2;
            }
            if bmi2 {
                return Isa::Bmi2;
            }
        }
        Isa::Baseline
    }

    /// What the kernels run, for a report: the set, and the CPU's own
    /// where `RIGVIEW_ISA` capped it.
    pub fn describe() -> String {
        let (isa, cpu) = (Self::detect(), Self::detect_cpu());
        if isa == cpu {
            isa.name().to_owned()
        } else {
            format!("{} (the CPU has {}; {ISA_VAR})", isa.name(), cpu.name())
        }
    }

    /// Every set this CPU can run, narrowest first.
    pub fn available() -> Vec<Self> {
        let best = Self::detect();
        Self::ALL.into_iter().filter(|&isa| isa <= best).collect()
    }

    /// `self`, or the widest set this CPU has if it lacks `self`.
    pub fn supported(self) -> Self {
        self.min(Self::detect())
    }

    /// The name used in telemetry and benchmarks.
    pub fn name(self) -> &'static str {
        match self {
            Self::Baseline => "baseline",
            Self::Bmi2 => "bmi2",
            Self::Avx2 => "avx2",
            Self::Avx512 => "avx512",
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_set_is_found_by_its_name_and_nothing_else_is() {
        for isa in Isa::ALL {
            assert_eq!(Isa::from_name(isa.name()), Some(isa));
            assert_eq!(Isa::from_name(&isa.name().to_uppercase()), Some(isa));
        }
        for other in ["", "sse2", "avx", "avx-512", "neon"] {
            assert_eq!(Isa::from_name(other), None, "{other:?}");
        }
        assert!(Isa::detect() <= Isa::detect_cpu());
    }

    #[test]
    fn the_sets_form_a_ladder_capped_at_the_detected_one() {
        let best = Isa::detect();
        let available = Isa::available();
        assert_eq!(available.first(), Some(&Isa::Baseline));
        assert_eq!(available.last(), Some(&best));
        assert!(available.windows(2).all(|w| w[0] < w[1]));
        for isa in Isa::ALL {
            assert_eq!(isa.supported(), isa.min(best), "{isa:?}");
            assert!(available.contains(&isa.supported()));
        }
        #[cfg(target_arch = "x86_64")]
        {
            use std::arch::is_x86_feature_detected as has;
            // What each detected set promises, the CPU has.
            if best >= Isa::Bmi2 {
                assert!(has!("bmi2"));
            }
            if best >= Isa::Avx2 {
                assert!(has!("avx2") && has!("fma"));
            }
            if best == Isa::Avx512 {
                assert!(has!("avx512f"));
            }
        }
    }
}
