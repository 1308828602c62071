//! The debrief's numbers, verdicts and sentences: a pure function of a read run (and a reference run).
//!
//! In: [`RunData`], optionally the reference's. Out: a [`Debrief`]: per blade its metrics, each with its value,
//! the reference's, a literature limit where one exists and a [`Verdict`], and two or three sentences that say what
//! to do differently with the numbers and times; the pair's metrics; the scene's (vessels, bands, ischemia).
//! Stays true: every frame is weighted by its own duration (the time since the previous frame; the first frame's
//! time itself, when positive, as a replay's first row ends one time step in); a value that is not finite is left
//! out; a metric that cannot be computed (no tip columns, no contact) is `None`, never 0.
//!
//! The metrics are named as the simulator-assessment literature names them where it does: "instrument tip path
//! length" and "sum of applied forces" (Azarnoush et al. 2015, NeuroTouch tier 2 metrics,
//! doi:10.1007/s11548-014-1091-z), the "bimanual forces ratio" (NeuroTouch metrics extraction, Surg Innov 2015,
//! doi:10.1177/1553350615579729); feedback against an expert's benchmark as the Virtual Operative Assistant gives it
//! (Mirchi et al. 2020, PLoS One, doi:10.1371/journal.pone.0229596). The 20 mmHg line is the retraction pressure
//! that 15 minutes did not exceed without damage in the rat (Rosenørn and Diemer 1985, PMID 4032025,
//! doi:10.3171/jns.1985.63.4.0608). The reference bands (1.25x, 2x) and the floors where the reference is about
//! zero are chosen, not taken from a study.

use serde::Serialize;

use super::read::{BladeTrack, Injury, RunData};
use crate::sim::report::RETRACTION_DANGER_MMHG;

/// A dip of the mean pressure under 20 mmHg shorter than this does not end a hold, s (chosen: a quarter second is
/// shorter than a deliberate release and return, longer than a blade's frame-to-frame chatter).
pub const HOLD_GAP_S: f64 = 0.25;

/// A value within this factor of the reference's is "within".
pub const WITHIN_FACTOR: f64 = 1.25;
/// Past "within", up to this factor it is "above"; beyond, "far above".
pub const ABOVE_FACTOR: f64 = 2.0;

/// How a metric compares.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Verdict {
    /// At most 1.25x the reference's (or under the metric's floor), or under the limit.
    Within,
    /// At most 2x the reference's.
    Above,
    /// More than 2x the reference's.
    FarAbove,
    /// Past a literature limit.
    OverLimit,
}

impl Verdict {
    pub fn words(self) -> &'static str {
        match self {
            Verdict::Within => "within",
            Verdict::Above => "above",
            Verdict::FarAbove => "far above",
            Verdict::OverLimit => "over the limit",
        }
    }
}

/// One number of the debrief.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Metric {
    /// Stable key, e.g. `path_length_mm`.
    pub key: String,
    /// Its name in words, as the literature names it where it does.
    pub name: String,
    pub unit: String,
    pub value: Option<f64>,
    /// The reference run's value of the same metric (same blade), when a reference is given.
    pub reference: Option<f64>,
    /// A limit from the literature (or the scene's own, e.g. a vessel's warning stretch).
    pub limit: Option<f64>,
    pub reference_verdict: Option<Verdict>,
    pub limit_verdict: Option<Verdict>,
    /// The worse of the two.
    pub verdict: Option<Verdict>,
}

/// One blade's debrief.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BladeDebrief {
    pub name: String,
    pub metrics: Vec<Metric>,
    /// What to do differently, with the numbers and times (two or three).
    pub sentences: Vec<String>,
}

/// The two hands together (the first two blades).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct PairDebrief {
    pub blades: [String; 2],
    pub metrics: Vec<Metric>,
}

/// A run's debrief.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Debrief {
    /// The run folder.
    pub run: String,
    pub scenario: Option<String>,
    /// The reference run folder, when given.
    pub reference: Option<String>,
    pub frames: usize,
    pub simulated_s: f64,
    pub interrupted: bool,
    pub integrity_failures: Vec<String>,
    pub blades: Vec<BladeDebrief>,
    pub pair: Option<PairDebrief>,
    /// Vessels, bands, ischemia.
    pub scene: Vec<Metric>,
    pub scene_sentences: Vec<String>,
    pub injuries: Vec<Injury>,
    /// Why the page has no pressure map, when it has none.
    pub map_note: Option<String>,
}

