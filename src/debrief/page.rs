//! The debrief as one self-contained HTML page and its JSON.
//!
//! In: the runs as read, their [`Debrief`]s, the output path. Out: the page (inline CSS; the timeline of
//! `fissure plot` as inline SVG; each run's map of where pressure was applied as a base64 PNG) and, beside it with
//! the same stem, the JSON of the debriefs (one object for one run, a list for several). Stays true: every number
//! in a verdict table is its metric's value, the reference's or the limit, printed to four significant digits
//! ([`shown`]), and the row names its section and key (`data-section`, `data-key`) so a reader can find it in the
//! JSON; both files are written whole or not at all ([`crate::fsio::write_atomic`]).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use base64::Engine as _;
use plotters::coord::Shift;
use plotters::prelude::*;

use super::read::{DoseVertex, RunData};
use super::score::{Debrief, Metric, Verdict};
use crate::study::plot::{FONT, Res, err, png_bytes};

/// Why a page was not written; each names the file.
#[derive(Debug, thiserror::Error)]
pub enum DebriefPageError {
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    #[error("{}: cannot write: {}", .0.path.display(), .0.source)]
    Write(#[from] crate::fsio::WriteError),
}

/// The map's size in pixels.
pub const MAP_SIZE: (u32, u32) = (1400, 650);
/// The timeline's size in pixels.
pub const TIMELINE_SIZE: (u32, u32) = (1200, 900);

/// A number as the page prints it: four significant digits (no exponent), `-` for none.
pub fn shown(value: Option<f64>) -> String {
    match value {
        None => "-".into(),
        Some(v) if !v.is_finite() => format!("{v}"),
        Some(v) if v == 0.0 => "0".into(),
        Some(v) => {
            let decimals = (3 - v.abs().log10().floor() as i32).clamp(0, 8) as usize;
            format!("{v:.decimals$}")
        }
    }
}

fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;").replace('"', "&quot;")
}

fn verdict_cell(v: Option<Verdict>) -> String {
    match v {
        None => "<td class=\"verdict\">-</td>".into(),
        Some(v) => format!("<td class=\"verdict {}\">{}</td>", format!("{v:?}").to_lowercase(), v.words()),
    }
}

const STYLE: &str = "body{font-family:sans-serif;margin:2em;max-width:1400px;color:#222}\
table{border-collapse:collapse;margin:0.5em 0 1em}td,th{border:1px solid #ccc;padding:0.25em 0.6em;text-align:right}\
td:first-child,th:first-child{text-align:left}.within{background:#d8f0d8}.above{background:#fbe7b0}\
.farabove{background:#f6b8a8}.overlimit{background:#e05050;color:white}.note{background:#fff3cd;padding:0.5em 1em;border-left:4px solid #e0a000}\
.columns{display:flex;gap:2em;flex-wrap:wrap}.column{flex:1;min-width:380px}img,svg{max-width:100%;height:auto}";

fn table_rows(html: &mut String, section: &str, metrics: &[Metric]) {
    let _ = writeln!(html, "<table><tr><th>metric</th><th>value</th><th>reference</th><th>limit</th><th>unit</th><th>verdict</th></tr>");
    for m in metrics {
        let _ = writeln!(
            html,
            "<tr data-section=\"{}\" data-key=\"{}\"><td>{}</td><td class=\"value\">{}</td><td class=\"reference\">{}</td><td class=\"limit\">{}</td><td>{}</td>{}</tr>",
            escape(section),
            escape(&m.key),
            escape(&m.name),
            shown(m.value),
            shown(m.reference),
            shown(m.limit),
            escape(&m.unit),
            verdict_cell(m.verdict)
        );
    }
    html.push_str("</table>\n");
}

fn notes(html: &mut String, d: &Debrief) {
    if d.interrupted {
        let _ = writeln!(html, "<p class=\"note\">This run stopped early ({} frames, {} s simulated): the numbers are those of the frames it has.</p>", d.frames, shown(Some(d.simulated_s)));
    }
    for f in &d.integrity_failures {
        let _ = writeln!(html, "<p class=\"note\">Integrity check failed: {}. The numbers after that frame describe a simulation that lost the tissue's integrity.</p>", escape(f));
    }
}

