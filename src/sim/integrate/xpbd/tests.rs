use super::kernel::solve_springs;
use super::layout::{Layout, Run, grid_order};
use super::*;
use crate::sim::WindField;
use crate::sim::simd::Build;
use crate::sim::{ClothModel, Collider, ColliderShape, Friction, GridSpec, Integrator, Pose};
use bevy::math::primitives::Sphere;
use glam::Vec3;

/// A still sphere of radius `r` at `at`, with a 1 cm margin.
fn ball(r: f32, at: Vec3, friction: Friction) -> Collider {
    Collider::fixed(
        ColliderShape::Sphere(Sphere::new(r)),
        Pose::from_translation(at),
        friction,
        0.01,
    )
}

/// Sea-level air moving at `velocity`, without gusts.
fn air(velocity: Vec3) -> WindField {
    WindField {
        velocity,
        air_density: 1.225,
        ..Default::default()
    }
}

/// Checks the layout and returns the number of gathered (scattered or tail) springs.
fn gathered(model: &ClothModel) -> usize {
    let (s, n) = (&model.springs, model.particle_count());
    let p = Projections::new(model);
    p.check(s, n).unwrap();
    p.runs
        .iter()
        .map(|r| match r.layout {
            Layout::Scattered => r.len as usize,
            _ => r.len as usize % LANES,
        })
        .sum()
}

#[test]
fn a_mesh_laid_out_as_a_grid_is_projected_as_vectors() {
    // A cape made as a grid of 20 × 25 vertices, its cells cut along either diagonal: its
    // springs (structural, and bend across every edge) are coloured as the grid's, so that as few
    // are gathered one by one as on the grid.
    let (nx, ny) = (20u32, 25u32);
    let positions: Vec<Vec3> = (0..ny)
        .flat_map(|j| (0..nx).map(move |i| Vec3::new(i as f32 * 0.03, -(j as f32) * 0.03, 0.0)))
        .collect();
    for flip in [false, true] {
        let mut indices = Vec::new();
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let a = j * nx + i;
                let (b, c, d) = (a + 1, a + nx, a + nx + 1);
                if flip {
                    indices.extend([a, c, d, a, d, b]);
                } else {
                    indices.extend([a, c, b, b, c, d]);
                }
            }
        }
        let model = ClothModel::from_mesh(&positions, None, &indices, 3).unwrap();
        let tails = gathered(&model);
        assert!(
            tails < LANES * model.springs.color_count(),
            "flip {flip}: {tails} of {} springs gathered",
            model.springs.len()
        );
    }
}

#[test]
fn grid_springs_are_projected_as_vectors() {
    let model = ClothModel::grid(&GridSpec::new(64, 64, 0.1)).unwrap();
    let p = Projections::new(&model);
    // The row ends are padded, so that only the last run of a colour, whose padding would
    // run past the last particle, can leave springs to scalar code; the padding costs a few
    // percent.
    let tails = gathered(&model);
    assert!(
        tails < LANES * model.springs.color_count(),
        "{tails} gathered"
    );
    let padding = p.spring.iter().filter(|s| s.is_none()).count();
    assert!(
        padding * 50 < p.spring.len(),
        "{padding} of {} slots",
        p.spring.len()
    );
    // Odd sizes break the row patterns but never the layout.
    for (nx, ny) in [(9, 7), (2, 2), (3, 17), (50, 31)] {
        let model = ClothModel::grid(&GridSpec::new(nx, ny, 0.1)).unwrap();
        gathered(&model);
    }
    let quad = [0, 1, 2, 3];
    let p = [Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::Y];
    gathered(&ClothModel::from_mesh(&p, None, &quad, 4).unwrap());
}

