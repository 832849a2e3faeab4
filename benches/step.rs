//! Time per simulated 1/60 s frame of the canonical grid cloth at 20 substeps (XPBD, one
//! iteration), on one thread and (64×64 and larger) on two: the solver alone, without ECS
//! overhead, with the throughput in constraint solves (springs × substeps) per second; 128×128
//! also at 10 substeps. The explicit
//! integrators (Verlet, symplectic Euler) on the same cloths at their stable substeps. Then the same
//! 64×64 frame among colliders (none, a sphere it drapes over, 100 far away) and in wind, and
//! whole App frames with one active cloth against 100 sleeping ones. Then self-collision's cost:
//! a hanging 64×64 cloth swinging (also its first second replayed frame for frame) and settled,
//! a flag flapping in wind, and one lying crumpled on a floor, each with it off and on. Then
//! character cloth: App frames of a 32×32 cape skinned to a walking, turning torso against the
//! same cape on static pins, and tethers' cost in a step. And tolerance mode on the 64×64 frame
//! with a sphere and wind against the fixed setting it settles on. Last, cloth–cloth contacts:
//! a 32×32 cloth's step lying on another, alone, and with the other out of reach.

use std::hint::black_box;
use std::time::{Duration, Instant};

use bevy::math::Vec3;
use bevy::math::primitives::{InfinitePlane3d, Sphere};
use bevy::prelude::{Quat, Transform, default};
use bevy::tasks::TaskPoolBuilder;
use bevy_cloth::harness::character::{Cape, spawn_cape, torso_pose};
use bevy_cloth::prelude::{Cloth, ClothConfig, ClothPins, ClothState};
use bevy_cloth::sim::{
    Accuracy, ClothModel, ClothSim, Collider, ColliderShape, Environment, Friction, GridNormals,
    GridPlane, GridSpec, Gusts, Integrator, OtherCloth, Pose, ScopedThread, SelfCollision,
    SolverSettings, Spread, Tethers, WindField, compute_normals,
};
use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};

/// A 1 m cloth of `n`×`n` particles hanging from two corners, a little into its swing.
fn hanging(n: u32) -> ClothSim {
    hanging_with(n, 20)
}

fn hanging_with(n: u32, substeps: u32) -> ClothSim {
    hanging_integrated(n, substeps, Integrator::Xpbd)
}

fn hanging_integrated(n: u32, substeps: u32, integrator: Integrator) -> ClothSim {
    let model = ClothModel::grid(&GridSpec::new(n, n, 1.0 / (n - 1) as f32)).unwrap();
    let settings = SolverSettings {
        integrator,
        substeps,
        iterations: 1,
        // Never asleep: these benchmarks time steps.
        sleep_speed: 0.0,
        ..Default::default()
    };
    let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
    let (a, b) = (sim.positions()[0], sim.positions()[n as usize - 1]);
    sim.set_pins([(0, a), (n - 1, b)]).unwrap();
    // Start from a moving, stretched state rather than rest.
    for _ in 0..30 {
        sim.step(1.0 / 60.0).unwrap();
    }
    sim
}

fn step(c: &mut Criterion) {
    for (substeps, sizes) in [(20, &[32u32, 64, 128][..]), (10, &[128][..])] {
        let mut group = c.benchmark_group(format!("xpbd_frame_{substeps}_substeps"));
        for &n in sizes {
            let mut sim = hanging_with(n, substeps);
            group.throughput(Throughput::Elements(
                sim.model().springs.len() as u64 * substeps as u64,
            ));
            group.bench_with_input(
                BenchmarkId::from_parameter(format!("{n}x{n}")),
                &n,
                |b, _| b.iter(|| sim.step(black_box(1.0 / 60.0)).unwrap()),
            );
            if n < 64 {
                continue;
            }
            // The same frame with a second thread projecting half of each colour: lent by a
            // Bevy task pool of one thread (kept between frames), and started per frame.
            let pool = TaskPoolBuilder::new().num_threads(1).build();
            let env = Environment::default();
            let spreads: [(&str, &dyn Spread); 2] = [("pool", &pool), ("scoped", &ScopedThread)];
            for (name, spread) in spreads {
                let mut sim = hanging_with(n, substeps);
                group.bench_with_input(
                    BenchmarkId::from_parameter(format!("{n}x{n}_two_threads_{name}")),
                    &n,
                    |b, _| {
                        b.iter(|| {
                            sim.step_in_parallel(black_box(1.0 / 60.0), &env, spread)
                                .unwrap()
                        })
                    },
                );
            }
        }
        group.finish();
    }
}

