//! The targets resolved a batch at a time, in vector code, with the bits of
//! [`resolve_target`](super::resolve_target).

use glam::Vec3;

use super::{Moving, TargetLimits};
use crate::sim::contact::narrow::ContactState;
use crate::sim::simd::{self, Build, Kernel};
use crate::sim::state::between_coordinate as at;

/// Targets resolved together in [`resolve_targets`].
const TARGET_BATCH: usize = 64;

/// Three coordinates of a batch's lanes.
type Lanes3 = [[f32; TARGET_BATCH]; 3];

/// [`resolve_target`](super::resolve_target) for every target of `targets`, whose particles are
/// distinct, with the same results: a batch of [`TARGET_BATCH`] at a time, its targets worked out
/// ([`TargetLanes`]), its particles gathered from the state, tested and projected in lanes
/// without branches ([`WithinLanes`], [`OutsideLanes`]), and those that moved set back. The
/// batch is wide enough that the vector units overlap several lanes' square roots and divisions.
pub(super) fn resolve_targets<S: ContactState>(
    targets: &[Moving],
    s: TargetLimits,
    (t0, t1, inv_h): (f32, f32, f32),
    state: &mut S,
) {
    const L: usize = TARGET_BATCH;
    let zero = [[0.0f32; L]; 3];
    for batch in targets.chunks(L) {
        let mut slot = [usize::MAX; L];
        let (mut x, mut v) = (zero, zero);
        let (mut target, mut velocity, mut normal) = (zero, zero, zero);
        let mut radius = [0.0f32; L];
        simd::run(TargetLanes {
            batch,
            times: (t0, t1, inv_h),
            scale: s.max_distance_scale,
            out: (&mut target, &mut velocity, &mut normal, &mut radius),
        });
        for (k, t) in batch.iter().enumerate() {
            let i = state.slot(t.particle);
            if state.inv_mass(i) == 0.0 {
                continue;
            }
            slot[k] = i;
            let (xk, vk) = (state.position(i), state.velocity(i));
            for c in 0..3 {
                (x[c][k], v[c][k]) = (xk[c], vk[c]);
            }
        }
        let mut moved = [false; L];
        simd::run(WithinLanes {
            limit: (&target, &velocity, &radius),
            state: (&mut x, &mut v),
            moved: &mut moved,
        });
        // The backstop sees the particle where the state put it, as in `resolve_target` (a
        // state may keep it as a displacement, whose sum rounds).
        let mut set = |k: usize, x: &mut Lanes3, v: &mut Lanes3, reread: bool| {
            let i = slot[k];
            state.set(
                i,
                Vec3::new(x[0][k], x[1][k], x[2][k]),
                Vec3::new(v[0][k], v[1][k], v[2][k]),
            );
            if reread {
                let (xk, vk) = (state.position(i), state.velocity(i));
                for c in 0..3 {
                    (x[c][k], v[c][k]) = (xk[c], vk[c]);
                }
            }
        };
        for k in 0..batch.len() {
            if moved[k] && slot[k] != usize::MAX {
                set(k, &mut x, &mut v, true);
            }
        }
        if s.backstop_radius > 0.0 {
            let backstop = (s.backstop_radius, s.backstop_offset);
            simd::run(OutsideLanes {
                limit: (&target, &velocity, &normal),
                backstop,
                state: (&mut x, &mut v),
                moved: &mut moved,
            });
            for k in 0..batch.len() {
                if moved[k] && slot[k] != usize::MAX {
                    set(k, &mut x, &mut v, false);
                }
            }
        }
    }
}

/// Each target of `batch` at the end of the substep `times` `(t0, t1, 1/h)`, its velocity over
/// the substep, its normal there (not normalised) and its maximum distance (weight times
/// `scale`), as [`resolve_target`](super::resolve_target) works them out, as a [`Kernel`].
struct TargetLanes<'a> {
    batch: &'a [Moving],
    times: (f32, f32, f32),
    scale: f32,
    out: (
        &'a mut Lanes3,
        &'a mut Lanes3,
        &'a mut Lanes3,
        &'a mut [f32; TARGET_BATCH],
    ),
}

impl Kernel for TargetLanes<'_> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let (t0, t1, inv_h) = self.times;
        let (target, velocity, normal, radius) = self.out;
        // `between` and `lerp`, coordinate by coordinate.
        for (k, m) in self.batch.iter().enumerate().take(TARGET_BATCH) {
            for c in 0..3 {
                let end = at(m.from[c], m.to[c], t1);
                target[c][k] = end;
                velocity[c][k] = (end - at(m.from[c], m.to[c], t0)) * inv_h;
                normal[c][k] = m.normal_from[c] * (1.0 - t1) + m.normal_to[c] * t1;
            }
            radius[k] = m.weight * self.scale;
        }
    }
}

