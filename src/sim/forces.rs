//! The spring-force kernel shared by every force-based integrator (symplectic Euler, Verlet,
//! implicit Euler): Hookean forces `f = k (|d| - L) d/|d|`, their linearisation (the stiffness
//! matrix, applied matrix-free), the spring potential energy, and the per-particle stability bound.
//!
//! Plain slices in, plain slices out; nothing here allocates. XPBD does not use forces (it solves the
//! same springs as compliant constraints, `integrate/xpbd`).

use glam::Vec3;

use super::model::Springs;
use super::runs;
use super::simd::{self, Build, Kernel};
use super::soa::Soa;

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

impl<'a> SpringSet<'a> {
    /// The model's springs `springs` with stiffnesses `k`.
    pub fn new(springs: &'a Springs, k: &'a [f32]) -> Self {
        Self {
            a: &springs.a,
            b: &springs.b,
            rest: &springs.rest,
            k,
        }
    }
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

/// Shortest run worth the vector kernel; springs in shorter stretches are evaluated one by one.
const MIN_RUN: usize = 8;

/// `len` slots from `slot` on: slot `slot + m` is a spring between particles `first + m` and
/// `first + m + offset`.
#[derive(Debug, Clone, Copy)]
struct ForceRun {
    first: u32,
    offset: u32,
    slot: u32,
    len: u32,
}

/// The springs regrouped for the vector force kernel ([`add_spring_forces`]).
///
/// Forces are summed, not solved, so unlike XPBD's colour runs these need no colouring: a run is
/// any stretch of springs `(i, i + d)` with one offset `d` and consecutive `i`, gaps of up to
/// [`MAX_GAP`](runs::MAX_GAP) filled with slots of zero stiffness. Each run is evaluated eight springs at a time,
/// and its forces are added with whole vector loads and stores in spring order, so the sums are
/// exact even where both ends of a spring fall within the same eight particles. A grid cloth is a
/// handful of runs (one per spring direction); springs of irregular meshes that fall in no run are
/// evaluated one by one.
#[derive(Debug, Clone, Default)]
pub(crate) struct ForceRuns {
    runs: Vec<ForceRun>,
    /// The spring in each slot, or `None` for a gap.
    spring: Vec<Option<u32>>,
    /// Rest length of each slot, m.
    rest: Vec<f32>,
    /// Stiffness of each slot, N/m (0 for gaps).
    k: Vec<f32>,
    /// Springs in no run.
    singles: Vec<u32>,
    /// The forces of one run between the kernel's two sweeps (scratch, as long as the longest run).
    kept: Soa,
    /// Number of springs this was built for.
    springs: usize,
}

impl ForceRuns {
    /// Groups the springs joining `a[s]` and `b[s]` into runs. Call
    /// [`set_stiffness`](Self::set_stiffness) before use.
    pub fn new(a: &[u32], b: &[u32]) -> Self {
        let mut order: Vec<(u32, u32, u32)> = a
            .iter()
            .zip(b)
            .enumerate()
            .map(|(s, (&a, &b))| (a.max(b) - a.min(b), a.min(b), s as u32))
            .collect();
        order.sort_unstable();
        let first: Vec<u32> = order.iter().map(|o| o.1).collect();
        let second: Vec<u32> = order.iter().map(|o| o.1 + o.0).collect();
        let mut runs = Self {
            springs: a.len(),
            ..Self::default()
        };
        let mut i = 0;
        while i < order.len() {
            let (taken, slots) = runs::extent(&first, &second, i, order.len(), Some);
            if taken < MIN_RUN {
                runs.singles.extend(order[i..i + taken].iter().map(|o| o.2));
            } else {
                let slot = runs.spring.len();
                runs.spring.resize(slot + slots, None);
                for o in &order[i..i + taken] {
                    runs.spring[slot + (o.1 - first[i]) as usize] = Some(o.2);
                }
                runs.runs.push(ForceRun {
                    first: first[i],
                    offset: order[i].0,
                    slot: slot as u32,
                    len: slots as u32,
                });
            }
            i += taken;
        }
        runs.kept = Soa::new(runs.runs.iter().map(|r| r.len as usize).max().unwrap_or(0));
        runs.rest = vec![0.0; runs.spring.len()];
        runs.k = vec![0.0; runs.spring.len()];
        runs
    }

    /// Whether this was built for `springs` springs.
    pub fn fits(&self, springs: usize) -> bool {
        self.springs == springs
    }

