//! Runtime-dispatched vector builds. A vector kernel is written once, as a [`Kernel`] body of
//! plain lane-wise loops; [`run`] compiles that body for AVX-512 and AVX2 as well as for the
//! baseline target and calls the widest build the CPU has. The builds compute bit-identical
//! results: they differ only in vector width, never in the order or kind of operations, and
//! [`Build`] lets a test run each on the same input. Rust never contracts `a * b + c` into a fused
//! multiply-add; a body that wants one calls `mul_add`, which every build rounds once: the vector
//! builds require the CPU's FMA instructions, and the plain build (the fallback for CPUs without
//! them) computes it exactly in software on x86-64, slowly.

/// One compiled build of a kernel body.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Build {
    /// The baseline target's instructions (SSE2 on x86-64).
    #[cfg_attr(
        not(test),
        allow(dead_code, reason = "only the tests run a kernel's plain build")
    )]
    Plain,
    /// 256-bit vectors (x86-64 with AVX2 and FMA).
    Avx2,
    /// 512-bit vectors (x86-64 with AVX-512F and FMA); the body is told it may use 16-lane
    /// batches.
    Avx512,
}

impl Build {
    /// Whether this CPU can run the build.
    #[cfg(test)]
    pub fn is_available(self) -> bool {
        match self {
            Build::Plain => true,
            #[cfg(target_arch = "x86_64")]
            Build::Avx2 => avx2_available(),
            #[cfg(target_arch = "x86_64")]
            Build::Avx512 => avx512_available(),
            #[cfg(not(target_arch = "x86_64"))]
            _ => false,
        }
    }
}

/// A vector kernel: one body, compiled once per [`Build`] up to [`Self::WIDEST`].
pub(crate) trait Kernel {
    /// The widest build with a body of its own: [`Build::Avx512`] for kernels that use 16-lane
    /// batches there, else [`Build::Avx2`].
    const WIDEST: Build;

    /// The work. `WIDE` is true only in the AVX-512 build. Implementations are
    /// `#[inline(always)]`, so that each build compiles the body with its own instructions.
    fn body<const WIDE: bool>(self);
}

/// Runs `kernel` in the widest build the CPU has, up to the kernel's widest.
#[inline(always)]
pub(crate) fn run<K: Kernel>(kernel: K) {
    #[cfg(target_arch = "x86_64")]
    if K::WIDEST == Build::Avx512 && avx512_available() {
        // SAFETY: the CPU supports the feature the function is compiled for (checked above).
        unsafe { avx512(kernel) };
        return;
    }
    #[cfg(target_arch = "x86_64")]
    if avx2_available() {
        // SAFETY: as above.
        unsafe { avx2(kernel) };
        return;
    }
    kernel.body::<false>();
}

/// Runs `kernel` in `build` if the CPU has it (and the kernel has a body for it); returns whether
/// it ran. For tests that compare the builds.
#[cfg(test)]
pub(crate) fn run_as<K: Kernel>(build: Build, kernel: K) -> bool {
    if build > K::WIDEST || !build.is_available() {
        return false;
    }
    match build {
        Build::Plain => kernel.body::<false>(),
        // SAFETY: the CPU supports the feature the function is compiled for (checked above).
        #[cfg(target_arch = "x86_64")]
        Build::Avx2 => unsafe { avx2(kernel) },
        // SAFETY: as above.
        #[cfg(target_arch = "x86_64")]
        Build::Avx512 => unsafe { avx512(kernel) },
        #[cfg(not(target_arch = "x86_64"))]
        _ => return false,
    }
    true
}

/// Whether the CPU runs [`avx2`]'s build.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn avx2_available() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// Whether the CPU runs [`avx512`]'s build.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn avx512_available() -> bool {
    std::arch::is_x86_feature_detected!("avx512f") && std::arch::is_x86_feature_detected!("fma")
}

/// The AVX2 build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
#[inline(never)]
fn avx2<K: Kernel>(kernel: K) {
    kernel.body::<false>();
}

/// The AVX-512 build.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,fma")]
#[inline(never)]
fn avx512<K: Kernel>(kernel: K) {
    kernel.body::<true>();
}
