//! Shared setup of the windowed examples: window, orbit camera, lights, ground, and the screenshot
//! mode used by CI and the README.
//!
//! Screenshot mode: set `BEVY_CLOTH_SCREENSHOT=path/to/file.png` (and optionally
//! `BEVY_CLOTH_SCREENSHOT_FRAMES`, default 90). Time then advances by exactly 1/60 s per frame, so
//! the picture is the same on every machine; after that many frames the window is saved and the app
//! exits. Simulated time starts only after [`START_FRAME`] frames (the renderer needs a few to
//! compile its pipelines), so that with `BEVY_CLOTH_SCREENSHOT_START=path/to/start.png` the window
//! is also saved in the scene's starting pose, for a check to see what moved. Between the two
//! pictures only the frames next to them are drawn (see [`RENDERED_AROUND`]).

use std::time::Duration;

use bevy::prelude::*;
use bevy::render::view::screenshot::{Screenshot, ScreenshotCaptured, save_to_disk};
use bevy::time::TimeUpdateStrategy;
use bevy::window::WindowResolution;
use bevy_panorbit_camera::{PanOrbitCamera, PanOrbitCameraPlugin};

/// Window, camera, lights, ground and screenshot mode for an example scene.
pub struct ExamplePlugin {
    /// Window title.
    pub title: &'static str,
    /// Point the camera orbits.
    pub focus: Vec3,
    /// Initial camera position.
    pub eye: Vec3,
}

#[derive(Resource)]
struct ScreenshotMode {
    path: String,
    frames: u32,
    start: Option<String>,
}

/// Frames the screenshot mode holds simulated time still for, and saves the starting pose at.
const START_FRAME: u32 = 30;

/// Frames after the starting pose's screenshot, and before the final one, that the screenshot mode
/// renders. In between, the cameras are switched off: nothing the examples draw depends on earlier
/// frames (no temporal effects), so the final picture is the same, and under a software renderer
/// drawing the frames nobody sees is most of an example's run.
const RENDERED_AROUND: u32 = 3;

impl Plugin for ExamplePlugin {
    fn build(&self, app: &mut App) {
        app.add_plugins(DefaultPlugins.set(WindowPlugin {
            primary_window: Some(Window {
                title: self.title.into(),
                resolution: WindowResolution::new(1280, 720),
                ..default()
            }),
            ..default()
        }))
        .add_plugins(PanOrbitCameraPlugin)
        .add_systems(Update, block_camera_under_egui)
        .insert_resource(ClearColor(Color::srgb(0.62, 0.72, 0.82)));
        let (focus, eye) = (self.focus, self.eye);
        app.add_systems(
            Startup,
            move |mut commands: Commands,
                  mut meshes: ResMut<Assets<Mesh>>,
                  mut materials: ResMut<Assets<StandardMaterial>>| {
                commands.spawn((
                    Transform::from_translation(eye).looking_at(focus, Vec3::Y),
                    PanOrbitCamera {
                        focus,
                        target_focus: focus,
                        ..default()
                    },
                ));
                commands.spawn((
                    DirectionalLight {
                        illuminance: 9_000.0,
                        shadow_maps_enabled: true,
                        ..default()
                    },
                    Transform::from_xyz(3.0, 6.0, 4.0).looking_at(Vec3::ZERO, Vec3::Y),
                ));
                commands.spawn((
                    Mesh3d(meshes.add(Plane3d::default().mesh().size(12.0, 12.0))),
                    MeshMaterial3d(materials.add(StandardMaterial {
                        base_color: Color::srgb(0.35, 0.38, 0.36),
                        perceptual_roughness: 1.0,
                        ..default()
                    })),
                ));
            },
        );
        if let Ok(path) = std::env::var("BEVY_CLOTH_SCREENSHOT") {
            let frames = std::env::var("BEVY_CLOTH_SCREENSHOT_FRAMES")
                .ok()
                .and_then(|f| f.parse().ok())
                .unwrap_or(90);
            app.insert_resource(TimeUpdateStrategy::ManualDuration(Duration::from_secs_f64(
                1.0 / 60.0,
            )))
            .insert_resource(Time::<Fixed>::from_hz(60.0))
            .add_systems(Startup, |mut time: ResMut<Time<Virtual>>| time.pause())
            .insert_resource(ScreenshotMode {
                path,
                frames,
                start: std::env::var("BEVY_CLOTH_SCREENSHOT_START").ok(),
            })
            .add_systems(Update, take_screenshot);
        }
    }
}

/// The orbit camera ignores the mouse while it is over an egui window.
fn block_camera_under_egui(
    wants: Option<Res<bevy_egui::input::EguiWantsInput>>,
    mut cameras: Query<&mut PanOrbitCamera>,
) {
    let blocked = wants.is_some_and(|w| w.wants_any_pointer_input());
    for mut camera in &mut cameras {
        if camera.enabled == blocked {
            camera.enabled = !blocked;
        }
    }
}

fn take_screenshot(
    mut commands: Commands,
    mode: Res<ScreenshotMode>,
    mut time: ResMut<Time<Virtual>>,
    mut frame: Local<u32>,
    mut cameras: Query<(Entity, &mut Camera)>,
    mut switched_off: Local<Vec<Entity>>,
) {
    *frame += 1;
    if *frame == START_FRAME {
        if let Some(start) = &mode.start {
            commands
                .spawn(Screenshot::primary_window())
                .observe(save_to_disk(start.clone()));
        }
        time.unpause();
    }
    let last = START_FRAME + mode.frames;
    if *frame == START_FRAME + RENDERED_AROUND && *frame + RENDERED_AROUND < last {
        for (entity, mut camera) in &mut cameras {
            if camera.is_active {
                camera.is_active = false;
                switched_off.push(entity);
            }
        }
    }
    if *frame + RENDERED_AROUND == last {
        for entity in switched_off.drain(..) {
            if let Ok((_, mut camera)) = cameras.get_mut(entity) {
                camera.is_active = true;
            }
        }
    }
    if *frame != last {
        return;
    }
    let path = mode.path.clone();
    commands.spawn(Screenshot::primary_window()).observe(
        move |captured: On<ScreenshotCaptured>, mut exit: MessageWriter<AppExit>| {
            save_to_disk(path.clone())(captured);
            exit.write(AppExit::Success);
        },
    );
}

/// A two-sided material with the fabric texture.
#[allow(dead_code)]
pub fn fabric(
    asset_server: &AssetServer,
    materials: &mut Assets<StandardMaterial>,
) -> Handle<StandardMaterial> {
    materials.add(StandardMaterial {
        base_color_texture: Some(asset_server.load("textures/fabric.png")),
        perceptual_roughness: 0.9,
        cull_mode: None,
        double_sided: true,
        ..default()
    })
}
