//! The source paper's scene (its Figure 5): a textured cloth pinned at its four corners above a
//! sphere, with wind, pin release, texture and wireframe toggles, a movable sphere, and the cloth
//! inspector panel (every `ClothConfig` field, subdivision level and rule, fps, step time).
//! Self-collision is on, so that a released cloth lands on the sphere and the floor without
//! passing through itself (the panel's checkbox turns it off).
//!
//! `cargo run --release --features examples --example drape`
//!
//! Keys: W wind, R release / re-pin the corners, T texture, F wireframe, arrows and PageUp/PageDown
//! move the sphere. Drag to orbit (the camera ignores the mouse over the panels).
//!
//! FPS test (the paper's: the average of 24 one-second windows): `BEVY_CLOTH_FPS_LOG=24` logs each
//! window's frame rate, prints the average, and exits.

mod common;

use std::time::{Duration, Instant};

use bevy::pbr::wireframe::{Wireframe, WireframePlugin};
use bevy::prelude::*;
use bevy_cloth::inspector::ClothInspectorPlugin;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::{ClothScene, SceneShape};
use bevy_egui::{EguiContexts, EguiPrimaryContextPass, egui};

/// The scene itself (cloth, pins, solver, sphere and floor), shared with `benches/pipeline.rs` and
/// `cloth_cli bench assets/scenes/drape.ron`.
const PAPER_SCENE: &str = include_str!("../assets/scenes/drape.ron");

fn main() {
    let mut app = App::new();
    app.add_plugins(common::ExamplePlugin {
        title: "bevy_cloth: drape (the paper's scene)",
        focus: Vec3::new(0.0, 1.2, 0.0),
        eye: Vec3::new(2.2, 2.4, 2.6),
    })
    .add_plugins((
        ClothPlugin::default(),
        ClothInspectorPlugin,
        WireframePlugin::default(),
    ))
    .insert_resource(Wind {
        velocity: Vec3::new(4.0, 0.0, 1.0),
        gusts: Some(Gusts {
            seed: 1,
            ..default()
        }),
        enabled: false,
        ..default()
    })
    .add_systems(Startup, setup)
    .add_systems(Update, (keys, follow_sphere))
    .add_systems(EguiPrimaryContextPass, scene_panel);
    if let Some(windows) = std::env::var("BEVY_CLOTH_FPS_LOG")
        .ok()
        .and_then(|n| n.parse::<u32>().ok())
    {
        app.insert_resource(FpsLog::new(windows))
            .add_systems(Update, log_fps);
    }
    app.run();
}

#[derive(Resource)]
struct Scene {
    cloth: Entity,
    sphere: Entity,
    sphere_radius: f32,
    /// The pinned corner particles.
    corners: Vec<u32>,
    fabric: Handle<StandardMaterial>,
    plain: Handle<StandardMaterial>,
    textured: bool,
    wireframe: bool,
}

fn setup(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut meshes: ResMut<Assets<Mesh>>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) -> Result {
    let paper = ClothScene::from_ron(PAPER_SCENE)?;
    let fabric = common::fabric(&asset_server, &mut materials);
    let plain = materials.add(StandardMaterial {
        base_color: Color::srgb(0.75, 0.2, 0.2),
        perceptual_roughness: 0.8,
        cull_mode: None,
        double_sided: true,
        ..default()
    });
    let cloth = commands
        .spawn((Name::new("drape"), paper.bundle()?))
        .insert((
            // Scenes show the exact simulated state; on screen, interpolate between fixed steps.
            ClothConfig {
                solver: SolverSettings {
                    self_collision: SelfCollision {
                        enabled: true,
                        ..paper.solver.self_collision
                    },
                    ..paper.solver
                },
                ..default()
            },
            // The paper renders the first subdivision level.
            ClothSubdivision {
                level: 1,
                ..default()
            },
            MeshMaterial3d(fabric.clone()),
        ))
        .id();
    // The sphere (drawn too) and the floor, so that a released cloth has somewhere to land.
    let mut sphere = None;
    for collider in &paper.colliders {
        let mut entity = commands.spawn(collider.bundle()?);
        if let SceneShape::Sphere { radius } = collider.shape {
            entity.insert((
                Mesh3d(meshes.add(Sphere::new(radius).mesh().ico(5)?)),
                MeshMaterial3d(materials.add(StandardMaterial {
                    base_color: Color::srgb(0.85, 0.8, 0.35),
                    ..default()
                })),
            ));
            sphere = Some((entity.id(), radius));
        }
    }
    let (sphere, sphere_radius) = sphere.ok_or("the paper's scene has a sphere")?;
    commands.insert_resource(Scene {
        cloth,
        sphere,
        sphere_radius,
        corners: paper.pins.clone(),
        fabric,
        plain,
        textured: true,
        wireframe: false,
    });
    Ok(())
}

/// What the panel and the keys can change.
#[derive(Default)]
struct Toggles {
    wind: bool,
    release: bool,
    texture: bool,
    wireframe: bool,
}

