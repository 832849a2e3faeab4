//! The colliders a cloth meets: their [`Shape`] (a primitive [`ColliderShape`] or a [`Surface`]
//! known through queries; exact signed distances and bounds), [`Pose`], [`Friction`] and margin
//! ([`Collider`]).

use std::fmt::Debug;
use std::sync::Arc;

use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use bevy::reflect::Reflect;
use glam::{Mat3, Quat, Vec3};
use serde::{Deserialize, Serialize};

use crate::error::{ClothError, non_negative, positive};

/// The shape of a collider, in its own frame.
#[derive(Debug, Clone, Copy, PartialEq, Reflect)]
pub enum ColliderShape {
    /// A ball centred on the origin.
    Sphere(Sphere),
    /// A capsule along the local Y axis, centred on the origin.
    Capsule(Capsule3d),
    /// A box centred on the origin.
    Cuboid(Cuboid),
    /// The solid half-space below a plane through the origin: everything with `p · normal < 0`.
    HalfSpace(InfinitePlane3d),
}

impl ColliderShape {
    /// Signed distance from local point `p` to the surface (negative inside) and the outward unit
    /// normal of the nearest surface point. Exact for every shape.
    #[inline(always)]
    pub fn signed_distance(&self, p: Vec3) -> (f32, Vec3) {
        match *self {
            ColliderShape::Sphere(s) => radial(p, s.radius),
            ColliderShape::Capsule(c) => radial(p - capsule_axis(p, c.half_length), c.radius),
            ColliderShape::Cuboid(b) => box_distance(p, b.half_size),
            ColliderShape::HalfSpace(plane) => {
                let n = Vec3::from(plane.normal);
                (p.dot(n), n)
            }
        }
    }

    /// [`Self::signed_distance`] of each point: for spheres and capsules coordinate by coordinate,
    /// so that the square roots and divisions run in vectors, each lane's operations the scalar
    /// ones in order (the results are the same bit for bit).
    #[inline(always)]
    pub(crate) fn signed_distances<const N: usize>(&self, p: &[Vec3; N]) -> [(f32, Vec3); N] {
        match *self {
            ColliderShape::Sphere(s) => radial_each(p, s.radius),
            ColliderShape::Capsule(c) => {
                radial_each(&p.map(|p| p - capsule_axis(p, c.half_length)), c.radius)
            }
            _ => std::array::from_fn(|k| self.signed_distance(p[k])),
        }
    }

    /// The shape with its dimensions scaled by a transform's `scale`: a cuboid per axis, a capsule's
    /// length by `|scale.y|` and its radius by the larger of `|scale.x|`, `|scale.z|`, a sphere by the
    /// largest `|scale|` component. A half-space is unchanged.
    pub fn scaled(&self, scale: Vec3) -> Self {
        let s = scale.abs();
        match *self {
            ColliderShape::Sphere(b) => {
                ColliderShape::Sphere(Sphere::new(b.radius * s.max_element()))
            }
            ColliderShape::Capsule(c) => ColliderShape::Capsule(Capsule3d {
                radius: c.radius * s.x.max(s.z),
                half_length: c.half_length * s.y,
            }),
            ColliderShape::Cuboid(b) => ColliderShape::Cuboid(Cuboid {
                half_size: b.half_size * s,
            }),
            ColliderShape::HalfSpace(p) => ColliderShape::HalfSpace(p),
        }
    }

    /// Checks the dimensions: radii and half sizes positive and finite, capsule half length
    /// non-negative.
    pub fn validate(&self) -> Result<(), ClothError> {
        match *self {
            ColliderShape::Sphere(s) => positive("collider.radius", s.radius),
            ColliderShape::Capsule(c) => {
                positive("collider.radius", c.radius)?;
                non_negative("collider.half_length", c.half_length)
            }
            ColliderShape::Cuboid(b) => {
                positive("collider.half_size.x", b.half_size.x)?;
                positive("collider.half_size.y", b.half_size.y)?;
                positive("collider.half_size.z", b.half_size.z)
            }
            ColliderShape::HalfSpace(p) => {
                if Vec3::from(p.normal).is_finite() {
                    Ok(())
                } else {
                    Err(ClothError::InvalidValue {
                        field: "collider.normal",
                        expected: "a finite unit vector",
                        value: f64::NAN,
                    })
                }
            }
        }
    }

