use bevy::math::primitives::InfinitePlane3d;

use super::*;
use crate::components::{AIR_DENSITY, DEFAULT_COLLIDER_MARGIN};
use crate::sim::{ColliderShape, Gusts, WindZoneShape};

#[test]
fn minimal_scene_gets_defaults() {
    let s = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)))").unwrap();
    assert_eq!(s.solver, SolverSettings::default());
    assert_eq!(s.dt, 1.0 / 60.0);
}

#[test]
fn unknown_fields_and_bad_values_are_errors() {
    let e =
        ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colour: 3)").unwrap_err();
    assert!(e.to_string().contains("colour"), "{e}");
    let e = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), pins: [12])")
        .unwrap_err();
    assert!(e.to_string().contains("12"), "{e}");
    let e =
        ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), dt: -1.0)").unwrap_err();
    assert!(e.to_string().contains("dt"), "{e}");
    let e =
        ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), solver: (substeps: 0))")
            .unwrap_err();
    assert!(e.to_string().contains("substeps"), "{e}");
    assert!(ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3").is_err());
    let e = ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colliders: [(shape: Sphere(radius: -1.0))])",
    )
    .unwrap_err();
    assert!(e.to_string().contains("collider.radius"), "{e}");
    let e = ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colliders: [(shape: Plane(normal: (0.0, 0.0, 0.0)))])",
    )
    .unwrap_err();
    assert!(e.to_string().contains("normal"), "{e}");
}

#[test]
fn wind_parses_with_defaults() {
    let s = ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some((
            velocity: (6.0, 0.0, 0.0),
            gusts: Some((seed: 7, strength: 0.4)),
            zones: [
                (shape: Sphere(radius: 0.5), translation: (0.0, 1.0, 0.0), velocity: (0.0, 2.0, 0.0)),
                (shape: Cuboid(half_size: (1.0, 0.5, 1.0)), rotation_degrees: (0.0, 45.0, 0.0),
                 velocity: (1.0, 0.0, 0.0), gusts: Some(()), falloff: 0.0),
            ],
        )))",
    )
    .unwrap();
    let wind = s.wind.as_ref().unwrap();
    let resource = wind.resource();
    assert_eq!(resource.velocity, Vec3::new(6.0, 0.0, 0.0));
    assert_eq!(resource.air_density, AIR_DENSITY);
    assert!(resource.enabled);
    let gusts = resource.gusts.unwrap();
    assert_eq!((gusts.seed, gusts.strength), (7, 0.4));
    assert_eq!(gusts.frequency, Gusts::default().frequency);
    let zone = wind.zones[0].component().unwrap();
    assert_eq!(zone.shape, WindZoneShape::Sphere(0.5));
    assert_eq!(zone.falloff, DEFAULT_SCENE_WIND_ZONE_FALLOFF);
    assert_eq!(zone.gusts, None);
    let boxed = wind.zones[1].component().unwrap();
    assert_eq!(boxed.shape, WindZoneShape::Cuboid(Vec3::new(1.0, 0.5, 1.0)));
    assert_eq!(boxed.gusts, Some(Gusts::default()));
    // An empty wind is still air of the default density; `None` is no air at all.
    let still = ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some(()))")
        .unwrap();
    assert_eq!(still.wind, Some(SceneWind::default()));
    let none =
        ClothScene::from_ron("(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: None)").unwrap();
    assert_eq!(none.wind, None);
}

#[test]
fn bad_wind_values_name_the_field() {
    let scene = |wind: &str| {
        ClothScene::from_ron(&format!(
            "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), wind: Some({wind}))"
        ))
    };
    for (wind, field) in [
        ("(air_density: -1.0)", "wind.air_density"),
        ("(velocity: (inf, 0.0, 0.0))", "wind.velocity"),
        ("(gusts: Some((strength: -0.5)))", "wind.gusts.strength"),
        ("(gusts: Some((frequency: NaN)))", "wind.gusts.frequency"),
        ("(gusts: Some((turbulence: -1.0)))", "wind.gusts.turbulence"),
        (
            "(zones: [(shape: Sphere(radius: 0.0), velocity: (1.0, 0.0, 0.0))])",
            "wind.zones.shape.radius",
        ),
        (
            "(zones: [(shape: Cuboid(half_size: (1.0, -1.0, 1.0)), velocity: (1.0, 0.0, 0.0))])",
            "wind.zones.shape.half_size",
        ),
        (
            "(zones: [(shape: Sphere(radius: 1.0), velocity: (1.0, 0.0, 0.0), falloff: 1.5)])",
            "wind.zones.falloff",
        ),
        (
            "(zones: [(shape: Sphere(radius: 1.0), velocity: (NaN, 0.0, 0.0))])",
            "wind.zones.velocity",
        ),
        (
            "(zones: [(shape: Sphere(radius: 1.0), velocity: (1.0, 0.0, 0.0), gusts: Some((strength: -2.0)))])",
            "wind.zones.gusts.strength",
        ),
        // Unknown and missing fields are named by the parser.
        ("(speed: 3.0)", "speed"),
        ("(gusts: Some((sead: 3)))", "sead"),
        ("(zones: [(shape: Sphere(radius: 1.0))])", "velocity"),
    ] {
        let e = scene(wind).unwrap_err();
        assert!(e.to_string().contains(field), "{wind}: {e}");
    }
}

