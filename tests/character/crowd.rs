//! Characters from a scene file: capes on walking torsos, each copy on its own phase.

use bevy::prelude::*;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::{ClothScene, Walker};

use crate::common;

#[test]
fn scene_characters_walk_their_circles_with_their_capes_on() {
    let scene = ClothScene::from_ron(
        "(cloth: Cape(nx: 8, ny: 10), walk: (speed: 1.5, radius: 1.0, sway: 0.4),
          copies: (count: 2, spacing: 5.0, phase: 0.5),
          also: [(cloth: Grid((nx: 4, ny: 4, spacing: 0.1)), translation: (0.0, 1.0, -5.0), pins: [0, 3])])",
    )
    .unwrap();
    let mut app = common::app();
    let cloths = scene.spawn_copies(app.world_mut()).unwrap();
    assert_eq!(cloths.len(), 3);
    common::run(&mut app, 90);
    for &c in &cloths {
        assert!(app.world().get::<ClothInvalid>(c).is_none());
    }
    // Each character's root walks its circle from its own placement, the second half a second
    // ahead: 1.5 s and 2 s along a circle of 1 m at 1.5 m/s.
    let mut roots: Vec<(Entity, Walker)> = app
        .world_mut()
        .query::<(Entity, &Walker)>()
        .iter(app.world())
        .map(|(e, w)| (e, *w))
        .collect();
    roots.sort_by(|a, b| a.1.phase.total_cmp(&b.1.phase));
    assert_eq!(roots.len(), 2);
    assert_eq!(roots[1].1.phase, 0.5);
    let global = |e: Entity| app.world().get::<GlobalTransform>(e).unwrap().translation();
    for (k, &(root, walker)) in roots.iter().enumerate() {
        let t = 1.5 + walker.phase;
        let expected = Vec3::new(1.0 - (1.5 * t).cos(), 0.0, (1.5 * t).sin())
            + Vec3::new(5.0 * k as f32, 0.0, 0.0);
        assert!(
            (global(root) - expected).length() < 1e-4,
            "{k}: {} vs {expected}",
            global(root)
        );
    }
    // Each cape's collar is pinned to its skin: it hangs from its own character's spine, 1.5 m
    // up and within a cape's width of the root.
    for (k, &(root, _)) in roots.iter().enumerate() {
        let cape = cloths[k];
        let state = common::state(&app, cape);
        let pinned: Vec<Vec3> = state
            .targets()
            .filter(|t| t.weight == 0.0)
            .map(|t| t.position)
            .collect();
        assert_eq!(pinned.len(), 8);
        for p in pinned {
            assert!((p.y - 1.5).abs() < 1e-3, "{p}");
            assert!(
                (p - global(root)).with_y(0.0).length() < 0.5,
                "{p} vs {}",
                global(root)
            );
        }
        let top = state.positions()[3];
        assert!((top.y - 1.5).abs() < 1e-3, "{top}");
    }
    // The two capes are in different poses: the phases differ.
    let p0 = common::state(&app, cloths[0]).positions()[75] - global(roots[0].0);
    let p1 = common::state(&app, cloths[1]).positions()[75] - global(roots[1].0);
    assert!((p0 - p1).length() > 0.05, "{p0} {p1}");
}