    /// What the shape at `pose` stays clear of, with a radius: the shape lies within that radius
    /// of the returned centre (its ball), or, for a half-space, on and below the returned plane
    /// (radius 0). A point at distance `D` from it is at least `D − radius` from the shape.
    pub(super) fn near(&self, pose: &Pose) -> (Near, f32) {
        let centre = pose.translation;
        match *self {
            ColliderShape::Sphere(s) => (Near::Point(centre), s.radius),
            ColliderShape::Capsule(c) => (Near::Point(centre), c.half_length + c.radius),
            ColliderShape::Cuboid(b) => (Near::Point(centre), b.half_size.length()),
            ColliderShape::HalfSpace(plane) => (
                Near::Plane(centre, pose.rotation * Vec3::from(plane.normal)),
                0.0,
            ),
        }
    }

    /// World-space bounding box at `pose`, or `None` for the unbounded half-space.
    pub(super) fn bounds(&self, pose: &Pose) -> Option<(Vec3, Vec3)> {
        let half = match *self {
            ColliderShape::Sphere(s) => {
                return Some(around(pose.translation, Vec3::splat(s.radius)));
            }
            ColliderShape::Capsule(c) => {
                let axis = (pose.rotation * Vec3::Y * c.half_length).abs();
                return Some(around(pose.translation, axis + Vec3::splat(c.radius)));
            }
            ColliderShape::Cuboid(b) => b.half_size,
            ColliderShape::HalfSpace(_) => return None,
        };
        Some(rotated_box(pose, Vec3::ZERO, half))
    }
}

/// A collider shape the solver knows only through queries, such as another physics engine's
/// convex hull, triangle mesh or heightfield. Distances must be exact Euclidean distances (the
/// swept test steps along a particle's path by them).
pub trait Surface: Send + Sync + Debug {
    /// Signed distance from local point `p` to the surface (negative inside) and the outward unit
    /// normal at the nearest surface point. A shell (see [`Self::is_shell`]) has no inside: its
    /// distance is never negative and its normal points from the nearest surface point to `p`.
    fn signed_distance(&self, p: Vec3) -> (f32, Vec3);
    /// The shape's bounding box `(min, max)` in its own frame.
    fn local_bounds(&self) -> (Vec3, Vec3);
    /// Whether the shape is convex: its signed distance is then convex along any line, which the
    /// test for a particle that went through the shape relies on.
    fn is_convex(&self) -> bool;
    /// Whether the shape is an open surface (a triangle mesh, a heightfield) that a particle may
    /// meet from either side.
    fn is_shell(&self) -> bool;
    /// Whether the straight segment from `a` to `b` (local points) crosses the surface.
    fn crosses(&self, a: Vec3, b: Vec3) -> bool;
}

/// The shape of a [`Collider`] as the solver sees it.
#[derive(Debug, Clone)]
pub enum Shape {
    /// One of the built-in shapes, with exact closed-form queries.
    Primitive(ColliderShape),
    /// Any other shape, through its [`Surface`] queries.
    Surface(Arc<dyn Surface>),
}

impl From<ColliderShape> for Shape {
    fn from(shape: ColliderShape) -> Self {
        Shape::Primitive(shape)
    }
}

impl PartialEq for Shape {
    /// Primitives by value, surfaces by identity.
    fn eq(&self, other: &Self) -> bool {
        match (self, other) {
            (Shape::Primitive(a), Shape::Primitive(b)) => a == b,
            (Shape::Surface(a), Shape::Surface(b)) => Arc::ptr_eq(a, b),
            _ => false,
        }
    }
}

impl Shape {
    /// See [`ColliderShape::signed_distance`] and [`Surface::signed_distance`].
    pub fn signed_distance(&self, p: Vec3) -> (f32, Vec3) {
        match self {
            Shape::Primitive(s) => s.signed_distance(p),
            Shape::Surface(s) => s.signed_distance(p),
        }
    }

    /// The primitive, if the shape is one.
    pub fn primitive(&self) -> Option<&ColliderShape> {
        match self {
            Shape::Primitive(s) => Some(s),
            Shape::Surface(_) => None,
        }
    }

