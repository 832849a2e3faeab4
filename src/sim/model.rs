//! Cloth topology, built once: rest positions, the spring set (coloured for deterministic
//! Gauss-Seidel solving), the triangle list for rendering, and texture coordinates.
//!
//! This is where the canonical grid cloth of DESIGN.md is defined, and where a cloth is derived from an
//! arbitrary triangle or quad mesh. Nothing here runs per step.

use bevy::reflect::Reflect;
use glam::{DVec3, Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::HashMap;

use crate::error::{ClothError, positive};
use crate::subdivision::{BoundaryMode, PolyMesh, Subdivider, SubdivisionError, VertexRule};

/// The three spring families of a Provot mass-spring cloth.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize, Reflect,
)]
pub enum SpringKind {
    /// Along grid rows and columns (or along mesh edges).
    Structural = 0,
    /// Along cell diagonals.
    Shear = 1,
    /// Skipping one particle (or across a shared mesh edge); resists folding.
    Bend = 2,
}

impl SpringKind {
    /// All kinds, in index order.
    pub const ALL: [SpringKind; 3] = [SpringKind::Structural, SpringKind::Shear, SpringKind::Bend];
}

/// Which plane a grid cloth lies in, in the cloth's local space. The grid is centred on the origin.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, Reflect)]
pub enum GridPlane {
    /// Particle `(i, j)` at `((i - (nx-1)/2) h, 0, (j - (ny-1)/2) h)`: a horizontal sheet, facing +Y.
    #[default]
    Horizontal,
    /// Particle `(i, j)` at `((i - (nx-1)/2) h, -(j - (ny-1)/2) h, 0)`: a hanging curtain, row 0 on
    /// top, facing +Z.
    Vertical,
}

/// Largest number of particles a cloth may have (16,777,216, a 4096 × 4096 grid): far beyond
/// real time, and small enough that building the cloth's springs fits in memory.
pub const MAX_PARTICLES: usize = 1 << 24;

/// A triangle whose doubled area is at most this fraction of the square of its longest edge (its
/// height is at most a millionth of that edge) counts as having zero area: [`ClothModel::from_mesh`]
/// rejects it as degenerate.
pub const DEGENERATE_TRIANGLE_RATIO: f64 = 1e-6;

/// The canonical rectangular grid cloth of DESIGN.md.
///
/// Particle `(i, j)` has index `j * nx + i`. Springs: structural `(i,j)-(i+1,j)`, `(i,j)-(i,j+1)`;
/// shear `(i,j)-(i+1,j+1)`, `(i+1,j)-(i,j+1)`; bend `(i,j)-(i+2,j)`, `(i,j)-(i,j+2)`. Rest lengths are
/// the initial distances.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Particles along the first axis (`i`), at least 2.
    pub nx: u32,
    /// Particles along the second axis (`j`), at least 2.
    pub ny: u32,
    /// Distance between neighbouring particles, in metres.
    pub spacing: f32,
    /// Orientation of the sheet in local space.
    #[serde(default)]
    pub plane: GridPlane,
}

impl GridSpec {
    /// A horizontal `nx` × `ny` grid with the given spacing.
    pub fn new(nx: u32, ny: u32, spacing: f32) -> Self {
        Self {
            nx,
            ny,
            spacing,
            plane: GridPlane::Horizontal,
        }
    }

    /// The same grid in another plane.
    pub fn with_plane(mut self, plane: GridPlane) -> Self {
        self.plane = plane;
        self
    }

    /// Index of particle `(i, j)`.
    pub fn index(&self, i: u32, j: u32) -> u32 {
        j * self.nx + i
    }

    /// Checks the spec; the error names the bad field: `nx` and `ny` at least 2, at most
    /// [`MAX_PARTICLES`] particles, `spacing` finite and positive and small enough that the grid's
    /// diagonal is finite in `f32`.
    pub fn validate(&self) -> Result<(), ClothError> {
        if self.nx < 2 {
            return Err(ClothError::GridTooSmall {
                field: "nx",
                value: self.nx,
            });
        }
        if self.ny < 2 {
            return Err(ClothError::GridTooSmall {
                field: "ny",
                value: self.ny,
            });
        }
        if (self.nx as u64) * (self.ny as u64) > MAX_PARTICLES as u64 {
            return Err(ClothError::GridTooLarge {
                nx: self.nx,
                ny: self.ny,
            });
        }
        positive("spacing", self.spacing)?;
        // Every spring is shorter than the diagonal; its length must not overflow.
        let diagonal = Vec2::new(
            (self.nx - 1) as f32 * self.spacing,
            (self.ny - 1) as f32 * self.spacing,
        )
        .length();
        if !diagonal.is_finite() {
            return Err(ClothError::InvalidValue {
                field: "spacing",
                expected: "small enough that the grid's diagonal is finite",
                value: self.spacing as f64,
            });
        }
        Ok(())
    }
}

/// The springs of a cloth in structure-of-arrays form, ordered by colour: within one colour no two
/// springs share a particle, so a colour can be solved in any order (or in parallel) with the same
/// result.
#[derive(Debug, Clone, Default)]
pub struct Springs {
    /// First particle of each spring.
    pub a: Vec<u32>,
    /// Second particle of each spring.
    pub b: Vec<u32>,
    /// Rest length of each spring, in metres.
    pub rest: Vec<f32>,
    /// Family of each spring.
    pub kind: Vec<SpringKind>,
    /// Springs of colour `c` are `color_offsets[c]..color_offsets[c + 1]`.
    pub color_offsets: Vec<u32>,
}

