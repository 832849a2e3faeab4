//! App frames of a 64×64 cloth (1 m, 20 substeps) lying draped over a ball in an app with
//! avian's physics (feature `avian`): the ball as a native `ClothCollider` and as an avian
//! collider, and the avian ball with 100 more avian colliders out of the cloth's reach, so the
//! cost of going through avian's colliders can be read as ratios from one run. For scale, the
//! native ball in an app without avian. Then the same cloth lying on a floor: a native
//! half-space against an avian triangle mesh (200 triangles, queried through parry).
//!
//! `cargo bench --features avian --bench avian`

use avian3d::prelude::{Collider, PhysicsPlugins, RigidBody};
use bevy::app::App;
use bevy::prelude::{Transform, Vec3, default};
use bevy_cloth::avian::ClothAvianPlugin;
use bevy_cloth::prelude::{Cloth, ClothCollider, ClothConfig};
use bevy_cloth::sim::{GridSpec, SolverSettings};
use criterion::{Criterion, criterion_group, criterion_main};

/// Where the ball stands, and its radius.
const BALL: (Vec3, f32) = (Vec3::ZERO, 0.3);

/// An app with the cloth draped over the ball that `spawn` adds (and whatever else it adds),
/// stepped until it lies on it.
fn draped(with_avian: bool, spawn: impl FnOnce(&mut App)) -> App {
    let mut app = if with_avian {
        bevy_cloth::harness::try_headless_app_with(
            1.0 / 60.0,
            (PhysicsPlugins::default(), ClothAvianPlugin),
        )
        .unwrap()
    } else {
        bevy_cloth::harness::headless_app(1.0 / 60.0)
    };
    spawn(&mut app);
    app.world_mut().spawn((
        Cloth::grid(GridSpec::new(64, 64, 1.0 / 63.0)),
        ClothConfig {
            // Never asleep: every frame steps the cloth against the ball.
            solver: SolverSettings {
                sleep_speed: 0.0,
                damping: 0.5,
                ..default()
            },
            ..default()
        },
        Transform::from_xyz(0.0, 0.45, 0.0),
    ));
    for _ in 0..60 {
        app.update();
    }
    app
}

fn native_ball(app: &mut App) {
    app.world_mut().spawn((
        ClothCollider::sphere(BALL.1),
        Transform::from_translation(BALL.0),
    ));
}

fn avian_ball(app: &mut App) {
    app.world_mut().spawn((
        RigidBody::Static,
        Collider::sphere(BALL.1),
        Transform::from_translation(BALL.0),
    ));
}

/// A case: its name, whether the app has avian, and what it spawns.
type Case = (&'static str, bool, fn(&mut App));

/// A flat 2 m square floor at y = 0 as a triangle mesh of 11 × 11 vertices (200 triangles).
fn floor_mesh() -> Collider {
    let (vertices, triangles) = bevy_cloth::harness::heightfield_mesh(11, 2.0, |_, _| 0.0);
    Collider::trimesh(vertices, triangles)
}

fn avian_frames(c: &mut Criterion) {
    let mut group = c.benchmark_group("avian_frame_64x64");
    let cases: [Case; 6] = [
        ("native_ball_without_avian", false, native_ball),
        ("native_ball", true, native_ball),
        ("avian_ball", true, avian_ball),
        ("avian_ball_and_100_far", true, |app| {
            avian_ball(app);
            // A 10 × 10 field of boxes and balls 20 m away: static, never in reach.
            for k in 0..100 {
                let at = Vec3::new(20.0 + (k % 10) as f32, 0.0, (k / 10) as f32);
                let collider = if k % 2 == 0 {
                    Collider::sphere(0.3)
                } else {
                    Collider::cuboid(0.5, 0.5, 0.5)
                };
                app.world_mut().spawn((
                    RigidBody::Static,
                    collider,
                    Transform::from_translation(at),
                ));
            }
        }),
        ("native_floor", true, |app| {
            app.world_mut()
                .spawn((ClothCollider::half_space(Vec3::Y), Transform::default()));
        }),
        ("avian_trimesh_floor", true, |app| {
            app.world_mut().spawn((RigidBody::Static, floor_mesh()));
        }),
    ];
    for (name, with_avian, spawn) in cases {
        let mut app = draped(with_avian, spawn);
        group.bench_function(name, |b| b.iter(|| app.update()));
    }
    group.finish();
}

criterion_group!(benches, avian_frames);
criterion_main!(benches);
