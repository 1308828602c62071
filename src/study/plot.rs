//! The study's plots, each as PNG and SVG (plotters; the face bundled in `assets/fonts/`).
//!
//! In: [`StudyResults`]. Out: `pareto` (RMS error vs frame p95 time, every run,
//! the Pareto front joined), `knobs` (one small panel a knob, each point
//! labelled with its setting), `budget` (for frame budgets of 1, 4 and 16 ms,
//! the most accurate run that fits), `fig13_collision_vs_nodes` (collision
//! time vs source nodes a face per backend, the paper's Fig. 13 points beside)
//! `speed_vs_error` (vertices pulled through a blade and RMS error vs speed
//! in thicknesses a frame, culling on and off under both contact models) and
//! `force_path` (one panel a knob: the force on the tissue against the
//! position along the path, each run of the knob over the reference).
//! Stays true: axes carry units; log axes where values span decades; an error
//! of exactly 0 is drawn on a separate band labelled "exact" below the axis'
//! smallest measured error, never at an invented number.

use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::prelude::*;

use super::output::{BUDGETS_MS, PAPER_COLLISION_CPU_MS, PAPER_COLLISION_GPU_MS, best_within, pareto_front};
use super::plan::{backend_name, contact_name};
use super::{Knob, RunRow, StudyError, StudyResults};
use crate::scenario::CollisionBackend;
use crate::sim::StageId;

/// Pixel size of every plot.
pub const SIZE: (u32, u32) = (1100, 720);
/// Pixel size of the panel-per-knob figure.
pub const KNOBS_SIZE: (u32, u32) = (1400, 1500);

/// The font family of every plot: DejaVu Sans, bundled (`assets/fonts/`) and
/// registered with plotters on the first plot, so that a plot is drawn alike
/// on every machine and needs no system font library.
pub(crate) const FONT: &str = "sans-serif";

/// Registers [`FONT`]'s regular and bold faces with plotters, once a process.
fn register_fonts() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        // The bytes are compiled in and parse; a failure here is a defect of the build.
        let faces: [(FontStyle, &'static [u8]); 2] =
            [(FontStyle::Normal, include_bytes!("../../assets/fonts/DejaVuSans.ttf")), (FontStyle::Bold, include_bytes!("../../assets/fonts/DejaVuSans-Bold.ttf"))];
        for (style, bytes) in faces {
            if plotters::style::register_font(FONT, style, bytes).is_err() {
                tracing::error!("the bundled plot font ({}) does not parse: plots will have no text", style.as_str());
            }
        }
    });
}

fn knob_color(k: Option<Knob>) -> RGBColor {
    match k {
        None => BLACK,
        Some(Knob::SourceNodes) => RGBColor(31, 119, 180),
        Some(Knob::Mesh) => RGBColor(255, 127, 14),
        Some(Knob::Speed) => RGBColor(44, 160, 44),
        Some(Knob::Contact) => RGBColor(227, 119, 194),
        Some(Knob::Substeps) => RGBColor(23, 190, 207),
        Some(Knob::Backend) => RGBColor(214, 39, 40),
        Some(Knob::Storage) => RGBColor(148, 103, 189),
        Some(Knob::RegionOfInterest) => RGBColor(140, 86, 75),
        Some(Knob::Skull) => RGBColor(188, 189, 34),
        Some(Knob::Refine) => RGBColor(127, 127, 127),
    }
}

/// A log error axis with an "exact" band: measured errors span `lo..hi` (mm);
/// an error of 0 is drawn at `exact`, a decade-spaced step below `lo`.
#[derive(Debug, Clone, Copy)]
struct ErrorAxis {
    exact: f64,
    lo: f64,
    hi: f64,
    /// Some error is exactly 0: the band is drawn.
    has_exact: bool,
}

