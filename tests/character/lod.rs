//! Levels of detail on scene characters: what each level does, that the cloths at full quality
//! are exactly what they are without levels, and that a change of level does not make the cloth
//! jump.

use bevy::prelude::*;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::{ClothScene, Walker};

use crate::common;

/// Capes on walking characters, 6 m apart in a row along +X, each with levels of detail at 6 m
/// (reduced), 10 m (coarse), 14 m (frozen) and 30 m (culled), and a viewer at `viewer`.
fn crowd(count: u32, viewer: &str, walk: &str) -> ClothScene {
    ClothScene::from_ron(&format!(
        "(cloth: Cape(nx: 8, ny: 10), walk: {walk},
          solver: (targets: (max_distance_scale: 0.35), tethers: (enabled: true, slack: 0.05)),
          copies: (count: {count}, columns: Some({count}), spacing: 6.0, phase: 0.4),
          lod: Some((reduced: 6.0, coarse: 10.0, frozen: 14.0, culled: 30.0)),
          viewer: {viewer})"
    ))
    .unwrap()
}

fn levels(app: &App, cloths: &[Entity]) -> Vec<LodLevel> {
    cloths
        .iter()
        .map(|&c| app.world().get::<ClothLodLevel>(c).unwrap().level)
        .collect()
}

#[test]
fn the_ten_nearest_cloths_are_bit_identical_to_a_crowd_without_levels() {
    // Twenty characters on a 5 × 4 layout 6 m apart, the viewer 14 m off its side, seeing it
    // all: full quality within 30 m holds the ten nearest (two columns and a half).
    let viewer = "Some((from: (-14.0, 2.0, 9.0), look_at: Some((12.0, 1.0, 9.0))))";
    let mut with = crowd(20, viewer, "(speed: 1.2, radius: 2.0, sway: 0.35)");
    with.copies.columns = Some(5);
    with.lod = with.lod.map(|lod| ClothLod {
        reduced: 30.0,
        coarse: 33.0,
        frozen: 36.0,
        culled: 60.0,
        ..lod
    });
    let mut without = with.clone();
    (without.lod, without.viewer) = (None, None);
    let mut apps = [common::app(), common::app()];
    let ca = with.spawn_copies(apps[0].world_mut()).unwrap();
    let cb = without.spawn_copies(apps[1].world_mut()).unwrap();
    let mut full_throughout = vec![true; ca.len()];
    let mut seen = [0usize; 5];
    for _ in 0..120 {
        apps[0].update();
        apps[1].update();
        for (k, level) in levels(&apps[0], &ca).into_iter().enumerate() {
            full_throughout[k] &= level == LodLevel::Full;
            seen[level as usize] += 1;
        }
    }
    // The farther ones ran reduced, coarse and frozen.
    assert!(seen[1] > 0 && seen[2] > 0 && seen[3] > 0, "{seen:?}");
    let measure = |k: usize| apps[0].world().get::<ClothLodLevel>(ca[k]).unwrap().measure;
    let mut nearest: Vec<usize> = (0..ca.len()).collect();
    nearest.sort_by(|&a, &b| measure(a).total_cmp(&measure(b)));
    for &k in &nearest[..10] {
        assert!(
            full_throughout[k],
            "cape {k}, {} m off, was not at full quality",
            measure(k)
        );
        let (pa, pb) = (
            common::state(&apps[0], ca[k]).positions(),
            common::state(&apps[1], cb[k]).positions(),
        );
        assert!(
            pa.iter()
                .zip(pb)
                .all(|(x, y)| x.to_array().map(f32::to_bits) == y.to_array().map(f32::to_bits)),
            "cape {k} differs from its twin without levels"
        );
    }
    // The farthest did less work, and moved otherwise.
    let far = nearest[ca.len() - 1];
    assert!(!full_throughout[far]);
    assert_ne!(
        common::state(&apps[0], ca[far]).positions(),
        common::state(&apps[1], cb[far]).positions()
    );
}

