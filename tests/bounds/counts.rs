//! The bounds on counts: sleep steps, substeps and iterations, springs per particle, pins and
//! targets, wind zones, scene files, the fixed step, subdivision levels and valences.

use bevy::prelude::*;
use bevy_cloth::plugin::{MAX_FIXED_STEP, MIN_FIXED_STEP, validate_fixed_step};
use bevy_cloth::scene::{ClothScene, MAX_SCENE_BYTES};
use bevy_cloth::sim::{
    Accuracy, ClothModel, ClothSim, GridSpec, Integrator, MAX_ITERATIONS, MAX_SPRINGS_PER_PARTICLE,
    MAX_SUBSTEPS, MAX_WIND_ZONES, PlacedWindZone, SolverSettings, SpringKind, Stiffness, Target,
    WindField, WindZoneShape,
};
use bevy_cloth::subdivision::analysis::{MAX_VALENCE, eigen_report};
use bevy_cloth::subdivision::{
    BoundaryMode, MAX_LEVEL, PolyMesh, Subdivider, SubdivisionError, VertexRule,
};
use bevy_cloth::{
    Cloth, ClothError, ClothInvalid, ClothSubdivision, MAX_CLOTH_SUBDIVISION_LEVEL,
    SubdivisionTarget,
};
use glam::DVec3;

use super::common;
use super::{error, names};

/// A `ClothError::CountOutOfRange` on `field` at `value`, range `min..=max`.
fn out_of_range(e: &ClothError, field: &str, value: u32, (min, max): (u32, u32)) {
    assert!(
        matches!(e, ClothError::CountOutOfRange { field: f, min: a, max: b, value: v }
            if *f == field && (*a, *b, *v) == (min, max, value)),
        "{e:?}"
    );
    names(e, &[field, &value.to_string(), &max.to_string()]);
}

/// A `ClothError::TooMany` on `field` counting `count`, bound `bound`.
fn too_many(e: &ClothError, field: &str, count: u64, bound: u64) {
    assert!(
        matches!(e, ClothError::TooMany { field: f, count: c, bound: b, .. }
            if *f == field && *c == count && *b == bound),
        "{e:?}"
    );
    names(e, &[field, &count.to_string(), &bound.to_string()]);
}

#[test]
fn sleep_steps_of_zero_are_refused_and_one_is_accepted() {
    let settings = |sleep_steps| SolverSettings {
        sleep_steps,
        ..default()
    };
    let model = ClothModel::grid(&GridSpec::new(16, 16, 0.05)).unwrap();
    // Zero would put the cloth to sleep before its first step.
    let e = error(ClothSim::new(model.clone(), settings(0), |p| p));
    out_of_range(&e, "sleep_steps", 0, (1, u32::MAX));
    // At one the cloth falls: about 14 cm in ten steps.
    let mut sim = ClothSim::new(model, settings(1), |p| p).unwrap();
    for _ in 0..10 {
        sim.step(1.0 / 60.0).unwrap();
    }
    assert!(sim.positions()[0].y < -0.1, "{}", sim.positions()[0]);
    assert!(!sim.is_sleeping());
}

#[test]
fn substeps_iterations_and_the_tolerance_modes_cap_have_bounds() {
    let with = |f: &dyn Fn(&mut SolverSettings)| {
        let mut s = SolverSettings::default();
        f(&mut s);
        s.validate()
    };
    assert_eq!(with(&|s| s.substeps = MAX_SUBSTEPS), Ok(()));
    let e = error(with(&|s| s.substeps = MAX_SUBSTEPS + 1));
    out_of_range(&e, "substeps", MAX_SUBSTEPS + 1, (1, MAX_SUBSTEPS));
    assert_eq!(with(&|s| s.iterations = MAX_ITERATIONS), Ok(()));
    let e = error(with(&|s| s.iterations = MAX_ITERATIONS + 1));
    out_of_range(&e, "iterations", MAX_ITERATIONS + 1, (1, MAX_ITERATIONS));
    let capped = |max| move |s: &mut SolverSettings| s.accuracy = Accuracy::relative(1e-3, max);
    assert_eq!(with(&capped(MAX_SUBSTEPS)), Ok(()));
    let e = error(with(&capped(MAX_SUBSTEPS + 1)));
    out_of_range(
        &e,
        "accuracy.max_substeps",
        MAX_SUBSTEPS + 1,
        (2, MAX_SUBSTEPS),
    );
}

#[test]
fn auto_substeps_stop_at_max_substeps() {
    // Stiff enough and light enough that the stability bound asks for far more.
    let settings = SolverSettings {
        integrator: Integrator::Verlet,
        auto_substeps: true,
        stiffness: Stiffness {
            structural: 1e7,
            shear: 1e7,
            bend: 1e7,
        },
        particle_mass: 1e-5,
        ..default()
    };
    let model = ClothModel::grid(&GridSpec::new(4, 4, 0.01)).unwrap();
    let sim = ClothSim::new(model, settings, |p| p).unwrap();
    assert_eq!(sim.substeps_for(1.0 / 60.0), MAX_SUBSTEPS);
}

