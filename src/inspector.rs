//! [`ClothInspectorPlugin`] (feature `egui`): an egui window that edits every cloth's
//! [`ClothConfig`] and [`ClothSubdivision`] at runtime, releases pins, tunes the [`Wind`], and shows
//! frames per second, the time the fixed step spends in the solver, particle counts, and how many
//! cloths run at each level of detail ([`ClothLodLevel`](crate::ClothLodLevel)) and what their
//! steps cost.
//!
//! Components are written only when a value really changes, so an open panel does not make the
//! plugin re-apply settings every frame.

use std::time::Instant;

use bevy::app::{App, FixedUpdate, Plugin};
use bevy::diagnostic::{DiagnosticsStore, FrameTimeDiagnosticsPlugin};
use bevy::ecs::prelude::*;
use bevy::math::Vec3;
use bevy_egui::{EguiContexts, EguiPlugin, EguiPrimaryContextPass, egui};

use crate::components::*;
use crate::plugin::ClothSystems;
use crate::sim::{AccuracyReport, ErrorUnit, Integrator, MAX_ITERATIONS, MAX_SUBSTEPS};
use crate::subdivision::{BoundaryMode, VertexRule};

/// Adds the cloth inspector window (and `EguiPlugin` and `FrameTimeDiagnosticsPlugin` if the app
/// has not added them). Assumes the cloths step in [`FixedUpdate`] (the default) for its timing.
///
/// ```no_run
/// use bevy::prelude::*;
/// use bevy_cloth::prelude::*;
/// use bevy_cloth::inspector::ClothInspectorPlugin;
///
/// App::new()
///     .add_plugins((DefaultPlugins, ClothPlugin::default(), ClothInspectorPlugin))
///     .run();
/// ```
#[derive(Debug, Default, Clone, Copy)]
pub struct ClothInspectorPlugin;

impl Plugin for ClothInspectorPlugin {
    fn build(&self, app: &mut App) {
        if !app.is_plugin_added::<EguiPlugin>() {
            app.add_plugins(EguiPlugin::default());
        }
        if !app.is_plugin_added::<FrameTimeDiagnosticsPlugin>() {
            app.add_plugins(FrameTimeDiagnosticsPlugin::default());
        }
        app.init_resource::<StepTiming>()
            .add_systems(
                FixedUpdate,
                (
                    start_timing.before(ClothSystems::Step),
                    stop_timing.after(ClothSystems::Step),
                ),
            )
            .add_systems(EguiPrimaryContextPass, inspector_window);
    }
}

/// Wall time of the solver's fixed step, smoothed.
#[derive(Resource, Debug, Default)]
struct StepTiming {
    started: Option<Instant>,
    /// Exponential moving average, ms.
    average_ms: f32,
}

fn start_timing(mut timing: ResMut<StepTiming>) {
    timing.started = Some(Instant::now());
}

fn stop_timing(mut timing: ResMut<StepTiming>) {
    if let Some(start) = timing.started.take() {
        let ms = start.elapsed().as_secs_f32() * 1e3;
        timing.average_ms = if timing.average_ms == 0.0 {
            ms
        } else {
            0.9 * timing.average_ms + 0.1 * ms
        };
    }
}

type InspectedCloth<'a> = (
    Entity,
    Option<&'a bevy::ecs::name::Name>,
    &'a mut ClothConfig,
    Option<&'a mut ClothSubdivision>,
    &'a mut ClothPins,
    Option<&'a ClothState>,
    (Option<&'a ClothInvalid>, Option<&'a ClothEditRejected>),
);

