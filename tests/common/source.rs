//! Reading the crate's own source as code: comments and the insides of string
//! and character literals blanked (newlines kept, so byte offsets and line
//! numbers stay those of the file), test-only items removable, and the
//! `crate::...` paths a file names, grouped `use` trees expanded. Enough of
//! Rust's lexical rules for the structure tests (`tests/suite/layers.rs`,
//! `tests/suite/code_size.rs`); not a parser.
#![allow(dead_code)]

use std::path::{Path, PathBuf};

/// The repository root.
pub const ROOT: &str = env!("CARGO_MANIFEST_DIR");

/// Every `.rs` file under `src/`, sorted, as paths relative to the root (`src/sim/build.rs`).
pub fn rust_files() -> Vec<String> {
    let mut out = Vec::new();
    let mut stack = vec![PathBuf::from(ROOT).join("src")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).expect("a readable folder under src/") {
            let path = entry.expect("a folder entry").path();
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let relative = path.strip_prefix(ROOT).expect("under the root");
                out.push(relative.to_string_lossy().replace('\\', "/"));
            }
        }
    }
    out.sort();
    out
}

/// The text of a file named relative to the root.
pub fn read(relative: &str) -> String {
    std::fs::read_to_string(Path::new(ROOT).join(relative)).unwrap_or_else(|e| panic!("{relative}: {e}"))
}

pub fn is_ident(c: u8) -> bool {
    c.is_ascii_alphanumeric() || c == b'_'
}

fn blank(code: &mut [u8], from: usize, to: usize) {
    let to = to.min(code.len());
    for c in &mut code[from..to] {
        if *c != b'\n' {
            *c = b' ';
        }
    }
}

/// `text` with comments (line, block, nested, doc) and the contents of string,
/// raw string and character literals replaced by spaces; quotes, newlines and
/// everything else kept in place. Lifetimes (`'a`) are left as code.
pub fn code_only(text: &str) -> Vec<u8> {
    let b = text.as_bytes();
    let mut code = b.to_vec();
    let mut i = 0;
    while i < b.len() {
        let before_is_ident = i > 0 && is_ident(b[i - 1]);
        match b[i] {
            b'/' if b.get(i + 1) == Some(&b'/') => {
                let end = b[i..].iter().position(|&c| c == b'\n').map_or(b.len(), |p| i + p);
                blank(&mut code, i, end);
                i = end;
            }
            b'/' if b.get(i + 1) == Some(&b'*') => {
                let (mut depth, mut j) = (1, i + 2);
                while j < b.len() && depth > 0 {
                    if b[j..].starts_with(b"/*") {
                        depth += 1;
                        j += 2;
                    } else if b[j..].starts_with(b"*/") {
                        depth -= 1;
                        j += 2;
                    } else {
                        j += 1;
                    }
                }
                blank(&mut code, i, j);
                i = j;
            }
            b'r' if raw_string_start(b, i) => {
                let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
                let open = i + 1 + hashes;
                let mut close = vec![b'"'];
                close.extend(std::iter::repeat_n(b'#', hashes));
                let end = b[open + 1..].windows(close.len()).position(|w| w == close.as_slice()).map_or(b.len(), |p| open + 1 + p);
                blank(&mut code, open + 1, end);
                i = end + close.len();
            }
            b'"' => {
                let mut j = i + 1;
                while j < b.len() && b[j] != b'"' {
                    j += if b[j] == b'\\' { 2 } else { 1 };
                }
                blank(&mut code, i + 1, j);
                i = j + 1;
            }
            // a character literal, or a byte literal (`b'{'`), not a lifetime
            b'\'' if !before_is_ident || (b[i - 1] == b'b' && (i == 1 || !is_ident(b[i - 2]))) => {
                if b.get(i + 1) == Some(&b'\\') {
                    // the escaped character may itself be a quote: the literal closes after it
                    let end = b.get(i + 3..).and_then(|r| r.iter().position(|&c| c == b'\'')).map_or(b.len(), |p| i + 3 + p);
                    blank(&mut code, i + 1, end);
                    i = end + 1;
                } else {
                    let width = text[i + 1..].chars().next().map_or(1, char::len_utf8);
                    if b.get(i + 1 + width) == Some(&b'\'') {
                        blank(&mut code, i + 1, i + 1 + width);
                        i += 2 + width;
                    } else {
                        i += 1; // a lifetime
                    }
                }
            }
            _ => i += 1,
        }
    }
    code
}

/// Whether `b[i]` (an `r`) opens a raw string: `r"`, `r#"`, `br"`, not part of an identifier.
fn raw_string_start(b: &[u8], i: usize) -> bool {
    let start_ok = i == 0 || !is_ident(b[i - 1]) || (b[i - 1] == b'b' && (i == 1 || !is_ident(b[i - 2])));
    let hashes = b[i + 1..].iter().take_while(|&&c| c == b'#').count();
    start_ok && b.get(i + 1 + hashes) == Some(&b'"')
}

