//! Building cloths (in [`ClothSystems::Build`](super::ClothSystems::Build)): skins adopted, new,
//! replaced and edited cloths built and validated (simulation, attachment to targets, render
//! side), and failures reported once as [`ClothInvalid`].

use std::time::Duration;

use bevy::asset::{AssetEvent, AssetId, Assets, Handle};
use bevy::ecs::prelude::*;
use bevy::log::{error, warn};
use bevy::math::Vec3;
use bevy::mesh::skinning::{SkinnedMesh, SkinnedMeshInverseBindposes};
use bevy::mesh::{Mesh, Mesh3d};
use bevy::platform::collections::HashSet;
use bevy::transform::components::GlobalTransform;

use super::edits::{commit_pins, plan_pins, report_edit, run_settings};
use super::mesh::refresh_render;
use super::poses::{invertible, pose_of};
use crate::components::{
    Cloth, ClothConfig, ClothEditRejected, ClothFrame, ClothInvalid, ClothPins, ClothSkin,
    ClothSource, ClothState, ClothSubdivision, ClothTargets, MAX_CLOTH_SUBDIVISION_LEVEL,
    RenderSubdivision, SubdivisionTarget, TargetWeights,
};
use crate::error::{ClothError, count_in};
use crate::render;
use crate::sim::{ClothModel, ClothSim, GridNormals, compute_normals};
use crate::skin::{Attachment, influences_from_mesh, weights_from_mesh};
use crate::subdivision::Subdivider;
use crate::tearing::ClothTearWeights;

/// A cloth spawned on a skinned mesh keeps the skin for its targets ([`ClothSkin`]); the
/// renderer must not skin the simulated mesh again.
pub(super) fn adopt_skins(
    mut commands: Commands,
    cloths: Query<(Entity, &SkinnedMesh), With<Cloth>>,
) {
    for (entity, skinned) in &cloths {
        commands
            .entity(entity)
            .remove::<SkinnedMesh>()
            .insert(ClothSkin {
                joints: skinned.joints.clone(),
                inverse_bindposes: skinned.inverse_bindposes.clone(),
            });
    }
}

type BuildQuery<'a> = (
    Entity,
    (Ref<'a, Cloth>, Ref<'a, ClothConfig>, Ref<'a, ClothPins>),
    &'a GlobalTransform,
    Option<Ref<'a, ClothSubdivision>>,
    (
        Option<Ref<'a, ClothTargets>>,
        Option<Ref<'a, ClothSkin>>,
        Option<&'a ClothFrame>,
        Option<Ref<'a, ClothTearWeights>>,
    ),
    Option<&'a mut ClothState>,
    (
        Has<ClothInvalid>,
        Option<&'a ClothEditRejected>,
        Has<AwaitingAssets>,
    ),
);

/// Marks a running cloth whose replacement waits for its assets (a new source mesh, a skin's
/// inverse bind poses): it runs on as it was and is rebuilt once they are loaded.
#[derive(Component)]
pub(super) struct AwaitingAssets;

/// What building a cloth reads besides its own components: mesh assets (and where new meshes
/// go), the skins' inverse bind poses, and joints' global transforms.
struct BuildInputs<'a, 'w, 's> {
    meshes: &'a mut Assets<Mesh>,
    bindposes: &'a Assets<SkinnedMeshInverseBindposes>,
    globals: &'a Query<'w, 's, &'static GlobalTransform>,
}

