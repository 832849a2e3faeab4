//! Tests of the limits.

use super::*;
use crate::sim::model::{ClothModel, GridPlane, GridSpec};

#[test]
fn geodesic_distances_run_straight_across_a_flat_cloth_to_the_nearest_pin() {
    // A 5×4 grid of 0.1 m spacing pinned at its two top corners: each particle is tied to
    // the corner on its side, at the straight line's length (a path along the edges would
    // be up to 8% longer).
    let spec = GridSpec::new(5, 4, 0.1).with_plane(GridPlane::Vertical);
    let model = ClothModel::grid(&spec).unwrap();
    let rest = &model.rest_positions;
    let n = model.particle_count();
    let top = rest.iter().map(|q| q.y).fold(f32::MIN, f32::max);
    let corners: Vec<usize> = (0..n)
        .filter(|&i| rest[i].y == top && (i % 5 == 0 || i % 5 == 4))
        .collect();
    assert_eq!(corners.len(), 2);
    let mut pinned = vec![false; n];
    for &c in &corners {
        pinned[c] = true;
    }
    let (nearest, distance) = geodesic_to_nearest(&model.triangles, rest, &pinned);
    for i in 0..n {
        let a = nearest[i] as usize;
        assert!(corners.contains(&a), "particle {i} tied to {a}");
        if i % 5 != 2 {
            assert_eq!(
                a.is_multiple_of(5),
                i % 5 < 2,
                "particle {i} tied to the far corner {a}"
            );
        }
        let straight = rest[i].distance(rest[a]);
        assert!(
            (distance[i] - straight).abs() <= 1e-6 * straight.max(1.0),
            "particle {i}: {} against the straight line {straight}",
            distance[i]
        );
    }
    // Nothing pinned: no anchor anywhere.
    let (nearest, _) = geodesic_to_nearest(&model.triangles, rest, &vec![false; n]);
    assert!(nearest.iter().all(|&a| a == u32::MAX));
}

#[test]
fn geodesic_distances_follow_a_curved_cloth() {
    // A 24×6 grid of 0.1 m spacing rolled into half a cylinder around its columns, pinned at
    // one corner: unrolled, the cloth is flat, so each particle's geodesic is the straight
    // line of the flat grid. Straight lines through the air (the chord) would be up to a
    // third shorter across the roll, paths along the edges up to 8% longer.
    let (nx, ny, h) = (24, 6, 0.1);
    let spec = GridSpec::new(nx, ny, h).with_plane(GridPlane::Vertical);
    let model = ClothModel::grid(&spec).unwrap();
    let radius = (nx - 1) as f32 * h / std::f32::consts::PI;
    let flat = |p: u32| Vec3::new((p % nx) as f32 * h, (p / nx) as f32 * h, 0.0);
    let rest: Vec<Vec3> = (0..nx * ny)
        .map(|p| {
            let f = flat(p);
            let angle = f.x / radius;
            Vec3::new(radius * angle.sin(), f.y, radius * (1.0 - angle.cos()))
        })
        .collect();
    let mut pinned = vec![false; rest.len()];
    pinned[0] = true;
    let (nearest, distance) = geodesic_to_nearest(&model.triangles, &rest, &pinned);
    let mut shortest_chord: f32 = 1.0;
    for p in 1..nx * ny {
        let i = p as usize;
        assert_eq!(nearest[i], 0);
        let geodesic = flat(p).distance(flat(0));
        // The roll turns the normals by 7.8° a column, so the straight stretches bend at
        // particles, a little off the geodesic.
        assert!(
            (0.99 * geodesic..=1.04 * geodesic).contains(&distance[i]),
            "particle {p}: {} against the geodesic {geodesic}",
            distance[i]
        );
        assert!(distance[i] >= rest[i].distance(rest[0]) * (1.0 - 1e-6));
        shortest_chord = shortest_chord.min(rest[i].distance(rest[0]) / geodesic);
    }
    assert!(
        shortest_chord < 0.7,
        "the roll's chords are {shortest_chord} of its arcs"
    );
}

