//! The coarse level of a lattice cloth ([`ClothSim::set_coarse`]): every other row and column of
//! its particles (with the last ones, and the lines a pin needs) simulated as a cloth of their
//! own, whose motion is interpolated to all the particles, so that the cloth's
//! positions, mesh and readouts stay those of the full cloth.

use glam::Vec3;

use super::{ClothSim, Environment};
use crate::error::ClothError;
use crate::sim::integrate::Spread;
use crate::sim::model::ClothModel;

/// A coarse cloth standing in for a lattice cloth, and how its motion spreads to the full one.
#[derive(Debug, Clone)]
pub(super) struct Coarse {
    /// The coarse cloth.
    sim: Box<ClothSim>,
    /// Per particle of the full cloth, its particle in the coarse one (`u32::MAX`: none).
    index: Vec<u32>,
    /// Per particle of the full cloth, the coarse particles at the corners of its cell and their
    /// bilinear weights.
    stencils: Vec<([u32; 4], [f32; 4])>,
    /// The full cloth's pins on kept particles, in the coarse cloth's order (indices into its
    /// pins); the others lie between pinned kept particles and are put on their targets.
    pins: Vec<u32>,
    /// The full cloth's revision it was built at ([`ClothSim::apply_settings`] moves it on).
    revision: u64,
    /// Whether the full cloth runs at this level.
    pub(super) on: bool,
    /// Whether the full cloth's motion changed outside a coarse step (it is taken again).
    pub(super) stale: bool,
    /// Scratch: the full cloth's positions at the start of a step.
    start: Vec<Vec3>,
    /// Where each particle was off the kept lines' interpolation when the level took over, and
    /// the steps left for that detail to fade (so that taking over moves no particle at once).
    detail: Vec<Vec3>,
    fading: u32,
}

/// Steps over which the detail a cloth had fades when its coarse level takes over.
pub const COARSE_FADE_STEPS: u32 = 10;

/// Of `0..n`, the lines marked in `kept`, in order.
fn lines(kept: &[bool]) -> Vec<usize> {
    (0..kept.len()).filter(|&i| kept[i]).collect()
}

/// For each of `0..n`, the kept lines on either side (equal when it is kept) and its weight
/// toward the second.
fn spans(n: usize, kept: &[usize]) -> Vec<(usize, usize, f32)> {
    let mut out = Vec::with_capacity(n);
    let mut k = 0;
    for i in 0..n {
        while kept[k] < i {
            k += 1;
        }
        if kept[k] == i {
            out.push((k, k, 0.0));
        } else {
            let (a, b) = (kept[k - 1], kept[k]);
            out.push((k - 1, k, (i - a) as f32 / (b - a) as f32));
        }
    }
    out
}

