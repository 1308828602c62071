//! A spanned outline of a RON document: where every value sits in the text.
//!
//! In: RON text. Out: a [`Node`] tree with byte spans (structs with named fields,
//! tuples, lists, maps, atoms), and lookups by field path
//! (`spatulas[1].shape.thickness_mm`). The typed parse is `ron`'s; this outline
//! only serves to place `--set` overrides and to name the line and field of an
//! error. Stays true: spans are byte ranges on char boundaries of the text, a
//! child's span lies inside its parent's, and parsing never panics (depth is
//! bounded by [`MAX_DEPTH`]).

/// Deepest nesting the outline accepts (ron's own limit is 128).
pub const MAX_DEPTH: usize = 128;

/// One value of the document with its byte span `[start, end)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// What the value is.
    pub kind: NodeKind,
    /// Byte offset of its first character.
    pub start: usize,
    /// Byte offset one past its last character.
    pub end: usize,
}

/// The shape of a value.
#[derive(Debug, Clone, PartialEq)]
pub enum NodeKind {
    /// A number, string, char, boolean or bare identifier (unit variant, `None`).
    Atom,
    /// `Name?(key: value, ...)`; `close` is the offset of the `)`.
    Struct { name: Option<String>, fields: Vec<Field>, close: usize },
    /// `Name?(value, ...)` (tuples, tuple variants, `Some(x)`).
    Tuple { name: Option<String>, items: Vec<Node>, close: usize },
    /// `[value, ...]`.
    List { items: Vec<Node> },
    /// `{key: value, ...}`.
    Map { entries: Vec<(Node, Node)> },
}

/// A named field of a struct.
#[derive(Debug, Clone, PartialEq)]
pub struct Field {
    /// The field's identifier.
    pub key: String,
    /// Byte offset of the identifier.
    pub key_start: usize,
    /// The value.
    pub value: Node,
}

/// One step of a field path.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Segment {
    /// A named field (`shape`).
    Key(String),
    /// A position in a list or tuple (`[1]`).
    Index(usize),
}

/// Formats a path as `a.b[2].c`.
pub fn path_to_string(path: &[Segment]) -> String {
    let mut s = String::new();
    for seg in path {
        match seg {
            Segment::Key(k) => {
                if !s.is_empty() {
                    s.push('.');
                }
                s.push_str(k);
            }
            Segment::Index(i) => {
                s.push('[');
                s.push_str(&i.to_string());
                s.push(']');
            }
        }
    }
    s
}

/// Parses `a.b[2].c` into segments; `None` when malformed.
pub fn parse_path(text: &str) -> Option<Vec<Segment>> {
    let mut out = Vec::new();
    let bytes = text.as_bytes();
    let mut i = 0;
    let mut expect_key = true;
    while i < bytes.len() {
        match bytes[i] {
            b'[' => {
                let close = text[i..].find(']')? + i;
                let index: usize = text[i + 1..close].trim().parse().ok()?;
                out.push(Segment::Index(index));
                i = close + 1;
                expect_key = false;
            }
            b'.' => {
                if expect_key {
                    return None;
                }
                i += 1;
                expect_key = true;
            }
            _ => {
                if !expect_key && !out.is_empty() {
                    return None;
                }
                let end = text[i..].find(['.', '[']).map_or(text.len(), |e| e + i);
                let key = &text[i..end];
                if key.is_empty() || !key.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
                    return None;
                }
                out.push(Segment::Key(key.to_string()));
                i = end;
                expect_key = false;
            }
        }
    }
    if out.is_empty() || expect_key && text.ends_with('.') {
        return None;
    }
    Some(out)
}

/// Why the outline could not be built.
#[derive(Debug, Clone, PartialEq)]
pub struct OutlineError {
    /// Byte offset of the problem.
    pub offset: usize,
    /// What was wrong.
    pub message: String,
}