impl ErrorAxis {
    fn of(errors: impl Iterator<Item = f64>) -> Self {
        let errors: Vec<f64> = errors.collect();
        let (lo, hi) = log_range(errors.iter().copied(), (1e-3, 10.0));
        Self { exact: lo / 10.0, lo, hi, has_exact: errors.contains(&0.0) }
    }
    fn range(&self) -> std::ops::Range<f64> {
        if self.has_exact { self.exact / 2.0..self.hi } else { self.lo..self.hi }
    }
    /// Where an error (mm) is drawn.
    fn y(&self, e: f64) -> f64 {
        if e > 0.0 { e.max(self.lo) } else { self.exact }
    }
    /// Tick text: "exact" on the band, the log ticks above it, nothing between.
    fn tick(&self, v: &f64) -> String {
        if (v / self.exact - 1.0).abs() < 1e-9 {
            "exact".into()
        } else if *v < self.lo {
            String::new()
        } else {
            log_tick(v)
        }
    }
    /// Height of the dashed line between the band and the measured errors.
    fn separator(&self) -> f64 {
        (self.exact * self.lo).sqrt()
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

/// What a drawing step returns: plotters' error, in words.
pub type Res = Result<(), String>;

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

/// Any plotters error, in words.
pub(crate) fn err<E: std::fmt::Display>(e: E) -> String {
    e.to_string()
}

/// (frame p95 ms, RMS error mm) of a run with accuracy.
fn error_point(r: &RunRow) -> Option<(f64, f64)> {
    let m = r.outcome.as_ref().ok()?;
    let a = m.accuracy.as_ref()?;
    Some((m.frame.p95 * 1e3, a.rms_error_m * 1e3))
}

/// The dashed line over the "exact" band and its label, when the axis has the band.
fn exact_band<DB: DrawingBackend>(
    chart: &mut ChartContext<'_, DB, Cartesian2d<LogCoord<f64>, LogCoord<f64>>>,
    axis: &ErrorAxis,
    x0: f64,
    x1: f64,
) -> Res {
    if !axis.has_exact {
        return Ok(());
    }
    let y = axis.separator();
    chart.draw_series(DashedLineSeries::new(vec![(x0, y), (x1, y)], 6, 4, RGBColor(150, 150, 150).into())).map_err(err)?;
    chart.draw_series(std::iter::once(Text::new("exact (0)", (x0 * 1.05, y), (FONT, 13).into_font().color(&RGBColor(100, 100, 100))))).map_err(err)?;
    Ok(())
}

fn knob_label(k: Option<Knob>) -> String {
    k.map_or_else(|| "the reference (finest of every knob)".into(), |k| format!("sweep: {}", k.name()))
}

fn draw_pareto<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let points: Vec<(Option<Knob>, (f64, f64))> = results.rows.iter().filter_map(|r| error_point(r).map(|p| (r.knob, p))).collect();
    let (x0, x1) = log_range(points.iter().map(|p| p.1.0), (0.1, 100.0));
    let axis = ErrorAxis::of(points.iter().map(|p| p.1.1));
    let mut chart = ChartBuilder::on(root)
        .caption("Accuracy vs time: every run against the one reference, Pareto front joined", (FONT, 24))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(90)
        .build_cartesian_2d((x0..x1).log_scale(), axis.range().log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_label_formatter(&log_tick)
        .y_label_formatter(&|v| axis.tick(v))
        .x_desc("frame time, 95th percentile (ms)")
        .y_desc("RMS surface displacement error (mm)")
        .axis_desc_style((FONT, 18))
        .label_style((FONT, 15))
        .draw()
        .map_err(err)?;
    exact_band(&mut chart, &axis, x0, x1)?;
    let front: Vec<(f64, f64)> = pareto_front(&results.rows).into_iter().filter_map(error_point).map(|(x, e)| (x, axis.y(e))).collect();
    chart
        .draw_series(LineSeries::new(front, BLACK.stroke_width(2)))
        .map_err(err)?
        .label("Pareto front")
        .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(2)));
    for knob in std::iter::once(None).chain(Knob::ALL.into_iter().map(Some)) {
        let pts: Vec<(f64, f64)> = points.iter().filter(|p| p.0 == knob).map(|p| (p.1.0, axis.y(p.1.1))).collect();
        if pts.is_empty() {
            continue;
        }
        let c = knob_color(knob);
        chart
            .draw_series(pts.into_iter().map(|p| Circle::new(p, 6, c.filled())))
            .map_err(err)?
            .label(knob_label(knob))
            .legend(move |(x, y)| Circle::new((x + 10, y), 6, c.filled()));
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT, 15))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(err)?;
    root.present().map_err(err)
}

