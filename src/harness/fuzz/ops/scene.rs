//! The fuzzer's operations on the world around the cloths: source mesh assets swapped in place
//! (same topology, another topology, broken), pin anchor entities and character joints moved
//! and despawned, colliders, wind and wind zones (valid and not finite), and with the `avian`
//! feature, avian bodies and the two-way coupling switch.

use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy::transform::components::Transform;

use super::super::Rng;
use super::super::model::{Breakage, BuiltMesh, Fixture, Shape, Source, Validity, cape, sheet};
use super::Applied;
use crate::components::{ClothCollider, Wind, WindZone};
use crate::sim::{Friction, Gusts, WindZoneShape};

/// Replaces a mesh asset's contents under the same handle (one that a cloth uses, mostly):
/// the same topology moved, another topology, or a broken mesh. Every cloth made from it may be
/// rebuilt.
pub(super) fn swap_mesh(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    let used: Vec<usize> = fx
        .cloths
        .iter()
        .filter_map(|c| match c.source {
            Source::Mesh(i) => Some(i),
            Source::Grid { .. } => None,
        })
        .collect();
    let index = match (used.is_empty(), fx.meshes.is_empty()) {
        (false, _) if rng.chance(0.85) => rng.pick(&used),
        (_, false) => rng.index(fx.meshes.len()),
        (_, true) => {
            let built = sheet(5, 5, 0.08, 0.0, false);
            fx.add_mesh(built)
        }
    };
    let shape = fx.meshes[index].shape;
    let same = |rng: &mut Rng| match shape {
        Shape::Sheet { nx, ny, colors } => {
            sheet(nx, ny, rng.float(0.05, 0.1), rng.float(0.0, 0.05), colors)
        }
        Shape::Cape { nx, ny } => cape(nx, ny, rng.float(0.0, 0.2)).0,
    };
    let (mut built, mut kind) = match rng.below(if fx.invalid { 6 } else { 4 }) {
        0 | 1 => (same(rng), "mesh swap: same topology"),
        2 | 3 => {
            let (nx, ny) = (rng.range(4, 8), rng.range(4, 7));
            let built = if rng.chance(0.5) {
                sheet(nx, ny, 0.07, 0.02, rng.chance(0.5))
            } else {
                cape(nx.max(5), ny, 0.0).0
            };
            (built, "mesh swap: other topology")
        }
        _ => {
            let breakage = rng.pick(&Breakage::ALL);
            (breakage.apply(same(rng)), breakage.kind())
        }
    };
    if !fx.invalid && !keeps_cloths_valid(fx, index, &built) {
        (built, kind) = (same(rng), "mesh swap: same topology");
    }
    let detail = format!(
        "swap mesh asset {index} ({}) for {}",
        fx.meshes[index].label, built.label
    );
    fx.swap_mesh(index, built);
    let mut applied = Applied::new(kind, detail);
    applied.topology = fx
        .cloths
        .iter()
        .filter(|c| c.source == Source::Mesh(index))
        .map(|c| c.entity)
        .collect();
    applied.min_steps = 2;
    applied
}

/// Whether every cloth made from mesh asset `index` would stay valid with `built` in it.
fn keeps_cloths_valid(fx: &Fixture, index: usize, built: &BuiltMesh) -> bool {
    let mut meshes = fx.meshes.clone();
    let asset = &mut meshes[index];
    (asset.vertices, asset.validity) = (built.vertices, built.validity);
    (asset.colors, asset.joints) = (built.colors, built.joints);
    fx.cloths
        .iter()
        .filter(|c| c.source == Source::Mesh(index))
        .all(|c| c.validity(&meshes) == Validity::Valid)
}

/// Spawns, moves or despawns an entity that pins may be anchored to.
pub(super) fn edit_anchor(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    let at = Vec3::new(
        rng.float(-1.5, 1.5),
        rng.float(0.5, 2.0),
        rng.float(-1.5, 1.5),
    );
    let live: Vec<Entity> = fx
        .anchors
        .iter()
        .copied()
        .filter(|&e| fx.app.world().get_entity(e).is_ok())
        .collect();
    match rng.below(3) {
        _ if live.is_empty() || fx.anchors.len() < 2 && rng.chance(0.5) => {
            let e = fx
                .app
                .world_mut()
                .spawn(Transform::from_translation(at))
                .id();
            fx.anchors.push(e);
            Applied::new("anchor: spawned", format!("spawn anchor {e} at {at}"))
        }
        0 => {
            let e = rng.pick(&live);
            fx.app
                .world_mut()
                .entity_mut(e)
                .insert(Transform::from_translation(at));
            Applied::new("anchor: moved", format!("move anchor {e} to {at}"))
        }
        _ => {
            let e = rng.pick(&live);
            fx.app.world_mut().despawn(e);
            Applied::new("anchor: despawned", format!("despawn anchor {e}"))
        }
    }
}

