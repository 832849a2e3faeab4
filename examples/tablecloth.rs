//! A round tablecloth falls on a round table. The cloth is a quad disc whose centre particle has
//! valence 5 (five quad patches meet there: `ClothModel::disc`), given to the plugin as a prebuilt
//! model (`Cloth::from_model`) so that its quads stay quads, and rendered as a Catmull-Clark
//! surface at level 2 with the tuned vertex rule. The inspector panel switches level and rule
//! (Original, the paper's Enhanced, Tuned) while it drapes.
//!
//! `cargo run --release --features examples --example tablecloth`
//!
//! Keys: R drop the cloth again, V switch the centre's valence between 5 and 6, F wireframe. Drag to
//! orbit (the camera ignores the mouse over the panels).
//!
//! The table top is a regular 16-gon made of 8 box colliders (each box spans two opposite edges of
//! the polygon, so their union is exactly the polygon), and the floor is a half-space.

mod common;

use std::f32::consts::PI;

use bevy::pbr::wireframe::{Wireframe, WireframePlugin};
use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_cloth::sim::ClothModel;
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};

/// Radius of the cloth, m.
const CLOTH_RADIUS: f32 = 0.85;
/// Quads along each spoke of the disc.
const RINGS: u32 = 14;
/// Height the cloth is dropped from, above the table top, m.
const DROP: f32 = 0.3;
/// Radius of the table top (the polygon's circumradius), m.
const TABLE_RADIUS: f32 = 0.5;
/// Height of the table top's upper face, m.
const TABLE_HEIGHT: f32 = 0.75;
/// Thickness of the table top, m.
const TOP_THICKNESS: f32 = 0.04;
/// Edges of the table top polygon (even); it takes half as many boxes.
const TABLE_EDGES: u32 = 16;
/// Distance the table's colliders keep the cloth's particles from the wood, m. The smooth
/// (subdivided) surface cuts the corner where the cloth folds over the table's edge by about a
/// quarter of the particle spacing, so the visible table is also a little smaller than its
/// colliders.
const MARGIN: f32 = 0.015;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: tablecloth",
            focus: Vec3::new(0.0, 0.55, 0.0),
            eye: Vec3::new(1.35, 1.3, 1.8),
        })
        .add_plugins((
            ClothPlugin::default(),
            ClothInspectorPlugin,
            WireframePlugin::default(),
        ))
        .add_systems(Startup, setup)
        .add_systems(Update, keys)
        .add_systems(EguiPrimaryContextPass, scene_panel)
        .run();
}

#[derive(Resource)]
struct Scene {
    cloth: Entity,
    sectors: u32,
    wireframe: bool,
}

/// The cloth component for a disc with `sectors` patches around its centre.
fn tablecloth(sectors: u32) -> Result<Cloth, BevyError> {
    let model = ClothModel::disc(&DiscSpec::new(sectors, RINGS, CLOTH_RADIUS))?;
    Ok(Cloth::from_model(model))
}

