//! Tests of the force model through [`add_aero_forces`]: the plate's drag and lift against their
//! closed forms, and what a triangle list adds to its vertices.

use super::triangles::triangle_force;
use super::*;
use glam::Vec3;
use std::f32::consts::FRAC_1_SQRT_2;

/// `|a − b| ≤ tol · max(1, |b|)`.
fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).length() <= tol * b.length().max(1.0)
}

/// Forces on a mesh with still vertices in a uniform wind.
fn forces_in_wind(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    wind: Vec3,
    params: &AeroParams,
) -> Vec<Vec3> {
    let velocities = vec![Vec3::ZERO; positions.len()];
    let winds = vec![wind; triangles.len()];
    let mut forces = vec![Vec3::ZERO; positions.len()];
    add_aero_forces(
        positions,
        &velocities,
        triangles,
        &winds,
        params,
        &mut forces,
    );
    forces
}

fn total(forces: &[Vec3]) -> Vec3 {
    forces.iter().copied().sum()
}

/// A generic tilted triangle.
const TILTED: [Vec3; 3] = [
    Vec3::new(0.1, -0.2, 0.3),
    Vec3::new(1.3, 0.4, -0.2),
    Vec3::new(-0.3, 0.9, 0.8),
];

#[test]
fn zero_relative_velocity_gives_exactly_zero_force() {
    let v = Vec3::new(1.3, -0.7, 2.1);
    let mut forces = vec![Vec3::ZERO; 3];
    add_aero_forces(
        &TILTED,
        &[v; 3],
        &[[0, 1, 2]],
        &[v],
        &AeroParams::default(),
        &mut forces,
    );
    assert!(forces.iter().all(|&f| f == Vec3::ZERO), "{forces:?}");
}

#[test]
fn force_scales_with_relative_speed_squared() {
    let dir = Vec3::new(0.6, 0.48, -0.64);
    let params = AeroParams::default();
    let f10 = total(&forces_in_wind(&TILTED, &[[0, 1, 2]], 10.0 * dir, &params));
    let f5 = total(&forces_in_wind(&TILTED, &[[0, 1, 2]], 5.0 * dir, &params));
    assert!(f5.length() > 0.0);
    assert!((f10.length() / f5.length() - 4.0).abs() < 1e-4);
    assert!(close(f10, 4.0 * f5, 1e-5), "same direction");
}

#[test]
fn plate_facing_wind_gets_pure_drag() {
    // Right triangle in the yz plane with legs 2 m and 3 m: area 3 m².
    let plate = [
        Vec3::ZERO,
        Vec3::new(0.0, 2.0, 0.0),
        Vec3::new(0.0, 0.0, 3.0),
    ];
    let params = AeroParams::default();
    let speed = 8.0;
    let f = total(&forces_in_wind(
        &plate,
        &[[0, 1, 2]],
        speed * Vec3::X,
        &params,
    ));
    let expected = 0.5 * params.air_density * params.drag * 3.0 * speed * speed;
    assert!(
        (f.x - expected).abs() < 1e-5 * expected,
        "{f} vs {expected}"
    );
    assert_eq!((f.y, f.z), (0.0, 0.0), "no lift");
}

#[test]
fn edge_on_plate_gets_zero_force() {
    // Plate in the xy plane (normal z), wind along x.
    let plate = [
        Vec3::ZERO,
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.5, 1.0, 0.0),
    ];
    let forces = forces_in_wind(&plate, &[[0, 1, 2]], 12.0 * Vec3::X, &AeroParams::default());
    assert!(forces.iter().all(|&f| f == Vec3::ZERO), "{forces:?}");
}

#[test]
fn flipping_triangle_winding_leaves_forces_unchanged() {
    let positions = [
        Vec3::new(0.0, 0.0, 0.0),
        Vec3::new(1.0, 0.1, 0.0),
        Vec3::new(0.0, 0.2, 1.0),
        Vec3::new(1.1, 0.5, 1.2),
    ];
    let velocities = [
        Vec3::new(0.1, 0.0, -0.2),
        Vec3::new(-0.3, 0.4, 0.0),
        Vec3::new(0.0, 0.2, 0.5),
        Vec3::new(0.2, -0.1, 0.1),
    ];
    let winds = [Vec3::new(4.0, 1.0, 2.0), Vec3::new(3.0, -2.0, 1.5)];
    let run = |triangles: &[[u32; 3]]| {
        let mut forces = [Vec3::ZERO; 4];
        let params = AeroParams::default();
        add_aero_forces(
            &positions,
            &velocities,
            triangles,
            &winds,
            &params,
            &mut forces,
        );
        forces
    };
    let original = run(&[[0, 1, 2], [1, 3, 2]]);
    let flipped = run(&[[0, 2, 1], [1, 2, 3]]);
    assert!(original.iter().any(|f| f.length() > 1.0));
    for (a, b) in original.iter().zip(&flipped) {
        assert!(close(*b, *a, 1e-6), "{a} vs {b}");
    }
}

