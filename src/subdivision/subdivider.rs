//! The top-level API: [`Subdivider`] (refine once, apply every frame),
//! [`RefinedTopology`] and [`RenderMesh`] (what a renderer builds its mesh
//! from), smooth normals, and one-shot [`refine_positions`].
//!
//! This module glues `refine` and `stencil` together. It must not hold rule
//! formulas or refinement internals, and its per-frame functions
//! ([`Subdivider::apply`], [`RefinedTopology::compute_normals`],
//! [`RenderMesh::expand`]) must not allocate.

mod follow;
#[cfg(test)]
mod tests;

use std::collections::HashMap;

pub use follow::Followed;
use follow::Patch;
use glam::{DVec3, Vec2, Vec3, Vec3A};

use super::grid::{GridEvaluator, GridShape};
use super::refine::{compose, refine, refine_direct};
use super::sparse_rows::SparseRows;
use super::{BoundaryMode, PolyMesh, StencilTable, SubdivisionError, VertexRule};

/// Connectivity of the finest refinement level, built once.
///
/// At level 0 the faces are the control polygons; at level ≥ 1 every face is
/// a quad. Vertex indices refer to refined vertices, i.e. to rows of the
/// [`StencilTable`].
#[derive(Debug, Clone, PartialEq)]
pub struct RefinedTopology {
    vertex_count: usize,
    face_offsets: Vec<u32>,
    face_indices: Vec<u32>,
    all_quads: bool,
    triangles: Vec<u32>,
    corner_uvs: Option<Vec<Vec2>>,
    control_vertex_map: Vec<u32>,
    render: RenderMesh,
}

impl RefinedTopology {
    /// Number of refined vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count
    }

    /// Number of refined faces.
    pub fn face_count(&self) -> usize {
        self.face_offsets.len() - 1
    }

    /// CSR face offsets of the refined faces.
    pub fn face_offsets(&self) -> &[u32] {
        &self.face_offsets
    }

    /// All refined face corners, concatenated.
    pub fn face_indices(&self) -> &[u32] {
        &self.face_indices
    }

    /// The refined faces as a flat quad index buffer (4 per face), or `None`
    /// when some face is not a quad (only possible at level 0).
    pub fn quad_indices(&self) -> Option<&[u32]> {
        self.all_quads.then_some(self.face_indices.as_slice())
    }

    /// The refined faces fan-triangulated (quad `a b c d` → `a b c`, `a c d`),
    /// 3 indices per triangle, same orientation as the faces.
    pub fn triangle_indices(&self) -> &[u32] {
        &self.triangles
    }

    /// Face-varying UVs of the refined faces (parallel to
    /// [`face_indices`](Self::face_indices)), interpolated linearly: a
    /// refined corner on a parent corner keeps its UV, one on a parent edge
    /// gets the edge's mean UV, and the face point gets the face's mean UV.
    pub fn corner_uvs(&self) -> Option<&[Vec2]> {
        self.corner_uvs.as_deref()
    }

    /// For each control vertex, the index of the refined vertex it became
    /// (its vertex point at the finest level).
    pub fn control_vertex_map(&self) -> &[u32] {
        &self.control_vertex_map
    }

    /// Render-ready vertex layout (UV seams split, triangles).
    pub fn render_mesh(&self) -> &RenderMesh {
        &self.render
    }

    /// Computes smooth per-vertex normals of the refined surface.
    ///
    /// Each face contributes its vector area (area-weighted normal, from the
    /// cross product of its diagonals for quads, a fan for other polygons) to
    /// each of its corners; sums are then normalized. A vertex whose sum has
    /// (near) zero length, e.g. an unused vertex or a fully degenerate
    /// neighbourhood, gets `Vec3::Y`. `positions` and `normals` must both have
    /// [`vertex_count`](Self::vertex_count) elements. Does not allocate.
    pub fn compute_normals(
        &self,
        positions: &[Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), SubdivisionError> {
        check_len("positions", self.vertex_count, positions.len())?;
        check_len("normals", self.vertex_count, normals.len())?;
        normals.fill(Vec3::ZERO);
        if self.all_quads {
            for q in self.face_indices.chunks_exact(4) {
                let (a, b, c, d) = (q[0] as usize, q[1] as usize, q[2] as usize, q[3] as usize);
                let n = (positions[c] - positions[a]).cross(positions[d] - positions[b]);
                normals[a] += n;
                normals[b] += n;
                normals[c] += n;
                normals[d] += n;
            }
        } else {
            for w in self.face_offsets.windows(2) {
                let face = &self.face_indices[w[0] as usize..w[1] as usize];
                let p0 = positions[face[0] as usize];
                let mut n = Vec3::ZERO;
                for k in 1..face.len() - 1 {
                    n += (positions[face[k] as usize] - p0)
                        .cross(positions[face[k + 1] as usize] - p0);
                }
                for &v in face {
                    normals[v as usize] += n;
                }
            }
        }
        for n in normals.iter_mut() {
            let len2 = n.length_squared();
            *n = if len2 > f32::MIN_POSITIVE && len2.is_finite() {
                *n / len2.sqrt()
            } else {
                Vec3::Y
            };
        }
        Ok(())
    }
}

