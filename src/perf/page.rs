//! `docs/performance.md` rendered from a [`PerfRecord`]: the run's machine, date, commit and command, the
//! summary table between its markers (copied into the README), then each measure's section. The real-GPU
//! section cannot be measured by the script: it is carried through from the page as it was.

use super::record::{FEM_MODELS, PerfError, PerfRecord};
use super::summary::{
    NOT_RUN_FAST, Replays, WINDOW_COMMAND, build_of, cholmod_not_run, early_of, errors, fem_command, frame_at, need, orderings, precompute, summary_rows, window_not_run,
};
use std::fmt::Write;

pub const SUMMARY_BEGIN: &str = "<!-- performance summary: begin -->";
pub const SUMMARY_END: &str = "<!-- performance summary: end -->";
pub const GPU_BEGIN: &str = "<!-- gpu table: begin -->";
pub const GPU_END: &str = "<!-- gpu table: end -->";

/// The fine brain's mesh as the startup probe's runs set it.
pub const Q15_MESH: &str = "mesh=File(path: \"../../assets/brain/brain_pial_q15.msh.gz\", units: Millimetres)";
/// The coarse brain's, for the same motion on both brains.
pub const COARSE_MESH: &str = "mesh=File(path: \"../../assets/brain/brain_pial_coarse.msh.gz\", units: Millimetres)";

/// The lines strictly between two marker lines of `text` (None without both markers).
pub fn between_markers<'a>(text: &'a str, begin: &str, end: &str) -> Option<&'a str> {
    let start = text.find(&format!("{begin}\n"))? + begin.len() + 1;
    let stop = start + text[start..].find(&format!("{end}\n")).or_else(|| text[start..].strip_suffix(end).map(str::len))?;
    Some(&text[start..stop])
}

/// `text` with what is between the markers replaced by `inner` (each marker on a line of its own, once).
pub fn replace_between(text: &str, begin: &str, end: &str, inner: &str) -> Result<String, String> {
    let old = between_markers(text, begin, end).ok_or_else(|| format!("no `{begin}` ... `{end}` lines"))?;
    let start = old.as_ptr() as usize - text.as_ptr() as usize;
    Ok(format!("{}{inner}{}", &text[..start], &text[start + old.len()..]))
}

/// The real-GPU section to carry: the previous page's, markers included, or a line saying how to measure it.
pub fn gpu_section(previous_page: Option<&str>) -> String {
    match previous_page.and_then(|p| between_markers(p, GPU_BEGIN, GPU_END)) {
        Some(inner) => format!("{GPU_BEGIN}\n{inner}{GPU_END}\n"),
        None => format!(
            "{GPU_BEGIN}\n\nNot measured yet: run `bash scripts/gpu_devkit.sh`, then `REPLAY=1 SYLVIAN=1 bash .devkit/run.sh` on a machine with a GPU, and put its table here with that machine, date and commit.\n\n{GPU_END}\n"
        ),
    }
}

/// The whole page.
pub fn render(r: &PerfRecord, gpu_section: &str) -> Result<String, PerfError> {
    let mut out = String::new();
    header(r, &mut out);
    let _ = write!(out, "## Summary\n\nEach goal is the design's bar for the measure; \"met\" compares today's figure with it.\n\n{SUMMARY_BEGIN}\n{}{SUMMARY_END}\n\n", summary_rows(r)?);
    collision_section(r, &mut out);
    replay_sections(r, &mut out)?;
    startup_section(r, &mut out)?;
    window_section(r, &mut out);
    fem_section(r, &mut out)?;
    audit_section(r, &mut out);
    cholmod_section(r, &mut out);
    let _ = write!(
        out,
        "## The collision stage on a real GPU\n\nOnly a machine with a GPU can measure this (`bash scripts/gpu_devkit.sh` packs\nwhat it needs); `scripts/perf_docs.sh` keeps this section as it finds it.\n\n{gpu_section}"
    );
    Ok(out)
}

