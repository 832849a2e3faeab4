//! [`Soa`]: particle vectors stored one array per coordinate, the layout every vector kernel of
//! the solver reads and writes.

use glam::Vec3;

/// Particle positions or forces, one array per coordinate, so that kernels can read and write
/// eight consecutive particles with whole vector loads and stores.
#[derive(Debug, Clone, Default)]
pub(crate) struct Soa {
    pub x: Vec<f32>,
    pub y: Vec<f32>,
    pub z: Vec<f32>,
}

impl Soa {
    /// `n` zero vectors.
    pub fn new(n: usize) -> Self {
        Self {
            x: vec![0.0; n],
            y: vec![0.0; n],
            z: vec![0.0; n],
        }
    }

    /// Makes it hold `n` vectors (new ones zero), keeping its allocation.
    pub fn resize(&mut self, n: usize) {
        for a in [&mut self.x, &mut self.y, &mut self.z] {
            a.resize(n, 0.0);
        }
    }

    /// Number of vectors.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// Copies `vectors` in (as many as both hold).
    pub fn load(&mut self, vectors: &[Vec3]) {
        for (p, (x, y, z)) in vectors.iter().zip(self.iter_mut()) {
            (*x, *y, *z) = (p.x, p.y, p.z);
        }
    }

    /// [`Self::load`] in storage order `order` (`order[s]` is the vector stored at `s`; empty:
    /// the vectors' own order).
    pub fn load_ordered(&mut self, vectors: &[Vec3], order: &[u32]) {
        if order.is_empty() {
            return self.load(vectors);
        }
        for (&i, (x, y, z)) in order.iter().zip(self.iter_mut()) {
            let p = vectors[i as usize];
            (*x, *y, *z) = (p.x, p.y, p.z);
        }
    }

    /// Copies the vectors out into `vectors` (as many as both hold).
    pub fn write_to(&self, vectors: &mut [Vec3]) {
        for (p, v) in vectors.iter_mut().zip(self.iter()) {
            *p = v;
        }
    }

    /// [`Self::write_to`] from storage order `order` (see [`Self::load_ordered`]).
    pub fn write_ordered(&self, vectors: &mut [Vec3], order: &[u32]) {
        if order.is_empty() {
            return self.write_to(vectors);
        }
        for (&i, v) in order.iter().zip(self.iter()) {
            vectors[i as usize] = v;
        }
    }

    /// Copies `other`'s vectors in (both hold the same number).
    pub fn copy_from(&mut self, other: &Soa) {
        self.x.copy_from_slice(&other.x);
        self.y.copy_from_slice(&other.y);
        self.z.copy_from_slice(&other.z);
    }

    /// Vector `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// Sets vector `i`.
    #[inline]
    pub fn set(&mut self, i: usize, v: Vec3) {
        (self.x[i], self.y[i], self.z[i]) = (v.x, v.y, v.z);
    }

    /// The coordinates of each vector, in order, for writing.
    pub fn iter_mut(&mut self) -> impl Iterator<Item = (&mut f32, &mut f32, &mut f32)> {
        self.x
            .iter_mut()
            .zip(self.y.iter_mut())
            .zip(self.z.iter_mut())
            .map(|((x, y), z)| (x, y, z))
    }

    /// The vectors in order.
    pub fn iter(&self) -> impl Iterator<Item = Vec3> + '_ {
        self.x
            .iter()
            .zip(&self.y)
            .zip(&self.z)
            .map(|((x, y), z)| Vec3::new(*x, *y, *z))
    }
}
