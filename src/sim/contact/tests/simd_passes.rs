//! The vector passes: every build gives the same bits as the plain test.

use super::*;
use crate::sim::contact::simd_passes::{Clearances, SinceKernel};
use crate::sim::simd;
use crate::sim::soa::Soa;

/// The clearances' signs of 103 particles (a partial last batch) from `near` against 0.05 m, by
/// the kernel's `build` (`AHEAD` as the kernel's), if the CPU has it.
fn clearances_in<const AHEAD: bool>(build: Build, near: Near) -> Option<Vec<u32>> {
    let n = 103;
    let mut x = Soa::new(n);
    let mut d = Soa::new(n);
    for i in 0..n {
        let t = i as f32;
        x.set(i, Vec3::new(t.sin(), 0.1 * t, (0.3 * t).cos()));
        d.set(i, 1e-2 * Vec3::new((1.3 * t).cos(), -0.5, (2.1 * t).sin()));
    }
    let mut out = vec![0.0; n];
    let kernel = Clearances::<AHEAD> {
        x: &x,
        d: &d,
        near,
        within: 0.05,
        out: &mut out,
    };
    simd::run_as(build, kernel).then(|| out.iter().map(|c| c.to_bits()).collect())
}

#[test]
fn the_clearance_kernels_sign_is_the_clearance_test_without_square_roots() {
    // Particles near a point and a plane, some inside, some grazing, some far, moving up to
    // 0.3 m; the sign against `within` must be the test on `distance(end) − |end − start|`
    // wherever that clearance is not within rounding of `within`.
    let mut uniform = uniform_draws(0x9e37_79b9_7f4a_7c15);
    let n = 4000;
    let (mut x, mut d) = (Soa::new(n), Soa::new(n));
    for i in 0..n {
        let at = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0));
        let moved = Vec3::new(uniform(-1.0, 1.0), uniform(-1.0, 1.0), uniform(-1.0, 1.0));
        // A few particles that do not move at all.
        let moved = if i % 37 == 0 {
            Vec3::ZERO
        } else {
            0.15 * moved
        };
        x.set(i, at);
        d.set(i, moved);
    }
    let nears = [
        Near::Point(Vec3::new(0.1, -0.2, 0.05)),
        Near::Plane(Vec3::new(0.0, 0.1, 0.0), Vec3::new(0.6, 0.8, 0.0)),
    ];
    let mut out = vec![0.0; n];
    let (mut close, mut far) = (0, 0);
    for near in nears {
        for within in [0.0, 0.05, 0.4] {
            for ahead in [false, true] {
                if ahead {
                    soa_clearances::<true>(&x, &d, (near, within), &mut out);
                } else {
                    soa_clearances::<false>(&x, &d, (near, within), &mut out);
                }
                for (i, &sign) in out.iter().enumerate() {
                    let (at, moved) = (x.get(i), d.get(i));
                    let end = if ahead { at + moved } else { at };
                    let clearance = near.distance(end) - moved.length();
                    if (clearance - within).abs() < 1e-5 {
                        continue;
                    }
                    let near_it = clearance <= within;
                    assert_eq!(
                        sign <= 0.0 || sign.is_nan(),
                        near_it,
                        "particle {i}, {near:?}, within {within}: clearance {clearance}"
                    );
                    (close, far) = (close + usize::from(near_it), far + usize::from(!near_it));
                }
            }
        }
    }
    assert!(close > 2000 && far > 2000, "{close} near, {far} not");
}

#[test]
fn every_build_of_the_clearance_kernel_gives_the_same_bits() {
    let nears = [
        Near::Point(Vec3::new(0.2, 3.0, -0.4)),
        Near::Plane(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.6, 0.8, 0.0)),
    ];
    for near in nears {
        for build in [Build::Avx2, Build::Avx512] {
            let plain = (
                clearances_in::<false>(Build::Plain, near),
                clearances_in::<true>(Build::Plain, near),
            );
            let wide = (
                clearances_in::<false>(build, near),
                clearances_in::<true>(build, near),
            );
            if wide.0.is_some() {
                assert_eq!(wide, plain, "{build:?} against the plain build, {near:?}");
            }
        }
    }
}