fn header(r: &PerfRecord, out: &mut String) {
    let i = &r.info;
    let _ = write!(
        out,
        "# Performance

Every figure on this page except the real-GPU table comes from one run of
`scripts/perf_docs.sh` (release build): the machine, date and commit are
below, and each row names its command (`fissure` is `target/release/fissure`,
`startup_probe` is `cargo run --release --example startup_probe --`). The raw
output of every measure is in `target/perf/` after a run, and the page is
rendered from it by `examples/perf_page.rs`. The machine is shared
and a replay's p95 moves by 10-30 % from one hour to the next: compare figures
measured in the same run.

- Machine: {}
- Date: {}
- Commit: {}
- Command: `{}`

",
        i.machine, i.date, i.commit, i.command
    );
}

fn collision_section(r: &PerfRecord, out: &mut String) {
    let _ = writeln!(
        out,
        "## The collision stage per backend

`fissure bench collision --frames 30` ({} s). Two blades advance into
the surface and the surface deforms to each frame's targets, so the later frames
cast through contact. All backends of a case give the same answers (the last
column hashes every frame's output; the command fails otherwise). `bvh` runs on
its default 2 threads (a cast is split over them only when the last one took
20,000 traversal steps or more), `bvh xN` on every core; `gpu` sends the lines its
candidates cannot decide to the CPU (column \"lines to CPU\"); `reference` is the
brute force. \"cast / rest of stage\" splits a frame into the backend's own part
(surface update and cast) and the part every backend shares (rays, candidate
pairs, culling, targets). The GPU's own time comes from timestamp queries. Without
a GPU the `gpu` rows run on Mesa's software Vulkan driver (llvmpipe), which shares
the CPU cores with everything else.
",
        r.seconds_of("collision")
    );
    out.push_str(r.collision_table.trim_end());
    out.push('\n');
    for note in &r.collision.notes {
        let _ = write!(out, "\nNote: {note}\n");
    }
    out.push('\n');
}

fn replay_sections(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let _ = write!(
        out,
        "## Replays of the shipped scenes

`fissure replay SCENARIO --set solver.cache_dir=None` for every scene in `config/`
and `config/real_brain/` with a trajectory, {} run(s) each ({} s in all); the
wide press adds `--trajectory assets/trajectories/real_brain_sylvian_wide.csv --set duration_s=4.5`.
(`config/study_fissure.ron` has no trajectory: `fissure study` moves its blade.)
Frame times come from `summary.json` (the replay's own clock, the precompute
excluded); the whole run and its peak memory from `/usr/bin/time` (the
precompute included); contact vertices (the surface vertices carrying a blade's
force) and forces from the last row of `metrics.csv`, one figure a blade. The
final state hashes every surface displacement bit: runs of the same build agree.

| scene | run | frames | frame p50 / p95 / max ms | stages p50 / p95 ms | whole run s | peak MB | contact vertices at the end | force at the end N | integrity | final state |
|---|---:|---:|---|---|---:|---:|---|---|---|---|
",
        r.info.repeat,
        r.seconds_of("replays")
    );
    for run in &r.replays {
        let s = &run.summary;
        let stages: Vec<String> = s.stages.iter().map(|(id, p)| format!("{} {:.3} / {:.3}", id.name(), p.p50_ms, p.p95_ms)).collect();
        let list = |v: Vec<String>| if v.is_empty() { "-".to_string() } else { v.join("/") };
        let _ = writeln!(
            out,
            "| {} | {} | {} | {:.3} / {:.3} / {:.3} | {} | {:.2} | {} | {} | {} | {} | {} |",
            run.tag,
            run.run,
            s.frames,
            s.frame.p50_ms,
            s.frame.p95_ms,
            s.frame.max_ms,
            stages.join("; "),
            run.wall_s,
            run.peak_mb.map_or("n/a".to_string(), |m| format!("{m:.0}")),
            list(run.contact_vertices.clone()),
            list(run.forces_n.iter().map(|f| format!("{f:.3}")).collect()),
            if s.integrity.passed { "pass" } else { "FAIL" },
            s.final_state_hash.get(..8).unwrap_or(&s.final_state_hash)
        );
    }
    let rep = Replays(&r.replays);
    let _ = write!(
        out,
        "
## The same motion on the coarse and the fine brain

The fine-brain Sylvian scene as a user writes it (`--set 'fixed=[LowestPerComponent(height_mm: 10.0)]'`: no `refine`, so `Auto`), its
motion replayed on the fine brain (q15) and on the coarse one (`--set '{COARSE_MESH}'`),
each with the working region's rows (the default `solver.row_band_mm`, 10 mm
beyond the region of interest) and with a row for every surface vertex
(`--set solver.row_band_mm=None`); {} run(s) each, medians. The region
is the same in millimetres on both brains; the fine brain has more vertices in it, except where `Auto` refined both to the same edge.

| brain | rows x columns, working region | frame p50 / p95 ms | rows, every surface vertex | frame p50 / p95 ms |
|---|---|---|---|---|
",
        r.info.repeat
    );
    for brain in ["coarse", "fine"] {
        let (band, all) = (format!("size/{brain}"), format!("size/{brain}_all"));
        let (c, a) = (rep.first(&band)?.summary.compliance, rep.first(&all)?.summary.compliance);
        let _ = writeln!(
            out,
            "| {brain} | {} x {} | {:.3} / {:.3} | {} | {:.3} / {:.3} |",
            c.rows,
            c.columns,
            rep.p50(&band),
            rep.p95(&band),
            a.rows,
            rep.p50(&all),
            rep.p95(&all)
        );
    }
    out.push('\n');
    Ok(())
}

fn startup_section(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let _ = write!(
        out,
        "## Startup

`examples/startup_probe.rs` ({} s in all): a scene's build (mesh, model,
factor, compliance) and what it keeps; with `--background` the build returns
after the factor and the compliance columns fill in the background while the
scene's motion runs, as the window does with `solver.early_start` (the shipped
scenes set it). Times are from the process's start. The fine brain is the
inter-hemispheric scene on q15 (`{Q15_MESH}`),
f32 storage. Each cold run starts with an empty cache folder or none.

| run | command (after `startup_probe`) | figures |
|---|---|---|
",
        r.seconds_of("startup")
    );
    let cold = build_of(r, "q15_cold")?;
    let c = &cold.compliance;
    let _ = writeln!(
        out,
        "| fine brain, cold | `config/real_brain/interhemispheric.ron 'mesh=File(q15)' solver.compliance_storage=F32 'solver.cache_dir=Some(DIR)'` | model + factor {:.2} s; compliance {} rows x {} columns, {:.0} MB, computed in {:.2} s; build done {:.2} s (the cache file written); peak {:.0} MB |",
        cold.before_compliance_s, c.rows, c.cols, c.megabytes, c.compute_s, cold.build_s, cold.peak_rss_mb
    );
    let background = "the same with `solver.cache_dir=None --background`";
    if r.info.fast {
        let _ = writeln!(out, "| fine brain, cold, early start | {background} | {NOT_RUN_FAST} |");
    } else {
        let e = early_of(r, "q15_cold_background")?;
        let _ = writeln!(
            out,
            "| fine brain, cold, early start | {background} | first frame {:.2} s; {} frames done {:.2} s; slowest frame {:.0} ms, {} over 50 ms (those waiting for their columns); every column final {:.2} s; peak {:.0} MB |",
            e.first_frame_s, e.frames, e.motion_done_s, e.slowest_frame_ms, e.frames_over_50ms, e.columns_final_s, e.peak_rss_mb
        );
    }
    let k = build_of(r, "q15_cache")?;
    let _ = writeln!(
        out,
        "| fine brain from the cache | the first command again | build done {:.2} s, of which reading the file {:.2} s; peak {:.0} MB |",
        k.build_s, k.compliance.load_s, k.peak_rss_mb
    );
    let e = early_of(r, "q15_cache_background")?;
    let _ = writeln!(
        out,
        "| fine brain from the cache, early start | the same with `--background` | first frame {:.2} s; {} frames done {:.2} s; slowest frame {:.0} ms, {} over 50 ms; every column read {:.2} s; peak {:.0} MB |",
        e.first_frame_s, e.frames, e.motion_done_s, e.slowest_frame_ms, e.frames_over_50ms, e.columns_final_s, e.peak_rss_mb
    );
    user_startup_section(r, out)
}

