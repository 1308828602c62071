//! Replay runs drawn against time (`fissure plot`): what a trainee looks at
//! after a training run in the window, and what an engineer compares settings with.
//!
//! In: run directories as `fissure replay` writes them: `metrics.csv` (a row a
//! frame; each blade's columns are found by name, `NAME_force_n`,
//! `NAME_mean_pressure_mmhg` and `NAME_contact_vertices`, beside `time_s`,
//! whatever the other columns and their order) and, when there is one,
//! `summary.json` (its scenario name and its `interrupted` flag go under the
//! run's name in the legend; its `injuries`, the tethers torn and cut, are
//! marked on the time axis of every panel). Out: one PNG, or an SVG when the output's name
//! ends in `.svg`, with three panels stacked on one time axis: the force on
//! each blade (N), its mean contact pressure (mmHg) with the
//! [`RETRACTION_DANGER_MMHG`] line drawn and labelled, and its contact vertices;
//! a colour a run, a line style a blade, a legend beside each panel; and each
//! later run's force against the first's ([`force_against`]).
//! Stays true: a value that is not finite (NaN) is left out and breaks its
//! line, never drawn as 0; the legends stand beside the panels, never over the
//! data; a directory or file that cannot be read, or a row that does not parse,
//! is an error naming the file (and the line), never a panic or a half-drawn
//! plot; the plot is written whole or not at all
//! ([`crate::fsio::write_atomic`]).
//!
//! Here rather than beside [`crate::sim::metrics`]: drawing belongs to the
//! study, whose [`super::plot`] owns the font and the in-memory PNG / SVG
//! rendering this reuses; the simulation core never draws.

use std::io::{BufRead, BufReader};
use std::ops::Range;
use std::path::{Path, PathBuf};

use plotters::coord::Shift;
use plotters::coord::types::RangedCoordf64;
use plotters::element::DashedPathElement;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};

use super::plot::{FONT, Res, err, png_bytes, svg_text};
use crate::fsio::{Cap, ReadError, WriteError};
use crate::sim::report::RETRACTION_DANGER_MMHG;

/// Pixel size of the plot unless asked otherwise.
pub const DEFAULT_SIZE: (u32, u32) = (1400, 1000);
/// The smallest size whose three panels, axes and legends still fit.
pub const MIN_SIZE: (u32, u32) = (480, 360);
/// The plot's title.
pub const TITLE: &str = "fissure: force, pressure and contact against time";

/// `metrics.csv`: some 600 bytes a row for two blades, so millions of frames.
const METRICS_CAP: Cap = Cap { bytes: 8 << 30, what: "a metrics file" };
/// `summary.json`: a few KiB.
const SUMMARY_CAP: Cap = Cap { bytes: 16 << 20, what: "a run summary" };

const TIME: &str = "time_s";
const FORCE: &str = "_force_n";
const PRESSURE: &str = "_mean_pressure_mmhg";
const CONTACT: &str = "_contact_vertices";

/// Why runs were not plotted; each names the file (and the line).
#[derive(Debug, thiserror::Error)]
pub enum RunPlotError {
    #[error("nothing to plot: name at least one run directory")]
    NoRuns,
    /// A directory, a file or the plot itself.
    #[error("{}: {message}", path.display())]
    File { path: PathBuf, message: String },
    /// A line of `metrics.csv` (1: the header).
    #[error("{}: line {line}: {message}", path.display())]
    Line { path: PathBuf, line: usize, message: String },
    /// Its message names the file and says why (so it is not repeated as a cause).
    #[error("{0}")]
    Read(ReadError),
    #[error("{}: cannot write the plot: {}", .0.path.display(), .0.source)]
    Write(WriteError),
}

impl From<ReadError> for RunPlotError {
    fn from(e: ReadError) -> Self {
        RunPlotError::Read(e)
    }
}

impl From<WriteError> for RunPlotError {
    fn from(e: WriteError) -> Self {
        RunPlotError::Write(e)
    }
}

impl RunPlotError {
    fn file(path: &Path, message: impl Into<String>) -> Self {
        RunPlotError::File { path: path.to_path_buf(), message: message.into() }
    }
}

/// One blade's series: a value a frame, as the file has it (NaN included).
#[derive(Debug, Clone, PartialEq)]
pub struct BladeSeries {
    /// The spatula's name (the prefix of its columns).
    pub name: String,
    pub force_n: Vec<f64>,
    pub pressure_mmhg: Vec<f64>,
    pub contact_vertices: Vec<f64>,
}

/// One run directory, read.
#[derive(Debug, Clone, PartialEq)]
pub struct RunSeries {
    pub dir: PathBuf,
    /// The run's name in the legend: the directory's name, or its path as
    /// given where two runs share a name.
    pub label: String,
    /// `summary.json`'s scenario name, when there is one.
    pub scenario: Option<String>,
    /// `summary.json` says the run stopped early.
    pub interrupted: bool,
    /// Simulated time a frame, s.
    pub time_s: Vec<f64>,
    /// In the file's (the scenario's) order.
    pub blades: Vec<BladeSeries>,
    /// `summary.json`'s injuries, in time order (none without the file).
    pub events: Vec<RunEvent>,
}

