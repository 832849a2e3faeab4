//! Cloth in an [avian3d](https://docs.rs/avian3d) physics world (feature `avian`):
//! [`ClothAvianPlugin`].
//!
//! Every avian [`Collider`] acts on every cloth whose
//! [`collision_mask`](crate::ClothConfig::collision_mask) meets its [`CollisionLayers`], with no
//! component to add: its shape, pose and velocity are read each cloth step, after the crate's
//! own [`ClothCollider`](crate::ClothCollider)s are gathered.
//!
//! # Shapes
//! Balls, capsules, cuboids and half-spaces (scaled ones too, and the parts of a compound) become
//! the solver's exact primitives. Every other shape (convex hulls, cylinders, cones, round shapes,
//! triangle meshes, heightfields, polylines, voxels) is queried through parry's point projection
//! and ray cast ([`Surface`]): convex shapes with their inside, the open ones (triangle meshes,
//! heightfields, polylines, segments, triangles) as two-sided shells that the cloth keeps its
//! margin from on whichever side it is.
//!
//! # Motion
//! avian steps in `FixedPostUpdate`, after the cloths' `FixedUpdate` step. So that the cloth meets
//! a body where the body will be at the end of the tick rather than a tick late, a moving body's
//! colliders are carried over the cloth's step from their pose now along the body's velocity,
//! and a dynamic body's also by gravity (ending where avian's semi-implicit step would put it, or,
//! for a two-way cloth, gaining it substep by substep): exact for a kinematic body, and within
//! one step's unforeseen acceleration (contacts with other bodies) for a dynamic one.
//!
//! # Two-way coupling
//! For a cloth with [`ClothPushesBodies`], a dynamic body's colliders give way within the cloth's
//! step: substep by substep, the impulses they give the particles change their velocity and spin
//! (by the body's mass and inertia) and gravity speeds them up, so a body lands on the cloth
//! rather than sinking into it for a whole step. After the step the body takes the opposite of
//! those impulses, with their moment about its centre of mass, as a force and torque over avian's
//! coming step (through [`Forces`]): momentum is exchanged, not created, and a body resting on the
//! cloth feels a steady push that balances its weight. Each collider of a body gives way as if it
//! were the whole body and turns about its own origin; a body of several colliders, or one whose
//! centre of mass lies off its collider's origin, is approximated so within a step (what it takes
//! afterwards is exact).
//!
//! # Filtering
//! [`Sensor`]s are ignored, and so is a collider with [`NoClothContact`]. A cloth with mask `m`
//! meets a collider when `m` shares a bit with both its memberships and its filters (the cloth's
//! mask acts as both of its own).

use std::fmt;
use std::sync::Arc;

use avian3d::parry::query::Ray;
use avian3d::parry::shape::{SharedShape, TypedShape};
use avian3d::prelude::{
    AngularVelocity, Collider, ColliderOf, ColliderTransform, CollisionLayers,
    ComputedAngularInertia, ComputedCenterOfMass, ComputedMass, Forces, Gravity, GravityScale,
    LinearVelocity, Position, RigidBody, Rotation, Sensor, WriteRigidBodyForces,
};
use bevy::app::{App, Plugin};
use bevy::ecs::prelude::*;
use bevy::log::error;
use bevy::math::primitives::{Capsule3d, Cuboid, InfinitePlane3d, Sphere};
use bevy::math::{Dir3, Mat3, Quat, Vec3};
use bevy::reflect::prelude::*;
use bevy::time::Time;

pub use crate::components::ClothPushesBodies;
use crate::components::{ClothState, DEFAULT_COLLIDER_MARGIN};
use crate::plugin::{ClothSchedule, ColliderSnapshot, gather_colliders, step_cloths};
use crate::sim::{self, ColliderShape, Pose, Shape, Surface};
use crate::{ClothInvalid, ClothSystems};