/// Builds new and replaced cloths (and invalid ones that were edited), and rebuilds running ones
/// whose targets, simulated subdivision or source mesh asset changed. A cloth that cannot be built
/// becomes [`ClothInvalid`]; a running cloth whose rebuild fails runs on as it was
/// ([`ClothEditRejected`]). Each failure is logged once.
pub(super) fn build_cloths(
    mut commands: Commands,
    mut meshes: ResMut<Assets<Mesh>>,
    mut mesh_events: MessageReader<AssetEvent<Mesh>>,
    bindposes: Res<Assets<SkinnedMeshInverseBindposes>>,
    (mut removed_subdivisions, mut removed_targets, mut removed_weights): (
        RemovedComponents<ClothSubdivision>,
        RemovedComponents<ClothTargets>,
        RemovedComponents<ClothTearWeights>,
    ),
    mut cloths: Query<BuildQuery>,
    globals: Query<&'static GlobalTransform>,
) {
    // Source meshes replaced or edited since the last frame (the cloths' own render meshes,
    // written every frame, are other assets).
    let modified: HashSet<AssetId<Mesh>> = mesh_events
        .read()
        .filter_map(|event| match event {
            AssetEvent::Modified { id } => Some(*id),
            _ => None,
        })
        .collect();
    // A cloth whose last edit was rejected, or that could not be built, is built again from
    // what it has at its next edit (a removal included), which is accepted or rejected whole.
    let removed: HashSet<Entity> = removed_subdivisions
        .read()
        .chain(removed_targets.read())
        .chain(removed_weights.read())
        .collect();
    for (
        entity,
        (cloth, config, pins),
        transform,
        subdivision,
        (targets, skin, frame, tear_weights),
        mut state,
        (invalid, rejected, awaiting),
    ) in &mut cloths
    {
        let subdivision_changed = match (&subdivision, &state) {
            (Some(s), _) => s.is_changed(),
            (None, Some(state)) => state.subdivision.is_some() || state.refined,
            (None, None) => false,
        };
        // Targets added, edited or removed, or a skin: the cloth is rebuilt.
        let targets_changed = targets.as_ref().is_some_and(|t| t.is_changed())
            || skin.as_ref().is_some_and(|s| s.is_changed())
            || targets.is_none() && state.as_ref().is_some_and(|s| s.attachment.is_some())
            || tear_weights.as_ref().is_some_and(|w| w.is_changed())
            || tear_weights.is_none()
                && state
                    .as_ref()
                    .is_some_and(|s| s.sim.tear_weights().is_some());
        let source_changed = cloth.is_changed()
            || matches!(&cloth.source, ClothSource::Mesh(h) if modified.contains(&h.id()));
        let edited = source_changed
            || config.is_changed()
            || pins.is_changed()
            || subdivision_changed
            || targets_changed;
        let failure = state
            .as_mut()
            .filter(|s| s.failure.is_some())
            .and_then(|s| s.failure.take());
        // New, replaced, waiting for its assets, or edited after being invalid; or its
        // subdivision changed while (or to) refining the simulation itself.
        let refines_sim = |s: &ClothSubdivision| s.target == SubdivisionTarget::Simulation;
        let rebuild = match &state {
            Some(state) => {
                source_changed
                    || awaiting
                    || targets_changed
                    || rejected.is_some() && (edited || removed.contains(&entity))
                    || subdivision_changed
                        && (state.refined || subdivision.as_deref().is_some_and(refines_sim))
            }
            None => !invalid || edited || removed.contains(&entity),
        };
        let subdivision = subdivision.as_deref();
        let mut inputs = BuildInputs {
            meshes: &mut meshes,
            bindposes: &bindposes,
            globals: &globals,
        };
        let running = state.is_some();
        let result = match (failure, state) {
            // A step or a mesh write failed: the cloth stops.
            (Some(e), _) => Err(e),
            (None, state) if rebuild => match build_state(
                (&cloth, &config, &pins),
                subdivision,
                (targets.as_deref(), skin.as_deref(), frame),
                tear_weights.as_deref(),
                transform,
                state.as_deref(),
                &mut inputs,
            ) {
                Ok(Some((state, mesh))) => {
                    let mut entity = commands.entity(entity);
                    entity
                        .remove::<(ClothInvalid, AwaitingAssets)>()
                        .insert((state, Mesh3d(mesh)));
                    if rejected.is_some() {
                        entity.remove::<ClothEditRejected>();
                    }
                    Ok(())
                }
                Ok(None) => {
                    if running && !awaiting {
                        commands.entity(entity).insert(AwaitingAssets);
                    }
                    Ok(())
                }
                Err(e) if running => {
                    commands.entity(entity).remove::<AwaitingAssets>();
                    report_edit(&mut commands, entity, Err(e), rejected);
                    Ok(())
                }
                Err(e) => Err(e),
            },
            (None, Some(mut state)) if subdivision_changed => {
                let result = rebuild_render(&mut state, subdivision, (None, false), inputs.meshes)
                    .map(|mesh| {
                        commands.entity(entity).insert(Mesh3d(mesh));
                    });
                report_edit(&mut commands, entity, result, rejected);
                Ok(())
            }
            (None, _) => Ok(()),
        };
        if let Err(e) = result {
            error!("cloth {entity}: {e}; the cloth is skipped until it is edited");
            commands
                .entity(entity)
                .remove::<(ClothState, ClothEditRejected, AwaitingAssets)>()
                .insert(ClothInvalid(e));
        }
    }
}