/// A render vertex layout for the refined surface.
///
/// Render vertex `i < refined_vertex_count` is refined vertex `i`; where
/// face-varying UVs have seams, extra render vertices are appended, render
/// vertex `refined_vertex_count + k` being a copy of refined vertex
/// `seam_vertices[k]` with its own UV. Without UVs there are no seam vertices.
/// A renderer builds its index buffer from
/// [`triangle_indices`](Self::triangle_indices) once and each frame fills
/// positions and normals with [`expand`](Self::expand).
#[derive(Debug, Clone, PartialEq)]
pub struct RenderMesh {
    refined_vertex_count: usize,
    seam_vertices: Vec<u32>,
    uvs: Option<Vec<Vec2>>,
    triangles: Vec<u32>,
}

impl RenderMesh {
    /// Number of render vertices (refined vertices plus seam copies).
    pub fn vertex_count(&self) -> usize {
        self.refined_vertex_count + self.seam_vertices.len()
    }

    /// The refined vertex each appended seam vertex copies.
    pub fn seam_vertices(&self) -> &[u32] {
        &self.seam_vertices
    }

    /// Per-render-vertex UVs (unused refined vertices get `Vec2::ZERO`), if
    /// the control mesh had UVs.
    pub fn uvs(&self) -> Option<&[Vec2]> {
        self.uvs.as_deref()
    }

    /// Triangle index buffer over render vertices, 3 per triangle.
    pub fn triangle_indices(&self) -> &[u32] {
        &self.triangles
    }

    /// Copies per-refined-vertex data (positions, normals) into the render
    /// layout. `refined` must have one element per refined vertex and `out`
    /// one per render vertex. Does not allocate.
    pub fn expand(&self, refined: &[Vec3], out: &mut [Vec3]) -> Result<(), SubdivisionError> {
        check_len("refined", self.refined_vertex_count, refined.len())?;
        check_len("out", self.vertex_count(), out.len())?;
        let (head, tail) = out.split_at_mut(self.refined_vertex_count);
        head.copy_from_slice(refined);
        for (o, &v) in tail.iter_mut().zip(&self.seam_vertices) {
            *o = refined[v as usize];
        }
        Ok(())
    }
}

