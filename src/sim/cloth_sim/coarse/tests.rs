use glam::Vec3;

use crate::error::ClothError;
use crate::sim::model::DiscSpec;
use crate::sim::{COARSE_FADE_STEPS, ClothModel, ClothSim, Cut, GridSpec, SolverSettings, Target};

const DT: f32 = 1.0 / 60.0;

/// A sheet of `n` × `n` particles 5 cm apart, held flat by two corners of its first row (and
/// `more` pins), to swing down.
fn curtain(n: u32, more: &[u32]) -> ClothSim {
    let spec = GridSpec::new(n, n, 0.05);
    let model = ClothModel::grid(&spec).unwrap();
    let mut sim = ClothSim::new(model, SolverSettings::default(), |p| p).unwrap();
    let pins: Vec<(u32, Vec3)> = [0, n - 1]
        .iter()
        .chain(more)
        .map(|&i| (i, sim.positions()[i as usize]))
        .collect();
    sim.set_pins(pins).unwrap();
    sim
}

/// The farthest any particle lies from where it was in `before`, m.
fn farthest(now: &[Vec3], before: &[Vec3]) -> f32 {
    now.iter()
        .zip(before)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max)
}

fn run(sim: &mut ClothSim, steps: usize) {
    for _ in 0..steps {
        sim.step(DT).unwrap();
    }
}

#[test]
fn every_particle_follows_the_kept_rows_and_columns_bilinearly() {
    let mut sim = curtain(9, &[]);
    sim.set_coarse(true).unwrap();
    assert!(sim.is_coarse());
    assert_eq!(sim.coarse_particle_count(), Some(25));
    run(&mut sim, 40);
    let x = sim.positions();
    let at = |i: usize, j: usize| x[j * 9 + i];
    // It swung down.
    assert!(
        at(4, 8).distance(Vec3::new(0.0, 0.0, 0.2)) > 0.3,
        "{}",
        at(4, 8)
    );
    for j in 0..9 {
        for i in 0..9 {
            let (i0, i1) = (i & !1, (i + 1) & !1);
            let (j0, j1) = (j & !1, (j + 1) & !1);
            let expect = 0.25 * (at(i0, j0) + at(i1, j0) + at(i0, j1) + at(i1, j1));
            assert!(at(i, j).distance(expect) < 1e-6, "({i}, {j})");
        }
    }
    // The pins hold.
    assert_eq!(at(0, 0), Vec3::new(-0.2, 0.0, -0.2));
    assert_eq!(at(8, 0), Vec3::new(0.2, 0.0, -0.2));
    // The coarse particles carry the whole mass.
    let (full, coarse): (f32, f32) = {
        let c = sim.coarse.as_ref().unwrap();
        (sim.masses().iter().sum(), c.sim.masses().iter().sum())
    };
    assert!((full - coarse).abs() < 1e-5 * full, "{full} {coarse}");
}

#[test]
fn a_coarse_curtain_hangs_like_the_full_one() {
    let (mut full, mut coarse) = (curtain(17, &[]), curtain(17, &[]));
    coarse.set_coarse(true).unwrap();
    run(&mut full, 300);
    run(&mut coarse, 300);
    let mean = |s: &ClothSim| s.positions().iter().sum::<Vec3>() / s.positions().len() as f32;
    let lowest = |s: &ClothSim| s.positions().iter().map(|p| p.y).fold(f32::MAX, f32::min);
    // 0.8 m wide: the centres of mass and the lowest points within 2 cm of each other.
    let (a, b) = (mean(&full), mean(&coarse));
    assert!(a.distance(b) < 0.02, "{a} {b}");
    assert!((lowest(&full) - lowest(&coarse)).abs() < 0.02);
}

#[test]
fn a_pin_off_the_kept_lines_keeps_its_row_and_column() {
    let mut sim = curtain(9, &[3]);
    sim.set_coarse(true).unwrap();
    // Columns 0, 2, 3, 4, 6, 8 of every kept row.
    assert_eq!(sim.coarse_particle_count(), Some(30));
    let target = sim.positions()[3] + Vec3::new(0.0, 0.0, 0.1);
    sim.move_pins([sim.positions()[0], sim.positions()[8], target]);
    run(&mut sim, 10);
    assert!(sim.positions()[3].distance(target) < 1e-6);
}

#[test]
fn an_edge_pinned_along_its_length_keeps_every_other_row() {
    // The first column held along a pole, as a flag is.
    let pole: Vec<u32> = (1..9).map(|j| 9 * j).collect();
    let mut sim = curtain(9, &pole);
    sim.set_coarse(true).unwrap();
    assert_eq!(sim.coarse_particle_count(), Some(25));
    let held: Vec<Vec3> = sim.positions().iter().step_by(9).copied().collect();
    run(&mut sim, 30);
    // Pins between kept pinned particles are on their targets all the same.
    for (j, x) in held.iter().enumerate() {
        assert_eq!(sim.positions()[9 * j], *x, "row {j}");
    }
}

