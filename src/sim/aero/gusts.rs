//! The gust field: a base wind whose speed and direction fluctuate smoothly in time, carried
//! downstream ([`Gusts`]); its sampler for many points of one time ([`GustSampler`]); and the table
//! that interpolates it between knots in phase for a cloth's triangles ([`GustTable`]).

#[cfg(doc)]
use super::noise::value_noise;
use super::noise::{FractalNoise, channel_seed};
use super::plate::MIN_SPEED_SQ;
use crate::hash::{mix64, unit_interval};
use bevy::reflect::Reflect;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::f32::consts::TAU;

/// A gusty wind field: a base wind whose speed and direction fluctuate smoothly in time, with the
/// fluctuations carried downstream at the base wind speed ("frozen" gusts, Taylor's hypothesis).
///
/// A pure function of its fields and the inputs of [`Gusts::sample`]: no state, no allocation,
/// no global random number generator. Points at the same downstream distance see the same gust at
/// the same time; the field does not vary across the wind.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct Gusts {
    /// Seed of the noise; different seeds give uncorrelated gusts.
    pub seed: u64,
    /// Relative amplitude of the speed fluctuation: the speed stays within
    /// `|base| (1 ± strength)` (0.3 = ±30%). Above 1 the wind reverses in lulls.
    pub strength: f32,
    /// Rate of the noise, Hz: roughly how many independent gust values per second.
    pub frequency: f32,
    /// Relative amplitude of the direction wobble: the direction is tilted by the angle
    /// `atan(turbulence · |w|)` with `|w| ≤ √2` (0.1 = up to about 8°).
    pub turbulence: f32,
}

impl Default for Gusts {
    /// Seed 0, ±30% speed gusts at 0.5 Hz, 10% direction wobble.
    fn default() -> Self {
        Self {
            seed: 0,
            strength: 0.3,
            frequency: 0.5,
            turbulence: 0.1,
        }
    }
}

/// Noise channels, to derive independent seeds from [`Gusts::seed`].
const CHANNEL_SPEED: u64 = 0;
const CHANNEL_WOBBLE_1: u64 = 1;
const CHANNEL_WOBBLE_2: u64 = 2;
const CHANNEL_SINE_PHASES: u64 = 3;

/// Frequencies of the two sine components relative to [`Gusts::frequency`]: `(√5 − 1)/4` and
/// `1/√2`, an irrational ratio, so the sum never repeats.
const SINE_FREQUENCIES: [f32; 2] = [0.309_017, std::f32::consts::FRAC_1_SQRT_2];

/// Weights of the fractal noise and the two sines in the speed fluctuation.
const SPEED_WEIGHTS: [f32; 3] = [1.0, 0.35, 0.2];

/// Frequency of the direction wobble relative to [`Gusts::frequency`].
const WOBBLE_FREQUENCY: f32 = 1.7;

impl Gusts {
    /// Checks that `strength`, `frequency` and `turbulence` are finite and not negative; the error
    /// names the first bad one.
    pub fn validate(&self) -> Result<(), crate::error::ClothError> {
        self.validate_as(["gusts.strength", "gusts.frequency", "gusts.turbulence"])
    }