impl Springs {
    /// Number of springs.
    pub fn len(&self) -> usize {
        self.a.len()
    }

    /// Whether there are no springs.
    pub fn is_empty(&self) -> bool {
        self.a.is_empty()
    }

    /// Number of colours.
    pub fn color_count(&self) -> usize {
        self.color_offsets.len().saturating_sub(1)
    }

    /// Number of springs of each kind, indexed by `SpringKind as usize`.
    pub fn count_by_kind(&self) -> [usize; 3] {
        let mut n = [0; 3];
        for k in &self.kind {
            n[*k as usize] += 1;
        }
        n
    }

    /// Builds the coloured spring set from `(a, b, kind)` triples, rest lengths from `positions`,
    /// with a greedy edge colouring. Springs of zero rest length are dropped (they cannot define a
    /// direction).
    fn build(positions: &[Vec3], pairs: &[(u32, u32, SpringKind)]) -> Self {
        let colors = greedy_edge_coloring(positions.len(), pairs.iter().map(|p| (p.0, p.1)));
        Self::build_colored(positions, pairs, &colors)
    }

    /// [`Self::build`] with a given colour per spring (no two springs of a colour may share a
    /// particle). Within a colour, springs are ordered by index offset `b - a` and then by `a`
    /// (XPBD's layout re-sorts them by storage position; see `xpbd::Projections`).
    fn build_colored(positions: &[Vec3], pairs: &[(u32, u32, SpringKind)], colors: &[u32]) -> Self {
        debug_assert!(is_proper_edge_coloring(positions.len(), pairs, colors));
        let pairs: Vec<(u32, u32, SpringKind, f32, u32)> = pairs
            .iter()
            .zip(colors)
            .map(|(&(a, b, k), &c)| {
                (
                    a.min(b),
                    a.max(b),
                    k,
                    positions[a as usize].distance(positions[b as usize]),
                    c,
                )
            })
            .filter(|p| p.3 > 0.0)
            .collect();
        let color_count = pairs
            .iter()
            .map(|p| p.4)
            .max()
            .map_or(0, |c| c as usize + 1);
        let mut order: Vec<usize> = (0..pairs.len()).collect();
        order.sort_by_key(|&s| (pairs[s].4, pairs[s].1 - pairs[s].0, pairs[s].0));
        let mut springs = Springs {
            a: Vec::with_capacity(pairs.len()),
            b: Vec::with_capacity(pairs.len()),
            rest: Vec::with_capacity(pairs.len()),
            kind: Vec::with_capacity(pairs.len()),
            color_offsets: vec![0; color_count + 1],
        };
        for &s in &order {
            let (a, b, k, r, c) = pairs[s];
            springs.a.push(a);
            springs.b.push(b);
            springs.rest.push(r);
            springs.kind.push(k);
            springs.color_offsets[c as usize + 1] += 1;
        }
        for c in 0..color_count {
            springs.color_offsets[c + 1] += springs.color_offsets[c];
        }
        springs
    }
}

/// Whether no two springs of the same colour share a particle.
fn is_proper_edge_coloring(nodes: usize, pairs: &[(u32, u32, SpringKind)], colors: &[u32]) -> bool {
    let mut seen = std::collections::HashSet::with_capacity(2 * pairs.len().min(nodes * 16));
    pairs.len() == colors.len()
        && pairs
            .iter()
            .zip(colors)
            .all(|(&(a, b, _), &c)| a != b && seen.insert((a, c)) && seen.insert((b, c)))
}

/// Greedy colouring of the edges of a graph: each edge gets the smallest colour not yet used at
/// either endpoint. Uses at most `2 Δ - 1` colours for maximum degree `Δ`.
fn greedy_edge_coloring(nodes: usize, edges: impl Iterator<Item = (u32, u32)> + Clone) -> Vec<u32> {
    let mut degree = vec![0u32; nodes];
    for (a, b) in edges.clone() {
        degree[a as usize] += 1;
        degree[b as usize] += 1;
    }
    let max_colors = (2 * degree.iter().copied().max().unwrap_or(0)).max(1) as usize;
    let words = max_colors.div_ceil(64);
    let mut used = vec![0u64; nodes * words];
    let mut colors = Vec::new();
    for (a, b) in edges {
        let (ua, ub) = (a as usize * words, b as usize * words);
        let mut color = 0;
        for w in 0..words {
            let free = !(used[ua + w] | used[ub + w]);
            if free != 0 {
                color = w * 64 + free.trailing_zeros() as usize;
                break;
            }
        }
        used[ua + color / 64] |= 1 << (color % 64);
        used[ub + color / 64] |= 1 << (color % 64);
        colors.push(color as u32);
    }
    colors
}

/// The immutable description of one cloth: rest shape, springs and render topology.
#[derive(Debug, Clone)]
pub struct ClothModel {
    /// Rest (initial) positions in the cloth's local space.
    pub rest_positions: Vec<Vec3>,
    /// Texture coordinates, one per particle.
    pub uvs: Vec<Vec2>,
    /// Triangle list (three indices per triangle) used for normals, rendering and aerodynamics.
    pub triangles: Vec<u32>,
    /// The control polygons, `face_size` indices each: quads for grids, the input faces for meshes.
    /// Subdivision refines these.
    pub faces: Vec<u32>,
    /// Corners per face in [`faces`](Self::faces): 3 or 4.
    pub face_size: usize,
    /// The coloured spring set.
    pub springs: Springs,
    /// Grid dimensions when built from a [`GridSpec`].
    pub grid: Option<GridSpec>,
    /// Mass of each particle in kg, when particles differ; `None` (the default) gives every
    /// particle [`SolverSettings::particle_mass`](super::SolverSettings::particle_mass). Set it with
    /// [`ClothModel::with_particle_masses`].
    pub particle_masses: Option<Vec<f32>>,
}