/// A tether torn or cut during a run (`summary.json`'s `injuries`).
#[derive(Debug, Clone, PartialEq)]
pub struct RunEvent {
    pub time_s: f64,
    pub kind: EventKind,
    /// The vessel's or band's name.
    pub tether: String,
}

/// What happened to a tether.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum EventKind {
    /// Broke under the blades: an injury.
    Torn,
    /// Cut on purpose (microscissors).
    Cut,
}

impl EventKind {
    fn word(self) -> &'static str {
        match self {
            EventKind::Torn => "torn",
            EventKind::Cut => "cut",
        }
    }
}

impl RunSeries {
    /// First and last finite time, s.
    pub fn time_span(&self) -> Option<(f64, f64)> {
        finite_span(self.time_s.iter().copied())
    }
}

/// One blade's force in a run against the same blade in another (the first
/// run named), as the study measures a run against its reference
/// ([`super::accuracy::force_error`]): at each of the first run's frames
/// inside the other's span, the other's force magnitude interpolated linearly
/// in time (so runs at another frame rate are compared at the same instants).
#[derive(Debug, Clone, PartialEq)]
pub struct ForceDifference {
    pub blade: String,
    /// RMS and largest |F - F_first| over the compared frames, % of the first run's peak force.
    pub rms_pct: f64,
    pub max_pct: f64,
    /// The first run's peak force on this blade, N.
    pub peak_n: f64,
    /// Frames of the first run compared (both values finite).
    pub frames: usize,
}

/// Each blade of `run` that `first` has too (by name), its force against
/// `first`'s ([`ForceDifference`]); a blade without a positive peak or without
/// a frame in common is left out.
pub fn force_against(first: &RunSeries, run: &RunSeries) -> Vec<ForceDifference> {
    // (time in ns, |F| as a vector) at the finite values: the study's force series.
    let series = |time: &[f64], force: &[f64]| -> Vec<(i64, crate::math::Vec3)> {
        time.iter()
            .zip(force)
            .filter(|(t, f)| t.is_finite() && f.is_finite())
            .map(|(&t, &f)| ((t * 1e9).round() as i64, crate::math::Vec3::new(f, 0.0, 0.0)))
            .collect()
    };
    let mut out = Vec::new();
    for a in &first.blades {
        let Some(b) = run.blades.iter().find(|b| b.name == a.name) else { continue };
        let reference = series(&first.time_s, &a.force_n);
        let peak = reference.iter().map(|(_, f)| f.norm()).fold(0.0, f64::max);
        let (rms, max, frames) = super::accuracy::force_error(&reference, &series(&run.time_s, &b.force_n));
        if frames > 0 && peak > 0.0 {
            out.push(ForceDifference { blade: a.name.clone(), rms_pct: 100.0 * rms / peak, max_pct: 100.0 * max / peak, peak_n: peak, frames });
        }
    }
    out
}

/// What the plot is written as, by the output's extension.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputFormat {
    Png,
    Svg,
}

impl OutputFormat {
    /// `.png` or `.svg` (any case); anything else is an error naming the file.
    pub fn of(path: &Path) -> Result<Self, RunPlotError> {
        match path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref() {
            Some("png") => Ok(OutputFormat::Png),
            Some("svg") => Ok(OutputFormat::Svg),
            _ => Err(RunPlotError::file(path, "the plot's name must end in .png or .svg")),
        }
    }
}

/// One blade's columns in the header.
#[derive(Debug, Clone, PartialEq)]
struct BladeColumns {
    name: String,
    force: usize,
    pressure: usize,
    contact: usize,
}

/// The time column and each blade's columns, found by name: a blade is the
/// prefix of a `NAME_mean_pressure_mmhg` column whose `NAME_force_n` and
/// `NAME_contact_vertices` are there too (names may hold underscores).
fn header_columns(header: &[&str]) -> Result<(usize, Vec<BladeColumns>), String> {
    let find = |name: &str| header.iter().position(|c| *c == name);
    let time = find(TIME).ok_or_else(|| format!("no `{TIME}` column in the header: not a fissure metrics.csv"))?;
    let mut blades = Vec::new();
    for (pressure, col) in header.iter().enumerate() {
        let Some(name) = col.strip_suffix(PRESSURE).filter(|n| !n.is_empty()) else { continue };
        let partner = |suffix: &str| find(&format!("{name}{suffix}")).ok_or_else(|| format!("`{col}` has no `{name}{suffix}` column beside it"));
        blades.push(BladeColumns { name: name.to_string(), force: partner(FORCE)?, pressure, contact: partner(CONTACT)? });
    }
    if blades.is_empty() {
        return Err(format!("no per-spatula columns (NAME{FORCE}, NAME{PRESSURE}, NAME{CONTACT}) in the header: not a fissure metrics.csv"));
    }
    Ok((time, blades))
}

