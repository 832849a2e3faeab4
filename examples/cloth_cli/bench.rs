//! A scene timed frame by frame through the whole plugin in a headless App: what `bench`
//! prints and `benchmarks` tabulates, and the loading and frame loop `simulate` shares.

use std::path::Path;
use std::time::Instant;

use bevy::prelude::*;
use bevy_cloth::harness::try_headless_app;
use bevy_cloth::prelude::*;
use bevy_cloth::scene::ClothScene;
use bevy_cloth::sim::{ClothSim, SpringKind};

/// A headless app with one copy of the scene built and at rest.
pub fn load(path: &Path) -> Result<(App, Entity, ClothScene), ClothError> {
    let one = Variant {
        copies: Some(1),
        ..Variant::default()
    };
    let (app, entities, scene) = load_copies(path, one)?;
    Ok((app, entities[0], scene))
}

/// A headless app with the scene's cloths built and at rest, as `variant` has them (0 copies:
/// the App alone).
fn load_copies(
    path: &Path,
    variant: Variant,
) -> Result<(App, Vec<Entity>, ClothScene), ClothError> {
    let mut scene = ClothScene::load(path)?;
    if let Some(count) = variant.copies {
        scene.copies.count = count;
    }
    if variant.first_only {
        scene.also.clear();
    }
    if variant.budget_ms.is_some() {
        scene.budget_ms = variant.budget_ms;
    }
    if variant.full_quality {
        scene.viewer = None;
        scene.budget_ms = None;
        scene.lod = None;
        for s in &mut scene.also {
            s.lod = None;
        }
    }
    if let Some(level) = variant.level {
        hold_at(&mut scene, level);
    }
    let mut app = try_headless_app(scene.dt)?;
    let entities = if scene.copies.count == 0 {
        Vec::new()
    } else {
        scene.spawn_copies(app.world_mut())?
    };
    app.update();
    for e in &entities {
        if let Some(ClothInvalid(e)) = app.world().get::<ClothInvalid>(*e) {
            return Err(e.clone());
        }
    }
    Ok((app, entities, scene))
}

/// Holds every cloth of `scene` at `level`: its thresholds below the level at 0 m, the others
/// out of reach, seen whatever the view, from the scene's viewer or one 1 km up; no budget.
fn hold_at(scene: &mut ClothScene, level: LodLevel) {
    let at = |k: LodLevel| if k <= level { 0.0 } else { f32::INFINITY };
    let held = ClothLod {
        metric: LodMetric::Distance,
        reduced: at(LodLevel::Reduced),
        coarse: at(LodLevel::Coarse),
        frozen: at(LodLevel::Frozen),
        culled: f32::INFINITY,
        cull_unseen: false,
        ..scene.lod.unwrap_or_default()
    };
    scene.lod = Some(held);
    for s in &mut scene.also {
        s.lod = Some(held);
    }
    scene.budget_ms = None;
    scene
        .viewer
        .get_or_insert_with(|| bevy_cloth::scene::SceneViewer::at(Vec3::new(0.0, 1000.0, 0.0)));
}

/// Runs `frames` updates (one fixed step each), returning the wall time of each in milliseconds.
pub fn run(app: &mut App, entity: Entity, frames: u32) -> Result<Vec<f64>, ClothError> {
    Ok(run_frames(app, &[entity], frames)?.frame_ms)
}

/// What [`run_frames`] measured.
struct Frames {
    /// Wall time of each whole frame, ms.
    frame_ms: Vec<f64>,
    /// The cloths' steps in it, summed ([`ClothState::last_step_time`]), ms.
    solver_ms: Vec<f64>,
    /// Cloth-frames skipped asleep.
    slept: u32,
    /// Cloth-frames at each level of detail, finest first.
    levels: [u32; LodLevel::ALL.len()],
}