impl ClothModel {
    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.rest_positions.len()
    }

    /// The longest triangle edge at rest, m (0 without triangles).
    pub fn max_edge_length(&self) -> f32 {
        let p = &self.rest_positions;
        self.triangles
            .chunks_exact(3)
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .map(|(a, b)| p[a as usize].distance(p[b as usize]))
            .fold(0.0, f32::max)
    }

    /// Builds the canonical grid cloth.
    pub fn grid(spec: &GridSpec) -> Result<Self, ClothError> {
        spec.validate()?;
        let (nx, ny, h) = (spec.nx, spec.ny, spec.spacing);
        let cx = (nx - 1) as f32 * 0.5;
        let cy = (ny - 1) as f32 * 0.5;
        let mut rest_positions = Vec::with_capacity((nx * ny) as usize);
        let mut uvs = Vec::with_capacity((nx * ny) as usize);
        for j in 0..ny {
            for i in 0..nx {
                let (u, v) = ((i as f32 - cx) * h, (j as f32 - cy) * h);
                rest_positions.push(match spec.plane {
                    GridPlane::Horizontal => Vec3::new(u, 0.0, v),
                    GridPlane::Vertical => Vec3::new(u, -v, 0.0),
                });
                uvs.push(Vec2::new(
                    i as f32 / (nx - 1) as f32,
                    j as f32 / (ny - 1) as f32,
                ));
            }
        }
        let id = |i: u32, j: u32| spec.index(i, j);
        // Twelve colours by family and parity: rows of structural springs alternate by column
        // (0, 1), columns by row (2, 3); both diagonals alternate by row (4–7); bend springs
        // alternate by pairs of columns (8, 9) and pairs of rows (10, 11). Each colour is then a
        // few long runs of regular index offset, which the XPBD kernel loads as whole vectors.
        let mut pairs = Vec::new();
        let mut colors = Vec::new();
        let mut add = |a, b, kind, color| {
            pairs.push((a, b, kind));
            colors.push(color);
        };
        for j in 0..ny {
            for i in 0..nx {
                if i + 1 < nx {
                    add(id(i, j), id(i + 1, j), SpringKind::Structural, i % 2);
                }
                if j + 1 < ny {
                    add(id(i, j), id(i, j + 1), SpringKind::Structural, 2 + j % 2);
                }
                if i + 1 < nx && j + 1 < ny {
                    add(id(i, j), id(i + 1, j + 1), SpringKind::Shear, 4 + j % 2);
                    add(id(i + 1, j), id(i, j + 1), SpringKind::Shear, 6 + j % 2);
                }
                if i + 2 < nx {
                    add(id(i, j), id(i + 2, j), SpringKind::Bend, 8 + (i / 2) % 2);
                }
                if j + 2 < ny {
                    add(id(i, j), id(i, j + 2), SpringKind::Bend, 10 + (j / 2) % 2);
                }
            }
        }
        let mut triangles = Vec::with_capacity(((nx - 1) * (ny - 1) * 6) as usize);
        let mut faces = Vec::with_capacity(((nx - 1) * (ny - 1) * 4) as usize);
        // Winding chosen so that the horizontal sheet faces +Y and the vertical one +Z.
        for j in 0..ny - 1 {
            for i in 0..nx - 1 {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
                triangles.extend_from_slice(&[a, c, b, b, c, d]);
                faces.extend_from_slice(&[a, c, d, b]);
            }
        }
        let springs = Springs::build_colored(&rest_positions, &pairs, &colors);
        Ok(Self {
            rest_positions,
            uvs,
            triangles,
            faces,
            face_size: 4,
            springs,
            grid: Some(*spec),
            particle_masses: None,
        })
    }

    /// Gives each particle its own mass (kg), replacing the uniform
    /// [`SolverSettings::particle_mass`](super::SolverSettings::particle_mass). The list must have
    /// one finite, positive value per particle; the error names the first bad one.
    ///
    /// ```
    /// use bevy_cloth::sim::{ClothModel, GridSpec};
    /// let model = ClothModel::grid(&GridSpec::new(2, 2, 0.1)).unwrap();
    /// let model = model.with_particle_masses(vec![0.001, 0.002, 0.001, 0.1]).unwrap();
    /// assert_eq!(model.mass_of(3, 0.5), 0.1);
    /// ```
    pub fn with_particle_masses(mut self, masses: Vec<f32>) -> Result<Self, ClothError> {
        if masses.len() != self.particle_count() {
            return Err(ClothError::InvalidMesh {
                what: format!(
                    "has {} particle masses for {} particles",
                    masses.len(),
                    self.particle_count()
                ),
            });
        }
        for m in &masses {
            positive("particle_masses", *m)?;
        }
        self.particle_masses = Some(masses);
        Ok(self)
    }

    /// Mass of particle `i` in kg: its own mass if the model has per-particle masses, else
    /// `uniform` (normally [`SolverSettings::particle_mass`](super::SolverSettings::particle_mass)).
    pub fn mass_of(&self, i: usize, uniform: f32) -> f32 {
        self.particle_masses
            .as_ref()
            .and_then(|m| m.get(i).copied())
            .unwrap_or(uniform)
    }

    /// Builds a cloth from an indexed mesh whose faces are all triangles (`face_size == 3`) or all
    /// quads (`face_size == 4`), one particle per vertex. Structural springs run along every edge;
    /// bend springs cross each interior edge: for triangles they join the two vertices opposite
    /// the edge; for quads they run straight through each end of the edge, joining that end's
    /// neighbours across it (on a regular quad grid these are exactly the canonical grid's
    /// `(i,j)-(i+2,j)` and `(i,j)-(i,j+2)` springs, each made once). Quads also get both diagonals
    /// as shear springs. Triangles for rendering keep the input's order (quads are split along
    /// their first diagonal).
    ///
    /// # Errors
    ///
    /// The whole mesh is checked before anything is built; the error names the problem and where:
    /// - [`ClothError::InvalidMesh`]: no positions, no indices, a face size other than 3 or 4, an
    ///   index count that is not a multiple of it, more than [`MAX_PARTICLES`] vertices, a
    ///   non-finite position or texture coordinate (naming the vertex), a texture coordinate count
    ///   that differs from the vertex count, or vertices so far apart that the distances between
    ///   them overflow `f32`;
    /// - [`ClothError::MeshIndexOutOfRange`]: an index past the last vertex (with its position in
    ///   the index buffer);
    /// - [`ClothError::DegenerateFace`]: a face that uses a vertex twice, or a triangle (for a quad,
    ///   either triangle of its split) with zero area (see [`DEGENERATE_TRIANGLE_RATIO`]);
    /// - [`ClothError::ZeroLengthEdge`]: an edge between two distinct vertices at the same position;
    /// - [`ClothError::NonManifoldEdge`]: an edge shared by more than two faces.
    ///
    /// # Duplicate vertices and other legal oddities
    ///
    /// Distinct vertices at the same position that no edge joins are legal. They are separate
    /// particles with no spring between them, so the cloth is *cut* there, like a seam that was
    /// never sewn: the two sides move independently and can pull apart. Exported meshes often have
    /// such duplicates along UV seams and hard edges; weld them (merge vertices by position) before
    /// building the cloth if the seam should hold. Vertices that no face uses are particles without
    /// springs: they fall freely and are not drawn. Faces need not be consistently oriented and
    /// several fans may meet at a vertex, but subdivision of the render mesh
    /// ([`ClothSubdivision`](crate::ClothSubdivision)) needs both and otherwise reports a
    /// [`ClothError::Subdivision`] error. A bend spring whose two vertices coincide (two faces folded
    /// flat onto each other) is left out, as are quad diagonals of zero length.
    pub fn from_mesh(
        positions: &[Vec3],
        uvs: Option<&[Vec2]>,
        indices: &[u32],
        face_size: usize,
    ) -> Result<Self, ClothError> {
        check_mesh(positions, uvs, indices, face_size)?;
        let count = positions.len();

        // Undirected edge -> its uses, one per face: the face, and for each end of the edge (the
        // smaller index first) that end's other neighbour in the face (the third corner of a
        // triangle, for both ends).
        type Uses = Vec<(usize, [u32; 2])>;
        let mut edges: HashMap<(u32, u32), Uses> = HashMap::new();
        let mut edge_order: Vec<(u32, u32)> = Vec::new();
        let mut pairs = Vec::new();
        let mut triangles = Vec::with_capacity(indices.len() / face_size * 3 * (face_size - 2));
        for (f, face) in indices.chunks_exact(face_size).enumerate() {
            for k in 0..face_size {
                let (a, b) = (face[k], face[(k + 1) % face_size]);
                // The corner before `a` and the corner after `b` (the same vertex in a triangle).
                let (before_a, after_b) = (
                    face[(k + face_size - 1) % face_size],
                    face[(k + 2) % face_size],
                );
                let key = (a.min(b), a.max(b));
                let across = if a < b {
                    [before_a, after_b]
                } else {
                    [after_b, before_a]
                };
                edges
                    .entry(key)
                    .or_insert_with(|| {
                        edge_order.push(key);
                        Vec::new()
                    })
                    .push((f, across));
            }
            if face_size == 4 {
                pairs.push((face[0], face[2], SpringKind::Shear));
                pairs.push((face[1], face[3], SpringKind::Shear));
                triangles
                    .extend_from_slice(&[face[0], face[1], face[2], face[0], face[2], face[3]]);
            } else {
                triangles.extend_from_slice(face);
            }
        }
        // A quad's straight bend spring through a vertex is found from both edges that pass
        // straight through it; make it once.
        let mut bends = std::collections::HashSet::new();
        for key in &edge_order {
            let uses = &edges[key];
            if uses.len() > 2 {
                return Err(ClothError::NonManifoldEdge {
                    a: key.0,
                    b: key.1,
                    faces: uses.iter().map(|&(f, _)| f).collect(),
                });
            }
            pairs.push((key.0, key.1, SpringKind::Structural));
            if let [(_, first), (_, second)] = uses[..] {
                let ends = if face_size == 4 { 2 } else { 1 };
                for (p, q) in first.into_iter().zip(second).take(ends) {
                    if p != q && bends.insert((p.min(q), p.max(q))) {
                        pairs.push((p, q, SpringKind::Bend));
                    }
                }
            }
        }
        let springs = Springs::build(positions, &pairs);
        Ok(Self {
            rest_positions: positions.to_vec(),
            uvs: uvs.map_or_else(|| vec![Vec2::ZERO; count], <[Vec2]>::to_vec),
            triangles,
            faces: indices.to_vec(),
            face_size,
            springs,
            grid: None,
            particle_masses: None,
        })
    }
}

