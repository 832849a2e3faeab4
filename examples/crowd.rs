//! A crowd wearing cloth: the scene `assets/scenes/crowd/crowd.ron`, a hundred characters in capes
//! walking circles and three flags in the wind, with levels of detail ([`ClothLod`]) chosen for
//! the camera. The camera flies across the crowd and back; capes near it run at full quality,
//! farther ones at half the substeps, far ones frozen on their characters, and those out of view
//! or farther still are culled. The inspector counts the cloths at each level and their cost.
//!
//! `cargo run --release --features examples --example crowd`

mod common;

use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::{ClothScene, ScenePlugin, Walker};
use bevy_panorbit_camera::PanOrbitCamera;

/// The row the camera's focus travels along, and how long it takes one way, s.
const FROM: Vec3 = Vec3::new(2.0, 1.0, 27.0);
const TO: Vec3 = Vec3::new(60.0, 1.0, 27.0);
const CROSSING: f32 = 60.0;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: crowd",
            focus: FROM,
            eye: FROM + Vec3::new(-2.0, 2.0, -7.0),
        })
        .add_plugins((ClothPlugin::default(), ScenePlugin, ClothInspectorPlugin))
        .add_systems(Startup, spawn_crowd)
        .add_systems(Update, (dress, fly_camera))
        .run();
}

/// The scene's cloths; the camera, not the scene's viewer, chooses their levels of detail.
fn spawn_crowd(world: &mut World) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/crowd/crowd.ron");
    let mut scene = ClothScene::load(path).expect("the crowd scene loads");
    scene.viewer = None;
    scene.spawn_copies(world).expect("the crowd scene spawns");
    let mut meshes = world.resource_mut::<Assets<Mesh>>();
    let ground = meshes.add(Plane3d::default().mesh().size(90.0, 90.0));
    let mut materials = world.resource_mut::<Assets<StandardMaterial>>();
    let grass = materials.add(StandardMaterial {
        base_color: Color::srgb(0.33, 0.42, 0.3),
        perceptual_roughness: 1.0,
        ..default()
    });
    world.spawn((
        Mesh3d(ground),
        MeshMaterial3d(grass),
        Transform::from_xyz(27.0, -0.005, 27.0),
    ));
}

/// The cloths' fabric, the characters' body and the bodies' and poles' material.
type Looks = (
    Handle<StandardMaterial>,
    Handle<Mesh>,
    Handle<StandardMaterial>,
);

/// Gives each new cloth its fabric, each character a body and each flag a pole; the camera its
/// viewer.
#[allow(clippy::too_many_arguments)]
fn dress(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
    cloths: Query<(Entity, &Cloth, &GlobalTransform), Added<Cloth>>,
    walkers: Query<Entity, Added<Walker>>,
    cameras: Query<Entity, (With<Camera3d>, Without<ClothViewer>)>,
    mut looks: Local<Option<Looks>>,
) {
    for camera in &cameras {
        commands.entity(camera).insert(ClothViewer::perspective(
            std::f32::consts::FRAC_PI_4,
            16.0 / 9.0,
        ));
    }
    let (fabric, body, skin) = looks
        .get_or_insert_with(|| {
            (
                common::fabric(&asset_server, &mut materials),
                meshes.add(Capsule3d::new(0.14, 1.25)),
                materials.add(Color::srgb(0.55, 0.45, 0.4)),
            )
        })
        .clone();
    for (entity, cloth, at) in &cloths {
        commands
            .entity(entity)
            .insert(MeshMaterial3d(fabric.clone()));
        if let ClothSource::Grid(spec) = cloth.source {
            // A pole along the flag's pinned edge, from the ground to just above its top.
            let half_width = 0.5 * (spec.nx - 1) as f32 * spec.spacing;
            let height = at.translation().y + 0.5 * (spec.ny - 1) as f32 * spec.spacing + 0.05;
            commands.spawn((
                Mesh3d(meshes.add(Cylinder::new(0.03, height))),
                MeshMaterial3d(skin.clone()),
                Transform::from_xyz(
                    at.translation().x - half_width - 0.04,
                    0.5 * height,
                    at.translation().z,
                ),
            ));
        }
    }
    for walker in &walkers {
        commands.spawn((
            Mesh3d(body.clone()),
            MeshMaterial3d(skin.clone()),
            Transform::from_xyz(0.0, 0.77, 0.0),
            ChildOf(walker),
        ));
    }
}

/// Moves the camera's focus along the row and back.
fn fly_camera(time: Res<Time>, mut cameras: Query<&mut PanOrbitCamera>) {
    let phase = (time.elapsed_secs() / CROSSING).rem_euclid(2.0);
    let s = if phase <= 1.0 { phase } else { 2.0 - phase };
    for mut camera in &mut cameras {
        camera.target_focus = FROM.lerp(TO, s);
    }
}