/// The rendered vertices of cloth `cloth`: its mesh under its transform.
fn rendered(app: &App, cloth: Entity) -> Vec<Vec3> {
    let mesh = app
        .world()
        .resource::<Assets<Mesh>>()
        .get(common::state(app, cloth).mesh())
        .unwrap();
    let Some(bevy::mesh::VertexAttributeValues::Float32x3(local)) =
        mesh.attribute(Mesh::ATTRIBUTE_POSITION)
    else {
        panic!("positions");
    };
    let to_world = app.world().get::<GlobalTransform>(cloth).unwrap().affine();
    local
        .iter()
        .map(|&p| to_world.transform_point3(Vec3::from(p)))
        .collect()
}

/// The vertices of `pose` in the space of `frame`'s global transform.
fn in_frame(app: &App, pose: &[Vec3], frame: Entity) -> Vec<Vec3> {
    let to_frame = app
        .world()
        .get::<GlobalTransform>(frame)
        .unwrap()
        .affine()
        .inverse();
    pose.iter().map(|&p| to_frame.transform_point3(p)).collect()
}

/// One character walking as `walk` says, its cape seen by a viewer 20 m off, in a new App.
fn cape_seen_from_20_m(walk: &str) -> (App, Entity) {
    let viewer = "Some((from: (0.0, 1.5, -20.0), look_at: Some((0.0, 1.0, 0.0))))";
    let mut app = common::app();
    let cape = crowd(1, viewer, walk)
        .spawn_copies(app.world_mut())
        .unwrap()[0];
    (app, cape)
}

#[test]
fn a_frozen_cape_keeps_its_pose_on_its_walking_character() {
    // The cape is frozen (between 14 and 30 m) after its first steps.
    let (mut app, cape) = cape_seen_from_20_m("(speed: 1.2, radius: 2.0, sway: 0.35)");
    let root = app
        .world_mut()
        .query_filtered::<Entity, With<Walker>>()
        .single(app.world())
        .unwrap();
    common::run(&mut app, 2);
    assert_eq!(levels(&app, &[cape]), [LodLevel::Frozen]);
    let level = *app.world().get::<ClothLodLevel>(cape).unwrap();
    assert!(
        level.seen && (level.measure - 19.0).abs() < 1.5,
        "{level:?}"
    );
    let steps = common::state(&app, cape).steps();
    let pose = in_frame(&app, &rendered(&app, cape), root);
    let start = app
        .world()
        .get::<GlobalTransform>(root)
        .unwrap()
        .translation();
    common::run(&mut app, 60);
    // No step was taken; the character walked 1.2 m along its circle (and swayed), and the cape
    // went with it: in the root's frame the hem moved only by the sway of the spine.
    assert_eq!(common::state(&app, cape).steps(), steps);
    let walked = app
        .world()
        .get::<GlobalTransform>(root)
        .unwrap()
        .translation()
        .distance(start);
    assert!(walked > 1.0, "{walked}");
    let now = in_frame(&app, &rendered(&app, cape), root);
    let moved = pose
        .iter()
        .zip(&now)
        .map(|(a, b)| a.distance(*b))
        .fold(0.0, f32::max);
    assert!(moved < 0.35, "{moved}");
    // The collar, pinned to the spine, still sits on its targets.
    let state = common::state(&app, cape);
    for t in state.targets().filter(|t| t.weight == 0.0) {
        let x = state.positions()[t.particle as usize];
        assert!(x.distance(t.position) < 1e-3, "{x} vs {}", t.position);
    }
}

