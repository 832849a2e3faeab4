//! The wind field a cloth sits in, and the per-cloth scratch that turns it into forces: once per
//! step the field is sampled at every particle, each triangle takes the mean of its corners'
//! winds, and the aerodynamic forces of [`aero`](super::aero) are evaluated from the positions
//! and velocities at the start of the step; every substep then applies those forces.
//!
//! A triangle's mean wind differs from the wind at its centroid by the field's curvature over a
//! triangle: gusts vary over metres (their speed over their period), a cloth's triangles measure
//! centimetres, and sampling the particles (about half as many as the triangles) spares the
//! centroids and gives each particle the wind its relative-speed cap needs.
//!
//! Holding the forces over a step (rather than re-evaluating them every substep) costs a twentieth
//! of the work at 20 substeps. Drag relaxes a particle's velocity toward the wind at the rate
//! `ρ C_d A |u| / m`, which for cloth is slow next to a 1/60 s step (about 5 /s for 1 g particles
//! 3 cm apart in 10 m/s wind), so the explicit-per-step force stays well inside its stability limit.

use glam::Vec3;

use super::aero::{
    AeroParams, GridAero, GustSampler, GustTable, Gusts, TriangleWind, add_aero_forces_in,
};
use super::model::ClothModel;
use crate::error::{ClothError, finite_vec3, non_negative, unit_interval};

/// A region of extra wind: inside `shape` (in the zone's frame, placed by `to_local`), `velocity` is
/// added to the global wind, fading linearly to zero over the outer `falloff` fraction of the
/// zone's size.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedWindZone {
    /// The zone's extent.
    pub shape: WindZoneShape,
    /// World point to the zone's frame (the inverse of its placement).
    pub to_local: glam::Affine3A,
    /// Wind added inside, m/s (world frame).
    pub velocity: Vec3,
    /// Gusts of the zone's wind, if any.
    pub gusts: Option<Gusts>,
    /// Fraction (0..=1) of the zone's size over which its wind fades out at the edge.
    pub falloff: f32,
}

/// The extent of a [`PlacedWindZone`], centred on its origin.
#[derive(
    Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize, bevy::reflect::Reflect,
)]
pub enum WindZoneShape {
    /// A ball of this radius, m.
    Sphere(f32),
    /// A box with these half extents, m.
    Cuboid(Vec3),
}

impl WindZoneShape {
    /// How deep inside `p` is, as a fraction: 1 at the centre (or anywhere deeper than the falloff
    /// band), 0 at and beyond the surface.
    fn weight(&self, p: Vec3, falloff: f32) -> f32 {
        // Normalised "radius": 0 at the centre, 1 on the surface.
        let r = match *self {
            WindZoneShape::Sphere(radius) => p.length() / radius,
            WindZoneShape::Cuboid(half) => (p.abs() / half).max_element(),
        };
        if r >= 1.0 {
            0.0
        } else if falloff <= 0.0 {
            1.0
        } else {
            ((1.0 - r) / falloff).min(1.0)
        }
    }

    /// Checks the dimensions are positive and finite.
    pub fn validate(&self) -> Result<(), ClothError> {
        match *self {
            WindZoneShape::Sphere(r) => crate::error::positive("wind_zone.radius", r),
            WindZoneShape::Cuboid(h) => {
                crate::error::positive("wind_zone.half_size.x", h.x)?;
                crate::error::positive("wind_zone.half_size.y", h.y)?;
                crate::error::positive("wind_zone.half_size.z", h.z)
            }
        }
    }
}

/// Most [`WindField::zones`]: every zone is sampled at every particle of every cloth in every
/// step (a zone is not culled by its box), so a step's wind costs their number times the
/// particles.
pub const MAX_WIND_ZONES: usize = 64;

/// The air around the cloths during one step: a global wind (optionally gusty), local zones, and
/// the air's density.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct WindField {
    /// The global mean wind, m/s.
    pub velocity: Vec3,
    /// Gusts of the global wind.
    pub gusts: Option<Gusts>,
    /// Air density, kg/m³.
    pub air_density: f32,
    /// Local wind zones, at most [`MAX_WIND_ZONES`].
    pub zones: Vec<PlacedWindZone>,
    /// Simulation time at the end of the step, s (drives the gusts).
    pub time: f32,
}

