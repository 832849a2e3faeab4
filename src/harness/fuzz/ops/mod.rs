//! The fuzzer's operations on a cloth's own components: spawning and despawning cloths of each
//! kind, a new source, and edits, inserts and removals of pins, config, targets and
//! subdivision, valid and invalid. Each is drawn and applied at once, to the world and to the
//! model, and says what it did. The operations on the rest of the world (mesh assets, anchors,
//! joints, colliders, wind, physics bodies) are in `scene`.

mod scene;

use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy::transform::components::Transform;

use super::Rng;
use super::model::{
    Anchor, ClothKind, Fixture, Source, Targets, TrackedCloth, Validity, cape, sheet,
};
use crate::components::{
    Cloth, ClothConfig, ClothPins, ClothSource, ClothSubdivision, ClothTargets, PinAnchor,
    SubdivisionTarget, TargetWeights,
};
use crate::sim::{GridSpec, Integrator};
use crate::subdivision::{BoundaryMode, VertexRule};

/// What an operation did.
#[derive(Debug, Clone)]
pub(super) struct Applied {
    /// Its kind, e.g. `"ClothPins: out of range"` (failures group by it).
    pub(super) kind: &'static str,
    /// What exactly it did, for the trail.
    pub(super) detail: String,
    /// Cloths whose topology it may change: an accepted edit may rebuild them from rest.
    pub(super) topology: Vec<Entity>,
    /// Fewest updates to run before checking (a swapped asset is seen through asset events).
    pub(super) min_steps: u32,
}

impl Applied {
    fn new(kind: &'static str, detail: String) -> Self {
        Self {
            kind,
            detail,
            topology: Vec::new(),
            min_steps: 1,
        }
    }
}

