//! The spring-force kernel shared by every force-based integrator (symplectic Euler, Verlet,
//! implicit Euler): Hookean forces `f = k (|d| - L) d/|d|`, their linearisation (the stiffness
//! matrix, applied matrix-free), the spring potential energy, and the per-particle stability bound.
//!
//! Plain slices in, plain slices out; nothing here allocates. XPBD does not use forces (it solves the
//! same springs as compliant constraints) and lives in `solver.rs`.

use glam::Vec3;

/// Per-spring linearisation of the spring forces at the current positions, written by
/// [`add_spring_forces_and_jacobians`] and used by [`add_stiffness_product`].
///
/// For a spring with unit direction `u = d/|d|` the block of the stiffness matrix is
/// `K_s = k u uᵀ + k max(0, 1 - L/|d|) (I - u uᵀ)`: the axial term plus the geometric (transverse)
/// term. The geometric term is negative for a compressed spring, which would make `K` indefinite;
/// it is clamped at 0 there (the usual definiteness fix, e.g. Choi & Ko 2002), so `M + h² K` stays
/// symmetric positive definite and conjugate gradients applies.
#[derive(Debug, Clone, Default)]
pub(crate) struct SpringJacobians {
    /// Unit direction of each spring (from `b` to `a`).
    pub dir: Vec<Vec3>,
    /// Axial stiffness minus transverse stiffness, `k - k_t`, N/m.
    pub axial: Vec<f32>,
    /// Transverse (geometric) stiffness `k_t = k max(0, 1 - L/|d|)`, N/m.
    pub transverse: Vec<f32>,
}

impl SpringJacobians {
    /// Buffers for `springs` springs.
    pub fn new(springs: usize) -> Self {
        Self {
            dir: vec![Vec3::ZERO; springs],
            axial: vec![0.0; springs],
            transverse: vec![0.0; springs],
        }
    }

    /// Whether the buffers are sized for `springs` springs.
    pub fn fits(&self, springs: usize) -> bool {
        self.dir.len() == springs
    }

    /// The diagonal of `K` (per coordinate) contributed by spring `s`: `k_t + (k - k_t) u∘u`.
    #[inline]
    pub fn diagonal(&self, s: usize) -> Vec3 {
        let u = self.dir[s];
        Vec3::splat(self.transverse[s]) + self.axial[s] * u * u
    }
}

/// The spring endpoints, rest lengths and stiffnesses, borrowed from the model and the solver.
#[derive(Clone, Copy)]
pub(crate) struct SpringSet<'a> {
    /// First particle of each spring.
    pub a: &'a [u32],
    /// Second particle of each spring.
    pub b: &'a [u32],
    /// Rest lengths, m.
    pub rest: &'a [f32],
    /// Stiffness of each spring, N/m.
    pub k: &'a [f32],
}

/// The Hookean force of one spring: with `d = x_a - x_b`, returns the unit direction `u = d/|d|`,
/// the length `|d|` and `f = k (|d| - L) u`, the force on `b` (`a` gets `-f`: a stretched spring pulls
/// its ends together). A degenerate spring (`|d|` ≈ 0) has no direction and exerts nothing.
#[inline(always)]
fn spring_force(xa: Vec3, xb: Vec3, rest: f32, k: f32) -> (Vec3, f32, Vec3) {
    let d = xa - xb;
    let len2 = d.length_squared();
    if len2 > 1e-20 {
        let len = len2.sqrt();
        let u = d * len.recip();
        (u, len, u * (k * (len - rest)))
    } else {
        (Vec3::ZERO, 0.0, Vec3::ZERO)
    }
}

/// Adds the spring forces at positions `x` to `forces` (which the caller has initialised, e.g. with
/// the particles' weights `m g`), using [`spring_force`] for each spring.
#[inline(never)]
pub(crate) fn add_spring_forces(springs: SpringSet<'_>, x: &[Vec3], forces: &mut [Vec3]) {
    let n = springs.a.len();
    let (b, rest, k) = (&springs.b[..n], &springs.rest[..n], &springs.k[..n]);
    for s in 0..n {
        let (ia, ib) = (springs.a[s] as usize, b[s] as usize);
        let (_, _, f) = spring_force(x[ia], x[ib], rest[s], k[s]);
        forces[ia] -= f;
        forces[ib] += f;
    }
}

/// [`add_spring_forces`], also writing each spring's linearisation (for implicit Euler).
#[inline(never)]
pub(crate) fn add_spring_forces_and_jacobians(
    springs: SpringSet<'_>,
    x: &[Vec3],
    forces: &mut [Vec3],
    jacobians: &mut SpringJacobians,
) {
    let n = springs.a.len();
    let (b, rest, k) = (&springs.b[..n], &springs.rest[..n], &springs.k[..n]);
    let (dir, axial, transverse) = (
        &mut jacobians.dir[..n],
        &mut jacobians.axial[..n],
        &mut jacobians.transverse[..n],
    );
    for s in 0..n {
        let (ia, ib) = (springs.a[s] as usize, b[s] as usize);
        let (u, len, f) = spring_force(x[ia], x[ib], rest[s], k[s]);
        forces[ia] -= f;
        forces[ib] += f;
        let t = if len > rest[s] {
            k[s] * (1.0 - rest[s] / len)
        } else {
            0.0
        };
        dir[s] = u;
        transverse[s] = t;
        axial[s] = k[s] - t;
    }
}

