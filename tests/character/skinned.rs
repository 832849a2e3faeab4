//! A skinned cape in a headless App.

use bevy::mesh::skinning::SkinnedMesh;
use bevy::prelude::*;
use bevy_cloth::harness::character::{Cape, SpawnedCape, spawn_cape, torso_pose};
use bevy_cloth::prelude::*;

use crate::common;

const NX: usize = 16;
const NY: usize = 24;

#[test]
fn a_cape_on_a_turning_walking_torso_stays_on_its_skin() {
    // The root walks at 3 m/s while the spine turns 90° every half second.
    let pose = |t: f32| torso_pose(t, 3.0, std::f32::consts::PI);
    let mut app = common::app();
    let cape = Cape::new(NX, NY);
    let mut config = ClothConfig {
        interpolate: false,
        ..ClothConfig::default()
    };
    config.solver.targets.max_distance_scale = 0.3;
    let SpawnedCape { cloth, root, spine } = spawn_cape(app.world_mut(), &cape, config);
    app.update();
    assert!(app.world().get::<ClothInvalid>(cloth).is_none());
    let Cape {
        rest,
        joints,
        weights,
        inverse_bindposes: bind,
        ..
    } = cape;
    // The skin moved to the cloth; the renderer has nothing to skin.
    assert!(app.world().get::<SkinnedMesh>(cloth).is_none());
    assert!(app.world().get::<ClothSkin>(cloth).is_some());
    let targets: Vec<_> = common::state(&app, cloth).targets().collect();
    assert_eq!(targets.len(), NX * NY);
    assert_eq!(targets.iter().filter(|t| t.weight == 0.0).count(), NX);
    assert_eq!(common::sim(&app, cloth).pinned().count(), NX);

    let (mut worst_pin, mut worst_excess, mut worst_skin): (f32, f32, f32) = (0.0, f32::MIN, 0.0);
    for step in 1..=600 {
        let t = step as f32 / 60.0;
        let (root_pose, spine_pose) = pose(t);
        *app.world_mut().get_mut::<Transform>(root).unwrap() = root_pose;
        *app.world_mut().get_mut::<Transform>(spine).unwrap() = spine_pose;
        app.update();
        // An independent skinning of every vertex: joint world matrices from the poses.
        let world = [
            root_pose.to_matrix(),
            root_pose.to_matrix() * spine_pose.to_matrix(),
        ];
        let skinned = |v: usize| -> Vec3 {
            (0..4)
                .map(|k| {
                    let j = joints[v][k] as usize;
                    weights[v][k] * (world[j] * bind[j]).transform_point3(rest[v])
                })
                .sum()
        };
        let state = common::state(&app, cloth);
        let x = state.positions();
        assert!(x.iter().all(|p| p.is_finite()), "step {step}: not finite");
        for target in state.targets() {
            let v = target.particle as usize;
            let expected = skinned(v);
            worst_skin = worst_skin.max(target.position.distance(expected));
            let d = x[v].distance(expected);
            if target.weight == 0.0 {
                worst_pin = worst_pin.max(d);
            } else {
                worst_excess = worst_excess.max(d - 0.3 * target.weight);
            }
        }
    }
    println!(
        "skinning {worst_skin:e} m, pins {worst_pin:e} m, past the max distance {worst_excess:e} m"
    );
    assert!(
        worst_skin <= 1e-5,
        "the plugin's skinning is {worst_skin} m off"
    );
    assert!(
        worst_pin <= 1e-3,
        "a weight-0 vertex was {worst_pin} m off its skin"
    );
    assert!(
        worst_excess <= 1e-3,
        "a vertex went {worst_excess} m past its max distance"
    );
}

/// A 12×16 cape in the XY plane, weights from 0 on its top row to 1 at its hem.
fn grid_cape() -> (GridSpec, Vec<f32>) {
    let spec = GridSpec::new(12, 16, 0.03).with_plane(GridPlane::Vertical);
    let weights = (0..12 * 16).map(|p| (p / 12) as f32 / 15.0).collect();
    (spec, weights)
}

