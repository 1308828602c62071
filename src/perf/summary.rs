//! The summary table of the performance page (copied into the README): a row a measure, today's figure, its
//! goal with "met" or "not met", and the command that measures it. Every figure comes from the typed record
//! ([`PerfRecord`]); a figure the row needs that the run did not write is an error naming the run.

use super::record::{PerfError, PerfRecord, ReplayRun};
use super::reports::{EarlyStartFigures, FemFigures, FrameFigures, StartupReport};
use std::fmt::Write;
use std::path::Path;

/// "met" when `v < limit`.
pub fn verdict(v: f64, limit: f64) -> &'static str {
    if !v.is_finite() {
        "not measured"
    } else if v < limit {
        "met"
    } else {
        "not met"
    }
}

/// "met" when `v <= limit`.
pub fn at_most(v: f64, limit: f64) -> &'static str {
    if !v.is_finite() {
        "not measured"
    } else if v <= limit {
        "met"
    } else {
        "not met"
    }
}

/// The middle value (the mean of the two middle ones); NaN when there is none.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => (v[n / 2 - 1] + v[n / 2]) / 2.0,
    }
}

pub fn code(s: &str) -> String {
    format!("`{s}`")
}

/// `FAST=1`'s words for a measure it skips.
pub const NOT_RUN_FAST: &str = "not run (FAST=1)";

/// The replays' figures by scene name.
pub struct Replays<'a>(pub &'a [ReplayRun]);

impl<'a> Replays<'a> {
    pub fn runs(&self, tag: &str) -> Vec<&'a ReplayRun> {
        self.0.iter().filter(|r| r.tag == tag).collect()
    }
    /// The scene names in the order first run.
    pub fn tags(&self) -> Vec<&'a str> {
        let mut tags: Vec<&str> = Vec::new();
        for r in self.0 {
            if !tags.contains(&r.tag.as_str()) {
                tags.push(&r.tag);
            }
        }
        tags
    }
    fn of(&self, tag: &str, f: impl Fn(&ReplayRun) -> f64) -> Vec<f64> {
        self.runs(tag).into_iter().map(f).collect()
    }
    pub fn p50(&self, tag: &str) -> f64 {
        median(self.of(tag, |r| r.summary.frame.p50_ms))
    }
    pub fn p95(&self, tag: &str) -> f64 {
        median(self.of(tag, |r| r.summary.frame.p95_ms))
    }
    pub fn max(&self, tag: &str) -> f64 {
        self.of(tag, |r| r.summary.frame.max_ms).into_iter().fold(f64::NAN, f64::max)
    }
    /// The first run of a scene (the one whose `summary.json` a row quotes).
    pub fn first(&self, tag: &str) -> Result<&'a ReplayRun, PerfError> {
        self.0.iter().find(|r| r.tag == tag).ok_or_else(|| PerfError::new(Path::new("replays.tsv"), format!("no run of {tag}")))
    }
    /// The last run of a scene.
    pub fn last(&self, tag: &str) -> Result<&'a ReplayRun, PerfError> {
        self.0.iter().rev().find(|r| r.tag == tag).ok_or_else(|| PerfError::new(Path::new("replays.tsv"), format!("no run of {tag}")))
    }
    /// "p50 X / p95 Y ms (max M ms)": the medians over the runs, the largest max.
    pub fn rp(&self, tag: &str) -> String {
        format!("p50 {:.3} / p95 {:.3} ms (max {:.3} ms)", self.p50(tag), self.p95(tag), self.max(tag))
    }
}

fn startup<'a>(record: &'a PerfRecord, name: &str) -> Result<&'a StartupReport, PerfError> {
    record.startup(name).ok_or_else(|| PerfError::new(Path::new("startup"), format!("no {name}.json")))
}

/// A startup run's build figures (the run waited for every column).
pub fn build_of<'a>(record: &'a PerfRecord, name: &str) -> Result<&'a super::reports::BuildFigures, PerfError> {
    startup(record, name)?.build.as_ref().ok_or_else(|| PerfError::new(&Path::new("startup").join(format!("{name}.json")), "no build figures"))
}

/// A startup run's early-start figures.
pub fn early_of<'a>(record: &'a PerfRecord, name: &str) -> Result<&'a EarlyStartFigures, PerfError> {
    startup(record, name)?.early_start.as_ref().ok_or_else(|| PerfError::new(&Path::new("startup").join(format!("{name}.json")), "no early-start figures"))
}

