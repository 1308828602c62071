//! The study's plots, each as PNG and SVG (plotters; fonts from fontconfig).
//!
//! In: [`StudyResults`]. Out: `pareto` (RMS error vs frame p95 time, every run,
//! the Pareto front joined), `fig13_collision_vs_nodes` (collision time vs
//! source nodes a face per backend, the paper's Fig. 13 points beside), and
//! `speed_vs_error` (vertices pulled through the blade and RMS error vs speed
//! in thicknesses a frame, culling on and off). Stays true: axes carry units;
//! log axes where values span decades; an error of exactly 0 is drawn at the
//! axis floor and the axis says so.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::output::{PAPER_COLLISION_CPU_MS, PAPER_COLLISION_GPU_MS, pareto_front};
use super::plan::backend_name;
use super::{Knob, RunRow, StudyError, StudyResults};
use crate::scenario::CollisionBackend;
use crate::sim::StageId;

/// Pixel size of every plot.
pub const SIZE: (u32, u32) = (1100, 720);
/// Errors of exactly 0 mm are drawn at this floor on log axes, mm.
pub const ERROR_FLOOR_MM: f64 = 1e-6;

const FONT: &str = "sans-serif";

fn knob_color(k: Knob) -> RGBColor {
    match k {
        Knob::SourceNodes => RGBColor(31, 119, 180),
        Knob::Mesh => RGBColor(255, 127, 14),
        Knob::Speed => RGBColor(44, 160, 44),
        Knob::Backend => RGBColor(214, 39, 40),
        Knob::Storage => RGBColor(148, 103, 189),
        Knob::RegionOfInterest => RGBColor(140, 86, 75),
    }
}

fn backend_color(b: CollisionBackend) -> RGBColor {
    match b {
        CollisionBackend::Reference => RGBColor(214, 39, 40),
        CollisionBackend::Bvh => RGBColor(31, 119, 180),
        CollisionBackend::Gpu => RGBColor(44, 160, 44),
        CollisionBackend::Auto => RGBColor(148, 103, 189),
    }
}

fn log_range(values: impl Iterator<Item = f64>, default: (f64, f64)) -> (f64, f64) {
    let (lo, hi) = values.filter(|v| v.is_finite() && *v > 0.0).fold((f64::INFINITY, 0.0_f64), |(a, b), v| (a.min(v), b.max(v)));
    if lo.is_finite() && hi > 0.0 { (lo / 2.0, hi * 2.0) } else { default }
}

type Res = Result<(), String>;

/// Tick text on a log axis: only mantissas 1, 2 and 5 are labelled, compactly.
fn log_tick(v: &f64) -> String {
    if v.is_nan() || *v <= 0.0 {
        return String::new();
    }
    let e = v.log10().floor();
    let m = v / 10f64.powf(e);
    if ![1.0, 2.0, 5.0].iter().any(|k| (m - k).abs() < 1e-6 * k) {
        return String::new();
    }
    if (1e-3..1e5).contains(v) { format!("{}", (v * 1e4).round() / 1e4) } else { format!("{v:.0e}") }
}

fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// (frame p95 ms, RMS error mm floored) of a run with accuracy.
fn pareto_point(r: &RunRow) -> Option<(f64, f64)> {
    let m = r.outcome.as_ref().ok()?;
    let a = m.accuracy.as_ref()?;
    Some((m.frame.p95 * 1e3, (a.rms_error_m * 1e3).max(ERROR_FLOOR_MM)))
}