#[test]
fn colliders_parse_with_defaults() {
    let s = ClothScene::from_ron(
        "(cloth: Grid((nx: 4, ny: 3, spacing: 0.1)), colliders: [
            (shape: Sphere(radius: 0.5), translation: (0.0, 1.0, 0.0)),
            (shape: Capsule(radius: 0.1, half_length: 0.3), velocity: (1.0, 0.0, 0.0)),
            (shape: Cuboid(half_size: (1.0, 0.5, 1.0)), friction: (static_coefficient: 0.9, kinetic_coefficient: 0.7)),
            (shape: Plane(normal: (0.0, 2.0, 0.0)), margin: 0.02),
        ])",
    )
    .unwrap();
    assert_eq!(s.colliders.len(), 4);
    assert_eq!(s.colliders[0].margin, DEFAULT_COLLIDER_MARGIN);
    assert_eq!(s.colliders[1].velocity, Vec3::X);
    let plane = s.colliders[3].component().unwrap();
    assert_eq!(
        plane.shape,
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y))
    );
}

#[test]
fn closed_cloths_parse_and_count_their_particles() {
    let s = ClothScene::from_ron(
        "(cloth: Icosphere(radius: 0.2, subdivisions: 3), solver: (pressure: Volume(scale: 1.0, bulk_modulus: 1.0e5)))",
    )
    .unwrap();
    assert_eq!(s.cloth.particle_count().unwrap(), 642);
    assert_eq!(s.model().unwrap().particle_count(), 642);
    let b = ClothScene::from_ron("(cloth: Cuboid(size: (0.4, 0.2, 0.4), spacing: 0.1), pins: [0])")
        .unwrap();
    let model = b.model().unwrap();
    assert_eq!(b.cloth.particle_count().unwrap(), model.particle_count());
    assert!(model.check_closed().is_ok());
    for (cloth, field) in [
        (
            "Icosphere(radius: 0.0, subdivisions: 2)",
            "icosphere radius",
        ),
        (
            "Icosphere(radius: 1.0, subdivisions: 9)",
            "icosphere subdivisions",
        ),
        (
            "Cuboid(size: (1.0, -1.0, 1.0), spacing: 0.1)",
            "cuboid size.y",
        ),
        (
            "Cuboid(size: (1.0, 1.0, 1.0), spacing: NaN)",
            "cuboid spacing",
        ),
    ] {
        let e = ClothScene::from_ron(&format!("(cloth: {cloth})")).unwrap_err();
        assert!(e.to_string().contains(field), "{cloth}: {e}");
    }
    // A pin past the sphere's last particle.
    let e = ClothScene::from_ron("(cloth: Icosphere(radius: 0.2, subdivisions: 0), pins: [12])")
        .unwrap_err();
    assert!(e.to_string().contains("12"), "{e}");
}

#[test]
fn copies_lay_out_on_a_square_grid() {
    let copies = SceneCopies {
        count: 7,
        columns: None,
        spacing: 2.0,
        phase: 0.0,
    };
    // ⌈√7⌉ = 3 columns along +X, rows along +Z.
    assert_eq!(copies.offset(0), Vec3::ZERO);
    assert_eq!(copies.offset(2), Vec3::new(4.0, 0.0, 0.0));
    assert_eq!(copies.offset(3), Vec3::new(0.0, 0.0, 2.0));
    assert_eq!(copies.offset(6), Vec3::new(0.0, 0.0, 4.0));
    let row = SceneCopies {
        columns: Some(7),
        ..copies
    };
    assert_eq!(row.offset(6), Vec3::new(12.0, 0.0, 0.0));
    for (copies, field) in [
        ("(count: 0)", "copies.count"),
        ("(count: 10001)", "copies.count"),
        ("(count: 4, columns: Some(0))", "copies.columns"),
        ("(count: 4, spacing: -1.0)", "copies.spacing"),
        ("(count: 4, rows: 2)", "rows"),
        // 20 copies of a 512 × 2048 grid: more particles than all copies may have.
        ("(count: 20)", "particles of all copies"),
    ] {
        let cloth = if field.starts_with("particles") {
            "Grid((nx: 512, ny: 2048, spacing: 0.01))"
        } else {
            "Grid((nx: 4, ny: 3, spacing: 0.1))"
        };
        let e = ClothScene::from_ron(&format!("(cloth: {cloth}, copies: {copies})")).unwrap_err();
        assert!(e.to_string().contains(field), "{copies}: {e}");
    }
}