/// The explicit integrators on the same cloths, at the substeps their stability bound asks for
/// (`auto_substeps`), with the throughput in spring force evaluations per second.
fn explicit(c: &mut Criterion) {
    let mut group = c.benchmark_group("explicit_frame_auto_substeps");
    for integrator in [Integrator::Verlet, Integrator::SymplecticEuler] {
        for n in [16u32, 64] {
            let mut sim = hanging_integrated(n, 1, integrator);
            let substeps = sim.substeps_for(1.0 / 60.0);
            group.throughput(Throughput::Elements(
                sim.model().springs.len() as u64 * substeps as u64,
            ));
            group.bench_function(format!("{integrator:?}_{n}x{n}_{substeps}_substeps"), |b| {
                b.iter(|| sim.step(black_box(1.0 / 60.0)).unwrap())
            });
        }
    }
    group.finish();
}

/// Implicit Euler on the hanging cloth: one and four substeps a frame, at most 20 conjugate-
/// gradient iterations each.
fn implicit(c: &mut Criterion) {
    let mut group = c.benchmark_group("implicit_frame");
    for substeps in [1u32, 4] {
        let mut sim = hanging_integrated(64, substeps, Integrator::ImplicitEuler);
        sim.set_settings(SolverSettings {
            iterations: 20,
            ..*sim.settings()
        })
        .unwrap();
        group.throughput(Throughput::Elements(
            sim.model().springs.len() as u64 * substeps as u64,
        ));
        group.bench_function(format!("64x64_{substeps}_substeps"), |b| {
            b.iter(|| sim.step(black_box(1.0 / 60.0)).unwrap())
        });
    }
    group.finish();
}

fn sphere_at(centre: Vec3) -> Collider {
    Collider::fixed(
        ColliderShape::Sphere(Sphere::new(0.3)),
        Pose::from_translation(centre),
        Friction::default(),
        0.01,
    )
}

fn environment(c: &mut Criterion) {
    let n = 64;
    let mut group = c.benchmark_group("xpbd_64x64_frame_environment");
    group.throughput(Throughput::Elements((n * n) as u64));
    // Under the sagging middle of the cloth, so that it drapes over the sphere.
    let touching = [sphere_at(Vec3::new(0.0, -0.4, 0.0))];
    let far: Vec<Collider> = (0..100)
        .map(|k| sphere_at(Vec3::new(50.0 + k as f32, 0.0, 0.0)))
        .collect();
    let wind = WindField {
        velocity: Vec3::new(5.0, 0.0, 2.0),
        air_density: 1.225,
        ..Default::default()
    };
    // The same wind gusting (`Gusts::default()`): sampled at every triangle once a step.
    let gusty = WindField {
        gusts: Some(Gusts::default()),
        ..wind.clone()
    };
    let cases: [(&str, Environment); 6] = [
        ("nothing", Environment::default()),
        (
            "one_sphere",
            Environment {
                colliders: &touching,
                ..Default::default()
            },
        ),
        (
            "100_far_spheres",
            Environment {
                colliders: &far,
                ..Default::default()
            },
        ),
        (
            "wind",
            Environment {
                wind: Some(&wind),
                ..Default::default()
            },
        ),
        (
            "gusty_wind",
            Environment {
                wind: Some(&gusty),
                ..Default::default()
            },
        ),
        (
            "sphere_and_wind",
            Environment {
                colliders: &touching,
                wind: Some(&wind),
                ..Default::default()
            },
        ),
    ];
    // The contacts and the wind stay on the step's thread; the colours and the particle passes
    // are shared with a pool thread.
    let pool = TaskPoolBuilder::new().num_threads(1).build();
    for (name, env) in cases {
        let mut sim = hanging(n);
        group.bench_function(name, |b| {
            b.iter(|| sim.step_in(black_box(1.0 / 60.0), &env).unwrap())
        });
        if matches!(name, "nothing" | "sphere_and_wind") {
            let mut sim = hanging(n);
            group.bench_function(format!("{name}_two_threads"), |b| {
                b.iter(|| {
                    sim.step_in_parallel(black_box(1.0 / 60.0), &env, &pool)
                        .unwrap()
                })
            });
        }
    }
    group.finish();
}

