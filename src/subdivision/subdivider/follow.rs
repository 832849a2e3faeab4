//! Following a control mesh whose faces were re-attached to other vertices, as a tear leaves it:
//! the faces around the change are refined again on their own and their refined vertices spliced
//! into the refinement, instead of refining the whole mesh.
//!
//! The refined vertices of a control face depend on the positions in the ring of faces around
//! it, and on the rules of its corners, which their own rings decide. So the faces within
//! [`CHANGED_RINGS`] ring of the re-attached faces' vertices get new stencils, computed from a
//! submesh [`SUPPORT_RINGS`] ring wider, in which their neighbourhoods are whole. Refined vertices keep their indices where a face that did not change still uses them;
//! the others take the indices the changed faces used, or new ones appended. Their stencils over
//! the control vertices replace the level tables' ([`Patch`]).

use std::collections::{BTreeMap, HashMap, HashSet};

use glam::{DVec3, Vec2, Vec3, Vec3A};

use super::super::refine::{compose, refine};
use super::super::sparse_rows::SparseRows;
use super::super::topology::LevelTopology;
use super::{PolyMesh, RefinedTopology, RenderMesh, StencilTable, Subdivider, SubdivisionError};

/// Rings of faces around the vertices of the changed faces whose refined vertices are computed
/// again.
const CHANGED_RINGS: usize = 1;

/// Rings of faces added around those for the submesh refined in their place, so that every
/// vertex whose stencil is kept has its whole neighbourhood in it.
const SUPPORT_RINGS: usize = 1;

/// Past this share of the faces (in the submesh), or of the refined vertices (in the rows kept),
/// refining the whole mesh again is cheaper or simpler than a patch.
const REBUILD_SHARE: usize = 4;

const UNSET: u32 = u32::MAX;

/// What [`Subdivider::follow`] did to bring the refinement up to date.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Followed {
    /// The mesh had the same faces and vertices: nothing to do.
    Unchanged,
    /// Refined again around the faces that changed.
    Locally {
        /// Control faces whose corners changed.
        changed_faces: usize,
        /// Refined vertices whose stencils were computed again.
        refined_vertices: usize,
    },
    /// Refined again whole: the change was not only faces re-attached to other vertices, or
    /// was too large for a patch.
    Rebuilt,
}

/// Stencils over the control vertices that replace those of the level tables (and the grid
/// evaluator) for some refined vertices, and give those past the tables' own.
#[derive(Debug, Clone)]
pub(super) struct Patch {
    /// Control vertices the tables read.
    pub base_control: usize,
    /// Refined vertices the tables give.
    pub base_refined: usize,
    /// The rows, by refined vertex.
    rows: BTreeMap<u32, (Vec<u32>, Vec<f64>)>,
    /// `rows` flattened for evaluation: row `k` of `table` is refined vertex `targets[k]`.
    targets: Vec<u32>,
    table: StencilTable,
    /// Where [`apply`](Self::apply) evaluates the rows before scattering them.
    values: Vec<Vec3A>,
}

impl Patch {
    fn new(base_control: usize, base_refined: usize) -> Self {
        Patch {
            base_control,
            base_refined,
            rows: BTreeMap::new(),
            targets: Vec::new(),
            table: StencilTable::from_rows(SparseRows::identity(0), 0),
            values: Vec::new(),
        }
    }

    /// Flattens `rows` over `control` columns.
    fn flatten(&mut self, control: usize) {
        let mut rows = SparseRows {
            offsets: vec![0],
            ..SparseRows::default()
        };
        self.targets.clear();
        for (&t, (idx, w)) in &self.rows {
            self.targets.push(t);
            rows.indices.extend_from_slice(idx);
            rows.weights.extend_from_slice(w);
            rows.offsets.push(rows.indices.len() as u32);
        }
        self.table = StencilTable::from_rows(rows, control);
        self.values = vec![Vec3A::ZERO; self.targets.len()];
    }

    /// Writes the patched vertices of `control` into `out`. Does not allocate.
    pub fn apply(&mut self, control: &[Vec3], out: &mut [Vec3]) -> Result<(), SubdivisionError> {
        self.table.apply_any(control, &mut self.values)?;
        for (&t, &v) in self.targets.iter().zip(&self.values) {
            out[t as usize] = v.into();
        }
        Ok(())
    }

