//! Render sync: the render positions and normals of each new state (copied or subdivided, in
//! [`ClothSystems::Subdivide`](super::ClothSystems::Subdivide)), and their write into each cloth's
//! `Mesh` once per frame, interpolated between the last two steps (in
//! [`ClothSystems::Writeback`](super::ClothSystems::Writeback)).

use bevy::asset::Assets;
use bevy::ecs::prelude::*;
use bevy::mesh::Mesh;
use bevy::time::{Fixed, Time};
use bevy::transform::components::GlobalTransform;

use super::poses::invertible;
use crate::components::{ClothConfig, ClothInvalid, ClothState};
use crate::error::ClothError;
use crate::render;
use crate::sim::compute_normals;

/// Whether the simulation runs in [`FixedUpdate`](bevy::app::FixedUpdate) (so that display
/// interpolation makes sense).
#[derive(Resource, Debug, Clone, Copy)]
pub(super) struct SteppedInFixedUpdate(pub(super) bool);

/// Keeps the last two render states (positions and normals) for display interpolation.
pub(super) fn update_render_buffers(mut cloths: Query<&mut ClothState, Without<ClothInvalid>>) {
    cloths.par_iter_mut().for_each(|mut state| {
        if state.failure.is_some() {
            return;
        }
        let s = &mut *state;
        if s.lod.level == crate::LodLevel::Culled {
            return;
        }
        // A sleeping cloth did not move: one refresh makes both render states its resting pose,
        // after which there is nothing to compute until it wakes.
        if s.sim.slept_last_step() {
            if s.at_rest {
                return;
            }
            s.at_rest = true;
        } else {
            s.at_rest = false;
        }
        std::mem::swap(&mut s.render_prev, &mut s.render_curr);
        std::mem::swap(&mut s.normals_prev, &mut s.normals_curr);
        if let Some(blend) = &mut s.lod.blend
            && !blend.next(s.sim.positions())
        {
            s.lod.blend = None;
        }
        s.failure = refresh_render(s).err();
        s.dirty = true;
    });
}

/// Computes the current render positions and normals from the particles: copied (each render
/// vertex its particle's, where the simulation welded the mesh's seams), or evaluated through the
/// subdivision stencils.
pub(super) fn refresh_render(s: &mut ClothState) -> Result<(), ClothError> {
    // A thawing cloth is drawn blended with its carried pose.
    let positions = match &s.lod.blend {
        Some(blend) => &blend.positions[..],
        None => s.sim.positions(),
    };
    match (&mut s.subdivision, &mut s.seam_normals) {
        (None, Some(normals)) => {
            // The weld maps every vertex of the mesh to one of the welded model's particles
            // (`ClothModel::weld_seams`); the buffers' sizes are checked as the copy's below.
            let map = s.particle_map.as_deref().unwrap_or_default();
            if s.render_curr.len() != map.len() || normals.len() != positions.len() {
                return Err(ClothError::InvalidMesh {
                    what: format!(
                        "has {} render vertices for {} welded to {} particles",
                        s.render_curr.len(),
                        map.len(),
                        positions.len()
                    ),
                });
            }
            compute_normals(positions, &s.sim.model().triangles, normals);
            for ((x, n), &p) in s.render_curr.iter_mut().zip(&mut s.normals_curr).zip(map) {
                (*x, *n) = (positions[p as usize], normals[p as usize]);
            }
        }
        (None, None) => {
            // Render buffers are sized from the mesh, checked against the particles at build.
            if s.render_curr.len() != positions.len() {
                return Err(ClothError::InvalidMesh {
                    what: format!(
                        "has {} render vertices for {} particles",
                        s.render_curr.len(),
                        positions.len()
                    ),
                });
            }
            s.render_curr.copy_from_slice(positions);
            let by_grid = s
                .grid_normals
                .as_mut()
                .is_some_and(|g| g.compute(&s.render_curr, &mut s.normals_curr));
            if !by_grid {
                compute_normals(
                    &s.render_curr,
                    &s.sim.model().triangles,
                    &mut s.normals_curr,
                );
            }
        }
        (Some(r), _) => {
            r.subdivider.apply(positions, &mut r.positions)?;
            r.subdivider.compute_normals(&r.positions, &mut r.normals)?;
            let layout = r.subdivider.topology().render_mesh();
            layout.expand(&r.positions, &mut s.render_curr)?;
            layout.expand(&r.normals, &mut s.normals_curr)?;
        }
    }
    Ok(())
}

/// Writes each changed cloth's render state into its mesh, in the entity's local space.
pub(super) fn write_meshes(
    fixed: Res<SteppedInFixedUpdate>,
    time: Res<Time<Fixed>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut cloths: Query<(&ClothConfig, &GlobalTransform, &mut ClothState), Without<ClothInvalid>>,
) {
    let fraction = if fixed.0 {
        time.overstep_fraction()
    } else {
        1.0
    };
    for (config, transform, mut state) in &mut cloths {
        let interpolating = config.interpolate
            && fraction < 1.0
            && !state.at_rest
            && state.lod.level != crate::LodLevel::Culled;
        // Compared by value: a transform written again unchanged (as propagation does without
        // static-scene tracking) leaves the mesh as it is.
        let moved = state.written_with != Some(transform.affine());
        if !(state.dirty || interpolating || moved) {
            continue;
        }
        // A transform scaled to zero (or not finite) has no local space to write into: the mesh
        // keeps its last shape until the transform is usable again.
        if !invertible(transform) {
            continue;
        }
        let Some(mut mesh) = meshes.get_mut(&state.mesh) else {
            continue;
        };
        let alpha = if config.interpolate { fraction } else { 1.0 };
        let world_to_local = transform.affine().inverse();
        let s = &mut *state;
        // A mesh whose buffers were replaced or resized stops the cloth; `Build` reports it once.
        if let Err(e) = render::write_mesh(
            &mut mesh,
            &world_to_local,
            (&s.render_prev, &s.render_curr),
            (&s.normals_prev, &s.normals_curr),
            alpha,
        ) {
            s.failure = Some(e);
        }
        s.dirty = false;
        s.written_with = Some(transform.affine());
    }
}
