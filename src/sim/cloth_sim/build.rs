//! Building a [`ClothSim`] and applying its settings: stiffness, masses, pins' inverse masses,
//! the frequency bound, self-contacts and the steppers, all derived once, never inside a step.

use glam::Vec3;

use super::sleep::Sleep;
use super::watchdog::Runaway;
use super::{ClothSim, adaptive};
use crate::error::ClothError;
use crate::sim::contact::{Contacts, SelfContacts};
use crate::sim::forces::{SpringSet, max_frequency_bound};
use crate::sim::integrate::Steppers;
use crate::sim::model::{ClothModel, enclosed_volume};
use crate::sim::pressure::{Air, BoundScratch};
use crate::sim::settings::{Integrator, SelfCollision, SolverSettings};
use crate::sim::state::Particles;
use crate::sim::wind::WindScratch;

impl ClothSim {
    /// Creates a cloth at rest, its particles at `model.rest_positions` mapped by `to_world`.
    pub fn new(
        model: ClothModel,
        settings: SolverSettings,
        to_world: impl Fn(Vec3) -> Vec3,
    ) -> Result<Self, ClothError> {
        let mut sim = Self::assemble(model, settings, to_world)?;
        sim.apply_settings();
        Ok(sim)
    }

    /// [`Self::new`] but for what its settings derive ([`Self::apply_settings`]): for a caller
    /// that sets pins and targets first and then applies the settings once.
    pub(super) fn assemble(
        model: ClothModel,
        settings: SolverSettings,
        to_world: impl Fn(Vec3) -> Vec3,
    ) -> Result<Self, ClothError> {
        settings.validate()?;
        // The steppers' vector kernels and threads rely on a consistent model (indices in range,
        // a proper colouring, a truthful grid): checked here, where every model enters.
        model.validate()?;
        let mean_edge = model.mean_edge_length();
        settings.self_collision.validate_for(mean_edge)?;
        let n = model.particle_count();
        let positions: Vec<Vec3> = model.rest_positions.iter().map(|p| to_world(*p)).collect();
        if let Some(i) = positions.iter().position(|p| !p.is_finite()) {
            return Err(ClothError::InvalidMesh {
                what: format!("vertex {i} has a non-finite world position"),
            });
        }
        // Only a closed surface holds air; a grid never is one.
        let built_volume = match model.grid {
            Some(_) => None,
            None => model
                .check_closed()
                .ok()
                .map(|_| enclosed_volume(&model.triangles, |i| positions[i]) as f32)
                .filter(|v| *v > 0.0),
        };
        let springs = model.springs.len();
        let mut sim = Self {
            particles: Particles {
                positions,
                velocities: vec![Vec3::ZERO; n],
                mass: vec![0.0; n],
                inv_mass: vec![0.0; n],
            },
            stiffness: vec![0.0; springs],
            steppers: Steppers::default(),
            omega_max: 0.0,
            spring_frequency: 0.0,
            longest_spring: model.springs.rest.iter().copied().fold(0.0, f32::max),
            active: settings.integrator,
            contacts: Contacts::new(n, (model.max_edge_length(), mean_edge)),
            wind: WindScratch::new(&model),
            built_volume,
            air: None,
            air_frequency: 0.0,
            air_bound: BoundScratch::default(),
            pins: Vec::new(),
            model,
            settings,
            steps: 0,
            tears: 0,
            tear_limits: Vec::new(),
            tear_weights: None,
            sleep: Sleep::default(),
            contact_work: None,
            step_start: Vec::with_capacity(n),
            runaway: Runaway::default(),
            frame: None,
            adaptive: None,
            detail: 1.0,
            revision: 0,
            coarse: None,
            no_coarse: None,
        };
        sim.check_air(settings)?;
        sim.prepare_self_contacts(settings.self_collision)?;
        Ok(sim)
    }

    /// With [`SolverSettings::pressure`] on, checks that the cloth can hold air: a closed surface
    /// wound outward ([`ClothModel::check_closed`]) that enclosed a positive volume where it was
    /// built. A torn cloth holds no air whatever the setting.
    fn check_air(&self, settings: SolverSettings) -> Result<(), ClothError> {
        if !settings.pressure.is_on() || self.built_volume.is_some() || self.tears > 0 {
            return Ok(());
        }
        // The model's own check names what is open or flipped; a closed model that enclosed no
        // volume in the world was mirrored by its transform.
        self.model.check_closed()?;
        Err(ClothError::NotClosed {
            what: "it enclosed no volume where it was built (was it mirrored by its transform?)"
                .into(),
        })
    }

