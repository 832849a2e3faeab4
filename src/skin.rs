//! Where a character cloth's weighted particles should be: each one's animated target (position
//! and surface normal), from the cloth's skin by linear-blend skinning on the CPU, or from its
//! rest shape under the cloth's transform. ECS-free: the plugin passes in the joints' and the
//! cloth's global transforms and hands the result to [`crate::sim::ClothSim`] as pins (weight 0)
//! and targets (weight > 0).

use bevy::math::{Affine3A, Mat4, Vec3};
use bevy::mesh::{Mesh, VertexAttributeValues};

use crate::error::ClothError;
use crate::sim::Target;

/// Up to four joints (index into the skin's joint list) and their weights, which sum to 1.
pub(crate) type Influences = [(u16, f32); 4];

/// A cloth's weighted particles with their rest shape and, when skinned, their influences.
#[derive(Debug, Clone)]
pub(crate) struct Attachment {
    /// Each weighted particle and its weight, in the order of the other lists.
    pub weighted: Vec<(u32, f32)>,
    /// Rest position and normal of each, in the space the skin or transform maps from.
    rest: Vec<(Vec3, Vec3)>,
    /// The skin: each particle's influences, and the joints' inverse bind poses.
    skin: Option<(Vec<Influences>, Vec<Affine3A>)>,
    /// The joints' skinning matrices of the last update (a missing joint keeps its last one).
    joint_matrices: Vec<Affine3A>,
    /// The transform of the last update, for targets that are not skinned.
    transform: Option<Affine3A>,
    /// Each particle's target (position, unit normal) after [`Self::update`].
    pub targets: Vec<(Vec3, Vec3)>,
}

impl Attachment {
    /// The particles of a cloth whose `weights` (one per particle; `None` leaves a particle
    /// free) are given, at rest positions `rest` with normals `normals`, skinned by `skin` (each
    /// particle's influences and the joints' inverse bind poses) when given.
    pub fn new(
        weights: &[Option<f32>],
        (rest, normals): (&[Vec3], &[Vec3]),
        skin: Option<(Vec<Influences>, &[Mat4])>,
    ) -> Result<Self, ClothError> {
        let mut weighted = Vec::new();
        for (i, w) in weights.iter().enumerate() {
            if let Some(w) = *w {
                crate::error::non_negative("target weight", w)?;
                weighted.push((i as u32, w));
            }
        }
        let skin = match skin {
            None => None,
            Some((influences, inverse_bindposes)) => {
                if influences.len() != weights.len() {
                    return Err(targets_error(format!(
                        "{} vertices have joint influences, but the cloth has {}",
                        influences.len(),
                        weights.len()
                    )));
                }
                let joints = inverse_bindposes.len();
                let mut chosen = Vec::with_capacity(weighted.len());
                for &(i, _) in &weighted {
                    let inf = influences[i as usize];
                    if let Some(&(j, _)) =
                        inf.iter().find(|(j, w)| *w > 0.0 && *j as usize >= joints)
                    {
                        return Err(targets_error(format!(
                            "vertex {i} names joint {j}, but the skin has {joints}"
                        )));
                    }
                    chosen.push(inf);
                }
                let bind = inverse_bindposes
                    .iter()
                    .map(|m| Affine3A::from_mat4(*m))
                    .collect::<Vec<_>>();
                if let Some(j) = bind.iter().position(|m| !m.is_finite()) {
                    return Err(targets_error(format!(
                        "the inverse bind pose of joint {j} is not finite"
                    )));
                }
                Some((chosen, bind))
            }
        };
        let rest = weighted
            .iter()
            .map(|&(i, _)| (rest[i as usize], normals[i as usize]))
            .collect::<Vec<_>>();
        // Until a joint is first found, its matrix is the identity's: the bind pose.
        let joint_matrices = skin
            .as_ref()
            .map_or_else(Vec::new, |(_, bind)| bind.clone());
        Ok(Self {
            targets: rest.clone(),
            weighted,
            rest,
            skin,
            joint_matrices,
            transform: None,
        })
    }