    /// [`validate`](Self::validate), naming the fields `strength`, `frequency` and `turbulence`
    /// as given (e.g. with the path where they were read from).
    pub(crate) fn validate_as(
        &self,
        [strength, frequency, turbulence]: [&'static str; 3],
    ) -> Result<(), crate::error::ClothError> {
        use crate::error::non_negative;
        non_negative(strength, self.strength)?;
        non_negative(frequency, self.frequency)?;
        non_negative(turbulence, self.turbulence)
    }

    /// The gusty wind velocity (m/s) at `position` (m) and `time` (s), around the mean wind
    /// `base` (m/s).
    ///
    /// The noise is evaluated at the phase `time − position·b̂ / |base|`, so a point a distance `d`
    /// downstream sees the same gust `d / |base|` later. The speed is `|base| (1 + strength·g)`
    /// with `g ∈ [−1, 1]` a normalised sum of three octaves of [`value_noise`] and two sines of
    /// incommensurate frequency. The direction is `b̂ + turbulence·w`, renormalised, where `w` is
    /// perpendicular to `base` with components from two further noise channels; the speed is not
    /// affected by the wobble.
    ///
    /// Returns exactly `base` when `strength` and `turbulence` are zero, and `base` unchanged for
    /// calm air (`|base| < 1e-6` m/s, including exactly zero). Many points at one time are
    /// sampled faster, to the same values, through [`GustSampler`].
    pub fn sample(&self, base: Vec3, time: f32, position: Vec3) -> Vec3 {
        GustSampler::new(self, base, time).sample(position)
    }
}

/// [`Gusts::sample`] at many points for one mean wind and time: what does not depend on the point
/// (the channels' seeds, the sines' phases, the directions across the wind) is worked out once,
/// and each noise octave keeps the lattice cell it last blended, which neighbouring points mostly
/// share. The values are those of [`Gusts::sample`], bit for bit.
#[derive(Debug, Clone)]
pub struct GustSampler {
    gusts: Gusts,
    base: Vec3,
    speed: f32,
    speed_sq: f32,
    time: f32,
    /// Two unit vectors across the mean wind.
    across: (Vec3, Vec3),
    /// Phases of the two sines of the speed fluctuation.
    sine_phases: [f32; 2],
    /// The noise of the speed and of the two wobble components.
    channels: [FractalNoise; 3],
}

impl GustSampler {
    /// Prepares `gusts` around the mean wind `base` (m/s) at `time` (s).
    pub fn new(gusts: &Gusts, base: Vec3, time: f32) -> Self {
        let speed_sq = base.length_squared();
        let speed = speed_sq.sqrt();
        // Calm air has no direction (and is returned as it is).
        let across = if speed_sq < MIN_SPEED_SQ {
            (Vec3::X, Vec3::Y)
        } else {
            (base / speed).any_orthonormal_pair()
        };
        let phases = channel_seed(gusts.seed, CHANNEL_SINE_PHASES);
        let channel = |c| FractalNoise::new(channel_seed(gusts.seed, c));
        Self {
            gusts: *gusts,
            base,
            speed,
            speed_sq,
            time,
            across,
            sine_phases: [
                TAU * unit_interval(phases),
                TAU * unit_interval(mix64(phases)),
            ],
            channels: [
                channel(CHANNEL_SPEED),
                channel(CHANNEL_WOBBLE_1),
                channel(CHANNEL_WOBBLE_2),
            ],
        }
    }

    /// The gusty wind velocity (m/s) at `position` (m): [`Gusts::sample`].
    pub fn sample(&mut self, position: Vec3) -> Vec3 {
        if self.is_calm() {
            return self.base;
        }
        let phase = self.phase(position);
        self.at_phase(phase)
    }

    /// Whether the mean wind is too slow to have a direction (it is then returned as it is).
    fn is_calm(&self) -> bool {
        self.speed_sq < MIN_SPEED_SQ
    }

    /// The noise phase of the gust at `position`. Frozen gusts: the air now at `position`
    /// crossed the plane through the origin `position·b̂ / |base|` seconds ago, carrying the gust
    /// it had then.
    fn phase(&self, position: Vec3) -> f32 {
        (self.time - position.dot(self.base) / self.speed_sq) * self.gusts.frequency
    }

    /// The gusty wind velocity (m/s) at noise phase `phase` (not calm air).
    fn at_phase(&mut self, phase: f32) -> Vec3 {
        let (base, speed) = (self.base, self.speed);
        let gain = 1.0 + self.gusts.strength * self.speed_fluctuation(phase);

        let (e1, e2) = self.across;
        let wobble_phase = WOBBLE_FREQUENCY * phase;
        let [_, wobble_1, wobble_2] = &mut self.channels;
        let w = wobble_1.at(wobble_phase) * e1 + wobble_2.at(wobble_phase) * e2;
        // Tilting `base` by the perpendicular `turbulence |base| w` and restoring its length: a
        // rotation by `atan(turbulence |w|)`. With zero turbulence this is `base` bit for bit.
        let turbulence = self.gusts.turbulence;
        let tilted = (base + turbulence * speed * w)
            / (1.0 + turbulence * turbulence * w.length_squared()).sqrt();
        gain * tilted
    }

