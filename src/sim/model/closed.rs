//! Closed cloths, the ones that can hold air ([`Pressure`](crate::sim::Pressure)): the check that
//! a model is a closed surface wound outward ([`ClothModel::check_closed`]), the volume it
//! encloses and its gradient ([`volume_gradient`]), and two closed shapes built like the grid, an
//! icosphere and a box.

use glam::{Vec2, Vec3};
use std::collections::HashMap;
use std::f32::consts::PI;

use super::ClothModel;
use crate::error::{ClothError, particles_within, positive};

/// The most subdivisions [`ClothModel::icosphere`] takes: 8 gives 655,362 particles, 9 would be
/// past [`MAX_PARTICLES`](super::MAX_PARTICLES).
pub const MAX_ICOSPHERE_SUBDIVISIONS: u32 = 8;

impl ClothModel {
    /// Checks that the model's triangles form a closed surface wound counter-clockwise seen from
    /// outside, and returns the volume it encloses at rest, m³. Every edge must border exactly two
    /// triangles that run it in opposite directions. The error ([`ClothError::NotClosed`]) names
    /// the first edge that borders one triangle (the surface is open there: a hole, or vertices
    /// split along a texture seam that were never welded), or more than two, or the first
    /// triangle wound against its neighbour; a consistently wound surface that encloses a
    /// negative volume is wound inside out. Several closed pieces are one closed surface.
    pub fn check_closed(&self) -> Result<f32, ClothError> {
        let not_closed = |what: String| Err(ClothError::NotClosed { what });
        if self.triangles.is_empty() {
            return not_closed("it has no triangles".into());
        }
        // Each triangle's edges as (smaller, larger, runs from smaller to larger, triangle).
        let mut edges: Vec<(u32, u32, bool, usize)> = Vec::with_capacity(self.triangles.len());
        for (t, tri) in self.triangles.chunks_exact(3).enumerate() {
            for k in 0..3 {
                let (a, b) = (tri[k], tri[(k + 1) % 3]);
                edges.push((a.min(b), a.max(b), a < b, t));
            }
        }
        edges.sort_unstable();
        for group in edges.chunk_by(|p, q| (p.0, p.1) == (q.0, q.1)) {
            let (a, b) = (group[0].0, group[0].1);
            match group {
                [(_, _, _, t)] => {
                    return not_closed(format!(
                        "edge ({a}, {b}) borders only triangle {t}: the surface is open there \
                         (a hole, or vertices split along a texture seam and not welded)"
                    ));
                }
                [(_, _, first, s), (_, _, second, t)] => {
                    if first == second {
                        return not_closed(format!(
                            "triangles {s} and {t} both run edge ({a}, {b}) the same way: one \
                             of them is wound against its neighbours"
                        ));
                    }
                }
                more => {
                    let triangles: Vec<usize> = more.iter().map(|e| e.3).collect();
                    return not_closed(format!(
                        "edge ({a}, {b}) borders {} triangles {triangles:?}",
                        more.len()
                    ));
                }
            }
        }
        let volume = enclosed_volume(&self.triangles, |i| self.rest_positions[i]);
        if volume.is_nan() || volume <= 0.0 {
            return not_closed(format!(
                "it encloses a volume of {volume:e} m³: its triangles wind clockwise seen from \
                 outside (reverse each triangle's order)"
            ));
        }
        Ok(volume as f32)
    }