/// Checks a number of wind zones against [`MAX_WIND_ZONES`].
pub(crate) fn validate_zone_count(zones: usize) -> Result<(), ClothError> {
    crate::error::at_most("wind zones", zones, MAX_WIND_ZONES, || {
        "MAX_WIND_ZONES: each is sampled at every particle of every cloth in every step".into()
    })
}

impl WindField {
    /// Whether the wind is the same everywhere: no gusts and no zones.
    pub fn is_uniform(&self) -> bool {
        self.gusts.is_none() && self.zones.is_empty()
    }

    /// The wind velocity at world point `p`.
    pub fn sample(&self, p: Vec3) -> Vec3 {
        let mut wind = [Vec3::ZERO];
        self.sample_many(&[p], &mut wind);
        wind[0]
    }

    /// The wind velocity at each of `points` into `out` (as many as both hold), with each gusty
    /// field prepared once for all of them ([`GustSampler`]): [`Self::sample`] at each, except
    /// where the points lie along a short stretch of the wind next to their number (a cloth's
    /// triangles). There gusts are sampled at phases along the wind and interpolated between them
    /// (`GustTable`), and each point's gust differs from [`Self::sample`]'s by a small part of
    /// the gusts' amplitude `|base| (strength + turbulence)` (held under 2.5·10⁻⁵ by a unit test
    /// for gusts up to 6 Hz).
    pub fn sample_many(&self, points: &[Vec3], out: &mut [Vec3]) {
        let points = &points[..points.len().min(out.len())];
        let sampler = |gusts: &Option<Gusts>, base: Vec3| {
            gusts
                .as_ref()
                .map(|g| GustTable::new(GustSampler::new(g, base, self.time), points))
        };
        let gust = |sampler: &mut Option<GustTable>, base: Vec3, p: Vec3| match sampler {
            Some(g) => g.sample(p),
            None => base,
        };
        let mut global = sampler(&self.gusts, self.velocity);
        for (w, &p) in out.iter_mut().zip(points) {
            *w = gust(&mut global, self.velocity, p);
        }
        for zone in &self.zones {
            let mut gusts = sampler(&zone.gusts, zone.velocity);
            for (w, &p) in out.iter_mut().zip(points) {
                let weight = zone
                    .shape
                    .weight(zone.to_local.transform_point3(p), zone.falloff);
                if weight > 0.0 {
                    *w += gust(&mut gusts, zone.velocity, p) * weight;
                }
            }
        }
    }

    /// Checks the number of zones (at most [`MAX_WIND_ZONES`]), the density, the velocity, the
    /// gusts and the zones (shape, velocity, gusts, falloff in `0..=1`, and a finite placement: a
    /// zone scaled to zero has none); the error names the first bad field and its value.
    pub fn validate(&self) -> Result<(), ClothError> {
        validate_zone_count(self.zones.len())?;
        non_negative("wind.air_density", self.air_density)?;
        finite_vec3(
            ["wind.velocity.x", "wind.velocity.y", "wind.velocity.z"],
            self.velocity,
        )?;
        if let Some(g) = &self.gusts {
            g.validate()?;
        }
        for z in &self.zones {
            z.shape.validate()?;
            finite_vec3(
                [
                    "wind_zone.velocity.x",
                    "wind_zone.velocity.y",
                    "wind_zone.velocity.z",
                ],
                z.velocity,
            )?;
            if let Some(g) = &z.gusts {
                g.validate()?;
            }
            unit_interval("wind_zone.falloff", z.falloff)?;
            if !z.to_local.is_finite() {
                return Err(ClothError::InvalidValue {
                    field: "wind_zone transform",
                    expected: "invertible (finite, with non-zero scale)",
                    value: f64::NAN,
                });
            }
        }
        Ok(())
    }
}