/// Makes avian's colliders act on cloths, and cloths with [`ClothPushesBodies`] push dynamic
/// bodies back. Add it with avian's `PhysicsPlugins` and [`ClothPlugin`](crate::ClothPlugin) (in
/// any order).
///
/// # Example
/// ```
/// use avian3d::prelude::*;
/// use bevy::prelude::*;
/// use bevy_cloth::avian::ClothAvianPlugin;
/// use bevy_cloth::prelude::*;
///
/// let mut app = App::new();
/// app.add_plugins((MinimalPlugins, TransformPlugin, AssetPlugin::default()))
///     .add_plugins(bevy::mesh::MeshPlugin)
///     .add_plugins((PhysicsPlugins::default(), ClothPlugin::default(), ClothAvianPlugin));
/// let mut commands = app.world_mut().commands();
/// // A hammock pinned at its four corners that holds up what falls into it...
/// commands.spawn((
///     Cloth::grid(GridSpec::new(32, 32, 0.05)),
///     ClothPins::new([0, 31, 992, 1023]),
///     ClothPushesBodies, // two-way: avian's dynamic bodies feel the cloth
/// ));
/// // ...and a crate: an ordinary avian body, nothing cloth-specific.
/// commands.spawn((RigidBody::Dynamic, Collider::cuboid(0.3, 0.3, 0.3), Transform::from_xyz(0.0, 1.0, 0.0)));
/// app.world_mut().flush();
/// ```
#[derive(Debug, Default, Clone, Copy)]
pub struct ClothAvianPlugin;

impl Plugin for ClothAvianPlugin {
    fn build(&self, app: &mut App) {
        app.register_type::<NoClothContact>()
            .register_type::<ClothContact>()
            .init_resource::<BodyLinks>();
    }

    fn finish(&self, app: &mut App) {
        let Some(schedule) = app.world().get_resource::<ClothSchedule>().copied() else {
            error!("ClothAvianPlugin needs ClothPlugin: avian colliders will not act on cloths");
            return;
        };
        app.add_systems(
            schedule.0,
            (
                gather_avian_colliders
                    .after(gather_colliders)
                    .in_set(ClothSystems::Prepare),
                push_bodies.after(step_cloths).in_set(ClothSystems::Step),
            )
                .run_if(any_with_component::<ClothState>),
        );
    }
}

/// On an avian collider: cloths ignore it.
#[derive(Component, Debug, Default, Clone, Copy, PartialEq, Eq, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct NoClothContact;

/// On an avian collider: how cloths meet it. Without it, the margin is
/// [`DEFAULT_COLLIDER_MARGIN`] and the friction is avian's [`Friction`](avian3d::prelude::Friction)
/// on the collider if it has one (static and dynamic coefficients; the combine rule does not
/// apply), else the crate's default [`Friction`](crate::sim::Friction).
#[derive(Component, Debug, Clone, Copy, PartialEq, Reflect)]
#[reflect(Component, Debug, Default)]
pub struct ClothContact {
    /// Distance kept between the surface and the cloth's particles, m.
    pub margin: f32,
    /// Coulomb friction against cloth; `None` takes it as described above.
    pub friction: Option<sim::Friction>,
}

impl Default for ClothContact {
    fn default() -> Self {
        Self {
            margin: DEFAULT_COLLIDER_MARGIN,
            friction: None,
        }
    }
}

/// For each collider of this step's [`ColliderSnapshot`] from index `first` on, the dynamic body
/// that takes the cloths' reaction and the lever from its centre of mass to the collider's origin
/// at the end of the step.
#[derive(Resource, Debug, Default)]
struct BodyLinks {
    first: usize,
    bodies: Vec<Option<(Entity, Vec3)>>,
}

impl BodyLinks {
    fn get(&self, collider: usize) -> Option<(Entity, Vec3)> {
        collider
            .checked_sub(self.first)
            .and_then(|i| self.bodies.get(i).copied().flatten())
    }
}

/// A body's rigid motion over the cloth's step, as avian will integrate it from its velocities
/// (without gravity's pull, which the solver adds itself; see `sim::Collider::acceleration`).
#[derive(Debug, Clone, Copy)]
struct Motion {
    /// Centre of mass now, world.
    com: Vec3,
    /// Velocity of the centre of mass over the step.
    velocity: Vec3,
    /// Rotation over the step.
    spin: Quat,
    dt: f32,
}

