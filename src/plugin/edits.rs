//! Runtime edits (in [`ClothSystems::Prepare`](super::ClothSystems::Prepare)): edited
//! [`ClothConfig`]s and [`ClothPins`] applied to running cloths before they step. Building a cloth
//! applies its settings and pins through the same functions.

use bevy::ecs::prelude::*;
use bevy::transform::components::GlobalTransform;

use crate::components::{ClothConfig, ClothInvalid, ClothPins, ClothState};
use crate::error::ClothError;
use crate::sim::SolverSettings;

/// Applies edited [`ClothConfig`]s and [`ClothPins`] to running cloths before they step. A bad edit
/// stops the cloth (reported by [`build_cloths`](super::build::build_cloths)).
#[allow(clippy::type_complexity)]
pub(super) fn apply_edits(
    mut cloths: Query<
        (
            Ref<ClothConfig>,
            Ref<ClothPins>,
            &GlobalTransform,
            &mut ClothState,
        ),
        Without<ClothInvalid>,
    >,
) {
    for (config, pins, transform, mut state) in &mut cloths {
        if state.failure.is_some() || !(config.is_changed() || pins.is_changed()) {
            continue;
        }
        let mut result = Ok(());
        if config.is_changed() {
            let settings = run_settings(&config, state.mass_scale);
            result = state.sim.set_settings(settings);
        }
        if result.is_ok() && pins.is_changed() {
            result = apply_pins(&mut state, &pins, transform);
        }
        state.failure = result.err();
    }
}

/// The solver settings of `config` as a cloth runs them: the particle mass scaled by
/// `mass_scale` (below 1 for a cloth simulated at a subdivided resolution, to keep its mass).
pub(super) fn run_settings(config: &ClothConfig, mass_scale: f32) -> SolverSettings {
    let mut settings = config.solver;
    settings.particle_mass *= mass_scale;
    settings
}

/// Replaces the pin set of a running cloth, each pin starting at its anchor's current position:
/// the [`ClothPins`], then the targets' weight-0 particles they do not pin.
pub(super) fn apply_pins(
    state: &mut ClothState,
    pins: &ClothPins,
    transform: &GlobalTransform,
) -> Result<(), ClothError> {
    state.pin_targets.clear();
    let mut targets = Vec::with_capacity(pins.pins.len());
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
        state.pin_targets.push(target);
        targets.push((index as u32, target));
    }
    state.target_pins.clear();
    if let Some(a) = &state.attachment {
        let mut pinned = vec![false; state.sim.positions().len()];
        for &(p, _) in &targets {
            pinned[p as usize] = true;
        }
        for (k, (&(particle, weight), &(target, _))) in
            a.weighted.iter().zip(&a.targets).enumerate()
        {
            if weight == 0.0 && !pinned[particle as usize] {
                state.target_pins.push(k);
                state.pin_targets.push(target);
                targets.push((particle, target));
            }
        }
    }
    state.sim.set_pins(targets)
}