/// Refines a control mesh once and evaluates it any number of times.
///
/// Construction does all topology work (refinement to `level`, one stencil
/// table per level, render layout); [`apply`](Self::apply) then only
/// multiplies the tables, level by level, with the current control positions.
///
/// # Example
/// ```
/// use glam::{DVec3, Vec3};
/// use bevy_cloth::subdivision::{BoundaryMode, PolyMesh, Subdivider, VertexRule};
///
/// let grid = PolyMesh::from_quads(
///     (0..9).map(|i| DVec3::new((i % 3) as f64, 0.0, (i / 3) as f64)),
///     &[0, 3, 4, 1, 1, 4, 5, 2, 3, 6, 7, 4, 4, 7, 8, 5],
/// )?;
/// let mut sub = Subdivider::new(&grid, 2, VertexRule::Original, BoundaryMode::EdgeAndCorner)?;
/// let control: Vec<Vec3> = grid.positions_f32();
/// let mut refined = vec![Vec3::ZERO; sub.refined_vertex_count()];
/// let mut normals = vec![Vec3::ZERO; sub.refined_vertex_count()];
/// sub.apply(&control, &mut refined)?;
/// sub.compute_normals(&refined, &mut normals)?;
/// assert_eq!(refined.len(), 81);
/// # Ok::<(), bevy_cloth::subdivision::SubdivisionError>(())
/// ```
#[derive(Debug, Clone)]
pub struct Subdivider {
    level: u32,
    rule: VertexRule,
    boundary: BoundaryMode,
    control_count: usize,
    /// Factorized stencils: level `i + 1` over level `i`.
    levels: Vec<StencilTable>,
    /// Positions of the intermediate levels `1 .. level` during [`apply`](Self::apply).
    scratch: Vec<Vec<Vec3A>>,
    /// For a grid, what [`apply`](Self::apply) evaluates instead of the level tables.
    grid: Option<GridEvaluator>,
    topology: RefinedTopology,
    /// The control mesh's faces, which [`follow`](Self::follow) compares a changed mesh with.
    control: ControlFaces,
    /// The stencils of the vertices that [`follow`](Self::follow) refined again.
    patch: Option<Patch>,
}

/// The faces (and corner UVs) of the control mesh a [`Subdivider`] refines.
#[derive(Debug, Clone)]
struct ControlFaces {
    face_offsets: Vec<u32>,
    face_indices: Vec<u32>,
    uvs: Option<Vec<Vec2>>,
}

impl Subdivider {
    /// Refines `mesh` uniformly to `level` (0 ..= [`MAX_LEVEL`](super::MAX_LEVEL))
    /// with the given interior vertex rule and boundary mode.
    ///
    /// Level 0 yields identity stencils and the control faces. Errors:
    /// [`SubdivisionError::LevelTooHigh`], or
    /// [`SubdivisionError::TooLarge`] when the refined mesh would exceed
    /// [`MAX_REFINED_FACES`](super::MAX_REFINED_FACES) faces or
    /// [`MAX_REFINED_VERTICES`](super::MAX_REFINED_VERTICES) vertices (both counted before
    /// anything is refined) or [`MAX_STENCIL_ENTRIES`](super::MAX_STENCIL_ENTRIES) stencil
    /// entries (counted as they are made).
    pub fn new(
        mesh: &PolyMesh,
        level: u32,
        rule: VertexRule,
        boundary: BoundaryMode,
    ) -> Result<Self, SubdivisionError> {
        let base = mesh.topology()?;
        let shape = if level > 0 {
            GridShape::detect(base)
        } else {
            None
        };
        let r = refine(
            base,
            mesh.uvs().map(<[Vec2]>::to_vec),
            shape.map(GridShape::coordinates),
            level,
            rule,
            boundary,
        )?;
        let grid_coordinates = r.grid_coordinates;
        let vertex_count = r.topology.num_vertices;
        let all_quads = r.topology.quads;
        let face_offsets = r.topology.faces.face_offsets;
        let face_indices = r.topology.faces.face_indices;
        let triangles = triangulate(&face_offsets, |c| face_indices[c]);
        let render = build_render_mesh(
            vertex_count,
            &face_offsets,
            &face_indices,
            r.uvs.as_deref(),
            &triangles,
        );
        let topology = RefinedTopology {
            vertex_count,
            face_offsets,
            face_indices,
            all_quads,
            triangles,
            corner_uvs: r.uvs,
            control_vertex_map: r.control_vertex_map,
            render,
        };
        let mut columns = mesh.vertex_count();
        let levels: Vec<StencilTable> = r
            .levels
            .into_iter()
            .map(|rows| {
                let table = StencilTable::from_rows(rows, columns);
                columns = table.len();
                table
            })
            .collect();
        let grid = shape
            .zip(grid_coordinates)
            .and_then(|(shape, coords)| GridEvaluator::new(shape, &levels, &coords));
        // The intermediate levels, unless the grid evaluator skips them.
        let scratch = levels
            .iter()
            .take(if grid.is_some() {
                0
            } else {
                levels.len().saturating_sub(1)
            })
            .map(|t| vec![Vec3A::ZERO; t.len()])
            .collect();
        Ok(Subdivider {
            level,
            rule,
            boundary,
            control_count: mesh.vertex_count(),
            levels,
            scratch,
            grid,
            topology,
            control: ControlFaces {
                face_offsets: mesh.face_offsets().to_vec(),
                face_indices: mesh.face_indices().to_vec(),
                uvs: mesh.uvs().map(<[Vec2]>::to_vec),
            },
            patch: None,
        })
    }