/// A fem model's frame at `constrained` vertices.
pub fn frame_at(f: &FemFigures, constrained: usize) -> Result<&FrameFigures, PerfError> {
    f.frames.iter().find(|x| x.constrained == constrained).ok_or_else(|| PerfError::new(Path::new(&format!("{}.json", f.model)), format!("no frame at {constrained} constrained")))
}

/// A figure the bench may leave out (null): the page needs it.
pub fn need(v: Option<f64>, model: &str, what: &str) -> Result<f64, PerfError> {
    v.ok_or_else(|| PerfError::new(Path::new(&format!("{model}.json")), format!("no {what}")))
}

/// The summary table, header included.
pub fn summary_rows(r: &PerfRecord) -> Result<String, PerfError> {
    let mut out = String::from("| measure | today | goal | command |\n|---|---|---|---|\n");
    collision_rows(r, &mut out)?;
    replay_rows(r, &mut out)?;
    effects_rows(r, &mut out)?;
    startup_rows(r, &mut out)?;
    window_row(r, &mut out);
    fem_rows(r, &mut out)?;
    cholmod_row(r, &mut out);
    Ok(out)
}

fn collision_rows(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let path = Path::new("collision.json");
    let c = &r.collision;
    let bvh = c.row("paper-12k", 500, "bvh").ok_or_else(|| PerfError::new(path, "no paper-12k 500 bvh row"))?;
    let q15 = c.row("brain-q15", 500, "bvh").ok_or_else(|| PerfError::new(path, "no brain-q15 500 bvh row (the fine brain was not found)"))?;
    let _ = writeln!(
        out,
        "| collision stage, two blades at 500 source nodes a face, paper-12k (14,810 triangles), bvh on 2 threads | p50 {:.3} / p95 {:.3} ms | under 1 ms, refit included: {} (p50) | {} |",
        bvh.p50_ms,
        bvh.p95_ms,
        verdict(bvh.p50_ms, 1.0),
        code("fissure bench collision --frames 30")
    );
    match c.row("paper-12k", 500, "gpu") {
        Some(gpu) => {
            let x = gpu.p50_ms / bvh.p50_ms;
            let _ = writeln!(
                out,
                "| the same on the gpu backend, on {} | p50 {:.3} / p95 {:.3} ms, {x:.2}x bvh | within 10x of bvh on a software driver: {} | the same |",
                c.device,
                gpu.p50_ms,
                gpu.p95_ms,
                verdict((x * 100.0).round() / 100.0, 10.0)
            );
        }
        None => out.push_str("| the same on the gpu backend | not run: no GPU adapter (not even a software one) | within 10x of bvh on a software driver | the same |\n"),
    }
    let _ = writeln!(
        out,
        "| collision stage, fine real brain (q15, 67,708 triangles), 500 source nodes a face, bvh | p50 {:.3} / p95 {:.3} ms | under 1 ms: {} (p50) | the same |",
        q15.p50_ms,
        q15.p95_ms,
        verdict(q15.p50_ms, 1.0)
    );
    Ok(())
}

/// What a shipped scene's row says it is.
fn scene_words(tag: &str) -> &str {
    match tag {
        "sylvian" => "default scene: paper-12k refined under the blades (refine: Auto), two spatulas, skull spheres",
        "interhemispheric" => "paper-9k, one spatula in the inter-hemispheric fissure",
        "u_shape" => "the paper's U block",
        "v_valley" => "the paper's V valley",
        "real_brain/interhemispheric" => "coarse real brain (25,757 nodes), two blades down the inter-hemispheric fissure",
        "real_brain/sylvian" => "fine real brain (q15), the Sylvian opening, refined where the blades reach (refine: Auto)",
        "real_brain/sylvian_wide" => "the same, pressed wider (the wide-press trajectory)",
        "sylvian_tethers" => "the default scene with its vessels and arachnoid bands, the careful opening (bands cut, then spread)",
        "sylvian_noisy" => "default scene, its spread with +-0.5 mm tracker noise every 10 ms, unfiltered",
        "sylvian_noisy_filtered" => "the same noisy spread through the One Euro filter",
        "unrefined/sylvian" => "default scene on the phantom's own mesh (refine: None), for comparison",
        other => other,
    }
}

