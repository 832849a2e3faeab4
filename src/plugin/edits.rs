//! Runtime edits (in [`ClothSystems::Prepare`](super::ClothSystems::Prepare)): edited
//! [`ClothConfig`]s and [`ClothPins`] applied to running cloths before they step, each as a
//! transaction: checked whole, then applied, or rejected with the cloth left as it was. Building a
//! cloth applies its settings and pins through the same functions.

use bevy::ecs::prelude::*;
use bevy::log::warn;
use bevy::math::Vec3;
use bevy::transform::components::GlobalTransform;

use crate::components::{
    Cloth, ClothConfig, ClothEditRejected, ClothInvalid, ClothPin, ClothPins, ClothState,
};
use crate::error::{ClothError, finite_vec3};
use crate::sim::SolverSettings;

type Incomplete = (Entity, Has<ClothConfig>, Has<ClothPins>);
type IncompleteFilter = (With<Cloth>, Or<(Without<ClothConfig>, Without<ClothPins>)>);

/// Gives a cloth whose [`ClothConfig`] or [`ClothPins`] was removed the default one (default
/// settings, no pins), applied as an edit: a cloth always has both.
pub(super) fn restore_required(
    mut commands: Commands,
    cloths: Query<Incomplete, IncompleteFilter>,
) {
    for (entity, config, pins) in &cloths {
        let mut entity = commands.entity(entity);
        if !config {
            entity.insert(ClothConfig::default());
        }
        if !pins {
            entity.insert(ClothPins::default());
        }
    }
}

/// Applies edited [`ClothConfig`]s and [`ClothPins`] to running cloths before they step. An edit
/// that fails leaves the cloth running unchanged and is reported ([`report_edit`]); the next
/// edit of such a cloth rebuilds it from all its components.
#[allow(clippy::type_complexity)]
pub(super) fn apply_edits(
    mut commands: Commands,
    mut cloths: Query<
        (
            Entity,
            Ref<ClothConfig>,
            Ref<ClothPins>,
            &GlobalTransform,
            &mut ClothState,
            Option<&ClothEditRejected>,
        ),
        Without<ClothInvalid>,
    >,
) {
    for (entity, config, pins, transform, mut state, rejected) in &mut cloths {
        // A cloth whose last edit was rejected runs what its components no longer say: it is
        // built again from all of them, as a whole (in `Build`).
        if state.failure.is_some()
            || rejected.is_some()
            || !(config.is_changed() || pins.is_changed())
        {
            continue;
        }
        let config = config.is_changed().then_some(&*config);
        let pins = pins.is_changed().then_some(&*pins);
        let result = edit_running(&mut state, config, pins, transform);
        report_edit(&mut commands, entity, result, rejected);
    }
}

/// Applies a new config and/or pin set to a running cloth, all or nothing: the pins are planned
/// (every index and target checked) before the settings are swapped in, and the settings (checked
/// against the cloth's model) before the pins.
fn edit_running(
    state: &mut ClothState,
    config: Option<&ClothConfig>,
    pins: Option<&ClothPins>,
    transform: &GlobalTransform,
) -> Result<(), ClothError> {
    let plan = pins
        .map(|pins| plan_pins(state, pins, transform))
        .transpose()?;
    if let Some(config) = config {
        state
            .sim
            .set_settings(run_settings(config, state.mass_scale))?;
    }
    match plan {
        Some(plan) => commit_pins(state, plan),
        None => Ok(()),
    }
}

/// Reports the outcome of an edit of a running cloth: a rejection is logged and marks the cloth
/// with [`ClothEditRejected`] (once: the same rejection again is not repeated); an accepted edit
/// clears the mark.
pub(super) fn report_edit(
    commands: &mut Commands,
    entity: Entity,
    result: Result<(), ClothError>,
    marked: Option<&ClothEditRejected>,
) {
    match result {
        Ok(()) if marked.is_some() => {
            commands.entity(entity).remove::<ClothEditRejected>();
        }
        Ok(()) => {}
        Err(e) if marked.is_some_and(|m| m.0 == e) => {}
        Err(e) => {
            warn!("cloth {entity}: edit rejected, the cloth runs on unchanged: {e}");
            commands.entity(entity).insert(ClothEditRejected(e));
        }
    }
}

/// The solver settings of `config` as a cloth runs them: the particle mass scaled by
/// `mass_scale` (below 1 for a cloth simulated at a subdivided resolution, to keep its mass).
pub(super) fn run_settings(config: &ClothConfig, mass_scale: f32) -> SolverSettings {
    let mut settings = config.solver;
    settings.particle_mass *= mass_scale;
    settings
}

/// A cloth's pin set as it will run, computed without changing the cloth: the [`ClothPins`] in
/// their order, then the targets' weight-0 particles they do not pin.
pub(super) struct PinPlan {
    pins: Vec<ClothPin>,
    /// Where each pin starts, in the order above.
    targets: Vec<Vec3>,
    /// The entries of the attachment pinned after the [`ClothPins`].
    target_pins: Vec<usize>,
    /// Each pinned simulation particle and its target.
    particles: Vec<(u32, Vec3)>,
}

/// Plans the pin set `pins` for `state`, each pin starting at its anchor's current position;
/// fails on a particle out of range or a target that is not finite.
pub(super) fn plan_pins(
    state: &ClothState,
    pins: &ClothPins,
    transform: &GlobalTransform,
) -> Result<PinPlan, ClothError> {
    let mut plan = PinPlan {
        pins: pins.pins.clone(),
        targets: Vec::with_capacity(pins.pins.len()),
        target_pins: Vec::new(),
        particles: Vec::with_capacity(pins.pins.len()),
    };
    for pin in &pins.pins {
        let Some(index) = state.particle(pin.particle) else {
            return Err(ClothError::PinOutOfRange {
                index: pin.particle,
                count: state
                    .particle_map
                    .as_ref()
                    .map_or(state.sim.positions().len(), Vec::len),
            });
        };
        let rest = state.sim.model().rest_positions[index];
        // An entity's anchor is resolved in `Prepare`; until then the particle stays where it is.
        let target = pin
            .anchor
            .target(|| Some(transform.transform_point(rest)), |_| None)
            .unwrap_or(state.sim.positions()[index]);
        finite_vec3(["pin target.x", "pin target.y", "pin target.z"], target)?;
        plan.targets.push(target);
        plan.particles.push((index as u32, target));
    }
    if let Some(a) = &state.attachment {
        let mut pinned = vec![false; state.sim.positions().len()];
        for &(p, _) in &plan.particles {
            pinned[p as usize] = true;
        }
        for (k, (&(particle, weight), &(target, _))) in
            a.weighted.iter().zip(&a.targets).enumerate()
        {
            if weight == 0.0 && !pinned[particle as usize] {
                plan.target_pins.push(k);
                plan.targets.push(target);
                plan.particles.push((particle, target));
            }
        }
    }
    Ok(plan)
}

/// Swaps a planned pin set in.
pub(super) fn commit_pins(state: &mut ClothState, plan: PinPlan) -> Result<(), ClothError> {
    state.sim.set_pins(plan.particles)?;
    state.pins = plan.pins;
    state.pin_targets = plan.targets;
    state.target_pins = plan.target_pins;
    Ok(())
}
