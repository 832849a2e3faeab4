//! The vector passes over a structure-of-arrays state ([`Soa`]): each particle's clearance from a
//! collider's bounding ball or plane, and how far the particles moved since a snapshot.

use glam::{Vec3, Vec3A};

use super::shapes::Near;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::soa::Soa;

/// [`ContactState::clearances`](super::narrow::ContactState::clearances) of particles displaced by `d` over the substep: ending at `x`, or
/// with `AHEAD` starting at `x` (and ending at `x + d`), against `within`. A vector [`Kernel`]
/// ([`simd`]).
pub(crate) fn soa_clearances<const AHEAD: bool>(
    x: &Soa,
    d: &Soa,
    (near, within): (Near, f32),
    out: &mut [f32],
) {
    let within = within.max(0.0);
    simd::run(Clearances::<AHEAD> {
        x,
        d,
        near,
        within,
        out,
    });
}

/// [`soa_clearances`]' arguments, as a [`Kernel`].
pub(super) struct Clearances<'a, const AHEAD: bool> {
    pub(super) x: &'a Soa,
    pub(super) d: &'a Soa,
    pub(super) near: Near,
    pub(super) within: f32,
    pub(super) out: &'a mut [f32],
}

impl<const AHEAD: bool> Kernel for Clearances<'_, AHEAD> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        clearances_body::<AHEAD>(self.x, self.d, (self.near, self.within), self.out);
    }
}

/// The sign of `|e| − |d| − w` (`w ≥ 0`) from `e2 = |e|²` and `d2 = |d|²`, without square
/// roots: `|e| ≤ w + |d|` holds where `q = |e|² − |d|² − w² ≤ 0`, and otherwise exactly where
/// `q² ≤ 4 w² |d|²`.
#[inline(always)]
fn point_gap_sign(e2: f32, d2: f32, w2: f32) -> f32 {
    let q = e2 - d2 - w2;
    if q <= 0.0 { q } else { q * q - 4.0 * w2 * d2 }
}

/// The sign of `a − |d| − w` (`w ≥ 0`) from `a` and `d2 = |d|²`, without a square root: it is
/// at most 0 where `a − w ≤ 0`, and otherwise exactly where `(a − w)² ≤ |d|²`.
#[inline(always)]
fn plane_gap_sign(a: f32, d2: f32, w: f32) -> f32 {
    let q = a - w;
    if q <= 0.0 { q } else { q * q - d2 }
}

#[inline(always)]
fn clearances_body<const AHEAD: bool>(
    x: &Soa,
    d: &Soa,
    (near, within): (Near, f32),
    out: &mut [f32],
) {
    let n = out.len().min(x.len()).min(d.len());
    let (x, y, z) = (&x.x[..n], &x.y[..n], &x.z[..n]);
    let (dx, dy, dz) = (&d.x[..n], &d.y[..n], &d.z[..n]);
    let moved2 = |i: usize| dx[i] * dx[i] + dy[i] * dy[i] + dz[i] * dz[i];
    let end = |x: &[f32], d: &[f32], i: usize| if AHEAD { x[i] + d[i] } else { x[i] };
    match near {
        Near::Point(c) => {
            let w2 = within * within;
            for (i, o) in out[..n].iter_mut().enumerate() {
                let (ex, ey, ez) = (
                    end(x, dx, i) - c.x,
                    end(y, dy, i) - c.y,
                    end(z, dz, i) - c.z,
                );
                *o = point_gap_sign(ex * ex + ey * ey + ez * ez, moved2(i), w2);
            }
        }
        Near::Plane(c, normal) => {
            for (i, o) in out[..n].iter_mut().enumerate() {
                let along = (end(x, dx, i) - c.x) * normal.x
                    + (end(y, dy, i) - c.y) * normal.y
                    + (end(z, dz, i) - c.z) * normal.z;
                *o = plane_gap_sign(along, moved2(i), within);
            }
        }
    }
}

/// What [`ContactState::since`](super::narrow::ContactState::since) measures over the particles: sums of their displacements since a
/// snapshot and over the substep, and how far the farthest one is from a guess.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct Since {
    /// Sum over the particles of `end − snapshot`.
    pub moved: Vec3,
    /// Sum over the particles of `end − start`.
    pub step: Vec3,
    /// Largest `|end − snapshot − guess|²`; infinite if a sum is not finite (a particle's
    /// position or the snapshot is NaN or infinite).
    pub worst: f32,
}

impl Since {
    /// Infinite `worst` where a displacement is not finite, which the sums always see (`max`
    /// alone would drop a NaN).
    pub(super) fn checked(self) -> Self {
        if self.moved.is_finite() && self.step.is_finite() {
            self
        } else {
            Self {
                worst: f32::INFINITY,
                ..self
            }
        }
    }
}

/// [`ContactState::since`](super::narrow::ContactState::since) of particles displaced by `d` over the substep: ending at `x`, or with
/// `AHEAD` starting at `x` (and ending at `x + d`). A vector [`Kernel`] ([`simd`]): sixteen
/// running sums and maxima per quantity, added up in a fixed order, so every build gives the same
/// bits.
pub(crate) fn soa_since<const AHEAD: bool>(x: &Soa, d: &Soa, at: &Soa, guess: Vec3) -> Since {
    let mut out = Since::default();
    simd::run(SinceKernel::<AHEAD> {
        x,
        d,
        at,
        guess,
        out: &mut out,
    });
    out.checked()
}

