//! Topology that opens where a cloth tears: particles split along a partition of the faces around
//! them, and the torn model built from the split faces. Which faces go to which side is the
//! caller's choice (a cut's plane, the direction of an overstretched spring); here a particle
//! whose faces fall on both sides becomes one particle per side, and each side that is not joined
//! across an edge through it gets its own, so every particle stays a single fan of faces.

use glam::{Vec2, Vec3};
use std::collections::HashMap;

use super::springs::{check_spring_counts, face_springs, face_triangles, torn_lattice_colors};
use super::{ClothModel, Springs, TornGrid};
use crate::error::ClothError;

/// The faces of a model being split, with the particles split so far.
pub(crate) struct Splitter<'a> {
    model: &'a ClothModel,
    /// The faces' corners, re-attached to copies as particles split.
    faces: Vec<u32>,
    /// The faces around each particle of the model, `offsets[p]..offsets[p + 1]` in `around`.
    offsets: Vec<u32>,
    around: Vec<u32>,
    /// The faces around particles split so far (the model's and the copies), replacing `around`.
    split: HashMap<u32, Vec<u32>>,
    /// For each copy made, the model's particle it was split from.
    origin: Vec<u32>,
    /// Every particle's mass, kg: the model's, then the copies'; a split shares the mass out by
    /// the faces' areas on each side.
    masses: Vec<f32>,
    /// Each face's rest area, m².
    areas: Vec<f32>,
}

impl<'a> Splitter<'a> {
    /// Starts splitting `model`, whose particles weigh `masses`.
    pub fn new(model: &'a ClothModel, masses: &[f32]) -> Self {
        let n = model.particle_count();
        let size = model.face_size;
        let mut offsets = vec![0u32; n + 1];
        for &c in &model.faces {
            offsets[c as usize + 1] += 1;
        }
        for p in 0..n {
            offsets[p + 1] += offsets[p];
        }
        let mut next = offsets.clone();
        let mut around = vec![0u32; model.faces.len()];
        for (f, face) in model.faces.chunks_exact(size).enumerate() {
            for &c in face {
                around[next[c as usize] as usize] = f as u32;
                next[c as usize] += 1;
            }
        }
        let rest = &model.rest_positions;
        let areas = model
            .faces
            .chunks_exact(size)
            .map(|face| {
                let p = |k: usize| rest[face[k] as usize];
                let mut twice = (p(1) - p(0)).cross(p(2) - p(0)).length();
                if size == 4 {
                    twice += (p(2) - p(0)).cross(p(3) - p(0)).length();
                }
                0.5 * twice
            })
            .collect();
        Self {
            model,
            faces: model.faces.clone(),
            offsets,
            around,
            split: HashMap::new(),
            origin: Vec::new(),
            masses: masses.to_vec(),
            areas,
        }
    }

    /// Number of particles, copies included.
    pub fn particle_count(&self) -> usize {
        self.model.particle_count() + self.origin.len()
    }

    /// The model's particle that particle `p` is or was split from.
    pub fn origin(&self, p: u32) -> u32 {
        let n = self.model.particle_count() as u32;
        if p < n {
            p
        } else {
            self.origin[(p - n) as usize]
        }
    }

