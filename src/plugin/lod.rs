//! Levels of detail (first in [`ClothSystems::Prepare`](super::ClothSystems::Prepare)): each
//! cloth with [`ClothLod`] gets its level from the viewers and the budget, and a changed level is
//! applied to its simulation; a frozen cloth's pose is carried in `resolve_pin_targets`.

use bevy::ecs::prelude::*;
use bevy::math::{Affine3A, Vec3};
use bevy::platform::time::Instant;
use bevy::transform::components::GlobalTransform;

use crate::components::{ClothInvalid, ClothState};
use crate::lod::{
    Blend, Carried, ClothBudget, ClothLod, ClothLodLevel, ClothViewer, CulledReturn, LodLevel,
    LodMetric,
};

/// One cloth as the budget sees it.
pub(super) struct Candidate {
    entity: Entity,
    /// Finest first: distance, or minus the screen size.
    priority: f32,
}

/// The cloths with levels of detail, as [`choose_levels`] reads them.
type Levelled<'a> = (
    Entity,
    &'a ClothLod,
    &'a mut ClothLodLevel,
    &'a mut ClothState,
);

/// Chooses each cloth's level and applies the changes.
pub(super) fn choose_levels(
    budget: Option<Res<ClothBudget>>,
    viewers: Query<(&ClothViewer, &GlobalTransform)>,
    mut cloths: Query<Levelled, Without<ClothInvalid>>,
    mut order: Local<Vec<Candidate>>,
) {
    order.clear();
    for (entity, lod, mut level, mut state) in &mut cloths {
        if lod.validate().is_err() {
            // An invalid setting leaves the cloth at full quality.
            *level = ClothLodLevel::default();
            full_quality(&mut state);
            continue;
        }
        let state = &mut *state;
        if budget.is_some() && state.lod.coarse_share.is_none() {
            // What the coarse level would cost, for the budget's plan.
            let n = state.sim.positions().len() as f32;
            let coarse = state.sim.coarse_particle_count();
            state.lod.coarse_share = Some(coarse.map(|c| c as f32 / n));
        }
        let (centre, radius) = state.lod.bound(state.sim.positions());
        let (measure, seen) = measure(lod.metric, (centre, radius), &viewers);
        let mut wanted = lod.level_for(measure, level.wanted);
        if lod.cull_unseen && !seen {
            wanted = LodLevel::Culled;
        }
        level.set_if_neq(ClothLodLevel {
            level: wanted,
            wanted,
            measure,
            seen,
        });
        let priority = match lod.metric {
            LodMetric::Distance => measure,
            LodMetric::ScreenSize => -measure,
        };
        order.push(Candidate { entity, priority });
    }
    if let Some(budget) = budget {
        order.sort_by(|a, b| a.priority.total_cmp(&b.priority));
        share_out(budget.plan_ms(), &order, &mut cloths);
    }
    for (_, lod, mut level, mut state) in &mut cloths {
        if lod.validate().is_ok() {
            apply(lod, &mut level, &mut state);
        }
    }
}

/// The measure of a cloth's bounding sphere for `metric` from the nearest (or the largest)
/// view, and whether a viewer sees it; with no viewer, full quality and seen.
fn measure(
    metric: LodMetric,
    (centre, radius): (Vec3, f32),
    viewers: &Query<(&ClothViewer, &GlobalTransform)>,
) -> (f32, bool) {
    if viewers.is_empty() {
        return match metric {
            LodMetric::Distance => (0.0, true),
            LodMetric::ScreenSize => (f32::INFINITY, true),
        };
    }
    let mut distance = f32::INFINITY;
    let mut size: f32 = 0.0;
    let mut seen = false;
    for (viewer, at) in viewers {
        let to = centre - at.translation();
        let d = to.length();
        distance = distance.min((d - radius).max(0.0));
        let half_height = d.max(f32::MIN_POSITIVE) * (0.5 * viewer.fov_y).tan();
        size = size.max(radius / half_height.max(f32::MIN_POSITIVE));
        seen |= d <= radius || {
            let forward = at.forward().as_vec3();
            let angle = forward.angle_between(to);
            angle <= viewer.half_angle + (radius / d).min(1.0).asin()
        };
    }
    match metric {
        LodMetric::Distance => (distance, seen),
        LodMetric::ScreenSize => (size, seen),
    }
}

/// Lowers levels to fit `ms`: in `order` (finest first), each cloth takes the finest level its
/// own choice allows whose cost fits what is left once every cloth after it has its floor
/// (frozen, or culled where it chose that).
fn share_out(ms: f32, order: &[Candidate], cloths: &mut Query<Levelled, Without<ClothInvalid>>) {
    let floor = |level: LodLevel| level.max(LodLevel::Frozen);
    let mut left = ms;
    for c in order {
        if let Ok((_, lod, level, state)) = cloths.get(c.entity) {
            left -= state.lod.cost(floor(level.wanted), lod.reduced_detail);
        }
    }
    for c in order {
        let Ok((_, lod, mut level, state)) = cloths.get_mut(c.entity) else {
            continue;
        };
        let lowest = floor(level.wanted);
        let base = state.lod.cost(lowest, lod.reduced_detail);
        let chosen = LodLevel::ALL
            .into_iter()
            .filter(|&l| l >= level.wanted && l <= lowest)
            .find(|&l| state.lod.cost(l, lod.reduced_detail) - base <= left)
            .unwrap_or(lowest);
        left -= state.lod.cost(chosen, lod.reduced_detail) - base;
        if chosen != level.level {
            level.level = chosen;
        }
    }
}