/// A row a shipped scene (the size, effects and hold runs have rows of their own).
fn replay_rows(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let rep = Replays(&r.replays);
    let runs_note = if r.info.repeat == 1 { "one run".to_string() } else { format!("median of {} runs", r.info.repeat) };
    for tag in rep.tags() {
        if ["size/", "effects/", "hold/"].iter().any(|p| tag.starts_with(p)) || (tag.starts_with("real_brain/") && tag.ends_with("_tethers")) {
            continue;
        }
        let p95 = rep.p95(tag);
        let last = rep.last(tag)?;
        let min_contact = last.contact_vertices.iter().filter_map(|c| c.parse::<u64>().ok()).min().unwrap_or(0);
        let goal = match tag {
            "sylvian" => format!("p95 <= 1.5 ms: {}; max <= 5 ms: {}", verdict(p95, 1.5), verdict(rep.max(tag), 5.0)),
            "real_brain/interhemispheric" => format!("p95 < 16 ms: {}", verdict(p95, 16.0)),
            "real_brain/sylvian" => format!("p95 < 4 ms (fine brain): {}; < 16 ms: {}", verdict(p95, 4.0), verdict(p95, 16.0)),
            "unrefined/sylvian" => "(for comparison)".to_string(),
            "sylvian_noisy" | "sylvian_noisy_filtered" => {
                let (x, within) = (p95 / rep.p95("sylvian"), if tag.ends_with("filtered") { 2.0 } else { 4.0 });
                format!("p95 within {within}x the clean run's: {x:.2}x, {}; no frame over 50 ms: {}", verdict(round2(x), within), verdict(rep.max(tag), 50.0))
            }
            "real_brain/sylvian_wide" => {
                let met = verdict(p95, 8.0) == "met" && min_contact >= 50;
                format!("p95 < 8 ms with >= 50 contact vertices a blade: {}", if met { "met" } else { "not met" })
            }
            _ => format!("p95 < 2 ms: {}", verdict(p95, 2.0)),
        };
        let extra = match tag {
            "real_brain/sylvian" => {
                let peak = median(rep.runs(tag).iter().filter_map(|r| r.peak_mb).collect());
                format!("; whole run {:.2} s, peak {peak:.0} MB", median(rep.runs(tag).iter().map(|r| r.wall_s).collect()))
            }
            "real_brain/sylvian_wide" => format!("; {} contact vertices at the end", last.contact_vertices.join("/")),
            "sylvian" | "sylvian_noisy" | "sylvian_noisy_filtered" | "unrefined/sylvian" => {
                let substeps = rep.runs(tag).iter().map(|r| r.summary.max_substeps).max().unwrap_or(0);
                format!("; up to {substeps} sub-steps a frame; force change a frame p95 {} N", force_jumps(last))
            }
            _ => String::new(),
        };
        let _ = writeln!(out, "| replay: {}, a frame | {}{extra}; {runs_note} | {goal} | {} |", scene_words(tag), rep.rp(tag), code(&last.command));
    }
    Ok(())
}

/// Each blade's p95 frame-to-frame force change, N ("-" without blades).
pub fn force_jumps(run: &ReplayRun) -> String {
    let s: Vec<String> = run.summary.spatulas.iter().map(|s| format!("{:.4}", s.p95_force_jump_n)).collect();
    if s.is_empty() { "-".into() } else { s.join("/") }
}

/// The effects' cost, the ten-minute hold, the coarse / fine brain, and the longest frame of all.
fn effects_rows(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let rep = Replays(&r.replays);
    let runs_note = if r.info.repeat == 1 { "one run".to_string() } else { format!("median of {} runs", r.info.repeat) };
    let (none, tissue, tethers) = (rep.p95("effects/none"), rep.p95("effects/tissue"), rep.p95("effects/tethers"));
    let (tethers_x, tissue_x) = (tethers / none, tissue / none);
    let t = &rep.first("effects/tethers")?.summary;
    let bands = t.bands.map_or(0, |b| b.total);
    let rough_max = rep.max("effects/tethers_rough");
    let _ = writeln!(
        out,
        "| what the effects cost on the fine-brain Sylvian opening, alternating run by run: frame p95 without them / with relaxation and ischemia (as shipped) / with its tethers ({bands} bands, {} vessels, `sylvian_tethers.ron`) | {none:.3} / {tissue:.3} / {tethers:.3} ms: tissue over time {tissue_x:.2}x, tethers {tethers_x:.2}x; {runs_note}; the rough opening with tethers p95 {:.3} ms (max {rough_max:.3} ms) | relaxation and ischemia within 1.2x: {}; tethers within 1.3x: {}; no frame over 50 ms: {} | {} |",
        t.vessels.len(),
        rep.p95("effects/tethers_rough"),
        verdict(round2(tissue_x), 1.2),
        verdict(round2(tethers_x), 1.3),
        verdict(rough_max, 50.0),
        code(&format!("{} [--set '{PLAIN_EFFECTS}']", rep.first("effects/tissue")?.command))
    );
    hold_row(&rep, out)?;
    size_row(&rep, out)?;
    let worst = r.replays.iter().filter(|x| x.tag != "effects/tethers_rough").max_by(|a, b| a.summary.frame.max_ms.total_cmp(&b.summary.frame.max_ms));
    if let Some(w) = worst {
        let ms = w.summary.frame.max_ms;
        let _ = writeln!(
            out,
            "| longest frame of every replay above (the haptic loop reads the last answer) | {ms:.3} ms ({}) | no frame frozen > 50 ms: {} | the replays above |",
            w.tag,
            verdict(ms, 50.0)
        );
    }
    Ok(())
}