/// Tolerance mode's cost on the 64×64 cloth over a sphere in wind: the mode itself (its
/// estimates and controller), against the fixed setting it settles on, measured in one run.
fn tolerance(c: &mut Criterion) {
    let n = 64;
    let mut group = c.benchmark_group("tolerance_64x64_sphere_and_wind");
    let touching = [sphere_at(Vec3::new(0.0, -0.4, 0.0))];
    let wind = WindField {
        velocity: Vec3::new(5.0, 0.0, 2.0),
        air_density: 1.225,
        ..Default::default()
    };
    let env = Environment {
        colliders: &touching,
        wind: Some(&wind),
        ..Default::default()
    };
    let (tolerance, cap) = (0.1, 64);
    let mut adaptive = hanging(n);
    let mut settings = *adaptive.settings();
    settings.accuracy = Accuracy::relative(tolerance, cap);
    adaptive.set_settings(settings).unwrap();
    for _ in 0..300 {
        adaptive.step_in(1.0 / 60.0, &env).unwrap();
    }
    let chosen = adaptive.accuracy_report().unwrap();
    eprintln!("tolerance mode settled on {chosen:?}");
    let mut fixed = hanging(n);
    fixed
        .set_settings(SolverSettings {
            integrator: chosen.integrator,
            substeps: chosen.substeps,
            auto_substeps: false,
            ..*fixed.settings()
        })
        .unwrap();
    for _ in 0..300 {
        fixed.step_in(1.0 / 60.0, &env).unwrap();
    }
    group.bench_function(format!("tolerance_{tolerance}_cap_{cap}"), |b| {
        b.iter(|| adaptive.step_in(black_box(1.0 / 60.0), &env).unwrap())
    });
    group.bench_function(
        format!(
            "fixed_{}_{}_substeps",
            chosen.integrator.name(),
            chosen.substeps
        ),
        |b| b.iter(|| fixed.step_in(black_box(1.0 / 60.0), &env).unwrap()),
    );
    let after = adaptive.accuracy_report().unwrap();
    eprintln!("after the benchmark: {after:?}");
    assert!(after.substeps <= cap);
    group.finish();
}

/// A headless App with `active` hanging 64×64 cloths and `sleeping` ones at rest (weightless, so
/// they fall asleep after `sleep_steps`), updated until every sleeper sleeps.
fn app_with(active: u32, sleeping: u32) -> bevy::app::App {
    let mut app = bevy_cloth::harness::headless_app(1.0 / 60.0);
    let grid = GridSpec::new(64, 64, 1.0 / 63.0);
    for k in 0..active + sleeping {
        let asleep = k >= active;
        let solver = SolverSettings {
            gravity: if asleep { Vec3::ZERO } else { default() },
            sleep_speed: if asleep { 0.005 } else { 0.0 },
            ..default()
        };
        app.world_mut().spawn((
            Cloth::grid(grid),
            ClothPins::new([0, 63]),
            ClothConfig {
                solver,
                ..default()
            },
            Transform::from_xyz(2.0 * k as f32, 0.0, 0.0),
        ));
    }
    for _ in 0..40 {
        app.update();
    }
    let world = app.world_mut();
    let asleep = world
        .query::<&ClothState>()
        .iter(world)
        .filter(|s| s.sim().is_sleeping())
        .count();
    assert_eq!(
        asleep, sleeping as usize,
        "the weightless cloths must sleep"
    );
    app
}