/// Builds the outline of a whole RON document (a leading `#![enable(...)]` is skipped).
pub fn parse(text: &str) -> Result<Node, OutlineError> {
    let mut p = Parser { text, bytes: text.as_bytes(), pos: 0 };
    p.skip_ws()?;
    while p.bytes[p.pos..].starts_with(b"#!") {
        let close = p.text[p.pos..]
            .find(']')
            .ok_or_else(|| p.err("unterminated `#![...]` attribute"))?;
        p.pos += close + 1;
        p.skip_ws()?;
    }
    let node = p.value(0)?;
    p.skip_ws()?;
    if p.pos != p.bytes.len() {
        return Err(p.err("trailing characters after the document"));
    }
    Ok(node)
}

struct Parser<'a> {
    text: &'a str,
    bytes: &'a [u8],
    pos: usize,
}

impl Parser<'_> {
    fn err(&self, message: &str) -> OutlineError {
        OutlineError { offset: self.pos, message: message.to_string() }
    }

    fn peek(&self) -> Option<u8> {
        self.bytes.get(self.pos).copied()
    }

    fn skip_ws(&mut self) -> Result<(), OutlineError> {
        loop {
            match self.peek() {
                Some(c) if c.is_ascii_whitespace() => self.pos += 1,
                Some(b'/') if self.bytes.get(self.pos + 1) == Some(&b'/') => {
                    while let Some(c) = self.peek() {
                        if c == b'\n' {
                            break;
                        }
                        self.pos += 1;
                    }
                }
                Some(b'/') if self.bytes.get(self.pos + 1) == Some(&b'*') => {
                    let mut depth = 0usize;
                    loop {
                        if self.bytes[self.pos..].starts_with(b"/*") {
                            depth += 1;
                            self.pos += 2;
                        } else if self.bytes[self.pos..].starts_with(b"*/") {
                            depth -= 1;
                            self.pos += 2;
                            if depth == 0 {
                                break;
                            }
                        } else if self.pos >= self.bytes.len() {
                            return Err(self.err("unterminated block comment"));
                        } else {
                            self.pos += 1;
                        }
                    }
                }
                _ => return Ok(()),
            }
        }
    }

    fn ident(&mut self) -> Option<String> {
        let start = self.pos;
        if self.bytes[self.pos..].starts_with(b"r#") {
            self.pos += 2;
        }
        let body = self.pos;
        while let Some(c) = self.peek() {
            if c.is_ascii_alphanumeric() || c == b'_' || (c == b'-' && self.pos > body) || c >= 0x80 {
                self.pos += 1;
            } else {
                break;
            }
        }
        // `-` only inside raw identifiers; a plain identifier stops before it.
        if start == body
            && let Some(dash) = self.text[body..self.pos].find('-')
        {
            self.pos = body + dash;
        }
        if self.pos == body {
            self.pos = start;
            return None;
        }
        Some(self.text[body..self.pos].to_string())
    }

    fn value(&mut self, depth: usize) -> Result<Node, OutlineError> {
        if depth > MAX_DEPTH {
            return Err(self.err("nesting deeper than 128"));
        }
        let start = self.pos;
        match self.peek() {
            None => Err(self.err("expected a value, found the end of the text")),
            Some(b'(') => self.parens(start, None, depth),
            Some(b'[') => self.list(start, depth),
            Some(b'{') => self.map(start, depth),
            Some(b'"') => {
                self.string()?;
                Ok(Node { kind: NodeKind::Atom, start, end: self.pos })
            }
            Some(b'\'') => {
                self.quoted(b'\'', "unterminated char")?;
                Ok(Node { kind: NodeKind::Atom, start, end: self.pos })
            }
            Some(c) if c == b'+' || c == b'-' || c == b'.' || c.is_ascii_digit() => {
                while let Some(c) = self.peek() {
                    if c.is_ascii_alphanumeric() || matches!(c, b'+' | b'-' | b'.' | b'_') {
                        self.pos += 1;
                    } else {
                        break;
                    }
                }
                Ok(Node { kind: NodeKind::Atom, start, end: self.pos })
            }
            Some(b'r')
                if self.bytes[self.pos..].starts_with(b"r\"")
                    || self.bytes[self.pos..].starts_with(b"r#\"")
                    || self.bytes[self.pos..].starts_with(b"r##") =>
            {
                self.raw_string()?;
                Ok(Node { kind: NodeKind::Atom, start, end: self.pos })
            }
            Some(b'b') if self.bytes.get(self.pos + 1) == Some(&b'"') => {
                self.pos += 1;
                self.string()?;
                Ok(Node { kind: NodeKind::Atom, start, end: self.pos })
            }
            Some(_) => {
                let Some(name) = self.ident() else {
                    return Err(self.err("expected a value"));
                };
                let after = self.pos;
                self.skip_ws()?;
                if self.peek() == Some(b'(') {
                    self.parens(start, Some(name), depth)
                } else {
                    self.pos = after;
                    Ok(Node { kind: NodeKind::Atom, start, end: self.pos })
                }
            }
        }
    }

    /// `[a, b, ...]` from its opening bracket.
    fn list(&mut self, start: usize, depth: usize) -> Result<Node, OutlineError> {
        self.pos += 1;
        let mut items = Vec::new();
        loop {
            self.skip_ws()?;
            if self.peek() == Some(b']') {
                self.pos += 1;
                break;
            }
            items.push(self.value(depth + 1)?);
            self.skip_ws()?;
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b']') => {}
                _ => return Err(self.err("expected `,` or `]` in a list")),
            }
        }
        Ok(Node { kind: NodeKind::List { items }, start, end: self.pos })
    }

    /// `{key: value, ...}` from its opening brace.
    fn map(&mut self, start: usize, depth: usize) -> Result<Node, OutlineError> {
        self.pos += 1;
        let mut entries = Vec::new();
        loop {
            self.skip_ws()?;
            if self.peek() == Some(b'}') {
                self.pos += 1;
                break;
            }
            let key = self.value(depth + 1)?;
            self.skip_ws()?;
            if self.peek() != Some(b':') {
                return Err(self.err("expected `:` in a map"));
            }
            self.pos += 1;
            self.skip_ws()?;
            let value = self.value(depth + 1)?;
            entries.push((key, value));
            self.skip_ws()?;
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b'}') => {}
                _ => return Err(self.err("expected `,` or `}` in a map")),
            }
        }
        Ok(Node { kind: NodeKind::Map { entries }, start, end: self.pos })
    }

    /// A `"string"` (`quote` `"`) or `'c'` literal (`quote` `'`) from its opening quote, escapes skipped.
    fn quoted(&mut self, quote: u8, unterminated: &'static str) -> Result<(), OutlineError> {
        self.pos += 1;
        loop {
            match self.peek() {
                None => return Err(self.err(unterminated)),
                Some(b'\\') => self.pos += 2,
                Some(c) if c == quote => {
                    self.pos += 1;
                    break;
                }
                Some(_) => self.pos += 1,
            }
        }
        self.pos = self.pos.min(self.bytes.len());
        Ok(())
    }

    fn string(&mut self) -> Result<(), OutlineError> {
        self.quoted(b'"', "unterminated string")
    }

    fn raw_string(&mut self) -> Result<(), OutlineError> {
        self.pos += 1;
        let mut hashes = 0;
        while self.peek() == Some(b'#') {
            hashes += 1;
            self.pos += 1;
        }
        if self.peek() != Some(b'"') {
            return Err(self.err("malformed raw string"));
        }
        self.pos += 1;
        let mut closing = String::from("\"");
        closing.push_str(&"#".repeat(hashes));
        match self.text.get(self.pos..).and_then(|rest| rest.find(&closing)) {
            Some(at) => {
                self.pos += at + closing.len();
                Ok(())
            }
            None => Err(self.err("unterminated raw string")),
        }
    }

    /// `(` ... `)`: a struct when the first entry is `ident:`, a tuple otherwise.
    fn parens(&mut self, start: usize, name: Option<String>, depth: usize) -> Result<Node, OutlineError> {
        self.pos += 1;
        self.skip_ws()?;
        let is_struct = {
            let save = self.pos;
            let named = self.ident().is_some() && {
                let _ = self.skip_ws();
                self.peek() == Some(b':') && self.bytes.get(self.pos + 1) != Some(&b':')
            };
            self.pos = save;
            named
        };
        if is_struct || self.peek() == Some(b')') {
            let mut fields = Vec::new();
            loop {
                self.skip_ws()?;
                if self.peek() == Some(b')') {
                    let close = self.pos;
                    self.pos += 1;
                    return Ok(Node { kind: NodeKind::Struct { name, fields, close }, start, end: self.pos });
                }
                let key_start = self.pos;
                let key = self.ident().ok_or_else(|| self.err("expected a field name"))?;
                self.skip_ws()?;
                if self.peek() != Some(b':') {
                    return Err(self.err("expected `:` after a field name"));
                }
                self.pos += 1;
                self.skip_ws()?;
                let value = self.value(depth + 1)?;
                fields.push(Field { key, key_start, value });
                self.skip_ws()?;
                match self.peek() {
                    Some(b',') => self.pos += 1,
                    Some(b')') => {}
                    _ => return Err(self.err("expected `,` or `)` after a field")),
                }
            }
        }
        let mut items = Vec::new();
        loop {
            self.skip_ws()?;
            if self.peek() == Some(b')') {
                let close = self.pos;
                self.pos += 1;
                return Ok(Node { kind: NodeKind::Tuple { name, items, close }, start, end: self.pos });
            }
            items.push(self.value(depth + 1)?);
            self.skip_ws()?;
            match self.peek() {
                Some(b',') => self.pos += 1,
                Some(b')') => {}
                _ => return Err(self.err("expected `,` or `)` in a tuple")),
            }
        }
    }
}