#[test]
fn without_a_skin_targets_follow_the_cloth_transform() {
    let mut app = common::app();
    let (spec, weights) = grid_cape();
    let mut config = ClothConfig {
        interpolate: false,
        ..ClothConfig::default()
    };
    config.solver.targets.max_distance_scale = 0.05;
    let cloth = common::spawn_valid(
        &mut app,
        (
            Cloth::grid(spec),
            ClothTargets {
                weights: TargetWeights::Values(weights),
            },
            // Two of the top row's weight-0 vertices are also pinned by hand: once each.
            ClothPins::new([0, 1]),
            config,
        ),
    );
    assert_eq!(common::sim(&app, cloth).pinned().count(), 12);
    let rest = common::sim(&app, cloth).model().rest_positions.clone();
    let mut worst: f32 = f32::MIN;
    for step in 1..=120 {
        let t = step as f32 / 60.0;
        let pose =
            Transform::from_xyz(2.0 * t, 0.0, 0.0).with_rotation(Quat::from_rotation_y(2.0 * t));
        *app.world_mut().get_mut::<Transform>(cloth).unwrap() = pose;
        app.update();
        let state = common::state(&app, cloth);
        for target in state.targets() {
            let v = target.particle as usize;
            let expected = pose.transform_point(rest[v]);
            assert!(target.position.distance(expected) < 1e-5, "target of {v}");
            let d = state.positions()[v].distance(expected);
            worst = worst.max(d - 0.05 * target.weight);
        }
    }
    println!("worst excess over the max distance {worst:e} m");
    assert!(
        worst <= 1e-3,
        "a particle went {worst} m past its max distance"
    );
}

#[test]
fn with_no_linear_inertia_a_cloth_entity_at_constant_speed_hangs_as_if_still() {
    // Pinned along its top row to its rest shape (so the pins move with the entity), the
    // cloth's shape relative to its entity matches a still one's.
    let run = |speed: f32, inertia: Inertia| -> Vec<Vec3> {
        let mut app = common::app();
        let (spec, _) = grid_cape();
        let mut config = ClothConfig::default();
        config.solver.inertia = inertia;
        config.solver.gravity = Vec3::new(0.0, -9.81, -3.0);
        config.solver.damping = 5.0;
        config.solver.sleep_speed = 0.0;
        let cloth =
            common::spawn_valid(&mut app, (Cloth::grid(spec), ClothPins::new(0..12), config));
        for step in 1..=120 {
            let t = step as f32 / 60.0;
            app.world_mut()
                .get_mut::<Transform>(cloth)
                .unwrap()
                .translation = Vec3::new(speed * t, 0.0, 0.0);
            app.update();
        }
        let offset = Vec3::new(speed * 2.0, 0.0, 0.0);
        common::state(&app, cloth)
            .positions()
            .iter()
            .map(|p| *p - offset)
            .collect()
    };
    let gap = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .zip(b)
            .map(|(p, q)| p.distance(*q))
            .fold(0.0, f32::max)
    };
    let none = Inertia {
        linear: 0.0,
        angular: 1.0,
    };
    let still = run(0.0, none);
    let carried = gap(&still, &run(5.0, none));
    let felt = gap(&still, &run(5.0, Inertia::default()));
    println!("inertia 0: {carried:e} m, inertia 1: {felt:e} m");
    assert!(carried <= 1e-3, "{carried} m from the still cloth");
    assert!(
        felt > 1e-2,
        "felt in full, the motion moved the cloth only {felt} m"
    );
}