/// The effects the "without them" runs keep.
pub const PLAIN_EFFECTS: &str = "effects=[Collision, Culling, ForceOutput, ContactPressure]";

fn round2(x: f64) -> f64 {
    (x * 100.0).round() / 100.0
}

fn hold_row(rep: &Replays<'_>, out: &mut String) -> Result<(), PerfError> {
    let (c, i) = (rep.first("hold/continuous")?, rep.first("hold/intermittent")?);
    let ischemia = |run: &ReplayRun| -> Result<(f64, f64), PerfError> {
        let s = run.summary.ischemia.as_ref().ok_or_else(|| PerfError::new(Path::new(&run.tag), "its summary.json has no ischemia"))?;
        let at_risk = s.levels.get(1).ok_or_else(|| PerfError::new(Path::new(&run.tag), "its summary.json has no second risk level"))?;
        Ok((round_to(at_risk.final_area_mm2, 1), round_to(s.max_risk, 3)))
    };
    let ((c_area, c_risk), (i_area, i_risk)) = (ischemia(c)?, ischemia(i)?);
    let met = i_area < c_area || (i_area == c_area && i_risk < c_risk);
    let _ = writeln!(
        out,
        "| ten minutes held on the fine-brain Sylvian scene ({} frames): whole run; frame p95; at the end, area at risk (risk >= 1/2) and the largest risk, continuous / intermittent (5 min, 1 min rest, 5 min) | {:.2} s; p95 {:.3} ms; {c_area} / {i_area} mm2, risk {c_risk} / {i_risk}; one run each | a held frame costs next to nothing; the intermittent hold risks less: {} | {} (`_intermittent.csv`, 668) |",
        c.summary.frames,
        c.wall_s,
        rep.p95("hold/continuous"),
        if met { "met" } else { "not met" },
        code(&c.command)
    );
    Ok(())
}

/// `x` rounded to `digits` decimals, as Python's `round` prints it.
fn round_to(x: f64, digits: i32) -> f64 {
    let k = 10f64.powi(digits);
    (x * k).round() / k
}

fn size_row(rep: &Replays<'_>, out: &mut String) -> Result<(), PerfError> {
    let c = |tag: &str| -> Result<crate::sim::metrics::ComplianceSummary, PerfError> { Ok(rep.first(tag)?.summary.compliance) };
    let (coarse, fine) = (c("size/coarse")?, c("size/fine")?);
    let _ = writeln!(
        out,
        "| the same blade motion on the coarse and the fine brain (the Sylvian scene as a user writes it), working region 10 mm beyond the ROI: frame p50 coarse / fine; fine over coarse, against its rows' ratio | {:.3} / {:.3} ms; {:.2}x for {:.2}x the rows ({} / {}); with a row for every surface vertex {:.2}x for {:.2}x ({} / {}) | frame time follows the working region's rows, not the brain (docs/performance.md, \"The same motion on the coarse and the fine brain\") | {} |",
        rep.p50("size/coarse"),
        rep.p50("size/fine"),
        rep.p50("size/fine") / rep.p50("size/coarse"),
        fine.rows as f64 / coarse.rows as f64,
        coarse.rows,
        fine.rows,
        rep.p50("size/fine_all") / rep.p50("size/coarse_all"),
        fine.surface_vertices as f64 / coarse.surface_vertices as f64,
        coarse.surface_vertices,
        fine.surface_vertices,
        code("fissure replay config/real_brain/sylvian.ron --set 'fixed=[LowestPerComponent(height_mm: 10.0)]' [--set 'mesh=File(coarse)'] [--set solver.row_band_mm=None]")
    );
    let fine_wall = median(rep.of("size/fine", |r| r.wall_s));
    let fine_peak = median(rep.runs("size/fine").iter().filter_map(|r| r.peak_mb).collect());
    let coarse_p95 = rep.p95("size/coarse");
    let _ = writeln!(
        out,
        "| the same scene as a user writes it (`refine` left to `Auto`, lowest 10 mm held, no cache), replayed on the coarse brain: frame p95; on the fine brain: the whole cold replay, peak memory | coarse p95 {:.3} ms (max {:.3} ms); fine {:.2} s, {:.0} MB; median of {} runs | coarse p95 <= 2 ms: {}; fine replay <= 10 s: {}; <= 1.2 GB: {} | the commands above without `row_band_mm` |",
        coarse_p95,
        rep.max("size/coarse"),
        fine_wall,
        fine_peak,
        rep.runs("size/fine").len(),
        verdict(coarse_p95, 2.0),
        verdict(fine_wall, 10.0),
        verdict(fine_peak, 1200.0),
    );
    Ok(())
}