    /// A sphere of radius `radius` (m) centred on the origin: an icosahedron whose triangles are
    /// split in four `subdivisions` times, its vertices pushed onto the sphere, `10·4ˢ + 2`
    /// particles (642 at 3, 2,562 at 4). Springs as [`from_mesh`](Self::from_mesh) makes them;
    /// texture coordinates by longitude and latitude. Errors: a radius that is not finite and
    /// positive, more than [`MAX_ICOSPHERE_SUBDIVISIONS`].
    pub fn icosphere(radius: f32, subdivisions: u32) -> Result<Self, ClothError> {
        positive("icosphere radius", radius)?;
        Self::icosphere_particle_count(subdivisions)?;
        let phi = (1.0 + 5f32.sqrt()) / 2.0;
        let mut points: Vec<Vec3> = [
            (-1.0, phi, 0.0),
            (1.0, phi, 0.0),
            (-1.0, -phi, 0.0),
            (1.0, -phi, 0.0),
            (0.0, -1.0, phi),
            (0.0, 1.0, phi),
            (0.0, -1.0, -phi),
            (0.0, 1.0, -phi),
            (phi, 0.0, -1.0),
            (phi, 0.0, 1.0),
            (-phi, 0.0, -1.0),
            (-phi, 0.0, 1.0),
        ]
        .iter()
        .map(|&(x, y, z)| Vec3::new(x, y, z).normalize())
        .collect();
        let mut triangles: Vec<u32> = vec![
            0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, 1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7,
            6, 7, 1, 8, 3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, 4, 9, 5, 2, 4, 11, 6, 2, 10,
            8, 6, 7, 9, 8, 1,
        ];
        for _ in 0..subdivisions {
            let mut middles: HashMap<(u32, u32), u32> = HashMap::new();
            let mut middle = |a: u32, b: u32, points: &mut Vec<Vec3>| {
                *middles.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let m = (points[a as usize] + points[b as usize]).normalize();
                    points.push(m);
                    points.len() as u32 - 1
                })
            };
            let mut finer = Vec::with_capacity(triangles.len() * 4);
            for t in triangles.chunks_exact(3) {
                let (a, b, c) = (t[0], t[1], t[2]);
                let ab = middle(a, b, &mut points);
                let bc = middle(b, c, &mut points);
                let ca = middle(c, a, &mut points);
                finer.extend_from_slice(&[a, ab, ca, b, bc, ab, c, ca, bc, ab, bc, ca]);
            }
            triangles = finer;
        }
        let uvs: Vec<Vec2> = points
            .iter()
            .map(|p| {
                Vec2::new(
                    0.5 + p.z.atan2(p.x) / (2.0 * PI),
                    p.y.clamp(-1.0, 1.0).acos() / PI,
                )
            })
            .collect();
        let positions: Vec<Vec3> = points.iter().map(|p| *p * radius).collect();
        Self::from_mesh(&positions, Some(&uvs), &triangles, 3)
    }

    /// The number of particles of an [`icosphere`](Self::icosphere) of `subdivisions`,
    /// `10·4ˢ + 2`, without building it. Errors: more than [`MAX_ICOSPHERE_SUBDIVISIONS`].
    pub fn icosphere_particle_count(subdivisions: u32) -> Result<usize, ClothError> {
        if subdivisions > MAX_ICOSPHERE_SUBDIVISIONS {
            return Err(ClothError::InvalidValue {
                field: "icosphere subdivisions",
                expected: "at most MAX_ICOSPHERE_SUBDIVISIONS (8)",
                value: subdivisions as f64,
            });
        }
        let count = 10 * 4u64.pow(subdivisions) + 2;
        particles_within(count, || {
            format!("an icosphere of {subdivisions} subdivisions")
        })?;
        Ok(count as usize)
    }

    /// A box of size `size` (m, each side positive) centred on the origin, its faces divided into
    /// quads of about `spacing` (m) per side (at least one per side; a cube of side `s` has
    /// `6 (s/spacing)² + 2` particles). Springs as [`from_mesh`](Self::from_mesh) makes them from
    /// quads; each face's texture coordinates run 0 to 1 (an edge's vertices keep one face's).
    pub fn cuboid(size: Vec3, spacing: f32) -> Result<Self, ClothError> {
        positive("cuboid size.x", size.x)?;
        positive("cuboid size.y", size.y)?;
        positive("cuboid size.z", size.z)?;
        positive("cuboid spacing", spacing)?;
        let cells = (size / spacing).round().max(Vec3::ONE);
        if !cells.is_finite() || cells.max_element() > u32::MAX as f32 {
            return Err(ClothError::InvalidValue {
                field: "cuboid spacing",
                expected: "finite cell counts below 2³² per side (and at most MAX_PARTICLES particles)",
                value: spacing as f64,
            });
        }
        let n = [cells.x as u64, cells.y as u64, cells.z as u64];
        // Surface points of the (n+1)³ lattice: all of it but the inside.
        let inside = n.iter().map(|c| c.saturating_sub(1)).product::<u64>();
        let total = n.iter().map(|c| c + 1).product::<u64>() - inside;
        particles_within(total, || {
            format!("a box of {}×{}×{} cells", n[0], n[1], n[2])
        })?;
        let mut index: HashMap<[u32; 3], u32> = HashMap::new();
        let (mut positions, mut uvs, mut quads) = (Vec::new(), Vec::new(), Vec::new());
        for axis in 0..3 {
            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
            for side in [0, n[axis]] {
                for j in 0..n[v] {
                    for i in 0..n[u] {
                        let mut corners = [[0u32; 3]; 4];
                        for (c, (di, dj)) in
                            corners.iter_mut().zip([(0, 0), (1, 0), (1, 1), (0, 1)])
                        {
                            c[axis] = side as u32;
                            c[u] = (i + di) as u32;
                            c[v] = (j + dj) as u32;
                        }
                        // Counter-clockwise in (u, v) faces +axis: outward on the far side.
                        if side == 0 {
                            corners.reverse();
                        }
                        for c in corners {
                            let k = *index.entry(c).or_insert_with(|| {
                                let cell = Vec3::new(c[0] as f32, c[1] as f32, c[2] as f32);
                                positions.push((cell / cells - 0.5) * size);
                                uvs.push(Vec2::new(
                                    c[u] as f32 / n[u] as f32,
                                    c[v] as f32 / n[v] as f32,
                                ));
                                positions.len() as u32 - 1
                            });
                            quads.push(k);
                        }
                    }
                }
            }
        }
        Self::from_mesh(&positions, Some(&uvs), &quads, 4)
    }
}

