//! A skinned cape on a two-joint torso, built in code: the character cloth of scene files
//! ([`SceneCloth::Cape`](super::SceneCloth::Cape)), the tests and the benchmarks. The torso is a
//! root joint at the origin and a spine joint 1 m above it; the cape hangs behind it from the
//! collar (y = 1.5) to the hem (y = 0.7), skinned to the spine at the collar and to the root at
//! the hem, with its target weight (0 at the collar, 1 at the hem) in the red channel of
//! `COLOR_0`. A [`Walker`] on the root joint animates the torso as [`SceneWalk`] says.

use bevy::asset::{Assets, Handle, RenderAssetUsages};
use bevy::ecs::prelude::*;
use bevy::math::{Mat4, Quat, Vec3};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues};
use bevy::time::Time;
use bevy::transform::components::Transform;
use serde::{Deserialize, Serialize};

use crate::components::{Cloth, ClothConfig, ClothTargets, TargetWeights};
use crate::error::{ClothError, finite, non_negative};

/// Where the spine joint sits on the root at bind time.
pub const SPINE: Vec3 = Vec3::new(0.0, 1.0, 0.0);

/// A cape mesh of `nx` × `ny` vertices and what it was made of.
#[derive(Debug, Clone)]
pub struct Cape {
    /// The mesh: positions, joint indices and weights, `COLOR_0`, triangles.
    pub mesh: Mesh,
    /// Each vertex's rest (bind) position.
    pub rest: Vec<Vec3>,
    /// Each vertex's joints (0 root, 1 spine).
    pub joints: Vec<[u16; 4]>,
    /// Each vertex's joint weights.
    pub weights: Vec<[f32; 4]>,
    /// The joints' inverse bind poses.
    pub inverse_bindposes: Vec<Mat4>,
}

impl Cape {
    /// A cape of `nx` × `ny` vertices (at least 2 each), 0.5 m wide, slightly curved around the
    /// back.
    pub fn new(nx: usize, ny: usize) -> Self {
        let (nx, ny) = (nx.max(2), ny.max(2));
        let mut rest = Vec::new();
        let (mut joints, mut weights, mut colors) = (Vec::new(), Vec::new(), Vec::new());
        for j in 0..ny {
            let s = j as f32 / (ny - 1) as f32;
            for i in 0..nx {
                let x = -0.25 + 0.5 * i as f32 / (nx - 1) as f32;
                rest.push(Vec3::new(x, 1.5 - 0.8 * s, -0.15 - 0.4 * x * x));
                joints.push([1u16, 0, 0, 0]);
                weights.push([1.0 - s, s, 0.0, 0.0]);
                colors.push([s, 0.0, 0.0, 1.0]);
            }
        }
        let mut indices = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = (j * nx + i) as u32;
                let (b, c, d) = (a + 1, a + nx as u32, a + nx as u32 + 1);
                indices.extend([a, c, b, b, c, d]);
            }
        }
        let mesh = Mesh::new(
            PrimitiveTopology::TriangleList,
            RenderAssetUsages::default(),
        )
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_POSITION,
            rest.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
        )
        .with_inserted_attribute(
            Mesh::ATTRIBUTE_JOINT_INDEX,
            VertexAttributeValues::Uint16x4(joints.clone()),
        )
        .with_inserted_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT, weights.clone())
        .with_inserted_attribute(Mesh::ATTRIBUTE_COLOR, colors)
        .with_inserted_indices(Indices::U32(indices));
        Self {
            mesh,
            rest,
            joints,
            weights,
            inverse_bindposes: vec![Mat4::IDENTITY, Mat4::from_translation(-SPINE)],
        }
    }
}

/// The root's and the spine's local transforms at time `t`: the root walks along +Z at `speed`
/// m/s while the spine turns about the vertical by `turn` radians per second.
pub fn torso_pose(t: f32, speed: f32, turn: f32) -> (Transform, Transform) {
    (
        Transform::from_xyz(0.0, 0.0, speed * t),
        Transform::from_translation(SPINE).with_rotation(Quat::from_rotation_y(turn * t)),
    )
}

/// The entities of a spawned cape.
#[derive(Debug, Clone, Copy)]
pub struct SpawnedCape {
    /// The cloth.
    pub cloth: Entity,
    /// The root joint.
    pub root: Entity,
    /// The spine joint (a child of the root).
    pub spine: Entity,
}

/// Spawns the torso's two joints at their bind pose and `cape` on them as a skinned cloth
/// ([`SkinnedMesh`], targets weighted by `COLOR_0`'s red channel) with `config`.
pub fn spawn_cape(world: &mut World, cape: &Cape, config: ClothConfig) -> SpawnedCape {
    let assets = cape_assets(world, cape);
    let (root_pose, spine_pose) = torso_pose(0.0, 0.0, 0.0);
    let root = world.spawn(root_pose).id();
    let spine = world.spawn((spine_pose, ChildOf(root))).id();
    let cloth = world
        .spawn((skinned_cloth(&assets, root, spine), config))
        .id();
    SpawnedCape { cloth, root, spine }
}