    /// [`apply`](Self::apply) in double precision.
    pub fn apply_f64(&self, control: &[DVec3], out: &mut [DVec3]) -> Result<(), SubdivisionError> {
        let mut values = vec![DVec3::ZERO; self.targets.len()];
        self.table.apply_f64(control, &mut values)?;
        for (&t, &v) in self.targets.iter().zip(&values) {
            out[t as usize] = v;
        }
        Ok(())
    }

    /// The stencils of all refined vertices: `base`'s (over the base's control vertices), each
    /// replaced by the patch's where it has one, then the patch's rows past the base's.
    pub fn compose_with(&self, base: SparseRows) -> SparseRows {
        let mut out = SparseRows {
            offsets: vec![0],
            ..SparseRows::default()
        };
        let mut push = |idx: &[u32], w: &[f64]| {
            out.indices.extend_from_slice(idx);
            out.weights.extend_from_slice(w);
            out.offsets.push(out.indices.len() as u32);
        };
        for r in 0..base.rows() {
            match self.rows.get(&(r as u32)) {
                Some((idx, w)) => push(idx, w),
                None => {
                    let (idx, w) = base.row(r);
                    push(idx, w);
                }
            }
        }
        for (idx, w) in self.rows.range(base.rows() as u32..).map(|(_, r)| r) {
            push(idx, w);
        }
        out
    }
}

impl Subdivider {
    /// Brings the refinement up to date with `mesh`, the control mesh it was built from (or last
    /// followed) with some faces re-attached to other vertices, new ones appended, as a tear
    /// leaves a cloth. Only the faces around those that changed are refined again: refined
    /// vertices that a face which did not change still uses keep their indices, new ones are
    /// appended, and the refined faces stay in their order. Any other change (faces added or
    /// removed, vertices removed, another face layout, a change too large to patch) refines the
    /// whole mesh as [`new`](Self::new) does. Either way the result gives the same surface as
    /// a subdivider built from `mesh`, up to the order of the refined vertices and rounding.
    ///
    /// After a local update, [`level_stencils`](Self::level_stencils) still describe the mesh
    /// as it was built; [`apply`](Self::apply) and
    /// [`composed_stencils`](Self::composed_stencils) include the changes. On an error the
    /// subdivider is left as it was.
    pub fn follow(&mut self, mesh: &PolyMesh) -> Result<Followed, SubdivisionError> {
        let n = mesh.vertex_count();
        let same_layout = self.level > 0
            && n >= self.control_count
            && mesh.face_offsets() == self.control.face_offsets.as_slice()
            && mesh.uvs().is_some() == self.control.uvs.is_some();
        if !same_layout {
            return self.rebuild(mesh);
        }
        let changed = self.changed_faces(mesh);
        if changed.is_empty() && n == self.control_count {
            return Ok(Followed::Unchanged);
        }
        match self.patch_faces(mesh, &changed)? {
            Some(refined_vertices) => Ok(Followed::Locally {
                changed_faces: changed.len(),
                refined_vertices,
            }),
            None => self.rebuild(mesh),
        }
    }

    fn rebuild(&mut self, mesh: &PolyMesh) -> Result<Followed, SubdivisionError> {
        *self = Subdivider::new(mesh, self.level, self.rule, self.boundary)?;
        Ok(Followed::Rebuilt)
    }

    /// The faces whose corners or corner UVs differ between `mesh` and the current control mesh
    /// (same face layout).
    fn changed_faces(&self, mesh: &PolyMesh) -> Vec<u32> {
        let bits = |uv: &Vec2| uv.to_array().map(f32::to_bits);
        let old = &self.control;
        let mut changed = Vec::new();
        for (f, w) in mesh.face_offsets().windows(2).enumerate() {
            let corners = w[0] as usize..w[1] as usize;
            let moved = mesh.face_indices()[corners.clone()] != old.face_indices[corners.clone()];
            let uvs_moved = match (mesh.uvs(), &old.uvs) {
                (Some(new), Some(old)) => new[corners.clone()]
                    .iter()
                    .zip(&old[corners])
                    .any(|(a, b)| bits(a) != bits(b)),
                _ => false,
            };
            if moved || uvs_moved {
                changed.push(f as u32);
            }
        }
        changed
    }