/// One small panel a knob: RMS error vs frame p95, each point labelled.
fn draw_knobs<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let knobs: Vec<Knob> = Knob::ALL.into_iter().filter(|k| results.rows.iter().any(|r| r.knob == Some(*k) && error_point(r).is_some())).collect();
    let root = root.titled("What each knob buys: error against the reference vs frame time (one panel a knob)", (FONT, 26)).map_err(err)?;
    let columns = 2;
    let rows = knobs.len().div_ceil(columns).max(1);
    let panels = root.split_evenly((rows, columns));
    for (knob, area) in knobs.iter().zip(&panels) {
        let points: Vec<(String, f64, f64)> =
            results.rows.iter().filter(|r| r.knob == Some(*knob)).filter_map(|r| error_point(r).map(|(x, e)| (r.label.clone(), x, e))).collect();
        let (x0, x1) = log_range(points.iter().map(|p| p.1), (0.1, 100.0));
        let axis = ErrorAxis::of(points.iter().map(|p| p.2));
        let mut chart = ChartBuilder::on(area)
            .caption(format!("{} ({} runs)", knob.name(), points.len()), (FONT, 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(65)
            .build_cartesian_2d((x0..x1 * 3.0).log_scale(), axis.range().log_scale())
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_label_formatter(&log_tick)
            .y_label_formatter(&|v| axis.tick(v))
            .x_desc("frame p95 (ms)")
            .y_desc("RMS error (mm)")
            .axis_desc_style((FONT, 14))
            .label_style((FONT, 12))
            .draw()
            .map_err(err)?;
        exact_band(&mut chart, &axis, x0, x1 * 3.0)?;
        let c = knob_color(Some(*knob));
        for (label, x, e) in &points {
            let p = (*x, axis.y(*e));
            chart.draw_series(std::iter::once(Circle::new(p, 5, c.filled()))).map_err(err)?;
            chart
                .draw_series(std::iter::once(Text::new(label.clone(), p, (FONT, 12).into_font().color(&BLACK))))
                .map_err(err)?;
        }
    }
    root.present().map_err(err)
}

/// One panel a knob: |F| on the tissue against the position along the path
/// (insert, open, close, withdraw; the phase starts dashed), the reference in
/// black under each of the knob's runs; a legend a panel. Each panel has its
/// own scale and shows the part of the path where its forces are.
fn draw_force_path<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let path_of = |r: &RunRow| {
        let mm_newton = |m: &super::RunMeasure| m.force_along.iter().map(|(s, f)| (*s as f64 * 1e-6, f.norm())).collect::<Vec<_>>();
        r.outcome.as_ref().ok().map(mm_newton).filter(|p| !p.is_empty())
    };
    let reference = results.rows.iter().find(|r| r.is_reference()).and_then(path_of);
    // Where the reference's mesh is not the base's: the reference's settings on the base mesh, dashed.
    let own_mesh = results.mesh_reference.as_ref().and_then(|r| path_of(r).map(|p| (format!("finest on {}", r.settings.mesh.label()), p)));
    let knobs: Vec<Knob> = Knob::ALL.into_iter().filter(|k| results.rows.iter().any(|r| r.knob == Some(*k) && path_of(r).is_some())).collect();
    let title = if own_mesh.is_some() {
        "Force on the tissue along the path: each knob's runs against the reference (black) and the base mesh's finest (dashed)"
    } else {
        "Force on the tissue along the path: each knob's runs against the reference (black)"
    };
    let root = root.titled(title, (FONT, 26)).map_err(err)?;
    let m = &results.motion;
    let length_mm = (2.0 * m.insert_m + 2.0 * m.open_m) * 1e3;
    let columns = 2;
    let rows = knobs.len().div_ceil(columns).max(1);
    let panels = root.split_evenly((rows, columns));
    for (knob, area) in knobs.iter().zip(&panels) {
        // Each panel its own scale: the path where this panel's forces are
        // above 1 % of its largest (2 mm either side), up to that force.
        let curves: Vec<Vec<(f64, f64)>> = reference
            .iter()
            .chain(own_mesh.iter().map(|(_, p)| p))
            .cloned()
            .chain(results.rows.iter().filter(|r| r.knob == Some(*knob)).filter_map(path_of))
            .collect();
        let top = curves.iter().flatten().map(|p| p.1).fold(0.0, f64::max).max(1e-6);
        let loaded = || curves.iter().flatten().filter(|p| p.1 > 0.01 * top).map(|p| p.0);
        let x0 = (loaded().fold(f64::INFINITY, f64::min) - 2.0).max(0.0);
        let x1 = (loaded().fold(f64::NEG_INFINITY, f64::max) + 2.0).min(length_mm);
        let (x0, x1) = if x0 < x1 { (x0, x1) } else { (0.0, length_mm) };
        let top = top * 1.1;
        let mut chart = ChartBuilder::on(area)
            .caption(knob.name(), (FONT, 18))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(60)
            .build_cartesian_2d(x0..x1, 0.0..top)
            .map_err(err)?;
        chart
            .configure_mesh()
            .x_desc("position along the path (mm)")
            .y_desc("|F| on the tissue (N)")
            .axis_desc_style((FONT, 14))
            .label_style((FONT, 12))
            .draw()
            .map_err(err)?;
        for (end, phase) in [(m.insert_m, "open"), (m.insert_m + m.open_m, "close"), (m.insert_m + 2.0 * m.open_m, "withdraw")] {
            let x = end * 1e3;
            if x <= x0 || x >= x1 {
                continue;
            }
            chart.draw_series(DashedLineSeries::new(vec![(x, 0.0), (x, top)], 5, 4, RGBColor(170, 170, 170).into())).map_err(err)?;
            chart.draw_series(std::iter::once(Text::new(phase, (x, top * 0.97), (FONT, 12).into_font().color(&RGBColor(110, 110, 110))))).map_err(err)?;
        }
        if let Some(p) = &reference {
            chart
                .draw_series(LineSeries::new(p.iter().copied().filter(|q| q.0 >= x0 && q.0 <= x1), BLACK.stroke_width(3)))
                .map_err(err)?
                .label("reference")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLACK.stroke_width(3)));
        }
        if let Some((label, p)) = &own_mesh {
            let grey = RGBColor(90, 90, 90);
            chart
                .draw_series(DashedLineSeries::new(p.iter().copied().filter(|q| q.0 >= x0 && q.0 <= x1), 8, 5, grey.stroke_width(2)))
                .map_err(err)?
                .label(label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(2)));
        }
        for (i, r) in results.rows.iter().filter(|r| r.knob == Some(*knob)).enumerate() {
            let Some(p) = path_of(r) else { continue };
            let c = Palette99::pick(i).to_rgba();
            chart
                .draw_series(LineSeries::new(p.into_iter().filter(|q| q.0 >= x0 && q.0 <= x1), c.stroke_width(2)))
                .map_err(err)?
                .label(r.label.clone())
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], c.stroke_width(2)));
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font((FONT, 12))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(err)?;
    }
    root.present().map_err(err)
}