#[test]
fn bad_target_weights_make_the_cloth_invalid() {
    let (spec, weights) = grid_cape();
    let mut nan = weights.clone();
    nan[30] = f32::NAN;
    for (what, weights) in [
        (
            "too few weights",
            TargetWeights::Values(weights[1..].to_vec()),
        ),
        ("a NaN weight", TargetWeights::Values(nan)),
        ("colours of a grid", TargetWeights::Color(0)),
        (
            "an attribute of a grid",
            TargetWeights::Attribute("weights".into()),
        ),
    ] {
        let mut app = common::app();
        let cloth = common::spawn(&mut app, (Cloth::grid(spec), ClothTargets { weights }));
        let invalid = app.world().get::<ClothInvalid>(cloth);
        assert!(invalid.is_some(), "{what} accepted");
        println!("{what}: {}", invalid.unwrap().0);
    }
}

#[test]
fn a_skirt_stays_outside_legs_that_kick_through_it() {
    // A skirt: a tube of radius 0.2 m from the waist (y = 1) down to y = 0.45, pinned along
    // its waist. Two legs, capsules of radius 6 cm hanging 0.8 m from hip joints at
    // x = ±0.1, swing ±45° about X at 1.5 Hz in opposite phase (the feet reach 5.6 m/s, a
    // capsule surface moves up to 9 cm in a step): they are moved by their joints, the
    // colliders' own transforms never change.
    use bevy_cloth::sim::ClothModel;
    let (around, rows) = (32usize, 12usize);
    let mut positions = Vec::new();
    for j in 0..rows {
        for i in 0..around {
            let a = std::f32::consts::TAU * i as f32 / around as f32;
            let y = 1.0 - 0.55 * j as f32 / (rows - 1) as f32;
            positions.push(Vec3::new(0.2 * a.cos(), y, 0.2 * a.sin()));
        }
    }
    let mut indices = Vec::new();
    for j in 0..rows - 1 {
        for i in 0..around {
            let (a, b) = (
                (j * around + i) as u32,
                (j * around + (i + 1) % around) as u32,
            );
            let (c, d) = (a + around as u32, b + around as u32);
            indices.extend([a, c, b, b, c, d]);
        }
    }
    let model = ClothModel::from_mesh(&positions, None, &indices, 3).unwrap();
    let mut app = common::app();
    let (radius, half_length) = (0.06, 0.34);
    let hips: Vec<Entity> = [-0.1f32, 0.1]
        .iter()
        .map(|&x| {
            let hip = app.world_mut().spawn(Transform::from_xyz(x, 1.0, 0.0)).id();
            app.world_mut().spawn((
                ClothCollider::capsule(radius, half_length),
                Transform::from_xyz(0.0, -0.4, 0.0),
                ChildOf(hip),
            ));
            hip
        })
        .collect();
    let cloth = common::spawn_valid(
        &mut app,
        (
            Cloth::from_model(model),
            ClothPins::new(0..around as u32),
            ClothConfig {
                interpolate: false,
                ..ClothConfig::default()
            },
        ),
    );
    let swing = |t: f32, k: usize| {
        let phase = if k == 0 { 0.0 } else { std::f32::consts::PI };
        std::f32::consts::FRAC_PI_4 * (std::f32::consts::TAU * 1.5 * t + phase).sin()
    };
    let (mut deepest, mut touching): (f32, usize) = (f32::MIN, 0);
    for step in 1..=240 {
        let t = step as f32 / 60.0;
        for (k, &hip) in hips.iter().enumerate() {
            app.world_mut().get_mut::<Transform>(hip).unwrap().rotation =
                Quat::from_rotation_x(swing(t, k));
        }
        app.update();
        let x = common::state(&app, cloth).positions();
        for (k, hip) in [-0.1f32, 0.1].iter().enumerate() {
            // The leg's axis now, from the hip's pose.
            let turn = Quat::from_rotation_x(swing(t, k));
            let centre = Vec3::new(*hip, 1.0, 0.0) + turn * Vec3::new(0.0, -0.4, 0.0);
            let axis = turn * Vec3::Y * half_length;
            for p in x {
                let along = (*p - centre).dot(axis) / axis.length_squared();
                let nearest = centre + axis * along.clamp(-1.0, 1.0);
                let depth = radius - p.distance(nearest);
                deepest = deepest.max(depth);
                touching += usize::from(depth > -0.02);
            }
        }
    }
    println!("deepest inside a leg {deepest:e} m; particle-steps within 2 cm of one {touching}");
    assert!(
        touching > 1000,
        "the legs hardly touched the skirt ({touching})"
    );
    assert!(
        deepest <= 1e-3,
        "a particle ended a step {deepest} m inside a leg"
    );
}

