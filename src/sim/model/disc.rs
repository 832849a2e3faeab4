//! The round cloth: a flat quad disc around one extraordinary vertex ([`DiscSpec`],
//! [`ClothModel::disc`]), the shape of a tablecloth. Topology and rest shape only, built once; the
//! springs come from [`ClothModel::from_mesh`] like any quad mesh's.

use std::f32::consts::PI;

use bevy::reflect::Reflect;
use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::ClothModel;
use crate::error::{ClothError, count_in, particles_within, positive};

/// Smallest [`DiscSpec::sectors`].
pub const MIN_DISC_SECTORS: u32 = 3;
/// Largest [`DiscSpec::sectors`].
pub const MAX_DISC_SECTORS: u32 = 16;
/// Largest [`DiscSpec::rings`].
pub const MAX_DISC_RINGS: u32 = 512;

/// A round, flat quad cloth of radius `radius` in the local XZ plane, facing +Y, centred on the
/// origin: `sectors` quad patches of `rings` × `rings` quads each meet at the centre, so the centre
/// particle is an interior vertex of valence `sectors` (extraordinary unless `sectors` is 4) and
/// every other interior particle has valence 4.
///
/// Each patch is the wedge between two spokes, mapped from the unit square by the concentric
/// square-to-disc map: the patch point `(u, v) = (k, l) / rings` sits at radius
/// `radius · max(u, v)`, at the angle of its first spoke plus `Δ/2 · v/u` when `u ≥ v`, and at
/// the second spoke's angle minus `Δ/2 · u/v` otherwise (`Δ = 2π / sectors`). So ring `k` has
/// `2k` particles per sector and the edges along the hem are about `π / (sectors · rings)` of the
/// radius long, against `1 / rings` along the spokes. The hem is a circle through the outermost
/// particles; where two sides of a patch meet on it (its corner opposite the centre) is a
/// boundary particle with only two edges, so render the disc with
/// [`BoundaryMode::EdgeOnly`](crate::subdivision::BoundaryMode::EdgeOnly) for a smooth hem.
///
/// Particle indices: 0 is the centre; sector `s` (0-based, counter-clockwise seen from below, i.e.
/// from +X towards +Z) owns the patch points `(k, l)` with `k` in `1..=rings` and `l` in
/// `0..=rings`, at `1 + s·rings·(rings+1) + (k−1)·(rings+1) + l` ([`DiscSpec::index`]); its points
/// `(0, l)` are the next sector's `(l, 0)`. Texture coordinates map the disc's bounding square onto
/// the unit square.
///
/// # Example
/// ```
/// use bevy_cloth::sim::{ClothModel, DiscSpec};
///
/// let spec = DiscSpec::new(5, 8, 0.8);
/// let model = ClothModel::disc(&spec).unwrap();
/// assert_eq!(model.particle_count(), spec.particle_count());
/// assert_eq!(model.face_size, 4);
/// ```
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(deny_unknown_fields)]
pub struct DiscSpec {
    /// Patches around the centre, which is the valence of the centre particle:
    /// [`MIN_DISC_SECTORS`]`..=`[`MAX_DISC_SECTORS`].
    pub sectors: u32,
    /// Quads along each spoke (and along each side of a patch): 1..=[`MAX_DISC_RINGS`], and few
    /// enough that the disc has at most [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES) particles.
    pub rings: u32,
    /// Radius of the hem, m.
    pub radius: f32,
}

impl DiscSpec {
    /// A disc of `sectors` patches with `rings` quads along each spoke and the given radius.
    pub fn new(sectors: u32, rings: u32, radius: f32) -> Self {
        Self {
            sectors,
            rings,
            radius,
        }
    }