/// Reads `metrics.csv`: the times and each blade's series.
fn read_metrics(path: &Path) -> Result<(Vec<f64>, Vec<BladeSeries>), RunPlotError> {
    let (file, _) = crate::fsio::open_regular(path, METRICS_CAP)?;
    let at = |line: usize, message: String| RunPlotError::Line { path: path.to_path_buf(), line, message };
    let mut lines = BufReader::new(file).lines();
    let header = match lines.next() {
        None => return Err(RunPlotError::file(path, "empty: no header and no frames")),
        Some(line) => line.map_err(|e| at(1, e.to_string()))?,
    };
    let names: Vec<&str> = header.split(',').map(str::trim).collect();
    let (time_col, columns) = header_columns(&names).map_err(|m| at(1, m))?;
    let mut time = Vec::new();
    let mut blades: Vec<BladeSeries> = columns
        .iter()
        .map(|c| BladeSeries { name: c.name.clone(), force_n: Vec::new(), pressure_mmhg: Vec::new(), contact_vertices: Vec::new() })
        .collect();
    for (k, line) in lines.enumerate() {
        let n = k + 2;
        let line = line.map_err(|e| at(n, e.to_string()))?;
        if line.trim().is_empty() {
            return Err(at(n, "an empty line among the frames".into()));
        }
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != names.len() {
            return Err(at(n, format!("{} fields, the header has {}", fields.len(), names.len())));
        }
        let value = |col: usize| fields[col].parse::<f64>().map_err(|_| at(n, format!("column `{}`: `{:.40}` is not a number", names[col], fields[col])));
        time.push(value(time_col)?);
        for (b, c) in blades.iter_mut().zip(&columns) {
            b.force_n.push(value(c.force)?);
            b.pressure_mmhg.push(value(c.pressure)?);
            b.contact_vertices.push(value(c.contact)?);
        }
    }
    if time.is_empty() {
        return Err(RunPlotError::file(path, "no frames: the header and no rows (the run stopped before its first frame)"));
    }
    if !time.iter().any(|t| t.is_finite()) {
        return Err(RunPlotError::file(path, format!("no frame has a finite `{TIME}`")));
    }
    Ok((time, blades))
}

/// What `summary.json` says of a run.
#[derive(Debug, Default)]
struct SummaryFacts {
    scenario: Option<String>,
    interrupted: bool,
    events: Vec<RunEvent>,
}

/// `summary.json`'s scenario name, `interrupted` flag and injuries; nothing without the file.
fn read_summary(dir: &Path) -> Result<SummaryFacts, RunPlotError> {
    let path = dir.join("summary.json");
    if std::fs::symlink_metadata(&path).is_err() {
        return Ok(SummaryFacts::default());
    }
    let text = crate::fsio::read_regular_text(&path, SUMMARY_CAP)?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(|e| RunPlotError::file(&path, format!("not a run summary: {e}")))?;
    let scenario = v.get("scenario").and_then(|s| s.as_str()).map(str::trim).filter(|s| !s.is_empty()).map(String::from);
    let interrupted = v.get("interrupted").and_then(serde_json::Value::as_bool).unwrap_or(false);
    let mut events = Vec::new();
    if let Some(list) = v.get("injuries") {
        let list = list.as_array().ok_or_else(|| RunPlotError::file(&path, "`injuries` is not a list"))?;
        for (k, e) in list.iter().enumerate() {
            let bad = |what: &str| RunPlotError::file(&path, format!("injuries[{k}]: {what}"));
            let time_s = e.get("time_s").and_then(serde_json::Value::as_f64).filter(|t| t.is_finite()).ok_or_else(|| bad("no finite `time_s`"))?;
            let kind = match e.get("kind").and_then(serde_json::Value::as_str) {
                Some("torn") => EventKind::Torn,
                Some("cut") => EventKind::Cut,
                other => return Err(bad(&format!("`kind` is {other:?}, not \"torn\" or \"cut\""))),
            };
            let tether = e.get("tether").and_then(serde_json::Value::as_str).unwrap_or("?").to_string();
            events.push(RunEvent { time_s, kind, tether });
        }
    }
    events.sort_by(|a, b| a.time_s.total_cmp(&b.time_s));
    Ok(SummaryFacts { scenario, interrupted, events })
}

/// The directory's own name (`out/run/` -> `run`; `.` -> the current folder's name).
fn dir_name(dir: &Path) -> String {
    let name = |p: &Path| p.file_name().map(|n| n.to_string_lossy().into_owned());
    name(dir).or_else(|| name(&dir.canonicalize().ok()?)).unwrap_or_else(|| dir.display().to_string())
}

/// Reads one run directory.
pub fn read_run(dir: &Path) -> Result<RunSeries, RunPlotError> {
    match std::fs::metadata(dir) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Err(RunPlotError::file(dir, "no such run directory")),
        Err(e) => return Err(RunPlotError::file(dir, e.to_string())),
        Ok(m) if !m.is_dir() => return Err(RunPlotError::file(dir, "not a directory: name a run directory (`fissure replay --out DIR` writes DIR/metrics.csv)")),
        Ok(_) => {}
    }
    let (time_s, blades) = read_metrics(&dir.join("metrics.csv"))?;
    let SummaryFacts { scenario, interrupted, events } = read_summary(dir)?;
    Ok(RunSeries { dir: dir.to_path_buf(), label: dir_name(dir), scenario, interrupted, time_s, blades, events })
}

/// Reads every run, in order; runs that share a directory name are named by
/// their paths instead (and numbered if those agree too).
pub fn read_runs(dirs: &[PathBuf]) -> Result<Vec<RunSeries>, RunPlotError> {
    let mut runs = dirs.iter().map(|d| read_run(d)).collect::<Result<Vec<_>, _>>()?;
    let names: Vec<String> = runs.iter().map(|r| r.label.clone()).collect();
    for r in runs.iter_mut() {
        if names.iter().filter(|n| **n == r.label).count() > 1 {
            r.label = r.dir.display().to_string();
        }
    }
    for k in 1..runs.len() {
        let same = runs[..k].iter().filter(|r| r.label == runs[k].label).count();
        if same > 0 {
            runs[k].label = format!("{} ({})", runs[k].label, same + 1);
        }
    }
    Ok(runs)
}

