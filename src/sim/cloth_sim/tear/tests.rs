use glam::Vec3;

use super::{Cut, Split};
use crate::error::ClothError;
use crate::sim::{
    ClothModel, ClothSim, GridPlane, GridSpec, Integrator, Pressure, SolverSettings, Tearing,
};
use crate::subdivision::{BoundaryMode, Subdivider, VertexRule};

const DT: f32 = 1.0 / 60.0;

/// A vertical `n`×`n` grid, 2 cm apart, pinned at its top corners.
fn hanging(n: u32, settings: SolverSettings) -> ClothSim {
    let spec = GridSpec::new(n, n, 0.02).with_plane(GridPlane::Vertical);
    let mut sim = ClothSim::new(ClothModel::grid(&spec).unwrap(), settings, |p| p).unwrap();
    let top = [0, n - 1].map(|i| (i, sim.positions()[i as usize]));
    sim.set_pins(top).unwrap();
    sim
}

/// Each face's corners all lie in one piece, springs join only particles of one piece, and every
/// particle is one fan of faces (the torn mesh subdivides).
fn assert_pieces_separate(sim: &ClothSim) -> (usize, Vec<u32>) {
    let model = sim.model();
    let mesh = model.control_mesh().unwrap();
    if let Err(e) = Subdivider::new(&mesh, 1, VertexRule::Original, BoundaryMode::EdgeAndCorner) {
        panic!("the torn mesh does not subdivide: {e}");
    }
    let (count, piece) = model.pieces();
    for face in model.faces.chunks_exact(model.face_size) {
        let p = piece[face[0] as usize];
        assert!(
            face.iter().all(|&c| piece[c as usize] == p),
            "face {face:?} spans pieces"
        );
    }
    for (&a, &b) in model.springs.a.iter().zip(&model.springs.b) {
        assert_eq!(piece[a as usize], piece[b as usize]);
    }
    (count, piece)
}

#[test]
fn a_grid_cut_along_its_middle_row_falls_as_two_pieces() {
    let mut sim = hanging(64, SolverSettings::default());
    for _ in 0..30 {
        sim.step(DT).unwrap();
    }
    let mass: f64 = sim.masses().iter().map(|&m| f64::from(m)).sum();
    let row = 32 * 64;
    let point = sim.positions()[row + 32];
    let splits = sim
        .tear(&[Cut::Plane {
            point,
            normal: Vec3::Y,
        }])
        .unwrap();
    // Every particle of the row is split in two; the copies follow the cloth's.
    assert_eq!(splits.len(), 64, "{splits:?}");
    assert!(
        splits
            .iter()
            .all(|s| (row..row + 64).contains(&(s.particle as usize)))
    );
    assert_eq!(sim.positions().len(), 64 * 65);
    let (count, piece) = assert_pieces_separate(&sim);
    assert_eq!(count, 2);
    // The row's own particles went one way, their copies the other.
    for s in &splits {
        assert_ne!(piece[s.particle as usize], piece[s.copy as usize]);
        assert_eq!(sim.positions()[s.copy as usize], s.position);
    }
    let total: f64 = sim.masses().iter().map(|&m| f64::from(m)).sum();
    assert!(
        (total - mass).abs() < 1e-7 * mass,
        "mass {mass} became {total}"
    );
    // The upper piece hangs on; the lower one falls free.
    let lowest = |sim: &ClothSim, which: u32| {
        sim.positions()
            .iter()
            .zip(&piece)
            .filter(|(_, p)| **p == which)
            .map(|(x, _)| x.y)
            .fold(f32::INFINITY, f32::min)
    };
    let hanging_piece = piece[0];
    let falling_piece = 1 - hanging_piece;
    let (top0, bottom0) = (lowest(&sim, hanging_piece), lowest(&sim, falling_piece));
    for _ in 0..30 {
        sim.step(DT).unwrap();
    }
    let fell = bottom0 - lowest(&sim, falling_piece);
    assert!(
        fell > 0.9 * 0.5 * 9.81 * 0.25,
        "the lower piece fell {fell} m in 0.5 s"
    );
    assert!((lowest(&sim, hanging_piece) - top0).abs() < 0.05);
}