/// Draws one operation and applies it.
pub(super) fn apply_random(fx: &mut Fixture, rng: &mut Rng) -> Applied {
    // Weights of the operation groups; those that need a cloth fall back to a spawn.
    let groups: [(u64, Group); 14] = [
        (3, Group::Spawn),
        (1, Group::Despawn),
        (2, Group::Source),
        (4, Group::Pins),
        (3, Group::Config),
        (3, Group::Targets),
        (3, Group::Subdivision),
        (3, Group::MeshSwap),
        (2, Group::Anchor),
        (1, Group::Joint),
        (2, Group::Collider),
        (1, Group::Wind),
        (1, Group::Zone),
        (if fx.avian { 2 } else { 0 }, Group::Body),
    ];
    let total: u64 = groups.iter().map(|g| g.0).sum();
    let mut draw = rng.below(total);
    let mut group = Group::Spawn;
    for (weight, g) in groups {
        if draw < weight {
            group = g;
            break;
        }
        draw -= weight;
    }
    let needs_cloth = !matches!(
        group,
        Group::Spawn
            | Group::MeshSwap
            | Group::Anchor
            | Group::Joint
            | Group::Collider
            | Group::Wind
            | Group::Zone
            | Group::Body
    );
    if fx.cloths.is_empty() && needs_cloth || fx.cloths.len() >= 6 && group == Group::Spawn {
        group = if fx.cloths.is_empty() {
            Group::Spawn
        } else {
            Group::Despawn
        };
    }
    let c = rng.index(fx.cloths.len());
    match group {
        Group::Spawn => spawn_cloth(fx, rng, true),
        Group::Despawn => despawn_cloth(fx, c),
        Group::Source => edit_cloth(fx, rng, c, draw_source),
        Group::Pins => edit_cloth(fx, rng, c, draw_pins),
        Group::Config => edit_cloth(fx, rng, c, draw_config),
        Group::Targets => edit_cloth(fx, rng, c, draw_targets),
        Group::Subdivision => edit_cloth(fx, rng, c, draw_subdivision),
        Group::MeshSwap => scene::swap_mesh(fx, rng),
        Group::Anchor => scene::edit_anchor(fx, rng),
        Group::Joint => scene::edit_joint(fx, rng),
        Group::Collider => scene::edit_collider(fx, rng),
        Group::Wind => scene::edit_wind(fx, rng),
        Group::Zone => scene::edit_zone(fx, rng),
        Group::Body => scene::edit_body(fx, rng),
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Group {
    Spawn,
    Despawn,
    Source,
    Pins,
    Config,
    Targets,
    Subdivision,
    MeshSwap,
    Anchor,
    Joint,
    Collider,
    Wind,
    Zone,
    Body,
}

/// A fresh fixture (see [`Fixture::empty`]) with two or three valid cloths, updated once.
pub(super) fn new_fixture(avian: bool, invalid: bool, rng: &mut Rng) -> Fixture {
    let mut fixture = Fixture::empty(avian, invalid);
    for _ in 0..2 + rng.below(2) {
        spawn_cloth(&mut fixture, rng, false);
    }
    fixture.app.update();
    fixture
}

/// Spawns a grid, mesh or character cloth somewhere above the origin, some with pins, a config,
/// targets or subdivision; with `bad`, sometimes one that cannot be built.
pub(super) fn spawn_cloth(fx: &mut Fixture, rng: &mut Rng, bad: bool) -> Applied {
    let at = Vec3::new(
        rng.float(-1.5, 1.5),
        rng.float(0.5, 2.0),
        rng.float(-1.5, 1.5),
    );
    let bad = bad && fx.invalid && rng.chance(0.3);
    let (entity, mut cloth, mut what) = match rng.below(3) {
        0 => {
            let (nx, ny) = (rng.range(6, 10), rng.range(6, 10));
            let spacing = rng.float(0.04, 0.1);
            let (spec, ok) = match bad && rng.chance(0.3) {
                false => (GridSpec::new(nx, ny, spacing), true),
                true if rng.chance(0.5) => (GridSpec::new(1, ny, spacing), false),
                true => (GridSpec::new(nx, ny, f32::NAN), false),
            };
            let e = fx
                .app
                .world_mut()
                .spawn((Cloth::grid(spec), Transform::from_translation(at)))
                .id();
            let source = Source::Grid { nx, ny, ok };
            let what = format!("grid {}×{} spacing {}", spec.nx, spec.ny, spec.spacing);
            (e, tracked(e, ClothKind::Grid, source), what)
        }
        1 => {
            let index = if !fx.meshes.is_empty() && rng.chance(0.4) {
                rng.index(fx.meshes.len())
            } else {
                let mut built = sheet(
                    rng.range(4, 8),
                    rng.range(4, 8),
                    rng.float(0.05, 0.1),
                    rng.float(0.0, 0.05),
                    rng.chance(0.5),
                );
                if bad && rng.chance(0.3) {
                    built = rng.pick(&super::model::Breakage::ALL).apply(built);
                }
                fx.add_mesh(built)
            };
            let handle = fx.meshes[index].handle.clone();
            let e = fx
                .app
                .world_mut()
                .spawn((Cloth::from_mesh(handle), Transform::from_translation(at)))
                .id();
            let what = format!("mesh cloth of asset {index} ({})", fx.meshes[index].label);
            (e, tracked(e, ClothKind::Mesh, Source::Mesh(index)), what)
        }
        _ => {
            let (built, cape) = cape(rng.range(5, 8), rng.range(4, 7), 0.0);
            let label = built.label.clone();
            let spawned = crate::harness::character::spawn_cape(
                fx.app.world_mut(),
                &cape,
                ClothConfig::default(),
            );
            let handle = match fx.app.world().get::<Cloth>(spawned.cloth) {
                Some(Cloth {
                    source: ClothSource::Mesh(h),
                }) => h.clone(),
                _ => unreachable!("spawn_cape makes a mesh cloth"),
            };
            fx.meshes.push(super::model::MeshAsset {
                handle,
                vertices: built.vertices,
                validity: built.validity,
                colors: built.colors,
                joints: built.joints,
                label: built.label,
                shape: built.shape,
            });
            fx.joints.push((spawned.root, spawned.spine));
            let e = spawned.cloth;
            let mut t = tracked(e, ClothKind::Character, Source::Mesh(fx.meshes.len() - 1));
            t.targets = Some(Targets::Color);
            t.skin = true;
            (e, t, format!("character with a {label}"))
        }
    };
    // Extras, good or (for a bad spawn) one bad one.
    let count = cloth.particles(&fx.meshes).unwrap_or(9) as u32;
    let mut world = fx.app.world_mut().entity_mut(entity);
    if rng.chance(0.6) {
        let (pins, model, label) = if bad && rng.chance(0.3) {
            bad_pins(&fx.anchors, rng, count)
        } else {
            let (pins, model) = valid_pins(&fx.anchors, rng, count);
            (pins, model, "pins")
        };
        what += &format!(", {label} {pins:?}");
        world.insert(pins);
        cloth.pins = model;
    }
    if rng.chance(0.4) || bad && rng.chance(0.3) {
        let (config, ok, label) = if bad && rng.chance(0.5) {
            let (config, label) = bad_config(rng);
            (config, false, label)
        } else {
            (valid_config(rng), true, "config")
        };
        what += &format!(", {label}");
        world.insert(config);
        cloth.config_ok = ok;
    }
    if rng.chance(0.2) {
        let nan = bad && rng.chance(0.5);
        let (weights, model) = values(rng, count as usize, nan);
        what += &format!(", targets {model:?}");
        world.insert(ClothTargets { weights });
        cloth.targets = Some(model);
    }
    if rng.chance(0.2) {
        let level = if bad && rng.chance(0.5) {
            5
        } else {
            rng.range(1, 2)
        };
        what += &format!(", render subdivision level {level}");
        world.insert(ClothSubdivision {
            level,
            ..Default::default()
        });
        cloth.subdivision = Some((level, false));
    }
    what = format!("spawn {entity}: {what}");
    let kind = match (cloth.validity(&fx.meshes), cloth.kind) {
        (Validity::Invalid, _) => "spawn: invalid cloth",
        (_, ClothKind::Grid) => "spawn: grid",
        (_, ClothKind::Mesh) => "spawn: mesh cloth",
        (_, ClothKind::Character) => "spawn: character",
    };
    fx.cloths.push(cloth);
    Applied::new(kind, what)
}

fn tracked(entity: Entity, kind: ClothKind, source: Source) -> TrackedCloth {
    TrackedCloth {
        entity,
        kind,
        source,
        config_ok: true,
        pins: Vec::new(),
        targets: None,
        subdivision: None,
        skin: false,
        topology_pending: false,
    }
}

fn despawn_cloth(fx: &mut Fixture, c: usize) -> Applied {
    let cloth = fx.cloths.remove(c);
    fx.app.world_mut().despawn(cloth.entity);
    Applied::new("despawn cloth", format!("despawn cloth {}", cloth.entity))
}

/// An edit of one of a cloth's own components, drawn before it is applied so that it can be
/// checked against the model first.
enum Change {
    Source(Cloth, Source),
    Pins(ClothPins, Vec<(u32, Anchor)>),
    RemovePins,
    Config(ClothConfig, bool),
    RemoveConfig,
    Targets(ClothTargets, Targets),
    RemoveTargets,
    Subdivision(ClothSubdivision),
    RemoveSubdivision,
}

impl Change {
    /// What the change makes of the model of the cloth.
    fn model(&self, cloth: &mut TrackedCloth) {
        match self {
            Change::Source(_, source) => cloth.source = *source,
            Change::Pins(_, pins) => cloth.pins = pins.clone(),
            Change::RemovePins => cloth.pins.clear(),
            Change::Config(_, ok) => cloth.config_ok = *ok,
            Change::RemoveConfig => cloth.config_ok = true,
            Change::Targets(_, targets) => cloth.targets = Some(*targets),
            Change::RemoveTargets => cloth.targets = None,
            Change::Subdivision(s) => {
                let simulated = s.target == SubdivisionTarget::Simulation;
                cloth.subdivision = Some((s.level, simulated));
            }
            Change::RemoveSubdivision => cloth.subdivision = None,
        }
    }

    /// Applies the change to the cloth `entity`.
    fn apply(self, entity: &mut EntityWorldMut) {
        match self {
            Change::Source(cloth, _) => drop(entity.insert(cloth)),
            Change::Pins(pins, _) => drop(entity.insert(pins)),
            Change::RemovePins => drop(entity.remove::<ClothPins>()),
            Change::Config(config, _) => drop(entity.insert(config)),
            Change::RemoveConfig => drop(entity.remove::<ClothConfig>()),
            Change::Targets(targets, _) => drop(entity.insert(targets)),
            Change::RemoveTargets => drop(entity.remove::<ClothTargets>()),
            Change::Subdivision(s) => drop(entity.insert(s)),
            Change::RemoveSubdivision => drop(entity.remove::<ClothSubdivision>()),
        }
    }
}

/// A drawn change, its operation kind and what it does (for the trail).
type Drawn = (Change, &'static str, String);

/// Draws an edit of cloth `c` from `draw` and applies it. Where the fuzzer draws valid inputs
/// only, an edit that would leave the cloth not valid is drawn again (and given up after a few
/// tries, for a valid config edit that changes nothing else).
fn edit_cloth(
    fx: &mut Fixture,
    rng: &mut Rng,
    c: usize,
    draw: fn(&mut Fixture, &mut Rng, usize) -> Drawn,
) -> Applied {
    let entity = fx.cloths[c].entity;
    let mut drawn = draw(fx, rng, c);
    for _ in 0..8 {
        let mut model = fx.cloths[c].clone();
        drawn.0.model(&mut model);
        if fx.invalid || model.validity(&fx.meshes) == Validity::Valid {
            break;
        }
        drawn = draw(fx, rng, c);
    }
    let (change, kind, detail) = drawn;
    let mut model = fx.cloths[c].clone();
    change.model(&mut model);
    if !fx.invalid && model.validity(&fx.meshes) != Validity::Valid {
        // Only the source or pins can be at fault here, and the cloth's own are valid.
        return Applied::new("skipped", format!("no valid edit of {entity} drawn"));
    }
    let refines = |m: &TrackedCloth| m.subdivision.is_some_and(|(_, simulated)| simulated);
    let topology = match change {
        Change::Source(..) => true,
        Change::Subdivision(_) | Change::RemoveSubdivision => {
            refines(&fx.cloths[c]) || refines(&model)
        }
        _ => false,
    };
    change.apply(&mut fx.app.world_mut().entity_mut(entity));
    fx.cloths[c] = model;
    let mut applied = Applied::new(kind, format!("{entity}: {detail}"));
    if topology {
        applied.topology.push(entity);
    }
    applied
}

/// Replaces the `Cloth` component: another grid, a mesh asset, or a grid that cannot be built.
fn draw_source(fx: &mut Fixture, rng: &mut Rng, _c: usize) -> Drawn {
    let choice = rng.below(if fx.invalid { 6 } else { 5 });
    match choice {
        2 | 3 if !fx.meshes.is_empty() => {
            let index = rng.index(fx.meshes.len());
            let handle = fx.meshes[index].handle.clone();
            let what = format!("source: mesh asset {index} ({})", fx.meshes[index].label);
            let change = Change::Source(Cloth::from_mesh(handle), Source::Mesh(index));
            (change, "Cloth: existing mesh asset", what)
        }
        2..=4 => {
            let built = sheet(
                rng.range(4, 8),
                rng.range(4, 8),
                0.08,
                0.02,
                rng.chance(0.5),
            );
            let what = format!("source: new mesh asset ({})", built.label);
            let index = fx.add_mesh(built);
            let handle = fx.meshes[index].handle.clone();
            let change = Change::Source(Cloth::from_mesh(handle), Source::Mesh(index));
            (change, "Cloth: new mesh asset", what)
        }
        5 => {
            let ny = rng.range(6, 10);
            let source = Source::Grid {
                nx: 1,
                ny,
                ok: false,
            };
            let change = Change::Source(Cloth::grid(GridSpec::new(1, ny, 0.05)), source);
            (change, "Cloth: bad grid", format!("source: grid 1×{ny}"))
        }
        _ => {
            let (nx, ny) = (rng.range(6, 10), rng.range(6, 10));
            let spec = GridSpec::new(nx, ny, rng.float(0.04, 0.1));
            let source = Source::Grid { nx, ny, ok: true };
            let change = Change::Source(Cloth::grid(spec), source);
            (change, "Cloth: new grid", format!("source: grid {nx}×{ny}"))
        }
    }
}

/// A few pins of particles below `count`, anchored at rest, at a world point or to an anchor
/// entity (live or despawned) with a finite offset.
fn valid_pins(anchors: &[Entity], rng: &mut Rng, count: u32) -> (ClothPins, Vec<(u32, Anchor)>) {
    let mut pins = ClothPins::default();
    for _ in 0..rng.range(1, 3) {
        let particle = rng.below(count as u64) as u32;
        let anchor = match rng.below(4) {
            0 | 1 => PinAnchor::Rest,
            2 => PinAnchor::World(Vec3::new(
                rng.float(-1.5, 1.5),
                rng.float(0.5, 2.0),
                rng.float(-1.5, 1.5),
            )),
            _ if anchors.is_empty() => PinAnchor::Rest,
            _ => PinAnchor::Entity {
                entity: rng.pick(anchors),
                offset: Vec3::new(rng.float(-0.1, 0.1), 0.0, rng.float(-0.1, 0.1)),
            },
        };
        pins.pin(particle, anchor);
    }
    let model = pins
        .pins
        .iter()
        .map(|p| (p.particle, Anchor::Finite))
        .collect();
    (pins, model)
}

/// Pins of which one is out of range, at a non-finite world point, or (which the plugin may
/// accept, holding the pin) at a non-finite offset from an anchor entity; and the kind.
fn bad_pins(
    anchors: &[Entity],
    rng: &mut Rng,
    count: u32,
) -> (ClothPins, Vec<(u32, Anchor)>, &'static str) {
    let (mut pins, mut model) = valid_pins(anchors, rng, count);
    let particle = rng.below(count as u64) as u32;
    let (particle, anchor, model_anchor, label) = match rng.below(4) {
        0 => (
            count + rng.below(3) as u32,
            PinAnchor::Rest,
            Anchor::Finite,
            "ClothPins: out of range",
        ),
        1 => (
            u32::MAX,
            PinAnchor::Rest,
            Anchor::Finite,
            "ClothPins: out of range",
        ),
        2 => (
            particle,
            PinAnchor::World(Vec3::new(0.0, f32::NAN, 0.0)),
            Anchor::NanWorld,
            "ClothPins: non-finite anchor",
        ),
        _ => (
            particle,
            PinAnchor::Entity {
                entity: anchors.first().copied().unwrap_or(Entity::PLACEHOLDER),
                offset: Vec3::splat(f32::INFINITY),
            },
            Anchor::NanOffset,
            "ClothPins: non-finite anchor offset",
        ),
    };
    pins.pin(particle, anchor);
    model.retain(|&(p, _)| p != particle);
    model.push((particle, model_anchor));
    (pins, model, label)
}

fn draw_pins(fx: &mut Fixture, rng: &mut Rng, c: usize) -> Drawn {
    let count = fx.cloths[c].particles(&fx.meshes).unwrap_or(9) as u32;
    let choice = rng.below(if fx.invalid { 10 } else { 6 });
    let (pins, model, kind) = match choice {
        0 => {
            return (
                Change::RemovePins,
                "ClothPins: removed",
                "remove ClothPins".into(),
            );
        }
        1 => (ClothPins::default(), Vec::new(), "ClothPins: none"),
        2..=5 => {
            let (pins, model) = valid_pins(&fx.anchors, rng, count);
            (pins, model, "ClothPins: valid")
        }
        _ => bad_pins(&fx.anchors, rng, count),
    };
    let what = format!("pins {:?}", pins.pins);
    (Change::Pins(pins, model), kind, what)
}

/// Settings every integrator the fuzzer uses steps stably.
fn valid_config(rng: &mut Rng) -> ClothConfig {
    let mut config = ClothConfig::default();
    let s = &mut config.solver;
    s.integrator = rng.pick(&[Integrator::Auto, Integrator::Xpbd]);
    s.substeps = rng.range(4, 30);
    s.stiffness.structural = rng.float(200.0, 5000.0);
    s.stiffness.shear = rng.float(50.0, 5000.0);
    s.stiffness.bend = rng.float(1.0, 100.0);
    s.particle_mass = rng.float(5e-4, 5e-3);
    s.damping = rng.float(0.0, 2.0);
    s.self_collision.enabled = rng.chance(0.25);
    config.interpolate = rng.chance(0.5);
    config
}

/// A config with one bad field, and the kind.
fn bad_config(rng: &mut Rng) -> (ClothConfig, &'static str) {
    let mut config = valid_config(rng);
    let s = &mut config.solver;
    let kind = match rng.below(4) {
        0 => {
            s.stiffness.structural = rng.pick(&[-1.0, f32::NAN, f32::INFINITY]);
            "ClothConfig: bad stiffness"
        }
        1 => {
            s.particle_mass = f32::NAN;
            "ClothConfig: NaN mass"
        }
        2 => {
            s.substeps = 0;
            "ClothConfig: zero substeps"
        }
        _ => {
            s.damping = -1.0;
            "ClothConfig: negative damping"
        }
    };
    (config, kind)
}

fn draw_config(fx: &mut Fixture, rng: &mut Rng, c: usize) -> Drawn {
    let entity = fx.cloths[c].entity;
    let choice = rng.below(if fx.invalid { 10 } else { 7 });
    let (config, ok, kind) = match choice {
        0 => {
            let what = "remove ClothConfig".into();
            return (Change::RemoveConfig, "ClothConfig: removed", what);
        }
        1 | 2 => {
            // Self-collision switched, the rest of the config kept.
            let world = fx.app.world();
            let mut config = world
                .get::<ClothConfig>(entity)
                .copied()
                .unwrap_or_default();
            let on = &mut config.solver.self_collision.enabled;
            *on = !*on;
            (
                config,
                fx.cloths[c].config_ok,
                "ClothConfig: self-collision switched",
            )
        }
        3..=6 => (valid_config(rng), true, "ClothConfig: valid"),
        _ => {
            let (config, kind) = bad_config(rng);
            (config, false, kind)
        }
    };
    let what = format!("config {:?}", config.solver);
    (Change::Config(config, ok), kind, what)
}

/// `len` weights in -0.2..1 (a negative one frees its particle), one NaN with `nan`.
fn values(rng: &mut Rng, len: usize, nan: bool) -> (TargetWeights, Targets) {
    let mut w: Vec<f32> = (0..len).map(|_| rng.float(-0.2, 1.0)).collect();
    if nan && len > 0 {
        let k = rng.index(len);
        w[k] = f32::NAN;
    }
    (
        TargetWeights::Values(w),
        Targets::Values {
            len,
            nan: nan && len > 0,
        },
    )
}

fn draw_targets(fx: &mut Fixture, rng: &mut Rng, c: usize) -> Drawn {
    let count = fx.cloths[c].particles(&fx.meshes).unwrap_or(9);
    let choice = rng.below(if fx.invalid { 8 } else { 6 });
    let (weights, model, kind) = match choice {
        0 => {
            let what = "remove ClothTargets".into();
            return (Change::RemoveTargets, "ClothTargets: removed", what);
        }
        1..=3 => {
            let (w, m) = values(rng, count, false);
            (w, m, "ClothTargets: valid weights")
        }
        4 | 5 => {
            let channel = rng.below(4) as u8;
            let w = TargetWeights::Color(channel);
            (w, Targets::Color, "ClothTargets: vertex colours")
        }
        6 => {
            let len = if rng.chance(0.5) {
                count + 1
            } else {
                count - 1
            };
            let (w, m) = values(rng, len, false);
            (w, m, "ClothTargets: wrong weight count")
        }
        _ => {
            let (w, m) = values(rng, count, true);
            (w, m, "ClothTargets: NaN weight")
        }
    };
    let what = match &weights {
        TargetWeights::Values(w) => format!("targets: {} weights", w.len()),
        other => format!("targets: {other:?}"),
    };
    (Change::Targets(ClothTargets { weights }, model), kind, what)
}

fn draw_subdivision(fx: &mut Fixture, rng: &mut Rng, _c: usize) -> Drawn {
    if rng.chance(0.15) {
        let what = "remove ClothSubdivision".into();
        return (Change::RemoveSubdivision, "ClothSubdivision: removed", what);
    }
    let simulated = rng.chance(0.35);
    let mut levels: &[u32] = if simulated {
        &[0, 1, 1, 2, 5]
    } else {
        &[0, 1, 1, 2, 2, 3, 4, 5]
    };
    if !fx.invalid {
        levels = &levels[..levels.len() - 1];
    }
    let level = rng.pick(levels);
    let subdivision = ClothSubdivision {
        level,
        rule: rng.pick(&[
            VertexRule::Original,
            VertexRule::Enhanced,
            VertexRule::Tuned,
        ]),
        boundary: rng.pick(&[BoundaryMode::EdgeOnly, BoundaryMode::EdgeAndCorner]),
        target: if simulated {
            SubdivisionTarget::Simulation
        } else {
            SubdivisionTarget::Render
        },
    };
    let kind = match (simulated, level) {
        (_, 5) => "ClothSubdivision: level too high",
        (true, _) => "ClothSubdivision: simulation",
        (false, _) => "ClothSubdivision: render",
    };
    let what = format!("{subdivision:?}");
    (Change::Subdivision(subdivision), kind, what)
}
