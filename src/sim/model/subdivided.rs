//! A cloth refined by Catmull-Clark subdivision before it is simulated ([`SubdividedModel`]).

use glam::{DVec3, Vec3};

use super::ClothModel;
use crate::error::{ClothError, particles_within};
use crate::subdivision::{BoundaryMode, PolyMesh, Subdivider, SubdivisionError, VertexRule};

/// A cloth model refined by Catmull-Clark subdivision before simulating
/// ([`ClothModel::subdivided`]).
#[derive(Debug, Clone)]
pub struct SubdividedModel {
    /// The refined model: all-quad faces, one particle per refined vertex.
    pub model: ClothModel,
    /// For each particle of the original model, the particle it became (its vertex point).
    pub particle_map: Vec<u32>,
    /// Original particle count over refined particle count: scale a uniform particle mass by it
    /// to keep the cloth's total mass (per-particle masses are already scaled).
    pub mass_scale: f32,
}

impl ClothModel {
    /// Refines the rest mesh `level` times with Catmull-Clark subdivision and builds a cloth model
    /// from the refined quads, so that the cloth simulates at the finer resolution (about 4× the
    /// particles per level) on the smooth limit shape rather than only rendering it.
    ///
    /// Springs follow [`from_mesh`](Self::from_mesh) on the refined quads with unchanged
    /// per-spring stiffness (the membrane stiffness of a spring grid does not depend on its
    /// spacing). Per-particle masses, if any, are interpolated with the subdivision stencils and
    /// scaled to keep their total; a uniform mass is left to the caller, who scales it by
    /// [`SubdividedModel::mass_scale`]. UVs follow the refined surface. Errors:
    /// [`ClothError::TooMany`] when the refined cloth would have more than
    /// [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES) particles (counted before refining), the
    /// subdivision errors of [`control_mesh`](Self::control_mesh) and
    /// [`Subdivider::new`](crate::subdivision::Subdivider::new) (a mesh that is not
    /// manifold and consistently oriented), and those of `from_mesh`.
    pub fn subdivided(
        &self,
        level: u32,
        rule: VertexRule,
        boundary: BoundaryMode,
    ) -> Result<SubdividedModel, ClothError> {
        let control = self.control_mesh()?;
        // Counted from the control mesh before anything is refined.
        let count = control.refined_vertex_count(level)?;
        particles_within(count, || {
            format!(
                "subdivision level {level} refines the cloth's {} particles to that many",
                self.particle_count()
            )
        })?;
        let sub = Subdivider::new(&control, level, rule, boundary)?;
        let n = sub.refined_vertex_count();
        let mut refined = vec![DVec3::ZERO; n];
        sub.apply_f64(control.positions(), &mut refined)?;
        let positions: Vec<Vec3> = refined.iter().map(|p| p.as_vec3()).collect();
        let topology = sub.topology();
        // Render vertices start with the refined vertices, each with the UV of its first corner.
        let uvs = topology.render_mesh().uvs().map(|uvs| &uvs[..n]);
        let faces = topology.face_indices();
        let face_size = if topology.quad_indices().is_some() {
            4
        } else {
            // Level 0 keeps the control faces.
            self.face_size
        };
        let mut model = ClothModel::from_mesh(&positions, uvs, faces, face_size)?;
        if let Some(masses) = &self.particle_masses {
            let control_masses: Vec<DVec3> = masses
                .iter()
                .map(|&m| DVec3::new(f64::from(m), 0.0, 0.0))
                .collect();
            let mut spread = vec![DVec3::ZERO; n];
            sub.apply_f64(&control_masses, &mut spread)?;
            let total: f64 = masses.iter().map(|&m| f64::from(m)).sum();
            let spread_total: f64 = spread.iter().map(|m| m.x).sum();
            let scale = total / spread_total;
            model = model
                .with_particle_masses(spread.iter().map(|m| (m.x * scale) as f32).collect())?;
        }
        Ok(SubdividedModel {
            model,
            particle_map: topology.control_vertex_map().to_vec(),
            mass_scale: (self.particle_count() as f64 / n as f64) as f32,
        })
    }

    /// The control polygon mesh (rest positions, faces and UVs) that subdivision refines.
    pub fn control_mesh(&self) -> Result<PolyMesh, SubdivisionError> {
        let positions = self.rest_positions.iter().map(|p| p.as_dvec3());
        let mesh = match self.face_size {
            4 => PolyMesh::from_quads(positions, &self.faces)?,
            _ => PolyMesh::from_triangles(positions, &self.faces)?,
        };
        mesh.with_vertex_uvs(&self.uvs)
    }
}
