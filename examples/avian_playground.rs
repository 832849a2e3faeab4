//! Cloth in an avian3d physics world: crates and balls fall into a hammock pinned at its four
//! corners (the hammock pushes them back: two-way coupling), and a second cloth drops onto a
//! triangle-mesh terrain and a convex rock. Every collider is an ordinary avian one; nothing is
//! mirrored by hand. The inspector panel edits the cloths.
//!
//! `cargo run --release --features examples --example avian_playground`
//!
//! Keys: Space drops another crate into the hammock, B another ball. Drag to orbit.

mod common;

use avian3d::prelude::*;
use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_cloth::avian::{ClothAvianPlugin, ClothPushesBodies};
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};

/// Where the hammock's centre hangs.
const HAMMOCK: Vec3 = Vec3::new(-0.1, 1.1, 0.0);
/// Where the terrain's centre lies.
const TERRAIN: Vec3 = Vec3::new(1.6, 0.0, 0.0);

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: avian playground",
            focus: Vec3::new(0.35, 0.5, 0.0),
            eye: Vec3::new(0.45, 2.5, 3.7),
        })
        .add_plugins((
            PhysicsPlugins::default(),
            ClothPlugin::default(),
            ClothAvianPlugin,
            ClothInspectorPlugin,
        ))
        .add_systems(Startup, setup)
        .add_systems(Update, keys)
        .add_systems(EguiPrimaryContextPass, panel)
        .run();
}

/// Meshes and materials for what the keys and the panel drop.
#[derive(Resource)]
struct Drops {
    crate_mesh: Handle<Mesh>,
    ball_mesh: Handle<Mesh>,
    wood: Handle<StandardMaterial>,
    rubber: Handle<StandardMaterial>,
    count: u32,
}

impl Drops {
    /// A 25 cm, 1.5 kg crate, or a 12 cm-radius, 0.8 kg ball, above the hammock.
    fn drop(&mut self, commands: &mut Commands, ball: bool) {
        // Spread the drops over the hammock so that they land side by side.
        let k = self.count as f32;
        self.count += 1;
        let at = HAMMOCK
            + Vec3::new(
                0.3 * (k * 2.4).sin(),
                0.9 + 0.3 * (k % 3.0),
                0.3 * (k * 2.4).cos(),
            );
        let transform = Transform::from_translation(at).with_rotation(Quat::from_rotation_y(k));
        if ball {
            commands.spawn((
                RigidBody::Dynamic,
                Collider::sphere(0.12),
                Mass(0.8),
                Mesh3d(self.ball_mesh.clone()),
                MeshMaterial3d(self.rubber.clone()),
                transform,
            ));
        } else {
            commands.spawn((
                RigidBody::Dynamic,
                Collider::cuboid(0.25, 0.25, 0.25),
                Mass(1.5),
                Mesh3d(self.crate_mesh.clone()),
                MeshMaterial3d(self.wood.clone()),
                transform,
            ));
        }
    }
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) -> Result {
    let fabric = common::fabric(&asset_server, &mut materials);
    // The ground (drawn by the common plugin).
    commands.spawn((RigidBody::Static, Collider::half_space(Vec3::Y)));

    // The hammock: 1.55 m square, pinned at its corners, pushing back on what falls in.
    let n = 32;
    let spacing = 0.05;
    let half = 0.5 * spacing * (n - 1) as f32;
    commands.spawn((
        Name::new("hammock"),
        Cloth::grid(GridSpec::new(n, n, spacing)),
        ClothConfig {
            solver: SolverSettings {
                particle_mass: 0.01,
                damping: 0.3,
                ..default()
            },
            ..default()
        },
        ClothPins::new([0, n - 1, n * (n - 1), n * n - 1]),
        ClothPushesBodies,
        MeshMaterial3d(fabric.clone()),
        Transform::from_translation(HAMMOCK),
    ));
    // Posts under the pinned corners, for the eye (and as colliders the cloth hangs between).
    let post = meshes.add(Cylinder::new(0.03, HAMMOCK.y).mesh());
    let metal = materials.add(StandardMaterial {
        base_color: Color::srgb(0.3, 0.3, 0.32),
        metallic: 0.6,
        ..default()
    });
    for (x, z) in [(-half, -half), (half, -half), (-half, half), (half, half)] {
        commands.spawn((
            Mesh3d(post.clone()),
            MeshMaterial3d(metal.clone()),
            Transform::from_translation(HAMMOCK + Vec3::new(x, -0.5 * HAMMOCK.y - 0.03, z)),
        ));
    }

    // The terrain: a bumpy triangle mesh, with a convex rock on it.
    let (vertices, indices) = bevy_cloth::harness::heightfield_mesh(17, 1.6, |x, z| {
        0.1 * (3.0 * x).sin() * (2.5 * z).cos() + 0.05
    });
    commands.spawn((
        RigidBody::Static,
        Collider::trimesh(vertices.clone(), indices.clone()),
        Mesh3d(meshes.add(mesh_of(&vertices, &indices))),
        Transform::from_translation(TERRAIN),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.45, 0.55, 0.35),
            perceptual_roughness: 1.0,
            ..default()
        })),
    ));
    let rock_points = [
        Vec3::new(-0.22, 0.0, -0.16),
        Vec3::new(0.26, 0.0, -0.1),
        Vec3::new(0.02, 0.0, 0.26),
        Vec3::new(0.05, 0.32, 0.0),
        Vec3::new(-0.12, 0.16, 0.12),
        Vec3::new(0.15, 0.12, 0.1),
    ];
    let rock = Collider::convex_hull(rock_points.to_vec()).ok_or("a rock hull")?;
    let rock_mesh = hull_mesh(&rock).ok_or("the rock's hull as triangles")?;
    commands.spawn((
        RigidBody::Static,
        rock,
        Mesh3d(meshes.add(rock_mesh)),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.5, 0.48, 0.45),
            perceptual_roughness: 0.9,
            ..default()
        })),
        Transform::from_translation(TERRAIN + Vec3::new(0.1, 0.02, -0.05)),
    ));
    // A cloth dropped onto them.
    let m = 28;
    commands.spawn((
        Name::new("sheet"),
        Cloth::grid(GridSpec::new(m, m, spacing)),
        ClothConfig {
            solver: SolverSettings {
                damping: 0.3,
                ..default()
            },
            ..default()
        },
        MeshMaterial3d(fabric),
        Transform::from_translation(TERRAIN + Vec3::new(0.0, 0.7, 0.0)),
    ));

    let mut drops = Drops {
        crate_mesh: meshes.add(Cuboid::new(0.25, 0.25, 0.25)),
        ball_mesh: meshes.add(Sphere::new(0.12).mesh().ico(4)?),
        wood: materials.add(StandardMaterial {
            base_color: Color::srgb(0.62, 0.45, 0.25),
            ..default()
        }),
        rubber: materials.add(StandardMaterial {
            base_color: Color::srgb(0.2, 0.35, 0.75),
            ..default()
        }),
        count: 0,
    };
    drops.drop(&mut commands, false);
    drops.drop(&mut commands, true);
    drops.drop(&mut commands, false);
    commands.insert_resource(drops);
    Ok(())
}