/// Per-cloth wind scratch: the wind at each particle for the current step, and the forces.
#[derive(Debug, Clone, Default)]
pub(crate) struct WindScratch {
    /// Whether the current step has wind (and so aerodynamic forces).
    pub active: bool,
    params: AeroParams,
    /// The wind at each particle, when it is not the same everywhere.
    particle_wind: Vec<Vec3>,
    /// Aerodynamic force on each particle for this step, N.
    particle_force: Vec<Vec3>,
    /// The forces row by row, for a cloth that is still the canonical grid.
    grid: Option<GridAero>,
}

impl WindScratch {
    /// Buffers for `model`'s particles.
    pub fn new(model: &ClothModel) -> Self {
        let particles = model.particle_count();
        Self {
            active: false,
            params: AeroParams::default(),
            particle_wind: vec![Vec3::ZERO; particles],
            particle_force: vec![Vec3::ZERO; particles],
            grid: GridAero::new(model),
        }
    }

    /// Samples `field` at every particle of the cloth (each triangle taking its corners' mean) and
    /// evaluates the aerodynamic force on every particle for this step (or switches wind off).
    /// `coefficients` are the cloth's drag and lift; the density comes from the field.
    pub fn begin_step(
        &mut self,
        field: Option<&WindField>,
        coefficients: (f32, f32),
        positions: &[Vec3],
        velocities: &[Vec3],
        (inv_mass, dt): (&[f32], f32),
        triangles: &[u32],
    ) {
        let Some(field) = field else {
            self.active = false;
            return;
        };
        self.active = true;
        self.params = AeroParams {
            air_density: field.air_density,
            drag: coefficients.0,
            lift: coefficients.1,
        };
        let triangles = triangles.as_chunks::<3>().0;
        self.particle_force.fill(Vec3::ZERO);
        // A uniform field needs no sampling.
        let uniform = field.is_uniform().then_some(field.velocity);
        let winds = match uniform {
            Some(wind) => TriangleWind::Uniform(wind),
            None => {
                field.sample_many(positions, &mut self.particle_wind);
                TriangleWind::Corners(&self.particle_wind)
            }
        };
        let forces = &mut self.particle_force;
        let by_rows = self
            .grid
            .as_mut()
            .is_some_and(|g| g.add_forces(positions, velocities, winds, &self.params, forces));
        if !by_rows {
            add_aero_forces_in(
                positions,
                velocities,
                triangles,
                |t| winds.at(triangles[t]),
                &self.params,
                forces,
            );
        }
        self.limit_to_relative_speed(velocities, inv_mass, dt, uniform);
    }

    /// Held over a step, drag is an explicit force: at relative speeds where `ρ C_d A |u| dt / m`
    /// nears 2 it would overshoot the wind and grow without bound. The air can at most bring a
    /// particle to its own speed, so each particle's aerodynamic velocity change over the step is
    /// capped at its speed relative to the wind where it is (`uniform`, or sampled there). At
    /// ordinary speeds (for cloth the rate is a few per second) the cap never binds.
    fn limit_to_relative_speed(
        &mut self,
        velocities: &[Vec3],
        inv_mass: &[f32],
        dt: f32,
        uniform: Option<Vec3>,
    ) {
        // The factor is selected, not branched on, so that the loops run in vectors; a factor of
        // 1 leaves a force's bits as they are.
        let limit = |f: &mut Vec3, v: Vec3, w: f32, mean: Vec3| {
            let relative_sq = (mean - v).length_squared();
            let dv_sq = f.length_squared() * (w * dt) * (w * dt);
            *f *= if dv_sq > relative_sq {
                (relative_sq / dv_sq).sqrt()
            } else {
                1.0
            };
        };
        let forces = self.particle_force.iter_mut().zip(velocities).zip(inv_mass);
        match uniform {
            Some(wind) => {
                for ((f, v), w) in forces {
                    limit(f, *v, *w, wind);
                }
            }
            None => {
                for (((f, v), w), wind) in forces.zip(&self.particle_wind) {
                    limit(f, *v, *w, *wind);
                }
            }
        }
    }

    /// The aerodynamic force on each particle for this step, N (meaningful when `active`).
    pub fn particle_forces(&self) -> &[Vec3] {
        &self.particle_force
    }