/// For each frame budget, the most accurate run within it: one bar a budget.
fn draw_budget<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let best: Vec<(f64, Option<&RunRow>)> = BUDGETS_MS.iter().map(|&b| (b, best_within(&results.rows, b))).collect();
    let axis = ErrorAxis::of(best.iter().filter_map(|(_, r)| r.and_then(|r| error_point(r)).map(|p| p.1)));
    let mut chart = ChartBuilder::on(root)
        .caption("For a frame budget, the most accurate setting that fits (frame p95 within the budget)", (FONT, 22))
        .margin(20)
        .x_label_area_size(60)
        .y_label_area_size(110)
        .build_cartesian_2d(axis.range().log_scale(), -0.5..BUDGETS_MS.len() as f64 - 0.5)
        .map_err(err)?;
    // One row a budget, centred on its index; ticks every half row, labelled on the whole ones.
    let row_of = |v: &f64| {
        let k = v.round();
        ((v - k).abs() < 1e-6 && k >= 0.0).then_some(k as usize)
    };
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(2 * BUDGETS_MS.len() + 1)
        .x_label_formatter(&|v| axis.tick(v))
        .y_label_formatter(&|v: &f64| row_of(v).and_then(|k| BUDGETS_MS.get(k)).map(|b| format!("{b} ms")).unwrap_or_default())
        .x_desc("RMS surface displacement error against the reference (mm; shorter is better)")
        .y_desc("frame budget (p95)")
        .axis_desc_style((FONT, 18))
        .label_style((FONT, 16))
        .draw()
        .map_err(err)?;
    for (k, (budget, row)) in best.iter().enumerate() {
        let y = k as f64;
        let Some(r) = row else {
            chart.draw_series(std::iter::once(Text::new(format!("nothing fits in {budget} ms"), (axis.range().start, y), (FONT, 16)))).map_err(err)?;
            continue;
        };
        let Some((p95, e)) = error_point(r) else { continue };
        let c = knob_color(r.knob);
        chart
            .draw_series(std::iter::once(Rectangle::new([(axis.range().start, y - 0.3), (axis.y(e), y + 0.3)], c.mix(0.6).filled())))
            .map_err(err)?;
        let rms = if e == 0.0 { "exact".to_string() } else if e < 0.01 { format!("{e:.1e} mm") } else { format!("{e:.3} mm") };
        let text = format!("{}: {} (p95 {:.2} ms, RMS {rms})", r.knob.map_or("reference", |k| k.name()), r.label, p95);
        chart.draw_series(std::iter::once(Text::new(text, (axis.range().start, y + 0.05), (FONT, 16)))).map_err(err)?;
    }
    root.present().map_err(err)
}

