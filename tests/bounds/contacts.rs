//! The bounds of contacts between layers: the self-collision thickness against the cloth's mean
//! rest edge length (when the cloth is built and when its settings change), the pairs within it
//! at rest, and the distance kept from another cloth.

use std::time::Instant;

use bevy::prelude::*;
use bevy_cloth::ClothError;
use bevy_cloth::sim::{
    ClothModel, ClothSim, Environment, GridSpec, MAX_THICKNESS_PER_EDGE, OtherCloth, SelfCollision,
    SolverSettings,
};

use super::{error, names};

/// The cloth of the case that took 2.1 GB and 38 s before the bound: 64 × 64, 1.6 cm spacing.
fn grid64() -> ClothModel {
    ClothModel::grid(&GridSpec::new(64, 64, 0.016)).unwrap()
}

/// Default settings with self-collision on (`enabled`) at `thickness`.
fn layers(enabled: bool, thickness: f32) -> SolverSettings {
    SolverSettings {
        self_collision: SelfCollision {
            enabled,
            thickness,
            ..default()
        },
        ..default()
    }
}

/// A `ClothError::TooLong` on `field` at `value`, bound `bound`.
fn too_thick(e: &ClothError, field: &str, value: f32, bound: f32) {
    assert!(
        matches!(e, ClothError::TooLong { field: f, value: v, bound: b, .. }
            if *f == field && *v == value && *b == bound),
        "{e:?}"
    );
    names(
        e,
        &[
            field,
            &value.to_string(),
            &bound.to_string(),
            "MAX_THICKNESS_PER_EDGE",
        ],
    );
}

#[test]
fn a_thickness_of_the_mean_edge_is_accepted_and_more_is_not() {
    let model = grid64();
    let bound = MAX_THICKNESS_PER_EDGE * model.mean_edge_length();
    // A grid's triangles have two sides and a diagonal.
    let expected = 0.016 * (2.0 + 2f32.sqrt()) / 3.0;
    assert!((model.mean_edge_length() - expected).abs() < 1e-6);
    let sim = ClothSim::new(model.clone(), layers(true, bound), |p| p).unwrap();
    assert_eq!(sim.settings().self_collision.thickness, bound);
    let past = bound * 1.01;
    let e = error(ClothSim::new(model, layers(true, past), |p| p));
    too_thick(&e, "self_collision.thickness", past, bound);
}

#[test]
fn a_thickness_of_five_metres_is_refused_at_once() {
    let model = grid64();
    let bound = MAX_THICKNESS_PER_EDGE * model.mean_edge_length();
    let start = Instant::now();
    let e = error(ClothSim::new(model.clone(), layers(true, 5.0), |p| p));
    let took = start.elapsed();
    eprintln!("a thickness of 5 m was refused in {took:?}");
    assert!(took.as_secs_f64() < 1.0, "{took:?}");
    too_thick(&e, "self_collision.thickness", 5.0, bound);
    // With self-collision off the cloth has no self-contacts to bound.
    assert!(ClothSim::new(model, layers(false, 5.0), |p| p).is_ok());
}

#[test]
fn set_settings_checks_the_thickness_against_the_cloth_and_changes_nothing_on_an_error() {
    let model = grid64();
    let bound = MAX_THICKNESS_PER_EDGE * model.mean_edge_length();
    let mut sim = ClothSim::new(model, layers(false, 5.0), |p| p).unwrap();
    let e = error(sim.set_settings(layers(true, 5.0)));
    too_thick(&e, "self_collision.thickness", 5.0, bound);
    assert_eq!(sim.settings(), &layers(false, 5.0));
    sim.set_settings(layers(true, bound)).unwrap();
    assert_eq!(sim.settings(), &layers(true, bound));
    sim.step(1.0 / 60.0).unwrap();
}

/// A cloth whose rest shape lies in `count` layers 0.2 mm apart, each a 3 × 3 grid of 1 cm.
fn stacked(count: u32) -> ClothModel {
    let layer = ClothModel::grid(&GridSpec::new(3, 3, 0.01)).unwrap();
    let n = layer.particle_count() as u32;
    let positions: Vec<Vec3> = (0..count)
        .flat_map(|k| {
            let lift = Vec3::Y * 0.0002 * k as f32;
            layer.rest_positions.iter().map(move |p| *p + lift)
        })
        .collect();
    let triangles: Vec<u32> = (0..count)
        .flat_map(|k| layer.triangles.iter().map(move |&t| t + k * n))
        .collect();
    ClothModel::from_mesh(&positions, None, &triangles, 3).unwrap()
}

#[test]
fn a_rest_shape_in_layers_closer_than_the_thickness_is_refused_not_stored() {
    // One layer at the largest thickness its edges allow: nothing in it is within the thickness
    // of a part it does not touch beyond what a flat cloth has.
    let one = stacked(1);
    let thickness = MAX_THICKNESS_PER_EDGE * one.mean_edge_length();
    assert!(ClothSim::new(one, layers(true, thickness), |p| p).is_ok());
    // Fifty layers within the thickness: every vertex is that close to every layer's triangles.
    let many = stacked(50);
    assert!(thickness <= MAX_THICKNESS_PER_EDGE * many.mean_edge_length());
    let bound = 32 * many.triangles.len() as u64 / 3;
    let e = error(ClothSim::new(many, layers(true, thickness), |p| p));
    assert!(
        matches!(&e, ClothError::TooMany { field, count, bound: b, .. }
            if *field == "pairs within self_collision.thickness at rest" && *count > bound
                && *b == bound),
        "{e:?}"
    );
    names(
        &e,
        &[
            "self_collision.thickness",
            &bound.to_string(),
            "MAX_EXEMPT_PAIRS_PER_TRIANGLE",
        ],
    );
}

#[test]
fn the_distance_kept_from_another_cloth_is_clamped_to_the_cloths_edges() {
    let model = ClothModel::grid(&GridSpec::new(16, 16, 0.02)).unwrap();
    let bound = MAX_THICKNESS_PER_EDGE * model.mean_edge_length();
    // Another cloth 1 cm above this one, within any of the distances below.
    let above: Vec<Vec3> = model
        .rest_positions
        .iter()
        .map(|p| *p + Vec3::Y * 0.01)
        .collect();
    let step = |thickness: f32| {
        let mut sim = ClothSim::new(model.clone(), layers(false, 0.005), |p| p).unwrap();
        let others = [OtherCloth {
            triangles: &model.triangles,
            start: &above,
            end: &above,
            thickness,
            friction: 0.3,
        }];
        let env = Environment {
            cloths: &others,
            ..default()
        };
        sim.step_in(1.0 / 60.0, &env).unwrap();
        // How far below the other cloth this one ends up.
        let lowest = sim.positions().iter().map(|p| p.y).fold(f32::MAX, f32::min);
        0.01 - lowest
    };
    // The pair keeps the mean of the two thicknesses up to the bound: at the bound, and far
    // past it (5 m asked for), the cloth is pushed the bound away, never farther.
    let at = step(2.0 * bound - 0.005);
    let past = step(5.0);
    assert!(
        at >= 0.9 * bound && at < 1.5 * bound,
        "{at} for a bound of {bound}"
    );
    assert!((past - at).abs() < 1e-4 * bound.max(1.0), "{past} vs {at}");
}
