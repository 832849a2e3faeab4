//! A textured 32×32 cloth pinned at two corners falls from horizontal and hangs.
//!
//! `cargo run --release --features examples --example hanging_cloth`
//! (drag to orbit, scroll to zoom; see `common` for the screenshot mode).

mod common;

use bevy::prelude::*;
use bevy_cloth::prelude::*;

fn main() {
    App::new()
        .add_plugins(common::ExamplePlugin {
            title: "bevy_cloth: hanging cloth",
            focus: Vec3::new(0.0, 1.5, -0.4),
            eye: Vec3::new(0.9, 1.9, 1.9),
        })
        .add_plugins(ClothPlugin::default())
        .add_systems(Startup, spawn_cloth)
        .run();
}

fn spawn_cloth(
    mut commands: Commands,
    asset_server: Res<AssetServer>,
    mut materials: ResMut<Assets<StandardMaterial>>,
) {
    let n = 32;
    commands.spawn((
        Cloth::grid(GridSpec::new(n, n, 0.05)),
        ClothPins::new([0, n - 1]),
        Transform::from_xyz(0.0, 2.2, 0.0),
        MeshMaterial3d(common::fabric(&asset_server, &mut materials)),
    ));
}