fn apply(
    t: Toggles,
    scene: &mut Scene,
    wind: &mut Wind,
    commands: &mut Commands,
    pins: &mut ClothPins,
) {
    if t.wind {
        wind.enabled = !wind.enabled;
    }
    if t.release {
        if pins.pins.is_empty() {
            *pins = ClothPins::new(scene.corners.iter().copied());
        } else {
            pins.release_all();
        }
    }
    if t.texture {
        scene.textured = !scene.textured;
        let material = if scene.textured {
            scene.fabric.clone()
        } else {
            scene.plain.clone()
        };
        commands
            .entity(scene.cloth)
            .insert(MeshMaterial3d(material));
    }
    if t.wireframe {
        scene.wireframe = !scene.wireframe;
        if scene.wireframe {
            commands.entity(scene.cloth).insert(Wireframe);
        } else {
            commands.entity(scene.cloth).remove::<Wireframe>();
        }
    }
}

fn keys(
    input: Res<ButtonInput<KeyCode>>,
    time: Res<Time>,
    mut commands: Commands,
    mut scene: ResMut<Scene>,
    mut wind: ResMut<Wind>,
    mut pins: Query<&mut ClothPins>,
    mut transforms: Query<&mut Transform>,
) {
    let toggles = Toggles {
        wind: input.just_pressed(KeyCode::KeyW),
        release: input.just_pressed(KeyCode::KeyR),
        texture: input.just_pressed(KeyCode::KeyT),
        wireframe: input.just_pressed(KeyCode::KeyF),
    };
    if let Ok(mut pins) = pins.get_mut(scene.cloth) {
        apply(toggles, &mut scene, &mut wind, &mut commands, &mut pins);
    }
    let mut step = Vec3::ZERO;
    for (key, dir) in [
        (KeyCode::ArrowLeft, Vec3::NEG_X),
        (KeyCode::ArrowRight, Vec3::X),
        (KeyCode::ArrowUp, Vec3::NEG_Z),
        (KeyCode::ArrowDown, Vec3::Z),
        (KeyCode::PageUp, Vec3::Y),
        (KeyCode::PageDown, Vec3::NEG_Y),
    ] {
        if input.pressed(key) {
            step += dir;
        }
    }
    if step != Vec3::ZERO
        && let Ok(mut t) = transforms.get_mut(scene.sphere)
    {
        t.translation += step * time.delta_secs();
    }
}

/// Keeps the sphere above the floor.
fn follow_sphere(scene: Res<Scene>, mut transforms: Query<&mut Transform>) {
    if let Ok(mut t) = transforms.get_mut(scene.sphere)
        && t.translation.y < scene.sphere_radius
    {
        t.translation.y = scene.sphere_radius;
    }
}

fn scene_panel(
    mut contexts: EguiContexts,
    mut commands: Commands,
    mut scene: ResMut<Scene>,
    mut wind: ResMut<Wind>,
    mut pins: Query<&mut ClothPins>,
    mut transforms: Query<&mut Transform>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    let mut toggles = Toggles::default();
    let pinned = pins.get(scene.cloth).is_ok_and(|p| !p.pins.is_empty());
    egui::Window::new("Scene")
        .anchor(egui::Align2::RIGHT_TOP, [-8.0, 8.0])
        .show(ctx, |ui| {
            toggles.wind = ui.selectable_label(wind.enabled, "wind [W]").clicked();
            toggles.release = ui
                .button(if pinned {
                    "release the corners [R]"
                } else {
                    "re-pin the corners [R]"
                })
                .clicked();
            toggles.texture = ui.selectable_label(scene.textured, "texture [T]").clicked();
            toggles.wireframe = ui
                .selectable_label(scene.wireframe, "wireframe [F]")
                .clicked();
            if let Ok(mut t) = transforms.get_mut(scene.sphere) {
                let mut p = t.translation;
                ui.label("sphere (arrows, PageUp/PageDown)");
                ui.add(egui::Slider::new(&mut p.x, -1.5..=1.5).text("x"));
                ui.add(egui::Slider::new(&mut p.y, scene.sphere_radius..=2.5).text("y"));
                ui.add(egui::Slider::new(&mut p.z, -1.5..=1.5).text("z"));
                if p != t.translation {
                    t.translation = p;
                }
            }
        });
    if let Ok(mut pins) = pins.get_mut(scene.cloth) {
        apply(toggles, &mut scene, &mut wind, &mut commands, &mut pins);
    }
    Ok(())
}

/// The paper's FPS test: frame rate averaged over one-second windows.
#[derive(Resource)]
struct FpsLog {
    windows: u32,
    rates: Vec<f64>,
    window_start: Option<Instant>,
    frames: u32,
}

impl FpsLog {
    fn new(windows: u32) -> Self {
        Self {
            windows: windows.max(1),
            rates: Vec::new(),
            window_start: None,
            frames: 0,
        }
    }
}

fn log_fps(mut log: ResMut<FpsLog>, mut exit: MessageWriter<AppExit>) {
    let now = Instant::now();
    let Some(start) = log.window_start else {
        log.window_start = Some(now);
        return;
    };
    log.frames += 1;
    let elapsed = now - start;
    if elapsed < Duration::from_secs(1) {
        return;
    }
    let rate = log.frames as f64 / elapsed.as_secs_f64();
    log.rates.push(rate);
    info!("fps window {}: {rate:.2}", log.rates.len());
    log.window_start = Some(now);
    log.frames = 0;
    if log.rates.len() as u32 == log.windows {
        let mean = log.rates.iter().sum::<f64>() / log.rates.len() as f64;
        println!(
            "average fps over {} one-second windows: {mean:.2} (the paper: 43.75)",
            log.rates.len()
        );
        exit.write(AppExit::Success);
    }
}