#[test]
fn a_batch_of_targets_moves_each_particle_as_one_target_alone_does() {
    use crate::hash::mix64;
    use crate::sim::contact::vectors::Vectors;
    // Particles scattered about their targets, some far out of reach, some on them, some at a
    // backstop's centre; targets that move and turn, or not, in some coordinates only; normals
    // of every length, zero among them; pinned particles; more targets than a whole batch.
    let n = 150;
    let mut seed = 7u64;
    let mut r = || {
        seed = mix64(seed);
        (seed >> 40) as f32 / (1u64 << 24) as f32 * 2.0 - 1.0
    };
    let mut vec = |scale: f32| Vec3::new(r(), r(), r()) * scale;
    let from: Vec<Vec3> = (0..n).map(|_| vec(2.0)).collect();
    let to: Vec<Vec3> = (0..n)
        .map(|k| match k % 4 {
            0 => from[k],
            1 => Vec3::new(from[k].x, from[k].y + 0.01, from[k].z),
            _ => from[k] + vec(0.05),
        })
        .collect();
    let normal = |k: usize, v: Vec3| match k % 5 {
        0 => Vec3::ZERO,
        1 => v * 1e-20,
        _ => v,
    };
    let normal_from: Vec<Vec3> = (0..n).map(|k| normal(k, vec(1.0))).collect();
    let normal_to: Vec<Vec3> = (0..n).map(|k| normal(k / 2, vec(1.5))).collect();
    // The backstop's centre within the maximum distance of a target of weight 1.
    let settings = TargetLimits {
        max_distance_scale: 0.3,
        backstop_radius: 0.6,
        backstop_offset: -0.5,
    };
    let times = (0.1, 0.3, 40.0);
    let mut x: Vec<Vec3> = (0..n).map(|k| to[k] + vec(0.8)).collect();
    // On its target, and at its backstop's centre.
    x[12] = between(from[12], to[12], times.1);
    let unit = normal_from[19].lerp(normal_to[19], times.1).normalize();
    let depth = settings.backstop_radius + settings.backstop_offset;
    x[19] = between(from[19], to[19], times.1) - unit * depth;
    let v: Vec<Vec3> = (0..n).map(|_| vec(3.0)).collect();
    let inv_mass: Vec<f32> = (0..n).map(|k| if k % 9 == 4 { 0.0 } else { 2.0 }).collect();
    // The targets in another order than the particles.
    let targets: Vec<Moving> = (0..n)
        .map(|k| {
            let p = (k * 37) % n;
            Moving {
                particle: p as u32,
                weight: match p % 6 {
                    0 => 0.0,
                    1 => 1.0,
                    _ => (r() + 1.0) * 0.5,
                },
                from: from[p],
                to: to[p],
                normal_from: normal_from[p],
                normal_to: normal_to[p],
            }
        })
        .collect();
    let bits = |a: &[Vec3]| -> Vec<[u32; 3]> {
        a.iter().map(|p| p.to_array().map(f32::to_bits)).collect()
    };
    for backstop in [settings.backstop_radius, 0.0] {
        let s = TargetLimits {
            backstop_radius: backstop,
            ..settings
        };
        let (mut xa, mut va, mut xb, mut vb) = (x.clone(), v.clone(), x.clone(), v.clone());
        let state = |x, v| Vectors {
            x,
            v,
            start: &[],
            inv_mass: &inv_mass,
            touches: None,
        };
        resolve_targets(&targets, s, times, &mut state(&mut xa, &mut va));
        let mut one = state(&mut xb, &mut vb);
        for t in &targets {
            resolve_target(t, s, times, &mut one);
        }
        let moved = (0..n).filter(|&k| xa[k] != x[k]).count();
        assert!(moved > n / 4, "{moved} of {n} particles moved");
        assert_eq!(bits(&xa), bits(&xb), "positions, backstop {backstop}");
        assert_eq!(bits(&va), bits(&vb), "velocities, backstop {backstop}");
    }
}

#[test]
fn a_particle_with_two_targets_takes_them_one_after_the_other() {
    use crate::sim::contact::vectors::Vectors;
    // Particle 1 has two targets on either side of it, each with a reach too short for where it
    // is: the second target must pull it from where the first left it, not from where it was.
    let mut limits = Limits::default();
    limits.set_settings(TargetLimits {
        max_distance_scale: 1.0,
        backstop_radius: 0.0,
        backstop_offset: 0.0,
    });
    let target = |particle, x: f32| Target {
        particle,
        weight: 0.3,
        position: Vec3::new(x, 0.0, 0.0),
        normal: Vec3::Y,
    };
    limits.set_targets([target(0, 0.0), target(1, -1.0), target(1, 1.0)]);
    let (mut x, mut v) = (
        vec![Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0)],
        vec![Vec3::ZERO; 2],
    );
    let mut state = Vectors {
        x: &mut x,
        v: &mut v,
        start: &[],
        inv_mass: &[1.0, 1.0],
        touches: None,
    };
    limits.resolve((0.0, 1.0, 0.01), &mut state);
    // Onto the first target's sphere (towards (-1, 0, 0)), then onto the second's from there.
    let first = Vec3::new(-1.0, 0.0, 0.0) + Vec3::new(1.0, 1.0, 0.0).normalize() * 0.3;
    let second = Vec3::X + (first - Vec3::X).normalize() * 0.3;
    assert!(x[1].distance(second) < 1e-6, "{} against {second}", x[1]);
}