/// Moves a cloth to the level in `level`: its substeps, the pose it freezes in, its return from
/// culled.
fn apply(lod: &ClothLod, level: &mut Mut<ClothLodLevel>, state: &mut ClothState) {
    let (from, mut to) = (state.lod.level, level.level);
    if from == LodLevel::Culled && to != LodLevel::Culled && lod.on_return == CulledReturn::Reset {
        // Put where the frozen pose would be, this step; at its level from the next.
        if state.lod.carried.is_some() {
            state.lod.reset = true;
            to = LodLevel::Frozen;
            level.level = to;
        }
    }
    if to == LodLevel::Coarse && state.sim.set_coarse(true).is_err() {
        // A cloth with no coarse level runs reduced.
        state.lod.coarse_share = Some(None);
        to = LodLevel::Reduced;
        level.level = to;
    }
    if to != LodLevel::Coarse {
        let _ = state.sim.set_coarse(false);
    }
    let freezes = !to.steps() && (to == LodLevel::Frozen || lod.on_return == CulledReturn::Reset);
    // Captured as the pins and targets are resolved, where the carriers still stand where the
    // particles were stepped to.
    state.lod.capture = from.steps() && freezes;
    if to.steps() {
        let carried = state.lod.carried.take();
        if from == LodLevel::Frozen && lod.blend_frames > 0 {
            state.lod.blend = carried.map(|carried| Blend::from(carried, lod.blend_frames));
        }
        let detail = if to == LodLevel::Reduced {
            lod.reduced_detail
        } else {
            1.0
        };
        if state.sim.detail() != detail {
            // Validated with the level of detail.
            let _ = state.sim.set_detail(detail);
        }
    } else {
        state.lod.blend = None;
    }
    state.lod.level = to;
}

/// Back to full quality, without a level of detail.
fn full_quality(state: &mut ClothState) {
    if state.lod.level != LodLevel::Full || state.sim.detail() != 1.0 || state.sim.is_coarse() {
        state.lod = Default::default();
        let _ = state.sim.set_detail(1.0);
        let _ = state.sim.set_coarse(false);
    }
}

/// A cloth whose [`ClothLod`] was removed runs at full quality again.
pub(super) fn restore_full_quality(
    mut removed: RemovedComponents<ClothLod>,
    mut cloths: Query<&mut ClothState>,
) {
    for entity in removed.read() {
        if let Ok(mut state) = cloths.get_mut(entity) {
            full_quality(&mut state);
        }
    }
}

/// Takes the pose a cloth freezes in from its particles and its carriers as they were after its
/// last step (`transform`: its transform then), when its level asks for it; a cloth that never
/// stepped freezes in its rest shape.
pub(super) fn capture_pose(state: &mut ClothState, transform: &Affine3A) {
    if !std::mem::take(&mut state.lod.capture) {
        return;
    }
    let (sim, attachment) = (&state.sim, state.attachment.as_ref());
    let carried = if sim.steps() == 0 {
        Carried::at_rest(&sim.model().rest_positions, attachment)
    } else {
        Carried::capture(sim.positions(), attachment, transform)
    };
    state.lod.carried = Some(carried);
}

/// Moves a thawing cloth's carried pose to where its carriers are this step.
pub(super) fn carry_blend(state: &mut ClothState, transform: &Affine3A) {
    let s = &mut *state;
    if let Some(blend) = &mut s.lod.blend {
        blend.target.resize(blend.carried.len(), Vec3::ZERO);
        blend
            .carried
            .carry(s.attachment.as_ref(), transform, &mut blend.target);
    }
}

/// Puts a frozen cloth where its carriers take the pose it froze in (its targets updated for
/// this step), with the velocity that took it there over `dt`; timed as its step.
pub(super) fn follow_carriers(state: &mut ClothState, transform: &Affine3A, dt: f32) {
    let started = Instant::now();
    let s = &mut *state;
    let n = s.sim.positions().len();
    if s.lod.carried.as_ref().is_none_or(|c| c.len() != n) {
        s.lod.carried = Some(Carried::capture(
            s.sim.positions(),
            s.attachment.as_ref(),
            transform,
        ));
    }
    let Some(carried) = &s.lod.carried else {
        return;
    };
    let mut next = std::mem::take(&mut s.lod.scratch);
    next.resize(n, Vec3::ZERO);
    carried.carry(s.attachment.as_ref(), transform, &mut next);
    let mut velocities = std::mem::take(&mut s.lod.velocities);
    velocities.clear();
    if s.lod.reset || dt <= 0.0 {
        velocities.resize(n, Vec3::ZERO);
    } else {
        let inv_dt = 1.0 / dt;
        velocities.extend(
            next.iter()
                .zip(s.sim.positions())
                .map(|(a, b)| (*a - *b) * inv_dt),
        );
    }
    // Both come from the cloth's own finite pose and transform; a transform that is not finite
    // leaves the cloth where it was.
    let _ = s.sim.place(&next, &velocities);
    s.lod.scratch = next;
    s.lod.velocities = velocities;
    s.lod.reset = false;
    s.lod.bound = None;
    s.step_time = started.elapsed();
    let ms = s.step_time.as_secs_f32() * 1e3;
    s.lod.measured(LodLevel::Frozen, 1.0, ms);
}