impl Debrief {
    /// Every metric with the section it belongs to (`blade NAME`, `pair`, `scene`).
    pub fn all_metrics(&self) -> Vec<(String, &Metric)> {
        let mut out: Vec<(String, &Metric)> = Vec::new();
        for b in &self.blades {
            out.extend(b.metrics.iter().map(|m| (format!("blade {}", b.name), m)));
        }
        if let Some(p) = &self.pair {
            out.extend(p.metrics.iter().map(|m| ("pair".to_string(), m)));
        }
        out.extend(self.scene.iter().map(|m| ("scene".to_string(), m)));
        out
    }
}

/// Each frame's duration, s: the time since the previous frame (the first frame's time, when positive).
pub fn frame_durations(time_s: &[f64]) -> Vec<f64> {
    let mut out = Vec::with_capacity(time_s.len());
    for (k, &t) in time_s.iter().enumerate() {
        let dt = if k == 0 {
            if t > 0.0 { t } else { time_s.get(1).map_or(0.0, |t1| t1 - t) }
        } else {
            t - time_s[k - 1]
        };
        out.push(if dt.is_finite() && dt > 0.0 { dt } else { 0.0 });
    }
    out
}

/// A hold of the mean pressure above 20 mmHg.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Hold {
    /// Its first frame's time, s.
    pub start: f64,
    /// From the first frame above to the last, dips included, s.
    pub span: f64,
    /// Time above the line in it, s, and the pressure's integral over that time, mmHg s.
    pub above: f64,
    integral: f64,
    /// The dip under the line since its last frame above, s.
    gap: f64,
    /// The mean pressure over its time above the line, mmHg.
    pub mean_mmhg: f64,
}

/// The plain numbers of one blade, before any verdict.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BladeNumbers {
    pub time_in_contact_s: f64,
    pub path_length_mm: Option<f64>,
    pub net_displacement_mm: Option<f64>,
    pub economy_of_motion: Option<f64>,
    pub peak_force_n: f64,
    pub peak_force_time_s: f64,
    pub mean_force_n: Option<f64>,
    pub rms_force_n: Option<f64>,
    pub force_roughness_n: Option<f64>,
    pub peak_mean_pressure_mmhg: f64,
    pub time_above_20mmhg_s: f64,
    pub pressure_time_above_20mmhg_mmhg_s: f64,
    /// The longest hold above 20 mmHg (dips under the line shorter than [`HOLD_GAP_S`] included).
    pub longest_above: Option<Hold>,
    pub max_area_at_risk_mm2: Option<f64>,
    pub first_at_risk_s: Option<f64>,
    /// Frame by frame: in contact.
    pub in_contact: Vec<bool>,
}

