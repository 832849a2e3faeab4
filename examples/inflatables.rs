//! Closed cloths with air inside, in an avian world: a beach ball (an ideal gas a little above the
//! air outside) dropped onto the ground bounces and rolls; a cushion (a box cloth that keeps its
//! volume) takes a 10 kg crate dropped on it and pushes it back. The inspector shows each cloth's
//! volume and pressure.
//!
//! `cargo run --release --features examples --example inflatables`
//!
//! Keys: Space drops another crate onto the cushion. Drag to orbit.

mod common;

use avian3d::prelude::*;
use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_cloth::sim::SolverSettings;

/// Where the cushion lies.
const CUSHION: Vec3 = Vec3::new(0.55, 0.0, 0.0);
/// The cushion's size, m.
const CUSHION_SIZE: Vec3 = Vec3::new(0.8, 0.2, 0.8);
/// Where the ball is dropped from.
const BALL: Vec3 = Vec3::new(-0.35, 1.4, 0.2);

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: inflatables",
            focus: Vec3::new(0.0, 0.35, 0.0),
            eye: Vec3::new(0.3, 1.6, 3.0),
        })
        .add_plugins((
            PhysicsPlugins::default(),
            ClothPlugin::default(),
            bevy_cloth::avian::ClothAvianPlugin,
            ClothInspectorPlugin,
        ))
        .add_systems(Startup, setup)
        .add_systems(Update, keys)
        .run();
}

/// The crate's mesh and material, for the crates the keys drop.
#[derive(Resource)]
struct Crates {
    mesh: Handle<Mesh>,
    wood: Handle<StandardMaterial>,
    count: u32,
}

impl Crates {
    /// A 30 cm, 10 kg crate above the cushion.
    fn drop(&mut self, commands: &mut Commands) {
        let k = self.count as f32;
        self.count += 1;
        let at = CUSHION + Vec3::new(0.08 * (k * 2.4).sin(), 0.7 + 0.35 * k, 0.0);
        commands.spawn((
            RigidBody::Dynamic,
            Collider::cuboid(0.3, 0.3, 0.3),
            Mass(10.0),
            Mesh3d(self.mesh.clone()),
            MeshMaterial3d(self.wood.clone()),
            Transform::from_translation(at).with_rotation(Quat::from_rotation_y(0.3 * k)),
        ));
    }
}

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) -> Result {
    // The ground (drawn by the common plugin).
    commands.spawn((RigidBody::Static, Collider::half_space(Vec3::Y)));

    // The beach ball: 30 cm radius, 642 particles of 0.5 g, 2 kPa above the air outside.
    let ball = ClothModel::icosphere(0.3, 3)?;
    let volume = ball.check_closed()?;
    commands.spawn((
        Name::new("beach ball"),
        Cloth::from_model(ball),
        ClothConfig {
            solver: SolverSettings {
                pressure: Pressure::gas(volume, 2000.0),
                particle_mass: 0.0005,
                damping: 0.2,
                ..default()
            },
            ..default()
        },
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.95, 0.35, 0.2),
            perceptual_roughness: 0.5,
            cull_mode: None,
            double_sided: true,
            ..default()
        })),
        Transform::from_translation(BALL),
    ));

    // The cushion: a box cloth that keeps its volume, as stiff as slowly compressed air.
    commands.spawn((
        Name::new("cushion"),
        Cloth::from_model(ClothModel::cuboid(CUSHION_SIZE, 0.05)?),
        ClothConfig {
            solver: SolverSettings {
                pressure: Pressure::Volume {
                    scale: 1.0,
                    bulk_modulus: 1.0e5,
                },
                particle_mass: 0.002,
                damping: 4.0,
                ..default()
            },
            ..default()
        },
        bevy_cloth::avian::ClothPushesBodies,
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.25, 0.45, 0.7),
            perceptual_roughness: 0.9,
            cull_mode: None,
            double_sided: true,
            ..default()
        })),
        Transform::from_translation(CUSHION + Vec3::Y * (0.5 * CUSHION_SIZE.y + 0.005)),
    ));

    let mut crates = Crates {
        mesh: meshes.add(Cuboid::new(0.3, 0.3, 0.3)),
        wood: materials.add(StandardMaterial {
            base_color: Color::srgb(0.62, 0.45, 0.25),
            ..default()
        }),
        count: 0,
    };
    crates.drop(&mut commands);
    commands.insert_resource(crates);
    Ok(())
}

fn keys(input: Res<ButtonInput<KeyCode>>, mut commands: Commands, mut crates: ResMut<Crates>) {
    if input.just_pressed(KeyCode::Space) {
        crates.drop(&mut commands);
    }
}