/// A fan of `triangles` triangles around particle 0 (a half disc): particle 0 has one spring
/// per rim particle.
fn fan(triangles: u32) -> Result<ClothModel, ClothError> {
    let rim = (0..=triangles).map(|k| {
        let a = std::f32::consts::PI * k as f32 / triangles as f32;
        Vec3::new(a.cos(), 0.0, a.sin())
    });
    let positions: Vec<Vec3> = std::iter::once(Vec3::ZERO).chain(rim).collect();
    let indices: Vec<u32> = (1..=triangles).flat_map(|k| [0, k, k + 1]).collect();
    ClothModel::from_mesh(&positions, None, &indices, 3)
}

#[test]
fn a_particle_may_have_max_springs_per_particle_and_not_one_more() {
    let n = MAX_SPRINGS_PER_PARTICLE as u32;
    assert!(fan(n - 1).is_ok());
    let e = error(fan(n));
    too_many(
        &e,
        "springs at one particle",
        n as u64 + 1,
        MAX_SPRINGS_PER_PARTICLE as u64,
    );
    names(&e, &["particle 0", "MAX_SPRINGS_PER_PARTICLE"]);
    // A star of springs, and a hand-built model's springs.
    let star = |arms: u32| {
        let points: Vec<Vec3> = (0..=arms).map(|k| Vec3::new(k as f32, 0.0, 0.0)).collect();
        let springs: Vec<_> = (1..=arms).map(|k| (0, k, SpringKind::Structural)).collect();
        ClothModel::from_springs(&points, &springs)
    };
    let at = star(n).unwrap();
    assert_eq!(at.validate(), Ok(()));
    let e = error(star(n + 1));
    too_many(
        &e,
        "springs at one particle",
        n as u64 + 1,
        MAX_SPRINGS_PER_PARTICLE as u64,
    );
    let mut edited = at.clone();
    edited.springs.a.push(0);
    edited.springs.b.push(1);
    edited.springs.rest.push(1.0);
    edited.springs.kind.push(SpringKind::Structural);
    let last = edited.springs.color_offsets.len();
    edited
        .springs
        .color_offsets
        .push(edited.springs.color_offsets[last - 1] + 1);
    let e = error(edited.validate());
    too_many(
        &e,
        "springs at one particle",
        n as u64 + 1,
        MAX_SPRINGS_PER_PARTICLE as u64,
    );
}

#[test]
fn pins_and_targets_are_at_most_one_per_particle() {
    let model = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
    let mut sim = ClothSim::new(model, default(), |p| p).unwrap();
    let all: Vec<(u32, Vec3)> = (0..16).map(|i| (i, sim.positions()[i as usize])).collect();
    sim.set_pins(all.iter().copied()).unwrap();
    let e = error(sim.set_pins(all.iter().copied().chain([(0, Vec3::ZERO)])));
    too_many(&e, "pins", 17, 16);
    // An endless list is refused, not collected.
    let e = error(sim.set_pins(std::iter::repeat((3, Vec3::ZERO))));
    too_many(&e, "pins", 17, 16);
    assert_eq!(sim.pinned().count(), 16, "the pins are as they were");
    let target = |particle| Target {
        particle,
        weight: 1.0,
        position: Vec3::ZERO,
        normal: Vec3::Y,
    };
    let targets: Vec<Target> = (0..16).map(target).collect();
    sim.set_targets(&targets).unwrap();
    let more: Vec<Target> = (0..17).map(|i| target(i % 16)).collect();
    too_many(&error(sim.set_targets(&more)), "targets", 17, 16);
}

#[test]
fn a_wind_field_may_have_max_wind_zones_and_not_one_more() {
    let zone = PlacedWindZone {
        shape: WindZoneShape::Sphere(1.0),
        to_local: default(),
        velocity: Vec3::X,
        gusts: None,
        falloff: 0.2,
    };
    let field = |zones| WindField {
        air_density: 1.2,
        zones: vec![zone; zones],
        ..default()
    };
    assert_eq!(field(MAX_WIND_ZONES).validate(), Ok(()));
    let e = error(field(MAX_WIND_ZONES + 1).validate());
    too_many(
        &e,
        "wind zones",
        MAX_WIND_ZONES as u64 + 1,
        MAX_WIND_ZONES as u64,
    );
    // A scene's zones too.
    let scene = |zones: usize| {
        let zone = "(shape: Sphere(radius: 1.0), velocity: (1.0, 0.0, 0.0)),";
        ClothScene::from_ron(&format!(
            "(cloth: Grid((nx: 4, ny: 4, spacing: 0.1)), wind: Some((zones: [{}])))",
            zone.repeat(zones)
        ))
    };
    assert!(scene(MAX_WIND_ZONES).is_ok());
    let e = error(scene(MAX_WIND_ZONES + 1));
    too_many(
        &e,
        "wind zones",
        MAX_WIND_ZONES as u64 + 1,
        MAX_WIND_ZONES as u64,
    );
}