/// Where the cloth starts: flat, centred above the table.
fn drop_transform() -> Transform {
    Transform::from_xyz(0.0, TABLE_HEIGHT + DROP, 0.0)
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) -> Result {
    let sectors = 5;
    let cloth = commands
        .spawn((
            Name::new("tablecloth"),
            tablecloth(sectors)?,
            ClothConfig {
                // A soft fabric: low bending stiffness lets the skirt fold.
                solver: SolverSettings {
                    damping: 1.0,
                    stiffness: Stiffness {
                        bend: 10.0,
                        ..default()
                    },
                    ..default()
                },
                ..default()
            },
            // A smooth hem: the disc has two-edge particles on its rim (see `DiscSpec`).
            ClothSubdivision {
                level: 2,
                rule: VertexRule::Tuned,
                boundary: BoundaryMode::EdgeOnly,
                ..default()
            },
            drop_transform(),
            MeshMaterial3d(common::fabric(&asset_server, &mut materials)),
        ))
        .id();

    let wood = materials.add(StandardMaterial {
        base_color: Color::srgb(0.42, 0.33, 0.25),
        perceptual_roughness: 0.6,
        ..default()
    });
    let top_centre = TABLE_HEIGHT - TOP_THICKNESS / 2.0;
    commands
        .spawn((
            Name::new("table"),
            Transform::from_xyz(0.0, top_centre, 0.0),
            Visibility::default(),
        ))
        .with_children(|table| {
            table.spawn((
                Mesh3d(
                    meshes.add(
                        Cylinder::new(TABLE_RADIUS - 0.025, TOP_THICKNESS - 0.01)
                            .mesh()
                            .resolution(64),
                    ),
                ),
                MeshMaterial3d(wood.clone()),
            ));
            // The top's colliders: box `k` spans the polygon's edges at angles `k·π/E` and
            // `k·π/E + π`; the union of the boxes is the regular E-gon inscribed in the circle.
            let half_edge_angle = PI / TABLE_EDGES as f32;
            let half_size = Vec3::new(
                TABLE_RADIUS * half_edge_angle.cos(),
                TOP_THICKNESS / 2.0,
                TABLE_RADIUS * half_edge_angle.sin(),
            );
            for k in 0..TABLE_EDGES / 2 {
                table.spawn((
                    ClothCollider::cuboid(half_size)
                        .with_friction(Friction::new(0.6))
                        .with_margin(MARGIN),
                    Transform::from_rotation(Quat::from_rotation_y(
                        2.0 * half_edge_angle * k as f32,
                    )),
                ));
            }
            let leg_height = TABLE_HEIGHT - TOP_THICKNESS;
            table.spawn((
                Mesh3d(meshes.add(Cylinder::new(0.05, leg_height))),
                MeshMaterial3d(wood.clone()),
                Transform::from_xyz(0.0, -leg_height / 2.0, 0.0),
            ));
            table.spawn((
                Mesh3d(meshes.add(Cylinder::new(0.28, 0.03))),
                MeshMaterial3d(wood.clone()),
                Transform::from_xyz(0.0, -top_centre + 0.015, 0.0),
            ));
        });
    // The floor (the ground plane of `ExamplePlugin` is its picture).
    commands.spawn((ClothCollider::half_space(Vec3::Y), Transform::IDENTITY));
    commands.insert_resource(Scene {
        cloth,
        sectors,
        wireframe: false,
    });
    Ok(())
}

/// What the panel and the keys can change.
#[derive(Default)]
struct Toggles {
    drop: bool,
    valence: bool,
    wireframe: bool,
}

fn apply(t: Toggles, scene: &mut Scene, commands: &mut Commands) -> Result {
    if t.valence {
        scene.sectors = if scene.sectors == 5 { 6 } else { 5 };
    }
    if t.drop || t.valence {
        // Replacing `Cloth` rebuilds the cloth at its entity's transform.
        commands
            .entity(scene.cloth)
            .insert((tablecloth(scene.sectors)?, drop_transform()));
    }
    if t.wireframe {
        scene.wireframe = !scene.wireframe;
        if scene.wireframe {
            commands.entity(scene.cloth).insert(Wireframe);
        } else {
            commands.entity(scene.cloth).remove::<Wireframe>();
        }
    }
    Ok(())
}

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    mut commands: Commands,
    mut scene: ResMut<Scene>,
) -> Result {
    let toggles = Toggles {
        drop: input.just_pressed(KeyCode::KeyR),
        valence: input.just_pressed(KeyCode::KeyV),
        wireframe: input.just_pressed(KeyCode::KeyF),
    };
    apply(toggles, &mut scene, &mut commands)
}

fn scene_panel(
    mut contexts: EguiContexts,
    mut commands: Commands,
    mut scene: ResMut<Scene>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let mut toggles = Toggles::default();
    egui::Window::new("Scene")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .show(ctx, |ui| {
            ui.label(format!(
                "round quad cloth, centre of valence {}",
                scene.sectors
            ));
            toggles.drop = ui.button("drop it again [R]").clicked();
            toggles.valence = ui
                .button(if scene.sectors == 5 {
                    "valence 6 at the centre [V]"
                } else {
                    "valence 5 at the centre [V]"
                })
                .clicked();
            toggles.wireframe = ui
                .selectable_label(scene.wireframe, "wireframe [F]")
                .clicked();
        });
    apply(toggles, &mut scene, &mut commands)
}