fn startup_rows(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let cold = build_of(r, "q15_cold")?;
    let cc = &cold.compliance;
    let _ = writeln!(
        out,
        "| fine brain (q15, 62.8k nodes) cold, f32, every column first: model + factor / compliance precompute ({} rows x {} columns, {:.0} MB) / peak memory | {:.2} s / {:.2} s / {:.0} MB | precompute < 60 s: {}; < 2 GB: {} | {} (empty DIR) |",
        cc.rows,
        cc.cols,
        cc.megabytes,
        cold.before_compliance_s,
        cc.compute_s,
        cold.peak_rss_mb,
        verdict(cc.compute_s, 60.0),
        verdict(cold.peak_rss_mb, 2048.0),
        code("startup_probe config/real_brain/interhemispheric.ron 'mesh=File(q15)' solver.compliance_storage=F32 'solver.cache_dir=Some(DIR)'")
    );
    let background = code("solver.cache_dir=None --background");
    if r.info.fast {
        let _ = writeln!(out, "| the same cold start with early start (as the window): first frame | {NOT_RUN_FAST} | first frame < 10 s | the same with {background} |");
    } else {
        let e = early_of(r, "q15_cold_background")?;
        let _ = writeln!(
            out,
            "| the same cold start with early start (as the window): first frame; slowest frame; every column final | first frame {:.2} s; slowest {:.0} ms ({} over 50 ms); columns {:.2} s; peak {:.0} MB | first frame < 10 s: {} | the same with {background} |",
            e.first_frame_s,
            e.slowest_frame_ms,
            e.frames_over_50ms,
            e.columns_final_s,
            e.peak_rss_mb,
            verdict(e.first_frame_s, 10.0)
        );
    }
    let cache = build_of(r, "q15_cache")?;
    let _ = writeln!(
        out,
        "| fine brain from the cache: whole build (of which reading the file) / peak memory | {:.2} s ({:.2} s) / {:.0} MB | reload < 1 s: {}; < 2 GB: {} | the same command again (DIR now full) |",
        cache.build_s,
        cache.compliance.load_s,
        cache.peak_rss_mb,
        verdict(cache.compliance.load_s, 1.0),
        verdict(cache.peak_rss_mb, 2048.0)
    );
    let k = early_of(r, "q15_cache_background")?;
    let _ = writeln!(
        out,
        "| fine brain from the cache with early start: first frame; slowest frame | first frame {:.2} s; slowest {:.0} ms ({} over 50 ms) | first frame < 1 s: {} | the same with {} |",
        k.first_frame_s,
        k.slowest_frame_ms,
        k.frames_over_50ms,
        verdict(k.first_frame_s, 1.0),
        code("--background")
    );
    user_startup_rows(r, out)
}

