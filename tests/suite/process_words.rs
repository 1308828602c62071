//! The repository's files speak of the product, not of how it was made: no
//! file names a numbered work period or work ticket, a work period of its
//! own, or the people who split the work. This test walks every text file of
//! the checkout and lists each line that does, as `path:line`.
//!
//! Skipped: what git ignores by the simple rules of the `.gitignore` files
//! (names, `/anchored` names, `*.ext`; `target/` and `.git/` always),
//! `Cargo.lock`, and binary files (images, gzip'd meshes, anything holding a
//! NUL byte or not UTF-8). The words are assembled at run time, so this file
//! does not match itself.

use std::path::{Path, PathBuf};

/// File endings never read as text.
const BINARY_ENDINGS: [&str; 12] = [".png", ".jpg", ".jpeg", ".gif", ".ico", ".gz", ".msh", ".bin", ".zip", ".pdf", ".ttf", ".svgz"];

/// One ignore rule of a `.gitignore`, relative to the folder holding it.
enum Rule {
    /// A name matched anywhere below the folder.
    Name(String),
    /// A name matched only directly in the folder (`/name`).
    Anchored(String),
    /// A file ending (`*.ext`).
    Ending(String),
}

/// The simple rules of `dir/.gitignore` (negations and other globs are left out:
/// a file they would skip is then read, which can only make the test stricter).
fn rules_of(dir: &Path) -> Vec<Rule> {
    let Ok(text) = std::fs::read_to_string(dir.join(".gitignore")) else { return Vec::new() };
    let mut rules = Vec::new();
    for line in text.lines().map(str::trim) {
        if line.is_empty() || line.starts_with('#') || line.starts_with('!') {
            continue;
        }
        let line = line.trim_end_matches('/');
        if let Some(ending) = line.strip_prefix('*') {
            if ending.starts_with('.') && !ending.contains(['*', '?', '[', '/']) {
                rules.push(Rule::Ending(ending.to_string()));
            }
        } else if line.contains(['*', '?', '[']) {
            continue;
        } else if let Some(name) = line.strip_prefix('/') {
            if !name.contains('/') {
                rules.push(Rule::Anchored(name.to_string()));
            }
        } else if !line.contains('/') {
            rules.push(Rule::Name(line.to_string()));
        }
    }
    rules
}

/// Whether `name`, directly in the folder at depth `depth` below the folder
/// whose rules these are, is ignored.
fn ignored(rules: &[Rule], name: &str, depth: usize) -> bool {
    rules.iter().any(|r| match r {
        Rule::Name(n) => n == name,
        Rule::Anchored(n) => depth == 0 && n == name,
        Rule::Ending(e) => name.ends_with(e.as_str()),
    })
}

/// Every file to read below `root`, sorted.
fn text_files(root: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    // (folder, the rules in force there with the depth below each rule's folder)
    let mut stack: Vec<(PathBuf, Vec<(usize, usize)>)> = Vec::new();
    let mut all_rules: Vec<Vec<Rule>> = Vec::new();
    stack.push((root.to_path_buf(), Vec::new()));
    while let Some((dir, inherited)) = stack.pop() {
        let mut in_force = inherited;
        let own = rules_of(&dir);
        if !own.is_empty() {
            all_rules.push(own);
            in_force.push((all_rules.len() - 1, 0));
        }
        let Ok(entries) = std::fs::read_dir(&dir) else { continue };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let Ok(kind) = entry.file_type() else { continue };
            if kind.is_symlink() || name == ".git" || (kind.is_dir() && name == "target") {
                continue;
            }
            if in_force.iter().any(|&(k, depth)| ignored(&all_rules[k], &name, depth)) {
                continue;
            }
            let path = entry.path();
            if kind.is_dir() {
                stack.push((path, in_force.iter().map(|&(k, d)| (k, d + 1)).collect()));
            } else if kind.is_file() {
                let lower = name.to_ascii_lowercase();
                let exempt = dir.as_path() == root && name == "Cargo.lock";
                if !exempt && !BINARY_ENDINGS.iter().any(|e| lower.ends_with(e)) {
                    out.push(path);
                }
            }
        }
    }
    out.sort();
    out
}

/// The words, put together here so that no line of this file matches them.
struct Words {
    period: String,
    ticket: String,
    this: String,
    the: String,
    lead: String,
    aide: String,
}

impl Words {
    fn new() -> Self {
        Self {
            period: format!("{}{}", "sess", "ion"),
            ticket: format!("{}{}", "iss", "ue"),
            this: format!("{}{}", "th", "is"),
            the: format!("{}{}", "t", "he"),
            lead: format!("{}{}", "le", "ad"),
            aide: format!("{}{}", "hel", "per"),
        }
    }
}

/// Whether position `i` of `b` starts a word (no letter, digit or `_` before it).
fn word_start(b: &[u8], i: usize) -> bool {
    i == 0 || !(b[i - 1].is_ascii_alphanumeric() || b[i - 1] == b'_')
}

/// Positions where `word` starts a word in `b`.
fn starts<'a>(b: &'a [u8], word: &'a str) -> impl Iterator<Item = usize> + 'a {
    let w = word.as_bytes();
    (0..b.len().saturating_sub(w.len() - 1)).filter(move |&i| b[i..].starts_with(w) && word_start(b, i))
}

/// Spaces and tabs from `i`: how many.
fn blanks(b: &[u8], i: usize) -> usize {
    b[i.min(b.len())..].iter().take_while(|c| **c == b' ' || **c == b'\t').count()
}

