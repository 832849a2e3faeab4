//! Render meshes of cloths: building the `Mesh` asset once when a cloth is created, reading a user's
//! mesh as a cloth source, and writing simulated positions and normals into the existing attribute
//! buffers in place every frame (no new buffers).

use bevy::asset::RenderAssetUsages;
use bevy::math::{Affine3A, Mat3A, Vec2, Vec3, Vec3A};
use bevy::mesh::{Indices, Mesh, MeshAccessError, PrimitiveTopology, VertexAttributeValues};

use crate::error::ClothError;
use crate::sim::ClothModel;
use crate::subdivision::Subdivider;

/// A triangle-list mesh of the cloth's rest shape with positions, normals, UVs and indices, usable
/// in both worlds so it can be rewritten every frame.
pub(crate) fn mesh_for_model(model: &ClothModel) -> Mesh {
    let mut normals = vec![Vec3::Y; model.particle_count()];
    crate::sim::compute_normals(&model.rest_positions, &model.triangles, &mut normals);
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, to_arrays(&model.rest_positions))
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, to_arrays(&normals))
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_UV_0,
        model.uvs.iter().map(|u| u.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(model.triangles.clone()))
}

/// A triangle-list mesh for a subdivided cloth (the render layout of the refined surface, UV seams
/// split). Positions and normals are placeholders until the first write.
pub(crate) fn mesh_for_subdivision(subdivider: &Subdivider) -> Mesh {
    let layout = subdivider.topology().render_mesh();
    let n = layout.vertex_count();
    let uvs: Vec<[f32; 2]> = match layout.uvs() {
        Some(uvs) => uvs.iter().map(|u| u.to_array()).collect(),
        None => vec![[0.0, 0.0]; n],
    };
    Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; n])
    .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32, 1.0, 0.0]; n])
    .with_inserted_attribute(Mesh::ATTRIBUTE_UV_0, uvs)
    .with_inserted_indices(Indices::U32(layout.triangle_indices().to_vec()))
}

fn to_arrays(v: &[Vec3]) -> Vec<[f32; 3]> {
    v.iter().map(|p| p.to_array()).collect()
}

fn mesh_error(what: impl Into<String>) -> ClothError {
    ClothError::InvalidMesh { what: what.into() }
}

fn access(e: MeshAccessError) -> ClothError {
    mesh_error(format!("cannot be read: {e}"))
}

/// Builds a cloth model from a user's triangle-list mesh (one particle per vertex).
pub(crate) fn model_from_mesh(mesh: &Mesh) -> Result<ClothModel, ClothError> {
    if mesh.primitive_topology() != PrimitiveTopology::TriangleList {
        return Err(mesh_error(format!(
            "must be a TriangleList, got {:?}",
            mesh.primitive_topology()
        )));
    }
    let positions: Vec<Vec3> = match mesh
        .try_attribute_option(Mesh::ATTRIBUTE_POSITION)
        .map_err(access)?
    {
        Some(VertexAttributeValues::Float32x3(p)) => {
            // Counted before anything is copied.
            crate::error::particles_within(p.len() as u64, || "one per mesh vertex".into())?;
            p.iter().map(|p| Vec3::from_array(*p)).collect()
        }
        Some(other) => {
            return Err(mesh_error(format!(
                "positions must be Float32x3, got {:?}",
                other.enum_variant_name()
            )));
        }
        None => return Err(mesh_error("has no vertex positions")),
    };
    // Every attribute holds one value per vertex: the cloth rewrites positions and normals in
    // place and keeps the others, so a short or long one would leave vertices without data.
    for (attribute, values) in mesh.try_attributes().map_err(access)? {
        if values.len() != positions.len() {
            return Err(mesh_error(format!(
                "attribute {} has {} values for {} vertex positions",
                attribute.name,
                values.len(),
                positions.len()
            )));
        }
    }
    let uvs: Option<Vec<Vec2>> = match mesh
        .try_attribute_option(Mesh::ATTRIBUTE_UV_0)
        .map_err(access)?
    {
        Some(VertexAttributeValues::Float32x2(uv)) => {
            Some(uv.iter().map(|u| Vec2::from_array(*u)).collect())
        }
        _ => None,
    };
    let indices: Vec<u32> = match mesh.try_indices_option().map_err(access)? {
        Some(Indices::U32(i)) => i.clone(),
        Some(Indices::U16(i)) => i.iter().map(|&i| i as u32).collect(),
        None => return Err(mesh_error("has no index buffer")),
    };
    ClothModel::from_mesh(&positions, uvs.as_deref(), &indices, 3)
}

/// The same mesh with positions and normals present as `Float32x3` (normals added if missing), ready
/// to be rewritten in place, and without joint indices and weights.
pub(crate) fn prepare_user_mesh(mut mesh: Mesh) -> Mesh {
    mesh.asset_usage = RenderAssetUsages::default();
    // The cloth's mesh holds simulated positions; nothing must skin it again.
    mesh.remove_attribute(Mesh::ATTRIBUTE_JOINT_INDEX);
    mesh.remove_attribute(Mesh::ATTRIBUTE_JOINT_WEIGHT);
    let count = mesh.count_vertices();
    let has_normals = matches!(
        mesh.try_attribute_option(Mesh::ATTRIBUTE_NORMAL),
        Ok(Some(VertexAttributeValues::Float32x3(n))) if n.len() == count
    );
    if !has_normals {
        mesh.insert_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0, 1.0, 0.0]; count]);
    }
    mesh
}