fn user_startup_section(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let s = build_of(r, "sylvian_cold")?;
    let _ = writeln!(
        out,
        "| fine-brain Sylvian scene as shipped, cold | `config/real_brain/sylvian.ron 'solver.cache_dir=Some(DIR)'` | refined mesh, {} rows x {} columns, {:.0} MB; build done {:.2} s; peak {:.0} MB |",
        s.compliance.rows, s.compliance.cols, s.compliance.megabytes, s.build_s, s.peak_rss_mb
    );
    let e = early_of(r, "sylvian_cache_background")?;
    let _ = writeln!(
        out,
        "| the same from the cache, early start | the same with `--background` | first frame {:.2} s; slowest frame {:.0} ms, {} over 50 ms; every column read {:.2} s; peak {:.0} MB |",
        e.first_frame_s, e.slowest_frame_ms, e.frames_over_50ms, e.columns_final_s, e.peak_rss_mb
    );
    let u = build_of(r, "user_sylvian_cold")?;
    let uc = &u.compliance;
    let _ = writeln!(
        out,
        "| the same scene as a user writes it, cold | `config/real_brain/sylvian.ron 'fixed=[LowestPerComponent(height_mm: 10.0)]' solver.compliance_storage=F64 solver.cache_dir=None solver.early_start=false` | model + factor {:.2} s; compliance {} rows x {} columns, {:.0} MB, computed in {:.2} s; build done {:.2} s; peak {:.0} MB |",
        u.before_compliance_s, uc.rows, uc.cols, uc.megabytes, uc.compute_s, u.build_s, u.peak_rss_mb
    );
    let b = early_of(r, "user_sylvian_background")?;
    let _ = writeln!(
        out,
        "| the same scene as a user writes it, cold, early start | the same with `solver.early_start=true --background` | first frame {:.2} s; {} frames done {:.2} s; slowest frame {:.0} ms, {} over 50 ms (those waiting for their columns); every column final {:.2} s; peak {:.0} MB |\n",
        b.first_frame_s, b.frames, b.motion_done_s, b.slowest_frame_ms, b.frames_over_50ms, b.columns_final_s, b.peak_rss_mb
    );
    Ok(())
}