/// Reads `dirs` and writes their plot to `out` (`.png` or `.svg`) at `size`
/// pixels; returns the runs as read. The output's name and the size are
/// checked before any run is read.
pub fn plot_runs(dirs: &[PathBuf], out: &Path, size: (u32, u32)) -> Result<Vec<RunSeries>, RunPlotError> {
    OutputFormat::of(out)?;
    check_size(out, size)?;
    if dirs.is_empty() {
        return Err(RunPlotError::NoRuns);
    }
    let runs = read_runs(dirs)?;
    write_plot(&runs, out, size)?;
    Ok(runs)
}

fn check_size(out: &Path, size: (u32, u32)) -> Result<(), RunPlotError> {
    if size.0 < MIN_SIZE.0 || size.1 < MIN_SIZE.1 {
        return Err(RunPlotError::file(out, format!("{}x{} pixels is too small for three panels: at least {}x{}", size.0, size.1, MIN_SIZE.0, MIN_SIZE.1)));
    }
    Ok(())
}

/// Draws `runs` into `out` (`.png` or `.svg`, by its name), written whole.
pub fn write_plot(runs: &[RunSeries], out: &Path, size: (u32, u32)) -> Result<(), RunPlotError> {
    let format = OutputFormat::of(out)?;
    check_size(out, size)?;
    if runs.is_empty() {
        return Err(RunPlotError::NoRuns);
    }
    let bytes = match format {
        OutputFormat::Png => png_bytes(size, |root| draw_runs(root, runs)),
        OutputFormat::Svg => svg_text(size, |root| draw_runs(root, runs)).map(String::into_bytes),
    };
    let bytes = bytes.map_err(|m| RunPlotError::file(out, format!("drawing the plot: {m}")))?;
    crate::fsio::write_atomic(out, &bytes)?;
    Ok(())
}

/// The SVG text of the figure [`write_plot`] draws, for `runs` at `size` pixels (at least [`MIN_SIZE`]): for a
/// page that embeds it.
pub fn runs_svg(runs: &[RunSeries], size: (u32, u32)) -> Result<String, RunPlotError> {
    if runs.is_empty() {
        return Err(RunPlotError::NoRuns);
    }
    let size = (size.0.max(MIN_SIZE.0), size.1.max(MIN_SIZE.1));
    svg_text(size, |root| draw_runs(root, runs)).map_err(|m| RunPlotError::file(&runs[0].dir, format!("drawing the timeline: {m}")))
}

/// Smallest and largest finite value.
fn finite_span(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |span, v| Some(span.map_or((v, v), |(lo, hi): (f64, f64)| (lo.min(v), hi.max(v)))))
}

/// The finite points of a series, split where a time or a value is not
/// finite: a gap in the line, never a 0.
fn segments(time: &[f64], values: &[f64]) -> Vec<Vec<(f64, f64)>> {
    let (mut all, mut current) = (Vec::new(), Vec::new());
    for (&t, &v) in time.iter().zip(values) {
        if t.is_finite() && v.is_finite() {
            current.push((t, v));
        } else if !current.is_empty() {
            all.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        all.push(current);
    }
    all
}

/// A colour a run: Tableau 10 without its red, which the danger line keeps.
const RUN_COLORS: [RGBColor; 9] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
];
const DANGER: RGBColor = RGBColor(200, 0, 0);
const GREY: RGBColor = RGBColor(110, 110, 110);

fn run_color(run: usize) -> RGBColor {
    RUN_COLORS[run % RUN_COLORS.len()]
}

/// A line style a blade, as (dash, gap) in pixels at the default size: solid,
/// dashed, dotted, long-dashed, then again.
fn blade_dash(blade: usize) -> Option<(u32, u32)> {
    [None, Some((12, 7)), Some((2, 5)), Some((26, 7))][blade % 4]
}

/// Lengths in pixels at the default size, scaled to the plot's.
#[derive(Debug, Clone, Copy)]
struct Scale(f64);