/// The end (one past) of the item starting at or after `from`: its closing
/// brace, or its `;` when one comes before any brace. Attributes before it
/// are part of it.
pub fn item_end(code: &[u8], from: usize) -> usize {
    let mut depth = 0usize;
    let mut j = from;
    while j < code.len() {
        match code[j] {
            b'#' if depth == 0 && code.get(j + 1) == Some(&b'[') => {
                j = matching(code, j + 1, b'[', b']');
                continue;
            }
            b';' if depth == 0 => return j + 1,
            b'{' => depth += 1,
            b'}' => {
                depth = depth.saturating_sub(1);
                if depth == 0 {
                    return j + 1;
                }
            }
            _ => {}
        }
        j += 1;
    }
    code.len()
}

/// One past the bracket that closes the one at `open`.
pub fn matching(code: &[u8], open: usize, up: u8, down: u8) -> usize {
    let mut depth = 0usize;
    for (j, &c) in code.iter().enumerate().skip(open) {
        if c == up {
            depth += 1;
        } else if c == down {
            depth -= 1;
            if depth == 0 {
                return j + 1;
            }
        }
    }
    code.len()
}

/// `code` with every item under `#[cfg(test)]` blanked (a `mod tests { ... }`,
/// a test-only `use` or function).
pub fn without_tests(mut code: Vec<u8>) -> Vec<u8> {
    const ATTRIBUTE: &[u8] = b"#[cfg(test)]";
    let mut i = 0;
    while let Some(p) = code[i..].windows(ATTRIBUTE.len()).position(|w| w == ATTRIBUTE) {
        let start = i + p;
        let end = item_end(&code, start + ATTRIBUTE.len());
        blank(&mut code, start, end);
        i = end;
    }
    code
}

/// The 1-based line of byte offset `at`.
pub fn line_of(code: &[u8], at: usize) -> usize {
    1 + code[..at].iter().filter(|&&c| c == b'\n').count()
}

fn skip_space(b: &[u8], mut i: usize) -> usize {
    while i < b.len() && b[i].is_ascii_whitespace() {
        i += 1;
    }
    i
}

/// Reads one use tree at `i` (a path, a `{...}` group or `*`), pushing each
/// full path below `prefix`; returns where it ends.
fn use_tree(b: &[u8], i: usize, prefix: &str, out: &mut Vec<String>) -> usize {
    let mut i = skip_space(b, i);
    if i >= b.len() {
        return i;
    }
    if b[i] == b'{' {
        i += 1;
        loop {
            i = skip_space(b, i);
            match b.get(i) {
                None => return i,
                Some(b'}') => return i + 1,
                Some(b',') => i += 1,
                Some(_) => {
                    let next = use_tree(b, i, prefix, out);
                    i = next.max(i + 1);
                }
            }
        }
    }
    if b[i] == b'*' {
        out.push(prefix.to_string());
        return i + 1;
    }
    let start = i;
    while i < b.len() && is_ident(b[i]) {
        i += 1;
    }
    if start == i {
        return i + 1;
    }
    let segment = std::str::from_utf8(&b[start..i]).expect("ASCII identifier");
    let path = if prefix.is_empty() { segment.to_string() } else { format!("{prefix}::{segment}") };
    let j = skip_space(b, i);
    if b[j..].starts_with(b"::") {
        let k = skip_space(b, j + 2);
        if k < b.len() && (b[k] == b'{' || b[k] == b'*' || is_ident(b[k])) {
            return use_tree(b, k, &path, out);
        }
    }
    out.push(path);
    // `as name` renames; the name is no path.
    if b[j..].starts_with(b"as") && b.get(j + 2).is_some_and(|c| c.is_ascii_whitespace()) {
        let mut k = skip_space(b, j + 2);
        while k < b.len() && is_ident(b[k]) {
            k += 1;
        }
        return k;
    }
    i
}

/// Every path that follows `root::` in `code` (`root` one of `crate`,
/// `super`, ...), with its byte offset: `use crate::a::b;`, inline
/// `crate::a::f(x)`, grouped `crate::{a::b, c::{d, e}}` (one path each). The
/// paths are written without the root: `a::b`.
pub fn paths_after(code: &[u8], root: &str) -> Vec<(usize, String)> {
    let needle = format!("{root}::");
    let needle = needle.as_bytes();
    let mut out = Vec::new();
    let mut i = 0;
    while let Some(p) = code[i..].windows(needle.len()).position(|w| w == needle) {
        let at = i + p;
        i = at + needle.len();
        if at > 0 && (is_ident(code[at - 1]) || code[at - 1] == b'$' || code[at - 1] == b':') {
            continue;
        }
        let mut paths = Vec::new();
        i = use_tree(code, i, "", &mut paths).max(i);
        out.extend(paths.into_iter().map(|path| (at, path)));
    }
    out
}