    /// The speed fluctuation `g ∈ [−1, 1]` at a noise phase (time × frequency).
    fn speed_fluctuation(&mut self, phase: f32) -> f32 {
        let [phase_1, phase_2] = self.sine_phases;
        let [w_noise, w_sine_1, w_sine_2] = SPEED_WEIGHTS;
        let sum = w_noise * self.channels[0].at(phase)
            + w_sine_1 * (TAU * SINE_FREQUENCIES[0] * phase + phase_1).sin()
            + w_sine_2 * (TAU * SINE_FREQUENCIES[1] * phase + phase_2).sin();
        (sum / (w_noise + w_sine_1 + w_sine_2)).clamp(-1.0, 1.0)
    }
}

/// Spacing of a [`GustTable`]'s knots, in noise phase (time × [`Gusts::frequency`]). The wind
/// is a smooth function of the phase (quintic fades, sines), so linear interpolation errs by a
/// part of the gusts' amplitude `|base| (strength + turbulence)` that falls with the square of
/// the spacing; at this spacing a unit test of `WindField::sample_many` holds it under
/// 2.5·10⁻⁵ for gusts up to 6 Hz.
const GUST_KNOT_SPACING: f32 = 1.0 / 512.0;

/// Most knots a [`GustTable`] holds (on the stack): points spread over more phase than this
/// covers are sampled one by one.
const MAX_GUST_KNOTS: usize = 512;

/// [`GustSampler::sample`] for many points of one step. The wind depends on a point only through
/// its phase along the wind, so where the points' phases span few knots
/// ([`GUST_KNOT_SPACING`]) next to their number, the sampler is evaluated at the knots and each
/// point gets the linear interpolation between its two, so a cloth's triangles share a few
/// samples. Otherwise each point is sampled, with exactly [`GustSampler::sample`]'s value.
#[derive(Debug, Clone)]
pub(crate) struct GustTable {
    sampler: GustSampler,
    knots: Option<GustKnots>,
}

/// The wind at `len` knots `GUST_KNOT_SPACING` apart in phase; a point `p` lies
/// `p·scale + offset` knots past the first.
#[derive(Debug, Clone)]
struct GustKnots {
    scale: Vec3,
    offset: f32,
    len: usize,
    wind: [Vec3; MAX_GUST_KNOTS],
}

impl GustTable {
    /// `sampler` for `points`: with knots where they are fewer than a quarter of the points.
    pub fn new(mut sampler: GustSampler, points: &[Vec3]) -> Self {
        if sampler.is_calm() {
            return Self {
                sampler,
                knots: None,
            };
        }
        // The phase as a linear function of the point, `p·along + at_origin`: `phase`'s value to
        // rounding, which the interpolation does not resolve anyway.
        let frequency = sampler.gusts.frequency;
        let along = sampler.base * (-frequency / sampler.speed_sq);
        let at_origin = sampler.time * frequency;
        let (lo, hi) = points
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |r, p| {
                let phase = p.dot(along) + at_origin;
                (r.0.min(phase), r.1.max(phase))
            });
        // At least two knots; a span that is not finite (or too long for `usize`) fails the
        // count below.
        let len = (((hi - lo) / GUST_KNOT_SPACING).ceil() as usize)
            .saturating_add(1)
            .max(2);
        let knots = (len <= MAX_GUST_KNOTS && 4 * len <= points.len()).then(|| {
            let mut wind = [Vec3::ZERO; MAX_GUST_KNOTS];
            for (k, w) in wind[..len].iter_mut().enumerate() {
                *w = sampler.at_phase(lo + k as f32 * GUST_KNOT_SPACING);
            }
            GustKnots {
                scale: along / GUST_KNOT_SPACING,
                offset: (at_origin - lo) / GUST_KNOT_SPACING,
                len,
                wind,
            }
        });
        Self { sampler, knots }
    }

    /// The gusty wind velocity (m/s) at `position`, one of the points the table was made for.
    #[inline]
    pub fn sample(&mut self, position: Vec3) -> Vec3 {
        let Some(knots) = &self.knots else {
            return self.sampler.sample(position);
        };
        let x = position.dot(knots.scale) + knots.offset;
        // `as` saturates (and takes NaN to 0); the last interval extends past its knot.
        let k = (x as usize).min(knots.len - 2);
        let (a, b) = (knots.wind[k], knots.wind[k + 1]);
        a + (b - a) * (x - k as f32)
    }