impl ClothModel {
    /// Checks that the model is consistent, for models assembled or edited by hand (its fields are
    /// public): finite rest positions, one texture coordinate (and mass, if any) per particle,
    /// triangles and faces whose indices are in range, a face size of 3 or 4, and springs whose
    /// arrays agree, whose particles exist, whose rest lengths are finite and positive, and whose
    /// colours partition them with no particle twice in a colour. The builders
    /// ([`grid`](Self::grid), [`from_mesh`](Self::from_mesh), [`disc`](Self::disc)) always pass.
    /// The error names the first problem.
    pub fn validate(&self) -> Result<(), ClothError> {
        let bad = |what: String| Err(ClothError::InvalidMesh { what });
        let n = self.particle_count();
        if n == 0 {
            return bad("has no vertex positions".into());
        }
        if let Some((i, p)) = self
            .rest_positions
            .iter()
            .enumerate()
            .find(|(_, p)| !p.is_finite())
        {
            return bad(format!("vertex {i} has a non-finite position {p}"));
        }
        if self.uvs.len() != n {
            return bad(format!(
                "has {} texture coordinates for {n} vertices",
                self.uvs.len()
            ));
        }
        if let Some(masses) = &self.particle_masses {
            if masses.len() != n {
                return bad(format!(
                    "has {} particle masses for {n} particles",
                    masses.len()
                ));
            }
            for m in masses {
                positive("particle_masses", *m)?;
            }
        }
        let in_range = |indices: &[u32]| -> Result<(), ClothError> {
            match indices.iter().enumerate().find(|(_, i)| **i as usize >= n) {
                Some((position, &index)) => Err(ClothError::MeshIndexOutOfRange {
                    index,
                    position,
                    count: n,
                }),
                None => Ok(()),
            }
        };
        if !self.triangles.len().is_multiple_of(3) {
            return bad(format!(
                "triangle index count {} is not a multiple of 3",
                self.triangles.len()
            ));
        }
        in_range(&self.triangles)?;
        if self.face_size != 3 && self.face_size != 4 {
            return bad(format!(
                "faces must have 3 or 4 vertices, got {}",
                self.face_size
            ));
        }
        if !self.faces.len().is_multiple_of(self.face_size) {
            return bad(format!(
                "face index count {} is not a multiple of the face size {}",
                self.faces.len(),
                self.face_size
            ));
        }
        in_range(&self.faces)?;
        let s = &self.springs;
        let len = s.len();
        if s.b.len() != len || s.rest.len() != len || s.kind.len() != len {
            return bad(format!(
                "springs have {} first particles, {} second particles, {} rest lengths and {} kinds",
                len,
                s.b.len(),
                s.rest.len(),
                s.kind.len()
            ));
        }
        in_range(&s.a)?;
        in_range(&s.b)?;
        if let Some((k, r)) = s
            .rest
            .iter()
            .enumerate()
            .find(|(_, r)| !(r.is_finite() && **r > 0.0))
        {
            return bad(format!(
                "spring {k} has rest length {r}, expected finite and > 0"
            ));
        }
        let offsets = &s.color_offsets;
        let partition = offsets.first().is_none_or(|&o| o == 0)
            && offsets.windows(2).all(|w| w[0] <= w[1])
            && offsets.last().map_or(len == 0, |&o| o as usize == len);
        if !partition {
            return bad(format!(
                "spring colour offsets {offsets:?} do not partition {len} springs"
            ));
        }
        let mut last_colour = vec![usize::MAX; n];
        for c in 0..s.color_count() {
            for k in offsets[c] as usize..offsets[c + 1] as usize {
                for p in [s.a[k] as usize, s.b[k] as usize] {
                    if last_colour[p] == c {
                        return bad(format!("spring colour {c} uses particle {p} twice"));
                    }
                    last_colour[p] = c;
                }
            }
        }
        Ok(())
    }