#[test]
fn a_coarse_cape_follows_its_character_with_every_vertex() {
    // 12 m off: coarse (between 10 and 14 m).
    let viewer = "Some((from: (0.0, 1.5, -12.0), look_at: Some((0.0, 1.0, 0.0))))";
    let mut app = common::app();
    let scene = crowd(1, viewer, "(speed: 1.2, radius: 2.0, sway: 0.35)");
    let cape = scene.spawn_copies(app.world_mut()).unwrap()[0];
    common::run(&mut app, 90);
    assert_eq!(levels(&app, &[cape]), [LodLevel::Coarse]);
    let sim = common::sim(&app, cape);
    assert!(sim.is_coarse());
    let state = common::state(&app, cape);
    // Every particle keeps within its target's reach, the collar's on its skin, kept or not.
    let reach = 0.35;
    for t in state.targets() {
        let off = state.positions()[t.particle as usize].distance(t.position);
        assert!(
            off <= t.weight * reach + 1e-4,
            "particle {}: {off} m",
            t.particle
        );
    }
    // The mesh drawn is the whole cape's.
    assert_eq!(rendered(&app, cape).len(), state.positions().len());
}

#[test]
fn no_rendered_vertex_jumps_at_a_change_of_level() {
    // One character walking its circle, swaying slowly, settled at full quality for 3 s; then the
    // viewer backs away from 2.5 m to 50 m and comes back over 8 s, taking the cape through every
    // level and back (culled past 30 m). Its twin in a second App never culls: it stays frozen
    // where the first is culled.
    let scene = crowd(
        1,
        "None",
        "(speed: 1.0, radius: 2.0, sway: 0.2, sway_rate: 0.15)",
    );
    let mut twin_scene = scene.clone();
    twin_scene.lod = twin_scene.lod.map(|lod| ClothLod {
        culled: f32::INFINITY,
        cull_unseen: false,
        ..lod
    });
    let at =
        |z: f32| Transform::from_xyz(2.0, 1.5, z).looking_at(Vec3::new(2.0, 1.0, 0.0), Vec3::Y);
    let [(mut app, cape, viewer), (mut twin, twin_cape, twin_viewer)] =
        [scene, twin_scene].map(|scene| {
            let mut app = common::app();
            let cape = scene.spawn_copies(app.world_mut()).unwrap()[0];
            let viewer = app
                .world_mut()
                .spawn((at(-2.5), ClothViewer::default()))
                .id();
            common::run(&mut app, 180);
            (app, cape, viewer)
        });
    // The last two poses drawn, and the level of the last.
    let mut drawn = [rendered(&app, cape), rendered(&app, cape)];
    let mut drawn_level = LodLevel::Full;
    // Frames drawn in a row: a pop needs the two before.
    let mut in_a_row = 2;
    let mut visited = vec![LodLevel::Full];
    let (mut worst_pop, mut worst_steady, mut returned): (f32, f32, u32) = (0.0, 0.0, 0);
    for frame in 1..=480 {
        let out = 1.0 - (frame as f32 / 240.0 - 1.0).abs();
        for (app, viewer) in [(&mut app, viewer), (&mut twin, twin_viewer)] {
            *app.world_mut().get_mut::<Transform>(viewer).unwrap() = at(-2.5 - 47.5 * out);
            app.update();
        }
        let level = levels(&app, &[cape])[0];
        let back = visited.last() == Some(&LodLevel::Culled) && level != LodLevel::Culled;
        if visited.last() != Some(&level) {
            visited.push(level);
        }
        if level == LodLevel::Culled {
            // Not drawn.
            continue;
        }
        let now = rendered(&app, cape);
        in_a_row += 1;
        if back {
            in_a_row = 1;
            // Back from culled where it would have been had it stayed frozen.
            let there = rendered(&twin, twin_cape);
            let off = now
                .iter()
                .zip(&there)
                .map(|(a, b)| a.distance(*b))
                .fold(0.0, f32::max);
            assert!(off < 1e-4, "back from culled {off} m from its frozen twin");
            returned += 1;
        } else if in_a_row > 2 {
            // A pop is motion the last two frames did not lead up to: the second difference.
            let pop = now
                .iter()
                .zip(&drawn[0])
                .zip(&drawn[1])
                .map(|((x, a), b)| (*x - 2.0 * *b + *a).length())
                .fold(0.0, f32::max);
            if level != drawn_level {
                worst_pop = worst_pop.max(pop);
            } else {
                worst_steady = worst_steady.max(pop);
            }
        }
        drawn = [std::mem::take(&mut drawn[1]), now];
        drawn_level = level;
    }
    use LodLevel::*;
    assert_eq!(
        visited,
        [
            Full, Reduced, Coarse, Frozen, Culled, Frozen, Coarse, Reduced, Full
        ],
        "the levels out and back"
    );
    assert_eq!(returned, 1);
    assert!(
        worst_pop < 0.01,
        "a change of level moved a vertex by {worst_pop} m more than its motion led to \
         (at most {worst_steady} m in frames without a change)"
    );
}