fn user_startup_rows(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let (syl_cold, syl) = (build_of(r, "sylvian_cold")?, early_of(r, "sylvian_cache_background")?);
    let sc = &syl_cold.compliance;
    let _ = writeln!(
        out,
        "| fine-brain Sylvian scene as shipped ({} rows x {} columns, {:.0} MB), from the cache with early start: first frame | first frame {:.2} s (cold build {:.2} s); peak {:.0} MB | first frame < 1 s: {} | {} |",
        sc.rows,
        sc.cols,
        sc.megabytes,
        syl.first_frame_s,
        syl_cold.build_s,
        syl.peak_rss_mb,
        verdict(syl.first_frame_s, 1.0),
        code("startup_probe config/real_brain/sylvian.ron 'solver.cache_dir=Some(DIR)' --background")
    );
    let (usr, usb) = (build_of(r, "user_sylvian_cold")?, early_of(r, "user_sylvian_background")?);
    let uc = &usr.compliance;
    let _ = writeln!(
        out,
        "| the same scene as a user writes it (no `refine`, so `Auto`; lowest 10 mm held, f64, no cache), every column first: compliance ({} rows x {} columns, {:.0} MB); whole build; peak memory | {:.2} s; {:.2} s; {:.0} MB | build < 30 s: {}; < 2 GB: {} | {} |",
        uc.rows,
        uc.cols,
        uc.megabytes,
        uc.compute_s,
        usr.build_s,
        usr.peak_rss_mb,
        verdict(usr.build_s, 30.0),
        verdict(usr.peak_rss_mb, 2048.0),
        code("startup_probe config/real_brain/sylvian.ron 'fixed=[LowestPerComponent(height_mm: 10.0)]' solver.compliance_storage=F64 solver.cache_dir=None solver.early_start=false")
    );
    let _ = writeln!(
        out,
        "| the same scene opened as the window opens it (early start): first frame; frames that waited for their columns | first frame {:.2} s; slowest {:.0} ms ({} over 50 ms); every column final {:.2} s; peak {:.0} MB | first frame <= 5 s: {}; no frame over 50 ms: {} | the same with {} |",
        usb.first_frame_s,
        usb.slowest_frame_ms,
        usb.frames_over_50ms,
        usb.columns_final_s,
        usb.peak_rss_mb,
        verdict(usb.first_frame_s, 5.0),
        if usb.frames_over_50ms == 0 { "met" } else { "not met" },
        code("solver.early_start=true --background")
    );
    Ok(())
}

/// The window's command on the page.
pub const WINDOW_COMMAND: &str = "fissure run config/sylvian.ron --exit-after 10 --size 1280x800";

fn window_row(r: &PerfRecord, out: &mut String) {
    match &r.window {
        Some([w, _]) => {
            let _ = writeln!(
                out,
                "| the window on the software renderer (Xvfb, llvmpipe on cores - 1 threads), default scene, blades held: fps; simulation step | {:.1} fps; step p50 {:.3} / p95 {:.3} ms | step p95 < 2 ms: {} | {} |",
                w.fps,
                w.step_p50_ms,
                w.step_p95_ms,
                verdict(w.step_p95_ms, 2.0),
                code(WINDOW_COMMAND)
            );
        }
        None => {
            let _ = writeln!(out, "| the window on the software renderer (Xvfb): fps; simulation step | {} | step p95 < 2 ms | {} |", window_not_run(), code(WINDOW_COMMAND));
        }
    }
}

/// Why the window was not measured.
pub fn window_not_run() -> &'static str {
    "not run: Xvfb is not installed (scripts/deps.sh installs it)"
}

/// The fem bench's command: its models.
pub fn fem_command(r: &PerfRecord) -> String {
    if r.info.fast { "cargo bench --bench fem -- paper".into() } else { "cargo bench --bench fem -- paper coarse".into() }
}