#[test]
fn a_torn_grid_is_projected_as_vectors_as_the_grid_was() {
    // A 64×64 grid holed by a ray and cut across a row keeps the grid's colours and storage
    // order: beyond the grid's own tails, only springs at its copies (about five a copy) may be
    // gathered one by one. Coloured afresh, three times as many are.
    let spec = GridSpec::new(64, 64, 0.02).with_plane(crate::sim::GridPlane::Vertical);
    let model = ClothModel::grid(&spec).unwrap();
    let grid_tails = gathered(&model);
    let mut sim = crate::sim::ClothSim::new(model, Default::default(), |p| p).unwrap();
    let at = |sim: &crate::sim::ClothSim, i: usize| sim.positions()[i];
    let cuts = [
        crate::sim::Cut::Ray {
            origin: at(&sim, 20 * 64 + 40) - Vec3::Z,
            direction: Vec3::Z,
            radius: 0.1,
        },
        crate::sim::Cut::Plane {
            point: at(&sim, 32 * 64 + 5) + 0.01 * Vec3::Y,
            normal: Vec3::Y,
        },
    ];
    for cut in cuts {
        assert!(!sim.tear(&[cut]).unwrap().is_empty());
    }
    let torn = sim.model();
    let copies = torn.particle_count() - 64 * 64;
    let tails = gathered(torn);
    assert!(
        tails < grid_tails + 6 * copies,
        "{tails} of {} springs gathered ({copies} copies; the grid: {grid_tails})",
        torn.springs.len()
    );
}

#[test]
fn single_vector_batches_of_a_grid_are_projected_in_pairs() {
    // A 64-column grid's rows leave many runs of 16 or 48 slots: a vector batch each that the
    // kernel would otherwise project with one chain of square root and division in flight.
    let model = ClothModel::grid(&GridSpec::new(64, 64, 0.1)).unwrap();
    let p = Projections::new(&model);
    let shares = (0..p.color_count()).flat_map(|c| [p.share(c, 0), p.share(c, 1)]);
    let (mut singles, mut solo) = (0, 0);
    for runs in shares {
        for k in p.wide_singles(runs) {
            singles += 1;
            solo += usize::from(p.solo[k]);
        }
    }
    assert!(singles > 500, "{singles} single batches");
    assert!(solo * 50 < singles, "{solo} of {singles} alone");
}

#[test]
fn grid_colours_split_into_balanced_shares() {
    for (nx, ny) in [(64, 64), (128, 128), (100, 37)] {
        let model = ClothModel::grid(&GridSpec::new(nx, ny, 0.1)).unwrap();
        let p = Projections::new(&model);
        p.check(&model.springs, model.particle_count()).unwrap();
        assert!(p.worth_sharing(), "{nx}×{ny}");
        for c in 0..p.color_count() {
            let [first, second] = [0, 1].map(|s| p.share(c, s).iter().map(|r| r.len).sum::<u32>());
            let total = first + second;
            assert!(
                first.abs_diff(second) * 10 <= total,
                "{nx}×{ny}, colour {c}: shares of {first} and {second} slots"
            );
        }
    }
}

#[test]
fn shared_sweeps_match_one_thread_bit_for_bit() {
    use crate::sim::{ClothSim, Environment, ScopedThread, SolverSettings, Spread};
    /// Runs the helper only after the step: the step's thread must do all the work.
    struct Late;
    impl Spread for Late {
        fn join(&self, helper: &(dyn Fn() + Sync), main: &mut dyn FnMut()) {
            main();
            helper();
        }
    }
    // A 96×48 cloth (27,000 springs, so it is shared) pinned at two corners, blown onto a
    // sphere, with one iteration and with three (which keep multipliers).
    let sphere = [ball(0.4, Vec3::new(0.5, -0.45, 0.3), Friction::default())];
    let wind = air(Vec3::new(2.0, 0.0, 5.0));
    let env = Environment {
        colliders: &sphere,
        wind: Some(&wind),
        ..Default::default()
    };
    for iterations in [1, 3] {
        let run = |spread: Option<&dyn Spread>| {
            let model = ClothModel::grid(&GridSpec::new(96, 48, 0.05)).unwrap();
            let settings = SolverSettings {
                integrator: Integrator::Xpbd,
                iterations,
                ..Default::default()
            };
            let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
            assert!(sim.steppers.xpbd.worth_sharing());
            sim.set_pins([(0, sim.positions()[0]), (95, sim.positions()[95])])
                .unwrap();
            let mut touching = 0;
            for _ in 0..15 {
                match spread {
                    Some(spread) => sim.step_in_parallel(1.0 / 60.0, &env, spread),
                    None => sim.step_in(1.0 / 60.0, &env),
                }
                .unwrap();
                touching += sim.active_colliders();
            }
            assert!(touching > 0, "the sphere was never in reach");
            (sim.positions().to_vec(), sim.velocities().to_vec())
        };
        let alone = run(None);
        assert!(run(Some(&ScopedThread)) == alone, "{iterations} iterations");
        assert!(
            run(Some(&Late)) == alone,
            "{iterations} iterations, late helper"
        );
    }
}