impl Scale {
    fn of((w, h): (u32, u32)) -> Self {
        Scale((f64::from(w) / f64::from(DEFAULT_SIZE.0)).min(f64::from(h) / f64::from(DEFAULT_SIZE.1)).clamp(0.5, 4.0))
    }
    fn px(self, n: u32) -> u32 {
        ((f64::from(n) * self.0).round() as u32).max(1)
    }
    fn i(self, n: u32) -> i32 {
        self.px(n) as i32
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Panel {
    Force,
    Pressure,
    Contact,
}

impl Panel {
    const ALL: [Panel; 3] = [Panel::Force, Panel::Pressure, Panel::Contact];

    fn caption(self) -> String {
        match self {
            Panel::Force => "Force on each blade".into(),
            Panel::Pressure => format!("Mean contact pressure on each blade (retraction injury risk above {RETRACTION_DANGER_MMHG} mmHg)"),
            Panel::Contact => "Contact vertices per blade (the size of the contact patch)".into(),
        }
    }
    fn y_desc(self) -> &'static str {
        match self {
            Panel::Force => "force (N)",
            Panel::Pressure => "mean pressure (mmHg)",
            Panel::Contact => "contact vertices",
        }
    }
    fn values(self, b: &BladeSeries) -> &[f64] {
        match self {
            Panel::Force => &b.force_n,
            Panel::Pressure => &b.pressure_mmhg,
            Panel::Contact => &b.contact_vertices,
        }
    }
    /// The value axis: from 0 (or below, for negative values) to a little
    /// above the largest value; the pressure axis always shows the danger line
    /// and the contact axis at least 5 vertices (whole ticks).
    fn y_range(self, runs: &[RunSeries]) -> Range<f64> {
        let values = runs.iter().flat_map(|r| r.blades.iter().flat_map(move |b| self.values(b).iter().copied()));
        let (lo, hi) = finite_span(values.chain([0.0])).unwrap_or((0.0, 1.0));
        let floor = match self {
            Panel::Force => 0.0,
            // Room above the line for its label.
            Panel::Pressure => RETRACTION_DANGER_MMHG * 1.15,
            Panel::Contact => 5.0,
        };
        let hi = hi.max(floor);
        let hi = if hi > lo { hi } else { lo + 1.0 };
        let pad = (hi - lo) * 0.1;
        (if lo < 0.0 { lo - pad } else { lo })..hi + pad
    }
}

/// The time axis every panel shares: from 0 where the first frame is close
/// to it (a replay's first row is the end of its first frame).
fn time_range(runs: &[RunSeries]) -> Range<f64> {
    match finite_span(runs.iter().flat_map(|r| r.time_s.iter().copied())) {
        Some((t0, t1)) if t1 > t0 => (if t0 > 0.0 && t0 < 0.1 * (t1 - t0) { 0.0 } else { t0 })..t1,
        Some((t, _)) => t - 0.5..t + 0.5,
        None => 0.0..1.0,
    }
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// One segment of one blade's line (a lone point as a dot).
fn draw_segment<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, points: Vec<(f64, f64)>, blade: usize, color: RGBColor, s: Scale) -> Res {
    let style = color.stroke_width(s.px(2));
    let drawn = if points.len() == 1 {
        chart.draw_series(points.into_iter().map(|p| Circle::new(p, s.px(3), color.filled()))).map(|_| ())
    } else {
        match blade_dash(blade) {
            None => chart.draw_series(LineSeries::new(points, style)).map(|_| ()),
            Some((dash, gap)) => chart.draw_series(DashedLineSeries::new(points, s.px(dash), s.px(gap), style)).map(|_| ()),
        }
    };
    drawn.map_err(err)
}

/// One panel: axes, (for pressure) the danger zone and its line, every run's blades.
fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: Panel, runs: &[RunSeries], t: Range<f64>, s: Scale, bottom: bool) -> Res {
    let y = panel.y_range(runs);
    let mut chart = ChartBuilder::on(area)
        .caption(panel.caption(), (FONT, s.px(19)))
        .margin_top(s.px(4))
        .margin_left(s.px(10))
        .margin_right(s.px(18))
        .margin_bottom(s.px(4))
        .x_label_area_size(s.px(if bottom { 58 } else { 32 }))
        .y_label_area_size(s.px(88))
        .build_cartesian_2d(t.clone(), y.clone())
        .map_err(err)?;
    let whole = |v: &f64| if (v - v.round()).abs() < 1e-9 { format!("{v:.0}") } else { String::new() };
    let mut mesh = chart.configure_mesh();
    mesh.x_labels(12)
        .y_labels(6)
        .y_desc(panel.y_desc())
        .axis_desc_style((FONT, s.px(17)))
        .label_style((FONT, s.px(14)))
        .light_line_style(TRANSPARENT);
    if bottom {
        mesh.x_desc("time (s)");
    }
    if panel == Panel::Contact {
        mesh.y_label_formatter(&whole);
    }
    mesh.draw().map_err(err)?;
    if panel == Panel::Pressure {
        let line = RETRACTION_DANGER_MMHG;
        chart.draw_series(std::iter::once(Rectangle::new([(t.start, line), (t.end, y.end)], DANGER.mix(0.06).filled()))).map_err(err)?;
        chart.draw_series(DashedLineSeries::new([(t.start, line), (t.end, line)], s.px(16), s.px(6), DANGER.stroke_width(s.px(2)))).map_err(err)?;
        let label = format!("{line} mmHg: retraction-injury line");
        let style = (FONT, s.px(15)).into_font().color(&DANGER).pos(Pos::new(HPos::Left, VPos::Bottom));
        let at = (t.start + (t.end - t.start) * 0.01, line + (y.end - y.start) * 0.015);
        chart.draw_series(std::iter::once(Text::new(label, at, style))).map_err(err)?;
    }
    draw_events(&mut chart, panel, runs, &t, &y, s)?;
    for (r, run) in runs.iter().enumerate() {
        for (b, blade) in run.blades.iter().enumerate() {
            for points in segments(&run.time_s, panel.values(blade)) {
                draw_segment(&mut chart, points, b, run_color(r), s)?;
            }
        }
    }
    Ok(())
}

