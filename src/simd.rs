//! Which vector instructions the kernels run, for the whole process: the CPU's best
//! (AVX2, and GFNI where the blue-noise hash can use it) or the portable Rust that every
//! CPU runs (a CPU without AVX2, aarch64). Every kernel with an AVX2 build asks here
//! rather than asking the CPU, so `--simd portable` reaches all of them: the accel's
//! traversals and packets, the render's camera, light and sampler lanes, and the film's
//! filters.
//!
//! Both builds do the same IEEE operations in the same order (no fused multiply-adds), so
//! they give the same bits: a replay ends at the same state hash either way, which is
//! what makes a recording a test on any CPU. `tests/autoplay.rs` replays every shipped
//! recording with the portable kernels to hold that.

use std::sync::atomic::{AtomicBool, Ordering};

/// A choice of kernels (`--simd` on the commands that run the simulation or time it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, clap::ValueEnum)]
pub enum Simd {
    /// The fastest build this CPU runs.
    #[default]
    Native,
    /// Plain Rust only, as a CPU without AVX2 runs it.
    Portable,
}

impl Simd {
    /// The name `--simd` takes, and the bench report's `simd` field.
    pub fn name(self) -> &'static str {
        match self {
            Simd::Native => "native",
            Simd::Portable => "portable",
        }
    }
}

/// Set by `use_kernels(Simd::Portable)`; read by every kernel dispatch. A relaxed load per
/// dispatch: the dispatches sit outside the per-ray loops, beside the CPU query they
/// already made.
static PORTABLE_ONLY: AtomicBool = AtomicBool::new(false);

/// Run `simd`'s kernels from now on, in every thread. Set it before the work starts:
/// a frame that changes kernels half way gives the same bits, but is timed as neither.
pub fn use_kernels(simd: Simd) {
    PORTABLE_ONLY.store(simd == Simd::Portable, Ordering::Relaxed);
}

/// The kernels in use.
pub fn kernels() -> Simd {
    if PORTABLE_ONLY.load(Ordering::Relaxed) {
        Simd::Portable
    } else {
        Simd::Native
    }
}

/// Whether the AVX2 builds may run: the CPU has AVX2 and the portable kernels are not
/// forced.
#[inline]
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        !PORTABLE_ONLY.load(Ordering::Relaxed) && std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// Whether the AVX2 builds that also use GFNI may run.
#[inline]
pub fn avx2_gfni() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        avx2() && std::arch::is_x86_feature_detected!("gfni")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}