/// [`within`](super::within) on every lane (`moved`: whether it moved), as a [`Kernel`].
struct WithinLanes<'a> {
    limit: (&'a Lanes3, &'a Lanes3, &'a [f32; TARGET_BATCH]),
    state: (&'a mut Lanes3, &'a mut Lanes3),
    moved: &'a mut [bool; TARGET_BATCH],
}

impl Kernel for WithinLanes<'_> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let ([cx, cy, cz], [ux, uy, uz], radius) = self.limit;
        let ([xx, xy, xz], [vx, vy, vz]) = self.state;
        let moved = self.moved;
        for k in 0..TARGET_BATCH {
            let (ox, oy, oz) = (xx[k] - cx[k], xy[k] - cy[k], xz[k] - cz[k]);
            let distance2 = ox * ox + oy * oy + oz * oz;
            // Out unless within (a NaN is out, as in `within`).
            let inside = distance2 <= radius[k] * radius[k];
            let out = !inside;
            let root = distance2.sqrt();
            let (nx, ny, nz) = (ox / root, oy / root, oz / root);
            let (rx, ry, rz) = (vx[k] - ux[k], vy[k] - uy[k], vz[k] - uz[k]);
            let outward = rx * nx + ry * ny + rz * nz;
            let slow = out && outward > 0.0;
            vx[k] = if slow { vx[k] - outward * nx } else { vx[k] };
            vy[k] = if slow { vy[k] - outward * ny } else { vy[k] };
            vz[k] = if slow { vz[k] - outward * nz } else { vz[k] };
            xx[k] = if out { cx[k] + nx * radius[k] } else { xx[k] };
            xy[k] = if out { cy[k] + ny * radius[k] } else { xy[k] };
            xz[k] = if out { cz[k] + nz * radius[k] } else { xz[k] };
            moved[k] = out;
        }
    }
}

/// [`outside`](super::outside) on every lane (`moved`: whether it moved), for the
/// `backstop` (radius, offset) behind each target along its normal (not yet normalised), as a
/// [`Kernel`].
struct OutsideLanes<'a> {
    limit: (&'a Lanes3, &'a Lanes3, &'a Lanes3),
    backstop: (f32, f32),
    state: (&'a mut Lanes3, &'a mut Lanes3),
    moved: &'a mut [bool; TARGET_BATCH],
}

impl Kernel for OutsideLanes<'_> {
    const WIDEST: Build = Build::Avx512;

    #[inline(always)]
    fn body<const WIDE: bool>(self) {
        let (radius, offset) = self.backstop;
        let depth = radius + offset;
        let ([tx, ty, tz], [ux, uy, uz], [mx, my, mz]) = self.limit;
        let ([xx, xy, xz], [vx, vy, vz]) = self.state;
        let moved = self.moved;
        for k in 0..TARGET_BATCH {
            // `normalize_or_zero`.
            let rcp = 1.0 / (mx[k] * mx[k] + my[k] * my[k] + mz[k] * mz[k]).sqrt();
            let unit = rcp.is_finite() && rcp > 0.0;
            let ax = if unit { mx[k] * rcp } else { 0.0 };
            let ay = if unit { my[k] * rcp } else { 0.0 };
            let az = if unit { mz[k] * rcp } else { 0.0 };
            let some = ax != 0.0 || ay != 0.0 || az != 0.0;
            let (cx, cy, cz) = (tx[k] - ax * depth, ty[k] - ay * depth, tz[k] - az * depth);
            let (ox, oy, oz) = (xx[k] - cx, xy[k] - cy, xz[k] - cz);
            let distance = (ox * ox + oy * oy + oz * oz).sqrt();
            // Inside unless clear (a NaN is inside, as in `outside`).
            let clear = distance >= radius;
            let inside = some && !clear;
            let off_centre = distance > 1e-9 * radius;
            let nx = if off_centre { ox / distance } else { ax };
            let ny = if off_centre { oy / distance } else { ay };
            let nz = if off_centre { oz / distance } else { az };
            let (rx, ry, rz) = (vx[k] - ux[k], vy[k] - uy[k], vz[k] - uz[k]);
            let inward = rx * nx + ry * ny + rz * nz;
            let slow = inside && inward < 0.0;
            vx[k] = if slow { vx[k] - inward * nx } else { vx[k] };
            vy[k] = if slow { vy[k] - inward * ny } else { vy[k] };
            vz[k] = if slow { vz[k] - inward * nz } else { vz[k] };
            xx[k] = if inside { cx + nx * radius } else { xx[k] };
            xy[k] = if inside { cy + ny * radius } else { xy[k] };
            xz[k] = if inside { cz + nz * radius } else { xz[k] };
            moved[k] = inside;
        }
    }
}
