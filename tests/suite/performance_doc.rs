//! The README's performance table is docs/performance.md's summary, verbatim
//! (`scripts/perf_docs.sh` writes the page and copies the summary; a hand
//! edit of one and not the other fails here); the page says where its figures
//! come from (the machine, date, commit and command lines above the summary);
//! and the README stays a front door of at most 250 lines.

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const SUMMARY_BEGIN: &str = "<!-- performance summary: begin -->";
const SUMMARY_END: &str = "<!-- performance summary: end -->";
/// The header lines docs/performance.md opens with, each followed by a value.
const HEADER_LINES: [&str; 4] = ["- Machine: ", "- Date: ", "- Commit: ", "- Command: "];
const README_MAX_LINES: usize = 250;

fn read(path: &str) -> String {
    std::fs::read_to_string(format!("{ROOT}/{path}")).unwrap_or_else(|e| panic!("{path}: {e}"))
}

/// The text between the marker lines (markers excluded); `Err` says what is
/// wrong: a marker missing, repeated, not on a line of its own, or out of order.
fn summary_section<'a>(text: &'a str, file: &str) -> Result<&'a str, String> {
    for marker in [SUMMARY_BEGIN, SUMMARY_END] {
        let count = text.matches(marker).count();
        if count != 1 {
            return Err(format!("{file} has {count} `{marker}` (exactly one expected)"));
        }
        if !text.lines().any(|l| l == marker) {
            return Err(format!("{file}: `{marker}` must be a line of its own"));
        }
    }
    let a = text.find(SUMMARY_BEGIN).unwrap_or_default() + SUMMARY_BEGIN.len();
    let b = text.find(SUMMARY_END).unwrap_or_default();
    if b < a {
        return Err(format!("{file}: the summary's end marker comes before its begin marker"));
    }
    Ok(&text[a..b])
}

#[test]
fn readme_performance_section_is_the_performance_page_summary() {
    let readme = read("README.md");
    let page = read("docs/performance.md");
    let a = summary_section(&readme, "README.md").unwrap_or_else(|e| panic!("{e}"));
    let b = summary_section(&page, "docs/performance.md").unwrap_or_else(|e| panic!("{e}"));
    assert!(b.lines().any(|l| l.starts_with("| ")), "docs/performance.md's summary has no table rows:\n{b}");
    assert_eq!(a, b, "README's performance table differs from docs/performance.md's summary: copy it again (`scripts/perf_docs.sh --readme`)");
}

#[test]
fn performance_page_names_its_machine_date_commit_and_command() {
    let page = read("docs/performance.md");
    let head = page.split(SUMMARY_BEGIN).next().unwrap_or_default();
    for prefix in HEADER_LINES {
        let value = head.lines().find_map(|l| l.strip_prefix(prefix)).map(str::trim);
        assert!(
            value.is_some_and(|v| !v.is_empty()),
            "docs/performance.md must say, above its summary, a line `{prefix}...` with a value (scripts/perf_docs.sh writes it); found {value:?}"
        );
    }
}

#[test]
fn readme_is_at_most_250_lines() {
    let lines = read("README.md").lines().count();
    assert!(
        lines <= README_MAX_LINES,
        "README.md has {lines} lines, more than {README_MAX_LINES}: it is the front door; move the detail to docs/ (docs/usage.md, docs/performance.md)"
    );
}