/// Writes world-space `positions` and `normals` (blended as `prev + (curr - prev) * alpha`) into
/// the mesh's existing position and normal buffers, in the local space given by `world_to_local`.
/// Fails without writing if the buffers are missing or have the wrong size.
pub(crate) fn write_mesh(
    mesh: &mut Mesh,
    world_to_local: &Affine3A,
    positions: (&[Vec3], &[Vec3]),
    normals: (&[Vec3], &[Vec3]),
    alpha: f32,
) -> Result<(), ClothError> {
    // An entity that is only moved, not turned or scaled (the common case): the positions are
    // shifted, and the normals, unit as every normals pass leaves them, are kept unless blended.
    if world_to_local.matrix3 == Mat3A::IDENTITY {
        let shift = world_to_local.translation;
        write_attribute(mesh, Mesh::ATTRIBUTE_POSITION, positions, alpha, |p| {
            p + shift
        })?;
        return if alpha >= 1.0 {
            write_attribute(mesh, Mesh::ATTRIBUTE_NORMAL, normals, alpha, |n| n)
        } else {
            write_attribute(mesh, Mesh::ATTRIBUTE_NORMAL, normals, alpha, |n| {
                n.normalize_or(Vec3A::Y)
            })
        };
    }
    let normal_matrix: Mat3A = world_to_local.matrix3.inverse().transpose();
    write_attribute(mesh, Mesh::ATTRIBUTE_POSITION, positions, alpha, |p| {
        world_to_local.transform_point3a(p)
    })?;
    write_attribute(mesh, Mesh::ATTRIBUTE_NORMAL, normals, alpha, |n| {
        (normal_matrix * n).normalize_or(Vec3A::Y)
    })
}

fn write_attribute(
    mesh: &mut Mesh,
    attribute: bevy::mesh::MeshVertexAttribute,
    (prev, curr): (&[Vec3], &[Vec3]),
    alpha: f32,
    map: impl Fn(Vec3A) -> Vec3A,
) -> Result<(), ClothError> {
    let Some(VertexAttributeValues::Float32x3(out)) =
        mesh.try_attribute_mut_option(attribute).map_err(access)?
    else {
        return Err(mesh_error(format!("lost its {} buffer", attribute.name)));
    };
    if out.len() != curr.len() {
        return Err(mesh_error(format!(
            "{} buffer has {} entries, the cloth has {}",
            attribute.name,
            out.len(),
            curr.len()
        )));
    }
    // In 16-byte vectors: whole SIMD registers for the arithmetic.
    if alpha >= 1.0 {
        for (o, c) in out.iter_mut().zip(curr) {
            *o = Vec3::from(map(Vec3A::from(*c))).to_array();
        }
    } else {
        for ((o, p), c) in out.iter_mut().zip(prev).zip(curr) {
            *o = Vec3::from(map(Vec3A::from(*p).lerp(Vec3A::from(*c), alpha))).to_array();
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::math::Quat;

    fn attribute(mesh: &Mesh, attribute: bevy::mesh::MeshVertexAttribute) -> Vec<Vec3> {
        match mesh.try_attribute_option(attribute) {
            Ok(Some(VertexAttributeValues::Float32x3(v))) => {
                v.iter().map(|&a| Vec3::from(a)).collect()
            }
            _ => panic!("no {} buffer", attribute.name),
        }
    }

    #[test]
    fn a_moved_entity_and_a_turned_one_get_the_mesh_of_their_transform() {
        let curr = [Vec3::new(0.1, 2.0, -0.3), Vec3::new(-1.0, 0.5, 0.25)];
        let prev = [Vec3::new(0.0, 1.9, -0.3), Vec3::new(-1.0, 0.4, 0.2)];
        let normals = [Vec3::new(0.6, 0.8, 0.0), Vec3::Z];
        let normals_prev = [Vec3::Y, Vec3::X];
        let moved = Affine3A::from_translation(Vec3::new(1.0, -2.0, 0.5));
        let turned = Affine3A::from_scale_rotation_translation(
            Vec3::new(1.0, 2.0, 0.5),
            Quat::from_rotation_y(0.7),
            Vec3::new(0.3, 0.0, -1.0),
        );
        for world_to_local in [moved, turned] {
            for alpha in [1.0, 0.25] {
                let mut mesh = Mesh::new(
                    PrimitiveTopology::TriangleList,
                    RenderAssetUsages::default(),
                )
                .with_inserted_attribute(Mesh::ATTRIBUTE_POSITION, vec![[0.0f32; 3]; 2])
                .with_inserted_attribute(Mesh::ATTRIBUTE_NORMAL, vec![[0.0f32; 3]; 2]);
                let (p, n) = ((&prev[..], &curr[..]), (&normals_prev[..], &normals[..]));
                write_mesh(&mut mesh, &world_to_local, p, n, alpha).unwrap();
                let normal_matrix = world_to_local.matrix3.inverse().transpose();
                let got = (
                    attribute(&mesh, Mesh::ATTRIBUTE_POSITION),
                    attribute(&mesh, Mesh::ATTRIBUTE_NORMAL),
                );
                for k in 0..2 {
                    let position = world_to_local.transform_point3(prev[k].lerp(curr[k], alpha));
                    let normal =
                        normal_matrix * Vec3A::from(normals_prev[k].lerp(normals[k], alpha));
                    let normal = Vec3::from(normal.normalize());
                    assert!(
                        (got.0[k] - position).length() < 1e-6,
                        "{world_to_local:?} {k}"
                    );
                    assert!(
                        (got.1[k] - normal).length() < 1e-6,
                        "{world_to_local:?} {k}"
                    );
                }
            }
        }
    }
}