#[test]
fn the_grid_storage_order_changes_no_result() {
    use crate::sim::{ClothSim, Environment, SolverSettings};
    // The same 40×12 cloth with and without its grid (which alone selects the storage
    // order): pinned and moved, draped over a sphere, in wind. The lane arithmetic is the
    // same in every layout, so the positions must be bit-identical.
    let masses = (0..40 * 12).map(|i| 0.002 * (1 + i % 7) as f32).collect();
    let grid = ClothModel::grid(&GridSpec::new(40, 12, 0.05))
        .unwrap()
        .with_particle_masses(masses)
        .unwrap();
    let mut plain = grid.clone();
    plain.grid = None;
    assert!(!grid_order(grid.grid.as_ref().unwrap()).is_empty());
    let sphere = [ball(0.2, Vec3::new(0.3, -0.35, 0.05), Friction::default())];
    let wind = air(Vec3::new(3.0, 0.0, 4.0));
    let env = Environment {
        colliders: &sphere,
        wind: Some(&wind),
        ..Default::default()
    };
    let run = |model: ClothModel| {
        let settings = SolverSettings {
            integrator: Integrator::Xpbd,
            ..Default::default()
        };
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        // Corners stay where they are stored; particle 22 moves to the third column block.
        let ends = [Vec3::new(-1.0, 0.0, 0.3), Vec3::new(0.1, 0.0, 0.3)];
        let pins = [(0, ends[0]), (22, ends[1]), (39, Vec3::new(1.0, 0.0, 0.3))];
        sim.set_pins(pins).unwrap();
        for frame in 0..40 {
            let x = 0.01 * frame as f32;
            let right = Vec3::new(1.0 - x, 0.0, 0.3);
            sim.move_pins([ends[0] + Vec3::X * x, ends[1] + Vec3::Y * x, right]);
            sim.step_in(1.0 / 60.0, &env).unwrap();
        }
        assert!(sim.active_colliders() > 0, "the sphere was never in reach");
        (sim.positions().to_vec(), sim.velocities().to_vec())
    };
    let (a, b) = (run(grid), run(plain));
    assert!(a == b, "the storage order changed the result");
}