impl Coarse {
    /// The coarse level of `full`, at its motion now.
    fn build(full: &ClothSim) -> Result<Self, ClothError> {
        let no = |what: &str| ClothError::NoCoarseLevel { what: what.into() };
        let lattice = full
            .model
            .lattice()
            .ok_or_else(|| no("its particles are not rows and columns of a lattice"))?;
        let (nx, ny) = (lattice.nx, lattice.ny);
        // Every other row and column and the last ones; then the row and column of each pin
        // that does not lie between pinned kept particles, until every pin does.
        let every_other = |n: usize| (0..n).map(|i| i % 2 == 0 || i + 1 == n).collect();
        let (mut keep_i, mut keep_j): (Vec<bool>, Vec<bool>) = (every_other(nx), every_other(ny));
        let mut pinned = vec![false; nx * ny];
        for p in &full.pins {
            pinned[p.particle as usize] = true;
        }
        let (columns, rows, across, down) = loop {
            let (columns, rows) = (lines(&keep_i), lines(&keep_j));
            let (across, down) = (spans(nx, &columns), spans(ny, &rows));
            let mut added = false;
            for p in &full.pins {
                let f = p.particle as usize;
                let ((i0, i1, _), (j0, j1, _)) = (across[f % nx], down[f / nx]);
                let held = [(i0, j0), (i1, j0), (i0, j1), (i1, j1)]
                    .iter()
                    .all(|&(i, j)| pinned[rows[j] * nx + columns[i]]);
                if !held {
                    added |= !keep_i[f % nx] || !keep_j[f / nx];
                    (keep_i[f % nx], keep_j[f / nx]) = (true, true);
                }
            }
            if !added {
                break (columns, rows, across, down);
            }
        };
        let (cx, cy) = (columns.len(), rows.len());
        if cx * cy == nx * ny {
            return Err(no("it is too small to keep fewer rows or columns"));
        }
        let picked: Vec<usize> = rows
            .iter()
            .flat_map(|&j| columns.iter().map(move |&i| j * nx + i))
            .collect();
        let mut index = vec![u32::MAX; nx * ny];
        for (c, &f) in picked.iter().enumerate() {
            index[f] = c as u32;
        }
        let stencils: Vec<([u32; 4], [f32; 4])> = (0..nx * ny)
            .map(|f| {
                let ((i0, i1, s), (j0, j1, t)) = (across[f % nx], down[f / nx]);
                let at = |i: usize, j: usize| (j * cx + i) as u32;
                (
                    [at(i0, j0), at(i1, j0), at(i0, j1), at(i1, j1)],
                    [(1.0 - s) * (1.0 - t), s * (1.0 - t), (1.0 - s) * t, s * t],
                )
            })
            .collect();
        // Each coarse particle carries the mass its stencils give it, so the total is kept.
        let mut masses = vec![0.0f32; picked.len()];
        for (f, (corners, weights)) in stencils.iter().enumerate() {
            let m = full.model.mass_of(f, full.settings.particle_mass);
            for (&c, &w) in corners.iter().zip(weights) {
                masses[c as usize] += w * m;
            }
        }
        let model = &full.model;
        let rest: Vec<Vec3> = picked.iter().map(|&f| model.rest_positions[f]).collect();
        let uvs: Vec<_> = picked.iter().map(|&f| model.uvs[f]).collect();
        let mut quads = Vec::with_capacity(4 * (cx - 1) * (cy - 1));
        for j in 0..cy - 1 {
            for i in 0..cx - 1 {
                let a = (j * cx + i) as u32;
                let (b, c, d) = (a + 1, a + cx as u32, a + cx as u32 + 1);
                // Wound as the full cloth's triangles are.
                quads.extend(if lattice.clockwise {
                    [a, c, d, b]
                } else {
                    [a, b, d, c]
                });
            }
        }
        let coarse =
            ClothModel::from_mesh(&rest, Some(&uvs), &quads, 4)?.with_particle_masses(masses)?;
        let mut sim = ClothSim::assemble(coarse, full.settings, |p| p)?;
        let pins: Vec<u32> = (0..full.pins.len() as u32)
            .filter(|&k| index[full.pins[k as usize].particle as usize] != u32::MAX)
            .collect();
        sim.pins = pins
            .iter()
            .map(|&k| {
                let p = full.pins[k as usize];
                crate::sim::state::PinState {
                    particle: index[p.particle as usize],
                    ..p
                }
            })
            .collect();
        sim.apply_settings();
        sim.detail = full.detail;
        let mut coarse = Self {
            sim: Box::new(sim),
            index,
            stencils,
            pins,
            revision: full.revision,
            on: false,
            stale: true,
            start: Vec::new(),
            detail: Vec::new(),
            fading: 0,
        };
        coarse.take_motion(full);
        Ok(coarse)
    }

    /// Takes the full cloth's motion at the kept particles, and the detail between them to fade.
    fn take_motion(&mut self, full: &ClothSim) {
        let p = &mut self.sim.particles;
        for (f, &c) in self.index.iter().enumerate() {
            if c != u32::MAX {
                p.positions[c as usize] = full.particles.positions[f];
                p.velocities[c as usize] = full.particles.velocities[f];
            }
        }
        self.detail.clear();
        self.detail.extend(
            full.particles
                .positions
                .iter()
                .zip(&self.stencils)
                .map(|(x, stencil)| *x - between(&p.positions, stencil)),
        );
        self.fading = COARSE_FADE_STEPS;
        self.sim.runaway = Default::default();
        self.sim.wake();
        self.stale = false;
    }