    /// Builds a cloth of explicit springs and no faces, one particle per position: a chain, a
    /// rope, a net, or a single spring for a test. Rest lengths are the initial distances. The
    /// model has no triangles (so no aerodynamic forces and nothing to draw or subdivide) and
    /// `face_size` 3.
    ///
    /// Errors name the problem: the vertex checks of [`ClothModel::from_mesh`]
    /// ([`ClothError::InvalidMesh`]), a spring end past the last position
    /// ([`ClothError::MeshIndexOutOfRange`], `position` being `2 · spring + end`), and a spring
    /// from a particle to itself or between two particles at the same place
    /// ([`ClothError::InvalidMesh`], naming the spring).
    ///
    /// ```
    /// use bevy_cloth::sim::{ClothModel, SpringKind};
    /// use glam::Vec3;
    ///
    /// let points = [Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)];
    /// let chain = ClothModel::from_springs(
    ///     &points,
    ///     &[(0, 1, SpringKind::Structural), (1, 2, SpringKind::Structural)],
    /// )
    /// .unwrap();
    /// assert_eq!(chain.springs.len(), 2);
    /// ```
    pub fn from_springs(
        positions: &[Vec3],
        springs: &[(u32, u32, SpringKind)],
    ) -> Result<Self, ClothError> {
        check_vertices(positions, None)?;
        let count = positions.len();
        for (k, &(a, b, _)) in springs.iter().enumerate() {
            for (end, v) in [a, b].into_iter().enumerate() {
                if v as usize >= count {
                    return Err(ClothError::MeshIndexOutOfRange {
                        index: v,
                        position: 2 * k + end,
                        count,
                    });
                }
            }
            let p = positions[a as usize];
            if a == b || p == positions[b as usize] {
                return Err(ClothError::InvalidMesh {
                    what: format!("spring {k} ({a}, {b}) has zero length: both ends are at {p}"),
                });
            }
        }
        Ok(Self {
            rest_positions: positions.to_vec(),
            uvs: vec![Vec2::ZERO; count],
            triangles: Vec::new(),
            faces: Vec::new(),
            face_size: 3,
            springs: Springs::build(positions, springs),
            grid: None,
            particle_masses: None,
        })
    }
}