/// Builds the simulation and mesh of a cloth. `Ok(None)` means its mesh asset (or its skin's
/// inverse bind poses) is not loaded yet.
fn build_state(
    (cloth, config, pins): (&Cloth, &ClothConfig, &ClothPins),
    subdivision: Option<&ClothSubdivision>,
    (targets, skin, frame): (
        Option<&ClothTargets>,
        Option<&ClothSkin>,
        Option<&ClothFrame>,
    ),
    tear_weights: Option<&ClothTearWeights>,
    transform: &GlobalTransform,
    previous: Option<&ClothState>,
    inputs: &mut BuildInputs,
) -> Result<Option<(ClothState, Handle<Mesh>)>, ClothError> {
    if !invertible(transform) {
        return Err(ClothError::InvalidValue {
            field: "GlobalTransform determinant",
            expected: "finite and non-zero (no axis of the cloth entity scaled to 0)",
            value: transform.affine().matrix3.determinant() as f64,
        });
    }
    let meshes = &mut *inputs.meshes;
    let source_mesh = match &cloth.source {
        ClothSource::Mesh(handle) => meshes.get(handle),
        _ => None,
    };
    let (model, user_mesh, seams) = match (&cloth.source, source_mesh) {
        (ClothSource::Grid(spec), _) => (ClothModel::grid(spec)?, None, None),
        (ClothSource::Mesh(_), None) => return Ok(None),
        (ClothSource::Mesh(_), Some(source)) => {
            let model = render::model_from_mesh(source)?;
            // A closed surface split along its seams is simulated welded, rendered split.
            let (model, seams) = match model.weld_seams() {
                Some((welded, particle_of_vertex)) => (welded, Some(particle_of_vertex)),
                None => (model, None),
            };
            if model.triangles.len() > 3 && shares_no_vertex(&model.triangles) {
                warn!(
                    "a cloth mesh shares no vertex between its triangles, so its triangles move \
                     apart; was it exported without normals (Bevy's glTF loader then splits \
                     every vertex) or unwelded?"
                );
            }
            (
                model,
                Some(render::prepare_user_mesh(source.clone())),
                seams,
            )
        }
        (ClothSource::Model(shared), _) => {
            shared.model().validate()?;
            (shared.model().clone(), None, None)
        }
    };
    if seams.is_some() && targets.is_some() {
        return Err(ClothError::InvalidTargets {
            what: "a closed mesh welded along its seams takes no targets".into(),
        });
    }
    let refined = subdivision.filter(|s| s.level > 0 && s.target == SubdivisionTarget::Simulation);
    let (model, user_mesh, particle_map, mass_scale) = match refined {
        None => (model, user_mesh, seams.clone(), 1.0),
        Some(sub) => {
            check_level(sub)?;
            if targets.is_some() {
                return Err(ClothError::InvalidTargets {
                    what: "a cloth with targets is simulated at its own resolution \
                               (subdivide its render mesh instead)"
                        .into(),
                });
            }
            let refined = model.subdivided(sub.level, sub.rule, sub.boundary)?;
            // The user's mesh no longer matches the particles: render the refined model.
            (
                refined.model,
                None,
                // Pins index the source mesh's vertices: through the welding first.
                Some(match &seams {
                    Some(welded) => welded
                        .iter()
                        .map(|&p| refined.particle_map[p as usize])
                        .collect(),
                    None => refined.particle_map,
                }),
                refined.mass_scale,
            )
        }
    };
    let attachment = match targets {
        None => None,
        Some(targets) => {
            let skin = match skin {
                None => None,
                Some(skin) => match inputs.bindposes.get(&skin.inverse_bindposes) {
                    Some(bind) => Some((skin, &bind[..])),
                    None => return Ok(None),
                },
            };
            let mut attachment = build_attachment(&model, targets, source_mesh, skin)?;
            let joints = skin.map_or(&[][..], |(s, _)| &s.joints[..]);
            let globals = inputs.globals;
            attachment.update(&transform.affine(), |j| {
                globals.get(*joints.get(j)?).ok().map(|g| g.affine())
            });
            Some(attachment)
        }
    };
    let tear_values = match tear_weights {
        None => None,
        Some(_) if refined.is_some() => {
            return Err(ClothError::InvalidValue {
                field: "ClothTearWeights",
                expected: "a cloth simulated at its own resolution \
                           (subdivide its render mesh instead)",
                value: f64::from(refined.map_or(0, |s| s.level)),
            });
        }
        Some(w) => {
            let values = authored_weights(&w.weights, source_mesh, "tear weights")?;
            // Per source vertex; a vertex welded into a particle gives it the weakest of theirs.
            Some(match &particle_map {
                None => values,
                Some(map) if values.len() != map.len() => {
                    return Err(ClothError::InvalidValue {
                        field: "tear weights",
                        expected: "one per vertex of the source mesh",
                        value: values.len() as f64,
                    });
                }
                Some(map) => {
                    let mut per = vec![f32::INFINITY; model.particle_count()];
                    for (&v, &p) in values.iter().zip(map) {
                        per[p as usize] = per[p as usize].min(v);
                    }
                    per
                }
            })
        }
    };
    let meshes = &mut *inputs.meshes;
    let mut sim = ClothSim::new(model, run_settings(config, mass_scale), |p| {
        transform.transform_point(p)
    })?;
    // A rebuild that keeps the topology (new targets, a reshaped source mesh) keeps the motion.
    if let Some(previous) = previous {
        sim.continue_from(&previous.sim);
    }
    // The reference frame starts where it is now.
    let frame = frame.map_or(Some(*transform), |f| inputs.globals.get(f.0).ok().copied());
    if let Some(frame) = frame {
        sim.move_frame(pose_of(&frame));
    }
    if let Some(a) = &attachment {
        sim.set_targets(&a.limited().collect::<Vec<_>>())?;
    }
    if let Some(values) = tear_values {
        sim.set_tear_weights(Some(values))?;
    }
    let mut state = ClothState {
        sim,
        mesh: Handle::default(),
        subdivision: None,
        grid_normals: None,
        refined: refined.is_some(),
        particle_map,
        seam_normals: None,
        mass_scale,
        render_prev: Vec::new(),
        render_curr: Vec::new(),
        normals_prev: Vec::new(),
        normals_curr: Vec::new(),
        pins: Vec::new(),
        pin_targets: Vec::new(),
        attachment,
        target_pins: Vec::new(),
        failure: None,
        cuts: Vec::new(),
        splits: Vec::new(),
        step_time: Duration::ZERO,
        dirty: true,
        at_rest: false,
        lod: Default::default(),
        written_with: None,
    };
    let plan = plan_pins(&state, pins, transform)?;
    commit_pins(&mut state, plan)?;
    let mesh = rebuild_render(
        &mut state,
        subdivision,
        (user_mesh, seams.is_some()),
        meshes,
    )?;
    Ok(Some((state, mesh)))
}