impl Motion {
    const STILL: Motion = Motion {
        com: Vec3::ZERO,
        velocity: Vec3::ZERO,
        spin: Quat::IDENTITY,
        dt: 0.0,
    };

    /// Where `pose` is at the end of the step.
    fn carry(&self, pose: Pose) -> Pose {
        Pose {
            rotation: (self.spin * pose.rotation).normalize(),
            translation: self.com
                + self.velocity * self.dt
                + self.spin * (pose.translation - self.com),
        }
    }

    /// The centre of mass at the end of the step.
    fn com_end(&self) -> Vec3 {
        self.com + self.velocity * self.dt
    }
}

type ColliderItem<'a> = (
    Entity,
    &'a Collider,
    &'a Position,
    &'a Rotation,
    Option<&'a ColliderOf>,
    Option<&'a ColliderTransform>,
    Option<&'a CollisionLayers>,
    Option<&'a avian3d::prelude::Friction>,
    Option<&'a ClothContact>,
);

type BodyItem<'a> = (
    &'a RigidBody,
    &'a Position,
    &'a Rotation,
    Option<&'a LinearVelocity>,
    Option<&'a AngularVelocity>,
    Option<&'a ComputedCenterOfMass>,
    Option<&'a GravityScale>,
    Option<&'a ComputedMass>,
    Option<&'a ComputedAngularInertia>,
);

/// Appends every avian collider, carried over the step by its body's motion, to the step's
/// colliders, and records which dynamic body each belongs to.
fn gather_avian_colliders(
    mut snapshot: ResMut<ColliderSnapshot>,
    mut links: ResMut<BodyLinks>,
    colliders: Query<ColliderItem, (Without<Sensor>, Without<NoClothContact>)>,
    bodies: Query<BodyItem>,
    gravity: Option<Res<Gravity>>,
    time: Res<Time>,
    mut parts: Local<Vec<(Shape, Pose)>>,
) {
    let dt = time.delta_secs();
    links.first = snapshot.0.len();
    links.bodies.clear();
    let gravity = gravity.map_or(Vec3::ZERO, |g| g.0);
    for (entity, collider, position, rotation, of, offset, layers, friction, contact) in &colliders
    {
        let own = Pose {
            rotation: rotation.0,
            translation: position.0,
        };
        let body = of.and_then(|of| bodies.get(of.body).ok().map(|b| (of.body, b)));
        // A child collider's own `Position` is refreshed only at the start of avian's step: its
        // pose now is the body's composed with its offset.
        let (pose, motion, acceleration, dynamic) = match body {
            Some((body_entity, (kind, body_pos, body_rot, v, w, com, scale, mass, inertia))) => {
                let body_pose = Pose {
                    rotation: body_rot.0,
                    translation: body_pos.0,
                };
                let pose = match offset {
                    Some(o) if body_entity != entity => compose(
                        &body_pose,
                        &Pose {
                            rotation: o.rotation.0,
                            translation: o.translation,
                        },
                    ),
                    _ => own,
                };
                let motion = if kind.is_static() {
                    Motion::STILL
                } else {
                    Motion {
                        com: body_pose.transform_point(com.map_or(Vec3::ZERO, |c| c.0)),
                        velocity: v.map_or(Vec3::ZERO, |v| v.0),
                        spin: Quat::from_scaled_axis(w.map_or(Vec3::ZERO, |w| w.0) * dt),
                        dt,
                    }
                };
                let acceleration = if kind.is_dynamic() {
                    gravity * scale.map_or(1.0, |s| s.0)
                } else {
                    Vec3::ZERO
                };
                let inv_mass = mass.map_or(0.0, |m| m.inverse());
                let inv_inertia =
                    inertia.map_or(Mat3::ZERO, |i| Mat3::from(i.rotated(body_rot.0).inverse()));
                let dynamic = (kind.is_dynamic() && inv_mass.is_finite() && inv_mass > 0.0)
                    .then_some((body_entity, inv_mass, inv_inertia));
                (pose, motion, acceleration, dynamic)
            }
            None => (own, Motion::STILL, Vec3::ZERO, None),
        };
        let margin = contact.map_or(DEFAULT_COLLIDER_MARGIN, |c| c.margin);
        let friction = contact.and_then(|c| c.friction).unwrap_or_else(|| {
            friction.map_or_else(sim::Friction::default, |f| sim::Friction {
                static_coefficient: f.static_coefficient,
                kinetic_coefficient: f.dynamic_coefficient,
            })
        });
        let layers = layers.copied().unwrap_or_default();
        shapes_of(collider.shape_scaled(), Pose::IDENTITY, &mut parts);
        for (shape, local) in parts.drain(..) {
            let start = compose(&pose, &local);
            let end = if motion.dt > 0.0 {
                motion.carry(start)
            } else {
                start
            };
            let c = sim::Collider {
                shape,
                start,
                end,
                friction,
                margin,
                layers: layers.memberships.0,
                filters: layers.filters.0,
                inv_mass: dynamic.map_or(0.0, |(_, w, _)| w),
                inv_inertia: dynamic.map_or(Mat3::ZERO, |(_, _, i)| i),
                acceleration,
            };
            match c.validate() {
                Ok(()) => {
                    let lever = dynamic.map(|(b, ..)| (b, end.translation - motion.com_end()));
                    snapshot.0.push(c);
                    links.bodies.push(lever);
                }
                Err(e) => bevy::log::warn_once!("avian collider {entity}: {e}; cloths ignore it"),
            }
        }
    }
}

