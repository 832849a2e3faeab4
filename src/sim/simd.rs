//! Runtime-dispatched vector builds. A vector kernel is written once, as a [`Kernel`] body of
//! plain lane-wise loops; [`run`] compiles that body for AVX-512 and AVX2 as well as for the
//! baseline target and calls the widest build the CPU has. The builds compute bit-identical
//! results: they differ only in vector width, never in the order or kind of operations, and
//! [`Build`] lets a test run each on the same input. Rust never contracts `a * b + c` into a fused
//! multiply-add; a body that wants one calls [`mul_add`], which every build rounds once: the
//! vector builds require the CPU's FMA instructions, and the plain build (the fallback for CPUs
//! without them) computes the same rounding in plain arithmetic.

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

/// Whether the CPU has fused multiply-add instructions (FMA on x86-64, which both vector builds
/// require; always on AArch64).
#[inline]
pub(crate) fn fma_in_hardware() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("fma")
    }
    #[cfg(target_arch = "aarch64")]
    {
        true
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        false
    }
}

/// `a * b + c` rounded once, as `f32::mul_add`: by the CPU's instruction with `HARDWARE` (which
/// the caller must have checked with [`fma_in_hardware`]), else by [`mul_add_exact`], the same
/// result in plain arithmetic that vectorises without FMA.
#[inline(always)]
pub(crate) fn mul_add<const HARDWARE: bool>(a: f32, b: f32, c: f32) -> f32 {
    if HARDWARE {
        a.mul_add(b, c)
    } else {
        mul_add_exact(a, b, c)
    }
}

/// `a * b + c` rounded once to `f32`, bit for bit as `f32::mul_add`, without FMA instructions
/// or a library call. The product is exact in `f64` (48 significant bits of 53), the sum is
/// rounded to odd there (its error found by TwoSum: an inexact sum with an even last bit moves
/// one unit towards the exact value), and rounding a value rounded to odd with at least two bits
/// more than twice `f32`'s to `f32` rounds it once (Boldo and Melquiond, 2008).
#[inline(always)]
pub(crate) fn mul_add_exact(a: f32, b: f32, c: f32) -> f32 {
    let (p, c) = (f64::from(a) * f64::from(b), f64::from(c));
    let s = p + c;
    let t = s - p;
    let error = (p - (s - t)) + (c - t);
    let bits = s.to_bits();
    // A NaN error (an infinite sum) compares false both ways and leaves the sum as it is.
    let inexact = error.abs() > 0.0;
    let s = if inexact && bits & 1 == 0 {
        let away_from_zero = (error > 0.0) == (s > 0.0);
        f64::from_bits(if away_from_zero { bits + 1 } else { bits - 1 })
    } else {
        s
    };
    s as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn mul_add_exact_rounds_as_the_fused_instruction() {
        // A sum just below an f32 midpoint that rounds onto it in f64: rounding twice would give
        // 2^30 + 256, once gives 2^30 + 128.
        let (a, b, c) = (
            8.0 + 2f32.powi(-20),
            8.0 - 2f32.powi(-20),
            2f32.powi(30) + 128.0,
        );
        assert_eq!(a.mul_add(b, c), 2f32.powi(30) + 128.0);
        assert_eq!(mul_add_exact(a, b, c).to_bits(), a.mul_add(b, c).to_bits());
        let special = [
            0.0,
            -0.0,
            1.0,
            -1.0,
            f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            f32::MAX,
            f32::MIN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            1.0 + f32::EPSILON,
            1.0 - f32::EPSILON / 2.0,
            3.0e-20,
            7.5e19,
        ];
        let mut values = special.to_vec();
        // Pseudo-random values over many binades, of both signs.
        let mut state = 0x9E37_79B9_7F4A_7C15u64;
        for _ in 0..300 {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            let bits = (state >> 32) as u32;
            let v = f32::from_bits(bits);
            if v.is_finite() && v.abs() < 1e30 && v.abs() > 1e-30 {
                values.push(v);
            }
        }
        let mut checked = 0;
        for &a in &values {
            for &b in values.iter().step_by(3) {
                for &c in values.iter().step_by(7) {
                    let (want, got) = (a.mul_add(b, c), mul_add_exact(a, b, c));
                    assert!(
                        want.to_bits() == got.to_bits() || (want.is_nan() && got.is_nan()),
                        "{a:e} * {b:e} + {c:e}: {want:e} against {got:e}"
                    );
                    checked += 1;
                }
            }
        }
        assert!(checked > 100_000, "{checked}");
    }
}