fn window_section(r: &PerfRecord, out: &mut String) {
    out.push_str(
        "## The window's frame time

The simulation runs on its own thread; the window draws what it last finished.
On a machine without a GPU, Mesa's llvmpipe draws the window on the CPU and
takes cores from the simulation, so `fissure run` and the bare `fissure` set
`LP_NUM_THREADS` to the number of cores minus one unless it is already set (a
real GPU's driver never reads it): the drawing slows, the simulation keeps its pace.

",
    );
    let Some([default, all]) = &r.window else {
        let _ = write!(out, "The window was {}.\n\n", window_not_run());
        return;
    };
    let adapter = |a: &str| if a.is_empty() { "not named".to_string() } else { a.to_string() };
    let _ = write!(
        out,
        "Under Xvfb, `{WINDOW_COMMAND}`
with the blades held, from a filled compliance cache (a first run, not counted, fills it):

| llvmpipe threads | window fps | simulation step p50 / p95 ms | adapter |
|---|---:|---|---|
| cores - 1 (what `fissure run` sets) | {:.1} | {:.3} / {:.3} | {} |
| {} (`LP_NUM_THREADS={}`: every core) | {:.1} | {:.3} / {:.3} | {} |

",
        default.fps,
        default.step_p50_ms,
        default.step_p95_ms,
        adapter(&default.adapter),
        r.info.cores,
        r.info.cores,
        all.fps,
        all.step_p50_ms,
        all.step_p95_ms,
        adapter(&all.adapter)
    );
}

fn fem_section(r: &PerfRecord, out: &mut String) -> Result<(), PerfError> {
    let _ = write!(
        out,
        "## The exact FEM solve

`{}` ({} s with the audit below): for each model, the
scene-independent solver on a window of constrained vertices sliding over the
surface (100 / 300 constrained, 10 / 30 new a frame), f32 compliance reloaded
from the cache, its rows the working region's (the surface within the default
`solver.row_band_mm` of the ROI, as a scene stores them). The floors are measured
in the same run: W's floor is reading W's new entries plus the cheapest dense
Cholesky of W; the product floor is reading every stored row of the constrained
columns once at this machine's streaming rate; what the frame reads and factors
is their sum.

| | {} | {} |
|---|---|---|
",
        fem_command(r),
        r.seconds_of("fem"),
        FEM_MODELS[0].1,
        FEM_MODELS[1].1
    );
    let mut rows: Vec<(&str, Vec<String>)> = [
        "nodes",
        "model + factor (total)",
        "entries of L stored (counted exactly), AMD -> METIS",
        "compliance (f32): size, precompute, reload",
        "frame p50 / p95, 100 constrained",
        "frame p50 / p95, 300 constrained",
        "at 300: the floor; frame p95 against it",
        "at 300: the surface product against its floor (streaming at this rate)",
        "at 300: frame p95 against both floors",
        "f32 against f64 at 300: displacement / reaction error",
        "peak resident memory (the process so far)",
    ]
    .into_iter()
    .map(|name| (name, Vec::new()))
    .collect();
    for (k, f) in r.fem.iter().enumerate() {
        for (row, cell) in rows.iter_mut().zip(fem_column(f, k == 0)?) {
            row.1.push(cell);
        }
    }
    for (name, mut cells) in rows {
        if cells.len() < 2 {
            cells.push(NOT_RUN_FAST.to_string());
        }
        let _ = writeln!(out, "| {name} | {} |", cells.join(" | "));
    }
    out.push_str(
        "
How the frame grows with the contact set (the bench writes the plot and its CSV
to `target/fem-bench-cache/sweep/`): the surface product grows with the
constrained vertices, the W factor with their cube.

![frame time against constrained vertices](images/fem_constrained_sweep.png)

",
    );
    Ok(())
}