#[test]
fn a_ray_punches_a_hole_and_a_blade_cuts_a_slit() {
    let mut sim = hanging(24, SolverSettings::default());
    sim.step(DT).unwrap();
    let centre = sim.positions()[12 * 24 + 12];
    let before = sim.positions().len();
    let splits = sim
        .tear(&[Cut::Ray {
            origin: centre - Vec3::Z,
            direction: Vec3::Z,
            radius: 0.05,
        }])
        .unwrap();
    assert!(!splits.is_empty());
    let (count, piece) = assert_pieces_separate(&sim);
    assert_eq!(count, 2, "the hole's disc is a piece of its own");
    let disc = piece[12 * 24 + 12];
    let in_disc = piece.iter().filter(|&&p| p == disc).count();
    assert!(
        in_disc > 4 && in_disc < 64,
        "{in_disc} particles in the disc"
    );
    assert_eq!(sim.positions().len(), before + splits.len());

    // A slit from one side to the middle: still one piece, but no spring crosses it.
    let mut sim = hanging(24, SolverSettings::default());
    sim.step(DT).unwrap();
    let (start, end) = (sim.positions()[10 * 24], sim.positions()[10 * 24 + 12]);
    let splits = sim
        .tear(&[Cut::Segment {
            start: start - 0.03 * Vec3::X,
            end,
            radius: 0.01,
        }])
        .unwrap();
    assert!(splits.len() >= 10, "{splits:?}");
    let (count, _) = assert_pieces_separate(&sim);
    assert_eq!(count, 1);
    let x = sim.positions();
    let model = sim.model();
    let crosses = model
        .springs
        .a
        .iter()
        .zip(&model.springs.b)
        .filter(|&(&a, &b)| {
            let (p, q) = (x[a as usize], x[b as usize]);
            let below = |v: Vec3| v.y < start.y - 1e-4;
            let above = |v: Vec3| v.y > start.y + 1e-4;
            let inside = p.x.max(q.x) < end.x - 0.015;
            inside && (below(p) && above(q) || above(p) && below(q))
        })
        .count();
    assert_eq!(crosses, 0, "springs cross the slit");
}

/// The largest structural stretch a heavy hanging cloth reaches over its first second.
fn peak_stretch(settings: SolverSettings) -> f32 {
    let mut sim = hanging(16, settings);
    let mut peak = 0.0f32;
    for _ in 0..60 {
        sim.step(DT).unwrap();
        peak = peak.max(sim.max_strain(crate::sim::SpringKind::Structural));
    }
    peak
}

#[test]
fn a_cloth_tears_past_its_threshold_and_never_below_it() {
    let settings = SolverSettings {
        integrator: Integrator::Xpbd,
        particle_mass: 0.05,
        ..SolverSettings::default()
    };
    let peak = peak_stretch(settings);
    assert!(peak > 0.05, "the load stretches the springs: {peak}");
    let run = |max_stretch: f32| {
        let tearing = Tearing {
            enabled: true,
            max_stretch,
            ..Tearing::default()
        };
        let mut sim = hanging(
            16,
            SolverSettings {
                tearing,
                ..settings
            },
        );
        let mut splits = Vec::new();
        for _ in 0..60 {
            sim.step(DT).unwrap();
            let torn: Vec<Split> = sim.tear(&[]).unwrap();
            assert!(torn.len() <= tearing.max_per_step as usize);
            splits.extend(torn);
        }
        (sim, splits)
    };
    let (sim, splits) = run(1.02 * peak);
    assert!(splits.is_empty(), "tore under its threshold: {splits:?}");
    assert_eq!(sim.tears(), 0);
    let (sim, splits) = run(0.9 * peak);
    assert!(!splits.is_empty(), "did not tear past its threshold");
    assert_eq!(sim.tears(), splits.len() as u64);
    // Pinned particles never split under strain.
    assert!(splits.iter().all(|s| s.particle != 0 && s.particle != 15));
    assert_pieces_separate(&sim);
}

