//! The `character` example's glTF asset (feature `gltf`): the committed file is what its
//! generator writes; Bevy's glTF loader reads back the joints, joint weights and target weights
//! the generator wrote; and the scene it spawns runs as character cloth.

use std::path::PathBuf;

use bevy::asset::{AssetServer, Assets, LoadState};
use bevy::gltf::{Gltf, GltfAssetLabel, GltfMesh, GltfNode, GltfPlugin, GltfSkin};
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Mesh, Mesh3d, VertexAttributeValues};
use bevy::prelude::*;
use bevy::world_serialization::{WorldAssetRoot, WorldSerializationPlugin};
use bevy_cloth::prelude::*;

#[path = "../examples/character_asset/gltf.rs"]
mod gltf;

const ASSET: &str = "character/character.gltf";

fn asset_file() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("assets")
        .join(ASSET)
}

#[test]
fn the_committed_asset_is_what_the_generator_writes() {
    let committed = std::fs::read_to_string(asset_file()).expect("the asset is committed");
    assert!(
        committed == gltf::document(),
        "{} is stale: run `cargo run --example character_asset`",
        asset_file().display()
    );
}

/// A headless app with the glTF loader, reading assets from the crate's `assets` folder, with
/// `ASSET` loading.
fn app_with_asset() -> (App, Handle<Gltf>) {
    let mut app = bevy_cloth::harness::try_headless_app_with(
        1.0 / 60.0,
        (
            WorldSerializationPlugin,
            bevy::animation::AnimationPlugin,
            GltfPlugin::default(),
        ),
    )
    .unwrap();
    let handle: Handle<Gltf> = app.world().resource::<AssetServer>().load(ASSET);
    for _ in 0..1000 {
        app.update();
        match app.world().resource::<AssetServer>().load_state(&handle) {
            LoadState::Loaded => return (app, handle),
            LoadState::Failed(e) => panic!("{ASSET}: {e}"),
            _ => std::thread::sleep(std::time::Duration::from_millis(2)),
        }
    }
    panic!("{ASSET} did not load");
}

fn attribute(mesh: &Mesh, id: bevy::mesh::MeshVertexAttribute) -> &VertexAttributeValues {
    mesh.attribute(id)
        .unwrap_or_else(|| panic!("no {}", id.name))
}

#[test]
fn the_loader_reads_back_the_joints_and_weights_the_generator_wrote() {
    let (app, handle) = app_with_asset();
    let world = app.world();
    let gltf = world.resource::<Assets<Gltf>>().get(&handle).unwrap();
    // The skin: the four joints by name, with the generator's inverse bind matrices.
    let skins = world.resource::<Assets<GltfSkin>>();
    let nodes = world.resource::<Assets<GltfNode>>();
    assert_eq!(gltf.skins.len(), 1);
    let skin = skins.get(&gltf.skins[0]).unwrap();
    let names: Vec<&str> = skin
        .joints
        .iter()
        .map(|j| nodes.get(j).unwrap().name.as_str())
        .collect();
    let expected: Vec<&str> = gltf::JOINTS.iter().map(|(name, _, _)| *name).collect();
    assert_eq!(names, expected);
    let bind = world
        .resource::<Assets<SkinnedMeshInverseBindposes>>()
        .get(&skin.inverse_bind_matrices)
        .unwrap();
    let written = gltf::inverse_bind_matrices();
    assert_eq!(bind.len(), written.len());
    for (m, w) in bind.iter().zip(&written) {
        assert_eq!(m.to_cols_array(), *w);
    }
    // The cloth meshes: positions, joints, joint weights and target weights (COLOR_0's red) as
    // written.
    let meshes = world.resource::<Assets<Mesh>>();
    for part in [gltf::cape(), gltf::skirt()] {
        let gltf_mesh = world
            .resource::<Assets<GltfMesh>>()
            .get(&gltf.named_meshes[part.name])
            .unwrap();
        let mesh = meshes.get(&gltf_mesh.primitives[0].mesh).unwrap();
        use VertexAttributeValues as Values;
        for (id, written) in [
            (
                Mesh::ATTRIBUTE_POSITION,
                Values::Float32x3(part.positions.clone()),
            ),
            (
                Mesh::ATTRIBUTE_JOINT_INDEX,
                Values::Uint16x4(part.joints.clone()),
            ),
            (
                Mesh::ATTRIBUTE_JOINT_WEIGHT,
                Values::Float32x4(part.weights.clone()),
            ),
            (
                Mesh::ATTRIBUTE_COLOR,
                Values::Float32x4(part.colors.clone()),
            ),
        ] {
            assert_eq!(attribute(mesh, id), &written, "{}: {}", part.name, id.name);
        }
        let colors = &part.colors;
        assert!(colors.iter().any(|c| c[0] == 0.0) && colors.iter().any(|c| c[0] == 1.0));
    }
}

