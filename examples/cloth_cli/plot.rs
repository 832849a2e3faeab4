//! The work-precision plot: one log-log panel per scene (largest particle error against
//! milliseconds per simulated frame), one curve per integrator (its Pareto front, with every
//! measured point as a dot), tolerance mode's runs joined in order of their tolerance, failed
//! (unstable) runs as crosses along the top edge. Drawn with plotters' bitmap backend and encoded
//! with the `png` crate. Plotters is built without a font engine, so labels use the small built-in
//! pixel font below.

use std::path::Path;

use plotters::coord::Shift;
use plotters::prelude::*;

use super::work_precision::{Measurement, pareto_front};
use bevy_cloth::harness::scenes::AccuracyScene;
use bevy_cloth::sim::Integrator;

/// The colour of each integrator's curve.
pub fn color(integrator: Integrator) -> RGBColor {
    match integrator {
        Integrator::Xpbd => RGBColor(214, 39, 40),
        Integrator::SymplecticEuler => RGBColor(31, 119, 180),
        Integrator::Verlet => RGBColor(44, 160, 44),
        Integrator::ImplicitEuler => RGBColor(148, 103, 189),
        Integrator::Auto => RGBColor(0, 0, 0),
    }
}

/// The colour of the tolerance-mode curve (orange).
pub const TOLERANCE_COLOR: RGBColor = RGBColor(255, 127, 14);

/// The curves drawn, in drawing order: the four methods, then the default's choice among them on
/// top.
pub const CURVES: [Integrator; 5] = [
    Integrator::Xpbd,
    Integrator::SymplecticEuler,
    Integrator::Verlet,
    Integrator::ImplicitEuler,
    Integrator::Auto,
];

/// Colour names for the Markdown legend.
pub fn color_name(integrator: Integrator) -> &'static str {
    match integrator {
        Integrator::Xpbd => "red",
        Integrator::SymplecticEuler => "blue",
        Integrator::Verlet => "green",
        Integrator::ImplicitEuler => "purple",
        Integrator::Auto => "black",
    }
}

/// 3×5 pixel glyphs, one row of three bits per entry, top row first.
fn glyph(c: char) -> [u8; 5] {
    match c.to_ascii_uppercase() {
        'A' => [2, 5, 7, 5, 5],
        'B' => [6, 5, 6, 5, 6],
        'C' => [3, 4, 4, 4, 3],
        'D' => [6, 5, 5, 5, 6],
        'E' => [7, 4, 6, 4, 7],
        'F' => [7, 4, 6, 4, 4],
        'G' => [3, 4, 5, 5, 3],
        'H' => [5, 5, 7, 5, 5],
        'I' => [7, 2, 2, 2, 7],
        'J' => [1, 1, 1, 5, 2],
        'K' => [5, 5, 6, 5, 5],
        'L' => [4, 4, 4, 4, 7],
        'M' => [5, 7, 7, 5, 5],
        'N' => [6, 5, 5, 5, 5],
        'O' => [2, 5, 5, 5, 2],
        'P' => [6, 5, 6, 4, 4],
        'Q' => [2, 5, 5, 6, 3],
        'R' => [6, 5, 6, 5, 5],
        'S' => [3, 4, 2, 1, 6],
        'T' => [7, 2, 2, 2, 2],
        'U' => [5, 5, 5, 5, 7],
        'V' => [5, 5, 5, 5, 2],
        'W' => [5, 5, 7, 7, 5],
        'X' => [5, 5, 2, 5, 5],
        'Y' => [5, 5, 2, 2, 2],
        'Z' => [7, 1, 2, 4, 7],
        '0' => [7, 5, 5, 5, 7],
        '1' => [2, 6, 2, 2, 7],
        '2' => [6, 1, 2, 4, 7],
        '3' => [6, 1, 2, 1, 6],
        '4' => [5, 5, 7, 1, 1],
        '5' => [7, 4, 6, 1, 6],
        '6' => [3, 4, 7, 5, 7],
        '7' => [7, 1, 2, 2, 2],
        '8' => [7, 5, 7, 5, 7],
        '9' => [7, 5, 7, 1, 6],
        '-' => [0, 0, 7, 0, 0],
        '.' => [0, 0, 0, 0, 2],
        '/' => [1, 1, 2, 4, 4],
        '(' => [2, 4, 4, 4, 2],
        ')' => [2, 1, 1, 1, 2],
        ':' => [0, 2, 0, 2, 0],
        '=' => [0, 7, 0, 7, 0],
        '×' => [0, 5, 2, 5, 0],
        '<' => [1, 2, 4, 2, 1],
        '>' => [4, 2, 1, 2, 4],
        _ => [0; 5],
    }
}

