//! The source paper's Table 1, live: a control mesh with extraordinary vertices refined by the three
//! vertex rules (rows: Original, Enhanced, Tuned) at levels 0–3 (columns). Keys 1/2/3 (or the panel)
//! switch between the cube (valence 3), the valence-5 disc and the valence-6 disc; the discs lie on
//! a paraboloid (shown with its height exaggerated 4×), so a dent or a sharp point at the centre is
//! a defect of the rule.
//!
//! `cargo run --release --features examples --example subdivision_compare`

mod common;

use bevy::asset::RenderAssetUsages;
use bevy::mesh::{Indices, PrimitiveTopology};
use bevy::prelude::*;
use bevy_cloth::subdivision::{BoundaryMode, PolyMesh, Subdivider, VertexRule, parse_obj};
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};

const SHAPES: [(&str, &str); 3] = [
    ("cube (valence 3)", "cube"),
    ("disc, valence 5", "star5"),
    ("disc, valence 6", "star6"),
];

#[derive(Resource)]
struct Shown(usize);

#[derive(Component)]
struct Refined;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: Catmull-Clark rules by level",
            focus: Vec3::new(0.0, 0.0, 0.0),
            eye: Vec3::new(0.0, 3.6, 6.0),
        })
        .add_plugins(EguiPlugin::default())
        .insert_resource(Shown(1))
        .add_systems(Startup, show)
        .add_systems(
            Update,
            (keys, show.run_if(resource_changed::<Shown>)).chain(),
        )
        .add_systems(EguiPrimaryContextPass, panel)
        .run();
}

fn load(name: &str) -> Result<PolyMesh, String> {
    let path = format!(
        "{}/tests/data/subdivision/shapes/{name}.obj",
        env!("CARGO_MANIFEST_DIR")
    );
    let text = std::fs::read_to_string(&path).map_err(|e| format!("{path}: {e}"))?;
    parse_obj(&text).map_err(|e| format!("{path}: {e}"))
}

/// A flat-shaded-free render mesh of the refined surface (smooth normals).
fn refined_mesh(control: &PolyMesh, level: u32, rule: VertexRule) -> Result<Mesh, String> {
    let mut sub =
        Subdivider::new(control, level, rule, BoundaryMode::EdgeOnly).map_err(|e| e.to_string())?;
    let mut positions = vec![Vec3::ZERO; sub.refined_vertex_count()];
    let mut normals = vec![Vec3::Y; sub.refined_vertex_count()];
    sub.apply(&control.positions_f32(), &mut positions)
        .map_err(|e| e.to_string())?;
    sub.compute_normals(&positions, &mut normals)
        .map_err(|e| e.to_string())?;
    Ok(Mesh::new(
        PrimitiveTopology::TriangleList,
        RenderAssetUsages::default(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_POSITION,
        positions.iter().map(|p| p.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_attribute(
        Mesh::ATTRIBUTE_NORMAL,
        normals.iter().map(|n| n.to_array()).collect::<Vec<_>>(),
    )
    .with_inserted_indices(Indices::U32(sub.topology().triangle_indices().to_vec())))
}

fn show(
    mut commands: Commands,
    shown: Res<Shown>,
    old: Query<Entity, With<Refined>>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    for e in &old {
        commands.entity(e).despawn();
    }
    let control = match load(SHAPES[shown.0].1) {
        Ok(m) => m,
        Err(e) => {
            error!("{e}");
            return;
        }
    };
    let (lo, hi) = control.bounding_box();
    let size = (hi - lo).max_element().max(1e-6) as f32;
    let centre = ((lo + hi) * 0.5).as_vec3();
    // The discs are shallow paraboloids: exaggerate their height so dents and points show.
    let relief = if SHAPES[shown.0].1 == "cube" {
        1.0
    } else {
        4.0
    };
    let colours = [
        Color::srgb(0.35, 0.75, 0.45),
        Color::srgb(0.85, 0.55, 0.25),
        Color::srgb(0.35, 0.55, 0.9),
    ];
    for (row, rule) in [
        VertexRule::Original,
        VertexRule::Enhanced,
        VertexRule::Tuned,
    ]
    .into_iter()
    .enumerate()
    {
        let material = materials.add(StandardMaterial {
            base_color: colours[row],
            perceptual_roughness: 0.6,
            cull_mode: None,
            double_sided: true,
            ..default()
        });
        for level in 0..=3u32 {
            let mesh = match refined_mesh(&control, level, rule) {
                Ok(m) => m,
                Err(e) => {
                    error!("{rule:?} level {level}: {e}");
                    continue;
                }
            };
            let at = Vec3::new((level as f32 - 1.5) * 1.6, 0.6, (row as f32 - 1.0) * 1.6);
            commands.spawn((
                Refined,
                Mesh3d(meshes.add(mesh)),
                MeshMaterial3d(material.clone()),
                Transform::from_translation(at)
                    .with_scale(Vec3::new(1.0, relief, 1.0) * (1.2 / size))
                    * Transform::from_translation(-centre),
            ));
        }
    }
}

fn keys(input: Res<ButtonInput<KeyCode>>, mut shown: ResMut<Shown>) {
    for (k, key) in [KeyCode::Digit1, KeyCode::Digit2, KeyCode::Digit3]
        .into_iter()
        .enumerate()
    {
        if input.just_pressed(key) && shown.0 != k {
            shown.0 = k;
        }
    }
}

fn panel(mut contexts: EguiContexts, mut shown: ResMut<Shown>) -> Result {
    let ctx = contexts.ctx_mut()?;
    egui::Window::new("Catmull-Clark").show(ctx, |ui| {
        ui.label("columns: level 0, 1, 2, 3");
        ui.label("rows (back to front): Original (green), Enhanced (orange), Tuned (blue)");
        let mut selected = shown.0;
        for (k, (label, _)) in SHAPES.iter().enumerate() {
            ui.radio_value(&mut selected, k, format!("{} [{}]", label, k + 1));
        }
        if selected != shown.0 {
            shown.0 = selected;
        }
    });
    Ok(())
}