    /// Refines the faces around `changed` again and splices them in; returns the number of
    /// refined vertices computed again, or `None` where refining the whole mesh is the way
    /// (the change is too large, or its neighbourhood cannot be refined on its own).
    fn patch_faces(
        &mut self,
        mesh: &PolyMesh,
        changed: &[u32],
    ) -> Result<Option<usize>, SubdivisionError> {
        let topo = mesh.topology()?;
        let faces = topo.face_count();
        let (old_n, n) = (self.control_count, mesh.vertex_count());
        // The vertices of the changed faces, before and after: their rings changed.
        let mut seeds: Vec<u32> = changed
            .iter()
            .flat_map(|&f| {
                let (s, e) = corner_range(&self.control.face_offsets, f);
                self.control.face_indices[s..e]
                    .iter()
                    .chain(&mesh.face_indices()[s..e])
            })
            .copied()
            .collect();
        seeds.sort_unstable();
        seeds.dedup();
        let mut is_changed = vec![false; faces];
        for &f in changed {
            is_changed[f as usize] = true;
        }
        let mut in_region = is_changed.clone();
        let mut frontier = seeds.clone();
        grow(topo, &mut in_region, &mut frontier, CHANGED_RINGS);
        let in_changed_rings = in_region.clone();
        grow(topo, &mut in_region, &mut frontier, SUPPORT_RINGS);
        let region: Vec<u32> = (0..faces as u32)
            .filter(|&f| in_region[f as usize])
            .collect();
        if region.len() * REBUILD_SHARE > faces {
            return Ok(None);
        }

        // The region as a mesh of its own: local vertices in order of first use.
        let mut local_of: HashMap<u32, u32> = HashMap::new();
        let mut global_of: Vec<u32> = Vec::new();
        let mut offsets = vec![0u32];
        let mut indices = Vec::new();
        let mut uvs = mesh.uvs().map(|_| Vec::new());
        for &f in &region {
            let (s, e) = corner_range(mesh.face_offsets(), f);
            for &v in &mesh.face_indices()[s..e] {
                let local = *local_of.entry(v).or_insert_with(|| {
                    global_of.push(v);
                    global_of.len() as u32 - 1
                });
                indices.push(local);
            }
            offsets.push(indices.len() as u32);
            if let (Some(out), Some(all)) = (&mut uvs, mesh.uvs()) {
                out.extend_from_slice(&all[s..e]);
            }
        }
        // A region whose boundary pinches at a vertex is not a mesh that refines on its own.
        let Ok(local_topo) = LevelTopology::build(global_of.len(), offsets.clone(), indices) else {
            return Ok(None);
        };
        let r = refine(&local_topo, uvs, None, self.level, self.rule, self.boundary)?;
        let local_n = global_of.len();
        let mut stencils = SparseRows::identity(local_n);
        for masks in &r.levels {
            stencils = compose(&stencils, masks, local_n)?;
        }

        // Refined faces of control face `f` are `scale · first corner ..`, in the whole mesh and
        // in the region alike (each level makes one quad per corner, in corner order).
        let scale = 4usize.pow(self.level - 1);
        let refined_corners = |offsets: &[u32], f: usize| {
            4 * scale * offsets[f] as usize..4 * scale * offsets[f + 1] as usize
        };
        let old_corners = &self.topology.face_indices;
        let local_corners = &r.topology.face_indices;
        let mut index_of = vec![UNSET; r.topology.num_vertices];
        let mut claimed: HashSet<u32> = HashSet::new();
        // Vertex points keep their control vertex's refined vertex.
        for (local, &global) in global_of.iter().enumerate() {
            if (global as usize) < old_n {
                let g = self.topology.control_vertex_map[global as usize];
                index_of[r.control_vertex_map[local] as usize] = g;
                claimed.insert(g);
            }
        }
        // Faces that did not change keep their refined vertices.
        for (j, &f) in region.iter().enumerate() {
            if is_changed[f as usize] {
                continue;
            }
            let (global, local) = (
                refined_corners(&self.control.face_offsets, f as usize),
                refined_corners(&offsets, j),
            );
            for (&g, &s) in old_corners[global].iter().zip(&local_corners[local]) {
                match index_of[s as usize] {
                    UNSET => {
                        index_of[s as usize] = g;
                        claimed.insert(g);
                    }
                    same if same == g => {}
                    _ => return Ok(None),
                }
            }
        }
        // The changed faces' refined vertices: the index their corner had, unless a face that
        // did not change keeps it, else a new one.
        let changed_corners: Vec<_> = region
            .iter()
            .enumerate()
            .filter(|&(_, &f)| is_changed[f as usize])
            .map(|(j, &f)| {
                (
                    refined_corners(&self.control.face_offsets, f as usize),
                    refined_corners(&offsets, j),
                )
            })
            .collect();
        let mut next = self.topology.vertex_count as u32;
        for (global, local) in &changed_corners {
            let (global, local) = (global.clone(), local.clone());
            for (&g, &s) in old_corners[global].iter().zip(&local_corners[local]) {
                if index_of[s as usize] == UNSET {
                    index_of[s as usize] = if claimed.insert(g) {
                        g
                    } else {
                        next += 1;
                        next - 1
                    };
                }
            }
        }

        // New stencils for the refined vertices of the faces near the change, and for the vertex
        // points of the vertices that changed.
        let mut recompute: Vec<u32> = region
            .iter()
            .enumerate()
            .filter(|&(_, &f)| in_changed_rings[f as usize])
            .flat_map(|(j, _)| local_corners[refined_corners(&offsets, j)].iter().copied())
            .chain(
                seeds
                    .iter()
                    .filter_map(|v| local_of.get(v).map(|&l| r.control_vertex_map[l as usize])),
            )
            .collect();
        recompute.sort_unstable();
        recompute.dedup();
        let mut rows = self
            .patch
            .as_ref()
            .map(|p| p.rows.clone())
            .unwrap_or_default();
        for &s in &recompute {
            let (idx, w) = stencils.row(s as usize);
            let mut row: Vec<(u32, f64)> = idx
                .iter()
                .map(|&l| global_of[l as usize])
                .zip(w.iter().copied())
                .collect();
            row.sort_unstable_by_key(|&(c, _)| c);
            rows.insert(
                index_of[s as usize],
                row.into_iter().unzip::<u32, f64, Vec<u32>, Vec<f64>>(),
            );
        }
        // Control vertices no face uses are refined to themselves.
        for &v in seeds.iter().filter(|&&v| (v as usize) < old_n) {
            if !local_of.contains_key(&v) {
                rows.insert(
                    self.topology.control_vertex_map[v as usize],
                    (vec![v], vec![1.0]),
                );
            }
        }
        let mut vertex_map = self.topology.control_vertex_map.clone();
        for v in old_n as u32..n as u32 {
            let refined = match local_of.get(&v) {
                Some(&l) => index_of[r.control_vertex_map[l as usize] as usize],
                None => {
                    next += 1;
                    rows.insert(next - 1, (vec![v], vec![1.0]));
                    next - 1
                }
            };
            vertex_map.push(refined);
        }
        if rows.len() * REBUILD_SHARE > next as usize {
            return Ok(None);
        }

        // Nothing fails past here: the subdivider takes the patch.
        let recomputed = recompute.len();
        let refined = self.topology.vertex_count;
        let patch = self.patch.get_or_insert_with(|| Patch::new(old_n, refined));
        patch.rows = rows;
        patch.flatten(n);
        self.control_count = n;
        self.control.face_indices.clear();
        self.control
            .face_indices
            .extend_from_slice(mesh.face_indices());
        if let (Some(old), Some(new)) = (&mut self.control.uvs, mesh.uvs()) {
            old.copy_from_slice(new);
        }
        self.topology.splice(
            &changed_corners,
            |s| index_of[s as usize],
            local_corners,
            r.uvs.as_deref(),
            next as usize,
            vertex_map,
        );
        Ok(Some(recomputed))
    }
}

