//! The performance page rendered from a recorded run (`tests/fixtures/perf_record/`: the JSON each measuring
//! program wrote, the replays' `summary.json` and the last row of their `metrics.csv`, one run a scene): every
//! figure of the summary is there and is the recorded one, the README gets the same summary, the real-GPU
//! section is carried through, and a missing or renamed figure stops the rendering naming its file with
//! nothing written.

use fissure::perf::{RunInfo, write_page};
use std::path::{Path, PathBuf};

const FIXTURE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fixtures/perf_record");

fn info() -> RunInfo {
    RunInfo {
        machine: "a test machine, 2 cores, 4.0 GiB RAM".into(),
        date: "2026-11-29 21:09 UTC".into(),
        commit: "abc1234".into(),
        command: "scripts/perf_docs.sh".into(),
        fast: false,
        repeat: 1,
        no_window: false,
        no_cholmod: true,
        cores: 2,
    }
}

fn copy_dir(from: &Path, to: &Path) {
    std::fs::create_dir_all(to).unwrap();
    for entry in std::fs::read_dir(from).unwrap() {
        let entry = entry.unwrap();
        let target = to.join(entry.file_name());
        if entry.file_type().unwrap().is_dir() {
            copy_dir(&entry.path(), &target);
        } else {
            std::fs::copy(entry.path(), &target).unwrap();
        }
    }
}

/// A copy of the fixture, a README with the summary markers and a page holding a real-GPU section to carry.
struct Run {
    _dir: tempfile::TempDir,
    record: PathBuf,
    page: PathBuf,
    readme: PathBuf,
}

const OLD_PAGE: &str = "# Performance\n\nold\n\n<!-- gpu table: begin -->\nMachine: a GPU, measured by hand.\n<!-- gpu table: end -->\n";
const OLD_README: &str = "# fissure\n\nfront\n\n<!-- performance summary: begin -->\n| old |\n<!-- performance summary: end -->\n\nback\n";

fn setup() -> Run {
    let dir = tempfile::tempdir().unwrap();
    let record = dir.path().join("perf");
    copy_dir(Path::new(FIXTURE), &record);
    let (page, readme) = (dir.path().join("performance.md"), dir.path().join("README.md"));
    std::fs::write(&page, OLD_PAGE).unwrap();
    std::fs::write(&readme, OLD_README).unwrap();
    Run { _dir: dir, record, page, readme }
}

impl Run {
    fn render(&self, info: RunInfo) -> Result<(), fissure::perf::PerfError> {
        write_page(&self.record, &self.record.join("fem"), info, &self.page, &self.readme)
    }
    fn page(&self) -> String {
        std::fs::read_to_string(&self.page).unwrap()
    }
}

fn summary(text: &str) -> &str {
    fissure::perf::page::between_markers(text, fissure::perf::page::SUMMARY_BEGIN, fissure::perf::page::SUMMARY_END).expect("a summary block")
}

#[test]
fn the_page_carries_every_recorded_figure_and_the_readme_its_summary() {
    let run = setup();
    run.render(info()).unwrap_or_else(|e| panic!("{e}"));
    let page = run.page();
    let rows = summary(&page);
    assert!(rows.lines().count() > 30, "{rows}");
    for word in ["n/a", "NaN", "nan", "inf", "not measured", "| |"] {
        assert!(!rows.contains(word), "the summary says {word:?}:\n{rows}");
    }
    // Figures as the programs recorded them (the default scene's summary.json, the collision bench's
    // paper-12k 500 bvh row, the cold fine-brain build, the window's report, the fem bench's paper-12k).
    for figure in [
        "| replay: default scene: paper-12k refined under the blades (refine: Auto), two spatulas, skull spheres, a frame | p50 0.877 / p95 1.650 ms (max 4.442 ms); up to 2 sub-steps a frame; force change a frame p95 0.0007/0.0007 N; one run |",
        "| p50 1.777 / p95 2.300 ms | under 1 ms, refit included: not met (p50) |",
        "| 3.21 s / 28.84 s / 1143 MB | precompute < 60 s: met; < 2 GB: met |",
        "| 3.7 fps; step p50 0.774 / p95 2.354 ms | step p95 < 2 ms: not met |",
        "paper-12k 6.37e-7 / 5.97e-10; coarse brain 3.62e-7 / 1.11e-9 | < 1e-5: met",
        "(18 bands, 4 vessels, `sylvian_tethers.ron`)",
        "`fissure replay config/real_brain/sylvian.ron --set solver.cache_dir=None --trajectory assets/trajectories/real_brain_sylvian_wide.csv --set duration_s=4.5`",
    ] {
        assert!(rows.contains(figure), "the summary lacks {figure:?}:\n{rows}");
    }
    for line in ["- Machine: a test machine, 2 cores, 4.0 GiB RAM", "- Commit: abc1234", "- Command: `scripts/perf_docs.sh`"] {
        assert!(page.lines().any(|l| l == line), "the header lacks {line:?}");
    }
    // Every replay run has its row in the replays' table, with its final state's first eight hex digits.
    let manifest = std::fs::read_to_string(run.record.join("replays.tsv")).unwrap();
    for line in manifest.lines() {
        let tag = line.split('\t').next().unwrap();
        assert!(page.lines().any(|l| l.starts_with(&format!("| {tag} | 1 | "))), "no row for {tag}");
    }
    assert!(page.contains("| paper-12k | w-factor-reuse | held | factor+solve W | 0.89 -> 17.28 | 19.42x | 7.51 -> 26.09 |"), "{page}");
    assert!(page.contains("<!-- gpu table: begin -->\nMachine: a GPU, measured by hand.\n<!-- gpu table: end -->\n"), "the real-GPU section was not carried");
    let readme = std::fs::read_to_string(&run.readme).unwrap();
    assert_eq!(summary(&readme), rows, "the README's summary is the page's");
    assert!(readme.starts_with("# fissure\n\nfront\n\n") && readme.ends_with("\n\nback\n"), "the rest of the README is kept:\n{readme}");
}

