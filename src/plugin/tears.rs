//! Tearing in the ECS: [`ClothCut`] messages queued for a cloth's next step (in
//! [`ClothSystems::Prepare`](super::ClothSystems::Prepare)), and each torn cloth's pins, targets
//! and render mesh following its new topology, announced as [`ClothTorn`] (in
//! [`ClothSystems::Subdivide`](super::ClothSystems::Subdivide), before the render positions).

use bevy::asset::Assets;
use bevy::ecs::prelude::*;
use bevy::log::warn;
use bevy::mesh::{Mesh, Mesh3d};
use bevy::reflect::Reflect;
use bevy::transform::components::GlobalTransform;

use super::build::rebuild_render;
use super::edits::{commit_pins, plan_pins};
use crate::components::{ClothInvalid, ClothPins, ClothState, ClothSubdivision, TargetWeights};
use crate::sim::{Cut, Split};

/// Cuts a cloth at its next step ([`Cut`]: a plane, a blade's segment, a ray's hole). Written by
/// a game like any message; a cut that is not valid (a zero normal, a negative radius) or names no
/// running cloth is logged and dropped. The cloth tears where the cut meets it, and a
/// [`ClothTorn`] follows.
///
/// ```
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
/// use bevy_cloth::sim::Cut;
///
/// fn slash(mut cuts: MessageWriter<ClothCut>, cloths: Query<Entity, With<Cloth>>) {
///     for cloth in &cloths {
///         // Cut every cloth through its middle, side to side.
///         let cut = Cut::Plane { point: Vec3::ZERO, normal: Vec3::Y };
///         cuts.write(ClothCut { cloth, cut });
///     }
/// }
/// # bevy::ecs::system::assert_is_system(slash);
/// ```
#[derive(Message, Debug, Clone, Copy, PartialEq)]
pub struct ClothCut {
    /// The cloth's entity.
    pub cloth: Entity,
    /// Where it is cut, world space.
    pub cut: Cut,
}

/// A cloth tore in its latest step, by a [`ClothCut`] or under strain
/// ([`SolverSettings::tearing`](crate::sim::SolverSettings::tearing)): the particles that split,
/// each with its copy and where it split (to play a sound or spawn debris there). The cloth stays
/// one entity; [`ClothModel::pieces`](crate::sim::ClothModel::pieces) of its
/// [`ClothState::sim`] model says which particles make each piece.
#[derive(Message, Debug, Clone, PartialEq)]
pub struct ClothTorn {
    /// The cloth's entity.
    pub cloth: Entity,
    /// The splits, in the order they happened.
    pub splits: Vec<Split>,
}

/// How strong a cloth is, particle by particle, for tearing under strain
/// ([`SolverSettings::tearing`](crate::sim::SolverSettings::tearing)): each particle's weight
/// scales `max_stretch` for the springs at it (a spring takes the smaller of its ends' weights), so
/// 0 paints a line that tears at any stretch and 2 a hem that takes twice the stretch
/// ([`ClothSim::set_tear_weights`](crate::sim::ClothSim::set_tear_weights)). The weights come as
/// [`ClothTargets`](crate::ClothTargets)' do: values, or a vertex colour channel or attribute of
/// the source mesh. Adding, editing or removing it rebuilds the cloth; a cloth refined for its
/// simulation ([`SubdivisionTarget::Simulation`](crate::SubdivisionTarget)) takes none.
#[derive(Component, Debug, Clone, PartialEq, Reflect)]
#[reflect(Component, Debug)]
pub struct ClothTearWeights {
    /// The weights, one per particle (per vertex of the source mesh), non-negative.
    pub weights: TargetWeights,
}

/// Hands each valid [`ClothCut`] to its cloth for the next step.
pub(super) fn queue_cuts(
    mut cuts: MessageReader<ClothCut>,
    mut cloths: Query<&mut ClothState, Without<ClothInvalid>>,
) {
    for ClothCut { cloth, cut } in cuts.read() {
        if let Err(e) = cut.validate() {
            warn!("cloth {cloth}: cut dropped: {e}");
            continue;
        }
        match cloths.get_mut(*cloth) {
            Ok(mut state) => state.cuts.push(*cut),
            Err(_) => warn!("cut dropped: {cloth} is not a running cloth"),
        }
    }
}

/// After a step that tore cloths: their copies of targeted particles join the targets and the
/// pieces torn free leave them, as in the solver; pins are set again (weight-0 targets pin the
/// copies too); the render side is rebuilt for the new particles and faces, and a [`ClothTorn`]
/// is written.
#[allow(clippy::type_complexity)]
pub(super) fn follow_tears(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut torn: MessageWriter<ClothTorn>,
    mut cloths: Query<
        (
            Entity,
            &mut ClothState,
            &GlobalTransform,
            Option<&ClothSubdivision>,
        ),
        Without<ClothInvalid>,
    >,
) {
    for (entity, mut state, transform, subdivision) in &mut cloths {
        if state.splits.is_empty() || state.failure.is_some() {
            continue;
        }
        let state = &mut *state;
        let splits = std::mem::take(&mut state.splits);
        let result = (|| {
            if let Some(attachment) = &mut state.attachment {
                attachment.add_copies(splits.iter().map(|s| (s.particle, s.copy)));
                // The targets the solver kept (those of pieces torn free are gone); weight-0
                // ones are pins, which the solver's targets do not list.
                let kept: std::collections::HashSet<u32> = state.sim.targeted().collect();
                attachment.retain(|p, w| w == 0.0 || kept.contains(&p));
                let targets: Vec<_> = attachment.limited().collect();
                state.sim.set_targets(&targets)?;
            }
            // The pins the cloth runs, its weight-0 targets' copies among them.
            let running = ClothPins {
                pins: state.pins.clone(),
            };
            let plan = plan_pins(state, &running, transform)?;
            commit_pins(state, plan)?;
            // A torn mesh the subdivision cannot refine is drawn as it is.
            rebuild_render(state, subdivision, (None, false), &mut meshes).or_else(|e| {
                warn!("cloth {entity}: its torn mesh is drawn unsubdivided: {e}");
                rebuild_render(state, None, (None, false), &mut meshes)
            })
        })();
        match result {
            Ok(mesh) => {
                commands.entity(entity).insert(Mesh3d(mesh));
                torn.write(ClothTorn {
                    cloth: entity,
                    splits,
                });
            }
            // The topology changed under the cloth: it cannot go on half followed.
            Err(e) => state.failure = Some(e),
        }
    }
}