/// Gives each dynamic body the opposite of what the cloths with [`ClothPushesBodies`] took from
/// its colliders in this step, as a force and torque over avian's coming step of the same
/// length (so that a body resting on a cloth feels a steady push that balances its weight, not a
/// kick per step).
fn push_bodies(
    links: Res<BodyLinks>,
    cloths: Query<&ClothState, (With<ClothPushesBodies>, Without<ClothInvalid>)>,
    mut bodies: Query<Forces>,
    time: Res<Time>,
) {
    let dt = time.delta_secs();
    if dt <= 0.0 {
        return;
    }
    for state in &cloths {
        if state.failure.is_some() {
            continue;
        }
        for r in state.sim.reactions() {
            let Some((body, lever)) = links.get(r.collider) else {
                continue;
            };
            if let Ok(mut forces) = bodies.get_mut(body) {
                forces.apply_force(-r.impulse / dt);
                forces.apply_torque(-(r.moment + lever.cross(r.impulse)) / dt);
            }
        }
    }
}

/// `outer` then `inner`: the pose of a frame placed at `inner` in `outer`'s frame.
fn compose(outer: &Pose, inner: &Pose) -> Pose {
    Pose {
        rotation: outer.rotation * inner.rotation,
        translation: outer.transform_point(inner.translation),
    }
}