/// Whether no vertex is used by more than one of the `triangles` (a mesh split into loose
/// triangles).
fn shares_no_vertex(triangles: &[u32]) -> bool {
    let mut seen = vec![false; triangles.iter().max().map_or(0, |&m| m as usize + 1)];
    triangles
        .iter()
        .all(|&v| !std::mem::replace(&mut seen[v as usize], true))
}

/// The weighted particles of a cloth with `targets`, from its model and (for weights or a skin
/// read from it) its source mesh, skinned by `skin` and its inverse bind poses when given.
fn build_attachment(
    model: &ClothModel,
    targets: &ClothTargets,
    source: Option<&Mesh>,
    skin: Option<(&ClothSkin, &[bevy::math::Mat4])>,
) -> Result<Attachment, ClothError> {
    let n = model.particle_count();
    let from_mesh = |what: &str| {
        source.ok_or_else(|| ClothError::InvalidTargets {
            what: format!("{what} needs a cloth made from a mesh asset"),
        })
    };
    let weights = authored_weights(&targets.weights, source, "targets")?;
    if weights.len() != n {
        return Err(ClothError::InvalidTargets {
            what: format!("{} weights for a cloth of {n} particles", weights.len()),
        });
    }
    // A negative weight leaves the particle free; NaN is refused by the attachment.
    let weights: Vec<Option<f32>> = weights
        .iter()
        .map(|&w| (w.is_nan() || w >= 0.0).then_some(w))
        .collect();
    let mut normals = vec![Vec3::ZERO; n];
    compute_normals(&model.rest_positions, &model.triangles, &mut normals);
    let skin = match skin {
        None => None,
        Some((skin, bind)) => {
            let influences = influences_from_mesh(from_mesh("a skin")?)?;
            if bind.len() != skin.joints.len() {
                return Err(ClothError::InvalidTargets {
                    what: format!(
                        "the skin has {} joints but {} inverse bind poses",
                        skin.joints.len(),
                        bind.len()
                    ),
                });
            }
            Some((influences, bind))
        }
    };
    Attachment::new(&weights, (&model.rest_positions, &normals), skin)
}