#[test]
fn copies_bring_their_own_colliders_and_zones_but_share_the_shared_ones() {
    let s = ClothScene::from_ron(
        "(cloth: Icosphere(radius: 0.1, subdivisions: 1), translation: (1.0, 2.0, 3.0),
          copies: (count: 3, columns: Some(3), spacing: 10.0),
          colliders: [
            (shape: Plane(normal: (0.0, 1.0, 0.0)), shared: true),
            (shape: Sphere(radius: 0.1), translation: (0.0, 1.0, 0.0)),
          ],
          wind: Some((zones: [(shape: Sphere(radius: 1.0), velocity: (1.0, 0.0, 0.0))])))",
    )
    .unwrap();
    let mut world = World::new();
    let cloths = s.spawn_copies(&mut world).unwrap();
    assert_eq!(cloths.len(), 3);
    let place = |e: Entity| world.get::<Transform>(e).unwrap().translation;
    assert_eq!(place(cloths[2]), Vec3::new(21.0, 2.0, 3.0));
    let mut colliders: Vec<(bool, Vec3)> = world
        .query::<(&crate::components::ClothCollider, &Transform)>()
        .iter(&world)
        .map(|(c, t)| {
            (
                matches!(c.shape, ColliderShape::HalfSpace(_)),
                t.translation,
            )
        })
        .collect();
    colliders.sort_by(|a, b| a.1.x.total_cmp(&b.1.x));
    assert_eq!(colliders.iter().filter(|c| c.0).count(), 1, "{colliders:?}");
    let spheres: Vec<Vec3> = colliders.iter().filter(|c| !c.0).map(|c| c.1).collect();
    assert_eq!(
        spheres,
        [0.0, 10.0, 20.0].map(|x| Vec3::new(x, 1.0, 0.0)).to_vec()
    );
    let zones = world
        .query::<&crate::components::WindZone>()
        .iter(&world)
        .count();
    assert_eq!(zones, 3);
    // The copies share one model.
    let model = |e: Entity| match &world.get::<Cloth>(e).unwrap().source {
        crate::components::ClothSource::Model(m) => m.0.clone(),
        other => panic!("{other:?}"),
    };
    assert!(std::sync::Arc::ptr_eq(&model(cloths[0]), &model(cloths[2])));
}

#[test]
fn the_crowd_scene_holds_capes_and_flags() {
    let s = ClothScene::load(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/assets/scenes/crowd/crowd.ron"
    ))
    .unwrap();
    assert_eq!(s.cloth, SceneCloth::Cape { nx: 20, ny: 25 });
    assert_eq!(s.cloth.particle_count().unwrap(), 500);
    assert_eq!(s.cloth.model().unwrap().particle_count(), 500);
    assert_eq!(s.also.len(), 1);
    assert!(s.walk.speed > 0.0);
    assert!(s.copies.phase > 0.0);
}