/// Adds `scale · K p` to `out`, with `K` the (clamped) stiffness matrix described by `jacobians`.
#[inline(never)]
pub(crate) fn add_stiffness_product(
    a: &[u32],
    b: &[u32],
    jacobians: &SpringJacobians,
    scale: f32,
    p: &[Vec3],
    out: &mut [Vec3],
) {
    let n = a.len();
    let (b, dir, axial, transverse) = (
        &b[..n],
        &jacobians.dir[..n],
        &jacobians.axial[..n],
        &jacobians.transverse[..n],
    );
    for s in 0..n {
        let (ia, ib) = (a[s] as usize, b[s] as usize);
        let dp = p[ia] - p[ib];
        let u = dir[s];
        let y = (dp * transverse[s] + u * (axial[s] * u.dot(dp))) * scale;
        out[ia] += y;
        out[ib] -= y;
    }
}

/// Elastic energy `Σ ½ k (|d| - L)²` of the springs at positions `x`, in joules (accumulated in f64).
pub(crate) fn spring_energy(springs: SpringSet<'_>, x: &[Vec3]) -> f64 {
    (0..springs.a.len())
        .map(|s| {
            let d = x[springs.a[s] as usize].as_dvec3() - x[springs.b[s] as usize].as_dvec3();
            let stretch = d.length() - springs.rest[s] as f64;
            0.5 * springs.k[s] as f64 * stretch * stretch
        })
        .sum()
}

/// An upper bound on the highest angular frequency (rad/s) of the linearised springs about their rest
/// lengths: Gershgorin's theorem on `M^{-1/2} K M^{-1/2}` gives, for each free particle `i`,
/// `ω_i² = Σ_{s ∋ i} k_s (w_i + √(w_i w_j))` with `w` the inverse masses (0 when pinned), and
/// `ω_max ≤ max_i ω_i`. Explicit integrators are stable for `h ω_max < 2`.
pub(crate) fn max_frequency_bound(
    springs: SpringSet<'_>,
    inv_mass: &[f32],
    scratch: &mut [f32],
) -> f32 {
    scratch.fill(0.0);
    for s in 0..springs.a.len() {
        let (ia, ib) = (springs.a[s] as usize, springs.b[s] as usize);
        let (wa, wb) = (inv_mass[ia], inv_mass[ib]);
        let cross = (wa * wb).sqrt();
        scratch[ia] += springs.k[s] * (wa + cross);
        scratch[ib] += springs.k[s] * (wb + cross);
    }
    scratch.iter().copied().fold(0.0, f32::max).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stiffness_matrix_is_the_force_derivative() {
        // A stretched spring between particles 0 and 1; compare K p with -(f(x + ε p) - f(x)) / ε.
        let (a, b, rest, k) = ([0u32], [1u32], [1.0f32], [100.0f32]);
        let springs = SpringSet {
            a: &a,
            b: &b,
            rest: &rest,
            k: &k,
        };
        let x = [Vec3::new(0.3, 1.1, -0.2), Vec3::new(0.0, 0.0, 0.1)];
        let p = [Vec3::new(0.2, -0.5, 0.7), Vec3::new(-0.4, 0.1, 0.3)];
        let mut f0 = [Vec3::ZERO; 2];
        let mut j = SpringJacobians::new(1);
        add_spring_forces_and_jacobians(springs, &x, &mut f0, &mut j);
        let eps = 1e-3;
        let xe = [x[0] + eps * p[0], x[1] + eps * p[1]];
        let mut f1 = [Vec3::ZERO; 2];
        add_spring_forces(springs, &xe, &mut f1);
        let mut kp = [Vec3::ZERO; 2];
        add_stiffness_product(&a, &b, &j, 1.0, &p, &mut kp);
        for i in 0..2 {
            let fd = -(f1[i] - f0[i]) / eps;
            assert!(
                (fd - kp[i]).length() < 0.05 * kp[i].length(),
                "{fd} vs {}",
                kp[i]
            );
        }
        // Newton's third law, and the force pulls a stretched spring together.
        assert!((f0[0] + f0[1]).length() < 1e-5);
        assert!(f0[0].dot(x[0] - x[1]) < 0.0);
    }

    #[test]
    fn frequency_bound_of_one_spring_is_exact() {
        // One free particle of mass m on a spring to a pinned one: ω = √(k/m).
        let (a, b, rest, k) = ([0u32], [1u32], [1.0f32], [400.0f32]);
        let springs = SpringSet {
            a: &a,
            b: &b,
            rest: &rest,
            k: &k,
        };
        let mut scratch = [0.0; 2];
        let w = max_frequency_bound(springs, &[0.0, 1.0 / 0.25], &mut scratch);
        assert!((w - 40.0).abs() < 1e-4, "{w}");
        // Two free equal masses: the stretch mode has ω² = 2k/m, and the bound is exact too.
        let w = max_frequency_bound(springs, &[4.0, 4.0], &mut scratch);
        assert!((w - (2.0f32 * 400.0 / 0.25).sqrt()).abs() < 1e-3, "{w}");
    }
}