/// What a path lookup found.
#[derive(Debug, PartialEq)]
pub enum Lookup<'n> {
    /// The whole path exists.
    Found(&'n Node),
    /// The path stops existing after `depth` segments, inside `parent`.
    Missing { depth: usize, parent: &'n Node },
    /// Segment `depth` cannot apply to the node it reaches (e.g. a key on a list,
    /// an index past the end).
    Mismatch { depth: usize, node: &'n Node },
}

impl Node {
    /// Follows a path from this node.
    pub fn lookup(&self, path: &[Segment]) -> Lookup<'_> {
        let mut node = self;
        for (depth, seg) in path.iter().enumerate() {
            let next = match (seg, &node.kind) {
                (Segment::Key(k), NodeKind::Struct { fields, .. }) => match fields.iter().find(|f| &f.key == k) {
                    Some(f) => &f.value,
                    None => return Lookup::Missing { depth, parent: node },
                },
                (Segment::Key(_), NodeKind::Tuple { name: Some(n), items, .. }) if n == "Some" && items.len() == 1 => {
                    // `Some((a: 1))`: look through the option.
                    match items[0].lookup(&path[depth..]) {
                        Lookup::Found(n) => return Lookup::Found(n),
                        Lookup::Missing { depth: d, parent } => return Lookup::Missing { depth: depth + d, parent },
                        Lookup::Mismatch { depth: d, node } => return Lookup::Mismatch { depth: depth + d, node },
                    }
                }
                (Segment::Index(i), NodeKind::List { items } | NodeKind::Tuple { items, .. }) => match items.get(*i) {
                    Some(n) => n,
                    None => return Lookup::Mismatch { depth, node },
                },
                _ => return Lookup::Mismatch { depth, node },
            };
            node = next;
        }
        Lookup::Found(node)
    }

    /// The path of the deepest node whose span holds `offset` (empty for the root).
    pub fn path_at(&self, offset: usize) -> Vec<Segment> {
        let mut path = Vec::new();
        let mut node = self;
        'descend: loop {
            match &node.kind {
                NodeKind::Struct { fields, .. } => {
                    for f in fields {
                        if offset >= f.key_start && offset < f.value.end.max(f.key_start + 1) {
                            path.push(Segment::Key(f.key.clone()));
                            node = &f.value;
                            continue 'descend;
                        }
                    }
                }
                NodeKind::Tuple { items, .. } | NodeKind::List { items } if !items.is_empty() => {
                    let is_some = matches!(&node.kind, NodeKind::Tuple { name: Some(n), .. } if n == "Some");
                    for (i, item) in items.iter().enumerate() {
                        if offset >= item.start && offset < item.end {
                            if !is_some {
                                path.push(Segment::Index(i));
                            }
                            node = item;
                            continue 'descend;
                        }
                    }
                }
                _ => {}
            }
            return path;
        }
    }
}