#[test]
fn further_cloths_and_walks_are_checked() {
    let grid = "Grid((nx: 4, ny: 3, spacing: 0.1))";
    for (text, wanted) in [
        (
            format!("(cloth: {grid}, walk: (speed: 1.0, radius: 1.0))"),
            "Cape",
        ),
        (
            "(cloth: Cape(nx: 4, ny: 4), walk: (speed: 1.0))".to_string(),
            "walk.radius",
        ),
        (
            "(cloth: Cape(nx: 4, ny: 4), walk: (speed: -1.0, radius: 1.0))".to_string(),
            "walk.speed",
        ),
        ("(cloth: Cape(nx: 1, ny: 4))".to_string(), "cape nx × ny"),
        (
            "(cloth: Cape(nx: 2, ny: 2), target_weights: Some([0.0, 0.0, 1.0, 1.0]))".to_string(),
            "target weights from its mesh",
        ),
        (
            format!("(cloth: {grid}, copies: (phase: inf))"),
            "copies.phase",
        ),
        (
            format!("(cloth: {grid}, lod: Some((hysteresis: 1.5)))"),
            "lod.hysteresis",
        ),
        (
            format!("(cloth: {grid}, lod: Some((reduced: 50.0)))"),
            "lod thresholds",
        ),
        (
            format!("(cloth: {grid}, budget_ms: Some(0.0))"),
            "budget_ms",
        ),
        (
            format!("(cloth: {grid}, viewer: Some((from: (0.0, 0.0, 0.0), seconds: 0.0)))"),
            "viewer.seconds",
        ),
        (
            format!("(cloth: {grid}, viewer: Some((from: (0.0, 0.0, 0.0), fov_y_degrees: 180.0)))"),
            "viewer.fov_y_degrees",
        ),
        (
            format!("(cloth: {grid}, also: [(cloth: {grid}, budget_ms: Some(1.0))])"),
            "also[0]: budget_ms",
        ),
        (
            format!("(cloth: {grid}, also: [(cloth: {grid}, dt: 0.01)])"),
            "also[0]: dt",
        ),
        (
            format!("(cloth: {grid}, also: [(cloth: {grid}), (cloth: {grid}, wind: Some(()))])"),
            "also[1]: wind",
        ),
        (
            format!("(cloth: {grid}, also: [(cloth: {grid}, also: [(cloth: {grid})])])"),
            "also[0]: also",
        ),
        (
            format!("(cloth: {grid}, also: [(cloth: {grid}, pins: [12])])"),
            "also[0]",
        ),
        // 8 copies of a 512 × 2048 grid, then 9 more beside them: too many particles in all.
        (
            "(cloth: Grid((nx: 512, ny: 2048, spacing: 0.01)), copies: (count: 8),
              also: [(cloth: Grid((nx: 512, ny: 2048, spacing: 0.01)), copies: (count: 9))])"
                .to_string(),
            "particles of all cloths",
        ),
    ] {
        let e = ClothScene::from_ron(&text).unwrap_err();
        assert!(e.to_string().contains(wanted), "{text}: {e}");
    }
}

#[test]
fn walks_start_at_the_placement_and_follow_their_circle() {
    let walk = SceneWalk {
        speed: 1.0,
        radius: 2.0,
        sway: 0.5,
        sway_rate: 0.25,
    };
    let (root, spine) = walk.pose(0.0);
    assert_eq!(root.translation, Vec3::ZERO);
    assert_eq!(spine.translation, character::SPINE);
    // A quarter of the circle (π m at 1 m/s): 2 m across and 2 m ahead, facing +X.
    let (root, spine) = walk.pose(std::f32::consts::PI);
    assert!(
        (root.translation - Vec3::new(2.0, 0.0, 2.0)).length() < 1e-5,
        "{root:?}"
    );
    assert!((root.rotation * Vec3::Z - Vec3::X).length() < 1e-5);
    // The spine at the top of its sway after a quarter period (1 s).
    let (_, spine_1) = walk.pose(1.0);
    assert!((spine_1.rotation.to_axis_angle().1 - 0.5).abs() < 1e-5);
    assert!(spine.rotation.is_finite());
    // Standing still: no motion at all.
    let (root, spine) = SceneWalk::default().pose(7.0);
    assert_eq!(
        (root, spine),
        (
            Transform::IDENTITY,
            Transform::from_translation(character::SPINE)
        )
    );
}

#[test]
fn a_scene_viewer_flies_there_and_back_looking_ahead_or_at_its_point() {
    let viewer = SceneViewer {
        from: Vec3::ZERO,
        to: Some(Vec3::new(10.0, 0.0, 0.0)),
        seconds: 5.0,
        look_at: None,
        fov_y_degrees: 45.0,
        aspect: 1.0,
    };
    viewer.validate().unwrap();
    let at = |t: f32| viewer.pose(t);
    assert!((at(2.5).translation - Vec3::new(5.0, 0.0, 0.0)).length() < 1e-5);
    assert!((at(5.0).translation - Vec3::new(10.0, 0.0, 0.0)).length() < 1e-5);
    // On the way out it looks along +X, back along -X; then it starts over.
    assert!((at(2.5).forward().as_vec3() - Vec3::X).length() < 1e-5);
    assert!((at(7.5).translation - Vec3::new(5.0, 0.0, 0.0)).length() < 1e-5);
    assert!((at(7.5).forward().as_vec3() + Vec3::X).length() < 1e-5);
    assert!((at(12.5).translation - at(2.5).translation).length() < 1e-4);
    // Looking at a point wherever it is.
    let watching = SceneViewer {
        look_at: Some(Vec3::new(5.0, 0.0, 5.0)),
        ..viewer
    };
    let pose = watching.pose(2.5);
    assert!(
        (pose.forward().as_vec3() - Vec3::Z).length() < 1e-5,
        "{pose:?}"
    );
}