/// The numbers of one blade over the frames of `time_s`.
pub fn blade_numbers(blade: &BladeTrack, time_s: &[f64]) -> BladeNumbers {
    let dt = frame_durations(time_s);
    let n = time_s.len();
    let mut b = BladeNumbers { in_contact: (0..n).map(|k| blade.contact_vertices.get(k).is_some_and(|&c| c > 0.0)).collect(), ..Default::default() };
    let (mut sum, mut sum_sq, mut frames) = (0.0, 0.0, 0usize);
    for k in 0..n {
        let f = blade.force_n.get(k).copied().unwrap_or(f64::NAN);
        if f.is_finite() && f > b.peak_force_n {
            (b.peak_force_n, b.peak_force_time_s) = (f, time_s[k]);
        }
        if b.in_contact[k] {
            b.time_in_contact_s += dt[k];
            if f.is_finite() {
                sum += f;
                sum_sq += f * f;
                frames += 1;
            }
        }
    }
    if frames > 0 {
        b.mean_force_n = Some(sum / frames as f64);
        b.rms_force_n = Some((sum_sq / frames as f64).sqrt());
    }
    // Frame-to-frame force change: the force vector's (the `_force_jump_n` column) where the file has it, else the
    // magnitude's; the first row's jump (from nothing before the run) is left out.
    let changes: Vec<f64> = match &blade.force_jump_n {
        Some(j) => j.iter().skip(1).copied().filter(|v| v.is_finite()).collect(),
        None => blade.force_n.windows(2).map(|w| w[1] - w[0]).filter(|v| v.is_finite()).collect(),
    };
    if !changes.is_empty() {
        b.force_roughness_n = Some((changes.iter().map(|c| c * c).sum::<f64>() / changes.len() as f64).sqrt());
    }
    // Pressure above the line: time, dose and the longest hold. A hold goes on across dips under the line shorter
    // than [`HOLD_GAP_S`] (a blade chattering about 20 mmHg is one hold, not many short ones).
    let mut hold: Option<Hold> = None;
    let close = |hold: &mut Option<Hold>, longest: &mut Option<Hold>| {
        if let Some(mut h) = hold.take()
            && longest.is_none_or(|l| h.span > l.span)
        {
            h.mean_mmhg = if h.above > 0.0 { h.integral / h.above } else { 0.0 };
            *longest = Some(h);
        }
    };
    for k in 0..n {
        let p = blade.mean_pressure_mmhg.get(k).copied().unwrap_or(f64::NAN);
        if p.is_finite() {
            b.peak_mean_pressure_mmhg = b.peak_mean_pressure_mmhg.max(p);
        }
        if p.is_finite() && p > RETRACTION_DANGER_MMHG {
            b.time_above_20mmhg_s += dt[k];
            b.pressure_time_above_20mmhg_mmhg_s += (p - RETRACTION_DANGER_MMHG) * dt[k];
            let h = hold.get_or_insert(Hold { start: time_s[k], span: 0.0, above: 0.0, integral: 0.0, gap: 0.0, mean_mmhg: 0.0 });
            h.span += h.gap + dt[k];
            h.gap = 0.0;
            h.above += dt[k];
            h.integral += p * dt[k];
        } else if let Some(h) = hold.as_mut() {
            h.gap += dt[k];
            if h.gap >= HOLD_GAP_S {
                close(&mut hold, &mut b.longest_above);
            }
        }
    }
    close(&mut hold, &mut b.longest_above);
    // The tip's path.
    if let Some(tip) = &blade.tip_mm {
        let finite: Vec<&[f64; 3]> = tip.iter().filter(|p| p.iter().all(|c| c.is_finite())).collect();
        if let (Some(first), Some(last)) = (finite.first(), finite.last()) {
            let dist = |a: &[f64; 3], b: &[f64; 3]| ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
            let path: f64 = finite.windows(2).map(|w| dist(w[0], w[1])).sum();
            let net = dist(first, last);
            b.path_length_mm = Some(path);
            b.net_displacement_mm = Some(net);
            b.economy_of_motion = (net > 1e-9).then(|| path / net);
        }
    }
    if let Some(area) = &blade.area_at_risk_mm2 {
        b.max_area_at_risk_mm2 = Some(area.iter().copied().filter(|a| a.is_finite()).fold(0.0, f64::max));
        b.first_at_risk_s = area.iter().position(|&a| a > 0.0).map(|k| time_s[k]);
    }
    b
}

/// How a metric is judged.
#[derive(Clone, Copy)]
struct Rule {
    /// Against the reference; below this the value is "within" whatever the reference (None: not judged).
    floor: Option<f64>,
    /// A literature limit: over it is [`Verdict::OverLimit`].
    limit: Option<f64>,
}

const NOT_JUDGED: Rule = Rule { floor: None, limit: None };

/// The verdict of `value` against `reference` (1.25x / 2x, with `floor` for a reference of about 0).
pub fn against_reference(value: f64, reference: f64, floor: f64) -> Verdict {
    if value <= (WITHIN_FACTOR * reference).max(floor) {
        Verdict::Within
    } else if value <= (ABOVE_FACTOR * reference).max(ABOVE_FACTOR * floor) {
        Verdict::Above
    } else {
        Verdict::FarAbove
    }
}

fn metric(key: &str, name: &str, unit: &str, value: Option<f64>, reference: Option<Option<f64>>, rule: Rule) -> Metric {
    let reference = reference.flatten();
    let reference_verdict = match (value, reference, rule.floor) {
        (Some(v), Some(r), Some(floor)) => Some(against_reference(v, r, floor)),
        _ => None,
    };
    let limit_verdict = match (value, rule.limit) {
        (Some(v), Some(l)) => Some(if v > l { Verdict::OverLimit } else { Verdict::Within }),
        _ => None,
    };
    let verdict = reference_verdict.max(limit_verdict);
    Metric { key: key.into(), name: name.into(), unit: unit.into(), value, reference, limit: rule.limit, reference_verdict, limit_verdict, verdict }
}