    /// The particles with a maximum distance (weight > 0), in order, with their targets as
    /// [`ClothSim::set_targets`](crate::sim::ClothSim::set_targets) takes them.
    pub fn limited(&self) -> impl Iterator<Item = Target> + '_ {
        self.all().filter(|t| t.weight > 0.0)
    }

    /// Whether the targets are skinned (rather than the rest shape under the cloth's transform).
    pub fn is_skinned(&self) -> bool {
        self.skin.is_some()
    }

    /// The map from rest to world space of entry `k` as of the last [`Self::update`]: its
    /// blended skin matrices (the identity without a skin, where the transform maps it).
    pub fn carrier(&self, k: usize) -> Affine3A {
        match &self.skin {
            Some((influences, _)) => blend(&self.joint_matrices, &influences[k]),
            None => Affine3A::IDENTITY,
        }
    }

    /// Every weighted particle with its target.
    pub fn all(&self) -> impl Iterator<Item = Target> + '_ {
        self.weighted
            .iter()
            .zip(&self.targets)
            .map(|(&(particle, weight), &(position, normal))| Target {
                particle,
                weight,
                position,
                normal,
            })
    }

    /// Gives each copy a tear made (`(particle, copy)`, in order) its particle's weight, rest
    /// shape, influences and target, after the weighted particles it has.
    pub fn add_copies(&mut self, copies: impl IntoIterator<Item = (u32, u32)>) {
        // The next update computes every target.
        self.transform = None;
        for (particle, copy) in copies {
            let Some(k) = self.weighted.iter().position(|&(p, _)| p == particle) else {
                continue;
            };
            self.weighted.push((copy, self.weighted[k].1));
            self.rest.push(self.rest[k]);
            self.targets.push(self.targets[k]);
            if let Some((influences, _)) = &mut self.skin {
                influences.push(influences[k]);
            }
        }
    }

    /// Keeps the weighted particles for which `keep(particle, weight)` holds, drops the others.
    pub fn retain(&mut self, keep: impl Fn(u32, f32) -> bool) {
        self.transform = None;
        let kept: Vec<bool> = self.weighted.iter().map(|&(p, w)| keep(p, w)).collect();
        retain_by(&mut self.weighted, &kept);
        retain_by(&mut self.rest, &kept);
        retain_by(&mut self.targets, &kept);
        if let Some((influences, _)) = &mut self.skin {
            retain_by(influences, &kept);
        }
    }

    /// Computes every target: skinned, with each joint's global transform from `joint`
    /// (`None`, a missing joint, keeps the pose it last had, or the identity if it never had
    /// one), or otherwise the rest shape under `transform`. Returns whether they moved: with
    /// the joints (or the transform) where they were, nothing is computed.
    pub fn update(
        &mut self,
        transform: &Affine3A,
        joint: impl Fn(usize) -> Option<Affine3A>,
    ) -> bool {
        let Some((influences, bind)) = &self.skin else {
            if self.transform == Some(*transform) {
                return false;
            }
            self.transform = Some(*transform);
            let normal_matrix = transform.matrix3.inverse().transpose();
            for (t, (p, n)) in self.targets.iter_mut().zip(&self.rest) {
                *t = (
                    transform.transform_point3(*p),
                    normal_matrix.mul_vec3(*n).normalize_or_zero(),
                );
            }
            return true;
        };
        // A joint that is missing (its entity despawned) keeps its last matrix, so the targets
        // it moves stay where they were.
        let mut moved = self.transform.is_none();
        self.transform = Some(*transform);
        for (j, (m, b)) in self.joint_matrices.iter_mut().zip(bind).enumerate() {
            if let Some(pose) = joint(j) {
                let next = pose * *b;
                moved |= next != *m;
                *m = next;
            }
        }
        if moved {
            for ((t, (p, n)), inf) in self.targets.iter_mut().zip(&self.rest).zip(influences) {
                *t = skin_point(&self.joint_matrices, inf, *p, *n);
            }
        }
        moved
    }
}

/// Keeps the entries of `list` whose `kept` (one per entry) is true.
fn retain_by<T>(list: &mut Vec<T>, kept: &[bool]) {
    let mut k = 0;
    list.retain(|_| {
        k += 1;
        kept[k - 1]
    });
}

/// The linear-blend skinned position and unit normal of a vertex at `p` with normal `n`:
/// `Σ w · M_j · p`, the normal by the blended matrices' linear parts (their inverse transpose,
/// for non-uniform scale).
fn skin_point(matrices: &[Affine3A], influences: &Influences, p: Vec3, n: Vec3) -> (Vec3, Vec3) {
    let blend = blend(matrices, influences);
    let normal = blend.matrix3.inverse().transpose().mul_vec3(n);
    (blend.transform_point3(p), normal.normalize_or_zero())
}

/// `Σ w · M_j` over a vertex's influences.
fn blend(matrices: &[Affine3A], influences: &Influences) -> Affine3A {
    let mut blend = Affine3A::ZERO;
    for &(j, w) in influences {
        if w > 0.0 {
            let m = matrices[j as usize];
            blend.matrix3 += m.matrix3 * w;
            blend.translation += m.translation * w;
        }
    }
    blend
}

/// A [`ClothError`] about a cloth's targets.
fn targets_error(what: String) -> ClothError {
    ClothError::InvalidTargets { what }
}