fn draw_fig13<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let rows: Vec<(CollisionBackend, f64, f64)> = results
        .rows
        .iter()
        .filter(|r| r.knob == Some(Knob::Backend))
        .filter_map(|r| {
            let p = r.outcome.as_ref().ok()?.stage(StageId::Collision)?;
            Some((r.settings.backend, r.settings.nodes_per_face() as f64, p.p50 * 1e3))
        })
        .collect();
    let (x0, x1) = log_range(rows.iter().map(|r| r.1).chain([500.0]), (5.0, 5000.0));
    let (y0, y1) = log_range(rows.iter().map(|r| r.2).chain([PAPER_COLLISION_GPU_MS, PAPER_COLLISION_CPU_MS]), (0.01, 5000.0));
    let triangles = results.rows.iter().filter(|r| r.knob == Some(Knob::Backend)).find_map(|r| r.outcome.as_ref().ok().map(|m| m.surface_triangles));
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

/// The contact sweep: tunnelling and error vs speed, culling on/off under both contact models.
fn draw_speed<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    use crate::scenario::SpatulaContact as C;
    root.fill(&WHITE).map_err(err)?;
    // (contact, culling, speed, crossed, RMS mm)
    let rows: Vec<(C, bool, f64, f64, f64)> = results
        .rows
        .iter()
        .filter(|r| r.knob == Some(Knob::Contact))
        .filter_map(|r| {
            let m = r.outcome.as_ref().ok()?;
            let e = m.accuracy.as_ref().map(|a| a.rms_error_m * 1e3).unwrap_or(0.0);
            Some((r.settings.contact, r.settings.culling, r.value, m.crossed_total as f64, e))
        })
        .collect();
    let (x0, x1) = log_range(rows.iter().map(|r| r.2), (0.1, 10.0));
    let crossed_max = rows.iter().map(|r| r.3).fold(0.0, f64::max).max(1.0);
    let axis = ErrorAxis::of(rows.iter().map(|r| r.4));
    let (top, bottom) = root.split_vertically(SIZE.1 / 2);
    let series = [
        (C::Bilateral, true, RGBColor(31, 119, 180), 0),
        (C::Bilateral, false, RGBColor(214, 39, 40), 0),
        (C::Unilateral, true, RGBColor(44, 160, 44), 1),
        (C::Unilateral, false, RGBColor(255, 127, 14), 1),
        (C::Sliding, true, RGBColor(148, 103, 189), 2),
        (C::Sliding, false, RGBColor(140, 86, 75), 2),
    ];
    let name = |c: C, culling: bool| format!("{}, culling {}", contact_name(c), if culling { "on" } else { "off" });
    {
        let mut chart = ChartBuilder::on(&top)
            .caption("Culling under each contact law: tunnelling and error vs spatula speed", (FONT, 24))
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
        for (contact, culling, c, dash) in series {
            let pts: Vec<(f64, f64)> = rows.iter().filter(|r| r.0 == contact && r.1 == culling).map(|r| (r.2, r.3)).collect();
            if pts.is_empty() {
                continue;
            }
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(err)?;
            let style = c.stroke_width(2 + dash);
            chart
                .draw_series(LineSeries::new(pts, style))
                .map_err(err)?
                .label(name(contact, culling))
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], style));
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
        .build_cartesian_2d((x0..x1).log_scale(), axis.range().log_scale())
        .map_err(err)?;
    chart
        .configure_mesh()
        .x_label_formatter(&log_tick)
        .y_label_formatter(&|v| axis.tick(v))
        .x_desc("speed (blade thicknesses a frame)")
        .y_desc("RMS displacement error (mm)")
        .axis_desc_style((FONT, 17))
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    for (contact, culling, c, dash) in series {
        let pts: Vec<(f64, f64)> = rows.iter().filter(|r| r.0 == contact && r.1 == culling).map(|r| (r.2, axis.y(r.4))).collect();
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 5, c.filled()))).map_err(err)?;
        chart.draw_series(LineSeries::new(pts, c.stroke_width(2 + dash))).map_err(err)?;
    }
    root.present().map_err(err)
}