#[test]
fn plate_at_45_degrees_gets_lift_perpendicular_to_wind_upward_for_a_kite() {
    let params = AeroParams {
        drag: 0.0,
        ..AeroParams::default()
    };
    let speed = 10.0;
    let wind = speed * Vec3::X;
    // Kite: leading (upwind) edge up, plate running down-wind along (1, −1, 0); area √2/2 m².
    let kite = [Vec3::ZERO, Vec3::new(1.0, -1.0, 0.0), Vec3::Z];
    // Ramp: leading edge down, plate rising down-wind along (1, 1, 0).
    let ramp = [Vec3::ZERO, Vec3::new(1.0, 1.0, 0.0), Vec3::Z];
    let area = 0.5 * std::f32::consts::SQRT_2;
    let lift = 0.5 * params.air_density * params.lift * area * speed * speed * 0.5;

    let f = total(&forces_in_wind(&kite, &[[0, 1, 2]], wind, &params));
    assert!(
        f.dot(Vec3::X).abs() < 1e-5 * lift,
        "perpendicular to the wind: {f}"
    );
    assert!(
        close(f, lift * Vec3::Y, 1e-5),
        "kite lifted up: {f} vs {lift}"
    );

    let f = total(&forces_in_wind(&ramp, &[[0, 1, 2]], wind, &params));
    assert!(
        close(f, -lift * Vec3::Y, 1e-5),
        "ramp pushed down: {f} vs {lift}"
    );

    // With drag on, the along-wind part is the drag on the projected area.
    let params = AeroParams::default();
    let f = total(&forces_in_wind(&kite, &[[0, 1, 2]], wind, &params));
    let drag = 0.5 * params.air_density * params.drag * area * speed * speed * FRAC_1_SQRT_2;
    let lift = 0.5 * params.air_density * params.lift * area * speed * speed * 0.5;
    assert!(close(f, Vec3::new(drag, lift, 0.0), 1e-5), "{f}");
}

#[test]
fn vertex_forces_sum_to_triangle_force() {
    let velocities = [
        Vec3::new(0.2, 0.0, 0.1),
        Vec3::ZERO,
        Vec3::new(-0.1, 0.3, 0.0),
    ];
    let wind = Vec3::new(5.0, 2.0, -3.0);
    let params = AeroParams::default();
    let expected = triangle_force(TILTED, velocities, wind, &params, 1.0);
    let mut forces = [Vec3::splat(1.0); 3];
    add_aero_forces(
        &TILTED,
        &velocities,
        &[[0, 1, 2]],
        &[wind],
        &params,
        &mut forces,
    );
    assert!(expected.length() > 1.0);
    for f in forces {
        assert!(
            close(f - Vec3::ONE, expected / 3.0, 1e-6),
            "a third each, added"
        );
    }
    assert!(close(total(&forces) - Vec3::splat(3.0), expected, 1e-6));
}

#[test]
fn degenerate_triangle_gets_zero_force() {
    let line = [Vec3::ZERO, Vec3::X, 2.0 * Vec3::X];
    let forces = forces_in_wind(
        &line,
        &[[0, 1, 2]],
        Vec3::new(3.0, 4.0, 5.0),
        &AeroParams::default(),
    );
    assert!(forces.iter().all(|&f| f == Vec3::ZERO));
}

#[test]
fn triangle_centroids_are_vertex_means() {
    let mut out = [Vec3::ZERO; 2];
    triangle_centroids(
        &[
            Vec3::ZERO,
            Vec3::new(3.0, 0.0, 0.0),
            Vec3::new(0.0, 3.0, 0.0),
            Vec3::new(0.0, 0.0, 6.0),
        ],
        &[[0, 1, 2], [1, 2, 3]],
        &mut out,
    );
    assert_eq!(out, [Vec3::new(1.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 2.0)]);
}