    /// The grid evaluator [`apply`](Self::apply) uses, if the control mesh is a grid.
    #[cfg(test)]
    pub(crate) fn grid(&self) -> Option<&GridEvaluator> {
        self.grid.as_ref()
    }

    /// The refinement level.
    pub fn level(&self) -> u32 {
        self.level
    }

    /// The interior vertex rule.
    pub fn rule(&self) -> VertexRule {
        self.rule
    }

    /// The boundary mode.
    pub fn boundary(&self) -> BoundaryMode {
        self.boundary
    }

    /// The factorized stencil tables, one per level: table `i` gives the vertices of level
    /// `i + 1` as weighted sums of the vertices of level `i` (level 0 being the control mesh).
    /// [`apply`](Self::apply) evaluates them in order. Empty at level 0.
    pub fn level_stencils(&self) -> &[StencilTable] {
        &self.levels
    }

    /// The stencils of the refined vertices over the control vertices: the level tables
    /// multiplied together (computed on each call; wider rows than the level tables, so
    /// slower to apply, but what a GPU evaluator or a caller wanting the weights needs).
    /// Errors with [`SubdivisionError::TooLarge`] past
    /// [`MAX_STENCIL_ENTRIES`](super::MAX_STENCIL_ENTRIES) entries.
    pub fn composed_stencils(&self) -> Result<StencilTable, SubdivisionError> {
        let base = self.base_counts().0;
        let mut rows = SparseRows::identity(base);
        for table in &self.levels {
            rows = compose(&rows, &table.sparse_rows(), base)?;
        }
        if let Some(patch) = &self.patch {
            rows = patch.compose_with(rows);
        }
        Ok(StencilTable::from_rows(rows, self.control_count))
    }

    /// The control and refined vertices the level tables (and the grid evaluator) read and give:
    /// those of the mesh as it was built.
    fn base_counts(&self) -> (usize, usize) {
        self.patch
            .as_ref()
            .map_or((self.control_count, self.topology.vertex_count), |p| {
                (p.base_control, p.base_refined)
            })
    }

    /// Connectivity of the refined mesh.
    pub fn topology(&self) -> &RefinedTopology {
        &self.topology
    }

    /// Number of control vertices expected by [`apply`](Self::apply).
    pub fn control_vertex_count(&self) -> usize {
        self.control_count
    }

    /// Number of refined vertices produced by [`apply`](Self::apply).
    pub fn refined_vertex_count(&self) -> usize {
        self.topology.vertex_count
    }