/// Each vertex's skin influences from `mesh`'s joint index and weight attributes, weights scaled
/// to sum to 1.
pub(crate) fn influences_from_mesh(mesh: &Mesh) -> Result<Vec<Influences>, ClothError> {
    let indices = match mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_INDEX) {
        Ok(Some(VertexAttributeValues::Uint16x4(j))) => j.clone(),
        _ => {
            return Err(targets_error(
                "a skinned cloth's mesh needs joint indices (Uint16x4)".into(),
            ));
        }
    };
    let weights = match mesh.try_attribute_option(Mesh::ATTRIBUTE_JOINT_WEIGHT) {
        Ok(Some(VertexAttributeValues::Float32x4(w))) => w.clone(),
        _ => {
            return Err(targets_error(
                "a skinned cloth's mesh needs joint weights (Float32x4)".into(),
            ));
        }
    };
    indices
        .iter()
        .zip(&weights)
        .enumerate()
        .map(|(v, (j, w))| {
            let sum: f32 = w.iter().sum();
            if !(w.iter().all(|w| w.is_finite() && *w >= 0.0) && sum > 0.0) {
                return Err(targets_error(format!(
                    "vertex {v} has joint weights {w:?} (they must be finite, non-negative, and not all 0)"
                )));
            }
            Ok(std::array::from_fn(|k| (j[k], w[k] / sum)))
        })
        .collect()
}

/// One weight per vertex from a float attribute of `mesh` named `name`, or from channel
/// `channel` (0 red … 3 alpha) of its vertex colours when `name` is `None`.
pub(crate) fn weights_from_mesh(
    mesh: &Mesh,
    name: Option<&str>,
    channel: usize,
) -> Result<Vec<f32>, ClothError> {
    let values = match name {
        None => mesh
            .try_attribute_option(Mesh::ATTRIBUTE_COLOR)
            .ok()
            .flatten(),
        Some(name) => mesh
            .attributes()
            .find(|(a, _)| a.name == name)
            .map(|(_, v)| v),
    };
    let what = name.unwrap_or("COLOR_0");
    if channel > 3 {
        return Err(targets_error(format!(
            "colour channel {channel} (0 red, 1 green, 2 blue, 3 alpha)"
        )));
    }
    match values {
        Some(VertexAttributeValues::Float32(w)) if name.is_some() => Ok(w.clone()),
        Some(VertexAttributeValues::Float32x4(c)) => {
            Ok(c.iter().map(|c| c[channel.min(3)]).collect())
        }
        Some(VertexAttributeValues::Float32x3(c)) if channel < 3 => {
            Ok(c.iter().map(|c| c[channel]).collect())
        }
        Some(other) => Err(targets_error(format!(
            "weights from {what} (channel {channel}): unsupported format {}",
            other.enum_variant_name()
        ))),
        None => Err(targets_error(format!("the mesh has no {what} attribute"))),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use bevy::math::Quat;

    #[test]
    fn skinning_blends_the_joint_matrices() {
        // Two joints: one moved up by 1, one turned 90° about Z; a vertex weighted half and half.
        let bind = [
            Mat4::IDENTITY,
            Mat4::from_translation(Vec3::new(-1.0, 0.0, 0.0)),
        ];
        let influences = vec![[(0, 0.5), (1, 0.5), (0, 0.0), (0, 0.0)]];
        let mut a = Attachment::new(
            &[Some(0.5)],
            (&[Vec3::new(1.0, 0.0, 0.0)], &[Vec3::Y]),
            Some((influences, &bind)),
        )
        .unwrap();
        let joints = [
            Affine3A::from_translation(Vec3::Y),
            Affine3A::from_rotation_translation(
                Quat::from_rotation_z(std::f32::consts::FRAC_PI_2),
                Vec3::new(1.0, 0.0, 0.0),
            ),
        ];
        a.update(&Affine3A::IDENTITY, |j| Some(joints[j]));
        // Joint 0 takes (1,0,0) to (1,1,0); joint 1 (bind at x = 1) takes it to the origin of its
        // frame, turned: (1,0,0). Half of each: (1, 0.5, 0).
        let (p, n) = a.targets[0];
        assert!((p - Vec3::new(1.0, 0.5, 0.0)).length() < 1e-6, "{p}");
        // Normals: Y under joint 0, −X under joint 1; blended and normalised.
        assert!(
            (n - Vec3::new(-1.0, 1.0, 0.0).normalize()).length() < 1e-6,
            "{n}"
        );
        // A joint whose entity is gone keeps its last pose: the target stays.
        a.update(&Affine3A::IDENTITY, |j| (j == 0).then_some(joints[0]));
        assert!((a.targets[0].0 - p).length() < 1e-6, "{:?}", a.targets[0]);
        // Influences for fewer vertices than the cloth has are an error.
        let one = vec![[(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)]];
        let two = [Vec3::ZERO, Vec3::X];
        let e = Attachment::new(
            &[Some(0.5), Some(1.0)],
            (&two, &[Vec3::Y; 2]),
            Some((one, &bind)),
        )
        .unwrap_err();
        assert!(
            e.to_string().contains("1 vertices have joint influences"),
            "{e}"
        );
        // A joint index past the skin is an error.
        let bad = vec![[(2, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)]];
        assert!(
            Attachment::new(
                &[Some(0.5)],
                (&[Vec3::ZERO], &[Vec3::Y]),
                Some((bad, &bind))
            )
            .is_err()
        );
    }
}