    /// Checks the spec; the error names the bad field: `sectors` and `rings` in their ranges,
    /// at most [`MAX_PARTICLES`](crate::sim::MAX_PARTICLES) particles in all (so 16 sectors take
    /// at most 255 rings), and a finite, positive `radius`.
    pub fn validate(&self) -> Result<(), ClothError> {
        count_in("sectors", self.sectors, MIN_DISC_SECTORS, MAX_DISC_SECTORS)?;
        count_in("rings", self.rings, 1, MAX_DISC_RINGS)?;
        particles_within(self.particle_count() as u64, || {
            format!(
                "a disc of sectors = {} and rings = {} has 1 + sectors · rings · (rings + 1)",
                self.sectors, self.rings
            )
        })?;
        positive("radius", self.radius)
    }

    /// Number of particles: `1 + sectors · rings · (rings + 1)`.
    pub fn particle_count(&self) -> usize {
        let a = self.rings as usize;
        1 + self.sectors as usize * a * (a + 1)
    }

    /// Index of patch point `(k, l)` (each in `0..=rings`) of sector `sector` (taken modulo
    /// `sectors`): 0 for the centre, the next sector's `(l, 0)` for `k = 0`.
    pub fn index(&self, sector: u32, k: u32, l: u32) -> u32 {
        let (n, a) = (self.sectors.max(1), self.rings);
        let sector = sector % n;
        match (k, l) {
            (0, 0) => 0,
            (0, l) => self.index(sector + 1, l, 0),
            (k, l) => 1 + sector * a * (a + 1) + (k - 1) * (a + 1) + l,
        }
    }

    /// The particles on the hem (the outer circle), going round once.
    pub fn hem(&self) -> impl Iterator<Item = u32> + '_ {
        let a = self.rings;
        (0..self.sectors).flat_map(move |s| {
            (0..a)
                .map(move |l| self.index(s, a, l))
                .chain((1..=a).rev().map(move |k| self.index(s, k, a)))
        })
    }

    /// Rest position of patch point `(k, l)` of `sector`, in the cloth's local space.
    fn position(&self, sector: u32, k: u32, l: u32) -> Vec3 {
        let a = self.rings as f32;
        let (u, v) = (k as f32 / a, l as f32 / a);
        let s = u.max(v);
        if s == 0.0 {
            return Vec3::ZERO;
        }
        let wedge = 2.0 * PI / self.sectors as f32;
        let start = sector as f32 * wedge;
        let angle = if u >= v {
            start + 0.5 * wedge * v / u
        } else {
            start + wedge - 0.5 * wedge * u / v
        };
        let r = self.radius * s;
        Vec3::new(r * angle.cos(), 0.0, r * angle.sin())
    }
}