    /// Continues the motion of `previous`, a cloth of the same topology (same particle count and
    /// triangles; the rest shape and settings may differ): its positions, velocities and step
    /// count. Returns whether it did; a cloth of another topology changes nothing.
    pub fn continue_from(&mut self, previous: &ClothSim) -> bool {
        let same = previous.model.particle_count() == self.model.particle_count()
            && previous.model.triangles == self.model.triangles;
        if same {
            let p = &previous.particles;
            self.particles.positions.copy_from_slice(&p.positions);
            self.particles.velocities.copy_from_slice(&p.velocities);
            self.steps = previous.steps;
            self.coarse_stale();
        }
        same
    }

    /// Replaces the settings, after validating them (for this cloth: see
    /// [`SelfCollision::validate_for`](crate::sim::SelfCollision::validate_for)); on an error
    /// nothing changes. Cheap (one pass over springs and particles) unless self-collision is
    /// turned on or its thickness or friction change; intended for runtime edits, not for calling
    /// every step.
    pub fn set_settings(&mut self, settings: SolverSettings) -> Result<(), ClothError> {
        settings.validate()?;
        settings
            .self_collision
            .validate_for(self.model.mean_edge_length())?;
        self.check_air(settings)?;
        self.prepare_self_contacts(settings.self_collision)?;
        self.settings = settings;
        self.apply_settings();
        self.wake();
        Ok(())
    }

    /// Recomputes everything derived from settings, masses and pins: per-spring stiffness,
    /// inverse masses, the frequency bound, and the steppers the integrator may run (their
    /// layouts, constants and scratch, [`Steppers::prepare`]). Runs at construction and on edits,
    /// never inside a step.
    pub(super) fn apply_settings(&mut self) {
        self.revision += 1;
        let s = &self.model.springs;
        for (k, kind) in self.stiffness.iter_mut().zip(&s.kind) {
            *k = self.settings.stiffness.of(*kind);
        }
        let p = &mut self.particles;
        for (i, (m, w)) in p.mass.iter_mut().zip(&mut p.inv_mass).enumerate() {
            *m = self.model.mass_of(i, self.settings.particle_mass);
            *w = 1.0 / *m;
        }
        for pin in &self.pins {
            p.inv_mass[pin.particle as usize] = 0.0;
        }
        let pinned: Vec<bool> = p.inv_mass.iter().map(|w| *w == 0.0).collect();
        let limits = self.contacts.limits_mut();
        limits.set_settings(self.settings.targets);
        limits.set_tethers(
            self.settings.tethers,
            (&self.model.triangles, &self.model.rest_positions),
            &pinned,
        );
        // A torn cloth's paths along itself are longer than they were, and may lead to another
        // pin: its tethers start no shorter than where the particles are.
        if self.tears > 0 {
            limits.fit_tethers(&self.particles.positions);
        }
        self.prepare_tearing();
        let mut scratch = vec![0.0; self.particles.positions.len()];
        self.spring_frequency =
            max_frequency_bound(self.spring_set(), &self.particles.inv_mass, &mut scratch);
        self.air = self
            .built_volume
            .filter(|_| self.settings.pressure.is_on())
            .map(|built_volume| {
                let mean_edge = self.model.mean_edge_length();
                Air::new(self.settings.pressure, built_volume, mean_edge)
            });
        self.refresh_air_frequency();
        // Tolerance mode chooses between XPBD and Verlet, as `Auto` does.
        let integrator = if self.settings.accuracy.tolerance.is_some() {
            Integrator::Auto
        } else {
            self.settings.integrator
        };
        self.steppers.prepare(
            integrator,
            &self.model,
            (&self.stiffness, &self.particles.inv_mass),
            (self.contacts.limits(), self.air.is_some()),
        );
        self.active = self.choose_integrator(1.0 / 60.0);
        // The copy tolerance mode estimates on is made of this cloth without its own copy.
        self.adaptive = None;
        self.adaptive = adaptive::Adaptive::new(self).map(Box::new);
        if let Some(a) = &self.adaptive {
            self.active = a.report().integrator;
        }
    }

    /// Builds the self-contacts' topology and exempt pairs for `c` when self-collision is turned
    /// on or its thickness or friction change, and drops them when it is turned off. On an error
    /// (see [`SelfContacts::new`]) the cloth keeps the ones it had.
    fn prepare_self_contacts(&mut self, c: SelfCollision) -> Result<(), ClothError> {
        if !c.enabled {
            self.contacts.set_self_contacts(None);
            return Ok(());
        }
        if self.contacts.self_contacts().map(|s| s.settings()) == Some((c.thickness, c.friction)) {
            return Ok(());
        }
        let contacts = SelfContacts::new(
            &self.model.triangles,
            &self.model.rest_positions,
            c.thickness,
            c.friction,
        )?;
        self.contacts.set_self_contacts(Some(contacts));
        if self.tears > 0 {
            self.part_the_sides();
        }
        Ok(())
    }

    /// The springs with their current stiffness, for the force kernel.
    pub(super) fn spring_set(&self) -> SpringSet<'_> {
        SpringSet::new(&self.model.springs, &self.stiffness)
    }
}