    /// Evaluates refined positions in single precision, level by level through the
    /// [`level_stencils`](Self::level_stencils) (intermediate levels go to buffers owned by the
    /// subdivider, hence `&mut self`). A control mesh that is a grid numbered along its rows (a
    /// cloth's) is refined instead as a product of curve refinements along its rows and columns,
    /// about twice as fast; the corners' vertices in edge-only mode, which are not such a product,
    /// come from their composed stencils. Both give the same surface up to rounding. `control`
    /// must have [`control_vertex_count`](Self::control_vertex_count) elements and `out`
    /// [`refined_vertex_count`](Self::refined_vertex_count); otherwise a
    /// [`SubdivisionError::LengthMismatch`] is returned. Does not allocate.
    pub fn apply(&mut self, control: &[Vec3], out: &mut [Vec3]) -> Result<(), SubdivisionError> {
        check_len("control", self.control_count, control.len())?;
        check_len("out", self.refined_vertex_count(), out.len())?;
        let (base_control, base_refined) = self.base_counts();
        self.apply_base(&control[..base_control], &mut out[..base_refined])?;
        match &mut self.patch {
            Some(patch) => patch.apply(control, out),
            None => Ok(()),
        }
    }

    /// [`apply`](Self::apply) of the mesh as it was built.
    fn apply_base(&mut self, control: &[Vec3], out: &mut [Vec3]) -> Result<(), SubdivisionError> {
        if let Some(grid) = &mut self.grid {
            grid.apply(control, out);
            return Ok(());
        }
        let Some((last, inner)) = self.levels.split_last() else {
            out.copy_from_slice(control);
            return Ok(());
        };
        // Control → level 1 → … → level L − 1 in aligned scratch buffers, then level L → `out`.
        let mut src: Option<&[Vec3A]> = None;
        for (table, buf) in inner.iter().zip(self.scratch.iter_mut()) {
            match src {
                None => table.apply_any(control, buf)?,
                Some(prev) => table.apply_any(prev, buf)?,
            }
            src = Some(buf);
        }
        match src {
            None => last.apply(control, out),
            Some(prev) => last.apply_any(prev, out),
        }
    }

    /// Evaluates refined positions in double precision (same contract as
    /// [`apply`](Self::apply)); allocates the intermediate levels, so it is meant for one-shot
    /// use, not every frame.
    pub fn apply_f64(&self, control: &[DVec3], out: &mut [DVec3]) -> Result<(), SubdivisionError> {
        check_len("control", self.control_count, control.len())?;
        check_len("out", self.refined_vertex_count(), out.len())?;
        let (base_control, base_refined) = self.base_counts();
        let (base_in, base_out) = (&control[..base_control], &mut out[..base_refined]);
        match self.levels.split_last() {
            None => base_out.copy_from_slice(base_in),
            Some((last, inner)) => {
                let mut src = base_in.to_vec();
                for table in inner {
                    let mut next = vec![DVec3::ZERO; table.len()];
                    table.apply_f64(&src, &mut next)?;
                    src = next;
                }
                last.apply_f64(&src, base_out)?;
            }
        }
        match &self.patch {
            Some(patch) => patch.apply_f64(control, out),
            None => Ok(()),
        }
    }

    /// Smooth normals of refined positions (see
    /// [`RefinedTopology::compute_normals`]). Does not allocate.
    pub fn compute_normals(
        &self,
        positions: &[Vec3],
        normals: &mut [Vec3],
    ) -> Result<(), SubdivisionError> {
        self.topology.compute_normals(positions, normals)
    }

    /// Builds the refined mesh for `control` positions (double precision),
    /// carrying the face-varying UVs.
    pub fn refined_mesh(&self, control: &[DVec3]) -> Result<PolyMesh, SubdivisionError> {
        let mut pos = vec![DVec3::ZERO; self.refined_vertex_count()];
        self.apply_f64(control, &mut pos)?;
        Ok(PolyMesh::from_refined(
            pos,
            self.topology.face_offsets.clone(),
            self.topology.face_indices.clone(),
            self.topology.corner_uvs.clone(),
        ))
    }
}