/// One model's column of the fem table (the first column's cells say more).
fn fem_column(f: &super::reports::FemFigures, first: bool) -> Result<Vec<String>, PerfError> {
    let m = &f.model;
    let (c, (amd, nd), e) = (precompute(f)?, orderings(f)?, errors(f)?);
    let (f100, f300) = (frame_at(f, 100)?, frame_at(f, 300)?);
    let solve = need(nd.solve_over_amd, m, "METIS's solve over AMD's")?;
    let orderings = format!("{:.2} ({:.2}) -> {:.2} ({:.2}) M; ", amd.nnz_l_millions, amd.exact_nnz_l_millions, nd.nnz_l_millions, nd.exact_nnz_l_millions);
    Ok(vec![
        f.nodes.to_string(),
        format!("{:.3} s", f.factor_total_s),
        if first { format!("{orderings}METIS's 96-column solve {solve:.2}x AMD's") } else { format!("{orderings}{solve:.2}x") },
        format!("{} x {}, {:.0} MB; {:.2} s; {:.3} s", c.rows, c.cols, c.megabytes, c.precompute_s, c.reload_s),
        format!("{:.2} / {:.2} ms", f100.p50_ms, f100.p95_ms),
        format!("{:.2} / {:.2} ms", f300.p50_ms, f300.p95_ms),
        format!("{:.2} ms; {:.1}x", need(f300.floor_ms, m, "floor")?, need(f300.p95_over_floor, m, "p95 over the floor")?),
        format!(
            "{:.2} ms against {:.2} ms ({:.1} GB/s)",
            f300.product_ms,
            need(f300.product_floor_ms, m, "product floor")?,
            need(f300.stream_gb_s, m, "streaming rate")?
        ),
        format!("{:.1}x ({:.2} ms)", need(f300.p95_over_two_floors, m, "p95 over both floors")?, need(f300.two_floors_ms, m, "floors")?),
        format!("{:.2e} / {:.2e}", e.displacement, e.reaction),
        format!("{:.0} MB", f.peak_rss_mb),
    ])
}

