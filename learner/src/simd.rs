//! The compiled variants of the hand-written inner loops (Adam's step in `adam`, the
//! fused gradient in `fused`): plain Rust compiled for the baseline target
//! and for AVX2 and AVX-512, chosen at run time. Without FMA contraction and with fixed
//! summation orders, all of them give the same bits.

/// Which compiled variant of the inner loops this CPU runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Simd {
    /// AVX-512F (and AVX2).
    Avx512,
    /// AVX2.
    Avx2,
    /// The baseline target.
    None,
}

/// The variant for this CPU.
pub fn simd() -> Simd {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::is_x86_feature_detected as has;
        if has!("avx2") {
            return if has!("avx512f") {
                Simd::Avx512
            } else {
                Simd::Avx2
            };
        }
    }
    Simd::None
}
