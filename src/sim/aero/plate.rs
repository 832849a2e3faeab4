//! The flat-plate force model: the air's and the cloth's coefficients ([`AeroParams`]) and the
//! drag and lift on one triangle from its edges and relative wind ([`plate_force`]), written once
//! so that every path through the triangles computes the same bits. Holds no gathering or
//! scattering of vertices; that is `triangles` and `grid`.

use bevy::reflect::Reflect;
use serde::{Deserialize, Serialize};

/// Squared relative speed (m²/s²) below which the air is treated as still: 1 µm/s.
pub(super) const MIN_SPEED_SQ: f32 = 1e-12;

/// Area (m²) below which a triangle is treated as degenerate and skipped.
const MIN_AREA: f32 = 1e-12;

/// Sea-level air density, kg/m³.
pub const AIR_DENSITY: f32 = 1.225;

/// Aerodynamic coefficients of the cloth and the density of the air around it.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(default, deny_unknown_fields)]
pub struct AeroParams {
    /// Density of the air, kg/m³ (sea-level air: 1.225).
    pub air_density: f32,
    /// Drag coefficient `C_d`, dimensionless, scaling the force along the relative wind.
    pub drag: f32,
    /// Lift coefficient `C_l`, dimensionless, scaling the force across the relative wind.
    pub lift: f32,
}

impl Default for AeroParams {
    /// Sea-level air (1.225 kg/m³), `C_d = 1.0`, `C_l = 0.5`.
    fn default() -> Self {
        Self {
            air_density: AIR_DENSITY,
            drag: 1.0,
            lift: 0.5,
        }
    }
}

/// The factors of [`plate_force`]'s drag and lift, `ρ/4 · share · C_d` and `ρ/4 · share · C_l`.
#[inline(always)]
pub(super) fn force_scale(params: &AeroParams, share: f32) -> (f32, f32) {
    let scale = 0.25 * params.air_density * share;
    (scale * params.drag, scale * params.lift)
}

/// The force of `TriangleLanes::forces` on one triangle with edges `e1`, `e2` and relative
/// wind `u`, `(drag, lift)` being [`force_scale`]: written once, so that every path computes the
/// same bits.
///
/// With the cross product `c = e₁ × e₂` (so `A = |c|/2`, `n = c/|c|`) and `k = c·u`, the
/// force `q (C_d |cos θ| û + C_l cos θ (n − cos θ û))` becomes
/// `ρ/4 (C_d |k| u + C_l k (|u|² c − k u) / (|c| |u|))`: one square root and one division,
/// and exactly zero when the plate is edge-on (`k = 0`).
#[inline(always)]
pub(super) fn plate_force(
    e1: [f32; 3],
    e2: [f32; 3],
    u: [f32; 3],
    (drag, lift): (f32, f32),
) -> [f32; 3] {
    let c = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    let speed_sq = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
    let cross_sq = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    let k = c[0] * u[0] + c[1] * u[1] + c[2] * u[2];
    let r = 1.0 / (cross_sq * speed_sq).sqrt();
    // Still air, or a degenerate triangle (|c| = 2A): no force.
    let on = speed_sq >= MIN_SPEED_SQ && cross_sq >= 4.0 * MIN_AREA * MIN_AREA;
    let (drag, lift) = if on {
        (drag * k.abs(), lift * k * r)
    } else {
        (0.0, 0.0)
    };
    let mut f = [0.0; 3];
    for d in 0..3 {
        f[d] = drag * u[d] + lift * (speed_sq * c[d] - k * u[d]);
    }
    f
}