fn sentences(html: &mut String, list: &[String]) {
    if list.is_empty() {
        return;
    }
    html.push_str("<ul>\n");
    for s in list {
        let _ = writeln!(html, "<li>{}</li>", escape(s));
    }
    html.push_str("</ul>\n");
}

/// One run's sections: notes, a table and sentences per blade, the pair, the scene, injuries.
fn run_sections(html: &mut String, d: &Debrief) {
    notes(html, d);
    for b in &d.blades {
        let _ = writeln!(html, "<h3>Blade: {}</h3>", escape(&b.name));
        table_rows(html, &format!("blade {}", b.name), &b.metrics);
        sentences(html, &b.sentences);
    }
    if let Some(p) = &d.pair {
        let _ = writeln!(html, "<h3>Both hands: {} and {}</h3>", escape(&p.blades[0]), escape(&p.blades[1]));
        table_rows(html, "pair", &p.metrics);
    }
    if !d.scene.is_empty() || !d.scene_sentences.is_empty() {
        html.push_str("<h3>Vessels, bands, ischemia</h3>\n");
        if !d.scene.is_empty() {
            table_rows(html, "scene", &d.scene);
        }
        sentences(html, &d.scene_sentences);
    }
    if !d.injuries.is_empty() {
        html.push_str("<h3>Tethers torn and cut</h3>\n<ul>\n");
        for i in &d.injuries {
            let _ = writeln!(html, "<li>{} s: {} {}</li>", shown(Some(i.time_s)), escape(&i.tether), escape(&i.kind));
        }
        html.push_str("</ul>\n");
    }
}

fn map_section(html: &mut String, run: &RunData) -> Result<(), DebriefPageError> {
    match &run.dose {
        Err(why) => {
            let _ = writeln!(html, "<p class=\"note\">No pressure map: {}.</p>", escape(why));
        }
        Ok(vertices) => {
            let png = png_bytes(MAP_SIZE, |root| draw_map(root, vertices)).map_err(|m| DebriefPageError::File { path: run.dir.clone(), message: format!("drawing the pressure map: {m}") })?;
            let _ = writeln!(
                html,
                "<img alt=\"pressure-time dose on the brain surface: top view and a close-up of the pressed region\" src=\"data:image/png;base64,{}\">",
                base64::engine::general_purpose::STANDARD.encode(png)
            );
        }
    }
    Ok(())
}

const SOURCES: &str = "<h2>Where the limits come from</h2><ul>\
<li>20 mmHg: retractor pressure that did not cause damage when held 15 minutes in the rat (Rosenørn and Diemer 1985, J Neurosurg 63:608-11, PMID 4032025, doi:10.3171/jns.1985.63.4.0608).</li>\
<li>Instrument tip path length and forces as simulator metrics: Azarnoush et al. 2015 (NeuroTouch tier 2 metrics, doi:10.1007/s11548-014-1091-z); the bimanual forces ratio: NeuroTouch metrics extraction (Surg Innov 2015, doi:10.1177/1553350615579729); feedback against an expert benchmark: the Virtual Operative Assistant (Mirchi et al. 2020, PLoS One, doi:10.1371/journal.pone.0229596).</li>\
<li>A vessel's warning stretch is the scene's. The reference bands (within: at most 1.25x the reference; above: at most 2x; far above: more) and the floors where the reference is about 0 are chosen, not taken from a study.</li></ul>";

