//! A character walking in a circle, wearing a cape and a skirt: a glTF asset (skeleton, walk
//! cycle, and two skinned cloth meshes whose vertex colours hold their target weights; made by
//! `examples/character_asset`) loaded through Bevy's glTF loader. Each cloth mesh becomes a
//! cloth tied to its skin ([`ClothTargets`]): held at the collar and waist, free within a
//! maximum distance further down, kept off the body by a backstop, its stretch bounded by
//! tethers, and feeling only part of the character's motion (inertia). Capsules on the leg
//! joints and the spine keep the cloth off the body. The inspector panel edits all of it.
//!
//! `cargo run --release --features examples --example character`

mod common;

use bevy::gltf::GltfAssetLabel;
use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy::world_serialization::WorldAssetRoot;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_panorbit_camera::PanOrbitCamera;

const ASSET: &str = "character/character.gltf";
/// Radius of the circle the character walks, m.
const RADIUS: f32 = 2.0;
/// Walking speed, m/s.
const SPEED: f32 = 1.4;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: character",
            focus: Vec3::new(RADIUS, 1.0, 0.0),
            eye: Vec3::new(RADIUS + 2.6, 1.7, -2.4),
        })
        .add_plugins((ClothPlugin::default(), ClothInspectorPlugin))
        .add_systems(Startup, setup)
        .add_systems(
            Update,
            (dress, add_colliders, start_walking, follow_with_camera),
        )
        .add_systems(FixedUpdate, walk.before(ClothSystems::Prepare))
        .run();
}

/// The character's root (the glTF scene's).
#[derive(Component)]
struct Character;

/// The walk cycle, as an animation graph.
#[derive(Resource)]
struct Walk {
    graph: Handle<AnimationGraph>,
    index: AnimationNodeIndex,
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut graphs: ResMut<Assets<AnimationGraph>>,
) {
    commands.spawn((
        Character,
        WorldAssetRoot(asset_server.load(GltfAssetLabel::Scene(0).from_asset(ASSET))),
        pose_at(0.0),
    ));
    let (graph, index) = AnimationGraph::from_clip(
        asset_server.load(GltfAssetLabel::Animation(0).from_asset(ASSET)),
    );
    commands.insert_resource(Walk {
        graph: graphs.add(graph),
        index,
    });
}

/// Where the character is at time `t`: on a circle around the origin, walking along it
/// (counter-clockwise seen from above; the glTF character faces +Z).
fn pose_at(t: f32) -> Transform {
    let angle = SPEED * t / RADIUS;
    Transform::from_xyz(RADIUS * angle.cos(), 0.0, RADIUS * angle.sin())
        .with_rotation(Quat::from_rotation_y(-angle))
}

/// Moves the character along its circle, in the fixed step the cloths are stepped in.
fn walk(time: Res<Time>, mut characters: Query<&mut Transform, With<Character>>) {
    for mut transform in &mut characters {
        *transform = pose_at(time.elapsed_secs());
    }
}

/// Plays the walk cycle on the scene's animation player once it appears.
fn start_walking(
    mut commands: Commands,
    walk: Res<Walk>,
    mut players: Query<(Entity, &mut AnimationPlayer), Added<AnimationPlayer>>,
) {
    for (entity, mut player) in &mut players {
        player.play(walk.index).repeat();
        commands
            .entity(entity)
            .insert(AnimationGraphHandle(walk.graph.clone()));
    }
}

/// Skinned meshes of the scene that are not cloths yet.
type Undressed = (With<SkinnedMesh>, Without<Cloth>);

/// Turns the scene's skinned cape and skirt into cloths tied to their skin.
fn dress(
    mut commands: Commands,
    skinned: Query<(Entity, &Mesh3d, &ChildOf), Undressed>,
    names: Query<&Name>,
    asset_server: Res<AssetServer>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    for (entity, mesh, parent) in &skinned {
        let Ok(name) = names.get(parent.parent()) else {
            continue;
        };
        let mut config = ClothConfig::default();
        let s = &mut config.solver;
        s.tethers.enabled = true;
        s.tethers.slack = 0.05;
        s.inertia.linear = 0.6;
        s.inertia.angular = 0.6;
        match name.as_str() {
            // Held at the collar; the hem swings up to 35 cm from the skin, never through the
            // back.
            "cape" => {
                s.targets.max_distance_scale = 0.35;
                s.targets.backstop_radius = 0.6;
                s.targets.backstop_offset = 0.0;
            }
            // Held at the waist; the hem flares up to 20 cm from the skin.
            "skirt" => {
                s.targets.max_distance_scale = 0.2;
                s.targets.backstop_radius = 0.3;
                s.targets.backstop_offset = 0.02;
            }
            _ => continue,
        }
        commands.entity(entity).insert((
            Name::new(format!("{name} (cloth)")),
            Cloth::from_mesh(mesh.0.clone()),
            ClothTargets {
                weights: TargetWeights::Color(0),
            },
            ClothSubdivision {
                level: 1,
                ..default()
            },
            config,
            MeshMaterial3d(common::fabric(&asset_server, &mut materials)),
        ));
    }
}

/// Capsules on the legs and the spine, a sphere on the hips: children of the joints, so they
/// move with the walk.
fn add_colliders(mut commands: Commands, joints: Query<(Entity, &Name), Added<Name>>) {
    for (entity, name) in &joints {
        let (collider, offset) = match name.as_str() {
            "leg.L" | "leg.R" => (
                ClothCollider::capsule(0.075, 0.38),
                Vec3::new(0.0, -0.45, 0.0),
            ),
            "spine" => (ClothCollider::capsule(0.13, 0.14), Vec3::new(0.0, 0.2, 0.0)),
            "hips" => (ClothCollider::sphere(0.16), Vec3::new(0.0, 0.05, 0.0)),
            _ => continue,
        };
        commands.spawn((
            collider.with_margin(0.015),
            Transform::from_translation(offset),
            ChildOf(entity),
        ));
    }
}

/// Keeps the orbit camera's focus on the character.
fn follow_with_camera(
    characters: Query<&Transform, With<Character>>,
    mut cameras: Query<&mut PanOrbitCamera>,
) {
    let Ok(character) = characters.single() else {
        return;
    };
    for mut camera in &mut cameras {
        camera.target_focus = character.translation + Vec3::Y;
    }
}