#[test]
fn a_missing_or_renamed_figure_stops_the_page_naming_its_file_and_writes_nothing() {
    let run = setup();
    std::fs::remove_file(run.record.join("startup/q15_cache.json")).unwrap();
    let e = run.render(info()).expect_err("a missing report");
    assert!(e.to_string().contains("q15_cache.json"), "{e}");
    assert_eq!(run.page(), OLD_PAGE, "nothing written");
    assert_eq!(std::fs::read_to_string(&run.readme).unwrap(), OLD_README);

    let run = setup();
    let path = run.record.join("window/threads_default.json");
    let text = std::fs::read_to_string(&path).unwrap().replace("\"step_p95_ms\"", "\"step_p95\"");
    std::fs::write(&path, text).unwrap();
    let e = run.render(info()).expect_err("a renamed field");
    assert!(e.to_string().contains("threads_default.json") && e.to_string().contains("step_p95"), "{e}");

    let run = setup();
    let summary_json = run.record.join("replay/sylvian_1/summary.json");
    let text = std::fs::read_to_string(&summary_json).unwrap().replace("\"p95_ms\"", "\"p95\"");
    std::fs::write(&summary_json, text).unwrap();
    let e = run.render(info()).expect_err("a replay summary without its p95");
    assert!(e.to_string().contains("sylvian_1/summary.json"), "{e}");

    let run = setup();
    std::fs::remove_file(run.record.join("fem/brain_pial_coarse_audit.json")).unwrap();
    let e = run.render(info()).expect_err("no audit of the coarse brain");
    assert!(e.to_string().contains("brain_pial_coarse_audit.json"), "{e}");
}

#[test]
fn a_fast_run_says_what_it_did_not_run_and_needs_nothing_of_it() {
    let run = setup();
    for skipped in ["startup/q15_cold_background.json", "fem/brain_pial_coarse.json", "fem/brain_pial_coarse_audit.json", "fem/paper-12k_audit.json"] {
        std::fs::remove_file(run.record.join(skipped)).unwrap();
    }
    std::fs::remove_dir_all(run.record.join("window")).unwrap();
    run.render(RunInfo { fast: true, no_window: true, ..info() }).unwrap_or_else(|e| panic!("{e}"));
    let page = run.page();
    let rows = summary(&page);
    assert!(rows.contains("| the same on the coarse real brain | not run (FAST=1) |"), "{rows}");
    assert!(rows.contains("| what each per-frame optimisation of the exact solve buys | not run (FAST=1) |"), "{rows}");
    assert!(rows.contains("not run: Xvfb is not installed"), "{rows}");
    assert!(rows.contains("| our sparse Cholesky against CHOLMOD: entries of L; numeric factor; solve | not run (FAST=1) |"), "{rows}");
    assert!(!rows.contains("n/a") && !rows.contains("NaN"), "{rows}");
}

#[test]
fn a_cold_start_that_read_a_cache_is_refused() {
    let run = setup();
    let path = run.record.join("startup/q15_cold.json");
    let text = std::fs::read_to_string(&path).unwrap().replace("\"from_cache\": false", "\"from_cache\": true");
    std::fs::write(&path, text).unwrap();
    let e = run.render(info()).expect_err("a cold run that was not cold");
    assert!(e.to_string().contains("q15_cold.json") && e.to_string().contains("not cold"), "{e}");
}