#[test]
fn a_bad_cut_is_an_error_and_changes_nothing() {
    let mut sim = hanging(8, SolverSettings::default());
    let before = sim.positions().to_vec();
    for cut in [
        Cut::Plane {
            point: Vec3::NAN,
            normal: Vec3::Y,
        },
        Cut::Plane {
            point: Vec3::ZERO,
            normal: Vec3::ZERO,
        },
        Cut::Ray {
            origin: Vec3::ZERO,
            direction: Vec3::Z,
            radius: -1.0,
        },
        Cut::Segment {
            start: Vec3::ONE,
            end: Vec3::ONE,
            radius: 0.1,
        },
    ] {
        let e = sim.tear(&[cut]).unwrap_err();
        assert!(matches!(e, ClothError::InvalidValue { .. }), "{cut:?}: {e}");
    }
    assert_eq!(sim.positions(), before);
    // Off, and no cut: nothing to do.
    assert!(sim.tear(&[]).unwrap().is_empty());
    assert_eq!(sim.tears(), 0);
}

#[test]
fn copies_keep_their_particles_targets_and_pieces_torn_free_lose_theirs() {
    let targeted = |pinned: bool| {
        let mut sim = hanging(8, SolverSettings::default());
        if !pinned {
            sim.set_pins([]).unwrap();
        }
        let targets: Vec<_> = (8..16)
            .map(|p| crate::sim::Target {
                particle: p,
                weight: 1.0,
                position: sim.positions()[p as usize],
                normal: Vec3::Z,
            })
            .collect();
        sim.set_targets(&targets).unwrap();
        let point = sim.positions()[8];
        let splits = sim
            .tear(&[Cut::Plane {
                point,
                normal: Vec3::Y,
            }])
            .unwrap();
        assert_eq!(splits.len(), 8);
        sim
    };
    // Nothing holds the cloth: both pieces keep their targets, the copies their particles'.
    let sim = targeted(false);
    let mut particles: Vec<u32> = sim.targeted().collect();
    particles.sort_unstable();
    assert_eq!(particles, (8..16).chain(64..72).collect::<Vec<_>>());
    // Pinned at its top corners: the lower piece is torn free and loses its targets; the pins
    // stay where they were.
    let sim = targeted(true);
    let (_, pieces) = sim.model().pieces();
    let held = pieces[0];
    assert_eq!(sim.targeted().count(), 8);
    assert!(sim.targeted().all(|p| pieces[p as usize] == held));
    assert_eq!(sim.pinned().collect::<Vec<_>>(), [0, 7]);
}

#[test]
fn a_torn_closed_cloth_loses_its_air() {
    let model = ClothModel::icosphere(0.2, 2).unwrap();
    let settings = SolverSettings {
        pressure: Pressure::gas(4.0 / 3.0 * std::f32::consts::PI * 0.008, 2000.0),
        ..SolverSettings::default()
    };
    let mut sim = ClothSim::new(model, settings, |p| p).unwrap();
    sim.step(DT).unwrap();
    assert!(sim.pressure().is_some());
    sim.tear(&[Cut::Plane {
        point: Vec3::ZERO,
        normal: Vec3::Y,
    }])
    .unwrap();
    assert_eq!(sim.model().pieces().0, 2);
    assert!(sim.pressure().is_none());
    // Its settings, pressure on, are still accepted.
    sim.set_settings(settings).unwrap();
    sim.step(DT).unwrap();
}

#[test]
fn a_tear_that_reaches_the_edge_leaves_no_particle_joining_two_fans() {
    // A 3×3 grid split at its centre, top to bottom: the new edges end at the middles of the top
    // and bottom edges, which would join the two sides by a vertex alone.
    let model = ClothModel::grid(&GridSpec::new(3, 3, 0.1)).unwrap();
    let mut sim = ClothSim::new(model, SolverSettings::default(), |p| p).unwrap();
    let centre = sim.positions()[4];
    let splits = sim
        .tear(&[Cut::Segment {
            start: centre - 0.01 * Vec3::Z,
            end: centre + 0.01 * Vec3::Z,
            radius: 0.02,
        }])
        .unwrap();
    let split: Vec<u32> = splits.iter().map(|s| s.particle).collect();
    assert_eq!(split, [4, 1, 7], "{splits:?}");
    let (count, _) = assert_pieces_separate(&sim);
    assert_eq!(count, 2);
}

