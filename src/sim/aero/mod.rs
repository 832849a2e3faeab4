//! Aerodynamics for triangle-mesh cloth: per-triangle drag and lift in the style of NvCloth's wind
//! model, and a deterministic, smooth, seeded gust field to drive it.
//!
//! Each triangle is treated as a thin flat plate in a uniform relative air flow. With the relative
//! air velocity `u` (wind minus the triangle's mean vertex velocity), area `A`, unit normal `n` and
//! `cos θ = n·û`, the plate feels
//!
//! - drag `½ ρ C_d A |u|² |cos θ| û`: along the relative wind, proportional to the projected area;
//! - lift `½ ρ C_l A |u|² |cos θ| sin θ l̂`: perpendicular to the relative wind (see
//!   [`add_aero_forces`] for the direction `l̂`).
//!
//! Both vanish for an edge-on plate, lift also for a face-on one, and neither depends on the
//! triangle's winding. The wind itself is sampled per triangle (e.g. at [`triangle_centroids`]),
//! typically from [`Gusts::sample`].
//!
//! SI units throughout (m, s, kg, N). Plain slices in, plain slices out. Nothing here allocates
//! but `GridAero`'s scratch, once, when it is made; nothing holds state from one step to the next
//! (a [`GustSampler`] notes the noise cells it last used, a `GustTable` its knots, both for one
//! step).
//!
//! `plate` holds the force model and its formula; `triangles` applies it to a triangle list and
//! `grid` to the canonical grid, row by row, with the same bits; `gusts` is the gust field, on
//! `noise`'s value noise.

mod grid;
mod gusts;
mod noise;
mod plate;
#[cfg(test)]
mod tests;
mod triangles;

pub(crate) use grid::{GridAero, TriangleWind};
pub(crate) use gusts::GustTable;
pub use gusts::{GustSampler, Gusts};
pub use noise::value_noise;
pub use plate::{AIR_DENSITY, AeroParams};
pub(crate) use triangles::add_aero_forces_in;
pub use triangles::{add_aero_forces, triangle_centroids};