#[test]
fn contacts_ahead_of_the_end_pass_match_contacts_after_it() {
    use crate::sim::{ClothSim, Environment, SolverSettings};
    // A 40×12 cloth (stored in the grid order) blown onto spheres and pinned at two corners:
    // contacts resolved on the state the substep ends in, then the fused end-and-start pass,
    // against contacts on the end state after a separate end pass (a test-only path). They
    // differ by rounding only: the end position `x + Δ` is rounded once more after a push. Over
    // a whole run the cloth's contacts amplify that rounding (3e-6 m and 4e-4 m/s after 25
    // frames), so each frame is stepped both ways from the same state and compared: up to
    // 7e-8 m, and velocities up to 1.5 times a position's last bit over a substep (3.2 times
    // with the still pins' targets rounded as they were before `state::between`). Keeping only
    // the first of a particle's contact velocities in a substep gives 5.9 times, leaving out
    // the velocity write-back 7e-3 m.
    // A second sphere overlapping the first, and a small one (smaller than the cloth's edges,
    // so triangles are tested too): particles are pushed more than once in a substep.
    let friction = Friction::new(0.4);
    let sphere = [
        ball(0.25, Vec3::new(0.9, -0.3, 0.4), friction),
        ball(0.25, Vec3::new(1.0, -0.3, 0.4), friction),
        ball(0.03, Vec3::new(0.5, -0.04, 0.3), friction),
    ];
    let wind = air(Vec3::new(0.0, 0.0, 6.0));
    let env = Environment {
        colliders: &sphere,
        wind: Some(&wind),
        ..Default::default()
    };
    let cloth = |tracked: bool| {
        let model = ClothModel::grid(&GridSpec::new(40, 12, 0.05)).unwrap();
        let settings = SolverSettings {
            integrator: Integrator::Xpbd,
            ..Default::default()
        };
        let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
        sim.set_pins([(0, sim.positions()[0]), (39, sim.positions()[39])])
            .unwrap();
        if tracked {
            sim.track_contact_work();
        }
        sim
    };
    let worst = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .zip(b)
            .map(|(a, b)| a.distance(*b))
            .fold(0.0, f32::max)
    };
    let (mut sim, mut tracked) = (cloth(false), cloth(true));
    let (mut touching, mut dx, mut dv) = (0, 0.0f32, 0.0f32);
    for _ in 0..30 {
        let mut after = sim.clone();
        after.steppers.xpbd.contacts_after_end = true;
        for s in [&mut sim, &mut after, &mut tracked] {
            s.step_in(1.0 / 60.0, &env).unwrap();
        }
        touching += sim.active_colliders();
        // Counting the energy contacts add (the stress suite) changes nothing.
        assert!(
            (tracked.positions(), tracked.velocities()) == (sim.positions(), sim.velocities()),
            "tracking changed the result"
        );
        dx = dx.max(worst(sim.positions(), after.positions()));
        // A velocity is a substep's displacement over its length, so one more rounding of a
        // position changes it by about the position's last bit over the substep.
        let h = 1.0 / (60.0 * SolverSettings::default().substeps as f32);
        let ulp = |x: Vec3| {
            let a = x.abs().max_element();
            f32::from_bits(a.to_bits() + 1) - a
        };
        for ((x, v), w) in (sim.positions().iter().zip(sim.velocities())).zip(after.velocities()) {
            dv = dv.max(v.distance(*w) * h / ulp(*x));
        }
    }
    assert!(
        touching > 10,
        "the sphere was in reach for {touching} steps"
    );
    assert!(dx > 0.0, "the two paths are distinct");
    assert!(dx < 1e-6, "positions differ by {dx}");
    assert!(
        dv < 2.5,
        "velocities differ by {dv} of a position's last bit per substep"
    );
}

/// One contiguous run of `slots` slots over `n` particles, its first ends particles `0..slots`
/// and its second ends `16..16 + slots`, the first `springs` slots springs and the rest padding
/// (rest length 0, stiffness 1e3, unit masses), weighted for substeps of 1/60 s.
fn contiguous_run(n: usize, slots: u32, springs: u32) -> Projections {
    let mut p = Projections {
        a: (0..slots).collect(),
        b: (16..16 + slots).collect(),
        spring: (0..slots).map(|m| (m < springs).then_some(m)).collect(),
        solo: vec![true; slots as usize],
        runs: vec![Run {
            layout: Layout::Contiguous,
            start: 0,
            len: slots,
        }],
        springs: springs as usize,
        ..Projections::default()
    };
    p.rest = vec![0.0; slots as usize];
    p.compliance = vec![0.0; slots as usize];
    p.inv_mass = vec![0.0; n];
    let springs = springs as usize;
    p.set_constants(&vec![0.5; springs], &vec![1e3; springs], &vec![1.0; n]);
    p.set_weights(3600.0);
    p
}

/// One sweep of `p`'s runs from positions `start`, updating the displacements `delta`.
fn sweep_runs(p: &Projections, start: &Soa, delta: &mut Soa) {
    let mut lambda = vec![0.0; p.a.len()];
    let x = SplitPositions {
        start: [&start.x, &start.y, &start.z].map(|v| ReadColumn::new(v)),
        delta: [&mut delta.x, &mut delta.y, &mut delta.z].map(|v| Column::new(v)),
    };
    // SAFETY: one thread, and the arrays are used through the columns only until the sweep
    // returns.
    unsafe { solve_springs::<false>(p, &p.runs, x, Column::new(&mut lambda), 3600.0) };
}