#[derive(Debug, Clone, Copy)]
enum Plot {
    Pareto,
    Knobs,
    Budget,
    Fig13,
    Speed,
    ForcePath,
}

impl Plot {
    fn size(self) -> (u32, u32) {
        match self {
            Plot::Knobs | Plot::ForcePath => KNOBS_SIZE,
            _ => SIZE,
        }
    }
}

fn draw<DB: DrawingBackend>(plot: Plot, root: &DrawingArea<DB, Shift>, results: &StudyResults) -> Res {
    match plot {
        Plot::Pareto => draw_pareto(root, results),
        Plot::Knobs => draw_knobs(root, results),
        Plot::Budget => draw_budget(root, results),
        Plot::Fig13 => draw_fig13(root, results),
        Plot::Speed => draw_speed(root, results),
        Plot::ForcePath => draw_force_path(root, results),
    }
}

/// `draw` on an RGB bitmap of `size` pixels in memory, encoded as PNG
/// (nothing touches a file: the caller writes the bytes whole).
pub fn png_bytes<F>(size: (u32, u32), draw: F) -> Result<Vec<u8>, String>
where
    F: FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> Res,
{
    register_fonts();
    let mut rgb = vec![0u8; size.0 as usize * size.1 as usize * 3];
    draw(&BitMapBackend::with_buffer(&mut rgb, size).into_drawing_area())?;
    let image = image::RgbImage::from_raw(size.0, size.1, rgb).ok_or("the bitmap has the wrong size")?;
    let mut encoded = std::io::Cursor::new(Vec::new());
    image.write_to(&mut encoded, image::ImageFormat::Png).map_err(err)?;
    Ok(encoded.into_inner())
}

/// `draw` on an SVG document of `size` pixels, as text.
pub(crate) fn svg_text<F>(size: (u32, u32), draw: F) -> Result<String, String>
where
    F: FnOnce(&DrawingArea<SVGBackend<'_>, Shift>) -> Res,
{
    register_fonts();
    let mut text = String::new();
    draw(&SVGBackend::with_string(&mut text, size).into_drawing_area())?;
    Ok(text)
}

fn both(out_dir: &Path, stem: &str, results: &StudyResults, plot: Plot) -> Result<Vec<PathBuf>, StudyError> {
    let png = out_dir.join(format!("{stem}.png"));
    let svg = out_dir.join(format!("{stem}.svg"));
    let size = plot.size();
    // Drawn in memory, then each file written whole (never a partial plot on a full disk).
    let encoded = png_bytes(size, |root| draw(plot, root, results)).map_err(|message| StudyError::Plot { path: png.clone(), message })?;
    crate::fsio::write_atomic(&png, &encoded).map_err(|e| StudyError::Output { path: e.path, source: e.source })?;
    let text = svg_text(size, |root| draw(plot, root, results)).map_err(|message| StudyError::Plot { path: svg.clone(), message })?;
    crate::fsio::write_atomic(&svg, text.as_bytes()).map_err(|e| StudyError::Output { path: e.path, source: e.source })?;
    Ok(vec![png, svg])
}

/// Draws every plot into `out_dir`; returns the files.
pub fn draw_all(results: &StudyResults, out_dir: &Path) -> Result<Vec<PathBuf>, StudyError> {
    let mut files = Vec::new();
    for (stem, plot) in [("pareto", Plot::Pareto), ("knobs", Plot::Knobs), ("budget", Plot::Budget), ("fig13_collision_vs_nodes", Plot::Fig13), ("speed_vs_error", Plot::Speed), ("force_path", Plot::ForcePath)] {
        files.extend(both(out_dir, stem, results, plot)?);
    }
    Ok(files)
}