fn timeline(html: &mut String, dirs: &[PathBuf]) {
    match crate::study::runs_plot::read_runs(dirs).and_then(|runs| crate::study::runs_plot::runs_svg(&runs, TIMELINE_SIZE)) {
        Ok(svg) => {
            html.push_str("<h2>Timeline</h2>\n<p>Force and mean contact pressure per blade against time, the 20 mmHg line, the tethers torn and cut.</p>\n");
            // The SVG document's own XML declaration, if any, cannot stand inside HTML.
            let start = svg.find("<svg").unwrap_or(0);
            html.push_str(&svg[start..]);
            html.push('\n');
        }
        Err(e) => {
            let _ = writeln!(html, "<p class=\"note\">No timeline: {}.</p>", escape(&e.to_string()));
        }
    }
}

fn head(html: &mut String, title: &str) {
    let _ = writeln!(html, "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>{}</title><style>{STYLE}</style></head><body>", escape(title));
}

/// The JSON path beside `html` (same stem, `.json`).
pub fn json_path(html: &Path) -> PathBuf {
    html.with_extension("json")
}

/// Writes the page for one run (`runs.len() == 1`) or several side by side, and the JSON beside it; returns the
/// JSON's path.
pub fn write_page(runs: &[RunData], debriefs: &[Debrief], out: &Path) -> Result<PathBuf, DebriefPageError> {
    let mut html = String::new();
    let scene = debriefs.first().and_then(|d| d.scenario.clone()).unwrap_or_else(|| "a fissure run".into());
    if let ([run], [d]) = (runs, debriefs) {
        head(&mut html, &format!("Debrief: {scene}"));
        let _ = writeln!(html, "<h1>Debrief: {}</h1>\n<p>Run folder <code>{}</code>", escape(&scene), escape(&d.run));
        if let Some(r) = &d.reference {
            let _ = write!(html, "; reference <code>{}</code> (each value against the reference's)", escape(r));
        }
        let _ = writeln!(html, "; {} frames, {} s.</p>", d.frames, shown(Some(d.simulated_s)));
        run_sections(&mut html, d);
        timeline(&mut html, std::slice::from_ref(&run.dir));
        html.push_str("<h2>Where pressure was applied</h2>\n");
        map_section(&mut html, run)?;
    } else {
        head(&mut html, &format!("Debrief: {scene}, {} runs", runs.len()));
        let _ = writeln!(html, "<h1>Debrief: {}, {} runs</h1>", escape(&scene), runs.len());
        trend_table(&mut html, debriefs);
        html.push_str("<div class=\"columns\">\n");
        for (run, d) in runs.iter().zip(debriefs) {
            let _ = writeln!(html, "<div class=\"column\"><h2><code>{}</code></h2>", escape(&d.run));
            run_sections(&mut html, d);
            map_section(&mut html, run)?;
            html.push_str("</div>\n");
        }
        html.push_str("</div>\n");
        timeline(&mut html, &runs.iter().map(|r| r.dir.clone()).collect::<Vec<_>>());
    }
    html.push_str(SOURCES);
    html.push_str("\n</body></html>\n");
    let json = if let [d] = debriefs { serde_json::to_string_pretty(d) } else { serde_json::to_string_pretty(debriefs) };
    let json = json.map_err(|e| DebriefPageError::File { path: json_path(out), message: e.to_string() })?;
    crate::fsio::write_atomic(out, html.as_bytes())?;
    crate::fsio::write_atomic(&json_path(out), (json + "\n").as_bytes())?;
    Ok(json_path(out))
}