#[test]
fn padding_slots_change_nothing() {
    // A contiguous run of three springs, padded to a batch of eight.
    let n = 32;
    let mut start = Soa::new(n);
    for i in 0..n {
        start.set(i, Vec3::new(i as f32 * 0.1, (i % 3) as f32, 0.0));
    }
    let mut delta = Soa::new(n);
    for i in 0..n {
        delta.set(i, Vec3::splat(1e-3 * i as f32));
    }
    let before = delta.clone();
    sweep_runs(&contiguous_run(n, 8, 3), &start, &mut delta);
    for i in 0..n {
        let moved = delta.get(i) != before.get(i);
        assert_eq!(moved, matches!(i, 0..3 | 16..19), "particle {i}");
    }
}

#[test]
#[should_panic(expected = "past the particles")]
fn a_contiguous_run_past_the_particles_panics() {
    // A run of 16 springs, its second ends moved to particles 20..36 of 32 after the constants
    // are set: the streamed run's one bounds test (or, on AVX-512, the batch's) must stop it.
    let n = 32;
    let mut p = contiguous_run(n, 16, 16);
    for b in &mut p.b {
        *b += 4;
    }
    sweep_runs(&p, &Soa::new(n), &mut Soa::new(n));
}

/// The displacements and multipliers after one sweep over `model`'s springs by the kernel's
/// `build` (with `ACCUMULATE`, from nonzero multipliers), if the CPU has it, as bits. `None` for
/// `build`: the plain build with its fused multiply-adds in plain arithmetic.
fn sweep_in<const ACCUMULATE: bool>(build: Option<Build>, model: &ClothModel) -> Option<Vec<u32>> {
    sweep_from::<ACCUMULATE>(build, model, |k| 1e-4 * (k % 5) as f32)
}

/// [`sweep_in`], with the multipliers starting at `lambda(slot)`.
fn sweep_from<const ACCUMULATE: bool>(
    build: Option<Build>,
    model: &ClothModel,
    lambda: impl Fn(usize) -> f32,
) -> Option<Vec<u32>> {
    let n = model.particle_count();
    let s = &model.springs;
    let mut p = Projections::new(model);
    let stiffness: Vec<f32> = (0..s.len()).map(|k| 50.0 + (k % 7) as f32 * 1e3).collect();
    let inv_mass: Vec<f32> = (0..n)
        .map(|i| if i % 11 == 0 { 0.0 } else { 1e3 })
        .collect();
    p.set_constants(&s.rest, &stiffness, &inv_mass);
    p.set_weights(3600.0);
    let mut start = Soa::new(n);
    let mut delta = Soa::new(n);
    for i in 0..n {
        let t = i as f32;
        let stored = p.stored(i as u32) as usize;
        start.set(stored, model.rest_positions[i] * 1.01);
        delta.set(
            stored,
            1e-3 * Vec3::new(t.sin(), (1.7 * t).cos(), (0.3 * t).sin()),
        );
    }
    let mut lambda: Vec<f32> = (0..p.slot_count()).map(lambda).collect();
    let x = SplitPositions {
        start: [&start.x, &start.y, &start.z].map(|v| ReadColumn::new(v)),
        delta: [&mut delta.x, &mut delta.y, &mut delta.z].map(|v| Column::new(v)),
    };
    // SAFETY: one thread, and the arrays are used through the columns only until the sweep
    // returns.
    let ran = unsafe {
        match build {
            Some(build) => kernel::solve_springs_in::<ACCUMULATE>(
                build,
                &p,
                x,
                Column::new(&mut lambda),
                3600.0,
            ),
            None => {
                kernel::solve_springs_unfused::<ACCUMULATE>(
                    &p,
                    x,
                    Column::new(&mut lambda),
                    3600.0,
                );
                true
            }
        }
    };
    ran.then(|| {
        let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
        [
            bits(&delta.x),
            bits(&delta.y),
            bits(&delta.z),
            bits(&lambda),
        ]
        .concat()
    })
}