/// The values of authored `weights` (for `what`), read from the cloth's `source` mesh when they
/// name one of its channels.
fn authored_weights(
    weights: &TargetWeights,
    source: Option<&Mesh>,
    what: &str,
) -> Result<Vec<f32>, ClothError> {
    let from_mesh = |how: &str| {
        source.ok_or_else(|| ClothError::InvalidTargets {
            what: format!("{what}: {how} needs a cloth made from a mesh asset"),
        })
    };
    Ok(match weights {
        TargetWeights::Values(w) => w.clone(),
        TargetWeights::Color(channel) => weights_from_mesh(
            from_mesh("weights from vertex colours")?,
            None,
            *channel as usize,
        )?,
        TargetWeights::Attribute(name) => {
            weights_from_mesh(from_mesh("weights from a vertex attribute")?, Some(name), 0)?
        }
    })
}

/// Checks a subdivision level against [`MAX_CLOTH_SUBDIVISION_LEVEL`].
fn check_level(sub: &ClothSubdivision) -> Result<(), ClothError> {
    count_in(
        "subdivision.level",
        sub.level,
        0,
        MAX_CLOTH_SUBDIVISION_LEVEL,
    )
}

/// Sets up the render side of a cloth (subdivision stencils, buffers, a new mesh asset) for its
/// current particles, and returns the mesh handle. Unsubdivided, the cloth renders into `user_mesh`
/// when given (a copy of the user's source mesh, keeping all its attributes; when the simulation
/// `welded` its seams, each vertex drawn at its particle in `particle_map`). Fails, changing
/// nothing, when the subdivision cannot be built; a render pass that then fails stops the cloth.
pub(super) fn rebuild_render(
    state: &mut ClothState,
    subdivision: Option<&ClothSubdivision>,
    (user_mesh, welded): (Option<Mesh>, bool),
    meshes: &mut Assets<Mesh>,
) -> Result<Handle<Mesh>, ClothError> {
    let model = state.sim.model();
    let render_level = |s: &&ClothSubdivision| s.level > 0 && s.target == SubdivisionTarget::Render;
    state.subdivision = match subdivision.filter(render_level) {
        None => None,
        Some(sub) => {
            check_level(sub)?;
            let subdivider =
                Subdivider::new(&model.control_mesh()?, sub.level, sub.rule, sub.boundary)?;
            let n = subdivider.refined_vertex_count();
            Some(RenderSubdivision {
                subdivider,
                positions: vec![Vec3::ZERO; n],
                normals: vec![Vec3::Y; n],
            })
        }
    };
    state.grid_normals = match state.subdivision {
        None => GridNormals::new(model),
        Some(_) => None,
    };
    state.seam_normals = None;
    let mesh = match (&state.subdivision, user_mesh) {
        (None, Some(user_mesh)) => {
            if welded {
                state.seam_normals = Some(vec![Vec3::Y; model.particle_count()]);
            }
            user_mesh
        }
        (None, None) => render::mesh_for_model(model),
        (Some(r), _) => render::mesh_for_subdivision(&r.subdivider),
    };
    Ok(install_mesh(state, mesh, meshes))
}

