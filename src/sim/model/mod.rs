//! Cloth topology, built once: rest positions, the spring set (coloured for deterministic
//! Gauss-Seidel solving), the triangle list for rendering, and texture coordinates.
//!
//! This is where the canonical grid cloth (docs/guide.md, "The model") is defined, and where a cloth is derived from an
//! arbitrary triangle or quad mesh. Nothing here runs per step.

use glam::{Vec2, Vec3};

use crate::error::{ClothError, indices_in_range, particles_within, positive};

mod closed;
mod disc;
mod grid;
mod lattice;
mod normals;
mod seams;
mod springs;
mod subdivided;
mod tear;
#[cfg(test)]
mod tests;

pub use closed::MAX_ICOSPHERE_SUBDIVISIONS;
pub(crate) use closed::{enclosed_volume, volume_gradient};
pub use disc::{DiscSpec, MAX_DISC_RINGS, MAX_DISC_SECTORS, MIN_DISC_SECTORS};
pub use grid::{GridPlane, GridSpec, MAX_PARTICLES};
pub use normals::GridNormals;
pub(crate) use normals::two_rows;
pub use springs::{MAX_SPRINGS_PER_PARTICLE, SpringKind, Springs};
use springs::{check_spring_counts, face_springs, face_triangles, lattice_colors};
pub use subdivided::SubdividedModel;
pub(crate) use tear::{Splitter, pull_apart};

/// A triangle whose doubled area is at most this fraction of the square of its longest edge (its
/// height is at most a millionth of that edge) counts as having zero area: [`ClothModel::from_mesh`]
/// rejects it as degenerate.
pub const DEGENERATE_TRIANGLE_RATIO: f64 = 1e-6;

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
    /// For a grid torn by [`ClothSim::tear`](crate::sim::ClothSim::tear): the grid, and for each
    /// particle past its own (the copies a tear made) the grid particle it was split from, so
    /// that the torn cloth keeps the grid's spring colours and storage order (its step costs
    /// what the grid's does). Set by tearing only.
    pub(crate) torn_grid: Option<TornGrid>,
}

/// The grid a torn model was, and the grid particle each of its copies was split from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct TornGrid {
    pub spec: GridSpec,
    /// The grid particle of each particle `nx · ny + k`.
    pub origins: Vec<u32>,
}

impl TornGrid {
    /// The grid particle that particle `p` is or was split from.
    pub fn origin(&self, p: u32) -> u32 {
        let n = self.spec.nx * self.spec.ny;
        if p < n {
            p
        } else {
            self.origins[(p - n) as usize]
        }
    }
}

impl ClothModel {
    /// Number of particles.
    pub fn particle_count(&self) -> usize {
        self.rest_positions.len()
    }