/// Walks a character's torso on, or despawns one of its joints (the spine, or the root with the
/// spine under it).
pub(super) fn edit_joint(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    let live: Vec<(Entity, Entity)> = fx
        .joints
        .iter()
        .copied()
        .filter(|&(root, _)| fx.app.world().get_entity(root).is_ok())
        .collect();
    if live.is_empty() {
        return edit_anchor(fx, rng);
    }
    let (root, spine) = rng.pick(&live);
    let world = fx.app.world_mut();
    let spine_live = world.get_entity(spine).is_ok();
    match rng.below(4) {
        0 if spine_live => {
            world.despawn(spine);
            Applied::new("joint: despawned", format!("despawn spine joint {spine}"))
        }
        1 => {
            world.despawn(root);
            Applied::new(
                "joint: despawned",
                format!("despawn root joint {root} (and its spine)"),
            )
        }
        _ => {
            fx.walk += rng.float(0.05, 0.5);
            let (root_pose, spine_pose) = crate::harness::character::torso_pose(fx.walk, 1.0, 0.8);
            let world = fx.app.world_mut();
            world.entity_mut(root).insert(root_pose);
            if spine_live {
                world.entity_mut(spine).insert(spine_pose);
            }
            Applied::new(
                "joint: moved",
                format!("walk torso {root} to t = {}", fx.walk),
            )
        }
    }
}

/// A collider of a random shape, sometimes with a non-finite size or a negative margin.
fn collider(rng: &mut Rng) -> (ClothCollider, bool) {
    let bad = rng.chance(0.25);
    let size = if bad {
        rng.pick(&[f32::NAN, f32::INFINITY, -0.2])
    } else {
        rng.float(0.05, 0.5)
    };
    let mut c = match rng.below(4) {
        0 => ClothCollider::sphere(size),
        1 => ClothCollider::capsule(size * 0.5, size),
        2 => ClothCollider::cuboid(Vec3::new(size, 0.5 * size, size)),
        _ => ClothCollider::half_space(Vec3::new(0.0, 1.0, if bad { f32::NAN } else { 0.1 })),
    };
    if bad && rng.chance(0.3) {
        c.margin = -1.0;
    }
    c = c.with_friction(Friction::new(rng.float(0.0, 1.0)));
    (c, bad)
}

/// Spawns, edits or despawns a collider.
pub(super) fn edit_collider(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    let at = Vec3::new(
        rng.float(-1.5, 1.5),
        rng.float(-0.5, 1.5),
        rng.float(-1.5, 1.5),
    );
    let (c, bad) = collider(rng);
    let kind = |spawned: bool| match (spawned, bad) {
        (true, false) => "collider: spawned",
        (true, true) => "collider: spawned not finite",
        (false, false) => "collider: edited",
        (false, true) => "collider: edited not finite",
    };
    match rng.below(3) {
        _ if fx.colliders.is_empty() => {
            let e = fx
                .app
                .world_mut()
                .spawn((c, Transform::from_translation(at)))
                .id();
            fx.colliders.push(e);
            Applied::new(kind(true), format!("spawn collider {e} {c:?} at {at}"))
        }
        0 => {
            let k = rng.index(fx.colliders.len());
            let e = fx.colliders.swap_remove(k);
            fx.app.world_mut().despawn(e);
            Applied::new("collider: despawned", format!("despawn collider {e}"))
        }
        1 => {
            let e = rng.pick(&fx.colliders);
            fx.app.world_mut().entity_mut(e).insert(c);
            Applied::new(kind(false), format!("edit collider {e} to {c:?}"))
        }
        _ => {
            let e = fx
                .app
                .world_mut()
                .spawn((c, Transform::from_translation(at)))
                .id();
            fx.colliders.push(e);
            Applied::new(kind(true), format!("spawn collider {e} {c:?} at {at}"))
        }
    }
}