/// The blade's metrics; `reference` the same blade's numbers in the reference run.
fn blade_metrics(b: &BladeNumbers, reference: Option<&BladeNumbers>) -> Vec<Metric> {
    let r = |f: fn(&BladeNumbers) -> Option<f64>| reference.map(f);
    let judged = |floor: f64| Rule { floor: Some(floor), limit: None };
    let mut out = vec![
        metric("time_in_contact_s", "time in contact", "s", Some(b.time_in_contact_s), r(|x| Some(x.time_in_contact_s)), judged(0.5)),
        metric("path_length_mm", "instrument tip path length", "mm", b.path_length_mm, r(|x| x.path_length_mm), judged(1.0)),
        metric("net_displacement_mm", "net tip displacement", "mm", b.net_displacement_mm, r(|x| x.net_displacement_mm), NOT_JUDGED),
        metric("economy_of_motion", "economy of motion (path length / net displacement)", "", b.economy_of_motion, r(|x| x.economy_of_motion), judged(1.0)),
        metric("peak_force_n", "peak force", "N", Some(b.peak_force_n), r(|x| Some(x.peak_force_n)), judged(0.01)),
        metric("mean_force_n", "mean force in contact", "N", b.mean_force_n, r(|x| x.mean_force_n), judged(0.01)),
        metric("rms_force_n", "RMS force in contact", "N", b.rms_force_n, r(|x| x.rms_force_n), judged(0.01)),
        metric("force_roughness_n", "force roughness (RMS frame-to-frame change)", "N", b.force_roughness_n, r(|x| x.force_roughness_n), judged(0.002)),
        metric(
            "peak_mean_pressure_mmhg",
            "peak mean contact pressure",
            "mmHg",
            Some(b.peak_mean_pressure_mmhg),
            r(|x| Some(x.peak_mean_pressure_mmhg)),
            Rule { floor: Some(2.0), limit: Some(RETRACTION_DANGER_MMHG) },
        ),
        metric("time_above_20mmhg_s", "time above 20 mmHg", "s", Some(b.time_above_20mmhg_s), r(|x| Some(x.time_above_20mmhg_s)), judged(0.1)),
        metric(
            "pressure_time_above_20mmhg_mmhg_s",
            "pressure-time dose above 20 mmHg",
            "mmHg s",
            Some(b.pressure_time_above_20mmhg_mmhg_s),
            r(|x| Some(x.pressure_time_above_20mmhg_mmhg_s)),
            judged(1.0),
        ),
    ];
    if b.max_area_at_risk_mm2.is_some() {
        out.push(metric(
            "max_area_at_risk_mm2",
            "largest area at risk of ischemia",
            "mm^2",
            b.max_area_at_risk_mm2,
            r(|x| x.max_area_at_risk_mm2),
            Rule { floor: Some(1.0), limit: Some(0.0) },
        ));
    }
    out
}

/// Numbers with 3 significant digits for sentences.
fn num(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let decimals = (2 - v.abs().log10().floor() as i32).clamp(0, 6) as usize;
    format!("{v:.decimals$}")
}