/// Refines `mesh` to `level` once and returns the refined mesh (double
/// precision positions, face-varying UVs carried linearly).
///
/// The same surface as `Subdivider::new(mesh, level, rule, boundary)?.refined_mesh(mesh.positions())`
/// (same vertex order), but evaluated level by level without building stencils, which is several
/// times faster for a one-off refinement.
pub fn refine_positions(
    mesh: &PolyMesh,
    level: u32,
    rule: VertexRule,
    boundary: BoundaryMode,
) -> Result<PolyMesh, SubdivisionError> {
    let r = refine_direct(
        mesh.topology()?,
        mesh.positions(),
        mesh.uvs().map(<[Vec2]>::to_vec),
        level,
        rule,
        boundary,
    )?;
    Ok(PolyMesh::from_refined(
        r.positions,
        r.face_offsets,
        r.face_indices,
        r.uvs,
    ))
}

fn check_len(what: &'static str, expected: usize, actual: usize) -> Result<(), SubdivisionError> {
    if expected != actual {
        return Err(SubdivisionError::LengthMismatch {
            what,
            expected,
            actual,
        });
    }
    Ok(())
}

/// Fan triangulation of CSR faces; `corner(c)` gives the index to emit for
/// face corner `c`.
fn triangulate(face_offsets: &[u32], corner: impl Fn(usize) -> u32) -> Vec<u32> {
    let corners = *face_offsets.last().unwrap_or(&0) as usize;
    let faces = face_offsets.len().saturating_sub(1);
    let mut tris = Vec::with_capacity(3 * corners.saturating_sub(2 * faces));
    for w in face_offsets.windows(2) {
        let (s, e) = (w[0] as usize, w[1] as usize);
        for k in s + 1..e.saturating_sub(1) {
            tris.extend_from_slice(&[corner(s), corner(k), corner(k + 1)]);
        }
    }
    tris
}

fn build_render_mesh(
    vertex_count: usize,
    face_offsets: &[u32],
    face_indices: &[u32],
    uvs: Option<&[Vec2]>,
    triangles: &[u32],
) -> RenderMesh {
    let Some(uvs) = uvs else {
        return RenderMesh {
            refined_vertex_count: vertex_count,
            seam_vertices: Vec::new(),
            uvs: None,
            triangles: triangles.to_vec(),
        };
    };
    let mut vertex_uv: Vec<Option<Vec2>> = vec![None; vertex_count];
    let mut seam_vertices = Vec::new();
    let mut seam_uvs = Vec::new();
    let mut seams: HashMap<(u32, [u32; 2]), u32> = HashMap::new();
    let mut corner_render = vec![0u32; face_indices.len()];
    for (c, (&v, &uv)) in face_indices.iter().zip(uvs).enumerate() {
        let slot = &mut vertex_uv[v as usize];
        corner_render[c] = match slot {
            None => {
                *slot = Some(uv);
                v
            }
            Some(first)
                if first.to_array().map(f32::to_bits) == uv.to_array().map(f32::to_bits) =>
            {
                v
            }
            Some(_) => *seams
                .entry((v, uv.to_array().map(f32::to_bits)))
                .or_insert_with(|| {
                    seam_vertices.push(v);
                    seam_uvs.push(uv);
                    (vertex_count + seam_vertices.len() - 1) as u32
                }),
        };
    }
    let mut all_uvs: Vec<Vec2> = vertex_uv
        .into_iter()
        .map(|u| u.unwrap_or(Vec2::ZERO))
        .collect();
    all_uvs.extend_from_slice(&seam_uvs);
    RenderMesh {
        refined_vertex_count: vertex_count,
        seam_vertices,
        uvs: Some(all_uvs),
        triangles: triangulate(face_offsets, |c| corner_render[c]),
    }
}