/// The render side's vertex normals of a 64×64 cloth draped over a sphere: by its triangles
/// (`compute_normals`) and by the grid kernel (`GridNormals`) the plugin uses for grid cloths.
fn normals(c: &mut Criterion) {
    let spec = GridSpec::new(64, 64, 1.0 / 63.0);
    let model = ClothModel::grid(&spec).unwrap();
    let mut sim = ClothSim::new(model.clone(), SolverSettings::default(), |p| p).unwrap();
    let sphere = [sphere_at(Vec3::new(0.0, -0.4, 0.0))];
    let env = Environment {
        colliders: &sphere,
        ..Environment::default()
    };
    for _ in 0..60 {
        sim.step_in(1.0 / 60.0, &env).unwrap();
    }
    let positions = sim.positions().to_vec();
    let mut out = vec![Vec3::ZERO; positions.len()];
    let mut group = c.benchmark_group("normals_64x64");
    group.bench_function("triangles", |b| {
        b.iter(|| compute_normals(black_box(&positions), &model.triangles, &mut out))
    });
    let mut kernel = GridNormals::new(&model).unwrap();
    group.bench_function("grid_kernel", |b| {
        b.iter(|| kernel.compute(black_box(&positions), &mut out))
    });
    group.finish();
}

fn sleeping(c: &mut Criterion) {
    // The solver alone: 100 sleeping 64×64 cloths stepped against one active one.
    let mut group = c.benchmark_group("solver_frame_64x64");
    let mut active = hanging(64);
    group.bench_function("one_active", |b| {
        b.iter(|| active.step(black_box(1.0 / 60.0)).unwrap())
    });
    let mut sleepers: Vec<ClothSim> = (0..100)
        .map(|_| {
            let model = ClothModel::grid(&GridSpec::new(64, 64, 1.0 / 63.0)).unwrap();
            let settings = SolverSettings {
                gravity: Vec3::ZERO,
                ..Default::default()
            };
            let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
            while !sim.is_sleeping() {
                sim.step(1.0 / 60.0).unwrap();
            }
            sim
        })
        .collect();
    group.bench_function("100_sleeping", |b| {
        b.iter(|| {
            for sim in &mut sleepers {
                sim.step(black_box(1.0 / 60.0)).unwrap();
            }
        })
    });
    group.finish();

    let mut group = c.benchmark_group("app_frame_64x64");
    for (name, active, sleeping) in [
        ("no_cloth", 0, 0),
        ("one_active", 1, 0),
        ("100_sleeping", 0, 100),
    ] {
        let mut app = app_with(active, sleeping);
        group.bench_function(name, |b| b.iter(|| app.update()));
    }
    // The same frames on Bevy's single-threaded executor and without its static-scene transform
    // tracking, which leaves out the hand-overs of systems and of that tracking's task to worker
    // threads.
    for (name, active) in [
        ("no_cloth_single_threaded", 0),
        ("one_active_single_threaded", 1),
    ] {
        let mut app = app_with(active, 0);
        bevy_cloth::harness::use_single_threaded_frame(&mut app);
        group.bench_function(name, |b| b.iter(|| app.update()));
    }
    group.finish();
}

/// `sim` with self-collision turned on or off (5 mm thick).
fn with_self_collision(mut sim: ClothSim, enabled: bool) -> ClothSim {
    let settings = SolverSettings {
        self_collision: SelfCollision {
            enabled,
            thickness: 0.005,
            ..Default::default()
        },
        ..*sim.settings()
    };
    sim.set_settings(settings).unwrap();
    sim
}