fn inspector_window(
    mut contexts: EguiContexts,
    diagnostics: Res<DiagnosticsStore>,
    timing: Res<StepTiming>,
    wind: Option<ResMut<Wind>>,
    mut cloths: Query<InspectedCloth>,
    levels: Query<(&crate::ClothLodLevel, &ClothState)>,
) -> Result {
    let ctx = contexts.ctx_mut()?;
    egui::Window::new("Cloth inspector")
        .default_width(280.0)
        .show(ctx, |ui| {
            let fps = diagnostics
                .get(&FrameTimeDiagnosticsPlugin::FPS)
                .and_then(|d| d.smoothed())
                .unwrap_or(0.0);
            let particles: usize = cloths
                .iter()
                .filter_map(|c| c.5)
                .map(|s| s.positions().len())
                .sum();
            ui.label(format!("{fps:.1} fps"));
            ui.label(format!("fixed step (solver): {:.2} ms", timing.average_ms));
            ui.label(format!("particles: {particles}"));
            if !levels.is_empty() {
                ui.label(levels_line(levels.iter().map(|(level, state)| {
                    (level.level, state.last_step_time().as_secs_f32() * 1e3)
                })));
            }
            // Many cloths: their sections start closed.
            let open = cloths.iter().len() <= 8;
            if let Some(mut wind) = wind {
                ui.separator();
                let mut w = *wind;
                wind_ui(ui, &mut w);
                if w != *wind {
                    *wind = w;
                }
            }
            for (entity, name, mut config, subdivision, mut pins, state, (invalid, rejected)) in
                &mut cloths
            {
                ui.separator();
                let title = name.map_or_else(|| format!("cloth {entity}"), |n| n.to_string());
                egui::CollapsingHeader::new(title)
                    .id_salt(entity)
                    .default_open(open)
                    .show(ui, |ui| {
                        if let Some(ClothInvalid(e)) = invalid {
                            ui.colored_label(egui::Color32::RED, e.to_string());
                        }
                        if let Some(ClothEditRejected(e)) = rejected {
                            ui.colored_label(egui::Color32::YELLOW, format!("edit rejected: {e}"));
                        }
                        if let Some(state) = state {
                            ui.label(format!(
                                "{} particles, {} steps ({}), {} colliders near{}",
                                state.positions().len(),
                                state.steps(),
                                state.sim().active_integrator().name(),
                                state.sim().active_colliders(),
                                if state.sim().is_sleeping() {
                                    ", asleep"
                                } else {
                                    ""
                                }
                            ));
                            if let Some(r) = state.sim().accuracy_report() {
                                ui.label(accuracy_line(&r));
                            }
                            if let Some(line) = air_line(state.sim()) {
                                ui.label(line);
                            }
                        }
                        let mut c = *config;
                        config_ui(ui, &mut c);
                        if c != *config {
                            *config = c;
                        }
                        if let Some(mut sub) = subdivision {
                            let mut s = *sub;
                            subdivision_ui(ui, &mut s);
                            if s != *sub {
                                *sub = s;
                            }
                        }
                        ui.horizontal(|ui| {
                            ui.label(format!("{} pins", pins.pins.len()));
                            if ui.button("Release all").clicked() && !pins.pins.is_empty() {
                                pins.release_all();
                            }
                        });
                    });
            }
        });
    Ok(())
}

/// A slider over `range` that shows a value outside it as it is, and clamps only what the user
/// drags or types (egui's default clamps the value as soon as the slider is drawn, which would
/// rewrite, say, a stiffness above the slider's top to the top).
fn slider<Num: egui::emath::Numeric>(
    value: &mut Num,
    range: std::ops::RangeInclusive<Num>,
) -> egui::Slider<'_> {
    egui::Slider::new(value, range).clamping(egui::SliderClamping::Edits)
}

fn vec3_ui(ui: &mut egui::Ui, label: &str, v: &mut Vec3, speed: f64) {
    ui.horizontal(|ui| {
        ui.label(label);
        ui.add(egui::DragValue::new(&mut v.x).speed(speed));
        ui.add(egui::DragValue::new(&mut v.y).speed(speed));
        ui.add(egui::DragValue::new(&mut v.z).speed(speed));
    });
}

/// A closed cloth's volume against its built volume, and the pressure of its air (when on).
fn air_line(sim: &crate::sim::ClothSim) -> Option<String> {
    let (volume, built) = (sim.volume()?, sim.built_volume()?);
    let mut line = format!(
        "volume {:.4} m³ ({:+.2}% of built)",
        volume,
        100.0 * (volume / built - 1.0)
    );
    if let Some(p) = sim.pressure() {
        line += &format!(", pressure {p:+.0} Pa above outside");
    }
    Some(line)
}

/// How many cloths run at each level of detail, and their steps' time together.
fn levels_line(levels: impl Iterator<Item = (crate::LodLevel, f32)>) -> String {
    use crate::LodLevel;
    let mut count = [0usize; LodLevel::ALL.len()];
    let mut ms = [0.0f32; LodLevel::ALL.len()];
    for (level, step_ms) in levels {
        count[level as usize] += 1;
        ms[level as usize] += step_ms;
    }
    let parts: Vec<String> = LodLevel::ALL
        .iter()
        .map(|&l| {
            let k = l as usize;
            format!("{} {} ({:.2} ms)", l.name(), count[k], ms[k])
        })
        .collect();
    format!("levels of detail: {}", parts.join(", "))
}