/// Several runs: each metric a row, a column a run, and its trend from the first run to the last.
fn trend_table(html: &mut String, debriefs: &[Debrief]) {
    html.push_str("<h2>Trend, first run to last</h2>\n<table><tr><th>metric</th>");
    for (k, _) in debriefs.iter().enumerate() {
        let _ = write!(html, "<th>run {}</th>", k + 1);
    }
    html.push_str("<th>trend</th></tr>\n");
    let Some(first) = debriefs.first() else { return };
    for (section, m) in first.all_metrics() {
        let _ = write!(html, "<tr><td>{} ({}){}</td>", escape(&m.name), escape(&section), if m.unit.is_empty() { String::new() } else { format!(", {}", escape(&m.unit)) });
        let values: Vec<Option<f64>> = debriefs.iter().map(|d| d.all_metrics().into_iter().find(|(s, x)| *s == section && x.key == m.key).and_then(|(_, x)| x.value)).collect();
        for v in &values {
            let _ = write!(html, "<td>{}</td>", shown(*v));
        }
        let trend = match (values.first().copied().flatten(), values.last().copied().flatten()) {
            (Some(a), Some(b)) if a != 0.0 => format!("{:+.0} %", 100.0 * (b - a) / a.abs()),
            (Some(a), Some(b)) if a == b => "no change".into(),
            (Some(_), Some(b)) => format!("from 0 to {}", shown(Some(b))),
            _ => "-".into(),
        };
        let _ = writeln!(html, "<td>{trend}</td></tr>");
    }
    html.push_str("</table>\n");
}

/// Yellow (little) to dark red (most).
fn dose_color(fraction: f64) -> RGBColor {
    const STOPS: [(u8, u8, u8); 5] = [(255, 255, 178), (254, 204, 92), (253, 141, 60), (227, 26, 28), (128, 0, 38)];
    let x = fraction.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
    let k = (x.floor() as usize).min(STOPS.len() - 2);
    let t = x - k as f64;
    let mix = |a: u8, b: u8| (a as f64 + (b as f64 - a as f64) * t).round() as u8;
    let (a, b) = (STOPS[k], STOPS[k + 1]);
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

/// One projection of the surface: the two axes drawn (0 x, 1 y, 2 z), the axis looked along (drawn from its low end
/// up, so the side at its high end shows), the area shown and the slab of depth kept.
struct MapView {
    title: String,
    axes: [usize; 2],
    depth: usize,
    /// Centre and size of the area shown, mm, on the two axes.
    centre: [f64; 2],
    size: [f64; 2],
    /// Only vertices whose depth lies in this range (a close-up cuts away what lies over the pressed patch).
    slab: (f64, f64),
    /// A rectangle to outline (the close-up's area, on the overview), on the two axes.
    outline: Option<([f64; 2], [f64; 2])>,
}

const AXIS: [&str; 3] = ["x", "y", "z"];

/// The axis-aligned box of `points` on axis `k`.
fn span_of<'a>(points: impl Iterator<Item = &'a DoseVertex>, k: usize) -> (f64, f64) {
    points.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| (lo.min(v.position_mm[k]), hi.max(v.position_mm[k])))
}

/// The views of the map: the whole surface from the top, and, when anything was pressed, a close-up of the pressed
/// patch seen along the axis in which it is thinnest (a fissure's wall, seen face on), the surface above and below
/// it more than 3 mm away cut off, the area 10 mm or a third of its size larger than the patch on each side.
fn map_views(vertices: &[&DoseVertex]) -> Option<(MapView, Option<MapView>)> {
    let whole = [0, 1, 2].map(|k| span_of(vertices.iter().copied(), k));
    if !whole.iter().all(|(lo, hi)| lo.is_finite() && hi.is_finite()) {
        return None;
    }
    let pressed: Vec<&DoseVertex> = vertices.iter().copied().filter(|v| v.pressure_time_mmhg_s > 0.0).collect();
    let box_of = |k: usize| span_of(pressed.iter().copied(), k);
    let close = (!pressed.is_empty()).then(|| {
        let spans = [0, 1, 2].map(box_of);
        let depth = (0..3).min_by(|&a, &b| (spans[a].1 - spans[a].0).total_cmp(&(spans[b].1 - spans[b].0))).unwrap_or(2);
        let axes = match depth {
            0 => [1, 2],
            1 => [0, 2],
            _ => [0, 1],
        };
        let pad = |(lo, hi): (f64, f64)| (10.0_f64).max((hi - lo) / 3.0);
        let area = axes.map(|k| {
            let (lo, hi) = spans[k];
            let p = pad(spans[k]);
            (lo - p, hi + p)
        });
        let (d0, d1) = spans[depth];
        MapView {
            title: format!("Close-up, looking along {} (surface more than 3 mm off the pressed patch cut away)", AXIS[depth]),
            axes,
            depth,
            centre: area.map(|(lo, hi)| (lo + hi) / 2.0),
            size: area.map(|(lo, hi)| hi - lo),
            slab: (d0 - 3.0, d1 + 3.0),
            outline: None,
        }
    });
    let outline = (!pressed.is_empty()).then(|| {
        let (x, y) = (box_of(0), box_of(1));
        ([x.0 - 5.0, y.0 - 5.0], [x.1 + 5.0, y.1 + 5.0])
    });
    let overview = MapView {
        title: "The whole surface from the top (looking down z)".into(),
        axes: [0, 1],
        depth: 2,
        centre: [(whole[0].0 + whole[0].1) / 2.0, (whole[1].0 + whole[1].1) / 2.0],
        size: [(whole[0].1 - whole[0].0).max(1.0) * 1.05, (whole[1].1 - whole[1].0).max(1.0) * 1.05],
        slab: (f64::NEG_INFINITY, f64::INFINITY),
        outline,
    };
    Some((overview, close))
}