#[test]
fn a_ron_scene_gives_a_cloth_its_target_weights() {
    let mut app = common::app();
    let scene = bevy_cloth::scene::ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1, plane: Vertical)), \
         target_weights: Some([0, 0, 0, 0, 0.5, 0.5, 0.5, 0.5, 1, 1, 1, -1]), \
         solver: (targets: (max_distance_scale: 0.2), tethers: (enabled: true)))",
    )
    .unwrap();
    let cloth = scene.spawn(app.world_mut()).unwrap();
    app.update();
    let state = common::state(&app, cloth);
    // Eleven weighted particles, the four of weight 0 pinned; the last one is free.
    assert_eq!(state.targets().count(), 11);
    assert_eq!(state.sim().pinned().count(), 4);
    // Seven targets with a max distance, and a tether for each of the eight free particles.
    assert_eq!(state.sim().limit_counts(), (7, 8));
}

#[test]
fn weights_come_from_a_named_vertex_attribute() {
    // A cape mesh without a skin whose weights sit in a custom float attribute (as a glTF
    // exporter's custom attribute arrives through the loader): the top row pinned, the rest
    // held near the rest shape under the cloth's transform.
    use bevy::mesh::{MeshVertexAttribute, VertexFormat};
    const WEIGHT: MeshVertexAttribute =
        MeshVertexAttribute::new("_CLOTH_WEIGHT", 988_540_917, VertexFormat::Float32);
    let cape = Cape::new(8, 6);
    let weights: Vec<f32> = (0..48).map(|v| (v / 8) as f32 / 5.0).collect();
    let mut mesh = cape.mesh.clone();
    mesh.insert_attribute(WEIGHT, weights.clone());
    let mut app = common::app();
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(mesh);
    let mut config = ClothConfig::default();
    config.solver.targets.max_distance_scale = 0.1;
    let cloth = common::spawn_valid(
        &mut app,
        (
            Cloth::from_mesh(handle),
            ClothTargets {
                weights: TargetWeights::Attribute("_CLOTH_WEIGHT".into()),
            },
            config,
        ),
    );
    common::run(&mut app, 60);
    let state = common::state(&app, cloth);
    let read: Vec<f32> = state.targets().map(|t| t.weight).collect();
    assert_eq!(read, weights);
    assert_eq!(state.sim().pinned().count(), 8);
    for t in state.targets() {
        let d = state.positions()[t.particle as usize].distance(t.position);
        assert!(
            d <= 0.1 * t.weight + 1e-3,
            "vertex {} is {d} m from its target",
            t.particle
        );
    }
    // A name the mesh does not have, or a colour channel past alpha, is an error naming it.
    for (weights, named) in [
        (TargetWeights::Attribute("_MISSING".into()), "_MISSING"),
        (TargetWeights::Color(7), "channel 7"),
    ] {
        let mut app = common::app();
        let handle = app
            .world_mut()
            .resource_mut::<Assets<Mesh>>()
            .add(cape.mesh.clone());
        let cloth = common::spawn(
            &mut app,
            (Cloth::from_mesh(handle), ClothTargets { weights }),
        );
        let invalid = app.world().get::<ClothInvalid>(cloth).expect("invalid");
        assert!(invalid.0.to_string().contains(named), "{}", invalid.0);
    }
}