/// What tolerance mode chose and how its estimate compares with the tolerance.
fn accuracy_line(r: &AccuracyReport) -> String {
    format!(
        "tolerance mode: {} × {} substeps, estimate {:.1e} m/s of {:.1e}{}{}",
        r.integrator.name(),
        r.substeps,
        r.error_rate,
        r.tolerance,
        if r.at_cap { ", at the cap" } else { "" },
        if r.at_floor { ", at round-off" } else { "" }
    )
}

fn config_ui(ui: &mut egui::Ui, c: &mut ClothConfig) {
    let s = &mut c.solver;
    let a = &mut s.accuracy;
    let mut tolerance_mode = a.tolerance.is_some();
    ui.checkbox(
        &mut tolerance_mode,
        "tolerance mode (chooses integrator and substeps)",
    );
    match (tolerance_mode, a.tolerance) {
        (true, None) => a.tolerance = Some(1e-3),
        (false, Some(_)) => a.tolerance = None,
        _ => {}
    }
    if let Some(t) = &mut a.tolerance {
        let unit = match a.unit {
            ErrorUnit::Relative => "of the size",
            ErrorUnit::Metres => "m",
        };
        ui.add(
            slider(t, 1e-6..=1e-1)
                .logarithmic(true)
                .text(format!("tolerance, {unit} per second")),
        );
        ui.add(
            slider(&mut a.max_substeps, 2..=MAX_SUBSTEPS)
                .logarithmic(true)
                .text("max substeps"),
        );
    }
    egui::ComboBox::from_label("integrator")
        .selected_text(s.integrator.name())
        .show_ui(ui, |ui| {
            for i in Integrator::CHOICES {
                ui.selectable_value(&mut s.integrator, i, i.name());
            }
        });
    ui.add(
        slider(&mut s.substeps, 1..=MAX_SUBSTEPS)
            .logarithmic(true)
            .text("substeps"),
    );
    ui.add(
        slider(&mut s.iterations, 1..=MAX_ITERATIONS)
            .logarithmic(true)
            .text("iterations"),
    );
    ui.checkbox(&mut s.auto_substeps, "auto substeps (explicit integrators)");
    for (value, label) in [
        (&mut s.stiffness.structural, "structural k, N/m"),
        (&mut s.stiffness.shear, "shear k, N/m"),
        (&mut s.stiffness.bend, "bend k, N/m"),
    ] {
        ui.add(slider(value, 0.0..=1e6).logarithmic(true).text(label));
    }
    ui.add(
        slider(&mut s.particle_mass, 1e-5..=1.0)
            .logarithmic(true)
            .text("particle mass, kg"),
    );
    ui.add(slider(&mut s.damping, 0.0..=10.0).text("damping, 1/s"));
    vec3_ui(ui, "gravity", &mut s.gravity, 0.1);
    ui.add(slider(&mut s.drag_coefficient, 0.0..=3.0).text("drag coefficient"));
    ui.add(slider(&mut s.lift_coefficient, 0.0..=3.0).text("lift coefficient"));
    ui.add(slider(&mut s.sleep_speed, 0.0..=0.1).text("sleep below, m/s (0 = never)"));
    ui.add(slider(&mut s.sleep_steps, 1..=600).text("sleep after steps"));
    let sc = &mut s.self_collision;
    ui.checkbox(&mut sc.enabled, "self-collision");
    ui.add(
        slider(&mut sc.thickness, 1e-4..=0.05)
            .logarithmic(true)
            .text("thickness, m"),
    );
    ui.add(slider(&mut sc.friction, 0.0..=1.0).text("friction between layers"));
    let t = &mut s.targets;
    ui.add(slider(&mut t.max_distance_scale, 0.0..=2.0).text("max distance per unit weight, m"));
    ui.add(slider(&mut t.backstop_radius, 0.0..=2.0).text("backstop radius, m (0 = none)"));
    ui.add(slider(&mut t.backstop_offset, -0.1..=0.1).text("backstop offset, m"));
    ui.checkbox(&mut s.tethers.enabled, "tethers");
    ui.add(slider(&mut s.tethers.slack, 0.0..=0.5).text("tether slack"));
    ui.add(slider(&mut s.inertia.linear, 0.0..=1.0).text("linear inertia"));
    ui.add(slider(&mut s.inertia.angular, 0.0..=1.0).text("angular inertia"));
    ui.checkbox(&mut c.interpolate, "interpolate display");
    ui.horizontal(|ui| {
        ui.label("collision mask");
        ui.add(egui::DragValue::new(&mut c.collision_mask).hexadecimal(8, false, true));
    });
    ui.horizontal(|ui| {
        ui.label("cloth layers (other cloths)");
        ui.add(egui::DragValue::new(&mut c.cloth_layers).hexadecimal(8, false, true));
    });
}

