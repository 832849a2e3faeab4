//! Colliders and wind.

use super::*;

// ---------------------------------------------------------------------------------------------
// Colliders and wind
// ---------------------------------------------------------------------------------------------

#[test]
fn collider_validation_names_the_field() {
    let ok = ClothCollider::sphere(0.5);
    let pose = Pose::IDENTITY;
    let collider =
        |c: ClothCollider| Collider::fixed(c.shape, pose, c.friction, c.margin).validate();
    assert!(collider(ok).is_ok());
    for (c, field) in [
        (ClothCollider::sphere(f32::NAN), "collider.radius"),
        (ClothCollider::sphere(-1.0), "collider.radius"),
        (ClothCollider::capsule(0.0, 1.0), "collider.radius"),
        (
            ClothCollider::capsule(0.1, f32::INFINITY),
            "collider.half_length",
        ),
        (
            ClothCollider::cuboid(Vec3::new(1.0, 1.0, -1.0)),
            "collider.half_size.z",
        ),
        (ok.with_margin(-0.1), "collider.margin"),
        (ok.with_margin(f32::NAN), "collider.margin"),
        (
            ok.with_friction(Friction::new(-0.5)),
            "friction.static_coefficient",
        ),
        (
            ok.with_friction(Friction {
                static_coefficient: 0.5,
                kinetic_coefficient: f32::INFINITY,
            }),
            "friction.kinetic_coefficient",
        ),
    ] {
        invalid_value(collider(c), field);
    }
    // A zero or non-finite half-space normal becomes +Y (documented); a pose must be finite.
    assert_eq!(
        ClothCollider::half_space(Vec3::ZERO).shape,
        ClothCollider::half_space(Vec3::Y).shape
    );
    let mut moving = Collider::fixed(ok.shape, pose, Friction::default(), 0.01);
    moving.end.translation.x = f32::NAN;
    invalid_value(moving.validate(), "collider transform");
}

fn zone() -> PlacedWindZone {
    PlacedWindZone {
        shape: WindZoneShape::Sphere(1.0),
        to_local: Affine3A::IDENTITY,
        velocity: Vec3::X,
        gusts: None,
        falloff: 0.5,
    }
}

#[test]
fn wind_validation_names_the_field() {
    let field = |f: fn(&mut WindField)| {
        let mut w = WindField {
            air_density: 1.2,
            zones: vec![zone()],
            ..Default::default()
        };
        f(&mut w);
        w.validate()
    };
    assert!(field(|_| {}).is_ok());
    assert!(field(|w| w.air_density = 0.0).is_ok(), "no air, no force");
    assert!(field(|w| w.zones[0].falloff = 1.0).is_ok());
    type Edit = fn(&mut WindField);
    let cases: [(Edit, &str); 13] = [
        (|w| w.air_density = -1.0, "wind.air_density"),
        (|w| w.air_density = f32::NAN, "wind.air_density"),
        (|w| w.velocity.y = f32::INFINITY, "wind.velocity.y"),
        (
            |w| {
                w.gusts = Some(Gusts {
                    strength: f32::NAN,
                    ..Default::default()
                })
            },
            "gusts.strength",
        ),
        (
            |w| {
                w.gusts = Some(Gusts {
                    frequency: -1.0,
                    ..Default::default()
                })
            },
            "gusts.frequency",
        ),
        (
            |w| {
                w.gusts = Some(Gusts {
                    turbulence: f32::INFINITY,
                    ..Default::default()
                })
            },
            "gusts.turbulence",
        ),
        (
            |w| w.zones[0].shape = WindZoneShape::Sphere(0.0),
            "wind_zone.radius",
        ),
        (
            |w| w.zones[0].shape = WindZoneShape::Cuboid(Vec3::new(1.0, f32::NAN, 1.0)),
            "wind_zone.half_size.y",
        ),
        (|w| w.zones[0].velocity.x = f32::NAN, "wind_zone.velocity.x"),
        (|w| w.zones[0].falloff = -0.5, "wind_zone.falloff"),
        (|w| w.zones[0].falloff = 1.5, "wind_zone.falloff"),
        (
            |w| {
                w.zones[0].gusts = Some(Gusts {
                    strength: -1.0,
                    ..Default::default()
                })
            },
            "gusts.strength",
        ),
        (
            |w| w.zones[0].to_local = Affine3A::from_scale(Vec3::ZERO).inverse(),
            "wind_zone transform",
        ),
    ];
    for (f, name) in cases {
        invalid_value(field(f), name);
    }
}