/// An event's vertical line: torn solid and heavy, cut dotted and light.
fn event_line<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, kind: EventKind, x: f64, y: &Range<f64>, color: RGBColor, s: Scale) -> Res {
    let points = [(x, y.start), (x, y.end)];
    match kind {
        EventKind::Torn => chart.draw_series(LineSeries::new(points, color.stroke_width(s.px(2)))).map(|_| ()),
        EventKind::Cut => chart.draw_series(DashedLineSeries::new(points, s.px(3), s.px(4), color.mix(0.8).stroke_width(s.px(1)))).map(|_| ()),
    }
    .map_err(err)
}

/// Events of one kind close in time, drawn under one label: (first time, count, the first's tether).
fn event_groups(events: &[RunEvent], kind: EventKind, close_s: f64) -> Vec<(f64, usize, &str)> {
    let mut out: Vec<(f64, usize, &str)> = Vec::new();
    let mut last = f64::NEG_INFINITY;
    for e in events.iter().filter(|e| e.kind == kind) {
        match out.last_mut() {
            Some(group) if e.time_s - last <= close_s => group.1 += 1,
            _ => out.push((e.time_s, 1, &e.tether)),
        }
        last = e.time_s;
    }
    out
}

/// Every run's torn and cut tethers as vertical lines in the run's colour;
/// on the force panel, a label over each group ("torn: NAME", or "8 cut"),
/// a row a run and kind so that runs do not write over each other.
fn draw_events<DB: DrawingBackend>(chart: &mut Chart<'_, DB>, panel: Panel, runs: &[RunSeries], t: &Range<f64>, y: &Range<f64>, s: Scale) -> Res {
    let close_s = 0.04 * (t.end - t.start);
    let mut row = 0;
    for (r, run) in runs.iter().enumerate() {
        for kind in [EventKind::Torn, EventKind::Cut] {
            let groups = event_groups(&run.events, kind, close_s);
            if groups.is_empty() {
                continue;
            }
            for e in run.events.iter().filter(|e| e.kind == kind) {
                event_line(chart, kind, e.time_s, y, run_color(r), s)?;
            }
            if panel != Panel::Force {
                continue;
            }
            row += 1;
            let at_y = y.end - (y.end - y.start) * 0.075 * row as f64;
            for (time, n, tether) in groups {
                let text = if n == 1 { format!("{}: {tether}", kind.word()) } else { format!("{n} {}", kind.word()) };
                let right = time > t.start + 0.7 * (t.end - t.start);
                let pos = Pos::new(if right { HPos::Right } else { HPos::Left }, VPos::Center);
                let color = if kind == EventKind::Torn { DANGER } else { run_color(r) };
                let style = (FONT, s.px(14), if kind == EventKind::Torn { FontStyle::Bold } else { FontStyle::Normal }).into_font().color(&color).pos(pos);
                let nudge = (t.end - t.start) * 0.006 * if right { -1.0 } else { 1.0 };
                chart.draw_series(std::iter::once(Text::new(text, (time + nudge, at_y), style))).map_err(err)?;
            }
        }
    }
    Ok(())
}

/// `text`, cut with "..." to fit `width` pixels in `style`.
fn fit<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, text: &str, style: &TextStyle, width: u32) -> String {
    let fits = |t: &str| area.estimate_text_size(t, style).map_or(true, |(w, _)| w <= width);
    if fits(text) {
        return text.to_string();
    }
    let chars: Vec<char> = text.chars().collect();
    (1..chars.len()).rev().map(|n| format!("{}...", chars[..n].iter().collect::<String>())).find(|t| fits(t)).unwrap_or_else(|| "...".into())
}

/// A row of a legend.
enum Row<'a> {
    Run { label: &'a str, color: RGBColor },
    Note(String),
    Blade { name: &'a str, blade: usize, color: RGBColor },
    Danger,
    Event(EventKind),
    More(usize),
}

/// The rows for `runs` (and the danger line on the pressure panel), as many
/// runs as fit in `rows` rows.
fn legend_rows(runs: &[RunSeries], panel: Panel, rows: usize) -> Vec<Row<'_>> {
    let mut out = Vec::new();
    let kinds: Vec<EventKind> = [EventKind::Torn, EventKind::Cut]
        .into_iter()
        .filter(|k| panel == Panel::Force && runs.iter().any(|r| r.events.iter().any(|e| e.kind == *k)))
        .collect();
    let reserved = usize::from(panel == Panel::Pressure) + kinds.len();
    for (r, run) in runs.iter().enumerate() {
        let note = match (&run.scenario, run.interrupted) {
            (Some(s), true) => Some(format!("{s} (interrupted)")),
            (Some(s), false) => Some(s.clone()),
            (None, true) => Some("interrupted".to_string()),
            (None, false) => None,
        };
        let own = 1 + usize::from(note.is_some()) + run.blades.len();
        let more = usize::from(r + 1 < runs.len());
        if out.len() + own + reserved + more > rows && r > 0 {
            out.push(Row::More(runs.len() - r));
            break;
        }
        out.push(Row::Run { label: &run.label, color: run_color(r) });
        out.extend(note.map(Row::Note));
        out.extend(run.blades.iter().enumerate().map(|(b, blade)| Row::Blade { name: &blade.name, blade: b, color: run_color(r) }));
    }
    if panel == Panel::Pressure {
        out.push(Row::Danger);
    }
    out.extend(kinds.into_iter().map(Row::Event));
    out
}