#[test]
fn one_iteration_with_weights_per_slot_moves_as_the_multiplier_update_from_zero() {
    // One iteration takes each end's share of the correction from the slot's weights; the update
    // with multipliers computes `Δλ` and multiplies by the inverse masses, from λ = 0 the same
    // step. They differ only in rounding: each correction rounds `L - |d|` to the last place of
    // the spring's length (7.5e-9 m for the longest, 0.1 m), and the sweep carries that on.
    // Pinned particles (w = 0) and stiffnesses from soft (α̃ far above w) to stiff are among the
    // springs.
    let models = [
        ClothModel::grid(&GridSpec::new(40, 9, 0.05)).unwrap(),
        ClothModel::disc(&crate::sim::DiscSpec::new(7, 6, 0.5)).unwrap(),
    ];
    for model in &models {
        let n = 3 * model.particle_count();
        let weights = sweep_from::<false>(Some(Build::Plain), model, |_| 0.0).unwrap();
        let multipliers = sweep_from::<true>(Some(Build::Plain), model, |_| 0.0).unwrap();
        let (mut largest, mut moved) = (0.0f32, 0.0f32);
        for (w, m) in weights[..n].iter().zip(&multipliers[..n]) {
            let (w, m) = (f32::from_bits(*w), f32::from_bits(*m));
            largest = largest.max((w - m).abs());
            moved = moved.max(m.abs());
        }
        assert!(moved > 1e-3, "the sweep moved the particles");
        assert!(
            largest < 4e-8,
            "the two updates differ by {largest} m in a displacement"
        );
    }
}

#[test]
fn the_slots_weights_follow_the_substep_and_the_masses() {
    let model = ClothModel::grid(&GridSpec::new(40, 9, 0.05)).unwrap();
    let (s, n) = (&model.springs, model.particle_count());
    let stiffness: Vec<f32> = (0..s.len()).map(|k| 50.0 + (k % 7) as f32 * 1e3).collect();
    let light = vec![1e3; n];
    let pinned: Vec<f32> = (0..n).map(|i| if i < 40 { 0.0 } else { 1e3 }).collect();
    let fresh = |inv_mass: &[f32], inv_h2: f32| {
        let mut p = Projections::new(&model);
        p.set_constants(&s.rest, &stiffness, inv_mass);
        p.set_weights(inv_h2);
        p.weights
    };
    let mut p = Projections::new(&model);
    p.set_constants(&s.rest, &stiffness, &light);
    p.set_weights(3600.0);
    assert_eq!(p.weights, fresh(&light, 3600.0));
    // Another substep length.
    p.set_weights(900.0);
    assert_eq!(p.weights, fresh(&light, 900.0));
    assert_ne!(p.weights, fresh(&light, 3600.0));
    // New masses (the first row pinned) at the same substep length.
    p.set_constants(&s.rest, &stiffness, &pinned);
    p.set_weights(900.0);
    assert_eq!(p.weights, fresh(&pinned, 900.0));
    assert_ne!(p.weights, fresh(&light, 900.0));
}

#[test]
fn every_build_of_the_slots_weights_gives_the_same_bits() {
    // Pinned particles (w = 0), both ends pinned, and compliances from stiff to soft, over a
    // slot count that leaves a partial last vector.
    let model = ClothModel::grid(&GridSpec::new(37, 9, 0.05)).unwrap();
    let (s, n) = (&model.springs, model.particle_count());
    let stiffness: Vec<f32> = (0..s.len()).map(|k| 0.5 + (k % 7) as f32 * 1e3).collect();
    let inv_mass: Vec<f32> = (0..n)
        .map(|i| {
            if i < 37 || i % 13 == 0 {
                0.0
            } else {
                1e3 / (1 + i % 5) as f32
            }
        })
        .collect();
    let weights = |build| {
        let mut p = Projections::new(&model);
        p.set_constants(&s.rest, &stiffness, &inv_mass);
        p.set_weights_in(build, 3600.0).then(|| {
            let bits = |v: &[f32]| v.iter().map(|f| f.to_bits()).collect::<Vec<_>>();
            [bits(&p.weights[0]), bits(&p.weights[1])]
        })
    };
    let plain = weights(Build::Plain).unwrap();
    assert!(plain[0].contains(&0) && plain[0].iter().any(|&w| w != 0));
    for build in [Build::Avx2, Build::Avx512] {
        if let Some(wide) = weights(build) {
            assert_eq!(wide, plain, "{build:?} against the plain build");
        }
    }
}

