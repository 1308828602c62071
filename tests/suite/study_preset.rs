//! The real presets, for measurements: ignored by default (minutes in release).
//! Run: `cargo test --release --test suite study_preset -- --ignored --nocapture`
//! with `FISSURE_STUDY_PRESET=quick|full` (default quick) and
//! `FISSURE_STUDY_OUT=DIR` (default `target/study-<preset>`).

use fissure::study::{StudyOptions, StudyPreset, run_study};
use std::path::PathBuf;

#[test]
#[ignore = "minutes in release; run explicitly for the report's numbers"]
fn preset_study_runs_and_every_phantom_row_succeeds() {
    let full = std::env::var("FISSURE_STUDY_PRESET").map(|p| p == "full").unwrap_or(false);
    let name = if full { "full" } else { "quick" };
    let out_dir = std::env::var_os("FISSURE_STUDY_OUT")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(concat!(env!("CARGO_MANIFEST_DIR"), "/target")).join(format!("study-{name}")));
    let options = StudyOptions::new(if full { StudyPreset::Full } else { StudyPreset::Quick }, out_dir.clone());
    let results = run_study(&options, &mut |p| eprintln!("[{}/{}] {}", p.done, p.total, p.label)).expect("study");
    println!("{} runs in {:.1} s; outputs in {}", results.rows.len(), results.elapsed_s, out_dir.display());
    for r in &results.rows {
        if let Err(e) = &r.outcome {
            println!("not run: {} {}: {e}", r.knob.map_or("reference", |k| k.name()), r.label);
            assert!(matches!(r.settings.backend, fissure::scenario::CollisionBackend::Gpu), "only GPU rows may fail (no adapter): {e}");
        }
    }
}