fn draw_pareto<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let points: Vec<(Knob, (f64, f64))> = results.rows.iter().filter_map(|r| pareto_point(r).map(|p| (r.knob, p))).collect();
    let (x0, x1) = log_range(points.iter().map(|p| p.1.0), (0.1, 100.0));
    let (_, y1) = log_range(points.iter().map(|p| p.1.1), (ERROR_FLOOR_MM, 10.0));
    let mut chart = ChartBuilder::on(root)
        .caption("Accuracy vs time: every run, Pareto front joined", (FONT, 26))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d((x0..x1).log_scale(), (ERROR_FLOOR_MM / 2.0..y1.max(ERROR_FLOOR_MM * 10.0)).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_label_formatter(&log_tick)
        .y_label_formatter(&log_tick)
        .x_desc("frame time, 95th percentile (ms)")
        .y_desc(format!("RMS surface displacement error (mm; 0 drawn at {ERROR_FLOOR_MM:.0e})"))
        .axis_desc_style((FONT, 18))
        .label_style((FONT, 15))
        .draw()
        .map_err(err)?;
    let front: Vec<(f64, f64)> = pareto_front(&results.rows).into_iter().filter_map(pareto_point).collect();
    chart
        .draw_series(LineSeries::new(front, BLACK.stroke_width(2)))
        .map_err(err)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    for knob in [Knob::SourceNodes, Knob::Mesh, Knob::Speed, Knob::Backend, Knob::Storage, Knob::RegionOfInterest] {
        let pts: Vec<(f64, f64)> = points.iter().filter(|p| p.0 == knob).map(|p| p.1).collect();
        if pts.is_empty() {
            continue;
        }
        let c = knob_color(knob);
        chart
            .draw_series(pts.into_iter().map(|p| Circle::new(p, 6, c.filled())))
            .map_err(err)?
            .label(format!("sweep: {}", knob.name()))
            .legend(move |(x, y)| Circle::new((x + 10, y), 6, c.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::MiddleLeft)
        .label_font((FONT, 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

fn draw_fig13<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let rows: Vec<(CollisionBackend, f64, f64)> = results
        .rows
        .iter()
        .filter(|r| r.knob == Knob::Backend && r.settings.culling)
        .filter_map(|r| {
            let p = r.outcome.as_ref().ok()?.stage(StageId::Collision)?;
            Some((r.settings.backend, r.settings.nodes_per_face() as f64, p.p50 * 1e3))
        })
        .collect();
    let (x0, x1) = log_range(rows.iter().map(|r| r.1).chain([500.0]), (5.0, 5000.0));
    let (y0, y1) = log_range(rows.iter().map(|r| r.2).chain([PAPER_COLLISION_GPU_MS, PAPER_COLLISION_CPU_MS]), (0.01, 5000.0));
    let triangles = results.rows.iter().filter(|r| r.knob == Knob::Backend).find_map(|r| r.outcome.as_ref().ok().map(|m| m.surface_triangles));
    let mut chart = ChartBuilder::on(root)
        .caption(
            format!("Collision time vs source nodes (our Fig. 13; {} surface triangles)", triangles.map(|t| t.to_string()).unwrap_or("?".into())),
            (FONT, 26),
        )
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_label_formatter(&log_tick)
        .y_label_formatter(&log_tick)
        .x_desc("source nodes a face (two faces, one spatula)")
        .y_desc("collision stage, median a frame (ms)")
        .axis_desc_style((FONT, 18))
        .label_style((FONT, 15))
        .draw()
        .map_err(err)?;
    for b in [CollisionBackend::Reference, CollisionBackend::Bvh, CollisionBackend::Gpu] {
        let mut pts: Vec<(f64, f64)> = rows.iter().filter(|r| r.0 == b).map(|r| (r.1, r.2)).collect();
        if pts.is_empty() {
            continue;
        }
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        let c = backend_color(b);
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(err)?;
        chart
            .draw_series(LineSeries::new(pts, c.stroke_width(2)))
            .map_err(err)?
            .label(format!("ours: {} backend", backend_name(b)))
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
    }
    for (ms, name, c) in [(PAPER_COLLISION_CPU_MS, "paper: CPU, 15,865 triangles", RGBColor(214, 39, 40)), (PAPER_COLLISION_GPU_MS, "paper: GPU, 15,865 triangles", RGBColor(44, 160, 44))] {
        chart
            .draw_series(std::iter::once(TriangleMarker::new((500.0, ms), 10, c.stroke_width(3))))
            .map_err(err)?
            .label(name)
            .legend(move |(x, y)| TriangleMarker::new((x + 10, y), 8, c.stroke_width(3)));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperLeft)
        .label_font((FONT, 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

fn draw_speed<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let rows: Vec<(bool, f64, f64, f64)> = results
        .rows
        .iter()
        .filter(|r| r.knob == Knob::Speed)
        .filter_map(|r| {
            let m = r.outcome.as_ref().ok()?;
            let e = m.accuracy.as_ref().map(|a| a.rms_error_m * 1e3).unwrap_or(0.0);
            Some((r.settings.culling, r.value, m.crossed_total as f64, e.max(ERROR_FLOOR_MM)))
        })
        .collect();
    let (x0, x1) = log_range(rows.iter().map(|r| r.1), (0.1, 10.0));
    let crossed_max = rows.iter().map(|r| r.2).fold(0.0, f64::max).max(1.0);
    let (_, e1) = log_range(rows.iter().map(|r| r.3), (ERROR_FLOOR_MM, 10.0));
    let (top, bottom) = root.split_vertically(SIZE.1 / 2);
    let series = [(true, "culling on", RGBColor(31, 119, 180)), (false, "culling off", RGBColor(214, 39, 40))];
    {
        let mut chart = ChartBuilder::on(&top)
            .caption("Tunnelling and error vs spatula speed", (FONT, 26))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(90)
            .build_cartesian_2d((x0..x1).log_scale(), 0.0..crossed_max * 1.15)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_label_formatter(&log_tick)
            .x_desc("speed (blade thicknesses a frame)")
            .y_desc("vertices pulled through (sum)")
            .axis_desc_style((FONT, 17))
            .label_style((FONT, 14))
            .draw()
            .map_err(err)?;
        for (culling, name, c) in series {
            let pts: Vec<(f64, f64)> = rows.iter().filter(|r| r.0 == culling).map(|r| (r.1, r.2)).collect();
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(err)?;
            chart
                .draw_series(LineSeries::new(pts, c.stroke_width(2)))
                .map_err(err)?
                .label(name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperLeft)
            .label_font((FONT, 15))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    let mut chart = ChartBuilder::on(&bottom)
        .margin(15)
        .x_label_area_size(55)
        .y_label_area_size(90)
        .build_cartesian_2d((x0..x1).log_scale(), (ERROR_FLOOR_MM / 2.0..e1.max(ERROR_FLOOR_MM * 10.0)).log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_label_formatter(&log_tick)
        .y_label_formatter(&log_tick)
        .x_desc("speed (blade thicknesses a frame)")
        .y_desc(format!("RMS displacement error (mm; 0 drawn at {ERROR_FLOOR_MM:.0e})"))
        .axis_desc_style((FONT, 17))
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    for (culling, _, c) in series {
        let pts: Vec<(f64, f64)> = rows.iter().filter(|r| r.0 == culling).map(|r| (r.1, r.3)).collect();
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(err)?;
        chart.draw_series(LineSeries::new(pts, c.stroke_width(2))).map_err(err)?;
    }
    root.present().map_err(err)
}

#[derive(Debug, Clone, Copy)]
enum Plot {
    Pareto,
    Fig13,
    Speed,
}

fn draw<DB: DrawingBackend>(plot: Plot, root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    match plot {
        Plot::Pareto => draw_pareto(root, results),
        Plot::Fig13 => draw_fig13(root, results),
        Plot::Speed => draw_speed(root, results),
    }
}

fn both(out_dir: &Path, stem: &str, results: &StudyResults, plot: Plot) -> Result<Vec<PathBuf>, StudyError> {
    let png = out_dir.join(format!("{stem}.png"));
    let svg = out_dir.join(format!("{stem}.svg"));
    // Drawn in memory, then each file written whole (never a partial plot on a full disk).
    let mut rgb = vec![0u8; SIZE.0 as usize * SIZE.1 as usize * 3];
    let drawn = draw(plot, &BitMapBackend::with_buffer(&mut rgb, SIZE).into_drawing_area(), results);
    drawn.map_err(|message| StudyError::Plot { path: png.clone(), message })?;
    let image = image::RgbImage::from_raw(SIZE.0, SIZE.1, rgb)
        .ok_or_else(|| StudyError::Plot { path: png.clone(), message: "the bitmap has the wrong size".into() })?;
    let mut encoded = std::io::Cursor::new(Vec::new());
    image
        .write_to(&mut encoded, image::ImageFormat::Png)
        .map_err(|e| StudyError::Plot { path: png.clone(), message: e.to_string() })?;
    crate::fsio::write_atomic(&png, encoded.get_ref()).map_err(|e| StudyError::Output { path: e.path, source: e.source })?;
    let mut text = String::new();
    let drawn = draw(plot, &SVGBackend::with_string(&mut text, SIZE).into_drawing_area(), results);
    drawn.map_err(|message| StudyError::Plot { path: svg.clone(), message })?;
    crate::fsio::write_atomic(&svg, text.as_bytes()).map_err(|e| StudyError::Output { path: e.path, source: e.source })?;
    Ok(vec![png, svg])
}

/// Draws every plot into `out_dir`; returns the files.
pub fn draw_all(results: &StudyResults, out_dir: &Path) -> Result<Vec<PathBuf>, StudyError> {
    let mut files = both(out_dir, "pareto", results, Plot::Pareto)?;
    files.extend(both(out_dir, "fig13_collision_vs_nodes", results, Plot::Fig13)?);
    files.extend(both(out_dir, "speed_vs_error", results, Plot::Speed)?);
    Ok(files)
}