/// What to do differently with this blade, worst first, at most three.
fn blade_sentences(name: &str, b: &BladeNumbers, metrics: &[Metric]) -> Vec<String> {
    let get = |key: &str| metrics.iter().find(|m| m.key == key);
    let worse = |key: &str| get(key).and_then(|m| m.reference_verdict).is_some_and(|v| v > Verdict::Within);
    let mut out: Vec<(u8, String)> = Vec::new();
    if let Some(h) = b.longest_above {
        let all = format!("{} s above 20 mmHg in all, a dose of {} mmHg s above the line", num(b.time_above_20mmhg_s), num(b.pressure_time_above_20mmhg_mmhg_s));
        // A hold mostly above the line reads as one; one that kept crossing it says so.
        let held = if h.above >= 0.9 * h.span {
            format!("The {name} blade held {} mmHg for {} s from {} s ({all})", num(h.mean_mmhg), num(h.span), num(h.start))
        } else {
            format!(
                "The {name} blade pressed about the 20 mmHg line for {} s from {} s, above it {} s of that at {} mmHg on average ({all})",
                num(h.span),
                num(h.start),
                num(h.above),
                num(h.mean_mmhg)
            )
        };
        out.push((0, format!("{held}: spread less, or release and return.")));
    }
    if let (Some(area), Some(t)) = (b.max_area_at_risk_mm2.filter(|a| *a > 0.0), b.first_at_risk_s) {
        out.push((0, format!("Under the {name} blade {} mm^2 reached even odds of ischemic injury, the first at {} s: release the retraction from time to time.", num(area), num(t))));
    }
    if worse("peak_force_n")
        && let Some(r) = get("peak_force_n").and_then(|m| m.reference)
    {
        out.push((1, format!("The {name} blade's force peaked at {} N at {} s against the reference's {} N: open less far, or more slowly.", num(b.peak_force_n), num(b.peak_force_time_s), num(r))));
    }
    if worse("economy_of_motion")
        && let (Some(v), Some(r)) = (b.economy_of_motion, get("economy_of_motion").and_then(|m| m.reference))
    {
        out.push((2, format!("Economy of motion {} against the reference's {}: move the {name} blade in fewer, straighter strokes.", num(v), num(r))));
    } else if worse("path_length_mm")
        && let (Some(v), Some(r)) = (b.path_length_mm, get("path_length_mm").and_then(|m| m.reference))
    {
        out.push((2, format!("The {name} blade's tip travelled {} mm against the reference's {} mm: plan the move, then make it once.", num(v), num(r))));
    }
    if worse("force_roughness_n")
        && let (Some(v), Some(r)) = (b.force_roughness_n, get("force_roughness_n").and_then(|m| m.reference))
    {
        out.push((3, format!("The {name} blade's force changed by {} N a frame (RMS) against the reference's {} N: move more steadily, without jerks.", num(v), num(r))));
    }
    if worse("time_in_contact_s")
        && let Some(r) = get("time_in_contact_s").and_then(|m| m.reference)
    {
        out.push((4, format!("The {name} blade touched the brain for {} s against the reference's {} s: leave the tissue when the blade is not needed.", num(b.time_in_contact_s), num(r))));
    }
    // Less is not judged "above", but a blade that did not go where the careful one went did not do the job: a tip
    // that moved less than half the reference's net displacement is told so (half: chosen).
    if let (Some(v), Some(r)) = (b.net_displacement_mm, get("net_displacement_mm").and_then(|m| m.reference))
        && r > 1.0
        && v < 0.5 * r
    {
        out.push((1, format!("The {name} blade's tip moved {} mm from where it started against the careful surgeon's {} mm: the opening is not done; take the blade to where the reference's went.", num(v), num(r))));
    }
    out.sort_by_key(|(rank, _)| *rank);
    let mut sentences: Vec<String> = out.into_iter().map(|(_, s)| s).take(3).collect();
    if sentences.is_empty() {
        let against = if metrics.iter().any(|m| m.reference.is_some()) { "the reference and the limits" } else { "the limits" };
        sentences.push(format!(
            "The {name} blade stayed within {against}: peak force {} N, mean pressure at most {} mmHg.",
            num(b.peak_force_n),
            num(b.peak_mean_pressure_mmhg)
        ));
    }
    sentences
}

/// The pair's numbers: the force ratio (the larger blade's mean contact force over the smaller's) and the time
/// both blades are in contact.
fn pair_numbers(a: &BladeNumbers, b: &BladeNumbers, time_s: &[f64]) -> (Option<f64>, f64) {
    let ratio = match (a.mean_force_n, b.mean_force_n) {
        (Some(x), Some(y)) if x.min(y) > 0.0 => Some(x.max(y) / x.min(y)),
        _ => None,
    };
    let dt = frame_durations(time_s);
    let both = (0..time_s.len()).filter(|&k| a.in_contact[k] && b.in_contact[k]).map(|k| dt[k]).sum();
    (ratio, both)
}

/// When a series first reaches its largest value.
fn time_of_max(series: &[f64], time_s: &[f64]) -> Option<f64> {
    let mut best: Option<(f64, f64)> = None;
    for (&v, &t) in series.iter().zip(time_s) {
        if v.is_finite() && best.is_none_or(|(b, _)| v > b) {
            best = Some((v, t));
        }
    }
    best.map(|(_, t)| t)
}

