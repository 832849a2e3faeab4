//! Collider contacts' tests, by what they test: the shapes' queries, the narrow phase and
//! response, the broad phase and catch-up, and the vector passes.

use super::narrow::closest_point_on_triangle;
use super::*;
use crate::sim::simd::Build;
use bevy::math::Dir3;
use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use glam::{Quat, Vec3A};

mod broad_phase;
mod colliders;
mod shapes;
mod simd_passes;

fn shapes() -> [ColliderShape; 4] {
    [
        ColliderShape::Sphere(Sphere::new(0.5)),
        ColliderShape::Capsule(Capsule3d::new(0.3, 1.0)),
        ColliderShape::Cuboid(Cuboid::new(1.0, 0.4, 0.6)),
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::new(0.0, 1.0, 1.0))),
    ]
}

fn active(collider: Collider, dt: f32, max_edge: f32) -> Contacts {
    let mut contacts = Contacts::new(1, (max_edge, 0.0));
    contacts.begin_step(
        &[collider],
        (u32::MAX, true),
        (Vec3::ZERO, Vec3::ZERO),
        10.0,
        dt,
    );
    contacts
}

/// Reproducible draws uniform in `[lo, hi)` (xorshift from `seed`, which must not be 0).
fn uniform_draws(mut seed: u64) -> impl FnMut(f32, f32) -> f32 {
    move |lo, hi| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        lo + (hi - lo) * (seed >> 40) as f32 / (1u64 << 24) as f32
    }
}
