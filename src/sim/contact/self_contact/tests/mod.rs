//! Self-contacts' tests, by what they test: the cubes' bounds, the patches' culling, the
//! narrow phase and response, when a search runs again, and the search itself.

use super::cubes::*;
use super::search::*;
use super::*;
use crate::hash::{mix64, unit_interval};
use crate::sim::contact::Vectors;
use crate::sim::contact::pairs::*;
use crate::sim::{ClothModel, GridSpec};

mod cubes;
mod patches;
mod resolution;
mod search;
mod search_again;

/// Resolves one substep of `contacts` from `start` to `x` with velocities `v`.
fn resolve(contacts: &mut SelfContacts, start: &[Vec3], x: &mut [Vec3], v: &mut [Vec3], w: &[f32]) {
    resolve_within(contacts, 0.0, start, x, v, w);
}

/// [`resolve`] in a step whose particles may move `reach` relative to each other.
fn resolve_within(
    contacts: &mut SelfContacts,
    reach: f32,
    start: &[Vec3],
    x: &mut [Vec3],
    v: &mut [Vec3],
    w: &[f32],
) {
    contacts.begin_step(reach);
    substep(contacts, (1.0 / 1200.0, true), start, (x, v), w);
}

/// One substep of `contacts` of length `h` (the step's `last` or not) for particles of
/// inverse masses `w` that moved from `start` to `x` (velocities `v`).
fn substep(
    contacts: &mut SelfContacts,
    (h, last): (f32, bool),
    start: &[Vec3],
    (x, v): (&mut [Vec3], &mut [Vec3]),
    w: &[f32],
) {
    let mut state = Vectors {
        x,
        v,
        start,
        inv_mass: w,
        touches: None,
    };
    contacts.resolve((h, last), &mut state);
    contacts.end_substep(&state);
}

/// A flat grid at `rest` (in the plane y = 0) folded back over itself along the line x =
/// `bend`, over a radius `r` (x being the arc length).
fn folded(rest: &[Vec3], bend: f32, r: f32) -> Vec<Vec3> {
    let arc = std::f32::consts::PI * r;
    (rest.iter())
        .map(|p| {
            let s = p.x;
            if s < bend {
                Vec3::new(s, 0.0, p.z)
            } else if s < bend + arc {
                let a = (s - bend) / r;
                Vec3::new(bend + r * a.sin(), r - r * a.cos(), p.z)
            } else {
                Vec3::new(bend - (s - bend - arc), 2.0 * r, p.z)
            }
        })
        .collect()
}