/// The scene's metrics (vessels, bands, ischemia) and sentences.
fn scene(run: &RunData, reference: Option<&RunData>) -> (Vec<Metric>, Vec<String>) {
    let mut metrics = Vec::new();
    let mut sentences = Vec::new();
    for v in &run.vessels {
        let word = crate::sim::metrics::column_word(&v.name);
        let r = reference.map(|r| r.vessels.iter().find(|x| x.name == v.name).map(|x| x.max_stretch));
        let mut m = metric(&format!("vessel_{word}_max_stretch"), &format!("largest stretch of {}", v.name), "", Some(v.max_stretch), r, Rule { floor: None, limit: Some(v.warning_stretch) });
        if v.torn {
            m.limit_verdict = Some(Verdict::OverLimit);
            m.verdict = Some(Verdict::OverLimit);
        }
        metrics.push(m);
        let when = v.stretch.as_deref().and_then(|s| time_of_max(s, &run.time_s));
        let at = when.map(|t| format!(" at {} s", num(t))).unwrap_or_default();
        if v.torn {
            let tore = run.injuries.iter().find(|i| i.tether == v.name && i.kind == "torn").map(|i| format!(" at {} s", num(i.time_s))).unwrap_or_default();
            sentences.push(format!(
                "The {} tore{tore} (rupture stretch {}): open the fissure along the vessel, not across it, and free it from its bands first.",
                v.name,
                num(v.rupture_stretch)
            ));
        } else if v.max_stretch > v.warning_stretch {
            sentences.push(format!("The {} stretched to {} (warning {}){at}: spread less where it crosses the fissure.", v.name, num(v.max_stretch), num(v.warning_stretch)));
        }
    }
    if let Some((total, torn, cut)) = run.bands {
        let r = reference.map(|r| r.bands.map(|b| b.1 as f64));
        metrics.push(metric("bands_torn", &format!("arachnoid bands torn (of {total})"), "", Some(torn as f64), r, Rule { floor: None, limit: Some(0.0) }));
        let r = reference.map(|r| r.bands.map(|b| b.2 as f64));
        metrics.push(metric("bands_cut", &format!("arachnoid bands cut (of {total})"), "", Some(cut as f64), r, NOT_JUDGED));
        if torn > 0 {
            let first = run.injuries.iter().find(|i| i.kind == "torn" && !run.vessels.iter().any(|v| v.name == i.tether)).map(|i| format!(", the first at {} s", num(i.time_s))).unwrap_or_default();
            sentences.push(format!("{torn} arachnoid band{} tore{first}: cut the bands (X) before spreading.", if torn == 1 { "" } else { "s" }));
        }
    }
    if let Some(area) = &run.ischemia_at_risk_mm2 {
        let max = |a: &[f64]| a.iter().copied().filter(|v| v.is_finite()).fold(0.0, f64::max);
        let r = reference.map(|r| r.ischemia_at_risk_mm2.as_deref().map(max));
        metrics.push(metric("ischemia_at_risk_mm2", "largest area at risk of ischemia", "mm^2", Some(max(area)), r, Rule { floor: Some(1.0), limit: Some(0.0) }));
    }
    (metrics, sentences)
}

