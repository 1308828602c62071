//! Function length and struct size are counted: no function of `src/` runs
//! over [`MAX_FN_LINES`] lines (signature to closing brace, tests included)
//! and no struct has over [`MAX_FIELDS`] named fields, except those listed in
//! [`OFFENDERS`] at their size when the rule came, which may shrink but not
//! grow. An offender split below the limit must leave the list, so the list
//! only shrinks. A failure prints every offender and what to do.

use crate::common::source::{code_only, is_ident, line_of, matching, read, rust_files};

/// Longest function, in lines from its `fn` line to its closing brace.
const MAX_FN_LINES: usize = 100;
/// Most named fields of one struct.
const MAX_FIELDS: usize = 20;

/// The items allowed over the limit: (file, `fn name` or `struct Name`,
/// size). An entry's size follows its item down, never up, and the entry goes
/// once the item is within the limit. The one left is the scenario file's
/// schema: its fields are the file's top-level keys, and grouping them would
/// change every scenario file written (serde's `flatten` cannot be combined
/// with the `deny_unknown_fields` that names a misspelt key).
const OFFENDERS: &[(&str, &str, usize)] = &[
    ("src/scenario/file.rs", "struct ScenarioFile", 23),
];

/// A function or a struct of the source and its size (lines, or named fields).
#[derive(Debug, Clone, PartialEq)]
struct Item {
    file: String,
    /// `fn name` or `struct Name`.
    name: String,
    line: usize,
    size: usize,
}

impl Item {
    fn limit(&self) -> usize {
        if self.name.starts_with("fn ") { MAX_FN_LINES } else { MAX_FIELDS }
    }
    fn unit(&self) -> &'static str {
        if self.name.starts_with("fn ") { "lines" } else { "named fields" }
    }
}

/// The identifier at `i`, if any, and where it ends.
fn ident_at(code: &[u8], i: usize) -> Option<(&str, usize)> {
    let end = i + code[i..].iter().take_while(|&&c| is_ident(c)).count();
    (end > i).then(|| (std::str::from_utf8(&code[i..end]).expect("ASCII"), end))
}

