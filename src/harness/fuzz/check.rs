//! The fuzzer's checks: a snapshot of every cloth before an operation, what must hold after
//! each step (finite values, no failed step, running cloths still running from where they were)
//! and after the last step before the next operation (rejections reported exactly where the
//! model says the cloth is invalid).

use bevy::asset::Assets;
use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy::mesh::{Mesh, VertexAttributeValues};
use bevy::transform::components::GlobalTransform;

use super::FailureKind;
use super::model::{Fixture, Validity};
use crate::components::{ClothEditRejected, ClothInvalid, ClothState};
use crate::error::ClothError;

/// How far (m) a cloth's centre must have moved from its rest centre before the check for a
/// reset to rest applies, and how close to the rest centre it must then come to count as reset.
/// A cloth rebuilt from rest moves about a centimetre in three steps of free fall. Only cloths
/// without pins or targets, before the operation and after it, are checked: a new pin set
/// anchored at the rest pose, or targets (the skinned or the source mesh's pose, here the rest
/// pose), rightly pull a cloth back to rest within a few steps, and targets still act in the
/// first update after they are removed (the step runs before the edit is built).
const MOVED: f32 = 0.2;
const BACK_AT_REST: f32 = 0.005;

/// One cloth before an operation.
#[derive(Debug, Clone, Copy)]
pub(super) struct ClothBefore {
    entity: Entity,
    /// Its state, if it had one: steps taken, centre, and rest centre under its transform.
    running: Option<(u64, Vec3, Vec3)>,
    validity: Validity,
    /// Whether pins or targets held it: their pull may still act in the update after they go.
    held: bool,
}

/// Every tracked cloth before an operation.
#[derive(Debug, Clone)]
pub(super) struct Snapshot(Vec<ClothBefore>);

impl Snapshot {
    /// Takes the snapshot.
    pub(super) fn take(fx: &Fixture) -> Self {
        let world = fx.app.world();
        Self(
            fx.cloths
                .iter()
                .map(|c| {
                    let running = world.get::<ClothState>(c.entity).map(|s| {
                        let transform = world
                            .get::<GlobalTransform>(c.entity)
                            .copied()
                            .unwrap_or_default();
                        let rest = mean(&s.sim().model().rest_positions);
                        (
                            s.steps(),
                            mean(s.positions()),
                            transform.transform_point(rest),
                        )
                    });
                    ClothBefore {
                        entity: c.entity,
                        running,
                        validity: c.validity(&fx.meshes),
                        held: c.targets.is_some() || !c.pins.is_empty(),
                    }
                })
                .collect(),
        )
    }

    fn get(&self, entity: Entity) -> Option<&ClothBefore> {
        self.0.iter().find(|b| b.entity == entity)
    }
}

fn mean(points: &[Vec3]) -> Vec3 {
    points.iter().sum::<Vec3>() / points.len().max(1) as f32
}

/// Whether a cloth was stopped by its step rather than refused for its input.
fn is_step_failure(e: &ClothError) -> bool {
    matches!(
        e.innermost(),
        ClothError::Diverged { .. } | ClothError::Unstable { .. }
    )
}

/// What must hold after update `step` (1-based) since the last operation: every state finite,
/// no step failed, and every cloth that was running still running: with its state, and with its
/// step count gone on by `step`, unless it is not invalid and has an edit of its topology
/// pending (which it may have just been rebuilt for).
pub(super) fn check_step(fx: &Fixture, before: &Snapshot, step: u32) -> Vec<(FailureKind, String)> {
    let world = fx.app.world();
    let meshes = world.resource::<Assets<Mesh>>();
    let mut found = Vec::new();
    for cloth in &fx.cloths {
        let e = cloth.entity;
        let state = world.get::<ClothState>(e);
        let invalid = world.get::<ClothInvalid>(e);
        if let Some(s) = state {
            let bad = s
                .positions()
                .iter()
                .chain(s.sim().velocities())
                .position(|p| !p.is_finite());
            if let Some(k) = bad {
                found.push((
                    FailureKind::NonFinite,
                    format!(
                        "cloth {e}: particle value {k} (positions, then velocities) is not finite"
                    ),
                ));
            }
            let mesh_bad = match meshes
                .get(s.mesh())
                .and_then(|m| m.attribute(Mesh::ATTRIBUTE_POSITION))
            {
                Some(VertexAttributeValues::Float32x3(p)) => {
                    p.iter().flatten().any(|x| !x.is_finite())
                }
                _ => false,
            };
            if mesh_bad {
                found.push((
                    FailureKind::NonFinite,
                    format!("cloth {e}: its mesh has a position that is not finite"),
                ));
            }
        }
        if let Some(ClothInvalid(error)) = invalid
            && is_step_failure(error)
        {
            found.push((
                FailureKind::StepFailure,
                format!("cloth {e} was stopped: {error}"),
            ));
        }
        let Some(&ClothBefore {
            running: Some((steps, centre, rest_centre)),
            held,
            ..
        }) = before.get(e)
        else {
            continue;
        };
        let Some(s) = state else {
            let why = invalid.map_or_else(
                || "no ClothInvalid either".to_string(),
                |i| format!("ClothInvalid: {}", i.0),
            );
            found.push((
                FailureKind::Lost,
                format!("running cloth {e} lost its ClothState ({why})"),
            ));
            continue;
        };
        let may_rebuild = cloth.topology_pending && cloth.validity(&fx.meshes) != Validity::Invalid;
        if may_rebuild {
            continue;
        }
        let expected = steps + step as u64;
        if s.steps() != expected {
            found.push((
                FailureKind::Lost,
                format!(
                    "running cloth {e} is at step {} after {step} update(s), not {expected}: \
                     rebuilt or stalled by an edit that kept its topology or was rejected",
                    s.steps()
                ),
            ));
        } else if !held
            && cloth.targets.is_none()
            && cloth.pins.is_empty()
            && centre.distance(rest_centre) > MOVED
            && mean(s.positions()).distance(rest_centre) < BACK_AT_REST
        {
            found.push((
                FailureKind::Lost,
                format!("running cloth {e} was put back at rest"),
            ));
        }
    }
    found
}