#[test]
fn every_build_of_the_spring_kernel_gives_the_same_bits() {
    // Stored in grid order (contiguous runs; on AVX-512 two batches at once, and four where
    // the rows, 40 particles apart, allow), in their own order (interleaved row runs), and a
    // disc (scattered springs and one-at-a-time tails).
    let models = [
        ClothModel::grid(&GridSpec::new(40, 9, 0.05)).unwrap(),
        ClothModel::grid(&GridSpec::new(19, 13, 0.05)).unwrap(),
        ClothModel::disc(&crate::sim::DiscSpec::new(7, 6, 0.5)).unwrap(),
    ];
    let mut compared = 0;
    for model in &models {
        let plain = (
            sweep_in::<false>(Some(Build::Plain), model),
            sweep_in::<true>(Some(Build::Plain), model),
        );
        // Without FMA instructions, as a CPU without them runs the plain build.
        let unfused = (
            sweep_in::<false>(None, model),
            sweep_in::<true>(None, model),
        );
        assert!(plain == unfused, "the plain build differs without FMA");
        for build in [Build::Avx2, Build::Avx512] {
            let wide = (
                sweep_in::<false>(Some(build), model),
                sweep_in::<true>(Some(build), model),
            );
            if wide.0.is_some() {
                assert!(wide == plain, "{build:?} differs from the plain build");
                compared += 1;
            }
        }
    }
    let available = [Build::Avx2, Build::Avx512]
        .iter()
        .filter(|b| b.is_available());
    assert_eq!(compared, models.len() * available.count());
}

/// Positions, velocities and displacements after the particle pass `END`, `BEGIN` (with wind if
/// `wind`) by the kernel's `build`, if the CPU has it, as bits.
fn advance_in<const END: bool, const BEGIN: bool>(build: Build, wind: bool) -> Option<Vec<u32>> {
    let n = 45;
    let f = |i: usize, k: f32| (i as f32 * k).sin();
    let mut x: [Vec<f32>; 3] = [0.3, 0.7, 1.1].map(|k| (0..n).map(|i| f(i, k)).collect());
    let mut v: [Vec<f32>; 3] = [1.3, 0.2, 0.5].map(|k| (0..n).map(|i| f(i, k)).collect());
    let mut d: [Vec<f32>; 3] = [0.9, 1.7, 0.4].map(|k| (0..n).map(|i| 1e-3 * f(i, k)).collect());
    let w: [Vec<f32>; 3] = [2.3, 0.1, 0.6].map(|k| (0..n).map(|i| 1e-2 * f(i, k)).collect());
    let m = Motion {
        h: 1.0 / 1200.0,
        inv_h: 1200.0,
        keep: 0.9996,
        gravity: [0.0, -9.81 / 1200.0, 0.0],
    };
    let [x0, x1, x2] = &mut x;
    let [v0, v1, v2] = &mut v;
    let [d0, d1, d2] = &mut d;
    let kernel = Advance::<END, BEGIN> {
        x: [x0, x1, x2].map(|a| &mut a[..]),
        v: [v0, v1, v2].map(|a| &mut a[..]),
        d: [d0, d1, d2].map(|a| &mut a[..]),
        wind_dv: wind.then(|| [&w[0][..], &w[1][..], &w[2][..]]),
        m: &m,
    };
    simd::run_as(build, kernel).then(|| {
        [x, v, d]
            .iter()
            .flatten()
            .flat_map(|c| c.iter().map(|f| f.to_bits()))
            .collect()
    })
}

#[test]
fn every_build_of_the_particle_pass_gives_the_same_bits() {
    for wind in [false, true] {
        for build in [Build::Avx2, Build::Avx512] {
            let pairs = [
                (
                    advance_in::<true, true>(build, wind),
                    advance_in::<true, true>(Build::Plain, wind),
                ),
                (
                    advance_in::<true, false>(build, wind),
                    advance_in::<true, false>(Build::Plain, wind),
                ),
                (
                    advance_in::<false, true>(build, wind),
                    advance_in::<false, true>(Build::Plain, wind),
                ),
            ];
            for (wide, plain) in pairs {
                if wide.is_some() {
                    assert!(
                        wide == plain,
                        "{build:?} differs from the plain build (wind {wind})"
                    );
                }
            }
        }
    }
}
