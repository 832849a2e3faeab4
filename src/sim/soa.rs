//! [`Soa`]: particle vectors stored one array per coordinate, the layout every vector kernel of
//! the solver reads and writes.

use glam::Vec3;

/// Particle positions or forces, one array per coordinate, so that kernels can read and write
/// eight consecutive particles with whole vector loads and stores.
#[derive(Debug, Clone, Default)]
pub(crate) struct Soa {
    pub x: Coordinate,
    pub y: Coordinate,
    pub z: Coordinate,
}

/// Values per 4 KiB page.
const PAGE: usize = 1024;

/// How far apart, in values, the columns of [`Soa::spread`] start within their pages (448 bytes).
const STAGGER: usize = 112;

/// A page of values, aligned to its size, so that a [`Coordinate`] knows where its values start
/// within a page.
#[derive(Clone, Copy)]
#[repr(C, align(4096))]
struct Page([f32; PAGE]);

/// One coordinate of a [`Soa`]: `len` values starting `offset` values into page-aligned storage,
/// used as a slice. Columns that a kernel reads and writes at the same indices start at different
/// places within a page ([`Soa::spread`]): where their starts share the low 12 address bits, a
/// store to one column looks, to the CPU, like a store to the address of a later load from
/// another at a nearby index (4K aliasing), and each such load waits. The results are the same
/// either way; only the time differs.
#[derive(Clone, Default)]
pub(crate) struct Coordinate {
    pages: Vec<Page>,
    offset: usize,
    len: usize,
}

impl Coordinate {
    /// `n` zeros, starting `offset` (under [`PAGE`]) values into the first page.
    fn zeros(n: usize, offset: usize) -> Self {
        let mut c = Self {
            pages: Vec::new(),
            offset: offset % PAGE,
            len: 0,
        };
        c.resize(n);
        c
    }

    /// Makes it hold `n` values (new ones zero), keeping its allocation where it suffices.
    pub fn resize(&mut self, n: usize) {
        let pages = (self.offset + n).div_ceil(PAGE);
        if pages > self.pages.len() {
            self.pages.resize(pages, Page([0.0; PAGE]));
        }
        let old = self.len;
        self.len = n;
        if n > old {
            self[old..].fill(0.0);
        }
    }

    /// All the storage's values.
    #[inline(always)]
    fn all(&self) -> &[f32] {
        // SAFETY: a `Page` is an array of `PAGE` f32 with no padding (`repr(C)`, its size a
        // multiple of its alignment), and a `Vec`'s pages lie one after another.
        unsafe {
            std::slice::from_raw_parts(self.pages.as_ptr().cast::<f32>(), self.pages.len() * PAGE)
        }
    }

    /// All the storage's values, to write.
    #[inline(always)]
    fn all_mut(&mut self) -> &mut [f32] {
        // SAFETY: as in `all`; the borrow is exclusive.
        unsafe {
            std::slice::from_raw_parts_mut(
                self.pages.as_mut_ptr().cast::<f32>(),
                self.pages.len() * PAGE,
            )
        }
    }
}

impl std::ops::Deref for Coordinate {
    type Target = [f32];
    #[inline(always)]
    fn deref(&self) -> &[f32] {
        let (offset, len) = (self.offset, self.len);
        &self.all()[offset..offset + len]
    }
}

impl std::ops::DerefMut for Coordinate {
    #[inline(always)]
    fn deref_mut(&mut self) -> &mut [f32] {
        let (offset, len) = (self.offset, self.len);
        &mut self.all_mut()[offset..offset + len]
    }
}

impl<'a> IntoIterator for &'a Coordinate {
    type Item = &'a f32;
    type IntoIter = std::slice::Iter<'a, f32>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter()
    }
}

impl<'a> IntoIterator for &'a mut Coordinate {
    type Item = &'a mut f32;
    type IntoIter = std::slice::IterMut<'a, f32>;
    fn into_iter(self) -> Self::IntoIter {
        self.iter_mut()
    }
}

impl PartialEq for Coordinate {
    /// The same values (wherever they are stored).
    fn eq(&self, other: &Self) -> bool {
        **self == **other
    }
}

impl std::fmt::Debug for Coordinate {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        (**self).fmt(f)
    }
}

impl Soa {
    /// `n` zero vectors.
    pub fn new(n: usize) -> Self {
        Self::spread(n, 0)
    }

    /// `n` zero vectors whose columns start [`STAGGER`] values apart within their pages, after
    /// those of `group` other `Soa`s (see [`Coordinate`]).
    pub fn spread(n: usize, group: usize) -> Self {
        let column = |c: usize| Coordinate::zeros(n, (3 * group + c) * STAGGER);
        Self {
            x: column(0),
            y: column(1),
            z: column(2),
        }
    }

    /// Makes it hold `n` vectors (new ones zero), keeping its allocation where it suffices.
    pub fn resize(&mut self, n: usize) {
        for a in [&mut self.x, &mut self.y, &mut self.z] {
            a.resize(n);
        }
    }

    /// Coordinate `c` (0, 1, 2: x, y, z) of every vector.
    pub fn coordinate(&self, c: usize) -> &[f32] {
        [&self.x, &self.y, &self.z][c]
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
    #[inline(always)]
    pub fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// Sets vector `i`.
    #[inline(always)]
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_states_columns_start_at_different_places_within_a_page() {
        let starts: Vec<usize> = (0..3)
            .flat_map(|group| {
                let s = Soa::spread(5000, group);
                [s.x, s.y, s.z].map(|c| c.as_ptr() as usize % 4096)
            })
            .collect();
        for (k, &start) in starts.iter().enumerate() {
            assert_eq!(start, k * STAGGER * 4 % 4096, "column {k}");
        }
    }

    #[test]
    fn a_coordinate_resizes_as_a_vec_does() {
        let mut c = Coordinate::zeros(3, 1000);
        c.copy_from_slice(&[1.0, 2.0, 3.0]);
        c.resize(30);
        assert_eq!(c[..4], [1.0, 2.0, 3.0, 0.0]);
        assert!(c[3..].iter().all(|&v| v == 0.0));
        c.resize(2);
        c.resize(5);
        assert_eq!(*c, [1.0, 2.0, 0.0, 0.0, 0.0]);
        assert_eq!(c.as_ptr() as usize % 4096, 4000);
    }
}