    /// Checks a primitive's dimensions, or that a surface's bounds are finite and ordered.
    pub fn validate(&self) -> Result<(), ClothError> {
        match self {
            Shape::Primitive(s) => s.validate(),
            Shape::Surface(s) => {
                let (lo, hi) = s.local_bounds();
                if lo.is_finite() && hi.is_finite() && lo.cmple(hi).all() {
                    Ok(())
                } else {
                    Err(ClothError::InvalidValue {
                        field: "collider.bounds",
                        expected: "a finite box",
                        value: f64::NAN,
                    })
                }
            }
        }
    }

    /// See [`ColliderShape::near`]; a surface's ball is its bounding box's.
    pub(super) fn near(&self, pose: &Pose) -> (Near, f32) {
        match self {
            Shape::Primitive(s) => s.near(pose),
            Shape::Surface(s) => {
                let (lo, hi) = s.local_bounds();
                let centre = 0.5 * (lo + hi);
                (
                    Near::Point(pose.transform_point(centre)),
                    0.5 * (hi - lo).length(),
                )
            }
        }
    }

    /// See [`ColliderShape::bounds`]; a surface's is its rotated bounding box's.
    pub(super) fn bounds(&self, pose: &Pose) -> Option<(Vec3, Vec3)> {
        match self {
            Shape::Primitive(s) => s.bounds(pose),
            Shape::Surface(s) => {
                let (lo, hi) = s.local_bounds();
                Some(rotated_box(pose, 0.5 * (lo + hi), 0.5 * (hi - lo)))
            }
        }
    }
}

/// The axis-aligned bounding box `(min, max)` of `positions` (min > max when empty).
pub fn bounds(positions: &[Vec3]) -> (Vec3, Vec3) {
    // Eight vectors at a time as 24 values, each kept in its own running minimum and maximum
    // (value `k` of a block is always coordinate `k mod 3`): a loop the compiler vectorizes.
    const BLOCK: usize = 24;
    let (blocks, rest) = bytemuck::cast_slice::<Vec3, f32>(positions).as_chunks::<BLOCK>();
    let (mut lo, mut hi) = ([f32::INFINITY; BLOCK], [f32::NEG_INFINITY; BLOCK]);
    for block in blocks {
        for k in 0..BLOCK {
            (lo[k], hi[k]) = (lo[k].min(block[k]), hi[k].max(block[k]));
        }
    }
    let (mut min, mut max) = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for k in 0..BLOCK {
        (min[k % 3], max[k % 3]) = (min[k % 3].min(lo[k]), max[k % 3].max(hi[k]));
    }
    let rest = rest.as_chunks::<3>().0.iter().map(|p| Vec3::from_array(*p));
    rest.fold((min, max), |(lo, hi), p| (lo.min(p), hi.max(p)))
}

/// World-space bounding box of the local box with centre `centre` and half size `half` at `pose`.
fn rotated_box(pose: &Pose, centre: Vec3, half: Vec3) -> (Vec3, Vec3) {
    let r = Mat3::from_quat(pose.rotation);
    let extent = r.x_axis.abs() * half.x + r.y_axis.abs() * half.y + r.z_axis.abs() * half.z;
    around(pose.transform_point(centre), extent)
}

fn around(centre: Vec3, half: Vec3) -> (Vec3, Vec3) {
    (centre - half, centre + half)
}

/// Below this distance from a ball's centre, [`radial`] takes +Y as the normal.
const CENTRE: f32 = 1e-12;

/// Distance to a ball of radius `r` about the origin, with the radial normal (+Y at the centre).
#[inline(always)]
fn radial(p: Vec3, r: f32) -> (f32, Vec3) {
    let len = p.length();
    let n = if len > CENTRE { p / len } else { Vec3::Y };
    (len - r, n)
}

/// [`radial`] of each point, coordinate by coordinate (see
/// [`ColliderShape::signed_distances`]).
#[inline(always)]
fn radial_each<const N: usize>(p: &[Vec3; N], r: f32) -> [(f32, Vec3); N] {
    let [x, y, z] = [p.map(|p| p.x), p.map(|p| p.y), p.map(|p| p.z)];
    let len: [f32; N] = std::array::from_fn(|k| (x[k] * x[k] + y[k] * y[k] + z[k] * z[k]).sqrt());
    let [nx, ny, nz] = [x, y, z].map(|c| std::array::from_fn::<f32, N, _>(|k| c[k] / len[k]));
    std::array::from_fn(|k| {
        let n = if len[k] > CENTRE {
            Vec3::new(nx[k], ny[k], nz[k])
        } else {
            Vec3::Y
        };
        (len[k] - r, n)
    })
}