/// Draws one view into `area`: each vertex a dot coloured by its dose against `max` (grey untouched), drawn from the
/// low end of the depth axis up, equal scales on both axes.
fn draw_view(area: &DrawingArea<BitMapBackend<'_>, Shift>, view: &MapView, vertices: &[&DoseVertex], max: f64) -> Res {
    let body = area.titled(&view.title, (FONT, 16)).map_err(err)?;
    let (mw, mh) = body.dim_in_pixel();
    let aspect = (mw.saturating_sub(80)) as f64 / (mh.saturating_sub(60)).max(1) as f64;
    let [mut sx, mut sy] = view.size;
    if sx / sy < aspect { sx = sy * aspect } else { sy = sx / aspect }
    let [cx, cy] = view.centre;
    let mut chart = ChartBuilder::on(&body)
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(cx - sx / 2.0..cx + sx / 2.0, cy - sy / 2.0..cy + sy / 2.0)
        .map_err(err)?;
    let [a, b] = view.axes;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(format!("{} (mm)", AXIS[a]))
        .y_desc(format!("{} (mm)", AXIS[b]))
        .label_style((FONT, 14))
        .draw()
        .map_err(err)?;
    let inside = |v: &&&DoseVertex| {
        let (p, d) = ((v.position_mm[a], v.position_mm[b]), v.position_mm[view.depth]);
        d >= view.slab.0 && d <= view.slab.1 && (p.0 - cx).abs() <= sx / 2.0 && (p.1 - cy).abs() <= sy / 2.0
    };
    let mut order: Vec<&&DoseVertex> = vertices.iter().filter(inside).collect();
    order.sort_by(|p, q| p.position_mm[view.depth].total_cmp(&q.position_mm[view.depth]));
    let radius = if view.slab.0.is_finite() { (3, 4) } else { (2, 3) };
    chart
        .draw_series(order.iter().map(|v| {
            let d = v.pressure_time_mmhg_s;
            let color = if d > 0.0 && max > 0.0 { dose_color((d / max).min(1.0)) } else { RGBColor(215, 215, 215) };
            Circle::new((v.position_mm[a], v.position_mm[b]), if d > 0.0 { radius.1 } else { radius.0 }, color.filled())
        }))
        .map_err(err)?;
    if let Some((lo, hi)) = view.outline {
        chart.draw_series(std::iter::once(Rectangle::new([(lo[0], lo[1]), (hi[0], hi[1])], BLACK.stroke_width(2)))).map_err(err)?;
    }
    Ok(())
}