fn fem_rows(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let p = r.fem.first().ok_or_else(|| PerfError::new(Path::new("paper-12k.json"), "the fem bench wrote no figures"))?;
    let (p100, p300) = (frame_at(p, 100)?, frame_at(p, 300)?);
    let m = &p.model;
    let _ = writeln!(
        out,
        "| exact FEM solve + surface update over the working region, paper-12k, f32, 100 / 300 constrained vertices (10 / 30 new a frame) | p95 {:.2} / {:.2} ms; at 300 {:.1}x the floor of what the frame reads and factors ({:.2} ms: W's new entries, W's factor, the working region's product), {:.1}x W's alone ({:.2} ms) | p95 < 3 ms at 300: {}; <= 2x the floor: {} | {} |",
        p100.p95_ms,
        p300.p95_ms,
        need(p300.p95_over_two_floors, m, "p95 over both floors")?,
        need(p300.two_floors_ms, m, "floors")?,
        need(p300.p95_over_floor, m, "p95 over the floor")?,
        need(p300.floor_ms, m, "floor")?,
        verdict(p300.p95_ms, 3.0),
        at_most(round_to(need(p300.p95_over_two_floors, m, "p95 over both floors")?, 1), 2.0),
        code(&fem_command(r))
    );
    let coarse = r.fem.get(1);
    match coarse {
        Some(c) => {
            let (c100, c300) = (frame_at(c, 100)?, frame_at(c, 300)?);
            let m = &c.model;
            let two_x = need(c300.p95_over_two_floors, m, "p95 over both floors")?;
            let _ = writeln!(
                out,
                "| the same on the coarse real brain (hemispheres stored apart) | p95 {:.2} / {:.2} ms; at 300 {two_x:.1}x the floor ({:.2} ms), {:.1}x W's alone ({:.2} ms) | <= 2x the floor: {} | the same |",
                c100.p95_ms,
                c300.p95_ms,
                need(c300.two_floors_ms, m, "floors")?,
                need(c300.p95_over_floor, m, "p95 over the floor")?,
                need(c300.floor_ms, m, "floor")?,
                at_most(round_to(two_x, 1), 2.0)
            );
        }
        None => {
            let _ = writeln!(out, "| the same on the coarse real brain | {NOT_RUN_FAST} | <= 2x the floor | the same |");
        }
    }
    fem_precompute_rows(p, coarse, out)?;
    audit_row(r, out);
    Ok(())
}

pub fn precompute(f: &FemFigures) -> Result<&super::reports::CompliancePrecompute, PerfError> {
    f.compliance.as_ref().ok_or_else(|| PerfError::new(Path::new(&format!("{}.json", f.model)), "no compliance figures"))
}

/// AMD's and METIS's entries of L, M.
pub fn orderings(f: &FemFigures) -> Result<(&super::reports::OrderingFigures, &super::reports::OrderingFigures), PerfError> {
    match &f.orderings[..] {
        [amd, nd, ..] => Ok((amd, nd)),
        _ => Err(PerfError::new(Path::new(&format!("{}.json", f.model)), "not two orderings (AMD, METIS)")),
    }
}

pub fn errors(f: &FemFigures) -> Result<&super::reports::ErrorFigures, PerfError> {
    f.error_vs_f64.as_ref().ok_or_else(|| PerfError::new(Path::new(&format!("{}.json", f.model)), "no f32 against f64 error"))
}

fn fem_precompute_rows(p: &FemFigures, coarse: Option<&FemFigures>, out: &mut String) -> Result<(), PerfError> {
    let pc = precompute(p)?;
    let _ = writeln!(
        out,
        "| compliance precompute / reload / peak memory (f32, 2 threads), paper-12k | {:.2} s / {:.3} s / {:.0} MB | < 60 s: {}; < 1 s: {}; < 2 GB: {} | the same |",
        pc.precompute_s,
        pc.reload_s,
        p.peak_rss_mb,
        verdict(pc.precompute_s, 60.0),
        verdict(pc.reload_s, 1.0),
        verdict(p.peak_rss_mb, 2048.0)
    );
    let (pa, pn) = orderings(p)?;
    let pe = errors(p)?;
    let Some(c) = coarse else {
        let _ = writeln!(out, "| the same, coarse real brain | {NOT_RUN_FAST} | < 60 s; < 1 s; < 2 GB | the same |");
        let cmd = code("cargo bench --bench fem -- paper");
        let _ = writeln!(out, "| fill-reducing ordering: entries of L stored, AMD -> METIS nested dissection | paper-12k {:.2} -> {:.2} M | the kept ordering (METIS) has fewer | {cmd} |", pa.nnz_l_millions, pn.nnz_l_millions);
        let _ = writeln!(
            out,
            "| f32 compliance against f64, 300 constrained: relative displacement / reaction error | paper-12k {:.2e} / {:.2e} | < 1e-5: {} | {cmd} |",
            pe.displacement,
            pe.reaction,
            verdict(pe.displacement, 1e-5)
        );
        return Ok(());
    };
    let cc = precompute(c)?;
    let _ = writeln!(
        out,
        "| the same, coarse real brain | {:.2} s / {:.3} s / {:.0} MB | < 60 s: {}; < 1 s: {}; < 2 GB: {} | the same |",
        cc.precompute_s,
        cc.reload_s,
        c.peak_rss_mb,
        verdict(cc.precompute_s, 60.0),
        verdict(cc.reload_s, 1.0),
        verdict(c.peak_rss_mb, 2048.0)
    );
    let (ca, cn) = orderings(c)?;
    let _ = writeln!(
        out,
        "| fill-reducing ordering: entries of L stored, AMD -> METIS nested dissection | paper-12k {:.2} -> {:.2} M; coarse brain {:.2} -> {:.2} M | the kept ordering (METIS) has fewer | the same (lines \"ordering\") |",
        pa.nnz_l_millions, pn.nnz_l_millions, ca.nnz_l_millions, cn.nnz_l_millions
    );
    let ce = errors(c)?;
    let _ = writeln!(
        out,
        "| f32 compliance against f64, 300 constrained: relative displacement / reaction error | paper-12k {:.2e} / {:.2e}; coarse brain {:.2e} / {:.2e} | < 1e-5: {} | the same |",
        pe.displacement,
        pe.reaction,
        ce.displacement,
        ce.reaction,
        verdict(pe.displacement.max(ce.displacement), 1e-5)
    );
    Ok(())
}