/// [`soa_since`] by the kernel's `build` (`AHEAD` as the kernel's), if the CPU has it.
fn since_in<const AHEAD: bool>(
    build: Build,
    x: &Soa,
    d: &Soa,
    at: &Soa,
    guess: Vec3,
) -> Option<Since> {
    let mut out = Since::default();
    let kernel = SinceKernel::<AHEAD> {
        x,
        d,
        at,
        guess,
        out: &mut out,
    };
    simd::run_as(build, kernel).then(|| out.checked())
}

#[test]
fn the_since_kernel_sees_every_particle_in_every_build() {
    // 37 particles (two whole blocks and a partial one), each in turn the one that moved far.
    let n = 37;
    let (mut x, mut d, mut at) = (Soa::new(n), Soa::new(n), Soa::new(n));
    for i in 0..n {
        let t = i as f32;
        at.set(i, Vec3::new(t.sin(), 0.1 * t, (0.3 * t).cos()));
        d.set(i, 1e-3 * Vec3::new((1.3 * t).cos(), -0.5, (2.1 * t).sin()));
    }
    let guess = Vec3::new(0.01, -0.02, 0.005);
    for far in 0..n {
        for i in 0..n {
            let jump = if i == far {
                Vec3::new(0.3, 0.4, 0.0)
            } else {
                Vec3::ZERO
            };
            x.set(i, at.get(i) + guess + jump);
        }
        for build in [Build::Plain, Build::Avx2, Build::Avx512] {
            let Some(s) = since_in::<false>(build, &x, &d, &at, guess) else {
                continue;
            };
            // Every particle but `far` sits at the guess; `far` 0.5 m from it.
            assert!(
                (s.worst - 0.25).abs() < 1e-5,
                "{build:?}, {far}: {}",
                s.worst
            );
            let moved = guess * n as f32 + Vec3::new(0.3, 0.4, 0.0);
            assert!(s.moved.distance(moved) < 1e-5, "{build:?}: {}", s.moved);
            let step: Vec3 = d.iter().sum();
            assert!(s.step.distance(step) < 1e-6, "{build:?}: {}", s.step);
            // Ahead of the end by `d` (the end is `x + d`), the same moves shifted by `d`.
            let ahead = since_in::<true>(build, &x, &d, &at, guess).unwrap();
            assert!(ahead.moved.distance(moved + step) < 1e-5, "{}", ahead.moved);
            let plain = since_in::<false>(Build::Plain, &x, &d, &at, guess);
            assert_eq!(Some(s), plain, "{build:?} against the plain build");
        }
    }
    // A position that is not a number is seen even where a maximum would drop it.
    x.set(20, Vec3::NAN);
    assert_eq!(soa_since::<false>(&x, &d, &at, guess).worst, f32::INFINITY);
}

#[test]
fn the_arrays_displacements_are_those_of_the_particles_paths() {
    // 9 particles at `x` displaced by `d` over the substep, found at `found`: the arrays' loop
    // against the trait's default on the same paths (ending at `x`, or with `AHEAD` at `x + d`).
    let n = 9;
    let (mut x, mut d) = (Soa::new(n), Soa::new(n));
    let found: Vec<Vec3> = (0..n)
        .map(|i| Vec3::new((i as f32).cos(), 0.2 * i as f32, 1.0))
        .collect();
    for (i, at) in found.iter().enumerate() {
        let t = i as f32;
        x.set(i, *at + Vec3::new(0.1 * t, -0.03, 0.01 * t * t));
        d.set(i, Vec3::new(0.002 * t, 0.001, -0.003));
    }
    for ahead in [false, true] {
        let (start, mut end): (Vec<Vec3>, Vec<Vec3>) = (x.iter().zip(d.iter()))
            .map(|(x, d)| if ahead { (x, x + d) } else { (x - d, x) })
            .unzip();
        let (mut v, w) = (vec![Vec3::ZERO; n], vec![1.0; n]);
        let paths = Vectors {
            x: &mut end,
            v: &mut v,
            start: &start,
            inv_mass: &w,
            touches: None,
        };
        let mut expected = vec![Vec3A::NAN; n];
        let sums = paths.displaced(&found, &mut expected);
        let mut moved = vec![Vec3A::NAN; n];
        let m = if ahead {
            soa_displaced::<true>(&x, &d, &found, &mut moved)
        } else {
            soa_displaced::<false>(&x, &d, &found, &mut moved)
        };
        assert_eq!((moved, m), (expected, sums), "ahead: {ahead}");
    }
}