#[test]
fn back_at_full_resolution_the_cloth_goes_on_from_where_it_was() {
    // One step after a switch moves no particle much farther than its speed takes it.
    let no_jump = |sim: &mut ClothSim, coarse: bool| {
        let before = sim.positions().to_vec();
        let speed = sim
            .velocities()
            .iter()
            .map(|v| v.length())
            .fold(0.0, f32::max);
        sim.set_coarse(coarse).unwrap();
        assert_eq!(sim.is_coarse(), coarse);
        sim.step(DT).unwrap();
        let moved = farthest(sim.positions(), &before);
        assert!(moved < 1.5 * speed * DT + 0.005, "{moved} m at {speed} m/s");
    };
    let mut sim = curtain(9, &[]);
    sim.set_coarse(true).unwrap();
    run(&mut sim, 20);
    no_jump(&mut sim, false);
    // And back again after a while: the coarse level takes up the full cloth's motion as it
    // is then, not as it was when the level was built.
    run(&mut sim, 30);
    no_jump(&mut sim, true);
}

#[test]
fn the_coarse_level_takes_over_without_moving_a_particle_at_once() {
    // A sheet at rest with a ripple between the kept columns: every odd column 1 cm up.
    let mut sim = curtain(17, &[]);
    let rippled: Vec<Vec3> = (sim.positions().iter().enumerate())
        .map(|(f, x)| *x + Vec3::Y * if f % 2 == 1 { 0.01 } else { 0.0 })
        .collect();
    sim.place(&rippled, &vec![Vec3::ZERO; rippled.len()])
        .unwrap();
    sim.set_coarse(true).unwrap();
    sim.step(DT).unwrap();
    // The ripple fades by a tenth a step (1 mm), and the sheet falls by g·dt² (2.7 mm) at most.
    let moved = farthest(sim.positions(), &rippled);
    assert!(moved < 0.004, "{moved} m");
    // Once it has faded the odd columns lie between their neighbours.
    run(&mut sim, COARSE_FADE_STEPS as usize);
    let x = sim.positions();
    let at = |i: usize, j: usize| x[j * 17 + i];
    assert!(at(5, 3).distance(0.5 * (at(4, 3) + at(6, 3))) < 1e-6);
}

#[test]
fn every_particle_keeps_within_its_own_target() {
    // Targets 5 mm off the sheet, up and down by turns along each row, each particle allowed
    // 1 mm from its own: the kept particles' interpolation alone puts the others 5 mm off.
    let mut sim = curtain(9, &[]);
    let targets: Vec<Target> = (sim.positions().iter().enumerate())
        .map(|(f, x)| Target {
            particle: f as u32,
            weight: 0.001,
            position: *x + Vec3::Y * if f % 2 == 0 { 0.005 } else { -0.005 },
            normal: Vec3::ZERO,
        })
        .collect();
    sim.set_targets(&targets).unwrap();
    sim.set_coarse(true).unwrap();
    run(&mut sim, 20);
    // The two pinned corners keep to their pins instead.
    for t in targets.iter().filter(|t| ![0, 8].contains(&t.particle)) {
        let off = sim.positions()[t.particle as usize].distance(t.position);
        assert!(off < 0.001 + 1e-5, "particle {}: {off} m", t.particle);
    }
}

#[test]
fn a_cloth_placed_at_its_coarse_level_goes_on_from_where_it_was_put() {
    let mut sim = curtain(9, &[]);
    sim.set_coarse(true).unwrap();
    run(&mut sim, 10);
    // Put 1 m aside, at rest, pins moved with it (as a frozen cloth thawing is placed).
    let aside: Vec<Vec3> = sim.positions().iter().map(|x| *x + Vec3::X).collect();
    sim.move_pins([aside[0], aside[8]]);
    sim.place(&aside, &vec![Vec3::ZERO; aside.len()]).unwrap();
    sim.step(DT).unwrap();
    let moved = farthest(sim.positions(), &aside);
    assert!(moved < 0.01, "{moved} m from where it was put");
}

#[test]
fn cloths_that_are_not_lattices_have_no_coarse_level() {
    let disc = ClothModel::disc(&DiscSpec::new(4, 8, 0.1)).unwrap();
    let mut sim = ClothSim::new(disc, SolverSettings::default(), |p| p).unwrap();
    let e = sim.set_coarse(true).unwrap_err();
    assert!(matches!(e, ClothError::NoCoarseLevel { .. }), "{e}");
    assert!(e.to_string().contains("lattice"), "{e}");
    assert!(!sim.is_coarse());
    let mut small = curtain(2, &[]);
    assert!(small.set_coarse(true).is_err());
    assert_eq!(small.coarse_particle_count(), None);
}

#[test]
fn a_cloth_torn_at_its_coarse_level_steps_on_at_full_resolution() {
    let mut sim = curtain(9, &[]);
    sim.set_coarse(true).unwrap();
    run(&mut sim, 2);
    let cut = Cut::Plane {
        point: Vec3::ZERO,
        normal: Vec3::Z,
    };
    assert!(!sim.tear(&[cut]).unwrap().is_empty());
    assert!(!sim.is_coarse());
    assert!(sim.set_coarse(true).is_err());
    run(&mut sim, 5);
}
