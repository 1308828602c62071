//! The performance record: the figures each measuring program writes as JSON ([`reports`], one type a report,
//! shared by its writer and by the page), one run of `scripts/perf_docs.sh` read back ([`record`]), and
//! `docs/performance.md` rendered from it ([`page`], [`summary`]), whose summary table the README repeats.
//!
//! In: the run's folder (`target/perf/`) and the fem bench's figures. Out: the page and the README's summary,
//! each written whole. Stays true: a figure the page needs that the run did not write stops the rendering
//! with an error naming its file, so no page goes out with a blank where a number was.

pub mod cholmod;
pub mod page;
pub mod record;
pub mod reports;
pub mod summary;

pub use record::{PerfError, PerfRecord, RunInfo};

use std::path::Path;

/// Renders the run in `dir` (figures of the fem bench in `fem_dir`) into `page_path`, carrying the real-GPU
/// section of the page already there, and copies the summary table into `readme_path`. Nothing is written
/// unless every figure was found.
pub fn write_page(dir: &Path, fem_dir: &Path, info: RunInfo, page_path: &Path, readme_path: &Path) -> Result<(), PerfError> {
    let record = PerfRecord::load(dir, fem_dir, info)?;
    let previous = std::fs::read_to_string(page_path).ok();
    let page = page::render(&record, &page::gpu_section(previous.as_deref()))?;
    let readme = readme_with_summary(&page, readme_path)?;
    record::write_whole(page_path, page.as_bytes())?;
    record::write_whole(readme_path, readme.as_bytes())
}

/// The README at `readme_path` with its summary block replaced by `page`'s.
pub fn readme_with_summary(page: &str, readme_path: &Path) -> Result<String, PerfError> {
    let summary = page::between_markers(page, page::SUMMARY_BEGIN, page::SUMMARY_END).ok_or_else(|| PerfError::new(Path::new("the page"), "no summary block"))?;
    let readme = std::fs::read_to_string(readme_path).map_err(|e| PerfError::new(readme_path, e.to_string()))?;
    page::replace_between(&readme, page::SUMMARY_BEGIN, page::SUMMARY_END, summary).map_err(|m| PerfError::new(readme_path, m))
}

/// Copies the summary of the page at `page_path` into the README (`scripts/perf_docs.sh --readme`).
pub fn copy_summary(page_path: &Path, readme_path: &Path) -> Result<(), PerfError> {
    let page = std::fs::read_to_string(page_path).map_err(|e| PerfError::new(page_path, e.to_string()))?;
    let readme = readme_with_summary(&page, readme_path)?;
    record::write_whole(readme_path, readme.as_bytes())
}
