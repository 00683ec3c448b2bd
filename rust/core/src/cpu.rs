//! What the processor offers beyond the build's baseline (x86-64: SSE2), detected once at run
//! time. Hot loops compiled a second time with `#[target_feature(enable = "avx2,fma")]` (the
//! sphere checker's kernels, the 1 kHz tick) are chosen by it, so one build runs everywhere.

/// Does the processor have AVX2 and FMA (detected once; false off x86-64)?
pub(crate) fn avx2_fma() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        static HAS: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
        *HAS.get_or_init(|| is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma"))
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