/// [`run`] for several cloths, also summing the cloths' steps within each frame and counting the
/// cloth-frames skipped asleep.
fn run_frames(app: &mut App, entities: &[Entity], frames: u32) -> Result<Frames, ClothError> {
    let mut out = Frames {
        frame_ms: Vec::with_capacity(frames as usize),
        solver_ms: Vec::with_capacity(frames as usize),
        slept: 0,
        levels: [0; LodLevel::ALL.len()],
    };
    for _ in 0..frames {
        let t = Instant::now();
        app.update();
        out.frame_ms.push(t.elapsed().as_secs_f64() * 1e3);
        let mut solver = 0.0;
        for e in entities {
            if let Some(ClothInvalid(e)) = app.world().get::<ClothInvalid>(*e) {
                return Err(e.clone());
            }
            let state = app.world().get::<ClothState>(*e);
            out.slept += state.is_some_and(|s| s.sim().slept_last_step()) as u32;
            let level = app
                .world()
                .get::<ClothLodLevel>(*e)
                .map_or(LodLevel::Full, |l| l.level);
            out.levels[level as usize] += 1;
            solver += state.map_or(0.0, |s| s.last_step_time().as_secs_f64() * 1e3);
        }
        out.solver_ms.push(solver);
    }
    Ok(out)
}

/// Median, 10th, 90th and 99th percentile, min and max.
pub fn stats(times: &mut [f64]) -> serde_json::Value {
    times.sort_by(f64::total_cmp);
    let q = |f: f64| times[((times.len() - 1) as f64 * f).round() as usize];
    serde_json::json!({
        "median_ms": q(0.5), "p10_ms": q(0.1), "p90_ms": q(0.9), "p99_ms": q(0.99),
        "min_ms": q(0.0), "max_ms": q(1.0),
    })
}

/// Median of `|length / rest - 1|` over the springs of `kinds` (structural: a grid's row and
/// column edges; shear: its diagonals; bend: its springs that skip one particle).
fn median_strain(sim: &ClothSim, kinds: &[SpringKind]) -> f64 {
    let mut strain: Vec<f64> = kinds
        .iter()
        .flat_map(|&kind| sim.strains(kind))
        .map(|s| f64::from(s.abs()))
        .collect();
    if strain.is_empty() {
        return f64::NAN;
    }
    strain.sort_by(f64::total_cmp);
    strain[strain.len() / 2]
}

/// How `bench` runs a scene.
#[derive(Debug, Clone, Copy, Default)]
pub struct Variant {
    /// Copies of the scene's cloth on its layout; its own when `None`.
    pub copies: Option<u32>,
    /// Bevy's single-threaded executor with static-scene transform tracking off
    /// (`harness::use_single_threaded_frame`), rather than its multi-threaded one.
    pub single_threaded: bool,
    /// Without the scene's levels of detail, viewer and budget.
    pub full_quality: bool,
    /// Without the scene's further cloths.
    pub first_only: bool,
    /// A budget in place of the scene's, ms a frame.
    pub budget_ms: Option<f32>,
    /// Frames run before the timed ones.
    pub warm_up: u32,
    /// Every cloth held at this level of detail.
    pub level: Option<LodLevel>,
}