/// After a tear, brings a subdivided cloth's render stencils up to date with its torn mesh
/// ([`Subdivider::follow`]: only the faces around the tear are refined again) and gives it a new
/// mesh asset; a cloth drawn unsubdivided is set up afresh ([`rebuild_render`]). Fails, changing
/// nothing, when the torn mesh cannot be refined.
pub(super) fn follow_render(
    state: &mut ClothState,
    subdivision: Option<&ClothSubdivision>,
    meshes: &mut Assets<Mesh>,
) -> Result<Handle<Mesh>, ClothError> {
    let Some(r) = &mut state.subdivision else {
        return rebuild_render(state, subdivision, (None, false), meshes);
    };
    r.subdivider.follow(&state.sim.model().control_mesh()?)?;
    let n = r.subdivider.refined_vertex_count();
    r.positions.resize(n, Vec3::ZERO);
    r.normals.resize(n, Vec3::Y);
    let mesh = render::mesh_for_subdivision(&r.subdivider);
    Ok(install_mesh(state, mesh, meshes))
}

/// Sizes the cloth's render buffers for `mesh`, fills them, and adds `mesh` as its asset.
fn install_mesh(state: &mut ClothState, mesh: Mesh, meshes: &mut Assets<Mesh>) -> Handle<Mesh> {
    let count = mesh.count_vertices();
    for buffer in [
        &mut state.render_prev,
        &mut state.render_curr,
        &mut state.normals_prev,
        &mut state.normals_curr,
    ] {
        buffer.resize(count, Vec3::ZERO);
    }
    // The buffers match the particles and the mesh by construction: a failure here is a bug,
    // reported as the cloth stopping rather than a rejected edit.
    state.failure = refresh_render(state).err();
    state.render_prev.copy_from_slice(&state.render_curr);
    state.normals_prev.copy_from_slice(&state.normals_curr);
    state.dirty = true;
    state.mesh = meshes.add(mesh);
    state.mesh.clone()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn loose_triangles_share_no_vertex_and_a_welded_strip_does() {
        assert!(shares_no_vertex(&[0, 1, 2, 3, 4, 5]));
        assert!(!shares_no_vertex(&[0, 1, 2, 2, 1, 3]));
        assert!(shares_no_vertex(&[]));
    }
}