    /// Whether the points are interpolated between knots (else sampled one by one).
    #[cfg(test)]
    pub fn interpolates(&self) -> bool {
        self.knots.is_some()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `|a − b| ≤ tol · max(1, |b|)`.
    fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
        (a - b).length() <= tol * b.length().max(1.0)
    }

    /// `n` evenly spaced samples over `[from, to)`.
    fn samples(from: f32, to: f32, n: usize) -> impl Iterator<Item = f32> {
        (0..n).map(move |k| from + (to - from) * k as f32 / n as f32)
    }

    #[test]
    fn a_sampler_kept_for_many_points_gives_each_what_a_fresh_one_gives() {
        let gusts = Gusts {
            seed: 11,
            strength: 0.6,
            frequency: 2.0,
            turbulence: 0.4,
        };
        let (base, time) = (Vec3::new(3.0, -1.0, 0.5), 4.0);
        let mut kept = GustSampler::new(&gusts, base, time);
        // Back and forth along the wind over several lattice cells of every octave, so that the
        // cells each octave keeps are both reused and replaced.
        let mut reused = 0;
        let mut last = None;
        for k in 0..1000 {
            let p = base * ((k as f32 * 0.05).sin() * 0.4 + (k % 4) as f32 * 0.01);
            let w = kept.sample(p);
            assert_eq!(w, GustSampler::new(&gusts, base, time).sample(p), "at {p}");
            let cell = kept.channels[0].octaves[0].last;
            reused += usize::from(last == Some(cell));
            last = Some(cell);
        }
        assert!(
            reused > 500 && reused < 1000,
            "the first octave kept its cell {reused} times"
        );
    }

    #[test]
    fn gusts_with_zero_strength_and_turbulence_return_base() {
        let gusts = Gusts {
            seed: 9,
            strength: 0.0,
            turbulence: 0.0,
            ..Gusts::default()
        };
        let base = Vec3::new(3.7, -0.3, 1.9);
        for t in samples(0.0, 100.0, 500) {
            let p = Vec3::new(t.sin(), 2.0, -t);
            assert_eq!(gusts.sample(base, t, p), base);
        }
    }

    #[test]
    fn gusts_with_zero_base_return_zero() {
        let gusts = Gusts::default();
        assert_eq!(gusts.sample(Vec3::ZERO, 1.5, Vec3::ONE), Vec3::ZERO);
    }

    #[test]
    fn gust_speed_stays_within_strength_band() {
        let gusts = Gusts {
            seed: 5,
            strength: 0.4,
            turbulence: 0.3,
            frequency: 2.0,
        };
        let base = Vec3::new(0.0, 0.0, -6.0);
        for t in samples(0.0, 200.0, 20_000) {
            let speed = gusts.sample(base, t, Vec3::ZERO).length();
            assert!(
                (3.6 * 0.99999..=8.4 * 1.00001).contains(&speed),
                "{speed} at {t}"
            );
        }
    }

    #[test]
    fn gust_mean_speed_is_close_to_base_speed() {
        let gusts = Gusts::default();
        let base = Vec3::new(8.0, 0.0, 6.0);
        let n = 100_000;
        let mean = samples(0.0, 5_000.0, n)
            .map(|t| f64::from(gusts.sample(base, t, Vec3::new(1.0, 2.0, 3.0)).length()))
            .sum::<f64>()
            / n as f64;
        assert!((mean / 10.0 - 1.0).abs() < 0.02, "mean speed {mean}");
    }

    #[test]
    fn downstream_point_sees_same_gust_delayed() {
        let gusts = Gusts {
            seed: 11,
            ..Gusts::default()
        };
        let base = Vec3::new(6.0, 0.0, 8.0);
        let upstream = Vec3::new(1.0, 2.0, -3.0);
        let distance = 25.0;
        let downstream = upstream + distance * base.normalize();
        let delay = distance / base.length();
        let mut varies = false;
        for t in samples(0.0, 60.0, 600) {
            let here = gusts.sample(base, t, upstream);
            let later = gusts.sample(base, t + delay, downstream);
            assert!(close(later, here, 1e-4), "{here} vs {later} at {t}");
            varies |= (gusts.sample(base, t, downstream) - here).length() > 0.1;
        }
        assert!(varies, "the gust is not the same everywhere at once");
    }
}