/// The point of a capsule's axis (along local Y, `half_length` each way) nearest `p`.
#[inline(always)]
fn capsule_axis(p: Vec3, half_length: f32) -> Vec3 {
    Vec3::new(0.0, p.y.clamp(-half_length, half_length), 0.0)
}

/// Exact signed distance to an axis-aligned box of half size `h`, with the outward normal of the
/// nearest face, edge or corner.
fn box_distance(p: Vec3, h: Vec3) -> (f32, Vec3) {
    let q = p.abs() - h;
    let outside = q.max(Vec3::ZERO);
    let out_len = outside.length();
    if out_len > 0.0 {
        return (out_len, (outside / out_len) * p.signum());
    }
    // Inside: the nearest face is the one with the largest (least negative) q.
    let (d, axis) = if q.x >= q.y && q.x >= q.z {
        (q.x, Vec3::X)
    } else if q.y >= q.z {
        (q.y, Vec3::Y)
    } else {
        (q.z, Vec3::Z)
    };
    (d, axis * p.signum())
}

/// Coulomb friction coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize, Reflect)]
#[serde(deny_unknown_fields)]
pub struct Friction {
    /// Static coefficient `μ_s`: a contact sticks while its tangential push is at most `μ_s` times
    /// its normal push.
    pub static_coefficient: f32,
    /// Kinetic coefficient `μ_k`: a sliding contact loses `μ_k` times its normal velocity change
    /// from its tangential velocity.
    pub kinetic_coefficient: f32,
}

impl Friction {
    /// Frictionless contact.
    pub const NONE: Friction = Friction {
        static_coefficient: 0.0,
        kinetic_coefficient: 0.0,
    };

    /// Static and kinetic coefficient both `mu`.
    pub fn new(mu: f32) -> Self {
        Self {
            static_coefficient: mu,
            kinetic_coefficient: mu,
        }
    }

    /// Checks both coefficients are finite and non-negative.
    pub fn validate(&self) -> Result<(), ClothError> {
        non_negative("friction.static_coefficient", self.static_coefficient)?;
        non_negative("friction.kinetic_coefficient", self.kinetic_coefficient)
    }
}

impl Default for Friction {
    /// `μ_s = 0.5`, `μ_k = 0.4`, about cotton on wood.
    fn default() -> Self {
        Self {
            static_coefficient: 0.5,
            kinetic_coefficient: 0.4,
        }
    }
}

/// A rigid placement: rotation, then translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    /// Orientation.
    pub rotation: Quat,
    /// Position, m.
    pub translation: Vec3,
}

impl Pose {
    /// The identity placement.
    pub const IDENTITY: Pose = Pose {
        rotation: Quat::IDENTITY,
        translation: Vec3::ZERO,
    };

    /// A placement at `translation` with no rotation.
    pub fn from_translation(translation: Vec3) -> Self {
        Self {
            rotation: Quat::IDENTITY,
            translation,
        }
    }

    /// Local point to world.
    #[inline]
    pub fn transform_point(&self, p: Vec3) -> Vec3 {
        self.rotate(p) + self.translation
    }

    /// World point to local (an unrotated pose skips the rotation, see [`Self::rotate`]).
    #[inline]
    pub fn inverse_transform_point(&self, p: Vec3) -> Vec3 {
        let p = p - self.translation;
        if self.rotation == Quat::IDENTITY {
            p
        } else {
            self.rotation.inverse() * p
        }
    }

    /// Local direction to world. An unrotated pose (a floor, most colliders) skips the rotation,
    /// which would give the same vector but for the sign of zero coordinates.
    #[inline]
    pub fn rotate(&self, v: Vec3) -> Vec3 {
        if self.rotation == Quat::IDENTITY {
            v
        } else {
            self.rotation * v
        }
    }

    /// The placement a fraction `t` of the way to `other` (linear in position, spherical in
    /// rotation).
    pub fn lerp(&self, other: &Pose, t: f32) -> Pose {
        Pose {
            rotation: self.rotation.slerp(other.rotation, t),
            translation: self.translation.lerp(other.translation, t),
        }
    }
}