/// The corners of face `f` in CSR `offsets`.
fn corner_range(offsets: &[u32], f: u32) -> (usize, usize) {
    (
        offsets[f as usize] as usize,
        offsets[f as usize + 1] as usize,
    )
}

/// Adds `rings` rings of faces around `frontier` (vertices) to `in_region`; `frontier` ends as
/// the vertices of the last ring's faces.
fn grow(topo: &LevelTopology, in_region: &mut [bool], frontier: &mut Vec<u32>, rings: usize) {
    for _ in 0..rings {
        let mut next = Vec::new();
        for &v in frontier.iter() {
            for &f in topo.faces_of(v as usize) {
                if !std::mem::replace(&mut in_region[f as usize], true) {
                    next.extend_from_slice(topo.face(f as usize));
                }
            }
        }
        next.sort_unstable();
        next.dedup();
        *frontier = next;
    }
}

/// The corners of changed refined faces: `(corners in the whole mesh, corners in the region)`.
type CornerRanges = [(std::ops::Range<usize>, std::ops::Range<usize>)];

impl RefinedTopology {
    /// Re-attaches the refined faces at `corners` to the region's refined vertices (their
    /// indices by `index_of`) with the region's corner UVs, grows the vertex count to
    /// `vertex_count` and takes the control vertices' new `vertex_map`; the render layout
    /// follows.
    fn splice(
        &mut self,
        corners: &CornerRanges,
        index_of: impl Fn(u32) -> u32,
        local_corners: &[u32],
        local_uvs: Option<&[Vec2]>,
        vertex_count: usize,
        vertex_map: Vec<u32>,
    ) {
        for (global, local) in corners {
            for (g, l) in global.clone().zip(local.clone()) {
                self.face_indices[g] = index_of(local_corners[l]);
            }
            if let (Some(out), Some(uvs)) = (&mut self.corner_uvs, local_uvs) {
                out[global.clone()].copy_from_slice(&uvs[local.clone()]);
            }
            for q in global.clone().step_by(4) {
                let t = 6 * (q / 4);
                self.triangles[t..t + 6].copy_from_slice(&quad_triangles(&self.face_indices[q..]));
            }
        }
        self.vertex_count = vertex_count;
        self.control_vertex_map = vertex_map;
        self.render.splice(
            corners.iter().map(|(g, _)| g.clone()),
            &self.face_indices,
            self.corner_uvs.as_deref(),
            vertex_count,
        );
    }
}

