//! Welding a mesh split along its seams: exporters and Bevy's own shapes give a vertex one copy per
//! texture coordinate or normal it takes, so a closed sphere arrives as a surface open along its
//! seam and at its poles. [`ClothModel::weld_seams`] joins the copies for the simulation.

use glam::Vec3;

use super::ClothModel;

/// How close (a fraction of the rest shape's bounding-box diagonal) two vertices must be to count
/// as copies of one: far below any edge of a mesh a cloth is made of, and above the rounding
/// of the trigonometry that places a seam's two copies.
const SEAM_TOLERANCE: f32 = 1e-5;

impl ClothModel {
    /// This model with the vertices its mesh split along texture or normal seams (copies at the
    /// same position, within 1e-5 times the rest shape's bounding-box diagonal) welded into one
    /// particle, when that makes it a closed surface ([`check_closed`](Self::check_closed)): the
    /// welded model (built again from its faces, with the first copy's texture coordinates and
    /// default masses) and, for each vertex of this model, its particle in the welded one. `None`
    /// when no vertices are copies, or the welded surface is not closed either (an open cloth
    /// keeps its seams).
    pub fn weld_seams(&self) -> Option<(ClothModel, Vec<u32>)> {
        let first = first_copies(&self.rest_positions);
        if first.iter().enumerate().all(|(i, &f)| f as usize == i) {
            return None;
        }
        let mut particle_of = vec![u32::MAX; first.len()];
        let (mut positions, mut uvs) = (Vec::new(), Vec::new());
        for (i, &f) in first.iter().enumerate() {
            if f as usize == i {
                particle_of[i] = positions.len() as u32;
                positions.push(self.rest_positions[i]);
                uvs.push(self.uvs.get(i).copied().unwrap_or_default());
            }
        }
        let particle_of: Vec<u32> = first.iter().map(|&f| particle_of[f as usize]).collect();
        let faces: Vec<u32> = self
            .faces
            .iter()
            .map(|&v| particle_of[v as usize])
            .collect();
        let welded = ClothModel::from_mesh(&positions, Some(&uvs), &faces, self.face_size).ok()?;
        welded.check_closed().ok()?;
        Some((welded, particle_of))
    }
}

/// For each point, the first point (lowest index) within [`SEAM_TOLERANCE`] of the points' size
/// of it, through chains of such points (itself when it has none before it).
fn first_copies(points: &[Vec3]) -> Vec<u32> {
    let (lo, hi) = points.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), p| (lo.min(*p), hi.max(*p)),
    );
    let tolerance = SEAM_TOLERANCE * (hi - lo).length();
    let mut first: Vec<u32> = (0..points.len() as u32).collect();
    fn root(first: &mut [u32], mut i: u32) -> u32 {
        while first[i as usize] != i {
            let up = first[first[i as usize] as usize];
            first[i as usize] = up;
            i = up;
        }
        i
    }
    // Sorted along x, each point is compared with those after it until x is out of reach.
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    order.sort_by(|&a, &b| points[a as usize].x.total_cmp(&points[b as usize].x));
    for (k, &a) in order.iter().enumerate() {
        let p = points[a as usize];
        for &b in &order[k + 1..] {
            let q = points[b as usize];
            if q.x - p.x > tolerance {
                break;
            }
            if p.distance(q) <= tolerance {
                let (ra, rb) = (root(&mut first, a), root(&mut first, b));
                let (keep, joined) = (ra.min(rb), ra.max(rb));
                first[joined as usize] = keep;
            }
        }
    }
    (0..points.len() as u32)
        .map(|i| root(&mut first, i))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_join_the_first_of_them_through_chains() {
        let e = 1e-7;
        let points = [
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0 + e, 0.0, 0.0),
            Vec3::new(0.0, 1.0, e),
            Vec3::new(1.0 + 2.0 * e, 0.0, 0.0),
            Vec3::new(0.5, 0.5, 0.0),
        ];
        assert_eq!(first_copies(&points), [0, 1, 0, 1, 0, 5]);
    }
}