    /// Wakes the coarse cloth.
    pub(super) fn wake(&mut self) {
        self.sim.wake();
    }

    /// Hands the coarse cloth what drives the full one this step: its pins' and targets' motion,
    /// its frame and its detail.
    fn drive(&mut self, full: &ClothSim) {
        let sim = &mut *self.sim;
        for (c, &k) in sim.pins.iter_mut().zip(&self.pins) {
            let f = &full.pins[k as usize];
            (c.from, c.to) = (f.from, f.to);
        }
        sim.contacts
            .limits_mut()
            .restrict_targets(full.contacts.limits(), &self.index);
        sim.frame = full.frame;
        if sim.detail != full.detail {
            // The full cloth's detail is valid.
            let _ = sim.set_detail(full.detail);
        }
    }

    /// Spreads the coarse cloth's motion over a step of `dt` to every particle of the full one,
    /// held to its pins, targets and tethers as a step of its own would leave it.
    fn spread_to(&mut self, full: &mut ClothSim, dt: f32) {
        self.start.clone_from(&full.particles.positions);
        let (x, v) = (
            &self.sim.particles.positions,
            &self.sim.particles.velocities,
        );
        let p = &mut full.particles;
        for ((pos, vel), stencil) in p
            .positions
            .iter_mut()
            .zip(&mut p.velocities)
            .zip(&self.stencils)
        {
            (*pos, *vel) = (between(x, stencil), between(v, stencil));
        }
        if self.fading > 0 {
            // The detail left shrinks by an equal share each step, and the particles move with it.
            self.fading -= 1;
            let left = self.fading as f32 / COARSE_FADE_STEPS as f32;
            let speed = 1.0 / (COARSE_FADE_STEPS as f32 * dt);
            for ((pos, vel), d) in p
                .positions
                .iter_mut()
                .zip(&mut p.velocities)
                .zip(&self.detail)
            {
                *pos += left * *d;
                *vel -= speed * *d;
            }
        }
        for pin in &full.pins {
            p.positions[pin.particle as usize] = pin.to;
        }
        let state = (&mut p.positions[..], &mut p.velocities[..], &self.start[..]);
        full.contacts.hold_to_limits(state, &p.inv_mass, dt);
    }
}

/// The value `stencil` interpolates from `values` at the coarse particles.
fn between(values: &[Vec3], (corners, weights): &([u32; 4], [f32; 4])) -> Vec3 {
    corners
        .iter()
        .zip(weights)
        .map(|(&c, &w)| w * values[c as usize])
        .sum()
}

impl ClothSim {
    /// Runs the cloth at its coarse level (`true`) or at full resolution (`false`, the default).
    ///
    /// A cloth whose particles are rows and columns of a lattice (a grid, or a mesh laid out like
    /// one, such as a skinned cape made from a grid of vertices) has a coarse level: every other
    /// row and column, with the last ones and the row and column of each pin that does not lie
    /// between pinned kept particles, simulated as a cloth of their own (springs from its quads,
    /// each coarse particle carrying the mass its neighbours lend it, the same settings, pins and
    /// targets). About a quarter of the particles step. After each of its steps every particle of
    /// the cloth is put where the coarse cloth's motion puts it, bilinearly between the kept rows
    /// and columns, and held to its own targets and tethers, so positions, the render mesh and
    /// every readout are still the full cloth's. The level takes up the cloth's motion as it is
    /// when it is turned on; the detail the cloth had between the kept lines then fades over
    /// [`COARSE_FADE_STEPS`] steps, so no particle jumps. Going back to full resolution continues
    /// from there. The coarse cloth is built on first use and again after pins, settings or
    /// topology change.
    ///
    /// Colliders and self-collision act on the kept particles only: a particle between them may
    /// lie inside a convex collider by up to the sag of a chord across two cells (a few
    /// millimetres on a cape), which is why this is a level for cloths seen from afar.
    ///
    /// A cloth with no coarse level (not a lattice, torn, or too small to keep fewer rows or
    /// columns) is [`ClothError::NoCoarseLevel`] and stays at full resolution.
    pub fn set_coarse(&mut self, on: bool) -> Result<(), ClothError> {
        if !on {
            if let Some(coarse) = self.coarse.as_mut().filter(|c| c.on) {
                coarse.on = false;
                self.wake();
            }
            return Ok(());
        }
        let coarse = self.coarse_level()?;
        if !coarse.on {
            // It takes up the cloth's motion as it is when it next steps.
            (coarse.on, coarse.stale) = (true, true);
        }
        Ok(())
    }

