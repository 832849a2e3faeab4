//! A flag on a pole in gusty wind: a 36×24 cloth pinned along the pole, seeded gusts, lift and
//! drag per triangle, rendered at subdivision level 1, with the cloth inspector panel.
//!
//! `cargo run --release --features examples --example flag`

mod common;

use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;

const NX: u32 = 36;
const NY: u32 = 24;
const SPACING: f32 = 0.04;
const POLE_HEIGHT: f32 = 3.0;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: flag",
            focus: Vec3::new(0.6, 2.4, 0.0),
            eye: Vec3::new(0.8, 2.2, 3.6),
        })
        .add_plugins((ClothPlugin::default(), ClothInspectorPlugin))
        .insert_resource(Wind {
            velocity: Vec3::new(7.0, 0.0, -1.5),
            gusts: Some(Gusts {
                seed: 42,
                strength: 0.45,
                frequency: 0.7,
                turbulence: 0.2,
            }),
            ..default()
        })
        .add_systems(Startup, setup)
        .run();
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let pole_radius = 0.03;
    commands.spawn((
        Mesh3d(meshes.add(Cylinder::new(pole_radius, POLE_HEIGHT))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.8, 0.8, 0.82),
            metallic: 0.6,
            ..default()
        })),
        Transform::from_xyz(0.0, POLE_HEIGHT / 2.0, 0.0),
        // The pole is also a collider, so the flag wraps around it rather than through it.
        ClothCollider::capsule(pole_radius, POLE_HEIGHT / 2.0),
    ));
    // A vertical grid has row 0 on top and column 0 on the left: pin column 0 to the pole.
    let width = (NX - 1) as f32 * SPACING;
    let height = (NY - 1) as f32 * SPACING;
    commands.spawn((
        Name::new("flag"),
        Cloth::grid(GridSpec {
            nx: NX,
            ny: NY,
            spacing: SPACING,
            plane: GridPlane::Vertical,
        }),
        ClothPins::new((0..NY).map(|j| j * NX)),
        ClothConfig {
            solver: SolverSettings {
                damping: 0.1,
                lift_coefficient: 0.8,
                ..default()
            },
            ..default()
        },
        ClothSubdivision {
            level: 1,
            ..default()
        },
        Transform::from_xyz(
            width / 2.0 + pole_radius + 0.01,
            POLE_HEIGHT - height / 2.0 - 0.02,
            0.0,
        ),
        MeshMaterial3d(common::fabric(&asset_server, &mut materials)),
    ));
}
