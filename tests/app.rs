//! Headless Bevy App tests of the plugin: scheduling, pins, settling, determinism, runtime edits,
//! meshes and bad input. Time is driven by hand: each `update()` runs a known number of fixed steps.

use bevy::mesh::{Indices, VertexAttributeValues};
use bevy::prelude::*;
use bevy::time::TimeUpdateStrategy;
use bevy_cloth::ClothStepBudget;
use bevy_cloth::prelude::*;
use bevy_cloth::sim::{SpringKind, compute_normals};

mod common;
use common::*;

fn hanging(n: u32) -> impl Bundle {
    hanging_at(n, Vec3::new(0.0, 2.0, 0.0))
}

fn hanging_at(n: u32, at: Vec3) -> impl Bundle {
    (
        Cloth::grid(GridSpec::new(n, n, 0.05)),
        ClothPins::new([0, n - 1]),
        Transform::from_translation(at),
    )
}

#[test]
fn exactly_n_fixed_steps_run() {
    let mut app = app();
    let e = spawn(&mut app, hanging(8));
    assert_eq!(state(&app, e).steps(), 0);
    assert_eq!(state(&app, e).last_step_time(), std::time::Duration::ZERO);
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(3));
    for _ in 0..7 {
        app.update();
    }
    assert_eq!(state(&app, e).steps(), 21);
    // Each step is timed where the plugin steps the cloth.
    assert!(state(&app, e).last_step_time() > std::time::Duration::ZERO);
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    run(&mut app, 5);
    assert_eq!(state(&app, e).steps(), 26);
}

#[test]
fn a_one_second_hitch_runs_at_most_the_capped_steps_and_the_cloth_survives() {
    #[derive(Resource, Default)]
    struct FixedSteps(u64);
    let mut app = app();
    app.init_resource::<FixedSteps>()
        .add_systems(FixedUpdate, |mut n: ResMut<FixedSteps>| n.0 += 1);
    let e = spawn(&mut app, hanging(16));
    run(&mut app, 60);
    let before = state(&app, e).steps();
    let fixed_before = app.world().resource::<FixedSteps>().0;
    // One frame of a whole second: the virtual clock clamps it to 250 ms, about 15 fixed steps.
    app.insert_resource(TimeUpdateStrategy::ManualDuration(
        std::time::Duration::from_secs(1),
    ));
    app.update();
    app.insert_resource(TimeUpdateStrategy::FixedTimesteps(1));
    let fixed = app.world().resource::<FixedSteps>().0 - fixed_before;
    assert!(fixed >= 14, "{fixed} fixed steps in the long frame");
    let cap = bevy_cloth::plugin::DEFAULT_MAX_STEPS_PER_FRAME as u64;
    assert_eq!(state(&app, e).steps() - before, cap);
    assert_eq!(
        app.world().resource::<ClothStepBudget>().skipped,
        fixed - cap
    );
    run(&mut app, 60);
    assert_eq!(state(&app, e).steps() - before, cap + 60);
    let sim = state(&app, e).sim();
    assert!(sim.positions().iter().all(|p| p.is_finite()));
    let strain = sim.max_strain(SpringKind::Structural);
    assert!(
        strain < 0.05,
        "max structural strain {strain} after the hitch"
    );
}

#[test]
fn unpinned_cloth_falls_like_a_free_particle() {
    let mut app = app();
    let config = ClothConfig {
        solver: SolverSettings {
            damping: 0.0,
            substeps: 20,
            ..Default::default()
        },
        interpolate: false,
        ..Default::default()
    };
    let e = spawn(
        &mut app,
        (
            Cloth::grid(GridSpec::new(4, 4, 0.1)),
            config,
            Transform::from_xyz(0.0, 10.0, 0.0),
        ),
    );
    let x0 = state(&app, e).positions()[5];
    run(&mut app, 60);
    let t = 1.0;
    let exact = x0 + 0.5 * config.solver.gravity * t * t;
    let x = state(&app, e).positions()[5];
    let rel = x.distance(exact) / (0.5 * 9.81 * t * t);
    assert!(rel < 1e-3, "relative error {rel} after 1 s");
}