/// The volume enclosed by the closed surface `triangles` (wound counter-clockwise seen from
/// outside) at positions `x(i)`, m³, with its gradient `∂V/∂x` written to `gradient` (one entry
/// per particle, all overwritten). `V = ⅙ Σ (x_a − o) · ((x_b − x_a) × (x_c − x_a))` for any point
/// `o`, and each corner's gradient gets a sixth of its triangle's doubled area vector, so one
/// cross product per triangle serves both.
pub(crate) fn volume_gradient(
    triangles: &[u32],
    x: impl Fn(usize) -> Vec3,
    gradient: &mut [Vec3],
) -> f64 {
    gradient.fill(Vec3::ZERO);
    volume_with(triangles, x, |[a, b, c], g| {
        gradient[a] += g;
        gradient[b] += g;
        gradient[c] += g;
    })
}

/// The volume enclosed by the closed surface `triangles` at positions `x(i)`, m³ (see
/// [`volume_gradient`]).
pub(crate) fn enclosed_volume(triangles: &[u32], x: impl Fn(usize) -> Vec3) -> f64 {
    volume_with(triangles, x, |_, _| {})
}

/// The enclosed volume, handing each triangle's corners and its share of the gradient to
/// `corners`. Summed in f64 about the first triangle's first corner, so a cloth far from the
/// origin loses no digits to its distance.
fn volume_with(
    triangles: &[u32],
    x: impl Fn(usize) -> Vec3,
    mut corners: impl FnMut([usize; 3], Vec3),
) -> f64 {
    let Some(&first) = triangles.first() else {
        return 0.0;
    };
    let origin = x(first as usize);
    // Four running sums, so that each triangle's addition does not wait for the one before.
    let mut six_v = [0.0f64; 4];
    for (k, t) in triangles.chunks_exact(3).enumerate() {
        let (a, b, c) = (t[0] as usize, t[1] as usize, t[2] as usize);
        let (pa, pb, pc) = (x(a), x(b), x(c));
        let area2 = (pb - pa).cross(pc - pa);
        six_v[k % 4] += (pa - origin).dot(area2) as f64;
        corners([a, b, c], area2 * (1.0 / 6.0));
    }
    (six_v[0] + six_v[1] + (six_v[2] + six_v[3])) / 6.0
}