/// A legend in the column beside a panel: runs (a swatch of their colour),
/// their scenario, their blades (a sample of their line).
fn draw_legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, panel: Panel, runs: &[RunSeries], s: Scale) -> Res {
    let (w, h) = area.dim_in_pixel();
    let (row_h, top, x0) = (s.i(22), s.i(34), s.i(4));
    let rows = legend_rows(runs, panel, ((h as i32 - top - s.i(12)) / row_h).max(1) as usize);
    let box_bottom = top + row_h * rows.len() as i32 + s.i(8);
    area.draw(&Rectangle::new([(x0, top), (w as i32 - s.i(6), box_bottom)], WHITE.filled())).map_err(err)?;
    area.draw(&Rectangle::new([(x0, top), (w as i32 - s.i(6), box_bottom)], RGBColor(160, 160, 160))).map_err(err)?;
    let (indent, sample) = (x0 + s.i(10), s.i(46));
    let left = |x: i32| (w as i32 - x - s.i(12)).max(1) as u32;
    let anchor = Pos::new(HPos::Left, VPos::Center);
    for (k, row) in rows.iter().enumerate() {
        let y = top + s.i(4) + row_h * k as i32 + row_h / 2;
        let (x, text, style) = match row {
            Row::Run { label, color } => {
                let swatch = s.i(14);
                area.draw(&Rectangle::new([(indent, y - swatch / 2), (indent + swatch, y + swatch / 2)], color.filled())).map_err(err)?;
                let x = indent + swatch + s.i(8);
                (x, format!("run: {label}"), (FONT, s.px(15), FontStyle::Bold).into_font().color(&BLACK))
            }
            Row::Note(note) => (indent + s.i(22), note.clone(), (FONT, s.px(13)).into_font().color(&GREY)),
            Row::Blade { name, blade, color } => {
                let (a, b) = (indent + s.i(14), indent + s.i(14) + sample);
                let style = color.stroke_width(s.px(2));
                match blade_dash(*blade) {
                    None => area.draw(&PathElement::new(vec![(a, y), (b, y)], style)),
                    Some((dash, gap)) => area.draw(&DashedPathElement::new(vec![(a, y), (b, y)], s.px(dash), s.px(gap), style)),
                }
                .map_err(err)?;
                (b + s.i(8), format!("blade: {name}"), (FONT, s.px(15)).into_font().color(&BLACK))
            }
            Row::Danger => {
                let (a, b) = (indent, indent + s.i(14) + sample);
                area.draw(&DashedPathElement::new(vec![(a, y), (b, y)], s.px(16), s.px(6), DANGER.stroke_width(s.px(2)))).map_err(err)?;
                (b + s.i(8), format!("{RETRACTION_DANGER_MMHG} mmHg injury line"), (FONT, s.px(15)).into_font().color(&DANGER))
            }
            Row::Event(kind) => {
                let x = indent + s.i(14) + sample / 2;
                let color = if *kind == EventKind::Torn { DANGER } else { GREY };
                let points = vec![(x, y - s.i(8)), (x, y + s.i(8))];
                match kind {
                    EventKind::Torn => area.draw(&PathElement::new(points, color.stroke_width(s.px(2)))),
                    EventKind::Cut => area.draw(&DashedPathElement::new(points, s.px(3), s.px(4), color.stroke_width(s.px(1)))),
                }
                .map_err(err)?;
                let what = match kind {
                    EventKind::Torn => "tether torn (run's colour)",
                    EventKind::Cut => "band cut (run's colour)",
                };
                (indent + s.i(14) + sample + s.i(8), what.to_string(), (FONT, s.px(15)).into_font().color(&color))
            }
            Row::More(n) => (indent, format!("... and {n} more run{}", if *n == 1 { "" } else { "s" }), (FONT, s.px(14)).into_font().color(&GREY)),
        };
        let style = style.pos(anchor);
        let text = fit(area, &text, &style, left(x));
        area.draw(&Text::new(text, (x, y), style)).map_err(err)?;
    }
    Ok(())
}