/// Self-collision off and on for the same cloth: the swinging cloth hanging from two corners
/// (a few candidate pairs; its cost is the broad phase, searched again as its parts move
/// relative to each other), the same cloth settled (its cost is the check between searches), a
/// flag flapping in wind,
/// 64×64 (1.6 cm spacing) dropped nearly upright onto a floor, crumpled into a pile by 1.5 s of
/// simulation with self-collision on, and the same cloth folded in half lying on the floor.
fn self_collision(c: &mut Criterion) {
    let mut group = c.benchmark_group("self_collision_64x64");
    let floor = [Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
        Pose::from_translation(Vec3::ZERO),
        Friction::default(),
        0.005,
    )];
    let on_floor = Environment {
        colliders: &floor,
        ..Default::default()
    };
    let model = ClothModel::grid(&GridSpec::new(64, 64, 1.0 / 63.0)).unwrap();
    let settings = SolverSettings {
        sleep_speed: 0.0,
        ..Default::default()
    };
    let tilt = Quat::from_rotation_z(1.45) * Quat::from_rotation_x(0.3);
    let upright = ClothSim::new(model, settings, |p| tilt * p + Vec3::new(0.0, 0.8, 0.0)).unwrap();
    let mut pile = with_self_collision(upright, true);
    for _ in 0..90 {
        pile.step_in(1.0 / 60.0, &on_floor).unwrap();
    }
    // The same cloth folded in half (a crease of 1 cm radius, the upper layer 2 cm above the
    // lower) and laid on the floor, settled for 2 s: two layers resting on each other.
    let r = 0.01;
    let fold = |p: Vec3| {
        let u = p.x + 0.1;
        let turn = std::f32::consts::PI * r;
        let q = if u <= 0.0 {
            Vec3::new(u, 0.0, p.z)
        } else if u < turn {
            Vec3::new(r * (u / r).sin(), r - r * (u / r).cos(), p.z)
        } else {
            Vec3::new(turn - u, 2.0 * r, p.z)
        };
        q + Vec3::new(0.0, 0.006, 0.0)
    };
    let flat = ClothModel::grid(&GridSpec::new(64, 64, 1.0 / 63.0)).unwrap();
    let mut folded = with_self_collision(ClothSim::new(flat, settings, fold).unwrap(), true);
    for _ in 0..120 {
        folded.step_in(1.0 / 60.0, &on_floor).unwrap();
    }
    let none = Environment::default();
    // The same hanging cloth 20 s later, at rest but for a sway: it cannot touch itself.
    let mut settled = hanging(64);
    for _ in 0..1200 {
        settled.step(1.0 / 60.0).unwrap();
    }
    // A 1 m flag of 64×64 particles along a pole, flapping in a steady 7 m/s wind (the `flag`
    // example's cloth settings) after 2 s: its parts move relative to each other all the time,
    // but it does not fold onto itself.
    let flag_model =
        ClothModel::grid(&GridSpec::new(64, 64, 1.0 / 63.0).with_plane(GridPlane::Vertical))
            .unwrap();
    let flag_settings = SolverSettings {
        damping: 0.1,
        lift_coefficient: 0.8,
        sleep_speed: 0.0,
        ..Default::default()
    };
    let mut flag = ClothSim::new(flag_model, flag_settings, |p| p).unwrap();
    let pole: Vec<(u32, Vec3)> = (0..64)
        .map(|j| (j * 64, flag.positions()[j as usize * 64]))
        .collect();
    flag.set_pins(pole).unwrap();
    let wind = WindField {
        velocity: Vec3::new(7.0, 0.0, -1.5),
        ..Default::default()
    };
    let in_wind = Environment {
        wind: Some(&wind),
        ..Default::default()
    };
    for _ in 0..120 {
        flag.step_in(1.0 / 60.0, &in_wind).unwrap();
    }
    for (name, sim, env) in [
        ("hanging", hanging(64), &none),
        ("hanging_settled", settled, &none),
        ("flag_in_wind", flag, &in_wind),
        ("pile", pile, &on_floor),
        ("folded", folded, &on_floor),
    ] {
        for enabled in [false, true] {
            let mut sim = with_self_collision(sim.clone(), enabled);
            let label = if enabled { "on" } else { "off" };
            group.bench_function(format!("{name}_{label}"), |b| {
                b.iter(|| sim.step_in(black_box(1.0 / 60.0), env).unwrap())
            });
        }
    }
    group.finish();
    // `hanging` above keeps stepping one cloth, whose swing calms over the run, so its calmer
    // seconds weigh in. Here the first second of the swing (frames 30 to 90 after the cloth is
    // let go) is replayed from the same state every iteration and timed per frame, so that two
    // builds are compared on the same frames.
    let mut group = c.benchmark_group("self_collision_64x64_swing");
    group.sample_size(10);
    for enabled in [false, true] {
        let start = with_self_collision(hanging(64), enabled);
        let label = if enabled { "on" } else { "off" };
        group.bench_function(format!("first_second_{label}"), |b| {
            b.iter_custom(|iters| {
                let mut total = Duration::ZERO;
                for _ in 0..iters {
                    let mut sim = start.clone();
                    let t = Instant::now();
                    for _ in 0..60 {
                        sim.step(black_box(1.0 / 60.0)).unwrap();
                    }
                    total += t.elapsed();
                }
                total / 60
            })
        });
    }
    group.finish();
}