#[test]
fn a_budget_lowers_levels_no_further_than_frozen() {
    // Six characters 3 to 33 m down the row: all within reach of full quality but the last.
    let viewer = "Some((from: (-3.0, 1.5, 0.0), look_at: Some((40.0, 1.5, 0.0))))";
    let mut scene = crowd(6, viewer, "(speed: 1.2, radius: 2.0)");
    for (budget, expect) in [(1e-6, LodLevel::Frozen), (1e6, LodLevel::Full)] {
        scene.budget_ms = Some(budget);
        let mut app = common::app();
        let cloths = scene.spawn_copies(app.world_mut()).unwrap();
        common::run(&mut app, 10);
        let first = *app.world().get::<ClothLodLevel>(cloths[0]).unwrap();
        assert_eq!(first.wanted, LodLevel::Full);
        assert_eq!(first.level, expect, "budget {budget} ms");
        // The last, which wants to be culled, is.
        assert_eq!(levels(&app, &cloths)[5], LodLevel::Culled);
    }
}

#[test]
fn a_cloth_with_no_coarse_level_runs_reduced_instead() {
    // A 2 × 2 grid keeps every row and column: it has no coarse level. Seen from 10 m, between
    // its coarse and frozen thresholds.
    let mut app = common::app();
    app.world_mut()
        .spawn((Transform::from_xyz(0.0, 0.0, 10.0), ClothViewer::default()));
    let cloth = app
        .world_mut()
        .spawn((
            Cloth::grid(GridSpec::new(2, 2, 0.1)),
            ClothLod {
                reduced: 1.0,
                coarse: 2.0,
                frozen: 50.0,
                culled: 100.0,
                ..default()
            },
        ))
        .id();
    common::run(&mut app, 3);
    let level = *app.world().get::<ClothLodLevel>(cloth).unwrap();
    assert_eq!(
        (level.wanted, level.level),
        (LodLevel::Coarse, LodLevel::Reduced)
    );
    let sim = common::sim(&app, cloth);
    assert!(!sim.is_coarse());
    assert_eq!(sim.detail(), 0.5);
}

#[test]
fn an_invalid_or_removed_level_of_detail_leaves_full_quality() {
    // The cape freezes.
    let (mut app, cape) = cape_seen_from_20_m("(speed: 1.2, radius: 2.0)");
    common::run(&mut app, 3);
    assert_eq!(levels(&app, &[cape]), [LodLevel::Frozen]);
    let steps = common::state(&app, cape).steps();
    let lod = *app.world().get::<ClothLod>(cape).unwrap();
    // An invalid setting: full quality, stepping again.
    app.world_mut().entity_mut(cape).insert(ClothLod {
        hysteresis: 2.0,
        ..lod
    });
    common::run(&mut app, 2);
    assert_eq!(levels(&app, &[cape]), [LodLevel::Full]);
    assert_eq!(common::state(&app, cape).steps(), steps + 2);
    // Valid again: frozen; removed: full quality.
    app.world_mut().entity_mut(cape).insert(lod);
    common::run(&mut app, 2);
    assert_eq!(levels(&app, &[cape]), [LodLevel::Frozen]);
    let steps = common::state(&app, cape).steps();
    app.world_mut().entity_mut(cape).remove::<ClothLod>();
    common::run(&mut app, 2);
    assert_eq!(common::state(&app, cape).steps(), steps + 2);
    assert_eq!(common::sim(&app, cape).detail(), 1.0);
}
