//! Smooth, seeded 1-D value noise ([`value_noise`]) and its three-octave sum
//! ([`FractalNoise`]), the randomness under the gusts. Pure functions of a seed and a parameter:
//! no state but the lattice cell each octave last blended.

use crate::hash::{GOLDEN_GAMMA, mix64, unit_interval};

/// Smooth 1-D value noise in `[−1, 1]`, deterministic in `(seed, t)`.
///
/// Each integer `i` gets a pseudo-random value in `[−1, 1]` hashed from `(seed, i)`; between two
/// lattice points the values are blended with the quintic fade `6f⁵ − 15f⁴ + 10f³`, so the noise
/// is C² and its slope is at most 3.75 per unit `t`. Independent of the lattice values, so
/// uncorrelated beyond one unit. `t` should be finite and well below 2²³ in magnitude, where `f32`
/// still resolves fractions of a unit.
pub fn value_noise(seed: u64, t: f32) -> f32 {
    NoiseOctave::new(seed).at(t)
}

/// `t.floor()`, and as an integer (saturating; 0 for NaN), without the library call that `floor`
/// is on x86-64 below SSE4.1.
#[inline]
fn floor(t: f32) -> (f32, i64) {
    // From 2²³ up every `f32` is whole (and NaN and the infinities go the library's way).
    if t.is_nan() || t.abs() >= 8_388_608.0 {
        return (t.floor(), t as i64);
    }
    let i = t as i64;
    // `as` truncates toward zero; below zero that is one above the floor unless `t` is whole.
    let i = if (i as f32) > t { i - 1 } else { i };
    // The sign, for -0.
    ((i as f32).copysign(t), i)
}

/// Relative rates and amplitudes of [`FractalNoise`]'s octaves.
const OCTAVES: [(f32, f32); 3] = [(1.0, 1.0), (2.03, 0.5), (4.11, 0.25)];

/// Three octaves of [`value_noise`] of one seed (relative rates 1, 2.03, 4.11; amplitudes 1, ½,
/// ¼), normalised to `[−1, 1]`; the non-integer rates keep the octaves' lattices from lining up.
/// Each octave keeps the lattice cell it last blended.
#[derive(Debug, Clone)]
pub(super) struct FractalNoise {
    pub(super) octaves: [NoiseOctave; 3],
}

impl FractalNoise {
    pub(super) fn new(seed: u64) -> Self {
        Self {
            octaves: [0, 1, 2].map(|k| NoiseOctave::new(channel_seed(seed, k))),
        }
    }

    /// The noise at `t`.
    pub(super) fn at(&mut self, t: f32) -> f32 {
        let mut sum = 0.0;
        let mut total = 0.0;
        for (octave, &(rate, amplitude)) in self.octaves.iter_mut().zip(&OCTAVES) {
            sum += amplitude * octave.at(rate * t);
            total += amplitude;
        }
        (sum / total).clamp(-1.0, 1.0)
    }
}

/// [`value_noise`] of one seed, keeping the lattice cell it last blended.
#[derive(Debug, Clone, Copy)]
pub(super) struct NoiseOctave {
    seed: u64,
    /// The cell last blended, with the lattice values at its two ends.
    pub(super) last: Option<(i64, f32, f32)>,
}

impl NoiseOctave {
    fn new(seed: u64) -> Self {
        Self { seed, last: None }
    }

    /// The noise at `t`.
    fn at(&mut self, t: f32) -> f32 {
        let (cell, i) = floor(t);
        let (a, b) = match self.last {
            Some((j, a, b)) if j == i => (a, b),
            _ => {
                let (a, b) = (
                    lattice_value(self.seed, i),
                    lattice_value(self.seed, i.wrapping_add(1)),
                );
                self.last = Some((i, a, b));
                (a, b)
            }
        };
        let f = t - cell;
        let fade = (f * f * f * (f * (f * 6.0 - 15.0) + 10.0)).min(1.0);
        (a + (b - a) * fade).clamp(-1.0, 1.0)
    }
}

/// The value in `[−1, 1]` at lattice point `i`: entry `i` of a SplitMix64 stream keyed by `seed`.
#[inline]
fn lattice_value(seed: u64, i: i64) -> f32 {
    let key = mix64(seed.wrapping_add(GOLDEN_GAMMA));
    let h = mix64(key.wrapping_add((i as u64).wrapping_mul(GOLDEN_GAMMA)));
    2.0 * unit_interval(h) - 1.0
}

/// A seed for sub-channel `channel` of `seed`.
#[inline]
pub(super) fn channel_seed(seed: u64, channel: u64) -> u64 {
    mix64(seed ^ mix64(channel.wrapping_add(1).wrapping_mul(GOLDEN_GAMMA)))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `n` evenly spaced samples over `[from, to)`.
    fn samples(from: f32, to: f32, n: usize) -> impl Iterator<Item = f32> {
        (0..n).map(move |k| from + (to - from) * k as f32 / n as f32)
    }

    #[test]
    fn value_noise_is_deterministic_for_same_seed() {
        for t in samples(-50.0, 50.0, 1000) {
            assert_eq!(value_noise(42, t).to_bits(), value_noise(42, t).to_bits());
        }
    }

    #[test]
    fn value_noise_differs_across_seeds() {
        let differing = samples(-50.0, 50.0, 1000)
            .filter(|&t| (value_noise(1, t) - value_noise(2, t)).abs() > 1e-3)
            .count();
        assert!(differing > 900, "{differing} of 1000 differ");
    }

    #[test]
    fn value_noise_stays_within_unit_range() {
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for seed in [0, 7, u64::MAX] {
            for t in samples(-20_000.0, 20_000.0, 200_000) {
                let g = value_noise(seed, t);
                assert!((-1.0..=1.0).contains(&g), "g({t}) = {g}");
                (lo, hi) = (lo.min(g), hi.max(g));
            }
        }
        assert!(lo < -0.99 && hi > 0.99, "spans the range: [{lo}, {hi}]");
    }

    #[test]
    fn value_noise_is_continuous() {
        // Slope ≤ 3.75, so a step of 1e-4 moves it by at most 3.75e-4 (plus rounding). The
        // sampling crosses many lattice points, where a discontinuity would show.
        let dt = 1e-4;
        for t in samples(-100.0, 100.0, 20_011).chain((-100..100).map(|i| i as f32 - 0.5 * dt)) {
            let step = (value_noise(3, t + dt) - value_noise(3, t)).abs();
            assert!(step < 1e-3, "jump {step} at {t}");
        }
    }

    #[test]
    fn floor_is_the_library_floor() {
        let mut values = vec![0.0, -0.0, 0.5, -0.5, 1.0, -1.0, 2.999_999_8, -3.000_000_2];
        values.extend((-3000..3000).map(|k| k as f32 * 0.377));
        values.extend([8_388_607.5, -8_388_607.5, 8_388_608.0, -1e20, 1e20, 3e38]);
        values.extend([f32::NAN, f32::INFINITY, f32::NEG_INFINITY]);
        for t in values {
            let (cell, i) = floor(t);
            assert_eq!(cell.to_bits(), t.floor().to_bits(), "floor of {t}");
            assert_eq!(i, t.floor() as i64, "floor of {t} as an integer");
        }
    }
}
