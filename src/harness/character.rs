//! A skinned cape on a two-joint torso, built in code: the character-cloth scene the tests and
//! benchmarks share. The torso is a root joint at the origin and a spine joint 1 m above it; the
//! cape hangs behind it from the collar (y = 1.5) to the hem (y = 0.7), skinned to the spine at
//! the collar and to the root at the hem, with its target weight (0 at the collar, 1 at the hem)
//! in the red channel of `COLOR_0`.

use bevy::asset::{Assets, RenderAssetUsages};
use bevy::ecs::prelude::*;
use bevy::math::{Mat4, Quat, Vec3};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Indices, Mesh, PrimitiveTopology, VertexAttributeValues};
use bevy::transform::components::Transform;

use crate::components::{Cloth, ClothConfig, ClothTargets, TargetWeights};

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
    let mesh = world.resource_mut::<Assets<Mesh>>().add(cape.mesh.clone());
    let inverse_bindposes = world
        .resource_mut::<Assets<SkinnedMeshInverseBindposes>>()
        .add(SkinnedMeshInverseBindposes::from(
            cape.inverse_bindposes.clone(),
        ));
    let (root_pose, spine_pose) = torso_pose(0.0, 0.0, 0.0);
    let root = world.spawn(root_pose).id();
    let spine = world.spawn((spine_pose, ChildOf(root))).id();
    let cloth = world
        .spawn((
            Cloth::from_mesh(mesh),
            SkinnedMesh {
                inverse_bindposes,
                joints: vec![root, spine],
            },
            ClothTargets {
                weights: TargetWeights::Color(0),
            },
            config,
        ))
        .id();
    SpawnedCape { cloth, root, spine }
}