#[test]
fn a_scene_may_pin_each_particle_once() {
    let scene = |pins: usize| {
        let list: Vec<String> = (0..pins).map(|i| (i % 4).to_string()).collect();
        ClothScene::from_ron(&format!(
            "(cloth: Grid((nx: 2, ny: 2, spacing: 0.1)), pins: [{}])",
            list.join(", ")
        ))
    };
    assert!(scene(4).is_ok());
    too_many(&error(scene(5)), "pins", 5, 4);
}

#[test]
fn a_scene_file_of_max_scene_bytes_is_read_and_a_longer_one_is_not() {
    let dir = std::env::temp_dir().join(format!("bevy_cloth_bounds_{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let scene = "(cloth: Grid((nx: 2, ny: 2, spacing: 0.1)))";
    // Padded with a comment to the length wanted.
    let write = |name: &str, bytes: usize| {
        let path = dir.join(name);
        let pad = bytes - scene.len() - 3;
        std::fs::write(&path, format!("{scene}\n//{}", " ".repeat(pad))).unwrap();
        assert_eq!(std::fs::metadata(&path).unwrap().len(), bytes as u64);
        path
    };
    let at = write("at.ron", MAX_SCENE_BYTES);
    assert!(ClothScene::load(&at).is_ok());
    let past = write("past.ron", MAX_SCENE_BYTES + 1);
    let e = error(ClothScene::load(&past));
    std::fs::remove_dir_all(&dir).unwrap();
    too_many(
        &e,
        "scene file bytes",
        MAX_SCENE_BYTES as u64 + 1,
        MAX_SCENE_BYTES as u64,
    );
}

#[test]
fn the_fixed_step_lies_between_its_bounds() {
    assert_eq!(validate_fixed_step(MIN_FIXED_STEP), Ok(()));
    assert_eq!(validate_fixed_step(MAX_FIXED_STEP), Ok(()));
    for dt in [MIN_FIXED_STEP * 0.5, MAX_FIXED_STEP * 1.5] {
        let e = error(validate_fixed_step(dt));
        assert!(
            matches!(e, ClothError::InvalidValue { field: "dt", .. }),
            "{e:?}"
        );
    }
}

#[test]
fn subdivision_levels_and_valences_have_bounds() {
    let quad = PolyMesh::from_quads(
        [DVec3::ZERO, DVec3::X, DVec3::new(1.0, 0.0, 1.0), DVec3::Z],
        &[0, 3, 2, 1],
    )
    .unwrap();
    let sub = |level| Subdivider::new(&quad, level, VertexRule::Original, BoundaryMode::EdgeOnly);
    assert!(sub(MAX_LEVEL).is_ok());
    assert_eq!(
        sub(MAX_LEVEL + 1).unwrap_err(),
        SubdivisionError::LevelTooHigh {
            level: MAX_LEVEL + 1,
            max: MAX_LEVEL
        }
    );
    assert!(eigen_report(MAX_VALENCE, VertexRule::Original).is_ok());
    assert!(matches!(
        eigen_report(MAX_VALENCE + 1, VertexRule::Original),
        Err(SubdivisionError::ValenceOutOfRange { valence, .. }) if valence == MAX_VALENCE + 1
    ));
}

#[test]
fn a_cloths_subdivision_level_is_at_most_max_cloth_subdivision_level() {
    let mut app = common::app();
    for (level, target) in [
        (MAX_CLOTH_SUBDIVISION_LEVEL, SubdivisionTarget::Render),
        (MAX_CLOTH_SUBDIVISION_LEVEL + 1, SubdivisionTarget::Render),
        (
            MAX_CLOTH_SUBDIVISION_LEVEL + 1,
            SubdivisionTarget::Simulation,
        ),
    ] {
        let e = common::spawn(
            &mut app,
            (
                Cloth::grid(GridSpec::new(3, 3, 0.1)),
                ClothSubdivision {
                    level,
                    target,
                    ..default()
                },
            ),
        );
        let invalid = app.world().get::<ClothInvalid>(e);
        if level <= MAX_CLOTH_SUBDIVISION_LEVEL {
            assert!(invalid.is_none(), "{invalid:?}");
        } else {
            let e = &invalid.expect("the level is past its bound").0;
            out_of_range(
                e,
                "subdivision.level",
                level,
                (0, MAX_CLOTH_SUBDIVISION_LEVEL),
            );
        }
    }
}