    /// The copies made so far, each with the model's particle it was split from, in the order
    /// they were made (their indices follow the model's particles).
    pub fn copies(&self) -> impl Iterator<Item = (u32, u32)> + '_ {
        let n = self.model.particle_count() as u32;
        self.origin
            .iter()
            .enumerate()
            .map(move |(k, &o)| (o, n + k as u32))
    }

    /// The faces around particle `p`, in increasing order.
    pub fn faces_of(&self, p: u32) -> &[u32] {
        match self.split.get(&p) {
            Some(faces) => faces,
            None if (p as usize) < self.model.particle_count() => {
                let (a, b) = (self.offsets[p as usize], self.offsets[p as usize + 1]);
                &self.around[a as usize..b as usize]
            }
            None => &[],
        }
    }

    /// The corners of face `f`.
    pub fn face(&self, f: u32) -> &[u32] {
        let size = self.model.face_size;
        &self.faces[f as usize * size..(f as usize + 1) * size]
    }

    /// The centre of face `f` (the mean of its corners) with the model's particles at `positions`
    /// (copies are where their origin is).
    pub fn centroid(&self, f: u32, positions: &[Vec3]) -> Vec3 {
        let face = self.face(f);
        let sum: Vec3 = face
            .iter()
            .map(|&c| positions[self.origin(c) as usize])
            .sum();
        sum / face.len() as f32
    }

    /// The two corners joined to `p` by an edge of face `f`.
    fn edge_neighbours(&self, f: u32, p: u32) -> [u32; 2] {
        let face = self.face(f);
        let k = face.iter().position(|&c| c == p).unwrap_or(0);
        let size = face.len();
        [face[(k + size - 1) % size], face[(k + 1) % size]]
    }

    /// Whether `p` lies on the cloth's boundary (or on a tear): an edge through it bounds one face.
    pub fn on_boundary(&self, p: u32) -> bool {
        let faces = self.faces_of(p);
        let mut uses: Vec<u32> = faces
            .iter()
            .flat_map(|&f| self.edge_neighbours(f, p))
            .collect();
        uses.sort_unstable();
        // Each interior edge appears twice, a boundary edge once.
        let mut k = 0;
        while k < uses.len() {
            let run = uses[k..].iter().take_while(|&&q| q == uses[k]).count();
            if run == 1 {
                return true;
            }
            k += run;
        }
        false
    }

    /// Splits particle `p` between the faces around it whose centre (with the model's particles
    /// at `positions`) is on the `side` and the others, when both are there: each side, and each
    /// part of a side not joined across an edge through `p`, gets its own particle. The part with
    /// the lowest face keeps `p`; the others get copies. Mass is shared by the parts' areas. The
    /// particles at the far ends of the new edges are then split into their own fans where the
    /// tear left them joined by a vertex alone (a tear reaching the cloth's edge, or another
    /// tear), so every particle stays one fan of faces, as subdivision needs. Returns the copies
    /// made, in order.
    pub fn split(&mut self, p: u32, positions: &[Vec3], side: impl Fn(Vec3) -> bool) -> Vec<u32> {
        let faces = self.faces_of(p).to_vec();
        let sides: Vec<bool> = faces
            .iter()
            .map(|&f| side(self.centroid(f, positions)))
            .collect();
        if sides.iter().all(|&s| s) || !sides.iter().any(|&s| s) {
            return Vec::new();
        }
        let ends: Vec<u32> = faces
            .iter()
            .flat_map(|&f| self.edge_neighbours(f, p))
            .collect();
        let mut copies = self.separate(p, &sides);
        for q in ends {
            let all = vec![true; self.faces_of(q).len()];
            copies.extend(self.separate(q, &all));
        }
        copies
    }

    /// Gives each part of the faces around `p` (those on one of the `sides`, one per face, joined
    /// across an edge through `p`) its own particle: the part with the lowest face keeps `p`, the
    /// others get copies, returned in order, with `p`'s mass shared by their areas.
    fn separate(&mut self, p: u32, sides: &[bool]) -> Vec<u32> {
        let faces = self.faces_of(p).to_vec();
        let neighbours: Vec<[u32; 2]> = faces.iter().map(|&f| self.edge_neighbours(f, p)).collect();
        let mut part = vec![usize::MAX; faces.len()];
        let mut parts = 0;
        for start in 0..faces.len() {
            if part[start] != usize::MAX {
                continue;
            }
            part[start] = parts;
            let mut stack = vec![start];
            while let Some(i) = stack.pop() {
                for j in 0..faces.len() {
                    let joined = sides[j] == sides[i]
                        && neighbours[j].iter().any(|q| neighbours[i].contains(q));
                    if part[j] == usize::MAX && joined {
                        part[j] = parts;
                        stack.push(j);
                    }
                }
            }
            parts += 1;
        }
        if parts < 2 {
            return Vec::new();
        }
        let size = self.model.face_size as f32;
        let mut area = vec![0.0f32; parts];
        for (i, &f) in faces.iter().enumerate() {
            area[part[i]] += self.areas[f as usize] / size;
        }
        let total: f32 = area.iter().sum();
        let mass = self.masses[p as usize];
        let share = |a: f32| {
            if total > 0.0 {
                mass * a / total
            } else {
                mass / parts as f32
            }
        };
        let origin = self.origin(p);
        let mut copies = Vec::with_capacity(parts - 1);
        // `faces` is in increasing order, so part 0 holds the lowest face and keeps `p`.
        for (k, &part_area) in area.iter().enumerate() {
            let mine: Vec<u32> = (0..faces.len())
                .filter(|&i| part[i] == k)
                .map(|i| faces[i])
                .collect();
            let particle = if k == 0 {
                self.masses[p as usize] = share(part_area);
                p
            } else {
                let copy = self.particle_count() as u32;
                self.origin.push(origin);
                self.masses.push(share(part_area));
                copies.push(copy);
                let size = self.model.face_size;
                for &f in &mine {
                    for c in &mut self.faces[f as usize * size..(f as usize + 1) * size] {
                        if *c == p {
                            *c = copy;
                        }
                    }
                }
                copy
            };
            self.split.insert(particle, mine);
        }
        copies
    }

    /// The torn model: the split faces with the springs [`ClothModel::from_mesh`] builds on them
    /// (none across a tear; each side keeps its edge), the model's triangles re-attached to the
    /// copies their faces took, copies at their origin's rest position and texture coordinate
    /// (with `gap` above 0, the rest positions of the particles `apart` pulled apart by it, see
    /// [`pull_apart`]), and the shared masses.
    pub fn finish(self, (apart, gap): (&[u32], f32)) -> Result<ClothModel, ClothError> {
        let model = self.model;
        let size = model.face_size;
        let origins = (0..model.particle_count() as u32).chain(self.origin.iter().copied());
        let (mut rest_positions, uvs): (Vec<Vec3>, Vec<Vec2>) = origins
            .map(|o| (model.rest_positions[o as usize], model.uvs[o as usize]))
            .unzip();
        pull_apart(&self.faces, size, &mut rest_positions, apart, gap);
        let pairs = face_springs(&self.faces, size)?;
        check_spring_counts(rest_positions.len(), pairs.iter().map(|&(a, b, _)| (a, b)))?;
        // A grid torn keeps its colouring: the XPBD kernel's runs, and its step's cost.
        let torn_grid = model.storage_grid().map(|&spec| {
            let root = |p: u32| match &model.torn_grid {
                Some(torn) => torn.origin(p),
                None => p,
            };
            let grid = spec.nx * spec.ny;
            let origins = (grid..rest_positions.len() as u32)
                .map(|p| root(self.origin(p)))
                .collect();
            TornGrid { spec, origins }
        });
        let springs = match &torn_grid {
            Some(torn) => {
                let colors = torn_lattice_colors(&pairs, torn.spec.nx as usize, |p| torn.origin(p));
                Springs::build_colored(&rest_positions, &pairs, &colors)
            }
            None => Springs::build(&rest_positions, &pairs),
        };
        let per_face = size - 2;
        let faces_count = self.faces.len() / size;
        // Each face's triangles follow its corners; a model whose triangles are not its faces'
        // (one per triangle, two per quad, in face order) is drawn as `from_mesh` draws faces.
        let triangles = if model.triangles.len() == faces_count * per_face * 3 {
            let mut triangles = model.triangles.clone();
            for (t, tri) in triangles.chunks_exact_mut(3).enumerate() {
                let f = t / per_face;
                let before = &model.faces[f * size..(f + 1) * size];
                let after = &self.faces[f * size..(f + 1) * size];
                for c in tri {
                    if let Some(k) = before.iter().position(|b| b == c) {
                        *c = after[k];
                    }
                }
            }
            triangles
        } else {
            face_triangles(&self.faces, size)
        };
        Ok(ClothModel {
            rest_positions,
            uvs,
            triangles,
            faces: self.faces,
            face_size: size,
            springs,
            grid: None,
            particle_masses: Some(self.masses),
            torn_grid,
        })
    }
}