/// The solver's shapes for a parry shape placed at `local` in the collider's frame: primitives
/// where one is exact, a compound's parts one by one, any other shape as a [`Surface`].
fn shapes_of(shape: &SharedShape, local: Pose, out: &mut Vec<(Shape, Pose)>) {
    let primitive = match shape.as_typed_shape() {
        TypedShape::Ball(b) => ColliderShape::Sphere(Sphere::new(b.radius)),
        TypedShape::Cuboid(c) => ColliderShape::Cuboid(Cuboid {
            half_size: c.half_extents,
        }),
        TypedShape::Capsule(c) => {
            // The solver's capsule lies along Y, centred: place it on parry's segment, turned as
            // little as possible (avian's own capsules run from +Y to -Y: no turn at all).
            let axis = c.segment.b - c.segment.a;
            let axis = if axis.y < 0.0 { -axis } else { axis };
            let length = axis.length();
            let rotation = if length > 0.0 {
                Quat::from_rotation_arc(Vec3::Y, axis / length)
            } else {
                Quat::IDENTITY
            };
            let centre = Pose {
                rotation,
                translation: 0.5 * (c.segment.a + c.segment.b),
            };
            out.push((
                ColliderShape::Capsule(Capsule3d {
                    radius: c.radius,
                    half_length: 0.5 * length,
                })
                .into(),
                compose(&local, &centre),
            ));
            return;
        }
        TypedShape::HalfSpace(h) => ColliderShape::HalfSpace(InfinitePlane3d {
            normal: Dir3::new(h.normal).unwrap_or(Dir3::Y),
        }),
        TypedShape::Compound(c) => {
            for (pose, part) in c.shapes() {
                let inner = Pose {
                    rotation: pose.rotation,
                    translation: pose.translation,
                };
                shapes_of(part, compose(&local, &inner), out);
            }
            return;
        }
        typed => {
            let shell = matches!(
                typed,
                TypedShape::TriMesh(_)
                    | TypedShape::HeightField(_)
                    | TypedShape::Polyline(_)
                    | TypedShape::Segment(_)
                    | TypedShape::Triangle(_)
            );
            out.push((
                Shape::Surface(Arc::new(ParryShape {
                    shape: shape.clone(),
                    shell,
                })),
                local,
            ));
            return;
        }
    };
    out.push((primitive.into(), local));
}

/// A parry shape as a [`Surface`].
struct ParryShape {
    shape: SharedShape,
    shell: bool,
}

impl fmt::Debug for ParryShape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ParryShape")
            .field("type", &self.shape.shape_type())
            .field("shell", &self.shell)
            .finish()
    }
}

impl Surface for ParryShape {
    fn signed_distance(&self, p: Vec3) -> (f32, Vec3) {
        let projection = self.shape.project_local_point(p, false);
        let inside = projection.is_inside && !self.shell;
        let offset = p - projection.point;
        let distance = offset.length();
        let sign = if inside { -1.0 } else { 1.0 };
        if distance > 1e-7 {
            return (sign * distance, sign * offset / distance);
        }
        // On the surface: the normal of the feature it lies on.
        let (projection, feature) = self.shape.project_local_point_and_get_feature(p);
        let normal = self
            .shape
            .feature_normal_at_point(feature, projection.point)
            .unwrap_or(Vec3::Y);
        (sign * distance, normal)
    }

    fn local_bounds(&self) -> (Vec3, Vec3) {
        let aabb = self.shape.compute_local_aabb();
        (aabb.mins, aabb.maxs)
    }

    fn is_convex(&self) -> bool {
        self.shape.is_convex()
    }

    fn is_shell(&self) -> bool {
        self.shell
    }