fn digit_at(b: &[u8], i: usize) -> bool {
    b.get(i).is_some_and(u8::is_ascii_digit)
}

/// What the lower-cased line `b` names, if anything.
fn offence(b: &[u8], w: &Words) -> Option<String> {
    // A numbered work period, singular or plural: "<period> 4", "<period>s 4".
    for i in starts(b, &w.period) {
        let mut j = i + w.period.len();
        if b.get(j) == Some(&b's') {
            j += 1;
        }
        let n = blanks(b, j);
        if n > 0 && digit_at(b, j + n) {
            return Some(format!("a numbered {}", w.period));
        }
    }
    // A numbered ticket: "<ticket> 21", "<ticket> #4", "<ticket>s 3", "<ticket>#4".
    for i in starts(b, &w.ticket) {
        let mut j = i + w.ticket.len();
        if b.get(j) == Some(&b's') {
            j += 1;
        }
        let n = blanks(b, j);
        let k = j + n;
        if (b.get(k) == Some(&b'#') && digit_at(b, k + 1)) || (n > 0 && digit_at(b, k)) {
            return Some(format!("a numbered {}", w.ticket));
        }
    }
    // "<this> <period>".
    for i in starts(b, &w.this) {
        let j = i + w.this.len();
        let n = blanks(b, j);
        if n > 0 && b[j + n..].starts_with(w.period.as_bytes()) {
            return Some(format!("\"{} {}\"", w.this, w.period));
        }
    }
    // "<the> <lead>", except the product words "<lead>-in" and "<lead>ing".
    for i in starts(b, &w.the) {
        let j = i + w.the.len();
        let n = blanks(b, j);
        if n > 0 && b[j + n..].starts_with(w.lead.as_bytes()) {
            let rest = &b[j + n + w.lead.len()..];
            if !(rest.starts_with(b"-in") || rest.starts_with(b"ing")) {
                return Some(format!("\"{} {}\"", w.the, w.lead));
            }
        }
    }
    // "<aide>" or "<aide>s", anywhere (identifiers too).
    if b.windows(w.aide.len()).any(|x| x == w.aide.as_bytes()) {
        return Some(format!("\"{}\"", w.aide));
    }
    None
}

/// Every offending line of the files below `root`, as `path:line: what: text`.
fn offences(root: &Path) -> Vec<String> {
    let w = Words::new();
    let mut found = Vec::new();
    for path in text_files(root) {
        let Ok(bytes) = std::fs::read(&path) else { continue };
        if bytes.contains(&0) {
            continue;
        }
        let Ok(text) = String::from_utf8(bytes) else { continue };
        let shown = path.strip_prefix(root).unwrap_or(&path).display().to_string();
        for (k, line) in text.lines().enumerate() {
            let lower = line.to_ascii_lowercase();
            if let Some(what) = offence(lower.as_bytes(), &w) {
                let excerpt: String = line.trim().chars().take(140).collect();
                found.push(format!("{shown}:{}: {what}: {excerpt}", k + 1));
            }
        }
    }
    found
}

#[test]
fn no_file_speaks_of_the_development_process() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let found = offences(root);
    assert!(
        found.is_empty(),
        "{} line(s) speak of the development process instead of the product; say what the code does and why \
         (a measured figure carries its command, machine, date and commit):\n{}",
        found.len(),
        found.join("\n")
    );
}

#[test]
fn the_matcher_finds_the_process_words_and_spares_the_product_words() {
    let w = Words::new();
    let hit = |s: String| offence(s.to_ascii_lowercase().as_bytes(), &w).is_some();
    let (p, t, l, a) = (&w.period, &w.ticket, &w.lead, &w.aide);
    // Found.
    assert!(hit(format!("measured in {p} 21")));
    assert!(hit(format!("{p}s 19 and 20")));
    assert!(hit(format!("as {t} 21 asks")));
    assert!(hit(format!("{t} #4's bar")));
    assert!(hit(format!("{t}s 3")));
    assert!(hit(format!("not tried again {} {p}.", w.this)));
    assert!(hit(format!("see {} {l}'s report", w.the)));
    assert!(hit(format!("the scene {a} writes it")));
    assert!(hit(format!("Shared {a}S")));
    assert!(hit(format!("The {}", l.to_uppercase())));
    // Spared.
    assert!(!hit(format!("the {l}-in starts at rest")));
    assert!(!hit(format!("the {l}ing face pushes")));
    assert!(!hit(format!("recordings are {p}_1764000000.csv")));
    assert!(!hit(format!("an interactive {p}; at the end")));
    assert!(!hit("it pulled tissue 54 mm".to_string()));
    assert!(!hit(format!("the {t}: Tab moved the focus")));
    assert!(!hit(format!("a {t} 'a' and more")));
}

#[test]
fn the_walk_skips_what_git_ignores_and_binary_files() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let files = text_files(root);
    let rel = |p: &PathBuf| p.strip_prefix(root).unwrap_or(p).to_string_lossy().replace('\\', "/");
    assert!(files.iter().any(|p| rel(p) == "src/lib.rs"), "the walk must read the sources");
    assert!(files.iter().all(|p| !rel(p).starts_with("target/") && !rel(p).starts_with(".git/")));
    assert!(files.iter().all(|p| !rel(p).ends_with(".png") && !rel(p).ends_with(".gz") && rel(p) != "Cargo.lock"));
}
