//! README's Controls table is the code's key table ([`CONTROLS`]), row for
//! row: a key added, removed or reworded in one place and not the other fails
//! here. (`fissure::input::bindings` holds every bound key to exactly one
//! row of the same table, so the chain code -> table -> README is closed.)

use fissure::input::bindings::CONTROLS;

/// The rows of the table under `## Controls`: (input, action) cells.
fn readme_controls() -> Vec<(String, String)> {
    let readme = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).expect("README.md");
    let section = readme.split("\n## Controls\n").nth(1).expect("a `## Controls` section");
    let section = section.split("\n## ").next().unwrap_or(section);
    let mut rows = Vec::new();
    for line in section.lines().map(str::trim).skip_while(|l| !l.starts_with('|')).take_while(|l| l.starts_with('|')) {
        let inner = line.trim_start_matches('|').trim_end_matches('|');
        let cells: Vec<&str> = inner.splitn(2, " | ").map(str::trim).collect();
        if cells.len() != 2 || cells[0].chars().all(|c| c == '-' || c == ' ') || cells[0] == "input" {
            continue;
        }
        let unquote = |s: &str| s.trim_matches('`').to_string();
        rows.push((unquote(cells[0]), cells[1].to_string()));
    }
    rows
}

#[test]
fn readme_controls_table_is_the_code_table() {
    let readme = readme_controls();
    let code: Vec<(String, String)> = CONTROLS.iter().map(|r| (r.input.to_string(), r.action.to_string())).collect();
    let expected: String = CONTROLS.iter().map(|r| format!("| {} | {} |\n", r.input, r.action)).collect();
    assert!(!readme.is_empty(), "no table found under ## Controls");
    assert_eq!(
        readme, code,
        "README's Controls table differs from fissure::input::bindings::CONTROLS; the table the code has is:\n| input | action |\n|---|---|\n{expected}"
    );
}