/// Each switch's gains over sequences and models, in the audit's order: (switch, lowest, highest).
pub fn audit_ranges(r: &PerfRecord) -> Vec<(String, f64, f64)> {
    let mut ranges: Vec<(String, f64, f64)> = Vec::new();
    for bar in r.audit.iter().flat_map(|(_, bars)| bars) {
        let g = round_to(bar.gain(), 2);
        match ranges.iter_mut().find(|(s, _, _)| *s == bar.switch) {
            Some((_, lo, hi)) => (*lo, *hi) = (lo.min(g), hi.max(g)),
            None => ranges.push((bar.switch.clone(), g, g)),
        }
    }
    ranges
}

fn audit_row(r: &PerfRecord, out: &mut String) {
    let cmd = code("cargo bench --bench fem -- audit paper coarse");
    if r.info.fast {
        let _ = writeln!(out, "| what each per-frame optimisation of the exact solve buys | {NOT_RUN_FAST} | each kept one faster where it acts | {cmd} |");
        return;
    }
    let ranges = audit_ranges(r);
    let gains: Vec<String> =
        ranges.iter().map(|(s, lo, hi)| if lo == hi { format!("{s} {lo:.2}x") } else { format!("{s} {lo:.2}-{hi:.2}x") }).collect();
    let worst = ranges.iter().map(|(_, lo, _)| *lo).fold(f64::INFINITY, f64::min);
    let _ = writeln!(
        out,
        "| what each per-frame optimisation of the exact solve buys: the phase it touches, with it against without, paper-12k and coarse brain (medians of three alternating rounds) | {} | each kept one faster where it acts (slowest case {worst:.2}x) | {cmd} |",
        gains.join("; ")
    );
}

fn cholmod_row(r: &PerfRecord, out: &mut String) {
    let goal = "entries within 10 %; factor and solve <= 1.0x CHOLMOD's time";
    let cmd = code("bash scripts/cholmod_compare.sh");
    match &r.cholmod_log {
        Some(log) => {
            let ratio = |mesh: &str, field: super::cholmod::Field| super::cholmod::ratio(log, mesh, "metis", field);
            use super::cholmod::Field::{Exact, Numeric, Solve};
            let _ = writeln!(
                out,
                "| our sparse Cholesky against CHOLMOD (METIS, one thread, median of rounds), coarse / fine brain: entries of L; numeric factor; 96-column solve | {:.3}x / {:.3}x; {:.3}x / {:.3}x; {:.3}x / {:.3}x | {goal} | {cmd} |",
                ratio("brain_pial_coarse", Exact),
                ratio("brain_pial_q15", Exact),
                ratio("brain_pial_coarse", Numeric),
                ratio("brain_pial_q15", Numeric),
                ratio("brain_pial_coarse", Solve),
                ratio("brain_pial_q15", Solve)
            );
        }
        None => {
            let _ = writeln!(out, "| our sparse Cholesky against CHOLMOD: entries of L; numeric factor; solve | {} | {goal} | {cmd} |", cholmod_not_run(r));
        }
    }
}

/// Why CHOLMOD was not compared.
pub fn cholmod_not_run(r: &PerfRecord) -> &'static str {
    if r.info.fast { NOT_RUN_FAST } else { "not run: CHOLMOD is not installed (apt-get install libsuitesparse-dev libopenblas0-pthread, then run this script again)" }
}
