//! Tearing: a flag in a rising gale tears from its pole, a curtain is holed by a thrown ball, and
//! a 64×64 cloth is cut in two along its middle row. The flag tears under strain ([`Tearing`] on:
//! a spring stretched past 8% splits the cloth there); the ball punches its hole with a
//! [`ClothCut`] along its path as it reaches the curtain, and carries off the piece it knocks out;
//! the square's cut is a plane, its lower half falls. Every tear is logged from its [`ClothTorn`].
//!
//! `cargo run --release --features examples --example tearing`

mod common;

use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_cloth::sim::Cut;

const POLE_HEIGHT: f32 = 3.0;
const POLE_RADIUS: f32 = 0.03;
/// The curtain's plane (z) and where the ball is thrown from.
const CURTAIN_Z: f32 = -1.0;
const BALL_START: Vec3 = Vec3::new(3.0, 2.0, 1.0);
const BALL_VELOCITY: Vec3 = Vec3::new(0.0, 0.0, -6.0);
const BALL_RADIUS: f32 = 0.15;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: tearing",
            focus: Vec3::new(1.6, 1.8, -0.5),
            eye: Vec3::new(1.7, 2.0, 5.0),
        })
        .add_plugins((ClothPlugin::default(), ClothInspectorPlugin))
        // Still air, but for the gale around the flag (a wind zone).
        .insert_resource(Wind::default())
        .add_systems(Startup, setup)
        .add_systems(
            FixedUpdate,
            (rising_gale, throw_ball, cut_in_two).before(ClothSystems::Prepare),
        )
        .add_systems(Update, log_tears)
        .run();
}

/// The thrown ball: where it is headed and whether it has holed the curtain.
#[derive(Component)]
struct Ball {
    holed: bool,
}

#[derive(Component)]
struct Curtain;

/// The square cut in two, until it is.
#[derive(Component)]
struct ToCut;

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let metal = materials.add(StandardMaterial {
        base_color: Color::srgb(0.8, 0.8, 0.82),
        metallic: 0.6,
        ..default()
    });
    commands.spawn((
        Mesh3d(meshes.add(Cylinder::new(POLE_RADIUS, POLE_HEIGHT))),
        MeshMaterial3d(metal.clone()),
        Transform::from_xyz(0.0, POLE_HEIGHT / 2.0, 0.0),
        ClothCollider::capsule(POLE_RADIUS, POLE_HEIGHT / 2.0),
    ));
    commands.spawn((
        Name::new("gale"),
        WindZone {
            shape: WindZoneShape::Cuboid(Vec3::new(1.1, 1.4, 1.2)),
            velocity: Vec3::ZERO,
            gusts: Some(Gusts {
                seed: 7,
                strength: 0.4,
                frequency: 0.8,
                turbulence: 0.25,
            }),
            falloff: 0.2,
        },
        Transform::from_xyz(1.0, 2.2, 0.0),
    ));
    let fabric = common::fabric(&asset_server, &mut materials);
    // The flag: 30×20, pinned along the pole, tearing where the gale stretches it past 8%.
    let (nx, ny, spacing) = (30u32, 20u32, 0.04);
    let (width, height) = ((nx - 1) as f32 * spacing, (ny - 1) as f32 * spacing);
    commands.spawn((
        Name::new("flag"),
        Cloth::grid(GridSpec::new(nx, ny, spacing).with_plane(GridPlane::Vertical)),
        ClothPins::new((0..ny).map(|j| j * nx)),
        ClothConfig {
            solver: SolverSettings {
                damping: 0.1,
                lift_coefficient: 0.8,
                tearing: Tearing {
                    enabled: true,
                    max_stretch: 0.08,
                    max_per_step: 4,
                    ..default()
                },
                ..default()
            },
            ..default()
        },
        ClothSubdivision {
            level: 1,
            ..default()
        },
        Transform::from_xyz(
            width / 2.0 + POLE_RADIUS + 0.01,
            POLE_HEIGHT - height / 2.0 - 0.02,
            0.0,
        ),
        MeshMaterial3d(fabric.clone()),
    ));
    // The curtain: 1.6 m × 1.6 m on a rail, the ball's target.
    let (n, spacing) = (40u32, 0.04);
    let side = (n - 1) as f32 * spacing;
    commands.spawn((
        Name::new("curtain"),
        Curtain,
        Cloth::grid(GridSpec::new(n, n, spacing).with_plane(GridPlane::Vertical)),
        ClothPins::new(0..n),
        ClothSubdivision {
            level: 1,
            ..default()
        },
        Transform::from_xyz(BALL_START.x, 2.6 - side / 2.0, CURTAIN_Z),
        MeshMaterial3d(fabric.clone()),
    ));
    commands.spawn((
        Mesh3d(meshes.add(Cylinder::new(0.02, side + 0.2))),
        MeshMaterial3d(metal.clone()),
        Transform::from_xyz(BALL_START.x, 2.62, CURTAIN_Z)
            .with_rotation(Quat::from_rotation_z(std::f32::consts::FRAC_PI_2)),
    ));
    // The square: 64×64, 2 cm apart, hanging from its top corners, cut along its middle row.
    let (n, spacing) = (64u32, 0.02);
    let side = (n - 1) as f32 * spacing;
    commands.spawn((
        Name::new("square"),
        ToCut,
        Cloth::grid(GridSpec::new(n, n, spacing).with_plane(GridPlane::Vertical)),
        ClothPins::new([0, n - 1]),
        Transform::from_xyz(4.9, 2.6 - side / 2.0, CURTAIN_Z - 1.0),
        MeshMaterial3d(fabric),
    ));
    commands.spawn((
        Ball { holed: false },
        Mesh3d(meshes.add(Sphere::new(BALL_RADIUS))),
        MeshMaterial3d(materials.add(Color::srgb(0.75, 0.2, 0.15))),
        Transform::from_translation(BALL_START),
        ClothCollider::sphere(BALL_RADIUS),
    ));
}