    /// The grid's `(nx, ny)` if this model's particles and triangles are still those
    /// [`ClothModel::grid`] built (its fields are public, so a model may have been edited since):
    /// particle `(i, j)` at `j nx + i`, and quad `(i, j)` as the triangles `(a, c, b)` and
    /// `(b, c, d)` of its corners `a = (i, j)`, `b = (i + 1, j)`, `c = (i, j + 1)`,
    /// `d = (i + 1, j + 1)`, quads in row order. Row-by-row kernels rely on exactly that.
    pub(crate) fn canonical_grid(&self) -> Option<(usize, usize)> {
        let spec = self.grid.as_ref()?;
        let (nx, ny) = (spec.nx as usize, spec.ny as usize);
        if nx < 2 || ny < 2 || self.rest_positions.len() != nx * ny {
            return None;
        }
        let id = |i: usize, j: usize| (j * nx + i) as u32;
        let canonical = (0..ny - 1).flat_map(|j| {
            (0..nx - 1).flat_map(move |i| {
                let (a, b, c, d) = (id(i, j), id(i + 1, j), id(i, j + 1), id(i + 1, j + 1));
                [a, c, b, b, c, d]
            })
        });
        self.triangles
            .iter()
            .copied()
            .eq(canonical)
            .then_some((nx, ny))
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

    /// The mean length of the triangles' edges at rest, m: each triangle's three edges, over all
    /// triangles (an edge two triangles share counts twice). 0 without triangles. What
    /// [`MAX_THICKNESS_PER_EDGE`](super::MAX_THICKNESS_PER_EDGE) multiplies.
    pub fn mean_edge_length(&self) -> f32 {
        let p = &self.rest_positions;
        let (sum, count) = self
            .triangles
            .chunks_exact(3)
            .flat_map(|t| [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])])
            .fold((0.0f64, 0usize), |(sum, count), (a, b)| {
                let d = p[a as usize].distance(p[b as usize]);
                (sum + f64::from(d), count + 1)
            });
        if count == 0 {
            0.0
        } else {
            (sum / count as f64) as f32
        }
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
        // Eighteen colours by family and position: rows of structural springs alternate by column
        // (0, 1); columns and both diagonals take four colours each by row (2–5, 6–9, 10–13), so
        // that one sweep carries a pull four rows down or up the cloth rather than two; bend
        // springs alternate by pairs of columns (14, 15) and pairs of rows (16, 17). Each colour
        // is then a few long runs of regular index offset, which the XPBD kernel loads as whole
        // vectors.
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
                    add(id(i, j), id(i, j + 1), SpringKind::Structural, 2 + j % 4);
                }
                if i + 1 < nx && j + 1 < ny {
                    add(id(i, j), id(i + 1, j + 1), SpringKind::Shear, 6 + j % 4);
                    add(id(i + 1, j), id(i, j + 1), SpringKind::Shear, 10 + j % 4);
                }
                if i + 2 < nx {
                    add(id(i, j), id(i + 2, j), SpringKind::Bend, 14 + (i / 2) % 2);
                }
                if j + 2 < ny {
                    add(id(i, j), id(i, j + 2), SpringKind::Bend, 16 + (j / 2) % 2);
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
            torn_grid: None,
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
    /// - [`ClothError::TooMany`]: more than [`MAX_PARTICLES`] vertices (checked before anything is
    ///   built), or a vertex with more than [`MAX_SPRINGS_PER_PARTICLE`] springs;
    /// - [`ClothError::InvalidMesh`]: no positions, no indices, a face size other than 3 or 4, an
    ///   index count that is not a multiple of it, a non-finite position or texture coordinate (naming the vertex), a texture coordinate count
    ///   that differs from the vertex count, or vertices so far apart that the distances between
    ///   them overflow `f32`;
    /// - [`ClothError::MeshIndexOutOfRange`]: an index past the last vertex (with its position in
    ///   the index buffer);
    /// - [`ClothError::DegenerateFace`]: a face that uses a vertex twice, a triangle (for a quad,
    ///   either triangle of its split) with zero area (see [`DEGENERATE_TRIANGLE_RATIO`]), or a
    ///   face with the same corners as an earlier one;
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
        let pairs = face_springs(indices, face_size)?;
        let triangles = face_triangles(indices, face_size);
        check_spring_counts(count, pairs.iter().map(|&(a, b, _)| (a, b)))?;
        let mut model = Self {
            rest_positions: positions.to_vec(),
            uvs: uvs.map_or_else(|| vec![Vec2::ZERO; count], <[Vec2]>::to_vec),
            triangles,
            faces: indices.to_vec(),
            face_size,
            springs: Springs::default(),
            grid: None,
            particle_masses: None,
            torn_grid: None,
        };
        // A mesh laid out as a grid (a cape made as a grid of vertices) is coloured as the grid.
        model.springs = match model.lattice() {
            Some(lattice) => {
                let colors = lattice_colors(&pairs, lattice.nx);
                Springs::build_colored(positions, &pairs, &colors)
            }
            None => Springs::build(positions, &pairs),
        };
        Ok(model)
    }
}

