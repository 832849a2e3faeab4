//! Tearing in the app: cuts as messages, tears under strain, the render mesh, pins and targets
//! following the torn topology.

use super::*;
use bevy_cloth::sim::Cut;
use bevy_cloth::subdivision::Subdivider;

/// Every [`ClothTorn`] written, in order.
#[derive(Resource, Default)]
struct TornLog(Vec<ClothTorn>);

fn app_logging_tears() -> App {
    let mut app = app();
    app.init_resource::<TornLog>().add_systems(
        Update,
        |mut torn: MessageReader<ClothTorn>, mut log: ResMut<TornLog>| {
            log.0.extend(torn.read().cloned());
        },
    );
    app
}

/// Cuts cloth `e` along the level plane through its particle `particle`, and takes a step.
fn cut_level_through(app: &mut App, e: Entity, particle: usize) {
    let point = state(app, e).positions()[particle];
    let cut = Cut::Plane {
        point,
        normal: Vec3::Y,
    };
    app.world_mut().write_message(ClothCut { cloth: e, cut });
    run(app, 1);
}

/// The lowest height of the particles of `piece`.
fn lowest(app: &App, e: Entity, pieces: &[u32], piece: u32) -> f32 {
    state(app, e)
        .positions()
        .iter()
        .zip(pieces)
        .filter(|(_, p)| **p == piece)
        .map(|(x, _)| x.y)
        .fold(f32::INFINITY, f32::min)
}

#[test]
fn a_cut_message_tears_the_subdivided_cloth_in_two_and_a_torn_message_follows() {
    let mut app = app_logging_tears();
    let n = 16u32;
    let spec = GridSpec::new(n, n, 0.05).with_plane(GridPlane::Vertical);
    let e = spawn_valid(
        &mut app,
        (
            Cloth::grid(spec),
            ClothPins::new([0, n - 1]),
            ClothSubdivision::default(),
            Transform::from_xyz(0.0, 2.0, 0.0),
        ),
    );
    run(&mut app, 20);
    let before = vertex_count(&app, e);
    cut_level_through(&mut app, e, (8 * n + 4) as usize);
    let log = &app.world().resource::<TornLog>().0;
    assert_eq!(log.len(), 1, "one torn message");
    assert_eq!(log[0].cloth, e);
    assert_eq!(log[0].splits.len(), n as usize);
    let particles = (n * (n + 1)) as usize;
    assert_eq!(state(&app, e).positions().len(), particles);
    // The render mesh is the refined surface of the torn cloth: more vertices along the cut.
    let after = vertex_count(&app, e);
    assert!(after > before, "{before} -> {after} render vertices");
    let (count, pieces) = sim(&app, e).model().pieces();
    assert_eq!(count, 2);
    let falling = 1 - pieces[0];
    let start = lowest(&app, e, &pieces, falling);
    run(&mut app, 30);
    assert!(app.world().get::<ClothInvalid>(e).is_none());
    let fell = start - lowest(&app, e, &pieces, falling);
    assert!(fell > 1.0, "the lower piece fell {fell} m in half a second");
    assert_eq!(
        app.world().resource::<TornLog>().0.len(),
        1,
        "no more tears"
    );
}

/// A slit in a subdivided 40×40 cloth: its render mesh follows the torn mesh (refined again
/// around the slit only) and draws the same surface as a subdivision of the torn mesh built
/// afresh, triangle by triangle.
#[test]
fn a_slit_subdivided_cloth_draws_the_refined_surface_of_its_torn_mesh() {
    let mut app = app_logging_tears();
    let n = 40u32;
    let spec = GridSpec::new(n, n, 0.02).with_plane(GridPlane::Vertical);
    let subdivision = ClothSubdivision::default();
    let e = spawn_valid(
        &mut app,
        (
            Cloth::grid(spec),
            ClothPins::new([0, n - 1]),
            subdivision,
            ClothConfig {
                interpolate: false,
                ..Default::default()
            },
            Transform::from_xyz(0.0, 2.0, 0.0),
        ),
    );
    run(&mut app, 10);
    let at = |app: &App, i: u32| state(app, e).positions()[i as usize];
    let across = at(&app, 20 * n + 1) - at(&app, 20 * n);
    let cut = Cut::Segment {
        start: at(&app, 20 * n) - across,
        end: at(&app, 20 * n + 10),
        radius: 0.006,
    };
    app.world_mut().write_message(ClothCut { cloth: e, cut });
    // Ten frames on, the slit has opened.
    run(&mut app, 10);
    assert_eq!(app.world().resource::<TornLog>().0.len(), 1, "it tore once");

    let mut fresh = Subdivider::new(
        &sim(&app, e).model().control_mesh().unwrap(),
        subdivision.level,
        subdivision.rule,
        subdivision.boundary,
    )
    .unwrap();
    // The entity sits at y = 2: the mesh is in its local space.
    let local: Vec<Vec3> = state(&app, e)
        .positions()
        .iter()
        .map(|p| *p - 2.0 * Vec3::Y)
        .collect();
    let mut refined = vec![Vec3::ZERO; fresh.refined_vertex_count()];
    fresh.apply(&local, &mut refined).unwrap();
    let layout = fresh.topology().render_mesh();
    let mut expected = vec![Vec3::ZERO; layout.vertex_count()];
    layout.expand(&refined, &mut expected).unwrap();
    let (drawn, _) = mesh_positions(&app, e);
    let mesh = app
        .world()
        .resource::<Assets<Mesh>>()
        .get(state(&app, e).mesh())
        .unwrap();
    let Some(Indices::U32(indices)) = mesh.indices() else {
        panic!("indices")
    };
    assert_eq!(indices.len(), layout.triangle_indices().len());
    for (&a, &b) in indices.iter().zip(layout.triangle_indices()) {
        let gap = Vec3::from_array(drawn[a as usize]).distance(expected[b as usize]);
        assert!(gap < 1e-5, "render vertices {a} and {b}: {gap} m apart");
    }
}