#[test]
fn pinned_particles_never_move() {
    let mut app = app();
    let e = spawn(&mut app, hanging(10));
    let p0 = state(&app, e).positions()[0];
    let p9 = state(&app, e).positions()[9];
    for _ in 0..120 {
        run(&mut app, 1);
        let s = state(&app, e);
        assert_eq!(s.positions()[0], p0);
        assert_eq!(s.positions()[9], p9);
    }
    // The rest did move.
    assert!(state(&app, e).positions()[55].y < p0.y - 0.1);
}

#[test]
fn hanging_cloth_settles_with_small_strain() {
    let mut app = app();
    let e = spawn(&mut app, hanging(16));
    // Largest kinetic energy in each 2-second window of a 20-second run.
    let mut windows = Vec::new();
    for _ in 0..10 {
        let mut max: f32 = 0.0;
        for _ in 0..120 {
            run(&mut app, 1);
            max = max.max(state(&app, e).sim().kinetic_energy());
        }
        windows.push(max);
    }
    for w in windows.windows(2) {
        assert!(w[1] < w[0], "kinetic energy did not decay: {windows:?}");
    }
    let (first, last) = (windows[0], windows[9]);
    assert!(
        last < 1e-3 * first,
        "kinetic energy only fell from {first} J to {last} J"
    );
    let sim = state(&app, e).sim();
    let strain = sim.max_strain(SpringKind::Structural);
    assert!(strain < 0.02, "max structural strain {strain}");
}

fn final_positions() -> Vec<Vec3> {
    let mut app = app();
    let e = spawn(&mut app, hanging(12));
    run(&mut app, 120);
    state(&app, e).positions().to_vec()
}

#[test]
fn identical_runs_are_bit_identical() {
    let a = final_positions();
    let b = final_positions();
    assert!(
        a.iter()
            .zip(&b)
            .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits))
    );
}

#[test]
fn despawning_one_cloth_leaves_the_other_running() {
    let mut app = app();
    let a = spawn(&mut app, hanging(8));
    let b = spawn(&mut app, hanging_at(8, Vec3::new(3.0, 2.0, 0.0)));
    run(&mut app, 10);
    app.world_mut().despawn(a);
    let before = state(&app, b).positions().to_vec();
    let steps = state(&app, b).steps();
    run(&mut app, 10);
    assert_eq!(state(&app, b).steps(), steps + 10);
    assert_ne!(state(&app, b).positions(), &before[..]);
    assert!(app.world().get_entity(a).is_err());
}

#[test]
fn mesh_cloth_keeps_vertex_count_and_indices() {
    let mut app = app();
    let source = Plane3d::default()
        .mesh()
        .size(1.0, 1.0)
        .subdivisions(5)
        .build();
    let count = source.count_vertices();
    let indices: Vec<u32> = source.indices().unwrap().iter().map(|i| i as u32).collect();
    let handle = app.world_mut().resource_mut::<Assets<Mesh>>().add(source);
    let e = spawn(
        &mut app,
        (
            Cloth::from_mesh(handle.clone()),
            ClothPins::new([0]),
            Transform::from_xyz(0.0, 1.0, 0.0),
        ),
    );
    run(&mut app, 10);
    let s = state(&app, e);
    assert_eq!(s.positions().len(), count);
    assert_ne!(s.mesh(), &handle, "the cloth deforms its own copy");
    let meshes = app.world().resource::<Assets<Mesh>>();
    let mesh = meshes.get(s.mesh()).unwrap();
    assert_eq!(mesh.count_vertices(), count);
    let out: Vec<u32> = mesh.indices().unwrap().iter().map(|i| i as u32).collect();
    assert_eq!(out, indices);
    // The original asset is untouched.
    let original = meshes.get(&handle).unwrap();
    let Some(VertexAttributeValues::Float32x3(p)) = original.attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        panic!("positions")
    };
    assert!(p.iter().all(|p| p[1] == 0.0));
}

fn mesh_positions(app: &App, e: Entity) -> (Vec<[f32; 3]>, *const [f32; 3]) {
    let meshes = app.world().resource::<Assets<Mesh>>();
    let mesh = meshes.get(state(app, e).mesh()).unwrap();
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        panic!("positions")
    };
    (p.clone(), p.as_ptr())
}