impl ClothModel {
    /// Checks that the model is consistent, for models assembled or edited by hand (its fields are
    /// public): at most [`MAX_PARTICLES`] particles, finite rest positions, one texture
    /// coordinate (and mass, if any) per particle, triangles and faces whose indices are in range,
    /// a face size of 3 or 4, and springs whose arrays agree, whose particles exist (with at most
    /// [`MAX_SPRINGS_PER_PARTICLE`] springs each), whose rest lengths are finite and positive, and
    /// whose colours partition them with no particle twice in a colour, and a `grid` (if any) that is
    /// valid and has as many particles as the model. The builders ([`grid`](Self::grid),
    /// [`from_mesh`](Self::from_mesh), [`disc`](Self::disc)) always pass. [`ClothSim::new`]
    /// checks every model it is given; the solver's vector kernels and threads rely on it. The
    /// error names the first problem.
    ///
    /// [`ClothSim::new`]: crate::sim::ClothSim::new
    pub fn validate(&self) -> Result<(), ClothError> {
        let bad = |what: String| Err(ClothError::InvalidMesh { what });
        let n = self.particle_count();
        if n == 0 {
            return bad("has no vertex positions".into());
        }
        particles_within(n as u64, || "one per rest position of the model".into())?;
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
        check_spring_counts(n, s.a.iter().copied().zip(s.b.iter().copied()))?;
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
        if let Some(grid) = &self.grid {
            grid.validate()?;
            let claimed = grid.nx as usize * grid.ny as usize;
            if claimed != n {
                return bad(format!(
                    "claims a {}×{} grid ({claimed} particles) but has {n} particles",
                    grid.nx, grid.ny
                ));
            }
        }
        if let Some(torn) = &self.torn_grid {
            torn.spec.validate()?;
            let grid = torn.spec.nx as usize * torn.spec.ny as usize;
            if grid + torn.origins.len() != n || torn.origins.iter().any(|&o| o as usize >= grid) {
                return bad(format!(
                    "a torn {}×{} grid whose copies do not match its {n} particles",
                    torn.spec.nx, torn.spec.ny
                ));
            }
        }
        Ok(())
    }

    /// The grid whose storage order the solver keeps: the model's, or the one it was torn from
    /// (its copies stored after the grid's particles).
    pub(crate) fn storage_grid(&self) -> Option<&GridSpec> {
        self.grid
            .as_ref()
            .or(self.torn_grid.as_ref().map(|t| &t.spec))
    }

    /// Builds a cloth of explicit springs and no faces, one particle per position: a chain, a
    /// rope, a net, or a single spring for a test. Rest lengths are the initial distances. The
    /// model has no triangles (so no aerodynamic forces and nothing to draw or subdivide) and
    /// `face_size` 3.
    ///
    /// Errors name the problem: the vertex checks of [`ClothModel::from_mesh`]
    /// ([`ClothError::InvalidMesh`], and [`ClothError::TooMany`] past [`MAX_PARTICLES`]), a
    /// spring end past the last position ([`ClothError::MeshIndexOutOfRange`], `position` being
    /// `2 · spring + end`), a spring from a particle to itself or between two particles at the
    /// same place ([`ClothError::InvalidMesh`], naming the spring), and a particle with more than
    /// [`MAX_SPRINGS_PER_PARTICLE`] springs ([`ClothError::TooMany`]).
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
        check_spring_counts(count, springs.iter().map(|&(a, b, _)| (a, b)))?;
        Ok(Self {
            rest_positions: positions.to_vec(),
            uvs: vec![Vec2::ZERO; count],
            triangles: Vec::new(),
            faces: Vec::new(),
            face_size: 3,
            springs: Springs::build(positions, springs),
            grid: None,
            particle_masses: None,
            torn_grid: None,
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
    indices_in_range(indices, count)?;
    for (f, face) in indices.chunks_exact(face_size).enumerate() {
        check_face(positions, f, face)?;
    }
    // Two faces on the same corners would double the cloth over itself there.
    let mut corners: Vec<([u32; 4], usize)> = indices
        .chunks_exact(face_size)
        .enumerate()
        .map(|(f, face)| {
            let mut key = [u32::MAX; 4];
            key[..face_size].copy_from_slice(face);
            key.sort_unstable();
            (key, f)
        })
        .collect();
    corners.sort_unstable();
    if let Some(pair) = corners.windows(2).find(|w| w[0].0 == w[1].0) {
        let (first, face) = (pair[0].1, pair[1].1);
        return Err(ClothError::DegenerateFace {
            face,
            vertices: indices[face * face_size..(face + 1) * face_size].to_vec(),
            reason: format!("it has the same corners as face {first}"),
        });
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
    particles_within(count as u64, || "one per mesh vertex".into())?;
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
