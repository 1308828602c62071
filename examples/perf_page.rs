//! Renders `docs/performance.md` from one run of `scripts/perf_docs.sh` (its folder, `target/perf/`, and the
//! fem bench's figures) and copies the page's summary into README.md; the script runs it last. Every figure
//! is read from the JSON its program wrote, as that program's type (`fissure::perf::reports`); a missing one
//! stops it, naming the file, and nothing is written.
//!
//! `cargo run --release --example perf_page -- --dir target/perf --fem target/fem-bench-cache/figures
//!  --machine M --date D --commit C --command CMD --repeat N --cores N [--fast] [--no-window] [--no-cholmod]
//!  [--page docs/performance.md] [--readme README.md]`
//! `cargo run --release --example perf_page -- --readme-only` copies the page's summary into README.md.
use fissure::perf::RunInfo;
use std::path::PathBuf;

fn main() {
    if let Err(message) = run(std::env::args().skip(1).collect()) {
        eprintln!("perf_page: {message}");
        std::process::exit(1);
    }
}

fn run(args: Vec<String>) -> Result<(), String> {
    let value = |name: &str| -> Result<String, String> {
        let k = args.iter().position(|a| a == name).ok_or(format!("{name} is required"))?;
        args.get(k + 1).cloned().ok_or(format!("{name} needs a value"))
    };
    let or = |name: &str, default: &str| if args.iter().any(|a| a == name) { value(name) } else { Ok(default.to_string()) };
    let (page, readme) = (PathBuf::from(or("--page", "docs/performance.md")?), PathBuf::from(or("--readme", "README.md")?));
    if args.iter().any(|a| a == "--readme-only") {
        return fissure::perf::copy_summary(&page, &readme).map_err(|e| e.to_string());
    }
    let flag = |name: &str| args.iter().any(|a| a == name);
    let number = |name: &str| -> Result<usize, String> { value(name)?.parse().map_err(|_| format!("{name}: not a whole number")) };
    let info = RunInfo {
        machine: value("--machine")?,
        date: value("--date")?,
        commit: value("--commit")?,
        command: value("--command")?,
        fast: flag("--fast"),
        repeat: number("--repeat")?,
        no_window: flag("--no-window"),
        no_cholmod: flag("--no-cholmod"),
        cores: number("--cores")?,
    };
    let (dir, fem) = (PathBuf::from(value("--dir")?), PathBuf::from(value("--fem")?));
    fissure::perf::write_page(&dir, &fem, info, &page, &readme).map_err(|e| e.to_string())?;
    println!("wrote {} and the summary in {}", page.display(), readme.display());
    Ok(())
}