#[test]
fn the_sides_of_a_tear_collide_once_they_have_parted() {
    // A 5 mm thick cloth cut in two: its sides lay together at rest, and are kept apart less
    // than the thickness while they touch; once the lower piece has fallen away they collide like
    // any layers.
    let settings = SolverSettings {
        self_collision: crate::sim::SelfCollision {
            enabled: true,
            thickness: 0.005,
            ..Default::default()
        },
        ..SolverSettings::default()
    };
    let mut sim = hanging(16, settings);
    let contacts = |sim: &ClothSim| {
        let c = sim.contacts.self_contacts().unwrap();
        (c.exempt_count(), c.parting_count())
    };
    assert_eq!(
        contacts(&sim),
        (0, 0),
        "a flat grid 2 cm apart has no pairs within 5 mm at rest"
    );
    sim.step(DT).unwrap();
    let point = sim.positions()[8 * 16];
    sim.tear(&[Cut::Plane {
        point,
        normal: Vec3::Y,
    }])
    .unwrap();
    let (exempt, together) = contacts(&sim);
    assert_eq!(exempt, 0, "no pair across the cut is exempt for good");
    assert!(
        together > 0,
        "the sides of the cut are parting while together"
    );
    for _ in 0..10 {
        sim.step(DT).unwrap();
    }
    assert_eq!(
        contacts(&sim),
        (0, 0),
        "the sides parted: none left of {together}"
    );
}

#[test]
fn tear_weights_scale_the_threshold_particle_by_particle() {
    let settings = SolverSettings {
        integrator: Integrator::Xpbd,
        particle_mass: 0.05,
        ..SolverSettings::default()
    };
    let peak = peak_stretch(settings);
    let tearing = Tearing {
        enabled: true,
        max_stretch: 0.9 * peak,
        ..Tearing::default()
    };
    // Past the limit everywhere, but weights that lift it over the peak, except (in the second
    // run) along the column i = 1, a weak seam beside a pin.
    let run = |weak: f32| {
        let mut sim = hanging(
            16,
            SolverSettings {
                tearing,
                ..settings
            },
        );
        let weights = (0..256)
            .map(|p| if p % 16 == 1 { weak } else { 1.3 })
            .collect();
        sim.set_tear_weights(Some(weights)).unwrap();
        let mut splits = Vec::new();
        for _ in 0..60 {
            sim.step(DT).unwrap();
            splits.extend(sim.tear(&[]).unwrap());
        }
        splits
    };
    assert!(
        run(1.3).is_empty(),
        "tore with every weight lifting the limit"
    );
    let splits = run(0.3);
    assert!(!splits.is_empty(), "the weak seam did not tear");
    for s in &splits {
        let column = s.particle % 16;
        assert!(column <= 2, "tore at column {column}, off the seam");
    }
    // Bad weights change nothing.
    let mut sim = hanging(16, settings);
    assert!(sim.set_tear_weights(Some(vec![1.0; 3])).is_err());
    assert!(sim.set_tear_weights(Some(vec![-1.0; 256])).is_err());
    assert!(sim.tear_weights().is_none());
}

#[test]
fn a_torn_grid_whose_copies_do_not_match_its_particles_is_refused() {
    let mut sim = hanging(8, SolverSettings::default());
    let point = sim.positions()[4 * 8];
    sim.tear(&[Cut::Plane {
        point,
        normal: Vec3::Y,
    }])
    .unwrap();
    let torn = sim.model().clone();
    assert!(torn.torn_grid.is_some(), "a torn grid remembers its grid");
    assert_eq!(torn.validate(), Ok(()));
    let mut extra = torn.clone();
    extra.torn_grid.as_mut().unwrap().origins.push(0);
    let mut outside = torn;
    outside.torn_grid.as_mut().unwrap().origins[0] = 64;
    for model in [extra, outside] {
        assert!(
            matches!(model.validate(), Err(ClothError::InvalidMesh { .. })),
            "{:?}",
            model.validate()
        );
    }
}
