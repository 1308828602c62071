//! ARCHITECTURE.md is the map a newcomer reads before the code: it stays
//! short and every path it names exists, so a module that moves or goes
//! takes its line in the map with it.

use std::path::Path;

const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Every token of `text` in backquotes that looks like a path in the tree:
/// starts with one of the top-level folders and has no spaces or wildcards.
fn named_paths(text: &str) -> Vec<String> {
    const TOP: [&str; 10] = ["src/", "tests/", "benches/", "examples/", "scripts/", "shaders/", "config/", "assets/", "docs/", "fuzz/"];
    text.split('`')
        .skip(1)
        .step_by(2)
        .filter(|t| TOP.iter().any(|top| t.starts_with(top)))
        .filter(|t| !t.contains([' ', '*', '{', '<', '(']))
        .map(|t| t.trim_end_matches([':', ',', '.']).to_string())
        .collect()
}

#[test]
fn architecture_md_is_short_and_every_path_it_names_exists() {
    let text = std::fs::read_to_string(Path::new(ROOT).join("ARCHITECTURE.md")).expect("ARCHITECTURE.md at the repository root");
    let lines = text.lines().count();
    assert!(lines <= 250, "ARCHITECTURE.md has {lines} lines; it is a map, at most 250");
    let paths = named_paths(&text);
    assert!(paths.len() >= 20, "the code map names the modules by path ({} found)", paths.len());
    let missing: Vec<&String> = paths.iter().filter(|p| !Path::new(ROOT).join(p.as_str()).exists()).collect();
    assert!(missing.is_empty(), "ARCHITECTURE.md names paths that do not exist: {missing:?}");
    // Every top-level module of the library appears in the map.
    let lib = std::fs::read_to_string(Path::new(ROOT).join("src/lib.rs")).expect("src/lib.rs");
    let modules: Vec<&str> = lib.lines().filter_map(|l| l.trim().strip_prefix("pub mod ")).map(|m| m.trim_end_matches(';')).collect();
    assert!(!modules.is_empty());
    let unmapped: Vec<&&str> = modules
        .iter()
        .filter(|m| !paths.iter().any(|p| p == &format!("src/{m}/") || p == &format!("src/{m}") || p == &format!("src/{m}.rs")))
        .collect();
    assert!(unmapped.is_empty(), "modules of src/lib.rs missing from ARCHITECTURE.md's code map: {unmapped:?}");
}

#[test]
fn the_path_finder_reads_backquoted_paths_only() {
    let found = named_paths("see `src/fem/` and `src/app/window.rs`, not `cargo test` or src/plain nor `src/*.rs`");
    assert_eq!(found, vec!["src/fem/", "src/app/window.rs"]);
}