    /// Copies each spring's rest length and stiffness into its slot.
    pub fn set_stiffness(&mut self, rest: &[f32], k: &[f32]) {
        for ((spring, r), kk) in self.spring.iter().zip(&mut self.rest).zip(&mut self.k) {
            (*r, *kk) = spring.map_or((0.0, 0.0), |s| (rest[s as usize], k[s as usize]));
        }
    }
}

/// The Hookean force `k (|d| - L) d / |d|` on the second end of a spring from `xb` to `xa`, with
/// `d = xa - xb` (the first end gets its negative), as [`spring_force`] computes it up to rounding;
/// a spring of (near) zero length exerts none. Written coordinate by coordinate so that loops
/// over it vectorise.
#[inline(always)]
fn spring_force_on_second(xa: [f32; 3], xb: [f32; 3], rest: f32, k: f32) -> [f32; 3] {
    let (dx, dy, dz) = (xa[0] - xb[0], xa[1] - xb[1], xa[2] - xb[2]);
    let len2 = dx * dx + dy * dy + dz * dz;
    let len = len2.sqrt();
    let scale = k * (len - rest) / len;
    let scale = if len2 > 1e-20 { scale } else { 0.0 };
    [dx * scale, dy * scale, dz * scale]
}

/// Adds the spring forces at positions `x` to `forces` (which the caller has initialised, e.g. with
/// the particles' weights `m g`): the runs of `runs` eight springs at a time, the rest one by one.
/// `springs` must be the springs `runs` was built from, and `runs` must hold their stiffness.
/// A vector kernel ([`simd`]): the builds' results are bit-identical.
pub(crate) fn add_spring_forces(
    runs: &mut ForceRuns,
    springs: SpringSet<'_>,
    x: &Soa,
    forces: &mut Soa,
) {
    simd::run(SpringForces {
        runs,
        springs,
        x,
        forces,
    });
}

/// [`add_spring_forces`]'s arguments, as a [`Kernel`].
struct SpringForces<'a, 'b> {
    runs: &'a mut ForceRuns,
    springs: SpringSet<'b>,
    x: &'a Soa,
    forces: &'a mut Soa,
}

impl Kernel for SpringForces<'_, '_> {
    const WIDEST: Build = Build::Avx2;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        add_spring_forces_body(self.runs, self.springs, self.x, self.forces);
    }
}