impl ClothModel {
    /// Builds the round quad cloth of a [`DiscSpec`] (through [`ClothModel::from_mesh`]: structural
    /// springs on the quads' edges, shear springs on their diagonals, bend springs across edges).
    /// Each quad is listed so that its first diagonal, along which it is split into triangles,
    /// runs outwards from the corner nearest the centre; the quads face +Y.
    pub fn disc(spec: &DiscSpec) -> Result<Self, ClothError> {
        spec.validate()?;
        let (n, a) = (spec.sectors, spec.rings);
        let count = spec.particle_count();
        let mut positions = vec![Vec3::ZERO; count];
        for s in 0..n {
            for k in 1..=a {
                for l in 0..=a {
                    positions[spec.index(s, k, l) as usize] = spec.position(s, k, l);
                }
            }
        }
        let uvs: Vec<Vec2> = positions
            .iter()
            .map(|p| Vec2::new(0.5 + 0.5 * p.x / spec.radius, 0.5 + 0.5 * p.z / spec.radius))
            .collect();
        let mut quads = Vec::with_capacity((n * a * a * 4) as usize);
        for s in 0..n {
            for k in 0..a {
                for l in 0..a {
                    quads.extend_from_slice(&[
                        spec.index(s, k, l),
                        spec.index(s, k, l + 1),
                        spec.index(s, k + 1, l + 1),
                        spec.index(s, k + 1, l),
                    ]);
                }
            }
        }
        Self::from_mesh(&positions, Some(&uvs), &quads, 4)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::compute_normals;

    fn valences(model: &ClothModel) -> Vec<usize> {
        let mut neighbours = vec![Vec::new(); model.particle_count()];
        for q in model.faces.chunks_exact(4) {
            for c in 0..4 {
                let (a, b) = (q[c] as usize, q[(c + 1) % 4] as usize);
                neighbours[a].push(b);
                neighbours[b].push(a);
            }
        }
        neighbours
            .into_iter()
            .map(|mut v| {
                v.sort_unstable();
                v.dedup();
                v.len()
            })
            .collect()
    }

    #[test]
    fn the_centre_has_the_valence_of_the_sector_count() {
        for sectors in [3, 5, 6, 8] {
            let spec = DiscSpec::new(sectors, 4, 1.0);
            let m = ClothModel::disc(&spec).unwrap();
            assert_eq!(m.particle_count(), 1 + sectors as usize * 4 * 5);
            assert_eq!(m.faces.len(), sectors as usize * 16 * 4);
            let v = valences(&m);
            assert_eq!(v[0], sectors as usize);
            let hem: Vec<u32> = spec.hem().collect();
            assert_eq!(hem.len(), 2 * 4 * sectors as usize);
            for (i, &valence) in v.iter().enumerate().skip(1) {
                let on_hem = hem.contains(&(i as u32));
                // Interior particles are regular; hem particles have 3 edges, or 2 at a patch's
                // outer corner.
                if on_hem {
                    assert!(valence == 3 || valence == 2, "hem particle {i}: {valence}");
                } else {
                    assert_eq!(valence, 4, "particle {i}");
                }
            }
        }
    }

    #[test]
    fn the_disc_is_round_flat_and_faces_up() {
        let spec = DiscSpec::new(6, 6, 0.8);
        let m = ClothModel::disc(&spec).unwrap();
        for i in spec.hem() {
            let p = m.rest_positions[i as usize];
            assert!((p.length() - 0.8).abs() < 1e-5, "hem particle {i} at {p}");
        }
        assert!(
            m.rest_positions
                .iter()
                .all(|p| p.y == 0.0 && p.length() <= 0.8 + 1e-5)
        );
        let mut normals = vec![Vec3::ZERO; m.particle_count()];
        compute_normals(&m.rest_positions, &m.triangles, &mut normals);
        assert!(normals.iter().all(|n| (*n - Vec3::Y).length() < 1e-5));
        // Every triangle has area: no particle twice, no sliver along the hem.
        let p = &m.rest_positions;
        for t in m.triangles.chunks_exact(3) {
            let area = 0.5
                * (p[t[1] as usize] - p[t[0] as usize])
                    .cross(p[t[2] as usize] - p[t[0] as usize])
                    .length();
            assert!(area > 1e-4, "triangle {t:?} has area {area}");
        }
        // The area adds up to (nearly) the circle's.
        let total: f32 = m
            .triangles
            .chunks_exact(3)
            .map(|t| {
                0.5 * (p[t[1] as usize] - p[t[0] as usize])
                    .cross(p[t[2] as usize] - p[t[0] as usize])
                    .length()
            })
            .sum();
        let circle = PI * 0.8 * 0.8;
        assert!(
            total < circle && total > 0.97 * circle,
            "{total} vs {circle}"
        );
    }

    #[test]
    fn the_control_mesh_subdivides() {
        let m = ClothModel::disc(&DiscSpec::new(5, 3, 1.0)).unwrap();
        let mesh = m.control_mesh().unwrap();
        assert!(mesh.is_all_quads());
        assert_eq!(mesh.face_count(), 5 * 9);
    }

    #[test]
    fn bad_specs_name_the_field() {
        for (spec, field) in [
            (DiscSpec::new(2, 4, 1.0), "sectors"),
            (DiscSpec::new(17, 4, 1.0), "sectors"),
            (DiscSpec::new(5, 0, 1.0), "rings"),
            (DiscSpec::new(5, 4, 0.0), "radius"),
            (DiscSpec::new(5, 4, f32::NAN), "radius"),
        ] {
            let e = ClothModel::disc(&spec).unwrap_err();
            assert!(e.to_string().contains(field), "{e}");
        }
    }
}