/// Moves each of the `split` particles (at `positions`, on `faces` of `size` corners) by `gap`
/// (at most a quarter of the way) toward the middle of its own faces: the two sides of a tear,
/// which were one, then lie `2 gap` apart across it.
pub(crate) fn pull_apart(
    faces: &[u32],
    size: usize,
    positions: &mut [Vec3],
    split: &[u32],
    gap: f32,
) {
    if gap <= 0.0 || split.is_empty() {
        return;
    }
    let mut split = split.to_vec();
    split.sort_unstable();
    split.dedup();
    let mut sum = vec![(Vec3::ZERO, 0u32); split.len()];
    for face in faces.chunks_exact(size) {
        let centre = face.iter().map(|&c| positions[c as usize]).sum::<Vec3>() / size as f32;
        for &c in face {
            if let Ok(k) = split.binary_search(&c) {
                sum[k].0 += centre;
                sum[k].1 += 1;
            }
        }
    }
    for (&p, &(total, count)) in split.iter().zip(&sum) {
        if count > 0 {
            let to = total / count as f32 - positions[p as usize];
            positions[p as usize] += to * (gap / to.length().max(4.0 * gap));
        }
    }
}

impl ClothModel {
    /// The pieces the cloth is in: how many, and for each particle the piece it belongs to
    /// (particles joined by a chain of springs are in one piece, numbered in order of their
    /// lowest particle). A cloth torn in two has two pieces.
    pub fn pieces(&self) -> (usize, Vec<u32>) {
        let n = self.particle_count();
        let mut parent: Vec<u32> = (0..n as u32).collect();
        fn root(parent: &mut [u32], mut p: u32) -> u32 {
            while parent[p as usize] != p {
                let up = parent[parent[p as usize] as usize];
                parent[p as usize] = up;
                p = up;
            }
            p
        }
        for (&a, &b) in self.springs.a.iter().zip(&self.springs.b) {
            let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
            if ra != rb {
                parent[ra.max(rb) as usize] = ra.min(rb);
            }
        }
        let mut label = vec![u32::MAX; n];
        let mut count = 0u32;
        let mut pieces = vec![0u32; n];
        for p in 0..n as u32 {
            let r = root(&mut parent, p) as usize;
            if label[r] == u32::MAX {
                label[r] = count;
                count += 1;
            }
            pieces[p as usize] = label[r];
        }
        (count as usize, pieces)
    }
}