#[test]
fn mesh_is_written_in_place_in_local_space() {
    let mut app = app();
    let e = spawn(
        &mut app,
        (
            hanging(8),
            ClothConfig {
                interpolate: false,
                ..Default::default()
            },
        ),
    );
    let (_, ptr0) = mesh_positions(&app, e);
    run(&mut app, 6);
    let (local, ptr1) = mesh_positions(&app, e);
    assert_eq!(ptr0, ptr1, "the position buffer was replaced");
    let world = state(&app, e).positions();
    for (l, w) in local.iter().zip(world) {
        // The entity sits at y = 2: local = world - (0, 2, 0).
        assert!((Vec3::from_array(*l) - (*w - Vec3::Y * 2.0)).length() < 1e-5);
    }
    let mesh = app
        .world()
        .resource::<Assets<Mesh>>()
        .get(state(&app, e).mesh())
        .unwrap();
    assert!(matches!(mesh.indices(), Some(Indices::U32(_))));
    let Some(VertexAttributeValues::Float32x3(n)) = mesh.attribute(Mesh::ATTRIBUTE_NORMAL) else {
        panic!("normals")
    };
    assert!(
        n.iter()
            .all(|n| (Vec3::from_array(*n).length() - 1.0).abs() < 1e-4)
    );
    // The smooth normals of the cloth's triangles (a translation leaves them as they are).
    let sim = state(&app, e).sim();
    let mut expected = vec![Vec3::ZERO; world.len()];
    compute_normals(sim.positions(), &sim.model().triangles, &mut expected);
    for (got, want) in n.iter().zip(&expected) {
        assert!(
            Vec3::from_array(*got).distance(*want) < 1e-5,
            "{got:?} vs {want}"
        );
    }
}

#[test]
fn pins_follow_an_entity_and_release_at_runtime() {
    let mut app = app();
    let anchor = app
        .world_mut()
        .spawn(Transform::from_xyz(0.0, 3.0, 0.0))
        .id();
    let mut pins = ClothPins::default();
    pins.pin(
        0,
        PinAnchor::Entity {
            entity: anchor,
            offset: Vec3::ZERO,
        },
    );
    let e = spawn(
        &mut app,
        (
            Cloth::grid(GridSpec::new(6, 6, 0.05)),
            pins,
            Transform::from_xyz(0.0, 3.0, 0.0),
        ),
    );
    run(&mut app, 2);
    app.world_mut()
        .get_mut::<Transform>(anchor)
        .unwrap()
        .translation = Vec3::new(1.0, 3.0, 0.0);
    run(&mut app, 3);
    let p = state(&app, e).positions()[0];
    assert!(
        p.distance(Vec3::new(1.0, 3.0, 0.0)) < 1e-5,
        "pinned particle at {p}"
    );

    // Release: the cloth falls freely. Whatever its internal swinging (the springs' forces cancel
    // in the sum), its centre of mass then moves under gravity `g` and the velocity damping `c`
    // alone: from height y₀ at vertical velocity v₀, y(t) = y₀ + (v₀ + g/c)(1 − e^{−ct})/c − g t/c.
    run(&mut app, 60);
    let com = |app: &App| {
        let sim = state(app, e).sim();
        let mean = |v: &[Vec3]| v.iter().sum::<Vec3>().y / v.len() as f32;
        (mean(sim.positions()), mean(sim.velocities()))
    };
    let (y0, v0) = com(&app);
    app.world_mut()
        .get_mut::<ClothPins>(e)
        .unwrap()
        .release_all();
    run(&mut app, 30);
    let (c, g, t) = (state(&app, e).sim().settings().damping, 9.81, 0.5);
    let fall = -((v0 + g / c) * (1.0 - (-c * t).exp()) / c - g * t / c);
    let fallen = y0 - com(&app).0;
    assert!(fall > 0.5, "a free fall of {fall} m from v0 = {v0} m/s");
    assert!(
        (fallen - fall).abs() < 0.01,
        "fell {fallen} m, free fall {fall} m"
    );
}

#[test]
fn config_edits_apply_at_runtime() {
    let mut app = app();
    let e = spawn(
        &mut app,
        (
            Cloth::grid(GridSpec::new(4, 4, 0.1)),
            Transform::from_xyz(0.0, 5.0, 0.0),
        ),
    );
    app.world_mut()
        .get_mut::<ClothConfig>(e)
        .unwrap()
        .solver
        .gravity = Vec3::ZERO;
    let before = state(&app, e).positions().to_vec();
    run(&mut app, 10);
    assert_eq!(
        state(&app, e).positions(),
        &before[..],
        "no gravity, no motion"
    );
}