/// Every check of [`ClothModel::from_mesh`] that does not need the edge map: buffers, sizes,
/// values, index ranges, then each face.
fn check_mesh(
    positions: &[Vec3],
    uvs: Option<&[Vec2]>,
    indices: &[u32],
    face_size: usize,
) -> Result<(), ClothError> {
    let invalid = |what: String| Err(ClothError::InvalidMesh { what });
    check_vertices(positions, uvs)?;
    if indices.is_empty() {
        return invalid("has no indices".into());
    }
    if face_size != 3 && face_size != 4 {
        return invalid(format!("faces must have 3 or 4 vertices, got {face_size}"));
    }
    if !indices.len().is_multiple_of(face_size) {
        return invalid(format!(
            "index count {} is not a multiple of the face size {face_size}",
            indices.len()
        ));
    }
    let count = positions.len();
    if let Some((position, &index)) = indices
        .iter()
        .enumerate()
        .find(|(_, i)| **i as usize >= count)
    {
        return Err(ClothError::MeshIndexOutOfRange {
            index,
            position,
            count,
        });
    }
    for (f, face) in indices.chunks_exact(face_size).enumerate() {
        check_face(positions, f, face)?;
    }
    Ok(())
}

/// The vertex checks shared by [`ClothModel::from_mesh`] and [`ClothModel::from_springs`]: some
/// vertices but not too many, finite positions and texture coordinates (one per vertex), and no
/// distance between two vertices that overflows `f32`.
fn check_vertices(positions: &[Vec3], uvs: Option<&[Vec2]>) -> Result<(), ClothError> {
    let invalid = |what: String| Err(ClothError::InvalidMesh { what });
    if positions.is_empty() {
        return invalid("has no vertex positions".into());
    }
    let count = positions.len();
    if count > MAX_PARTICLES {
        return invalid(format!(
            "has {count} vertices, more than the supported maximum {MAX_PARTICLES}"
        ));
    }
    if let Some((i, p)) = positions.iter().enumerate().find(|(_, p)| !p.is_finite()) {
        return invalid(format!("vertex {i} has a non-finite position {p}"));
    }
    if let Some(uvs) = uvs {
        if uvs.len() != count {
            return invalid(format!(
                "has {} texture coordinates for {count} vertices",
                uvs.len()
            ));
        }
        if let Some((i, uv)) = uvs.iter().enumerate().find(|(_, uv)| !uv.is_finite()) {
            return invalid(format!(
                "vertex {i} has a non-finite texture coordinate {uv}"
            ));
        }
    }
    // Every distance between two vertices is at most the bounding box's diagonal.
    let (lo, hi) = positions.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    if !(hi - lo).length().is_finite() {
        let e = |v: Vec3| format!("({:e}, {:e}, {:e})", v.x, v.y, v.z);
        return invalid(format!(
            "is too large: its vertices span {} to {}, so distances between them overflow f32",
            e(lo),
            e(hi)
        ));
    }
    Ok(())
}

