//! The ECS side of tearing: [`ClothTearWeights`] on a cloth, [`ClothCut`] messages a game
//! writes, and [`ClothTorn`] messages the plugin writes after a cloth tore. The solver's side is
//! [`ClothSim::tear`](crate::sim::ClothSim::tear).

use bevy::ecs::prelude::*;
use bevy::reflect::Reflect;

use crate::components::TargetWeights;
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
/// [`ClothState::sim`](crate::ClothState::sim) model says which particles make each piece.
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