/// Heavy particles (0.2 kg) on springs that tear past 5% stretch: a 12×12 cloth hanging from two
/// corners tears within a second.
fn overloaded() -> ClothConfig {
    let mut config = ClothConfig::default();
    config.solver.particle_mass = 0.2;
    config.solver.tearing = Tearing {
        enabled: true,
        max_stretch: 0.05,
        ..Tearing::default()
    };
    config
}

#[test]
fn an_overloaded_cloth_tears_under_strain_and_a_bad_cut_is_dropped() {
    let mut app = app_logging_tears();
    let n = 12u32;
    let config = overloaded();
    let e = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(n, n, 0.05).with_plane(GridPlane::Vertical)),
            ClothPins::new([0, n - 1]),
            config,
            Transform::from_xyz(0.0, 2.0, 0.0),
        ),
    );
    // A cut with a zero normal is logged and dropped; the cloth runs on.
    app.world_mut().write_message(ClothCut {
        cloth: e,
        cut: Cut::Plane {
            point: Vec3::ZERO,
            normal: Vec3::ZERO,
        },
    });
    run(&mut app, 60);
    assert!(app.world().get::<ClothInvalid>(e).is_none());
    let log = &app.world().resource::<TornLog>().0;
    assert!(!log.is_empty(), "the overloaded cloth did not tear");
    let splits: usize = log.iter().map(|t| t.splits.len()).sum();
    assert_eq!(state(&app, e).positions().len(), (n * n) as usize + splits);
    assert_eq!(vertex_count(&app, e), state(&app, e).positions().len());
    assert!(state(&app, e).positions().iter().all(|p| p.is_finite()));
}

#[test]
fn a_cloth_cut_below_its_targets_keeps_its_top_half_on_them() {
    let mut app = app_logging_tears();
    let n = 12u32;
    // The top row pinned to its targets, the rest free to swing a little.
    let weights = (0..n * n).map(|p| if p < n { 0.0 } else { -1.0 }).collect();
    let e = spawn_valid(
        &mut app,
        (
            Cloth::grid(GridSpec::new(n, n, 0.05).with_plane(GridPlane::Vertical)),
            ClothTargets {
                weights: TargetWeights::Values(weights),
            },
            Transform::from_xyz(0.0, 2.0, 0.0),
        ),
    );
    run(&mut app, 10);
    cut_level_through(&mut app, e, (6 * n + 3) as usize);
    let (count, pieces) = sim(&app, e).model().pieces();
    assert_eq!(count, 2);
    // The entity walks 1 m on; the top half goes along on its targets, the bottom falls.
    for step in 1..=60 {
        app.world_mut().get_mut::<Transform>(e).unwrap().translation =
            Vec3::new(0.0, 2.0, step as f32 / 60.0);
        app.update();
    }
    let x = state(&app, e).positions();
    let mean_z = |piece: u32| {
        let (sum, k) = x
            .iter()
            .zip(&pieces)
            .filter(|(_, p)| **p == piece)
            .fold((0.0, 0), |(s, k), (p, _)| (s + p.z, k + 1));
        sum / k as f32
    };
    let top = pieces[0];
    assert!(
        mean_z(top) > 0.8,
        "the attached half is at z = {}",
        mean_z(top)
    );
    assert!(
        mean_z(1 - top) < 0.2,
        "the cut half is at z = {}",
        mean_z(1 - top)
    );
    for t in state(&app, e).targets().filter(|t| t.weight == 0.0) {
        assert!(x[t.particle as usize].distance(t.position) < 1e-4);
    }
}

#[test]
fn tear_weights_hold_an_overloaded_cloth_together_and_a_bad_list_is_refused() {
    let mut app = app_logging_tears();
    let n = 12u32;
    let config = overloaded();
    let cloth = |weights: Vec<f32>| {
        (
            Cloth::grid(GridSpec::new(n, n, 0.05).with_plane(GridPlane::Vertical)),
            ClothPins::new([0, n - 1]),
            config,
            ClothTearWeights {
                weights: TargetWeights::Values(weights),
            },
            Transform::from_xyz(0.0, 2.0, 0.0),
        )
    };
    // The overloaded cloth that tears at weight 1 (see above) holds at weight 100.
    let e = spawn_valid(&mut app, cloth(vec![100.0; (n * n) as usize]));
    run(&mut app, 60);
    assert!(app.world().resource::<TornLog>().0.is_empty());
    assert_eq!(state(&app, e).sim().tears(), 0);
    let bad = spawn(&mut app, cloth(vec![1.0; 5]));
    assert!(app.world().get::<ClothInvalid>(bad).is_some());
}