/// After the last update before the next operation, compares each cloth's flags with its
/// validity: a valid cloth runs without rejection; a cloth made invalid while running carries
/// [`ClothEditRejected`] (and keeps running, which [`check_step`] checks); an invalid cloth
/// that was not running carries [`ClothInvalid`] and no state. Returns the rejections expected,
/// those reported, and the failures.
pub(super) fn check_flags(
    fx: &Fixture,
    before: &Snapshot,
) -> (usize, usize, Vec<(FailureKind, String)>) {
    let world = fx.app.world();
    let (mut expected, mut reported, mut found) = (0, 0, Vec::new());
    for cloth in &fx.cloths {
        let e = cloth.entity;
        let was = before.get(e);
        let running = was.is_some_and(|b| b.running.is_some());
        let newly_invalid = was.is_none_or(|b| b.validity != Validity::Invalid);
        let has_state = world.get::<ClothState>(e).is_some();
        let invalid = world.get::<ClothInvalid>(e).map(|i| &i.0);
        let rejected = world.get::<ClothEditRejected>(e).map(|r| &r.0);
        match cloth.validity(&fx.meshes) {
            Validity::Valid => {
                let problem = match (has_state, invalid, rejected) {
                    (_, Some(error), _) => Some(format!("carries ClothInvalid: {error}")),
                    (false, None, _) => Some("was not built".to_string()),
                    (true, None, Some(error)) => {
                        Some(format!("still carries ClothEditRejected: {error}"))
                    }
                    (true, None, None) => None,
                };
                if let Some(problem) = problem {
                    found.push((
                        FailureKind::SpuriousRejection,
                        format!("cloth {e}, whose components are all valid, {problem}"),
                    ));
                }
            }
            Validity::Invalid if running => {
                if newly_invalid {
                    expected += 1;
                    match (has_state, rejected) {
                        (true, Some(_)) => reported += 1,
                        // Lost: `check_step` said so.
                        (false, _) => {}
                        (true, None) => found.push((
                            FailureKind::Unreported,
                            format!(
                                "running cloth {e} was made invalid but carries no \
                                 ClothEditRejected"
                            ),
                        )),
                    }
                }
            }
            Validity::Invalid => {
                if newly_invalid {
                    expected += 1;
                }
                let problem = match (has_state, invalid) {
                    (true, _) => Some("was built"),
                    (false, None) => Some("carries no ClothInvalid"),
                    (false, Some(_)) => None,
                };
                match problem {
                    Some(problem) => found.push((
                        FailureKind::Unreported,
                        format!("cloth {e}, which is invalid and was not running, {problem}"),
                    )),
                    None if newly_invalid => reported += 1,
                    None => {}
                }
            }
            Validity::Unknown => {}
        }
    }
    (expected, reported, found)
}

#[cfg(test)]
mod tests {
    use bevy::mesh::Mesh;

    use super::*;
    use crate::harness::fuzz::Rng;

    /// A fuzz fixture of valid cloths, all running, stepped once after `before` was taken.
    fn stepped() -> (Fixture, Snapshot) {
        let mut fx = crate::harness::fuzz::ops::new_fixture(false, false, &mut Rng(5));
        fx.app.update();
        let before = Snapshot::take(&fx);
        assert!(before.0.iter().all(|b| b.running.is_some()));
        fx.app.update();
        (fx, before)
    }

    fn kinds(found: &[(FailureKind, String)]) -> Vec<FailureKind> {
        found.iter().map(|f| f.0).collect()
    }

    #[test]
    fn running_valid_cloths_pass_every_check() {
        let (fx, before) = stepped();
        assert_eq!(check_step(&fx, &before, 1), vec![]);
        assert_eq!(check_flags(&fx, &before), (0, 0, vec![]));
    }