#[inline(always)]
fn add_spring_forces_body(runs: &mut ForceRuns, springs: SpringSet<'_>, x: &Soa, forces: &mut Soa) {
    let ForceRuns {
        runs,
        rest,
        k,
        kept,
        singles,
        ..
    } = runs;
    // Each run in two sweeps, both in particle order: the forces on the first ends (kept), then
    // the kept forces on the second ends. Adding to both ends in one sweep would load forces that
    // were just stored at an overlapping address, which the CPU cannot forward. The sweeps are
    // plain loops over slices of one length, which the compiler turns into vector code.
    for run in runs.iter() {
        let (first, offset, slot, len) = (
            run.first as usize,
            run.offset as usize,
            run.slot as usize,
            run.len as usize,
        );
        let (a, b) = (first..first + len, first + offset..first + offset + len);
        let (xa, ya, za) = (&x.x[a.clone()], &x.y[a.clone()], &x.z[a.clone()]);
        let (xb, yb, zb) = (&x.x[b.clone()], &x.y[b.clone()], &x.z[b.clone()]);
        let (rest, k) = (&rest[slot..slot + len], &k[slot..slot + len]);
        let (kx, ky, kz) = (&mut kept.x[..len], &mut kept.y[..len], &mut kept.z[..len]);
        let (fx, fy, fz) = (
            &mut forces.x[a.clone()],
            &mut forces.y[a.clone()],
            &mut forces.z[a],
        );
        for m in 0..len {
            let f =
                spring_force_on_second([xa[m], ya[m], za[m]], [xb[m], yb[m], zb[m]], rest[m], k[m]);
            (kx[m], ky[m], kz[m]) = (f[0], f[1], f[2]);
            fx[m] -= f[0];
            fy[m] -= f[1];
            fz[m] -= f[2];
        }
        for (coord, kept) in [&mut forces.x, &mut forces.y, &mut forces.z]
            .into_iter()
            .zip([&*kx, &*ky, &*kz])
        {
            for (f, kept) in coord[b.clone()].iter_mut().zip(kept) {
                *f += *kept;
            }
        }
    }
    for &s in singles.iter() {
        let s = s as usize;
        let (ia, ib) = (springs.a[s] as usize, springs.b[s] as usize);
        let f = spring_force_on_second(
            [x.x[ia], x.y[ia], x.z[ia]],
            [x.x[ib], x.y[ib], x.z[ib]],
            springs.rest[s],
            springs.k[s],
        );
        for (coord, f) in [&mut forces.x, &mut forces.y, &mut forces.z]
            .into_iter()
            .zip(f)
        {
            coord[ia] -= f;
            coord[ib] += f;
        }
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

    /// The spring forces at `x` through [`ForceRuns`] and [`add_spring_forces`].
    fn forces_at(springs: SpringSet<'_>, x: &[Vec3]) -> Vec<Vec3> {
        forces_in(None, springs, x).expect("the widest build runs")
    }

    /// The spring forces at `x` from the kernel's `build` (its widest for `None`), if the CPU has
    /// that build.
    fn forces_in(build: Option<Build>, springs: SpringSet<'_>, x: &[Vec3]) -> Option<Vec<Vec3>> {
        let mut runs = ForceRuns::new(springs.a, springs.b);
        runs.set_stiffness(springs.rest, springs.k);
        let mut soa = Soa::new(x.len());
        soa.load(x);
        let mut f = Soa::new(x.len());
        let Some(build) = build else {
            add_spring_forces(&mut runs, springs, &soa, &mut f);
            return Some(f.iter().collect());
        };
        let kernel = SpringForces {
            runs: &mut runs,
            springs,
            x: &soa,
            forces: &mut f,
        };
        simd::run_as(build, kernel).then(|| f.iter().collect())
    }

    #[test]
    fn every_build_of_the_force_kernel_gives_the_same_bits() {
        // A 37×23 grid (runs with row-end gaps, and singles) at perturbed positions.
        let model = crate::sim::ClothModel::grid(&crate::sim::GridSpec::new(37, 23, 0.1)).unwrap();
        let s = &model.springs;
        let k: Vec<f32> = (0..s.len()).map(|i| 100.0 + (i % 5) as f32).collect();
        let springs = SpringSet {
            a: &s.a,
            b: &s.b,
            rest: &s.rest,
            k: &k,
        };
        let x: Vec<Vec3> = model
            .rest_positions
            .iter()
            .enumerate()
            .map(|(i, p)| *p + 0.01 * Vec3::new((i as f32).sin(), (i as f32 * 1.7).cos(), 0.3))
            .collect();
        let plain = forces_in(Some(Build::Plain), springs, &x).unwrap();
        let bits = |f: &[Vec3]| -> Vec<[u32; 3]> {
            f.iter().map(|v| v.to_array().map(f32::to_bits)).collect()
        };
        let mut compared = 0;
        for build in [Build::Avx2, Build::Avx512] {
            if let Some(f) = forces_in(Some(build), springs, &x) {
                assert_eq!(bits(&f), bits(&plain), "{build:?} against the plain build");
                compared += 1;
            }
        }
        assert_eq!(compared, usize::from(Build::Avx2.is_available()));
        assert_eq!(bits(&forces_at(springs, &x)), bits(&plain));
    }

    #[test]
    fn run_kernel_sums_the_same_forces_as_spring_by_spring() {
        // A 13×11 grid's springs (runs with gaps at the row ends) plus irregular ones (singles),
        // some listed high index first, at perturbed positions.
        let model = crate::sim::ClothModel::grid(&crate::sim::GridSpec::new(13, 11, 0.1)).unwrap();
        let s = &model.springs;
        let (mut a, mut b) = (s.a.clone(), s.b.clone());
        for (i, j) in [(0, 100), (140, 3), (7, 77), (50, 51)] {
            a.push(i);
            b.push(j);
        }
        for (i, (a, b)) in a.iter_mut().zip(b.iter_mut()).enumerate() {
            if i % 3 == 0 {
                std::mem::swap(a, b);
            }
        }
        let rest: Vec<f32> = (0..a.len())
            .map(|i| 0.08 + 0.001 * (i % 7) as f32)
            .collect();
        let k: Vec<f32> = (0..a.len()).map(|i| 100.0 + (i % 5) as f32).collect();
        let springs = SpringSet {
            a: &a,
            b: &b,
            rest: &rest,
            k: &k,
        };
        let runs = ForceRuns::new(&a, &b);
        assert!(
            runs.runs.len() >= 6 && runs.singles.len() < 8,
            "{} runs, {} singles",
            runs.runs.len(),
            runs.singles.len()
        );
        let x: Vec<Vec3> = model
            .rest_positions
            .iter()
            .enumerate()
            .map(|(i, p)| {
                *p + 0.01 * Vec3::new((i as f32).sin(), (i as f32 * 1.7).cos(), (i % 3) as f32)
            })
            .collect();
        let mut expected = vec![Vec3::ZERO; x.len()];
        for s in 0..a.len() {
            let (ia, ib) = (a[s] as usize, b[s] as usize);
            let (_, _, f) = spring_force(x[ia], x[ib], rest[s], k[s]);
            expected[ia] -= f;
            expected[ib] += f;
        }
        let got = forces_at(springs, &x);
        let scale = expected.iter().map(|f| f.length()).fold(0.0, f32::max);
        for (i, (g, e)) in got.iter().zip(&expected).enumerate() {
            assert!(
                (*g - *e).length() <= 1e-5 * scale,
                "particle {i}: {g} vs {e}"
            );
        }
    }

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
        let f1 = forces_at(springs, &xe);
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