fn audit_section(r: &PerfRecord, out: &mut String) {
    out.push_str("## What each per-frame optimisation buys\n\n");
    if r.info.fast {
        let _ = write!(out, "{NOT_RUN_FAST}.\n\n");
        return;
    }
    out.push_str(
        "`cargo bench --bench fem -- audit paper coarse`: each optimisation that
`fem::tuning` can switch off (`FISSURE_FEM_OFF=name`), on and off in the same
run, alternating, three rounds (the medians), on 300 constrained vertices held,
growing by 30 a frame, and sliding by 30 a frame; the phase it touches, on -> off
(the one 96-column solve: the best of three each).
The scene-level switches and huge pages are measured by `bash scripts/fem_audit.sh`;
docs/design-notes.md says why each optimisation is kept.

| model | optimisation | frames | phase it touches | on -> off ms | faster with it | frame p95 on -> off ms |
|---|---|---|---|---|---:|---|
",
    );
    for (model, bars) in &r.audit {
        for b in bars {
            let p95 = match (b.p95_on, b.p95_off) {
                (Some(on), Some(off)) => format!("{on:.2} -> {off:.2}"),
                _ => "-".to_string(),
            };
            let _ = writeln!(out, "| {model} | {} | {} | {} | {:.2} -> {:.2} | {:.2}x | {p95} |", b.switch, b.sequence, b.phase, b.on, b.off, b.gain());
        }
    }
    out.push_str(
        "
![what each fem optimisation buys, paper-12k](images/fem_audit_paper12k.png)
![what each fem optimisation buys, coarse brain](images/fem_audit_coarse_brain.png)

",
    );
}

fn cholmod_section(r: &PerfRecord, out: &mut String) {
    out.push_str("## Our sparse Cholesky beside CHOLMOD\n\n");
    let Some(log) = &r.cholmod_log else {
        let _ = write!(out, "`bash scripts/cholmod_compare.sh`: {}.\n\n", cholmod_not_run(r));
        return;
    };
    let _ = write!(
        out,
        "`bash scripts/cholmod_compare.sh` ({} s): the stiffness K_FF of each real
brain factored by fissure (`examples/factor_compare.rs`) and by CHOLMOD, each
with METIS and with AMD, one thread, best of 3 a round, rounds alternating.
Medians over the rounds of ours / CHOLMOD's:

| mesh | ordering | entries of L (exact) | numeric factor | 96-column solve |
|---|---|---:|---:|---:|
",
        r.seconds_of("cholmod")
    );
    use super::cholmod::{Field, ratio};
    for mesh in ["brain_pial_coarse", "brain_pial_q15"] {
        for ord in ["metis", "amd"] {
            let _ = writeln!(
                out,
                "| {mesh} | {ord} | {:.3}x | {:.3}x | {:.3}x |",
                ratio(log, mesh, ord, Field::Exact),
                ratio(log, mesh, ord, Field::Numeric),
                ratio(log, mesh, ord, Field::Solve)
            );
        }
    }
    let _ = write!(out, "\n```text\n{}\n```\n\n", log.trim_end());
}