/// The character scene spawned, its cape and skirt made cloths tied to their skin (targets of
/// `max_distance_scale` 0.2 m), and its hips joint.
fn character_in_cloth() -> (App, Vec<Entity>, Entity) {
    let (mut app, _handle) = app_with_asset();
    let scene = app
        .world()
        .resource::<AssetServer>()
        .load(GltfAssetLabel::Scene(0).from_asset(ASSET));
    app.world_mut().spawn(WorldAssetRoot(scene));
    // Wait for the scene's skinned meshes, then make each a cloth tied to its skin.
    let mut cloths = Vec::new();
    for _ in 0..100 {
        app.update();
        let world = app.world_mut();
        let mut skinned = world.query_filtered::<(Entity, &Mesh3d), With<SkinnedMesh>>();
        let found: Vec<(Entity, Handle<Mesh>)> =
            skinned.iter(world).map(|(e, m)| (e, m.0.clone())).collect();
        if found.len() == 2 {
            for (entity, mesh) in found {
                let mut config = ClothConfig::default();
                config.solver.targets.max_distance_scale = 0.2;
                world.entity_mut(entity).insert((
                    Cloth::from_mesh(mesh),
                    ClothTargets {
                        weights: TargetWeights::Color(0),
                    },
                    config,
                ));
                cloths.push(entity);
            }
            break;
        }
    }
    assert_eq!(cloths.len(), 2, "the scene's cape and skirt were not found");
    let hips = {
        let world = app.world_mut();
        let mut named = world.query::<(Entity, &Name)>();
        named
            .iter(world)
            .find(|(_, n)| n.as_str() == "hips")
            .map(|(e, _)| e)
            .expect("the hips joint")
    };
    (app, cloths, hips)
}

/// Walks the hips forward at 1.5 m/s for `steps` steps from where they are.
fn walk(app: &mut App, hips: Entity, steps: u32) {
    let start = app.world().get::<Transform>(hips).unwrap().translation;
    for step in 1..=steps {
        app.world_mut()
            .get_mut::<Transform>(hips)
            .unwrap()
            .translation = start + Vec3::Z * (1.5 * step as f32 / 60.0);
        app.update();
    }
}

#[test]
fn the_spawned_character_wears_its_cape_and_skirt_as_cloth() {
    let (mut app, cloths, hips) = character_in_cloth();
    walk(&mut app, hips, 120);
    for &cloth in &cloths {
        assert!(app.world().get::<ClothInvalid>(cloth).is_none());
        assert!(app.world().get::<SkinnedMesh>(cloth).is_none());
        let state = app.world().get::<ClothState>(cloth).expect("built");
        let x = state.positions();
        let (mut pinned, mut worst) = (0, f32::MIN);
        for t in state.targets() {
            let p = x[t.particle as usize];
            assert!(p.is_finite());
            if t.weight == 0.0 {
                pinned += 1;
                assert!(
                    p.distance(t.position) < 1e-4,
                    "a weight-0 vertex left its skin"
                );
            }
            worst = worst.max(p.distance(t.position) - 0.2 * t.weight);
        }
        assert!(pinned >= 16, "{pinned} pinned vertices");
        assert!(
            worst <= 1e-3,
            "a vertex went {worst} m past its max distance"
        );
        // The cloth went along: its mean is near the hips' new place, 3 m on.
        let mean = x.iter().sum::<Vec3>() / x.len() as f32;
        assert!(
            (mean.z - 3.0).abs() < 0.4,
            "the cloth's mean is at z = {}",
            mean.z
        );
    }
}

#[test]
fn a_cape_cut_in_two_keeps_its_attached_half_on_the_walking_character() {
    let (mut app, cloths, hips) = character_in_cloth();
    run_steps(&mut app, 10);
    // The cape is the flat one: 16 × 22 vertices.
    let cape = *cloths
        .iter()
        .find(|&&e| app.world().get::<ClothState>(e).unwrap().positions().len() == 16 * 22)
        .expect("the cape");
    app.world_mut().write_message(ClothCut {
        cloth: cape,
        cut: bevy_cloth::sim::Cut::Plane {
            point: Vec3::new(0.0, 1.2, 0.0),
            normal: Vec3::Y,
        },
    });
    run_steps(&mut app, 1);
    let state = app.world().get::<ClothState>(cape).unwrap();
    let (count, pieces) = state.sim().model().pieces();
    assert_eq!(count, 2, "the cape is in two pieces");
    let attached = pieces[state.targets().find(|t| t.weight == 0.0).unwrap().particle as usize];
    let loose = 1 - attached;
    assert!(
        state
            .targets()
            .all(|t| pieces[t.particle as usize] == attached),
        "the cut-off half has no targets left"
    );
    walk(&mut app, hips, 120);
    assert!(app.world().get::<ClothInvalid>(cape).is_none());
    let state = app.world().get::<ClothState>(cape).unwrap();
    let x = state.positions();
    for t in state.targets().filter(|t| t.weight == 0.0) {
        assert!(
            x[t.particle as usize].distance(t.position) < 1e-4,
            "left its skin"
        );
    }
    let mean = |piece: u32| {
        let (sum, k) = x
            .iter()
            .zip(&pieces)
            .filter(|(_, p)| **p == piece)
            .fold((Vec3::ZERO, 0), |(s, k), (p, _)| (s + *p, k + 1));
        sum / k as f32
    };
    // The attached half walked 3 m with the character; the cut half fell where it was cut.
    assert!(
        (mean(attached).z - 3.0).abs() < 0.4,
        "attached half at {}",
        mean(attached)
    );
    assert!(mean(loose).z.abs() < 0.5, "cut half at {}", mean(loose));
    assert!(mean(loose).y < 0.0, "the cut half fell: {}", mean(loose));
}

fn run_steps(app: &mut App, steps: u32) {
    for _ in 0..steps {
        app.update();
    }
}