    #[test]
    fn a_non_finite_mesh_position_is_found() {
        let (mut fx, before) = stepped();
        let e = fx.cloths[0].entity;
        let handle = fx.app.world().get::<ClothState>(e).unwrap().mesh().clone();
        let mut meshes = fx.app.world_mut().resource_mut::<Assets<Mesh>>();
        if let Some(VertexAttributeValues::Float32x3(p)) = meshes
            .get_mut(&handle)
            .unwrap()
            .attribute_mut(Mesh::ATTRIBUTE_POSITION)
        {
            p[1][0] = f32::NAN;
        }
        assert_eq!(
            kinds(&check_step(&fx, &before, 1)),
            [FailureKind::NonFinite]
        );
    }

    #[test]
    fn a_stopped_step_a_lost_state_and_a_stalled_count_are_found() {
        let (mut fx, before) = stepped();
        // Checked as if two updates had run: every cloth is one step short.
        let stalled = check_step(&fx, &before, 2);
        assert_eq!(stalled.len(), fx.cloths.len(), "{stalled:?}");
        assert!(stalled.iter().all(|f| f.0 == FailureKind::Lost));
        let e = fx.cloths[0].entity;
        let diverged = ClothError::Diverged {
            step: 1,
            particle: 0,
            dt: 0.1,
            substeps: 1,
        };
        let mut cloth = fx.app.world_mut().entity_mut(e);
        cloth.remove::<ClothState>().insert(ClothInvalid(diverged));
        assert_eq!(
            kinds(&check_step(&fx, &before, 1)),
            [FailureKind::StepFailure, FailureKind::Lost]
        );
        // A cloth whose topology edit is pending may be rebuilt, but not lose its state.
        fx.cloths[1].topology_pending = true;
        let found = check_step(&fx, &before, 2);
        let pending = fx.cloths[1].entity.to_string();
        assert!(found.iter().all(|f| !f.1.contains(&pending)), "{found:?}");
        fx.app
            .world_mut()
            .entity_mut(fx.cloths[1].entity)
            .remove::<ClothState>();
        let found = check_step(&fx, &before, 2);
        assert!(found.iter().any(|f| f.1.contains(&pending)), "{found:?}");
    }

    #[test]
    fn a_cloth_put_back_at_rest_is_lost_unless_pins_or_targets_pull_it_there() {
        let (mut fx, mut before) = stepped();
        // As if the first cloth had been a metre from its rest centre before this update, and
        // were at it now.
        let e = fx.cloths[0].entity;
        let now = mean(fx.app.world().get::<ClothState>(e).unwrap().positions());
        let at = before.0.iter().position(|b| b.entity == e).unwrap();
        let (steps, ..) = before.0[at].running.unwrap();
        before.0[at].running = Some((steps, now + Vec3::X, now));
        before.0[at].held = false;
        fx.cloths[0].targets = None;
        fx.cloths[0].pins.clear();
        let found = check_step(&fx, &before, 1);
        assert_eq!(kinds(&found), [FailureKind::Lost], "{found:?}");
        assert!(found[0].1.contains("put back at rest"), "{found:?}");
        fx.cloths[0].targets = Some(super::super::model::Targets::Color);
        assert_eq!(check_step(&fx, &before, 1), vec![]);
        fx.cloths[0].targets = None;
        fx.cloths[0]
            .pins
            .push((0, super::super::model::Anchor::Finite));
        assert_eq!(check_step(&fx, &before, 1), vec![]);
        // Held before the operation, free after it.
        fx.cloths[0].pins.clear();
        before.0[at].held = true;
        assert_eq!(check_step(&fx, &before, 1), vec![]);
    }

    #[test]
    fn rejections_must_be_reported_and_only_rejections() {
        let (mut fx, before) = stepped();
        // The model says the first cloth was made invalid; the world shows no rejection.
        fx.cloths[0].config_ok = false;
        let (expected, reported, found) = check_flags(&fx, &before);
        assert_eq!((expected, reported), (1, 0));
        assert_eq!(kinds(&found), [FailureKind::Unreported]);
        let e = fx.cloths[0].entity;
        let error = ClothError::PinOutOfRange { index: 9, count: 4 };
        let rejected = ClothEditRejected(error.clone());
        fx.app.world_mut().entity_mut(e).insert(rejected.clone());
        assert_eq!(check_flags(&fx, &before), (1, 1, vec![]));
        // A valid cloth must carry no rejection.
        fx.cloths[0].config_ok = true;
        let (_, _, found) = check_flags(&fx, &before);
        assert_eq!(kinds(&found), [FailureKind::SpuriousRejection]);
        let mut cloth = fx.app.world_mut().entity_mut(e);
        cloth
            .remove::<ClothEditRejected>()
            .insert(ClothInvalid(error));
        let (_, _, found) = check_flags(&fx, &before);
        assert_eq!(kinds(&found), [FailureKind::SpuriousRejection]);
    }
}