/// Times `frames` frames of the scene as `variant` says (after its warm-up frames) and returns
/// the JSON line `bench` prints.
pub fn bench_scene(
    scene: &Path,
    frames: u32,
    variant: Variant,
) -> Result<serde_json::Value, Box<dyn std::error::Error>> {
    let single_threaded = variant.single_threaded;
    let (mut app, entities, parsed) = load_copies(scene, variant)?;
    if single_threaded {
        bevy_cloth::harness::use_single_threaded_frame(&mut app);
    }
    run_frames(&mut app, &entities, variant.warm_up)?;
    let Frames {
        frame_ms: mut times,
        mut solver_ms,
        slept,
        levels,
    } = run_frames(&mut app, &entities, frames)?;
    let executor = if single_threaded { "single" } else { "multi" };
    if entities.is_empty() {
        // The App without cloths: what Bevy's schedules cost by themselves.
        let mut line = stats(&mut times);
        line["scene"] = scene.display().to_string().into();
        (line["frames"], line["copies"], line["executor"]) =
            (frames.into(), 0.into(), executor.into());
        return Ok(line);
    }
    let mut outside: Vec<f64> = times.iter().zip(&solver_ms).map(|(f, s)| f - s).collect();
    let state = app
        .world()
        .get::<ClothState>(entities[0])
        .ok_or("cloth was not built")?;
    let sim = state.sim();
    let solves = sim.model().springs.len() as f64
        * sim.substeps_for(parsed.dt) as f64
        * parsed.solver.iterations as f64
        * entities.len() as f64;
    let mut line = stats(&mut times);
    let median_s = line["median_ms"].as_f64().unwrap_or(f64::NAN) * 1e-3;
    line["scene"] = scene.display().to_string().into();
    line["frames"] = frames.into();
    line["copies"] = entities.len().into();
    line["per_cloth_median_ms"] = (median_s * 1e3 / entities.len() as f64).into();
    let mean = solver_ms.iter().sum::<f64>() / solver_ms.len().max(1) as f64;
    if let Some(budget) = parsed.budget_ms {
        // The share of frames whose steps took more than 1.1 × the budget.
        let over = solver_ms.iter().filter(|&&ms| ms > 1.1 * budget as f64);
        line["budget_ms"] = budget.into();
        line["frames_over_1_1_budget"] = over.count().into();
    }
    let mut steps = stats(&mut solver_ms);
    // The machine's frame-to-frame noise, for comparing a budget's overruns with: the frames
    // whose steps took more than 1.1 × the median.
    let median = steps["median_ms"].as_f64().unwrap_or(f64::NAN);
    let over_median = solver_ms.iter().filter(|&&ms| ms > 1.1 * median);
    steps["frames_over_1_1_median"] = over_median.count().into();
    line["cloth_steps_median_ms"] = steps["median_ms"].clone();
    steps["mean_ms"] = mean.into();
    line["cloth_steps"] = steps;
    line["outside_cloth_steps_median_ms"] = stats(&mut outside)["median_ms"].clone();
    line["threads"] = bevy::tasks::ComputeTaskPool::get().thread_num().into();
    line["executor"] = executor.into();
    line["particles"] = state.positions().len().into();
    line["springs"] = sim.model().springs.len().into();
    line["substeps"] = sim.substeps_for(parsed.dt).into();
    line["integrator"] = sim.active_integrator().name().into();
    if let Some(r) = sim.accuracy_report() {
        line["tolerance_mode"] = serde_json::json!({
            "tolerance_m_per_s": r.tolerance, "estimate_m_per_s": r.error_rate,
            "estimates": r.estimates, "rejected": r.rejected, "at_cap": r.at_cap,
            "at_floor": r.at_floor,
        });
    }
    line["constraint_solves_per_s"] = (solves / median_s).round().into();
    // Each family: which of them holds more of an unconverged solve's residual depends
    // on the order they are projected in.
    line["median_structural_strain"] = median_strain(sim, &[SpringKind::Structural]).into();
    line["median_shear_strain"] = median_strain(sim, &[SpringKind::Shear]).into();
    line["median_bend_strain"] = median_strain(sim, &[SpringKind::Bend]).into();
    // All springs pooled, as the bevy_silk harness pools all of its sticks.
    line["median_spring_strain"] = median_strain(sim, &SpringKind::ALL).into();
    line["cloth_frames_asleep"] = slept.into();
    line["cloth_frames_by_level"] = LodLevel::ALL
        .iter()
        .map(|&l| (l.name().to_string(), levels[l as usize].into()))
        .collect::<serde_json::Map<_, _>>()
        .into();
    Ok(line)
}