/// Checks one face of a mesh cloth: no vertex twice, no zero-length edge, and no triangle of zero
/// area (for a quad, neither triangle of its split along the first diagonal).
fn check_face(positions: &[Vec3], face: usize, corners: &[u32]) -> Result<(), ClothError> {
    let degenerate = |reason: String| ClothError::DegenerateFace {
        face,
        vertices: corners.to_vec(),
        reason,
    };
    if let Some(&v) = corners
        .iter()
        .enumerate()
        .find_map(|(k, v)| corners[..k].contains(v).then_some(v))
    {
        return Err(degenerate(format!("it uses vertex {v} more than once")));
    }
    let p = |v: u32| positions[v as usize];
    for k in 0..corners.len() {
        let (a, b) = (corners[k], corners[(k + 1) % corners.len()]);
        if p(a) == p(b) {
            return Err(ClothError::ZeroLengthEdge {
                face,
                a,
                b,
                position: p(a),
            });
        }
    }
    let split: &[[usize; 3]] = if corners.len() == 4 {
        &[[0, 1, 2], [0, 2, 3]]
    } else {
        &[[0, 1, 2]]
    };
    for t in split {
        // In f64, so that collinear f32 points give (almost exactly) zero.
        let [a, b, c] = t.map(|k| p(corners[k]).as_dvec3());
        let doubled_area = (b - a).cross(c - a).length();
        let longest = (b - a)
            .length_squared()
            .max((c - b).length_squared())
            .max((a - c).length_squared());
        if doubled_area <= DEGENERATE_TRIANGLE_RATIO * longest {
            return Err(degenerate(if corners.len() == 4 {
                format!(
                    "its triangle {:?} has zero area (collinear corners)",
                    t.map(|k| corners[k])
                )
            } else {
                "it has zero area (its corners are collinear)".into()
            }));
        }
    }
    Ok(())
}

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
    /// [`SubdividedModel::mass_scale`]. UVs follow the refined surface. Errors: the subdivision
    /// errors of [`control_mesh`](Self::control_mesh) and
    /// [`Subdivider::new`](crate::subdivision::Subdivider::new) (a mesh that is not
    /// manifold and consistently oriented), and those of `from_mesh`.
    pub fn subdivided(
        &self,
        level: u32,
        rule: VertexRule,
        boundary: BoundaryMode,
    ) -> Result<SubdividedModel, ClothError> {
        let control = self.control_mesh()?;
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

/// Writes area-weighted smooth vertex normals of a triangle mesh into `normals` (same length as
/// `positions`), without allocating. Vertices with no area around them get +Y.
pub fn compute_normals(positions: &[Vec3], triangles: &[u32], normals: &mut [Vec3]) {
    normals.fill(Vec3::ZERO);
    for t in triangles.chunks_exact(3) {
        let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let n = (positions[b] - positions[a]).cross(positions[c] - positions[a]);
        normals[a] += n;
        normals[b] += n;
        normals[c] += n;
    }
    for n in normals.iter_mut() {
        *n = n.try_normalize().unwrap_or(Vec3::Y);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grid_has_the_canonical_spring_counts() {
        let (nx, ny) = (5u32, 4u32);
        let m = ClothModel::grid(&GridSpec::new(nx, ny, 0.1)).unwrap();
        let [s, sh, b] = m.springs.count_by_kind();
        assert_eq!(s as u32, (nx - 1) * ny + nx * (ny - 1));
        assert_eq!(sh as u32, 2 * (nx - 1) * (ny - 1));
        assert_eq!(b as u32, (nx - 2) * ny + nx * (ny - 2));
        assert_eq!(m.triangles.len() as u32, (nx - 1) * (ny - 1) * 6);
        // particle (i, j) has index j * nx + i, spacing h along i and j.
        let p = |i: u32, j: u32| m.rest_positions[(j * nx + i) as usize];
        assert!((p(1, 0) - p(0, 0) - Vec3::new(0.1, 0.0, 0.0)).length() < 1e-6);
        assert!((p(0, 1) - p(0, 0) - Vec3::new(0.0, 0.0, 0.1)).length() < 1e-6);
    }

    #[test]
    fn a_quad_grid_mesh_gets_exactly_the_canonical_grid_springs() {
        let g = ClothModel::grid(&GridSpec::new(6, 5, 0.1)).unwrap();
        assert_eq!(g.face_size, 4);
        let m = ClothModel::from_mesh(&g.rest_positions, None, &g.faces, 4).unwrap();
        let set = |s: &Springs| {
            let mut v: Vec<_> = (0..s.len())
                .map(|k| (s.a[k].min(s.b[k]), s.a[k].max(s.b[k]), s.kind[k] as u8))
                .collect();
            v.sort_unstable();
            v
        };
        assert_eq!(set(&m.springs), set(&g.springs));
    }

    #[test]
    fn a_subdivided_grid_is_the_refined_quad_grid_with_its_mass() {
        let (nx, ny) = (5u32, 4u32);
        let n = (nx * ny) as usize;
        let masses: Vec<f32> = (1..=n).map(|i| i as f32 * 0.01).collect();
        let m = ClothModel::grid(&GridSpec::new(nx, ny, 0.1))
            .unwrap()
            .with_particle_masses(masses.clone())
            .unwrap();
        let r = m
            .subdivided(1, VertexRule::Original, BoundaryMode::EdgeAndCorner)
            .unwrap();
        let (rx, ry) = (2 * nx - 1, 2 * ny - 1);
        assert_eq!(r.model.particle_count(), (rx * ry) as usize);
        assert_eq!(r.model.face_size, 4);
        assert_eq!(
            r.model.faces.len(),
            4 * 4 * (nx - 1) as usize * (ny - 1) as usize
        );
        let [structural, shear, _] = r.model.springs.count_by_kind();
        assert_eq!(structural as u32, (rx - 1) * ry + rx * (ry - 1));
        assert_eq!(shear as u32, 2 * (rx - 1) * (ry - 1));
        assert!((r.mass_scale - n as f32 / (rx * ry) as f32).abs() < 1e-7);
        // A flat uniform grid with fixed corners reproduces itself: every particle keeps its
        // rest position, now as the vertex point named by the map.
        assert_eq!(r.particle_map.len(), n);
        for (i, &j) in r.particle_map.iter().enumerate() {
            let d = m.rest_positions[i].distance(r.model.rest_positions[j as usize]);
            assert!(d < 1e-6, "particle {i} moved by {d}");
        }
        let refined = r
            .model
            .particle_masses
            .as_ref()
            .expect("masses carried over");
        let (before, after) = (masses.iter().sum::<f32>(), refined.iter().sum::<f32>());
        assert!((after / before - 1.0).abs() < 1e-5, "{before} vs {after}");
        assert!(refined.iter().all(|&m| m > 0.0));
        r.model.validate().unwrap();
    }

    #[test]
    fn colours_never_share_a_particle() {
        let m = ClothModel::grid(&GridSpec::new(9, 7, 0.1)).unwrap();
        let s = &m.springs;
        for c in 0..s.color_count() {
            let mut seen = vec![false; m.particle_count()];
            for k in s.color_offsets[c] as usize..s.color_offsets[c + 1] as usize {
                for p in [s.a[k], s.b[k]] {
                    assert!(!seen[p as usize], "colour {c} uses particle {p} twice");
                    seen[p as usize] = true;
                }
            }
        }
        assert_eq!(*s.color_offsets.last().unwrap() as usize, s.len());
        assert!(s.color_count() <= 23, "{} colours", s.color_count());
    }

    #[test]
    fn grid_normals_face_up() {
        let m = ClothModel::grid(&GridSpec::new(4, 4, 0.1)).unwrap();
        let mut n = vec![Vec3::ZERO; m.particle_count()];
        compute_normals(&m.rest_positions, &m.triangles, &mut n);
        assert!(n.iter().all(|n| (*n - Vec3::Y).length() < 1e-6));
        let v =
            ClothModel::grid(&GridSpec::new(4, 4, 0.1).with_plane(GridPlane::Vertical)).unwrap();
        compute_normals(&v.rest_positions, &v.triangles, &mut n);
        assert!(n.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    }

    #[test]
    fn bad_grids_name_the_field() {
        let e = ClothModel::grid(&GridSpec::new(1, 4, 0.1)).unwrap_err();
        assert!(
            e.to_string().contains("nx") && e.to_string().contains('1'),
            "{e}"
        );
        let e = ClothModel::grid(&GridSpec::new(4, 0, 0.1)).unwrap_err();
        assert!(e.to_string().contains("ny"), "{e}");
        for h in [0.0, -1.0, f32::NAN, f32::INFINITY] {
            let e = ClothModel::grid(&GridSpec::new(4, 4, h)).unwrap_err();
            assert!(e.to_string().contains("spacing"), "{e}");
        }
    }

    #[test]
    fn mesh_cloth_from_two_triangles() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Z, Vec3::new(1.0, 0.0, 1.0)];
        let m = ClothModel::from_mesh(&p, None, &[0, 2, 1, 1, 2, 3], 3).unwrap();
        // 5 edges, one interior edge (1-2) whose opposite vertices 0 and 3 get a bend spring.
        assert_eq!(m.springs.count_by_kind(), [5, 0, 1]);
        assert_eq!(m.triangles, vec![0, 2, 1, 1, 2, 3]);
    }

    #[test]
    fn bad_meshes_are_errors() {
        let p = [Vec3::ZERO, Vec3::X, Vec3::Z];
        assert!(matches!(
            ClothModel::from_mesh(&p, None, &[], 3),
            Err(ClothError::InvalidMesh { .. })
        ));
        assert!(matches!(
            ClothModel::from_mesh(&[], None, &[0, 1, 2], 3),
            Err(ClothError::InvalidMesh { .. })
        ));
        assert_eq!(
            ClothModel::from_mesh(&p, None, &[0, 1, 7], 3).unwrap_err(),
            ClothError::MeshIndexOutOfRange {
                index: 7,
                position: 2,
                count: 3
            }
        );
        assert!(ClothModel::from_mesh(&p, None, &[0, 1], 3).is_err());
    }

    #[test]
    fn built_models_are_valid_and_broken_ones_are_errors() {
        let m = ClothModel::grid(&GridSpec::new(5, 4, 0.1)).unwrap();
        assert_eq!(m.validate(), Ok(()));
        let mut t = m.clone();
        t.triangles[4] = 99;
        assert!(matches!(
            t.validate(),
            Err(ClothError::MeshIndexOutOfRange { index: 99, .. })
        ));
        let mut u = m.clone();
        u.uvs.pop();
        assert!(u.validate().unwrap_err().to_string().contains("texture"));
        let mut s = m.clone();
        s.springs.rest[3] = 0.0;
        assert!(s.validate().unwrap_err().to_string().contains("spring 3"));
        let mut c = m.clone();
        let last = c.springs.color_offsets.len() - 1;
        c.springs.color_offsets[last] += 1;
        assert!(c.validate().unwrap_err().to_string().contains("partition"));
        // Two springs of colour 0 that share particle 0.
        let mut shared = m.clone();
        shared.springs.a[1] = shared.springs.a[0];
        let first_colour_len = shared.springs.color_offsets[1];
        assert!(first_colour_len >= 2);
        assert!(shared.validate().unwrap_err().to_string().contains("twice"));
        let mut f = m;
        f.face_size = 5;
        assert!(f.validate().unwrap_err().to_string().contains("3 or 4"));
    }

    #[test]
    fn particle_masses_are_checked() {
        let m = ClothModel::grid(&GridSpec::new(2, 2, 0.1)).unwrap();
        assert_eq!(m.mass_of(1, 0.25), 0.25);
        assert!(m.clone().with_particle_masses(vec![1.0; 3]).is_err());
        let e = m
            .clone()
            .with_particle_masses(vec![1.0, 1.0, -2.0, 1.0])
            .unwrap_err();
        assert!(e.to_string().contains("particle_masses"), "{e}");
        let m = m.with_particle_masses(vec![1.0, 2.0, 3.0, 4.0]).unwrap();
        assert_eq!(m.mass_of(2, 0.25), 3.0);
    }
}