/// [`ContactState::displaced`](super::narrow::ContactState::displaced) of particles displaced by `d` over the substep (see
/// [`soa_since`]): a plain loop over the arrays, whose running sums stay in registers.
pub(crate) fn soa_displaced<const AHEAD: bool>(
    x: &Soa,
    d: &Soa,
    found: &[Vec3],
    moved: &mut [Vec3A],
) -> (Vec3A, Vec3A) {
    let n = x.len().min(d.len()).min(found.len()).min(moved.len());
    let (mut m0, mut m1) = (Vec3A::ZERO, Vec3A::ZERO);
    for i in 0..n {
        let p = Vec3A::new(x.x[i], x.y[i], x.z[i]);
        let q = Vec3A::new(d.x[i], d.y[i], d.z[i]);
        let (start, end) = if AHEAD { (p, p + q) } else { (p - q, p) };
        let at = Vec3A::from(found[i]);
        let d = end - at;
        moved[i] = d;
        m0 += start - at;
        m1 += d;
    }
    (m0, m1)
}

/// [`ContactState::ends`](super::narrow::ContactState::ends) of particles displaced by `d` over the substep (see [`soa_since`]).
pub(crate) fn soa_ends<const AHEAD: bool>(x: &Soa, d: &Soa, out: &mut Soa) {
    let n = x.len().min(d.len());
    out.resize(n);
    for (o, (x, d)) in [&mut out.x, &mut out.y, &mut out.z].into_iter().zip([
        (&x.x, &d.x),
        (&x.y, &d.y),
        (&x.z, &d.z),
    ]) {
        if AHEAD {
            for ((o, x), d) in o.iter_mut().zip(&x[..n]).zip(&d[..n]) {
                *o = x + d;
            }
        } else {
            o.copy_from_slice(&x[..n]);
        }
    }
}

/// [`soa_since`]'s arguments, as a [`Kernel`].
pub(super) struct SinceKernel<'a, const AHEAD: bool> {
    pub(super) x: &'a Soa,
    pub(super) d: &'a Soa,
    pub(super) at: &'a Soa,
    pub(super) guess: Vec3,
    pub(super) out: &'a mut Since,
}

impl<const AHEAD: bool> Kernel for SinceKernel<'_, AHEAD> {
    // Sixteen lanes of seven running values fit AVX-512's registers (AVX2's spill).
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        *self.out = since_body::<AHEAD>(self.x, self.d, self.at, self.guess);
    }
}

#[inline(always)]
fn since_body<const AHEAD: bool>(x: &Soa, d: &Soa, at: &Soa, guess: Vec3) -> Since {
    let n = x.len().min(d.len()).min(at.len());
    let arrays = [&x.x, &x.y, &x.z, &d.x, &d.y, &d.z, &at.x, &at.y, &at.z].map(|a| &a[..n]);
    let mut acc = [[0.0; LANES]; 7];
    let whole = n - n % LANES;
    for base in (0..whole).step_by(LANES) {
        let block = |k: usize| -> &[f32; LANES] {
            arrays[k][base..base + LANES]
                .try_into()
                .expect("a whole block")
        };
        since_block::<AHEAD>(&mut acc, std::array::from_fn(block), guess);
    }
    for i in whole..n {
        since_lane::<AHEAD>(&mut acc, i - whole, arrays.map(|a| a[i]), guess);
    }
    let sum = |a: &[f32; LANES]| a.iter().sum::<f32>();
    Since {
        moved: Vec3::new(sum(&acc[0]), sum(&acc[1]), sum(&acc[2])),
        step: Vec3::new(sum(&acc[3]), sum(&acc[4]), sum(&acc[5])),
        worst: acc[6].iter().fold(0.0, |a, &w| a.max(w)),
    }
}

/// Lanes of [`since_body`]'s running sums and maxima.
const LANES: usize = 16;

/// One block of [`since_body`]: [`since_lane`] for [`LANES`] particles, whose x, y, z, d (x, y, z)
/// and snapshot (x, y, z) `block` holds.
#[inline(always)]
fn since_block<const AHEAD: bool>(
    acc: &mut [[f32; LANES]; 7],
    block: [&[f32; LANES]; 9],
    guess: Vec3,
) {
    for l in 0..LANES {
        since_lane::<AHEAD>(acc, l, block.map(|a| a[l]), guess);
    }
}

/// Adds one particle's move (x, y, z), substep displacement (x, y, z) and squared distance of the
/// move from `guess` (a maximum) to lane `l` of `acc`, from its x, y, z, d (x, y, z) and snapshot
/// (x, y, z).
#[inline(always)]
fn since_lane<const AHEAD: bool>(
    acc: &mut [[f32; LANES]; 7],
    l: usize,
    [x, y, z, dx, dy, dz, ax, ay, az]: [f32; 9],
    guess: Vec3,
) {
    let (ex, ey, ez) = if AHEAD {
        (x + dx, y + dy, z + dz)
    } else {
        (x, y, z)
    };
    let (mx, my, mz) = (ex - ax, ey - ay, ez - az);
    let (gx, gy, gz) = (mx - guess.x, my - guess.y, mz - guess.z);
    let w = gx * gx + gy * gy + gz * gz;
    acc[0][l] += mx;
    acc[1][l] += my;
    acc[2][l] += mz;
    acc[3][l] += dx;
    acc[4][l] += dy;
    acc[5][l] += dz;
    acc[6][l] = if w > acc[6][l] { w } else { acc[6][l] };
}