/// Inserts, edits (sometimes not finite) or removes the global wind.
pub(super) fn edit_wind(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    let velocity = Vec3::new(
        rng.float(-8.0, 8.0),
        rng.float(-1.0, 1.0),
        rng.float(-8.0, 8.0),
    );
    let gusts = rng.chance(0.4).then(|| Gusts {
        seed: rng.below(100),
        ..Default::default()
    });
    let mut wind = Wind {
        velocity,
        gusts,
        ..Default::default()
    };
    let kind = match rng.below(6) {
        0 => {
            fx.app.world_mut().remove_resource::<Wind>();
            return Applied::new("wind: removed", "remove Wind".into());
        }
        1 => {
            wind.velocity.x = f32::NAN;
            "wind: not finite"
        }
        2 => {
            wind.air_density = rng.pick(&[f32::NAN, -1.0]);
            "wind: not finite"
        }
        _ => "wind: valid",
    };
    let detail = format!("wind {wind:?}");
    fx.app.world_mut().insert_resource(wind);
    Applied::new(kind, detail)
}

/// Spawns, edits (sometimes with bad values) or despawns a wind zone.
pub(super) fn edit_zone(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    let bad = rng.chance(0.3);
    let size = if bad { f32::NAN } else { rng.float(0.3, 2.0) };
    let zone = WindZone {
        shape: if rng.chance(0.5) {
            WindZoneShape::Sphere(size)
        } else {
            WindZoneShape::Cuboid(Vec3::splat(size))
        },
        velocity: Vec3::new(rng.float(-6.0, 6.0), 0.0, rng.float(-6.0, 6.0)),
        gusts: None,
        falloff: if bad && rng.chance(0.5) {
            3.0
        } else {
            rng.float(0.0, 1.0)
        },
    };
    let kind = if bad {
        "wind zone: bad values"
    } else {
        "wind zone: valid"
    };
    let at = Vec3::new(rng.float(-1.0, 1.0), 1.0, rng.float(-1.0, 1.0));
    match rng.below(3) {
        0 if !fx.zones.is_empty() => {
            let e = fx.zones.swap_remove(rng.index(fx.zones.len()));
            fx.app.world_mut().despawn(e);
            Applied::new("wind zone: despawned", format!("despawn wind zone {e}"))
        }
        1 if !fx.zones.is_empty() => {
            let e = rng.pick(&fx.zones);
            fx.app.world_mut().entity_mut(e).insert(zone);
            Applied::new(kind, format!("edit wind zone {e} to {zone:?}"))
        }
        _ => {
            let e = fx
                .app
                .world_mut()
                .spawn((zone, Transform::from_translation(at)))
                .id();
            fx.zones.push(e);
            Applied::new(kind, format!("spawn wind zone {e} {zone:?}"))
        }
    }
}

/// Spawns or despawns an avian body near the cloths, or switches a cloth's two-way coupling.
#[cfg(feature = "avian")]
pub(super) fn edit_body(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    use crate::components::ClothPushesBodies;
    use avian3d::prelude::{Collider, LinearVelocity, RigidBody};

    let choice = rng.below(5);
    if choice == 0 && !fx.bodies.is_empty() {
        let e = fx.bodies.swap_remove(rng.index(fx.bodies.len()));
        fx.app.world_mut().despawn(e);
        return Applied::new("avian: body despawned", format!("despawn body {e}"));
    }
    if choice == 1 && !fx.cloths.is_empty() {
        let cloth = fx.cloths[rng.index(fx.cloths.len())].entity;
        let mut entity = fx.app.world_mut().entity_mut(cloth);
        let on = !entity.contains::<ClothPushesBodies>();
        if on {
            entity.insert(ClothPushesBodies);
        } else {
            entity.remove::<ClothPushesBodies>();
        }
        return Applied::new(
            "avian: coupling switched",
            format!("ClothPushesBodies on {cloth}: {on}"),
        );
    }
    let at = Vec3::new(
        rng.float(-1.5, 1.5),
        rng.float(0.0, 2.5),
        rng.float(-1.5, 1.5),
    );
    let size = rng.float(0.05, 0.4);
    let collider = if rng.chance(0.5) {
        Collider::sphere(size)
    } else {
        Collider::cuboid(size, size, size)
    };
    let body = rng.pick(&[RigidBody::Static, RigidBody::Kinematic, RigidBody::Dynamic]);
    let velocity = LinearVelocity(Vec3::new(rng.float(-1.0, 1.0), 0.0, rng.float(-1.0, 1.0)));
    let e = fx
        .app
        .world_mut()
        .spawn((body, collider, velocity, Transform::from_translation(at)))
        .id();
    fx.bodies.push(e);
    Applied::new(
        "avian: body spawned",
        format!("spawn {body:?} body {e} of size {size} at {at}"),
    )
}

/// Without the `avian` feature there are no bodies: a collider edit instead.
#[cfg(not(feature = "avian"))]
pub(super) fn edit_body(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    edit_collider(fx, rng)
}