#[test]
fn bad_cloth_is_reported_and_skipped_while_others_run() {
    let mut app = app();
    let good = spawn(&mut app, hanging(6));
    let bad = spawn(&mut app, Cloth::grid(GridSpec::new(1, 6, 0.05)));
    let bad_pin = spawn(
        &mut app,
        (Cloth::grid(GridSpec::new(4, 4, 0.05)), ClothPins::new([99])),
    );
    let before = state(&app, good).steps();
    run(&mut app, 5);
    assert_eq!(state(&app, good).steps(), before + 5);
    let err = &app.world().get::<ClothInvalid>(bad).unwrap().0;
    assert!(err.to_string().contains("nx"), "{err}");
    let err = &app.world().get::<ClothInvalid>(bad_pin).unwrap().0;
    assert!(err.to_string().contains("99"), "{err}");
    assert!(app.world().get::<ClothState>(bad).is_none());

    // An invalid edit of a running cloth is rejected and reported; the cloth runs on, and fixing
    // the edit clears the report.
    let before = state(&app, good).steps();
    app.world_mut()
        .get_mut::<ClothConfig>(good)
        .unwrap()
        .solver
        .substeps = 0;
    run(&mut app, 1);
    assert!(app.world().get::<ClothInvalid>(good).is_none());
    let err = &app.world().get::<ClothEditRejected>(good).unwrap().0;
    assert!(err.to_string().contains("substeps"), "{err}");
    app.world_mut()
        .get_mut::<ClothConfig>(good)
        .unwrap()
        .solver
        .substeps = 10;
    run(&mut app, 3);
    assert!(app.world().get::<ClothEditRejected>(good).is_none());
    assert_eq!(state(&app, good).steps(), before + 4);
}