    fn crosses(&self, a: Vec3, b: Vec3) -> bool {
        self.shape.intersects_local_ray(&Ray::new(a, b - a), 1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The signed distance of local point `p` to the solver's shapes for `collider` (the nearest
    /// part's), and parry's own (negative inside; unsigned for a shell).
    fn both(collider: &Collider, p: Vec3) -> (f32, f32) {
        let mut parts = Vec::new();
        shapes_of(collider.shape_scaled(), Pose::IDENTITY, &mut parts);
        let ours = parts
            .iter()
            .map(|(shape, pose)| shape.signed_distance(pose.inverse_transform_point(p)).0)
            .fold(f32::INFINITY, f32::min);
        let (q, inside) = collider.project_point(Vec3::ZERO, Quat::IDENTITY, p, false);
        let shell = parts
            .iter()
            .any(|(s, _)| matches!(s, Shape::Surface(s) if s.is_shell()));
        let sign = if inside && !shell { -1.0 } else { 1.0 };
        (ours, sign * q.distance(p))
    }

    /// Points around the origin, inside and outside shapes of about half a metre.
    fn samples() -> impl Iterator<Item = Vec3> {
        (0..400).map(|k| {
            let k = k as f32;
            let r = 0.05 + 0.9 * ((k * 0.618_034) % 1.0);
            let dir = Vec3::new((k * 2.39).cos(), (k * 0.77).sin(), (k * 1.31).sin());
            dir.normalize() * r
        })
    }

    #[test]
    fn the_solver_shapes_measure_what_parry_measures() {
        let hull = Collider::convex_hull(vec![
            Vec3::new(-0.3, -0.1, -0.2),
            Vec3::new(0.35, -0.1, -0.1),
            Vec3::new(0.0, -0.1, 0.4),
            Vec3::new(0.05, 0.4, 0.0),
        ])
        .expect("a hull");
        let cases = [
            ("ball", Collider::sphere(0.3)),
            ("capsule along +Y", Collider::capsule(0.15, 0.4)),
            (
                "capsule between two points",
                Collider::capsule_endpoints(
                    0.1,
                    Vec3::new(-0.3, 0.1, 0.05),
                    Vec3::new(0.2, -0.2, 0.3),
                ),
            ),
            ("cuboid", Collider::cuboid(0.6, 0.2, 0.4)),
            (
                "half-space",
                Collider::half_space(Vec3::new(0.3, 1.0, -0.2)),
            ),
            (
                "compound",
                Collider::compound(vec![
                    (
                        Position::from_xyz(0.2, 0.0, 0.0),
                        Rotation::from(Quat::from_rotation_z(0.7)),
                        Collider::capsule(0.1, 0.3),
                    ),
                    (
                        Position::from_xyz(-0.2, 0.1, 0.0),
                        Rotation::default(),
                        Collider::cuboid(0.2, 0.3, 0.2),
                    ),
                ]),
            ),
            ("cylinder", Collider::cylinder(0.25, 0.5)),
            ("cone", Collider::cone(0.3, 0.5)),
            ("convex hull", hull),
            (
                "triangle mesh",
                Collider::trimesh(
                    vec![
                        Vec3::new(-0.5, 0.0, -0.5),
                        Vec3::new(0.5, 0.1, -0.5),
                        Vec3::new(-0.5, -0.1, 0.5),
                        Vec3::new(0.5, 0.0, 0.5),
                    ],
                    vec![[0, 2, 1], [1, 2, 3]],
                ),
            ),
        ];
        for (name, collider) in cases {
            for p in samples() {
                let (ours, parry) = both(&collider, p);
                // A compound's parts overlap: inside it, the nearest part's surface is not the
                // union's. Outside (and on a part's surface) they agree.
                if name == "compound" && parry < 0.0 {
                    continue;
                }
                assert!(
                    (ours - parry).abs() < 1e-5,
                    "{name} at {p}: {ours} here, {parry} by parry"
                );
            }
        }
    }

    #[test]
    fn a_shell_is_crossed_only_by_a_path_through_it() {
        let mut parts = Vec::new();
        let mesh = Collider::trimesh(
            vec![
                Vec3::new(-1.0, 0.0, -1.0),
                Vec3::new(1.0, 0.0, -1.0),
                Vec3::new(-1.0, 0.0, 1.0),
            ],
            vec![[0, 2, 1]],
        );
        shapes_of(mesh.shape_scaled(), Pose::IDENTITY, &mut parts);
        let Shape::Surface(surface) = &parts[0].0 else {
            panic!("a triangle mesh is a surface");
        };
        assert!(surface.is_shell());
        let (above, below) = (Vec3::new(-0.5, 0.1, -0.5), Vec3::new(-0.5, -0.1, -0.5));
        assert!(surface.crosses(above, below));
        assert!(!surface.crosses(above, above + Vec3::X * 0.2));
        // Beside the triangle, past its long edge: no crossing.
        assert!(!surface.crosses(Vec3::new(0.6, 0.1, 0.6), Vec3::new(0.6, -0.1, 0.6)));
        // Below the surface the distance stays positive and the normal points down, away from it.
        let (d, n) = surface.signed_distance(below);
        assert!((d - 0.1).abs() < 1e-6 && n.y < -0.99, "{d} {n}");
    }
}