/// The map: the whole surface from the top with the pressed region outlined, and a close-up of that region
/// ([`map_views`]), each surface vertex coloured by its pressure-time dose; one colour bar with its unit.
fn draw_map(root: &DrawingArea<BitMapBackend<'_>, Shift>, vertices: &[DoseVertex]) -> Res {
    root.fill(&WHITE).map_err(err)?;
    let (w, _) = root.dim_in_pixel();
    let body = root.titled("Pressure-time dose on the brain surface", (FONT, 22)).map_err(err)?;
    let (maps, bar) = body.split_horizontally(w.saturating_sub(150));
    let finite: Vec<&DoseVertex> = vertices.iter().filter(|v| v.position_mm.iter().all(|c| c.is_finite())).collect();
    let Some((overview, close)) = map_views(&finite) else {
        return Err("no vertex with a finite position".into());
    };
    // The colour bar's top: the 99th percentile of the pressed vertices' doses (one vertex under a blade's edge
    // must not wash out the patch), the doses above it drawn in its colour and the bar saying so.
    let mut pressed: Vec<f64> = finite.iter().map(|v| v.pressure_time_mmhg_s).filter(|d| d.is_finite() && *d > 0.0).collect();
    pressed.sort_by(f64::total_cmp);
    let largest = pressed.last().copied().unwrap_or(0.0);
    let max = pressed.get(((pressed.len() as f64 - 1.0) * 0.99).round().max(0.0) as usize).copied().unwrap_or(0.0);
    match &close {
        Some(close) => {
            let (mw, _) = maps.dim_in_pixel();
            let (left, right) = maps.split_horizontally(mw * 9 / 20);
            draw_view(&left, &overview, &finite, max)?;
            draw_view(&right, close, &finite, max)?;
        }
        None => draw_view(&maps, &overview, &finite, max)?,
    }
    // The colour bar.
    let (bw, bh) = bar.dim_in_pixel();
    let (top, bottom, left) = (40i32, bh as i32 - 80, 20i32);
    let steps = 100;
    for k in 0..steps {
        let f = k as f64 / steps as f64;
        let y_hi = bottom - ((bottom - top) as f64 * (f + 1.0 / steps as f64)) as i32;
        let y_lo = bottom - ((bottom - top) as f64 * f) as i32;
        bar.draw(&Rectangle::new([(left, y_hi), (left + 30, y_lo)], dose_color(f).filled())).map_err(err)?;
    }
    bar.draw(&Rectangle::new([(left, top), (left + 30, bottom)], BLACK)).map_err(err)?;
    let top_label = if largest > max { format!("{} +", shown(Some(max))) } else { shown(Some(max)) };
    for (f, label) in [(0.0, "0".to_string()), (0.5, shown(Some(max / 2.0))), (1.0, top_label)] {
        let y = bottom - ((bottom - top) as f64 * f) as i32;
        bar.draw(&Text::new(label, (left + 36, y - 7), (FONT, 14).into_font())).map_err(err)?;
    }
    bar.draw(&Text::new("mmHg s", (left, bottom + 16), (FONT, 15).into_font())).map_err(err)?;
    bar.draw(&Text::new("grey: untouched", (left.min(bw as i32 - 120).max(0), bottom + 36), (FONT, 13).into_font().color(&RGBColor(110, 110, 110)))).map_err(err)?;
    if largest > max {
        // The top is the 99th percentile: say what lies above it.
        let grey = (FONT, 13).into_font().color(&RGBColor(110, 110, 110));
        bar.draw(&Text::new(format!("largest {}", shown(Some(largest))), (left.min(bw as i32 - 120).max(0), bottom + 52), grey)).map_err(err)?;
    }
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_show_four_significant_digits() {
        assert_eq!(shown(Some(1234.4)), "1234");
        assert_eq!(shown(Some(1.23456)), "1.235");
        assert_eq!(shown(Some(0.0123456)), "0.01235");
        assert_eq!(shown(Some(0.0)), "0");
        assert_eq!(shown(None), "-");
    }

    #[test]
    fn the_colour_runs_from_yellow_to_dark_red() {
        assert_eq!(dose_color(0.0), RGBColor(255, 255, 178));
        assert_eq!(dose_color(1.0), RGBColor(128, 0, 38));
    }
}