/// The offset of the next token at or after `offset` (whitespace and comments
/// skipped); `offset` itself when a comment is unterminated.
pub fn skip_trivia(text: &str, offset: usize) -> usize {
    let mut p = Parser { text, bytes: text.as_bytes(), pos: offset.min(text.len()) };
    match p.skip_ws() {
        Ok(()) => p.pos,
        Err(_) => offset,
    }
}

/// 1-based line and column (in chars) of a byte offset, as `ron` counts them.
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = 1 + before.bytes().filter(|&b| b == b'\n').count();
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, 1 + before[line_start..].chars().count())
}

/// Byte offset of a 1-based (line, column) position; clamped to the text.
pub fn offset_of(text: &str, line: usize, col: usize) -> usize {
    let mut offset = 0;
    for _ in 1..line.max(1) {
        match text[offset..].find('\n') {
            Some(i) => offset += i + 1,
            None => return text.len(),
        }
    }
    let rest = &text[offset..];
    let line_end = rest.find('\n').unwrap_or(rest.len());
    match rest[..line_end].char_indices().nth(col.saturating_sub(1)) {
        Some((i, _)) => offset + i,
        None => offset + line_end,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = "// c\n(\n  name: \"a\",\n  mesh: Phantom(preset: \"small\"),\n  spatulas: [ (shape: (length_mm: 1.0)), (shape: (length_mm: -2)) ],\n  pos: (1, 2.5, -3e-2),\n  skull: Some((r: 1)),\n)\n";

    #[test]
    fn outline_finds_nested_fields_and_indices() {
        let root = parse(DOC).expect("valid RON outline");
        let path = parse_path("spatulas[1].shape.length_mm").expect("valid path");
        let Lookup::Found(node) = root.lookup(&path) else { panic!("spatulas[1].shape.length_mm must exist") };
        assert_eq!(&DOC[node.start..node.end], "-2", "span of spatulas[1].shape.length_mm");
        let Lookup::Found(node) = root.lookup(&parse_path("pos[2]").expect("path")) else { panic!("pos[2]") };
        assert_eq!(&DOC[node.start..node.end], "-3e-2");
        let Lookup::Found(node) = root.lookup(&parse_path("skull.r").expect("path")) else { panic!("skull.r through Some") };
        assert_eq!(&DOC[node.start..node.end], "1");
        let Lookup::Found(node) = root.lookup(&parse_path("mesh.preset").expect("path")) else { panic!("mesh.preset") };
        assert_eq!(&DOC[node.start..node.end], "\"small\"");
        assert!(matches!(root.lookup(&parse_path("spatulas[2]").expect("path")), Lookup::Mismatch { depth: 1, .. }));
        assert!(matches!(root.lookup(&parse_path("nope.x").expect("path")), Lookup::Missing { depth: 0, .. }));
    }

    #[test]
    fn path_at_names_the_deepest_field() {
        let root = parse(DOC).expect("outline");
        let at = DOC.find("-2").expect("literal");
        assert_eq!(path_to_string(&root.path_at(at)), "spatulas[1].shape.length_mm");
    }

    #[test]
    fn paths_parse_and_print() {
        for p in ["a", "a.b", "a[0].b_c[12]", "spatulas[0].layout"] {
            assert_eq!(path_to_string(&parse_path(p).expect(p)), p, "round trip of {p}");
        }
        for bad in ["", ".a", "a..b", "a.", "a[x]", "a b", "a]"] {
            assert!(parse_path(bad).is_none(), "{bad:?} must be rejected");
        }
    }

    #[test]
    fn line_col_and_offset_agree() {
        let text = "ab\nçd\n\nx";
        for off in [0, 1, 3, 5, 6, 8, 9] {
            let (l, c) = line_col(text, off);
            assert_eq!(offset_of(text, l, c), off, "offset {off} -> {l}:{c}");
        }
    }

    #[test]
    fn malformed_text_is_an_error_not_a_panic() {
        for bad in ["(", "(a: ", "[1,", "\"abc", "/* x", "(a: 1 b: 2)", "r#\"x", "'"] {
            assert!(parse(bad).is_err(), "{bad:?} must fail");
        }
    }
}