/// Character cloth. App frames (step, skinning, mesh write) of a 32×32 cape (1,024 particles)
/// at the default settings: skinned to a torso that walks at 3 m/s while its spine turns at
/// 1 rad/s (collar pinned to its skin, the rest within 0.3 m × weight of it), against the same
/// cape mesh as a plain cloth pinned along its collar, standing still. Then one solver step of a
/// 32×32 curtain pinned along its top row, tethers off and on.
fn character(c: &mut Criterion) {
    let mut group = c.benchmark_group("character_cape_32x32");
    let cape = Cape::new(32, 32);
    let solver = SolverSettings {
        sleep_speed: 0.0,
        ..default()
    };
    let mut config = ClothConfig {
        solver,
        ..default()
    };
    config.solver.targets.max_distance_scale = 0.3;
    {
        let mut app = bevy_cloth::harness::headless_app(1.0 / 60.0);
        let mesh = app
            .world_mut()
            .resource_mut::<bevy::asset::Assets<bevy::mesh::Mesh>>()
            .add(cape.mesh.clone());
        app.world_mut().spawn((
            Cloth::from_mesh(mesh),
            ClothPins::new(0..32),
            ClothConfig {
                solver,
                ..default()
            },
        ));
        for _ in 0..30 {
            app.update();
        }
        group.bench_function("app_static_pins", |b| b.iter(|| app.update()));
    }
    {
        let mut app = bevy_cloth::harness::headless_app(1.0 / 60.0);
        let spawned = spawn_cape(app.world_mut(), &cape, config);
        let mut t = 0.0;
        let mut frame = |app: &mut bevy::app::App| {
            t += 1.0 / 60.0;
            let (root, spine) = torso_pose(t, 3.0, 1.0);
            *app.world_mut().get_mut::<Transform>(spawned.root).unwrap() = root;
            *app.world_mut().get_mut::<Transform>(spawned.spine).unwrap() = spine;
            app.update();
        };
        for _ in 0..30 {
            frame(&mut app);
        }
        group.bench_function("app_skinned", |b| b.iter(|| frame(&mut app)));
    }
    let spec = GridSpec::new(32, 32, 0.8 / 31.0).with_plane(GridPlane::Vertical);
    for enabled in [false, true] {
        let settings = SolverSettings {
            tethers: Tethers {
                enabled,
                ..default()
            },
            ..solver
        };
        let mut sim = ClothSim::new(ClothModel::grid(&spec).unwrap(), settings, |p| p).unwrap();
        let top: Vec<(u32, Vec3)> = (0..32).map(|i| (i, sim.positions()[i as usize])).collect();
        sim.set_pins(top).unwrap();
        for _ in 0..30 {
            sim.step(1.0 / 60.0).unwrap();
        }
        let label = if enabled { "on" } else { "off" };
        group.bench_function(format!("solver_tethers_{label}"), |b| {
            b.iter(|| sim.step(black_box(1.0 / 60.0)).unwrap())
        });
    }
    group.finish();
}