/// A render mesh of a triangle list, with flat normals.
fn mesh_of(vertices: &[Vec3], indices: &[[u32; 3]]) -> Mesh {
    let mut positions = Vec::new();
    let mut normals = Vec::new();
    for tri in indices {
        let [a, b, c] = tri.map(|i| vertices[i as usize]);
        let n = (b - a).cross(c - a).normalize_or_zero();
        for p in [a, b, c] {
            positions.push(p.to_array());
            normals.push(n.to_array());
        }
    }
    let count = positions.len() as u32;
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, positions)
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, normals)
    .with_inserted_indices(Indices::U32((0..count).collect()))
}

/// The render mesh of a convex-hull collider.
fn hull_mesh(collider: &Collider) -> Option<Mesh> {
    let hull = collider.shape().as_convex_polyhedron()?;
    let (points, triangles) = hull.to_trimesh();
    Some(mesh_of(&points, &triangles))
}

fn keys(input: Res<ButtonInput<KeyCode>>, mut commands: Commands, mut drops: ResMut<Drops>) {
    if input.just_pressed(KeyCode::Space) {
        drops.drop(&mut commands, false);
    }
    if input.just_pressed(KeyCode::KeyB) {
        drops.drop(&mut commands, true);
    }
}

fn panel(mut contexts: EguiContexts, mut commands: Commands, mut drops: ResMut<Drops>) -> Result {
    let ctx = contexts.ctx_mut()?;
    egui::Window::new("Scene")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .show(ctx, |ui| {
            if ui.button("drop a crate [Space]").clicked() {
                drops.drop(&mut commands, false);
            }
            if ui.button("drop a ball [B]").clicked() {
                drops.drop(&mut commands, true);
            }
            ui.label(format!("{} dropped", drops.count));
        });
    Ok(())
}