/// Width in pixels of `text` at pixel size `scale`.
fn text_width(text: &str, scale: i32) -> i32 {
    text.chars().count() as i32 * 4 * scale - scale
}

/// Draws `text` with its top-left corner at `(x, y)`.
fn text<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    text: &str,
    (x, y): (i32, i32),
    scale: i32,
    color: &RGBColor,
) -> Result<(), Box<dyn std::error::Error>> {
    for (k, c) in text.chars().enumerate() {
        let x0 = x + k as i32 * 4 * scale;
        for (row, bits) in glyph(c).iter().enumerate() {
            for col in 0..3 {
                if bits & (4 >> col) != 0 {
                    let (px, py) = (x0 + col * scale, y + row as i32 * scale);
                    area.draw(&Rectangle::new(
                        [(px, py), (px + scale - 1, py + scale - 1)],
                        color.filled(),
                    ))
                    .map_err(|e| e.to_string())?;
                }
            }
        }
    }
    Ok(())
}

/// `10^e` as a label: `1E-3`, `1`, `10`.
fn decade_label(e: i32) -> String {
    match e {
        0 => "1".into(),
        1 => "10".into(),
        2 => "100".into(),
        _ => format!("1E{e}"),
    }
}

/// Writes the plot of `results` (one `(scene, measurements)` entry per scene) to `path` as PNG.
pub fn write_plot(
    path: &Path,
    results: &[(AccuracyScene, Vec<Measurement>)],
    horizon: f64,
) -> Result<(), Box<dyn std::error::Error>> {
    let (panel_w, panel_h, legend_h) = (620u32, 520u32, 56u32);
    let (w, h) = (panel_w * results.len().max(1) as u32, panel_h + legend_h);
    let mut buffer = vec![255u8; (w * h * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let (plots, legend) = root.split_vertically(panel_h);
        let panels = plots.split_evenly((1, results.len().max(1)));
        for ((scene, measurements), panel) in results.iter().zip(&panels) {
            draw_panel(panel, (*scene, horizon), measurements)?;
        }
        let mut x = 80;
        for integrator in CURVES {
            let c = color(integrator);
            legend
                .draw(&PathElement::new(
                    vec![(x, 24), (x + 40, 24)],
                    c.stroke_width(3),
                ))
                .map_err(|e| e.to_string())?;
            text(&legend, integrator.name(), (x + 50, 17), 3, &BLACK)?;
            x += 90 + text_width(integrator.name(), 3);
        }
        legend
            .draw(&PathElement::new(
                vec![(x, 24), (x + 40, 24)],
                TOLERANCE_COLOR.stroke_width(3),
            ))
            .map_err(|e| e.to_string())?;
        text(&legend, "tolerance", (x + 50, 17), 3, &BLACK)?;
        x += 90 + text_width("tolerance", 3);
        let note = "X: UNSTABLE (NON-FINITE OR ERROR > 1)";
        legend
            .draw(&Cross::new((x + 8, 24), 7, BLACK.stroke_width(2)))
            .map_err(|e| e.to_string())?;
        text(&legend, &note[2..], (x + 24, 17), 3, &BLACK)?;
        root.present().map_err(|e| e.to_string())?;
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut encoder = png::Encoder::new(file, w, h);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header()?;
    writer.write_image_data(&buffer)?;
    writer.finish()?;
    Ok(())
}

fn draw_panel<DB: DrawingBackend>(
    panel: &DrawingArea<DB, Shift>,
    (scene, horizon): (AccuracyScene, f64),
    measurements: &[Measurement],
) -> Result<(), Box<dyn std::error::Error>> {
    let ok: Vec<&Measurement> = measurements
        .iter()
        .filter(|m| m.max_error.is_some())
        .collect();
    let times = measurements.iter().map(|m| m.ms_per_frame);
    let (tmin, tmax) = times.fold((f64::MAX, f64::MIN), |(a, b), t| (a.min(t), b.max(t)));
    let emin = ok
        .iter()
        .filter_map(|m| m.max_error)
        .fold(f64::MAX, f64::min)
        .max(1e-9);
    let (x0, x1) = (
        10f64.powf(tmin.max(1e-6).log10().floor()),
        10f64.powf(tmax.max(1e-5).log10().ceil()),
    );
    let (y0, y1) = (10f64.powf(emin.log10().floor()), 10.0);
    let (dw, dh) = panel.dim_in_pixel();
    let (left, right, top, bottom) = (84i32, 20i32, 46i32, 60i32);
    let (px, py) = panel.get_base_pixel();
    let inner = panel.margin(top as u32, bottom as u32, left as u32, right as u32);
    let mut chart = ChartBuilder::on(&inner)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(|e| e.to_string())?;
    let grey = RGBColor(225, 225, 225);
    let (ex0, ex1) = (x0.log10().round() as i32, x1.log10().round() as i32);
    let (ey0, ey1) = (y0.log10().round() as i32, y1.log10().round() as i32);
    for e in ex0..=ex1 {
        let v = 10f64.powi(e);
        chart
            .draw_series(LineSeries::new(
                vec![(v, y0), (v, y1)],
                grey.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
        let (sx, sy) = chart.backend_coord(&(v, y0));
        let label = decade_label(e);
        text(
            panel,
            &label,
            (sx - px - text_width(&label, 2) / 2, sy - py + 8),
            2,
            &BLACK,
        )?;
    }
    for e in ey0..=ey1 {
        let v = 10f64.powi(e);
        chart
            .draw_series(LineSeries::new(
                vec![(x0, v), (x1, v)],
                grey.stroke_width(1),
            ))
            .map_err(|e| e.to_string())?;
        let (sx, sy) = chart.backend_coord(&(x0, v));
        let label = decade_label(e);
        text(
            panel,
            &label,
            (sx - px - 8 - text_width(&label, 2), sy - py - 5),
            2,
            &BLACK,
        )?;
    }
    // The goal: error 1e-3 at 1 ms per frame per 1000 particles.
    if let Some(m) = measurements.first() {
        let budget = m.particles as f64 / 1000.0;
        let gold = RGBColor(200, 150, 0);
        chart
            .draw_series(LineSeries::new(
                vec![(x0, 1e-3), (budget, 1e-3), (budget, y0)],
                gold.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?;
    }
    // Frame.
    chart
        .draw_series(LineSeries::new(
            vec![(x0, y0), (x1, y0), (x1, y1), (x0, y1), (x0, y0)],
            BLACK.stroke_width(1),
        ))
        .map_err(|e| e.to_string())?;
    for integrator in CURVES {
        let c = color(integrator);
        let mine: Vec<&Measurement> = measurements
            .iter()
            .filter(|m| m.integrator == integrator && m.tolerance.is_none())
            .collect();
        let front = pareto_front(mine.iter().copied());
        // The default's curve is thinner, drawn over the methods it chooses between.
        let (width, dot) = if integrator == Integrator::Auto {
            (2, 2)
        } else {
            (3, 4)
        };
        chart
            .draw_series(LineSeries::new(
                front.iter().map(|(t, e)| (*t, *e)),
                c.stroke_width(width),
            ))
            .map_err(|e| e.to_string())?;
        for m in &mine {
            match m.max_error {
                Some(e) => chart
                    .draw_series(std::iter::once(Circle::new(
                        (m.ms_per_frame, e.max(y0)),
                        dot,
                        c.filled(),
                    )))
                    .map_err(|e| e.to_string())?,
                None => chart
                    .draw_series(std::iter::once(Cross::new(
                        (m.ms_per_frame, y1 * 0.7),
                        6,
                        c.stroke_width(2),
                    )))
                    .map_err(|e| e.to_string())?,
            };
        }
    }
    let mut tolerance: Vec<&Measurement> = measurements
        .iter()
        .filter(|m| m.tolerance.is_some())
        .collect();
    tolerance.sort_by(|a, b| {
        let t = |m: &Measurement| m.tolerance.unwrap_or(0.0);
        t(b).total_cmp(&t(a))
    });
    chart
        .draw_series(LineSeries::new(
            tolerance
                .iter()
                .filter_map(|m| m.max_error.map(|e| (m.ms_per_frame, e.max(y0)))),
            TOLERANCE_COLOR.stroke_width(3),
        ))
        .map_err(|e| e.to_string())?;
    for m in &tolerance {
        let point = match m.max_error {
            Some(e) => (m.ms_per_frame, e.max(y0)),
            None => (m.ms_per_frame, y1 * 0.7),
        };
        chart
            .draw_series(std::iter::once(TriangleMarker::new(
                point,
                7,
                TOLERANCE_COLOR.filled(),
            )))
            .map_err(|e| e.to_string())?;
    }
    let title = format!(
        "{}: {} PARTICLES, {horizon} S",
        scene.name(),
        measurements.first().map_or(0, |m| m.particles)
    );
    text(
        panel,
        &title,
        ((dw as i32 - text_width(&title, 3)) / 2, 12),
        3,
        &BLACK,
    )?;
    let xl = "MS PER 1/60 S FRAME";
    text(
        panel,
        xl,
        ((dw as i32 - text_width(xl, 2)) / 2, dh as i32 - 22),
        2,
        &BLACK,
    )?;
    text(panel, "LARGEST ERROR", (6, top - 24), 2, &BLACK)?;
    Ok(())
}