fn skip_space(code: &[u8], mut i: usize) -> usize {
    while i < code.len() && code[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

/// Where the item's body opens: the first `{` outside parentheses and
/// brackets after `from`, or `None` when a `;` comes first (a declaration, a
/// tuple or unit struct).
fn body_start(code: &[u8], from: usize) -> Option<usize> {
    let mut depth = 0usize;
    for (j, &c) in code.iter().enumerate().skip(from) {
        match c {
            b'(' | b'[' => depth += 1,
            b')' | b']' => depth = depth.saturating_sub(1),
            b'{' if depth == 0 => return Some(j),
            b';' if depth == 0 => return None,
            _ => {}
        }
    }
    None
}

/// Named fields in the struct body `code[open..close]`: `name:` at the body's
/// own depth (attributes, types in parentheses or brackets aside).
fn named_fields(code: &[u8], open: usize, close: usize) -> usize {
    let mut depth = 0usize;
    let mut count = 0;
    let mut j = open + 1;
    while j < close - 1 {
        match code[j] {
            b'(' | b'[' | b'{' => depth += 1,
            b')' | b']' | b'}' => depth = depth.saturating_sub(1),
            c if depth == 0 && is_ident(c) && !is_ident(code[j - 1]) => {
                let (_, end) = ident_at(code, j).expect("an identifier");
                let k = skip_space(code, end);
                if code[k] == b':' && code.get(k + 1) != Some(&b':') && code[j - 1] != b':' {
                    count += 1;
                }
                j = end;
                continue;
            }
            _ => {}
        }
        j += 1;
    }
    count
}

/// Every function (with a body) and every struct with named fields in one file's text.
fn items(file: &str, text: &str) -> Vec<Item> {
    let code = code_only(text);
    let mut out = Vec::new();
    let mut i = 0;
    while i < code.len() {
        if !is_ident(code[i]) || (i > 0 && (is_ident(code[i - 1]) || code[i - 1] == b'\'')) {
            i += 1;
            continue;
        }
        let (word, end) = ident_at(&code, i).expect("an identifier");
        let kind = match word {
            "fn" => "fn",
            "struct" => "struct",
            _ => {
                i = end;
                continue;
            }
        };
        let at = skip_space(&code, end);
        let Some((name, after)) = ident_at(&code, at).filter(|_| at > end) else {
            i = end;
            continue;
        };
        if let Some(open) = body_start(&code, after) {
            let close = matching(&code, open, b'{', b'}');
            let size = if kind == "fn" { line_of(&code, close - 1) - line_of(&code, i) + 1 } else { named_fields(&code, open, close) };
            out.push(Item { file: file.to_string(), name: format!("{kind} {name}"), line: line_of(&code, i), size });
        }
        i = after;
    }
    out
}

/// What breaks the rule, given the items found and the list of offenders.
fn verdict(found: &[Item], offenders: &[(&str, &str, usize)]) -> Vec<String> {
    let mut problems = Vec::new();
    for item in found.iter().filter(|it| it.size > it.limit()) {
        let listed = offenders.iter().find(|(f, n, _)| *f == item.file && *n == item.name);
        match listed {
            None => problems.push(format!(
                "{}:{}: {} has {} {} (at most {}): split it",
                item.file,
                item.line,
                item.name,
                item.size,
                item.unit(),
                item.limit()
            )),
            Some(&(_, _, was)) if item.size > was => problems.push(format!(
                "{}:{}: {} grew to {} {} (listed at {}, at most {} for new code): it may shrink, not grow",
                item.file,
                item.line,
                item.name,
                item.size,
                item.unit(),
                was,
                item.limit()
            )),
            Some(_) => {}
        }
    }
    for &(file, name, was) in offenders {
        let now: Vec<&Item> = found.iter().filter(|it| it.file == file && it.name == name).collect();
        if now.iter().all(|it| it.size <= it.limit()) {
            problems.push(format!("{file}: {name} (listed at {was}) is now within the limit or gone: remove it from OFFENDERS"));
        } else if let Some(smaller) = now.iter().map(|it| it.size).max().filter(|&s| s < was) {
            problems.push(format!("{file}: {name} shrank from {was} to {smaller}: lower its entry in OFFENDERS to {smaller}"));
        }
    }
    problems
}

#[test]
fn no_function_or_struct_grows_past_its_limit() {
    let found: Vec<Item> = rust_files().iter().flat_map(|f| items(f, &read(f))).collect();
    assert!(found.iter().filter(|it| it.name.starts_with("fn ")).count() > 1000, "the functions of src/ are found");
    let problems = verdict(&found, OFFENDERS);
    let mut offenders: Vec<&Item> = found.iter().filter(|it| it.size > it.limit()).collect();
    offenders.sort_by(|a, b| (&a.file, a.line).cmp(&(&b.file, b.line)));
    let listing: Vec<String> = offenders.iter().map(|it| format!("    (\"{}\", \"{}\", {}),", it.file, it.name, it.size)).collect();
    assert!(
        problems.is_empty(),
        "{}\n\nfunctions over {MAX_FN_LINES} lines and structs over {MAX_FIELDS} named fields today:\n{}",
        problems.join("\n"),
        listing.join("\n")
    );
}

#[test]
fn functions_and_structs_are_measured() {
    let text = "/// fn not_this() {\nfn short(x: u32) -> u32 {\n    let s = \"}\";\n    x\n}\nimpl A {\n    pub fn method<T: Into<u32>>(&self, f: &dyn Fn(u32) -> u32)\n    where T: Copy\n    {\n        let g: fn(u32) = drop;\n    }\n}\ntrait T { fn declared(&self); }\nstruct Named<'a> {\n    #[serde(rename = \"x\")]\n    pub a: u32,\n    pub(crate) b: std::collections::HashMap<u32, Vec<(u32, f64)>>,\n    c: &'a dyn Fn(u32, u32) -> u32,\n}\nstruct Tuple(u32, u32);\n";
    let found = items("src/x.rs", text);
    let brief: Vec<(&str, usize, usize)> = found.iter().map(|it| (it.name.as_str(), it.line, it.size)).collect();
    assert_eq!(brief, [("fn short", 2, 4), ("fn method", 7, 5), ("struct Named", 14, 3)]);
}

#[test]
fn a_listed_offender_may_shrink_but_not_grow_and_leaves_the_list_when_within() {
    let item = |name: &str, size| Item { file: "src/x.rs".into(), name: name.into(), line: 1, size };
    let found = [item("fn long", 120), item("fn new_long", 101), item("fn fixed", 90), item("struct Wide", 21)];
    let listed = [("src/x.rs", "fn long", 120), ("src/x.rs", "fn fixed", 130), ("src/x.rs", "struct Wide", 22)];
    let problems = verdict(&found, &listed);
    assert_eq!(problems.len(), 3, "{problems:#?}");
    assert!(problems[0].contains("fn new_long has 101 lines"), "{problems:#?}");
    assert!(problems[1].contains("fn fixed (listed at 130) is now within the limit"), "{problems:#?}");
    assert!(problems[2].contains("struct Wide shrank from 22 to 21"), "{problems:#?}");
    assert!(verdict(&[item("fn long", 121)], &[("src/x.rs", "fn long", 120)])[0].contains("grew to 121"));
}