    /// Adds this step's aerodynamic forces to `forces` (when wind is on).
    pub fn add_forces(&self, forces: &mut [Vec3]) {
        if self.active {
            for (f, a) in forces.iter_mut().zip(&self.particle_force) {
                *f += *a;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::{DiscSpec, GridPlane, GridSpec};

    #[test]
    fn grid_cloths_get_the_row_kernel_and_others_the_triangle_path() {
        // The two paths give the same bits, so only this sees which one a cloth takes.
        for plane in [GridPlane::Horizontal, GridPlane::Vertical] {
            let spec = GridSpec {
                plane,
                ..GridSpec::new(9, 5, 0.1)
            };
            let grid = ClothModel::grid(&spec).unwrap();
            assert!(WindScratch::new(&grid).grid.is_some(), "{plane:?}");
        }
        let disc = ClothModel::disc(&DiscSpec::new(12, 4, 0.5)).unwrap();
        assert!(WindScratch::new(&disc).grid.is_none());
    }

    #[test]
    fn the_winds_velocity_change_over_a_step_stops_at_the_air_speed() {
        // Light particles in a strong wind over a long step: uncapped, drag would carry them far
        // past the air's own speed.
        let spec = GridSpec::new(9, 5, 0.1).with_plane(GridPlane::Vertical);
        let model = ClothModel::grid(&spec).unwrap();
        let n = model.particle_count();
        let velocities: Vec<Vec3> = (0..n)
            .map(|k| Vec3::new((k as f32).sin(), 0.5, (k as f32 * 0.3).cos()))
            .collect();
        let (inv_mass, dt) = (vec![1000.0; n], 0.1);
        let uniform = WindField {
            velocity: Vec3::new(3.0, 0.0, 40.0),
            air_density: crate::sim::aero::AIR_DENSITY,
            ..Default::default()
        };
        let gusty = WindField {
            gusts: Some(Gusts::default()),
            ..uniform.clone()
        };
        for field in [uniform, gusty] {
            let mut wind = WindScratch::new(&model);
            let (x, v) = (&model.rest_positions, &velocities);
            let triangles = &model.triangles;
            wind.begin_step(Some(&field), (1.0, 0.5), x, v, (&inv_mass, dt), triangles);
            let mut capped = 0;
            for (k, f) in wind.particle_forces().iter().enumerate() {
                let mean = if field.is_uniform() {
                    field.velocity
                } else {
                    wind.particle_wind[k]
                };
                let (dv, relative) = (
                    (*f * inv_mass[k] * dt).length(),
                    mean.distance(velocities[k]),
                );
                assert!(
                    dv <= relative * (1.0 + 1e-5),
                    "particle {k}: {dv} past {relative}"
                );
                capped += usize::from(dv > relative * (1.0 - 1e-5));
            }
            assert!(capped > n / 2, "{capped} of {n} particles at the cap");
        }
    }

    #[test]
    fn many_points_sampled_at_once_get_what_each_gets_alone() {
        let gusts = |seed| {
            Some(Gusts {
                seed,
                strength: 0.5,
                frequency: 3.0,
                turbulence: 0.3,
            })
        };
        let zone = |at: Vec3, gusts| PlacedWindZone {
            shape: WindZoneShape::Sphere(1.5),
            to_local: glam::Affine3A::from_translation(-at),
            velocity: Vec3::new(0.0, 1.0, 4.0),
            gusts,
            falloff: 0.5,
        };
        let field = WindField {
            velocity: Vec3::new(6.0, 0.0, -2.0),
            gusts: gusts(7),
            zones: vec![zone(Vec3::ZERO, gusts(8)), zone(Vec3::X, None)],
            time: 2.5,
            ..Default::default()
        };
        // Points back and forth along the wind across many of the noise's lattice cells, inside
        // and outside the zones: too spread along the wind for interpolation, so each is
        // sampled on its own, to the same bits.
        let points: Vec<Vec3> = (0..400)
            .map(|k| {
                let s = (k as f32 * 0.37).sin() * 3.0;
                Vec3::new(s, (k % 7) as f32 * 0.2, (k % 3) as f32 * 0.5)
            })
            .collect();
        let sampler = GustSampler::new(field.gusts.as_ref().unwrap(), field.velocity, field.time);
        assert!(!GustTable::new(sampler, &points).interpolates());
        let mut winds = vec![Vec3::ZERO; points.len()];
        field.sample_many(&points, &mut winds);
        let mut inside = 0;
        for (p, w) in points.iter().zip(&winds) {
            assert_eq!(*w, field.sample(*p), "at {p}");
            inside += usize::from(p.length() < 1.5);
        }
        assert!(
            inside > 50 && inside < 350,
            "{inside} points in the first zone"
        );
    }

    #[test]
    fn a_cloths_points_get_the_gusts_interpolated_along_the_wind_within_the_bound() {
        // A 1 m cloth's triangle centroids in a gusty wind at several frequencies and directions:
        // few knots next to the points, so the table interpolates; each point's gust is then
        // close to its own sample.
        let points: Vec<Vec3> = (0..64 * 64)
            .map(|k| {
                let (i, j) = ((k % 64) as f32 / 63.0, (k / 64) as f32 / 63.0);
                Vec3::new(i - 0.5, 2.0 - 0.3 * (j * 3.0).sin(), j - 0.5)
            })
            .collect();
        let mut worst = 0.0f32;
        for (seed, frequency, velocity) in [
            (0, 0.5, Vec3::new(5.0, 0.0, 2.0)),
            (3, 2.0, Vec3::new(-1.0, 0.5, 8.0)),
            (11, 6.0, Vec3::new(20.0, 0.0, 0.0)),
        ] {
            let gusts = Gusts {
                seed,
                strength: 0.8,
                frequency,
                turbulence: 0.6,
            };
            let field = WindField {
                velocity,
                gusts: Some(gusts),
                time: 3.7,
                ..Default::default()
            };
            let sampler = GustSampler::new(&gusts, velocity, 3.7);
            assert!(
                GustTable::new(sampler.clone(), &points).interpolates(),
                "{frequency} Hz"
            );
            // One point out of all proportion sends them all to exact sampling; a point that is
            // not a number gets no number, as it would alone.
            for far in [Vec3::splat(1e30), Vec3::new(f32::INFINITY, 0.0, 0.0)] {
                let mut spread = points.clone();
                spread[0] = far;
                assert!(!GustTable::new(sampler.clone(), &spread).interpolates());
            }
            let mut odd = points.clone();
            odd[0] = Vec3::NAN;
            let mut table = GustTable::new(sampler.clone(), &odd);
            assert!(table.interpolates() && table.sample(odd[0]).is_nan());
            let mut winds = vec![Vec3::ZERO; points.len()];
            field.sample_many(&points, &mut winds);
            // The gusts' amplitude: how far they may take the wind from its mean.
            let amplitude = velocity.length() * (gusts.strength + gusts.turbulence);
            for (p, w) in points.iter().zip(&winds) {
                worst = worst.max((*w - field.sample(*p)).length() / amplitude);
            }
        }
        assert!(worst < 2.5e-5, "worst error {worst:e} of the amplitude");
    }

    #[test]
    fn zones_add_wind_inside_and_fade_at_the_edge() {
        let zone = PlacedWindZone {
            shape: WindZoneShape::Sphere(2.0),
            to_local: glam::Affine3A::from_translation(Vec3::new(-10.0, 0.0, 0.0)),
            velocity: Vec3::new(0.0, 0.0, 4.0),
            gusts: None,
            falloff: 0.5,
        };
        let field = WindField {
            velocity: Vec3::X,
            air_density: 1.2,
            zones: vec![zone],
            ..Default::default()
        };
        // The zone is centred at x = 10 (the inverse of a translation by -10).
        assert_eq!(
            field.sample(Vec3::new(10.0, 0.0, 0.0)),
            Vec3::new(1.0, 0.0, 4.0)
        );
        assert_eq!(
            field.sample(Vec3::new(10.0, 0.5, 0.0)),
            Vec3::new(1.0, 0.0, 4.0)
        );
        // Three quarters out: half way through the falloff band.
        let mid = field.sample(Vec3::new(10.0, 1.5, 0.0));
        assert!((mid.z - 2.0).abs() < 1e-5, "{mid}");
        assert_eq!(field.sample(Vec3::new(10.0, 2.5, 0.0)), Vec3::X);
    }
}