/// The gale rises from 6 m/s to 41 m/s in 1.75 seconds.
fn rising_gale(time: Res<Time>, mut zones: Query<&mut WindZone>) {
    let speed = 6.0 + 20.0 * time.elapsed_secs().min(1.75);
    for mut zone in &mut zones {
        zone.velocity = Vec3::new(speed, 0.0, -speed / 6.0);
    }
}

/// Throws the ball through the curtain; as it reaches the cloth, it punches a hole its size.
fn throw_ball(
    time: Res<Time>,
    mut balls: Query<(&mut Transform, &mut Ball)>,
    curtains: Query<Entity, With<Curtain>>,
    mut cuts: MessageWriter<ClothCut>,
) {
    let t = time.elapsed_secs();
    for (mut transform, mut ball) in &mut balls {
        // Still for half a second, then thrown, falling a little.
        let flight = (t - 0.5).max(0.0);
        transform.translation = BALL_START
            + BALL_VELOCITY * flight
            + Vec3::new(0.0, -0.5 * 9.81 * flight * flight, 0.0);
        let front = transform.translation.z - BALL_RADIUS;
        if !ball.holed && front <= CURTAIN_Z + 0.05 {
            ball.holed = true;
            for cloth in &curtains {
                cuts.write(ClothCut {
                    cloth,
                    cut: Cut::Ray {
                        origin: transform.translation,
                        direction: BALL_VELOCITY,
                        // Clear of the ball's margin however the cloth's edges fall.
                        radius: BALL_RADIUS + 0.08,
                    },
                });
            }
        }
    }
}

/// Cuts the square in two along its middle row (a horizontal plane through its centre, between
/// rows 31 and 32), 1.2 s in.
fn cut_in_two(
    mut commands: Commands,
    time: Res<Time>,
    squares: Query<(Entity, &Transform), With<ToCut>>,
    mut cuts: MessageWriter<ClothCut>,
) {
    if time.elapsed_secs() < 1.2 {
        return;
    }
    for (cloth, transform) in &squares {
        cuts.write(ClothCut {
            cloth,
            cut: Cut::Plane {
                point: transform.translation,
                normal: Vec3::Y,
            },
        });
        commands.entity(cloth).remove::<ToCut>();
    }
}

fn log_tears(mut torn: MessageReader<ClothTorn>, names: Query<&Name>) {
    for t in torn.read() {
        let name = names.get(t.cloth).map_or("a cloth", |n| n.as_str());
        info!("{name} tore: {} particles split", t.splits.len());
    }
}