/// Cloth–cloth contacts' cost in one step of a 32×32 cloth (3 cm spacing, self-collision off):
/// lying crumpled on another 32×32 cloth that lies on a floor (both dropped and settled for
/// 1.5 s, stepping one after the other as the plugin steps them), against the same step alone
/// and with the other cloth moved 10 m away (out of reach: only the box test).
fn cloth_contacts(c: &mut Criterion) {
    let mut group = c.benchmark_group("cloth_contacts_32x32");
    let floor = [Collider::fixed(
        ColliderShape::HalfSpace(InfinitePlane3d::new(Vec3::Y)),
        Pose::from_translation(Vec3::ZERO),
        Friction::default(),
        0.005,
    )];
    let settings = SolverSettings {
        sleep_speed: 0.0,
        ..Default::default()
    };
    let cloth = |at: Transform| {
        let model = ClothModel::grid(&GridSpec::new(32, 32, 0.03)).unwrap();
        ClothSim::new(model, settings, |p| at.transform_point(p)).unwrap()
    };
    let mut below = cloth(Transform::from_xyz(0.0, 0.05, 0.0));
    let mut above = cloth(
        Transform::from_xyz(0.1, 0.3, 0.05)
            .with_rotation(Quat::from_rotation_y(0.7) * Quat::from_rotation_x(0.4)),
    );
    let triangles = below.model().triangles.clone();
    let with = |x0: &[Vec3], x1: &[Vec3], step: &mut dyn FnMut(&Environment)| {
        let others = [OtherCloth {
            triangles: &triangles,
            start: x0,
            end: x1,
            thickness: 0.005,
            friction: 0.3,
        }];
        step(&Environment {
            colliders: &floor,
            cloths: &others,
            ..Default::default()
        });
    };
    for _ in 0..90 {
        let still = above.positions().to_vec();
        with(&still, &still, &mut |env| {
            below.step_in(1.0 / 60.0, env).unwrap()
        });
        let start = below.positions().to_vec();
        with(&start, below.positions(), &mut |env| {
            above.step_in(1.0 / 60.0, env).unwrap()
        });
    }
    let lying = below.positions().to_vec();
    let away: Vec<Vec3> = lying
        .iter()
        .map(|p| *p + Vec3::new(10.0, 0.0, 0.0))
        .collect();
    let alone = Environment {
        colliders: &floor,
        ..Default::default()
    };
    let mut sim = above.clone();
    group.bench_function("alone", |b| {
        b.iter(|| sim.step_in(black_box(1.0 / 60.0), &alone).unwrap())
    });
    for (name, other) in [
        ("lying_on_another", &lying),
        ("another_out_of_reach", &away),
    ] {
        let mut sim = above.clone();
        group.bench_function(name, |b| {
            b.iter(|| {
                with(other, other, &mut |env| {
                    sim.step_in(black_box(1.0 / 60.0), env).unwrap()
                })
            })
        });
    }
    group.finish();
}

criterion_group!(
    benches,
    step,
    explicit,
    implicit,
    environment,
    tolerance,
    normals,
    sleeping,
    self_collision,
    character,
    cloth_contacts
);
criterion_main!(benches);