    /// Whether the cloth runs at its coarse level ([`Self::set_coarse`]).
    pub fn is_coarse(&self) -> bool {
        self.coarse.as_ref().is_some_and(|c| c.on)
    }

    /// Number of particles the coarse level steps (built if needed); `None` for a cloth with no
    /// coarse level.
    pub fn coarse_particle_count(&mut self) -> Option<usize> {
        let coarse = self.coarse_level().ok()?;
        Some(coarse.sim.particles.positions.len())
    }

    /// The coarse level, built or built again for the cloth as it is now (a failure is kept
    /// until the cloth changes).
    fn coarse_level(&mut self) -> Result<&mut Coarse, ClothError> {
        if let Some((revision, e)) = &self.no_coarse
            && *revision == self.revision
        {
            return Err(e.clone());
        }
        let current = self.coarse.as_ref().is_some_and(|c| {
            c.revision == self.revision && c.index.len() == self.model.particle_count()
        });
        if !current {
            let on = self.coarse.take().is_some_and(|c| c.on);
            match Coarse::build(self) {
                Ok(mut built) => {
                    built.on = on;
                    self.coarse = Some(Box::new(built));
                }
                Err(e) => {
                    self.no_coarse = Some((self.revision, e.clone()));
                    return Err(e);
                }
            }
        }
        Ok(self.coarse.as_deref_mut().expect("built above"))
    }

    /// The cloth that takes the steps: the coarse one while the cloth runs at its coarse level.
    pub(super) fn stepping(&self) -> &ClothSim {
        match self.coarse.as_deref() {
            Some(c) if c.on => &c.sim,
            _ => self,
        }
    }

    /// Marks the full cloth's motion as set from outside a coarse step.
    pub(super) fn coarse_stale(&mut self) {
        if let Some(c) = &mut self.coarse {
            c.stale = true;
        }
    }

    /// One step at the coarse level; a cloth that lost its coarse level (torn, say) takes it at
    /// full resolution.
    pub(super) fn step_coarse(
        &mut self,
        dt: f32,
        env: &Environment,
        spread: Option<&dyn Spread>,
    ) -> Result<(), ClothError> {
        if self.coarse_level().is_err() {
            self.coarse = None;
            self.wake();
            return self.step_spread(dt, env, spread);
        }
        let mut coarse = self.coarse.take().expect("built above");
        if coarse.stale {
            coarse.take_motion(self);
        }
        coarse.drive(self);
        let result = coarse.sim.step_spread(dt, env, spread);
        if result.is_ok() {
            coarse.spread_to(self, dt);
        }
        // The full cloth's drivers have reached where this step took them.
        for pin in &mut self.pins {
            pin.from = pin.to;
        }
        self.contacts.limits_mut().end_step();
        if let Some((from, to)) = &mut self.frame {
            *from = *to;
        }
        self.sleep.asleep = coarse.sim.sleep.asleep;
        self.sleep.skipped = coarse.sim.sleep.skipped;
        self.steps += 1;
        self.coarse = Some(coarse);
        result
    }
}

#[cfg(test)]
mod tests;