/// The debrief of `run`, against `reference` when given.
pub fn debrief(run: &RunData, reference: Option<&RunData>) -> Debrief {
    let numbers: Vec<BladeNumbers> = run.blades.iter().map(|b| blade_numbers(b, &run.time_s)).collect();
    let reference_numbers: Option<Vec<(String, BladeNumbers)>> =
        reference.map(|r| r.blades.iter().map(|b| (b.name.clone(), blade_numbers(b, &r.time_s))).collect());
    let reference_of = |name: &str| reference_numbers.as_ref().and_then(|list| list.iter().find(|(n, _)| n == name).map(|(_, b)| b));
    let blades = run
        .blades
        .iter()
        .zip(&numbers)
        .map(|(blade, b)| {
            let metrics = blade_metrics(b, reference_of(&blade.name));
            let sentences = blade_sentences(&blade.name, b, &metrics);
            BladeDebrief { name: blade.name.clone(), metrics, sentences }
        })
        .collect();
    let pair = (run.blades.len() >= 2).then(|| {
        let (ratio, both) = pair_numbers(&numbers[0], &numbers[1], &run.time_s);
        let names = [run.blades[0].name.clone(), run.blades[1].name.clone()];
        let (r_ratio, r_both) = match (reference, reference_of(&names[0]), reference_of(&names[1])) {
            (Some(r), Some(a), Some(b)) => {
                let (x, y) = pair_numbers(a, b, &r.time_s);
                (Some(x), Some(Some(y)))
            }
            (Some(_), _, _) => (Some(None), Some(None)),
            _ => (None, None),
        };
        let metrics = vec![
            metric("force_ratio", "bimanual force ratio (larger mean contact force / smaller)", "", ratio, r_ratio, Rule { floor: Some(1.0), limit: None }),
            metric("time_both_in_contact_s", "time both blades in contact", "s", Some(both), r_both, NOT_JUDGED),
        ];
        PairDebrief { blades: names, metrics }
    });
    let (scene_metrics, mut scene_sentences) = scene(run, reference);
    if let Some(p) = &pair
        && let Some(m) = p.metrics.first().filter(|m| m.reference_verdict.is_some_and(|v| v > Verdict::Within))
        && let (Some(v), Some(r)) = (m.value, m.reference)
    {
        scene_sentences.push(format!("One hand pushed {} times as hard as the other (the reference {}): share the retraction between the two blades.", num(v), num(r)));
    }
    Debrief {
        run: run.dir.display().to_string(),
        scenario: run.scenario.clone(),
        reference: reference.map(|r| r.dir.display().to_string()),
        frames: run.time_s.len(),
        simulated_s: run.time_s.iter().copied().filter(|t| t.is_finite()).fold(0.0, f64::max),
        interrupted: run.interrupted,
        integrity_failures: run.integrity_failures.clone(),
        blades,
        pair,
        scene: scene_metrics,
        scene_sentences,
        injuries: run.injuries.clone(),
        map_note: run.dose.as_ref().err().cloned(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn blade(force: Vec<f64>, pressure: Vec<f64>, tip: Option<Vec<[f64; 3]>>) -> BladeTrack {
        let n = force.len();
        BladeTrack { name: "a".into(), contact_vertices: vec![3.0; n], force_n: force, mean_pressure_mmhg: pressure, force_jump_n: None, tip_mm: tip, area_at_risk_mm2: None }
    }

    #[test]
    fn a_straight_line_at_constant_speed_has_economy_one() {
        let time: Vec<f64> = (1..=5).map(|k| k as f64 * 0.1).collect();
        let tip = (0..5).map(|k| [k as f64 * 3.0, k as f64 * 4.0, 0.0]).collect();
        let b = blade_numbers(&blade(vec![0.1; 5], vec![5.0; 5], Some(tip)), &time);
        assert_eq!(b.path_length_mm, Some(20.0));
        assert_eq!(b.net_displacement_mm, Some(20.0));
        assert_eq!(b.economy_of_motion, Some(1.0));
        // There and back: path twice the way, net zero, no economy.
        let tip = vec![[0.0; 3], [1.0, 0.0, 0.0], [0.0; 3]];
        let b = blade_numbers(&blade(vec![0.1; 3], vec![5.0; 3], Some(tip)), &time[..3]);
        assert_eq!((b.path_length_mm, b.net_displacement_mm, b.economy_of_motion), (Some(2.0), Some(0.0), None));
    }

    #[test]
    fn a_constant_force_has_peak_mean_and_rms_equal_and_no_roughness() {
        let time: Vec<f64> = (1..=4).map(|k| k as f64 * 0.5).collect();
        let b = blade_numbers(&blade(vec![0.25; 4], vec![30.0; 4], None), &time);
        assert_eq!((b.peak_force_n, b.mean_force_n, b.rms_force_n, b.force_roughness_n), (0.25, Some(0.25), Some(0.25), Some(0.0)));
        // 30 mmHg for 2 s: 2 s above the line, a dose of 10 mmHg x 2 s.
        assert!((b.time_above_20mmhg_s - 2.0).abs() < 1e-12);
        assert!((b.pressure_time_above_20mmhg_mmhg_s - 20.0).abs() < 1e-12);
        let h = b.longest_above.expect("a hold");
        assert_eq!((h.start, h.span, h.above, h.mean_mmhg), (0.5, 2.0, 2.0, 30.0));
        assert_eq!(b.path_length_mm, None, "no tip columns: no path");
    }

    #[test]
    fn a_blade_that_went_less_than_half_as_far_as_the_reference_is_told_the_opening_is_not_done() {
        let time: Vec<f64> = (1..=3).map(|k| k as f64 * 0.5).collect();
        let run = |step: f64| blade(vec![0.1; 3], vec![5.0; 3], Some((0..3).map(|k| [step * k as f64, 0.0, 0.0]).collect()));
        let (mine, careful) = (blade_numbers(&run(2.0), &time), blade_numbers(&run(10.0), &time));
        let metrics = blade_metrics(&mine, Some(&careful));
        let said = blade_sentences("frontal", &mine, &metrics);
        assert!(said.iter().any(|s| s.contains("moved 4.00 mm") && s.contains("careful surgeon's 20.0 mm")), "{said:?}");
        let metrics = blade_metrics(&careful, Some(&careful));
        assert!(!blade_sentences("frontal", &careful, &metrics).iter().any(|s| s.contains("not done")), "the reference itself is done");
    }

    #[test]
    fn a_hold_goes_on_across_short_dips_and_ends_at_a_long_one() {
        // Frames of 0.1 s: above (30 mmHg), a 0.1 s dip, above twice (40), then 0.3 s under, then above once (50).
        let pressure = vec![30.0, 10.0, 40.0, 40.0, 10.0, 10.0, 10.0, 50.0];
        let time: Vec<f64> = (1..=pressure.len()).map(|k| k as f64 * 0.1).collect();
        let b = blade_numbers(&blade(vec![0.1; pressure.len()], pressure, None), &time);
        let Hold { start, span, mean_mmhg: mean, .. } = b.longest_above.expect("a hold");
        assert!((start - 0.1).abs() < 1e-12, "the hold starts at the first frame above: {start}");
        assert!((span - 0.4).abs() < 1e-12, "0.1 s dip inside it: four frames, 0.4 s: {span}");
        assert!((mean - (30.0 + 40.0 + 40.0) / 3.0).abs() < 1e-9, "mean over the frames above the line: {mean}");
        assert!((b.time_above_20mmhg_s - 0.4).abs() < 1e-12, "four frames above in all");
    }

    #[test]
    fn roughness_is_the_rms_of_the_changes() {
        let time = [0.1, 0.2, 0.3];
        let b = blade_numbers(&blade(vec![0.0, 0.3, 0.7], vec![0.0; 3], None), &time);
        let expected = ((0.3f64.powi(2) + 0.4f64.powi(2)) / 2.0).sqrt();
        assert!((b.force_roughness_n.unwrap() - expected).abs() < 1e-12);
    }

    #[test]
    fn verdicts_use_the_factors_and_the_floor() {
        assert_eq!(against_reference(1.25, 1.0, 0.0), Verdict::Within);
        assert_eq!(against_reference(1.3, 1.0, 0.0), Verdict::Above);
        assert_eq!(against_reference(2.0, 1.0, 0.0), Verdict::Above);
        assert_eq!(against_reference(2.1, 1.0, 0.0), Verdict::FarAbove);
        assert_eq!(against_reference(0.4, 0.0, 0.5), Verdict::Within, "a reference of 0: the floor");
        assert_eq!(against_reference(0.9, 0.0, 0.5), Verdict::Above);
    }

    #[test]
    fn a_run_against_itself_is_within_and_says_so() {
        let time: Vec<f64> = (1..=4).map(|k| k as f64 * 0.5).collect();
        let run = RunData { time_s: time, blades: vec![blade(vec![0.25; 4], vec![30.0; 4], None)], dose: Err("none".into()), ..Default::default() };
        let d = debrief(&run, Some(&run));
        for (_, m) in d.all_metrics() {
            assert!(m.reference_verdict.is_none_or(|v| v == Verdict::Within), "{m:?}");
        }
        let pressure = d.blades[0].metrics.iter().find(|m| m.key == "peak_mean_pressure_mmhg").unwrap();
        assert_eq!(pressure.limit_verdict, Some(Verdict::OverLimit), "30 mmHg is over the 20 mmHg line");
        assert!(d.blades[0].sentences[0].contains("held 30.0 mmHg for 2.00 s from 0.500 s"), "{:?}", d.blades[0].sentences);
    }
}