fn subdivision_ui(ui: &mut egui::Ui, s: &mut ClothSubdivision) {
    ui.add(slider(&mut s.level, 0..=MAX_CLOTH_SUBDIVISION_LEVEL).text("subdivision level"));
    egui::ComboBox::from_label("vertex rule")
        .selected_text(format!("{:?}", s.rule))
        .show_ui(ui, |ui| {
            for r in VertexRule::ALL {
                ui.selectable_value(&mut s.rule, r, format!("{r:?}"));
            }
        });
    egui::ComboBox::from_label("boundary")
        .selected_text(format!("{:?}", s.boundary))
        .show_ui(ui, |ui| {
            for b in [BoundaryMode::EdgeOnly, BoundaryMode::EdgeAndCorner] {
                ui.selectable_value(&mut s.boundary, b, format!("{b:?}"));
            }
        });
    egui::ComboBox::from_label("refines")
        .selected_text(format!("{:?}", s.target))
        .show_ui(ui, |ui| {
            for t in [SubdivisionTarget::Render, SubdivisionTarget::Simulation] {
                ui.selectable_value(&mut s.target, t, format!("{t:?}"));
            }
        });
}

fn wind_ui(ui: &mut egui::Ui, w: &mut Wind) {
    ui.checkbox(&mut w.enabled, "wind");
    vec3_ui(ui, "velocity, m/s", &mut w.velocity, 0.1);
    let mut gusty = w.gusts.is_some();
    ui.checkbox(&mut gusty, "gusts");
    match (gusty, &mut w.gusts) {
        (true, Some(g)) => {
            ui.add(slider(&mut g.strength, 0.0..=1.0).text("gust strength"));
            ui.add(slider(&mut g.frequency, 0.05..=5.0).text("gust frequency, Hz"));
        }
        (true, None) => w.gusts = Some(Default::default()),
        (false, _) => w.gusts = None,
    }
    ui.add(slider(&mut w.air_density, 0.0..=5.0).text("air density, kg/m³"));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_levels_line_counts_every_level() {
        use crate::LodLevel::*;
        let line =
            levels_line([(Full, 1.0), (Coarse, 0.25), (Culled, 0.0), (Full, 0.5)].into_iter());
        assert_eq!(
            line,
            "levels of detail: full 2 (1.50 ms), reduced 0 (0.00 ms), coarse 1 (0.25 ms), \
             frozen 0 (0.00 ms), culled 1 (0.00 ms)"
        );
    }

    /// Draws the panel's widgets for `config`, `subdivision` and `wind` once, with no input.
    fn draw(config: &mut ClothConfig, subdivision: &mut ClothSubdivision, wind: &mut Wind) {
        let ctx = egui::Context::default();
        let mut output = ctx.run_ui(egui::RawInput::default(), |ui| {
            config_ui(ui, config);
            subdivision_ui(ui, subdivision);
            wind_ui(ui, wind);
        });
        // Nothing renders the font textures egui built.
        output.textures_delta.clear();
    }

    #[test]
    fn drawing_the_panel_keeps_values_outside_the_sliders_ranges() {
        let mut config = ClothConfig::default();
        let s = &mut config.solver;
        s.stiffness.structural = 1e7;
        s.stiffness.shear = 3e6;
        s.particle_mass = 5.0;
        s.damping = 40.0;
        s.drag_coefficient = 4.5;
        s.lift_coefficient = 3.5;
        s.sleep_speed = 0.5;
        s.sleep_steps = 1000;
        s.self_collision.thickness = 0.2;
        s.self_collision.friction = 1.5;
        s.targets.max_distance_scale = 5.0;
        s.targets.backstop_radius = 3.0;
        s.targets.backstop_offset = 0.4;
        s.tethers.slack = 0.8;
        s.accuracy.tolerance = Some(0.5);
        let mut subdivision = ClothSubdivision::default();
        let mut wind = Wind {
            air_density: 12.0,
            gusts: Some(crate::sim::Gusts {
                strength: 2.0,
                frequency: 9.0,
                ..Default::default()
            }),
            ..Default::default()
        };
        let (config0, subdivision0, wind0) = (config, subdivision, wind);
        draw(&mut config, &mut subdivision, &mut wind);
        assert_eq!(config, config0);
        assert_eq!(subdivision, subdivision0);
        assert_eq!(wind, wind0);
    }
}
