//! A cloth's springs ([`Springs`]), in families ([`SpringKind`]) and coloured so that no two
//! springs of a colour share a particle.

use bevy::reflect::Reflect;
use glam::Vec3;
use std::collections::{HashMap, HashSet};
use std::hash::BuildHasherDefault;

use crate::error::ClothError;
use crate::hash::IntHasher;
use serde::{Deserialize, Serialize};

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

/// Most springs one particle may have. A grid's particle has 12 and a mesh vertex about two to
/// three times its valence; a hub with many more costs out of proportion: colouring the springs
/// takes scratch of the particle count times this per 32, and XPBD sweeps once per colour, of
/// which a particle's springs need as many as it has.
pub const MAX_SPRINGS_PER_PARTICLE: usize = 256;

/// Checks that no particle of `count` is an end of more than [`MAX_SPRINGS_PER_PARTICLE`] of the
/// springs between `pairs`; the error names the first such particle.
pub(super) fn check_spring_counts(
    count: usize,
    pairs: impl Iterator<Item = (u32, u32)>,
) -> Result<(), ClothError> {
    let mut springs = vec![0u32; count];
    for (a, b) in pairs {
        for p in [a, b] {
            let k = &mut springs[p as usize];
            *k += 1;
            if *k as usize > MAX_SPRINGS_PER_PARTICLE {
                return crate::error::at_most(
                    "springs at one particle",
                    *k as usize,
                    MAX_SPRINGS_PER_PARTICLE,
                    || format!("MAX_SPRINGS_PER_PARTICLE; particle {p} has at least that many"),
                );
            }
        }
    }
    Ok(())
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
    pub(super) fn build(positions: &[Vec3], pairs: &[(u32, u32, SpringKind)]) -> Self {
        let colors = greedy_edge_coloring(positions.len(), pairs.iter().map(|p| (p.0, p.1)));
        Self::build_colored(positions, pairs, &colors)
    }

    /// [`Self::build`] with a given colour per spring (no two springs of a colour may share a
    /// particle). Within a colour, springs are ordered by index offset `b - a` and then by `a`
    /// (XPBD's layout re-sorts them by storage position; see `xpbd::Projections`).
    pub(super) fn build_colored(
        positions: &[Vec3],
        pairs: &[(u32, u32, SpringKind)],
        colors: &[u32],
    ) -> Self {
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
        // No two springs of a colour share a particle, so the keys are distinct.
        order.sort_unstable_by_key(|&s| (pairs[s].4, pairs[s].1 - pairs[s].0, pairs[s].0));
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

/// Colours for springs `pairs` between the particles of a lattice of rows of `nx` (particle
/// `(i, j)` is `j · nx + i`), as [`ClothModel::grid`](super::ClothModel::grid) colours its own:
/// one pair of colours per direction `(di, dj)` a spring spans, alternating along that direction
/// (two springs of one direction share a particle only where one starts where the other ends).
/// A colour then holds the springs of one direction at every other step, whose index offsets
/// are all the same and whose first particles follow each other along the rows: XPBD's kernel
/// loads them as whole vectors, where a greedy colouring scatters them.
pub(super) fn lattice_colors(pairs: &[(u32, u32, SpringKind)], nx: usize) -> Vec<u32> {
    let mut directions: Vec<(i64, i64)> = Vec::new();
    pairs
        .iter()
        .map(|&(a, b, _)| {
            let (a, b) = (a.min(b) as i64, a.max(b) as i64);
            let nx = nx as i64;
            let (i, j) = (a % nx, a / nx);
            let (di, dj) = (b % nx - i, b / nx - j);
            let class = match directions.iter().position(|&d| d == (di, dj)) {
                Some(c) => c,
                None => {
                    directions.push((di, dj));
                    directions.len() - 1
                }
            };
            // The step along the direction: `dj > 0`, or `dj = 0` and `di > 0`.
            let step = if dj > 0 { j / dj } else { i / di.max(1) };
            (2 * class) as u32 + (step % 2) as u32
        })
        .collect()
}

/// [`lattice_colors`] for a torn grid's springs, each coloured as the spring between the grid
/// particles its ends were split from (`origin`). Where both sides of a tear kept a spring to the
/// same particle, the second takes the smallest colour past the lattice's free at both its ends.
pub(super) fn torn_lattice_colors(
    pairs: &[(u32, u32, SpringKind)],
    nx: usize,
    origin: impl Fn(u32) -> u32,
) -> Vec<u32> {
    let origins: Vec<_> = pairs
        .iter()
        .map(|&(a, b, k)| (origin(a), origin(b), k))
        .collect();
    let mut colors = lattice_colors(&origins, nx);
    let spare = colors.iter().max().map_or(0, |c| c + 1) as usize;
    // A spring's two ends have fewer than 2 · MAX_SPRINGS_PER_PARTICLE other springs, so one of
    // that many spare colours is free at both.
    let words = (spare + 2 * MAX_SPRINGS_PER_PARTICLE).div_ceil(64);
    let particles = pairs.iter().map(|&(a, b, _)| a.max(b) as usize + 1).max();
    let mut used = vec![0u64; particles.unwrap_or(0) * words];
    let taken =
        |used: &[u64], p: u32, c: usize| (used[p as usize * words + c / 64] >> (c % 64)) & 1;
    for (&(a, b, _), color) in pairs.iter().zip(&mut colors) {
        let free = |c: usize| (taken(&used, a, c) | taken(&used, b, c)) == 0;
        let c = match *color as usize {
            c if free(c) => c,
            _ => (spare..words * 64).find(|&c| free(c)).unwrap_or(spare),
        };
        *color = c as u32;
        for p in [a, b] {
            used[p as usize * words + c / 64] |= 1 << (c % 64);
        }
    }
    colors
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

/// The springs [`ClothModel::from_mesh`](super::ClothModel::from_mesh) builds on faces of `face_size` corners: structural along
/// every edge, bend across every interior edge, and for quads both diagonals as shear. Fails on an
/// edge shared by more than two faces.
pub(crate) fn face_springs(
    indices: &[u32],
    face_size: usize,
) -> Result<Vec<(u32, u32, SpringKind)>, ClothError> {
    // Each undirected edge, in order of first use, with its uses, one per face: the face, and
    // for each end of the edge (the smaller index first) that end's other neighbour in the face
    // (the third corner of a triangle, for both ends). Uses past two (a non-manifold edge) are
    // kept aside for the error.
    #[derive(Clone, Copy)]
    struct Edge {
        ends: (u32, u32),
        uses: [(usize, [u32; 2]); 2],
        count: usize,
    }
    let mut index: HashMap<u64, u32, BuildHasherDefault<IntHasher>> =
        HashMap::with_capacity_and_hasher(indices.len(), Default::default());
    let mut edges: Vec<Edge> = Vec::with_capacity(indices.len());
    let mut extra_uses: Vec<(u32, usize)> = Vec::new();
    let mut pairs = Vec::new();
    for (f, face) in indices.chunks_exact(face_size).enumerate() {
        for k in 0..face_size {
            let (a, b) = (face[k], face[(k + 1) % face_size]);
            // The corner before `a` and the corner after `b` (the same vertex in a triangle).
            let (before_a, after_b) = (
                face[(k + face_size - 1) % face_size],
                face[(k + 2) % face_size],
            );
            let ends = (a.min(b), a.max(b));
            let across = if a < b {
                [before_a, after_b]
            } else {
                [after_b, before_a]
            };
            let key = u64::from(ends.0) << 32 | u64::from(ends.1);
            let e = *index.entry(key).or_insert_with(|| {
                edges.push(Edge {
                    ends,
                    uses: [(f, across); 2],
                    count: 0,
                });
                edges.len() as u32 - 1
            });
            let edge = &mut edges[e as usize];
            match edge.uses.get_mut(edge.count) {
                Some(slot) => *slot = (f, across),
                None => extra_uses.push((e, f)),
            }
            edge.count += 1;
        }
        if face_size == 4 {
            pairs.push((face[0], face[2], SpringKind::Shear));
            pairs.push((face[1], face[3], SpringKind::Shear));
        }
    }
    // A quad's straight bend spring through a vertex is found from both edges that pass
    // straight through it; make it once.
    let mut bends: HashSet<u64, BuildHasherDefault<IntHasher>> = HashSet::default();
    for (e, edge) in edges.iter().enumerate() {
        let (a, b) = edge.ends;
        if edge.count > 2 {
            let more = extra_uses.iter().filter(|&&(x, _)| x as usize == e);
            return Err(ClothError::NonManifoldEdge {
                a,
                b,
                faces: edge
                    .uses
                    .iter()
                    .map(|&(f, _)| f)
                    .chain(more.map(|&(_, f)| f))
                    .collect(),
            });
        }
        pairs.push((a, b, SpringKind::Structural));
        if let [(_, first), (_, second)] = edge.uses[..edge.count] {
            let ends = if face_size == 4 { 2 } else { 1 };
            for (p, q) in first.into_iter().zip(second).take(ends) {
                if p != q && bends.insert(u64::from(p.min(q)) << 32 | u64::from(p.max(q))) {
                    pairs.push((p, q, SpringKind::Bend));
                }
            }
        }
    }
    Ok(pairs)
}

/// The triangles [`ClothModel::from_mesh`](super::ClothModel::from_mesh) draws faces of `face_size` corners with: a triangle as
/// it is, a quad split along its first diagonal.
pub(super) fn face_triangles(indices: &[u32], face_size: usize) -> Vec<u32> {
    if face_size == 3 {
        return indices.to_vec();
    }
    indices
        .chunks_exact(4)
        .flat_map(|f| [f[0], f[1], f[2], f[0], f[2], f[3]])
        .collect()
}