impl RenderMesh {
    /// Follows refined faces whose corners (`changed`, ranges of whole quads) were re-attached,
    /// with `vertex_count` refined vertices now (new ones appended): the seam copies move up
    /// past the new vertices, each new vertex takes the UV of its first corner, and a corner
    /// whose UV differs from its vertex's takes a seam copy.
    fn splice(
        &mut self,
        changed: impl Iterator<Item = std::ops::Range<usize>> + Clone,
        face_indices: &[u32],
        corner_uvs: Option<&[Vec2]>,
        vertex_count: usize,
    ) {
        let old = self.refined_vertex_count;
        let (Some(uvs), Some(corner_uvs)) = (&mut self.uvs, corner_uvs) else {
            for q in changed.flat_map(|r| r.step_by(4)) {
                let t = 6 * (q / 4);
                self.triangles[t..t + 6].copy_from_slice(&quad_triangles(&face_indices[q..]));
            }
            self.refined_vertex_count = vertex_count;
            return;
        };
        let added = vertex_count - old;
        if added > 0 && !self.seam_vertices.is_empty() {
            for t in &mut self.triangles {
                if *t as usize >= old {
                    *t += added as u32;
                }
            }
        }
        uvs.splice(old..old, std::iter::repeat_n(Vec2::ZERO, added));
        let bits = |uv: Vec2| uv.to_array().map(f32::to_bits);
        let mut seams: HashMap<(u32, [u32; 2]), u32> = self
            .seam_vertices
            .iter()
            .enumerate()
            .map(|(k, &v)| ((v, bits(uvs[vertex_count + k])), (vertex_count + k) as u32))
            .collect();
        let mut unset = vec![true; added];
        for q in changed.flat_map(|r| r.step_by(4)) {
            let mut render = [0u32; 4];
            for (k, out) in render.iter_mut().enumerate() {
                let (v, uv) = (face_indices[q + k], corner_uvs[q + k]);
                let fresh = (v as usize)
                    .checked_sub(old)
                    .is_some_and(|i| std::mem::replace(&mut unset[i], false));
                *out = if fresh {
                    uvs[v as usize] = uv;
                    v
                } else if bits(uvs[v as usize]) == bits(uv) {
                    v
                } else {
                    *seams.entry((v, bits(uv))).or_insert_with(|| {
                        self.seam_vertices.push(v);
                        uvs.push(uv);
                        (vertex_count + self.seam_vertices.len() - 1) as u32
                    })
                };
            }
            let t = 6 * (q / 4);
            self.triangles[t..t + 6].copy_from_slice(&quad_triangles(&render));
        }
        self.refined_vertex_count = vertex_count;
    }
}

/// The two triangles of the quad whose corners `c` starts with, as the faces are triangulated
/// (a fan from the first corner).
fn quad_triangles(c: &[u32]) -> [u32; 6] {
    [c[0], c[1], c[2], c[0], c[2], c[3]]
}