/// A collider as the solver sees it for one step: its shape, where it is at the start and at the
/// end of the step (it moves between them linearly, rotating at constant rate), and its contact
/// properties.
#[derive(Debug, Clone, PartialEq)]
pub struct Collider {
    /// Shape in the collider's frame (already scaled).
    pub shape: Shape,
    /// Pose at the start of the step.
    pub start: Pose,
    /// Pose at the end of the step.
    pub end: Pose,
    /// Friction against the cloth.
    pub friction: Friction,
    /// Thickness kept between the surface and the cloth's particles, m.
    pub margin: f32,
    /// Collision layers: the collider touches a cloth whose mask shares a bit with these.
    pub layers: u32,
    /// Layers the collider accepts: it touches a cloth only if the cloth's mask also shares a bit
    /// with these (every layer for the crate's own colliders; an avian collider's filters).
    pub filters: u32,
    /// Inverse mass of the body the collider belongs to, 1/kg. 0 (the crate's own colliders):
    /// it moves from `start` to `end` whatever the cloth does. Above 0, for a cloth stepped with
    /// [`Environment::two_way`](crate::sim::Environment::two_way), the impulses it gives the
    /// particles slow it within the step, substep by substep (its velocity changes by minus their
    /// sum times this, its angular velocity by [`Self::inv_inertia`] times minus their moment about
    /// its origin), so that a body does not sink into or rock on the cloth for a whole step before
    /// its reaction arrives.
    pub inv_mass: f32,
    /// Inverse inertia tensor of that body, world axes, 1/(kg m²), taken about the collider's
    /// origin (zero: the collider turns as given).
    pub inv_inertia: Mat3,
    /// Acceleration of that body over the step from everything but the cloth (gravity), m/s².
    /// A collider that gives way gains it substep by substep; one that moves as given ends the
    /// step `acceleration · dt²` beyond `end` (where a semi-implicit Euler step would put it).
    pub acceleration: Vec3,
}

impl Collider {
    /// A collider that stays at `pose` during the step, on every layer.
    pub fn fixed(shape: impl Into<Shape>, pose: Pose, friction: Friction, margin: f32) -> Self {
        Self {
            shape: shape.into(),
            start: pose,
            end: pose,
            friction,
            margin,
            layers: u32::MAX,
            filters: u32::MAX,
            inv_mass: 0.0,
            inv_inertia: Mat3::ZERO,
            acceleration: Vec3::ZERO,
        }
    }

    /// Whether the collider touches a cloth with collision mask `mask`.
    pub fn touches(&self, mask: u32) -> bool {
        self.layers & mask != 0 && self.filters & mask != 0
    }

    /// Checks the shape, friction and margin.
    pub fn validate(&self) -> Result<(), ClothError> {
        self.shape.validate()?;
        self.friction.validate()?;
        non_negative("collider.margin", self.margin)?;
        non_negative("collider.inv_mass", self.inv_mass)?;
        for (field, finite) in [
            ("collider.inv_inertia", self.inv_inertia.is_finite()),
            ("collider.acceleration", self.acceleration.is_finite()),
        ] {
            if !finite {
                return Err(ClothError::InvalidValue {
                    field,
                    expected: "finite",
                    value: f64::NAN,
                });
            }
        }
        let finite = |p: &Pose| p.translation.is_finite() && p.rotation.is_finite();
        if finite(&self.start) && finite(&self.end) {
            Ok(())
        } else {
            Err(ClothError::InvalidValue {
                field: "collider transform",
                expected: "finite",
                value: f64::NAN,
            })
        }
    }
}

/// What a particle's clearance from a collider is measured to (see [`ContactState::clearances`](super::narrow::ContactState::clearances)):
/// the centre of its bounding ball, or, for a half-space, its plane.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Near {
    /// Euclidean distance from the point.
    Point(Vec3),
    /// Signed distance from the plane through the point with the unit normal.
    Plane(Vec3, Vec3),
}

impl Near {
    /// Distance (signed for a plane) of `x`.
    #[inline(always)]
    pub fn distance(&self, x: Vec3) -> f32 {
        match *self {
            Near::Point(c) => (x - c).length(),
            Near::Plane(c, n) => (x - c).dot(n),
        }
    }
}