/// A cape's mesh and inverse bind poses as assets, to share between the characters wearing it.
#[derive(Debug, Clone)]
pub(super) struct CapeAssets {
    mesh: Handle<Mesh>,
    inverse_bindposes: Handle<SkinnedMeshInverseBindposes>,
}

pub(super) fn cape_assets(world: &mut World, cape: &Cape) -> CapeAssets {
    CapeAssets {
        mesh: world.resource_mut::<Assets<Mesh>>().add(cape.mesh.clone()),
        inverse_bindposes: world
            .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
            .add(SkinnedMeshInverseBindposes::from(
                cape.inverse_bindposes.clone(),
            )),
    }
}

/// The components of a cape cloth skinned to `root` and `spine`.
fn skinned_cloth(assets: &CapeAssets, root: Entity, spine: Entity) -> impl Bundle {
    (
        Cloth::from_mesh(assets.mesh.clone()),
        SkinnedMesh {
            inverse_bindposes: assets.inverse_bindposes.clone(),
            joints: vec![root, spine],
        },
        ClothTargets {
            weights: TargetWeights::Color(0),
        },
    )
}

/// Spawns a scene character: the cloth entity with `bundle` (its placement, settings and pins),
/// and under it the torso's joints, the root walking as `walk` says, `phase` seconds ahead.
pub(super) fn spawn_character(
    world: &mut World,
    assets: &CapeAssets,
    bundle: impl Bundle,
    walk: SceneWalk,
    phase: f32,
) -> Entity {
    let cloth = world.spawn(bundle).id();
    let (root_pose, spine_pose) = walk.pose(phase);
    let root = world.spawn((root_pose, ChildOf(cloth))).id();
    let spine = world.spawn((spine_pose, ChildOf(root))).id();
    world.entity_mut(root).insert(Walker { walk, phase, spine });
    world
        .entity_mut(cloth)
        .insert(skinned_cloth(assets, root, spine));
    cloth
}

fn default_sway_rate() -> f32 {
    1.0
}

/// How a scene character's torso moves: its root walks a circle of `radius` at `speed` (in place
/// with a radius of 0), turning as it goes, while its spine sways about the vertical. Standing
/// still by default.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneWalk {
    /// Walking speed along the circle, m/s; it needs a radius.
    #[serde(default)]
    pub speed: f32,
    /// Radius of the circle, m; the root starts at its placement facing +Z and turns left.
    #[serde(default)]
    pub radius: f32,
    /// Amplitude of the spine's sway about the vertical, rad.
    #[serde(default)]
    pub sway: f32,
    /// Sways per second, Hz.
    #[serde(default = "default_sway_rate")]
    pub sway_rate: f32,
}

impl Default for SceneWalk {
    fn default() -> Self {
        Self {
            speed: 0.0,
            radius: 0.0,
            sway: 0.0,
            sway_rate: default_sway_rate(),
        }
    }
}

impl SceneWalk {
    /// Checks the values: finite, not negative, and a radius where the speed is not 0.
    pub fn validate(&self) -> Result<(), ClothError> {
        finite("walk.sway", self.sway)?;
        non_negative("walk.speed", self.speed)?;
        non_negative("walk.radius", self.radius)?;
        non_negative("walk.sway_rate", self.sway_rate)?;
        if self.speed > 0.0 && self.radius <= 0.0 {
            return Err(ClothError::InvalidValue {
                field: "walk.radius",
                expected: "positive where walk.speed is (the circle walked)",
                value: self.radius as f64,
            });
        }
        Ok(())
    }

    /// The root's and the spine's local transforms at time `t`, s.
    pub fn pose(&self, t: f32) -> (Transform, Transform) {
        let angle = if self.radius > 0.0 {
            self.speed * t / self.radius
        } else {
            0.0
        };
        let root = Transform::from_xyz(
            self.radius * (1.0 - angle.cos()),
            0.0,
            self.radius * angle.sin(),
        )
        .with_rotation(Quat::from_rotation_y(angle));
        let sway = self.sway * (std::f32::consts::TAU * self.sway_rate * t).sin();
        let spine = Transform::from_translation(SPINE).with_rotation(Quat::from_rotation_y(sway));
        (root, spine)
    }
}

/// Animates a scene character: on its root joint, with the walk, how far ahead of the scene's
/// clock it runs, and its spine joint.
#[derive(Component, Debug, Clone, Copy)]
pub struct Walker {
    /// The motion.
    pub walk: SceneWalk,
    /// Seconds the walk runs ahead of the clock.
    pub phase: f32,
    /// The spine joint, a child of the root.
    pub spine: Entity,
}

/// Poses every walker's joints for the end of this step.
pub(super) fn walk_characters(
    time: Res<Time>,
    mut roots: Query<(&Walker, &mut Transform)>,
    mut spines: Query<&mut Transform, Without<Walker>>,
) {
    let t = time.elapsed_secs();
    for (walker, mut root) in &mut roots {
        let (root_pose, spine_pose) = walker.walk.pose(t + walker.phase);
        *root = root_pose;
        if let Ok(mut spine) = spines.get_mut(walker.spine) {
            *spine = spine_pose;
        }
    }
}