#[test]
fn diverging_cloth_is_stopped_without_nan_in_its_mesh() {
    let mut app = app();
    // A pin dragged to the edge of f32 range overflows the spring next to it.
    let mut pins = ClothPins::default();
    pins.pin(0, PinAnchor::World(Vec3::splat(3.0e38)));
    let config = ClothConfig {
        interpolate: false,
        ..Default::default()
    };
    let e = spawn(
        &mut app,
        (Cloth::grid(GridSpec::new(4, 4, 0.1)), config, pins),
    );
    let mesh = state(&app, e).mesh().clone();
    run(&mut app, 5);
    let err = &app.world().get::<ClothInvalid>(e).expect("stopped").0;
    assert!(matches!(err, ClothError::Diverged { .. }), "{err}");
    let m = app.world().resource::<Assets<Mesh>>().get(&mesh).unwrap();
    let Some(VertexAttributeValues::Float32x3(p)) = m.attribute(Mesh::ATTRIBUTE_POSITION) else {
        panic!("positions")
    };
    assert!(p.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn a_prebuilt_quad_model_keeps_its_quads_shares_and_steps() {
    use bevy_cloth::sim::ClothModel;
    use std::sync::Arc;

    let mut app = app();
    let model = ClothModel::disc(&DiscSpec::new(5, 4, 0.5)).unwrap();
    let (v, f) = (model.particle_count(), model.faces.len() / 4);
    // A disc: V − E + F = 1.
    let e = v + f - 1;
    let shared = Arc::new(model);
    let subdivided = spawn(
        &mut app,
        (
            Cloth::from_model(shared.clone()),
            ClothSubdivision {
                level: 1,
                rule: VertexRule::Tuned,
                boundary: BoundaryMode::EdgeOnly,
                ..default()
            },
            Transform::from_xyz(0.0, 2.0, 0.0),
        ),
    );
    let plain = spawn(
        &mut app,
        (
            Cloth::from_model(shared.clone()),
            Transform::from_xyz(3.0, 2.0, 0.0),
        ),
    );
    assert_eq!(
        app.world().get::<Cloth>(subdivided),
        app.world().get::<Cloth>(plain),
        "both cloths share one model"
    );
    // One level of Catmull-Clark on quads: a vertex per control vertex, edge and face. Had the
    // model been a triangle list, the faces would be triangles and the count different.
    assert_eq!(vertex_count(&app, subdivided), v + e + f);
    assert_eq!(vertex_count(&app, plain), v);
    let before = [subdivided, plain].map(|c| state(&app, c).steps());
    run(&mut app, 30);
    for (cloth, before) in [subdivided, plain].into_iter().zip(before) {
        let s = state(&app, cloth);
        assert_eq!(s.steps(), before + 30);
        assert_eq!(s.positions().len(), v);
        // Unpinned: it falls (half a second: about 1.2 m, less the air damping).
        assert!(s.positions()[0].y < 2.0 - 1.0, "{}", s.positions()[0]);
    }
    // The subdivided mesh is finite and follows the cloth down.
    let meshes = app.world().resource::<Assets<Mesh>>();
    let mesh = meshes.get(state(&app, subdivided).mesh()).unwrap();
    let Some(VertexAttributeValues::Float32x3(p)) = mesh.attribute(Mesh::ATTRIBUTE_POSITION) else {
        panic!("positions")
    };
    assert!(p.iter().flatten().all(|v| v.is_finite()));
}

#[test]
fn a_broken_prebuilt_model_is_reported_and_skipped() {
    use bevy_cloth::sim::ClothModel;

    let mut app = app();
    let mut model = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
    model.triangles[5] = 1000;
    let bad = spawn(&mut app, Cloth::from_model(model));
    let good = spawn(&mut app, hanging(4));
    run(&mut app, 2);
    let err = &app.world().get::<ClothInvalid>(bad).expect("reported").0;
    assert!(err.to_string().contains("1000"), "{err}");
    assert_eq!(state(&app, good).steps(), 2);
}

#[test]
fn a_round_tablecloth_drapes_over_a_round_table() {
    use bevy_cloth::sim::ClothModel;
    use std::f32::consts::PI;

    // The tablecloth example's scene: a 16-gon table top of 8 boxes, 0.5 m circumradius, its top
    // at 0.75 m; a soft 0.85 m disc (valence-5 centre) dropped from 0.3 m above it.
    let mut app = app();
    let (radius, top, thickness, margin) = (0.5f32, 0.75f32, 0.04f32, 0.015f32);
    let half = Vec3::new(
        radius * (PI / 16.0).cos(),
        thickness / 2.0,
        radius * (PI / 16.0).sin(),
    );
    for k in 0..8 {
        app.world_mut().spawn((
            ClothCollider::cuboid(half)
                .with_friction(Friction::new(0.6))
                .with_margin(margin),
            Transform::from_xyz(0.0, top - thickness / 2.0, 0.0)
                .with_rotation(Quat::from_rotation_y(k as f32 * PI / 8.0)),
        ));
    }
    app.world_mut().spawn(ClothCollider::half_space(Vec3::Y));
    let spec = DiscSpec::new(5, 14, 0.85);
    let cloth = spawn(
        &mut app,
        (
            Cloth::from_model(ClothModel::disc(&spec).unwrap()),
            ClothConfig {
                solver: SolverSettings {
                    damping: 1.0,
                    stiffness: Stiffness {
                        bend: 10.0,
                        ..default()
                    },
                    ..default()
                },
                ..default()
            },
            Transform::from_xyz(0.0, top + 0.3, 0.0),
        ),
    );
    run(&mut app, 180);
    let p = state(&app, cloth).positions();
    // The centre lies on the top, one margin above it.
    assert!((p[0].y - (top + margin)).abs() < 3e-3, "centre at {}", p[0]);
    assert!(
        p[0].xz().length() < 0.05,
        "the cloth slid: centre at {}",
        p[0]
    );
    // The hem hangs below the top, and nothing went through the table or the floor.
    for i in spec.hem() {
        let q = p[i as usize];
        assert!(q.y < top - 0.1, "hem particle {i} at {q}");
        assert!(q.y > 0.0);
    }
    let inside = p
        .iter()
        .filter(|q| q.xz().length() < radius * 0.95 && q.y < top && q.y > top - thickness)
        .count();
    assert_eq!(inside, 0, "particles inside the table top");
}

#[test]
fn the_paper_scene_preset_drapes_its_cloth_over_the_sphere() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/assets/scenes/drape.ron");
    let scene = bevy_cloth::scene::ClothScene::load(path).unwrap();
    // The paper's Figure 5: a 32 × 32 cloth pinned at its four corners, a sphere and the floor.
    let n = 32u32;
    let bevy_cloth::scene::SceneCloth::Grid(spec) = scene.cloth else {
        panic!("not a grid: {:?}", scene.cloth);
    };
    assert_eq!((spec.nx, spec.ny), (n, n));
    assert_eq!(scene.pins, vec![0, n - 1, n * (n - 1), n * n - 1]);
    assert_eq!(scene.colliders.len(), 2);
    let mut app = bevy_cloth::harness::headless_app(scene.dt);
    let cloth = scene.spawn(app.world_mut()).unwrap();
    let corners: Vec<Vec3> = {
        app.update();
        let p = state(&app, cloth).positions();
        scene.pins.iter().map(|&i| p[i as usize]).collect()
    };
    // The cloth lands on the sphere (radius 0.4 at y = 1.2, 1 cm margin) and, held taut by its
    // corners, bounces on it like a trampoline while the bounce dies down. Over the second second:
    // it keeps touching the sphere, never goes into it, and its middle stays on the sphere's top,
    // well below the corners.
    run(&mut app, 60);
    let (centre, surface) = (Vec3::new(0.0, 1.2, 0.0), 0.4 + 0.01);
    let (mut closest, mut deepest, mut highest_middle) = (f32::INFINITY, f32::INFINITY, 0.0f32);
    for _ in 0..60 {
        run(&mut app, 1);
        let p = state(&app, cloth).positions();
        let gap = p
            .iter()
            .map(|q| q.distance(centre) - surface)
            .fold(f32::INFINITY, f32::min);
        closest = closest.min(gap.abs());
        deepest = deepest.min(gap);
        let middle = p[(n / 2 * n + n / 2) as usize];
        assert!(middle.xz().length() < 0.1, "the middle slid to {middle}");
        highest_middle = highest_middle.max(middle.y);
    }
    assert!(
        closest < 1e-3,
        "the cloth never touched the sphere: {closest} m"
    );
    assert!(
        deepest > -3e-3,
        "a particle went {deepest} m into the sphere"
    );
    assert!(
        highest_middle < 1.75 - 0.05,
        "middle up to y = {highest_middle}"
    );
    let p = state(&app, cloth).positions();
    for (&i, c) in scene.pins.iter().zip(&corners) {
        assert_eq!(p[i as usize], *c, "corner {i} moved");
    }
}

#[test]
fn tolerance_mode_set_in_the_config_chooses_the_substeps_within_its_cap() {
    // A cloth turned to tolerance mode at runtime: its state reports the controller's choice,
    // within the cap, and it swings like the same cloth run accurately at fixed substeps.
    let mut app = app();
    let e = app.world_mut().spawn(hanging(12)).id();
    let fixed = app
        .world_mut()
        .spawn(hanging_at(12, Vec3::new(3.0, 2.0, 0.0)))
        .id();
    run(&mut app, 1);
    assert!(state(&app, e).sim().accuracy_report().is_none());
    let mut config = app.world_mut().get_mut::<ClothConfig>(e).unwrap();
    config.solver.accuracy = bevy_cloth::sim::Accuracy::relative(1e-3, 200);
    let mut config = app.world_mut().get_mut::<ClothConfig>(fixed).unwrap();
    config.solver.integrator = bevy_cloth::sim::Integrator::Verlet;
    config.solver.substeps = 400;
    // Both hang from the same pins, 3 m apart: after 1/3 s they differ by less than 1 mm (the
    // falling cloth buckles: later, even 400 and 800 substeps of Verlet part by centimetres).
    run(&mut app, 20);
    let offset = Vec3::new(3.0, 0.0, 0.0);
    let worst = state(&app, e)
        .positions()
        .iter()
        .zip(state(&app, fixed).positions())
        .map(|(a, b)| a.distance(*b - offset))
        .fold(0.0, f32::max);
    assert!(worst < 0.001, "{worst} m apart");
    for _ in 0..100 {
        run(&mut app, 1);
        let report = state(&app, e).sim().accuracy_report().unwrap();
        assert!(report.substeps <= 200, "{report:?}");
    }
    let report = state(&app, e).sim().accuracy_report().unwrap();
    assert!(report.estimates > 0, "{report:?}");
}

#[path = "app/subdivided.rs"]
mod subdivided;
use subdivided::vertex_count;
#[path = "app/seams.rs"]
mod seams;
#[path = "app/tearing.rs"]
mod tearing;
