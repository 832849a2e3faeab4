//! Laundry: three cloths dropped one after another onto a ball on the floor. Each collides with
//! itself and, sharing a cloth layer, with the others, so the pile folds without any cloth passing
//! through itself or another; with the cloth inspector panel.
//!
//! `cargo run --release --features examples --example laundry`
//!
//! Keys: R drops the cloths again.

mod common;

use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;

const N: u32 = 32;
const SPACING: f32 = 0.025;
const BALL: f32 = 0.35;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: laundry",
            focus: Vec3::new(0.0, 0.45, 0.0),
            eye: Vec3::new(1.5, 1.5, 1.9),
        })
        .add_plugins((ClothPlugin::default(), ClothInspectorPlugin))
        .add_systems(Startup, (setup, drop_laundry))
        .add_systems(Update, drop_again)
        .run();
}

/// One of the dropped cloths.
#[derive(Component)]
struct Laundry;

fn setup(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    commands.spawn((
        Mesh3d(meshes.add(Sphere::new(BALL).mesh().ico(5).expect("ico sphere"))),
        MeshMaterial3d(materials.add(StandardMaterial {
            base_color: Color::srgb(0.85, 0.85, 0.8),
            ..default()
        })),
        Transform::from_xyz(0.0, BALL, 0.0),
        // Slightly larger than drawn, so the cloth's triangles do not dip into the drawn ball.
        ClothCollider::sphere(BALL + 0.005),
    ));
    commands.spawn((ClothCollider::half_space(Vec3::Y), Transform::IDENTITY));
}

/// Spawns the three cloths above the ball, each turned and tinted differently.
fn drop_laundry(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let tints = [
        Color::WHITE,
        Color::srgb(1.0, 0.8, 0.55),
        Color::srgb(0.85, 0.7, 1.0),
    ];
    for (k, tint) in tints.into_iter().enumerate() {
        let k = k as f32;
        let material = materials.add(StandardMaterial {
            base_color: tint,
            base_color_texture: Some(asset_server.load("textures/fabric.png")),
            perceptual_roughness: 0.9,
            cull_mode: None,
            double_sided: true,
            ..default()
        });
        commands.spawn((
            Name::new(format!("laundry {k}")),
            Laundry,
            Cloth::grid(GridSpec::new(N, N, SPACING)),
            ClothConfig {
                solver: SolverSettings {
                    self_collision: SelfCollision {
                        enabled: true,
                        ..default()
                    },
                    ..default()
                },
                cloth_layers: 1,
                ..default()
            },
            ClothSubdivision {
                level: 1,
                ..default()
            },
            Transform::from_xyz(0.04 * k, 0.95 + 0.15 * k, -0.03 * k).with_rotation(
                Quat::from_rotation_y(0.6 * k) * Quat::from_rotation_x(0.2 * (k - 1.0)),
            ),
            MeshMaterial3d(material),
        ));
    }
}

/// R: the cloths are taken away and dropped again.
fn drop_again(
    keys: Res<ButtonInput<KeyCode>>,
    mut commands: Commands,
    laundry: Query<Entity, With<Laundry>>,
    asset_server: Res<AssetServer>,
    materials: ResMut<Assets<StandardMaterial>>,
) {
    if !keys.just_pressed(KeyCode::KeyR) {
        return;
    }
    for e in &laundry {
        commands.entity(e).despawn();
    }
    drop_laundry(commands, asset_server, materials);
}