/// The whole figure: the title, then three panels on one time axis, each with
/// its legend in a column to its right.
fn draw_runs<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>, runs: &[RunSeries]) -> Res {
    let (w, _) = root.dim_in_pixel();
    let s = Scale::of(root.dim_in_pixel());
    root.fill(&WHITE).map_err(err)?;
    let body = root.titled(TITLE, (FONT, s.px(28))).map_err(err)?;
    let (plots, legends) = body.split_horizontally(w - s.px(300).min(w / 3));
    // The bottom panel is taller by its time axis' label, so the three plotting areas match.
    let h = plots.dim_in_pixel().1;
    let upper = (h.saturating_sub(s.px(26)) / 3).max(1);
    let split = |area: &DrawingArea<DB, Shift>| {
        let (a, rest) = area.split_vertically(upper);
        let (b, c) = rest.split_vertically(upper);
        [a, b, c]
    };
    let t = time_range(runs);
    for ((k, panel), (area, legend)) in Panel::ALL.into_iter().enumerate().zip(split(&plots).iter().zip(&split(&legends))) {
        draw_panel(area, panel, runs, t.clone(), s, k == 2)?;
        draw_legend(legend, panel, runs, s)?;
    }
    root.present().map_err(err)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn blades_are_found_by_name_whatever_their_underscores() {
        let header = ["frame", "time_s", "frame_ms", "left_blade_force_n", "left_blade_contact_vertices", "left_blade_mean_pressure_mmhg", "b_force_n", "b_contact_vertices", "b_mean_pressure_mmhg", "constrained_vertices"];
        let (time, blades) = header_columns(&header).expect("a metrics header");
        assert_eq!(time, 1);
        assert_eq!(blades, vec![
            BladeColumns { name: "left_blade".into(), force: 3, pressure: 5, contact: 4 },
            BladeColumns { name: "b".into(), force: 6, pressure: 8, contact: 7 },
        ]);
        let e = header_columns(&["time_s", "a_mean_pressure_mmhg", "a_force_n"]).expect_err("no contact column");
        assert!(e.contains("a_contact_vertices"), "{e}");
        assert!(header_columns(&["frame", "time_s", "x"]).expect_err("no blades").contains("per-spatula"));
    }

    #[test]
    fn a_value_that_is_not_finite_breaks_the_line() {
        let t = [0.0, 0.1, 0.2, 0.3, f64::NAN, 0.5];
        let v = [1.0, f64::NAN, 3.0, 4.0, 5.0, f64::INFINITY];
        assert_eq!(segments(&t, &v), vec![vec![(0.0, 1.0)], vec![(0.2, 3.0), (0.3, 4.0)]]);
    }

    #[test]
    fn the_pressure_axis_always_shows_the_danger_line() {
        let run = |p: f64| RunSeries {
            dir: "r".into(),
            label: "r".into(),
            scenario: None,
            interrupted: false,
            events: Vec::new(),
            time_s: vec![0.0, 1.0],
            blades: vec![BladeSeries { name: "a".into(), force_n: vec![0.0, 0.2], pressure_mmhg: vec![0.0, p], contact_vertices: vec![0.0, 3.0] }],
        };
        assert!(Panel::Pressure.y_range(&[run(2.0)]).end > RETRACTION_DANGER_MMHG);
        assert!(Panel::Pressure.y_range(&[run(50.0)]).end > 50.0);
        assert!(Panel::Contact.y_range(&[run(2.0)]).end >= 5.0);
    }

    #[test]
    fn a_run_is_compared_with_the_first_at_the_first_runs_instants() {
        let run = |t: Vec<f64>, f: Vec<f64>| RunSeries {
            dir: "r".into(),
            label: "r".into(),
            scenario: None,
            interrupted: false,
            events: Vec::new(),
            blades: vec![BladeSeries { name: "a".into(), force_n: f.clone(), pressure_mmhg: vec![0.0; f.len()], contact_vertices: vec![0.0; f.len()] }],
            time_s: t,
        };
        // The first: 0, 1, 2 N at 0, 1, 2 s (peak 2 N). The other, half the frame rate, 0.5 N above it
        // where it has frames and on a line between them: 0.5 N off at every instant of the first.
        let first = run(vec![0.0, 1.0, 2.0], vec![0.0, 1.0, 2.0]);
        let other = run(vec![0.0, 2.0], vec![0.5, 2.5]);
        let d = force_against(&first, &other);
        assert_eq!(d.len(), 1);
        assert_eq!((d[0].frames, d[0].peak_n), (3, 2.0));
        assert!((d[0].rms_pct - 25.0).abs() < 1e-12 && (d[0].max_pct - 25.0).abs() < 1e-12, "{d:?}");
        // Outside the other's span, or NaN in it: not compared.
        let short = run(vec![0.0, 1.0], vec![0.0, f64::NAN]);
        assert_eq!(force_against(&first, &short)[0].frames, 1);
        assert!(force_against(&first, &run(vec![5.0, 6.0], vec![1.0, 1.0])).is_empty());
        assert_eq!(force_against(&first, &first)[0].max_pct, 0.0);
    }

    #[test]
    fn events_close_in_time_share_a_label() {
        let e = |time_s: f64, kind: EventKind, tether: &str| RunEvent { time_s, kind, tether: tether.into() };
        let events = [e(1.0, EventKind::Cut, "b1"), e(1.02, EventKind::Torn, "vein"), e(1.03, EventKind::Cut, "b2"), e(1.2, EventKind::Cut, "b3"), e(2.0, EventKind::Torn, "b4")];
        assert_eq!(event_groups(&events, EventKind::Cut, 0.05), vec![(1.0, 2, "b1"), (1.2, 1, "b3")]);
        assert_eq!(event_groups(&events, EventKind::Torn, 0.05), vec![(1.02, 1, "vein"), (2.0, 1, "b4")]);
        assert_eq!(event_groups(&events, EventKind::Torn, 1.0), vec![(1.02, 2, "vein")]);
    }

    #[test]
    fn the_output_is_a_png_or_an_svg() {
        assert_eq!(OutputFormat::of(Path::new("a/b.PNG")).unwrap(), OutputFormat::Png);
        assert_eq!(OutputFormat::of(Path::new("b.svg")).unwrap(), OutputFormat::Svg);
        assert!(OutputFormat::of(Path::new("b.jpg")).unwrap_err().to_string().starts_with("b.jpg: "));
    }
}
