//! `--set PATH=VALUE` overrides, and the bookkeeping that maps every position of
//! the overridden text back to the file or to the `--set` argument it came from.
//!
//! In: the scenario text and the override arguments in order. Out: a
//! [`Document`] whose `text` is the scenario with each override spliced in
//! (the value at PATH replaced, or the field inserted into its struct when the
//! file leaves it out), ready for the typed parse. Stays true: every byte of
//! `text` maps to exactly one origin (the file, or one argument), so an error
//! anywhere names the right line and column; the typed parse validates an
//! override exactly like the file (an unknown key becomes `ron`'s "unexpected
//! field ..., expected one of ..." for that level).

use std::path::{Path, PathBuf};

use super::error::{Location, Origin, ScenarioError};
use super::tree::{self, Lookup, NodeKind, Segment};

/// One applied splice, in the coordinates of the text just before it.
#[derive(Debug, Clone)]
struct Splice {
    /// Byte offset where the old text started.
    at: usize,
    /// Bytes removed.
    old_len: usize,
    /// Bytes inserted.
    new_len: usize,
    /// Which override (index into `Document::overrides`).
    argument: usize,
    /// Byte offset, inside the inserted text, where the VALUE starts.
    value_in_new: usize,
    /// Byte offset, inside the argument, where the VALUE starts.
    value_in_argument: usize,
}

/// A scenario text with its overrides applied and the map back to the sources.
#[derive(Debug, Clone)]
pub struct Document {
    /// The scenario file's path as the user gave it (for messages).
    pub path: PathBuf,
    /// The file's text.
    pub original: String,
    /// The text after every override.
    pub text: String,
    /// The override arguments, verbatim, in order.
    pub overrides: Vec<String>,
    splices: Vec<Splice>,
}

impl Document {
    /// A document with no override yet.
    pub fn new(path: &Path, text: String) -> Self {
        Self { path: path.to_path_buf(), original: text.clone(), text, overrides: Vec::new(), splices: Vec::new() }
    }

    /// Applies one `PATH=VALUE` argument.
    ///
    /// Errors: malformed argument or value, an index past the end of a list, a
    /// key into something that is not a struct. A missing key is inserted (the
    /// typed parse then rejects it if the schema does not know it). The
    /// current text must already parse as RON (else the caller reports the
    /// file's syntax error first).
    pub fn apply(&mut self, argument: &str) -> Result<(), ScenarioError> {
        let bad = |problem: String| ScenarioError::Override { argument: argument.to_string(), problem };
        let Some(eq) = argument.find('=') else {
            return Err(bad("expected PATH=VALUE, e.g. material.poisson_ratio=0.45".into()));
        };
        let path_text = argument[..eq].trim();
        let raw_value = &argument[eq + 1..];
        let value = raw_value.trim();
        let value_in_argument = eq + 1 + (raw_value.len() - raw_value.trim_start().len());
        let path = tree::parse_path(path_text)
            .ok_or_else(|| bad(format!("`{path_text}` is not a field path (expected e.g. spatulas[0].shape.width_mm)")))?;
        if value.is_empty() {
            return Err(bad("the value is empty".into()));
        }
        if let Err(e) = tree::parse(value) {
            return Err(bad(format!("the value `{value}` is not one RON value: {} at column {}", e.message, e.offset + 1)));
        }
        let root = tree::parse(&self.text).map_err(|e| bad(format!("the scenario text does not parse: {}", e.message)))?;
        let argument_index = self.overrides.len();
        let splice = match root.lookup(&path) {
            Lookup::Found(node) => Splice {
                at: node.start,
                old_len: node.end - node.start,
                new_len: value.len(),
                argument: argument_index,
                value_in_new: 0,
                value_in_argument,
            },
            Lookup::Missing { depth, parent } => {
                let inserted = self.missing_field(&path, depth, parent, value).map_err(bad)?;
                self.splices.push(Splice { argument: argument_index, value_in_argument, ..inserted });
                self.overrides.push(argument.to_string());
                return Ok(());
            }
            Lookup::Mismatch { depth, node } => return Err(bad(mismatch_problem(&path, depth, node))),
        };
        self.text.replace_range(splice.at..splice.at + splice.old_len, value);
        self.splices.push(splice);
        self.overrides.push(argument.to_string());
        Ok(())
    }

    /// Inserts the fields `path[depth..]` that the scenario lacks, nested, with `value` innermost, at the end of
    /// struct `parent`; returns the splice made (its argument fields for the caller to fill).
    fn missing_field(&mut self, path: &[Segment], depth: usize, parent: &tree::Node, value: &str) -> Result<Splice, String> {
        let rest = &path[depth..];
        let mut keys = Vec::with_capacity(rest.len());
        for seg in rest {
            match seg {
                Segment::Key(k) => keys.push(k.as_str()),
                Segment::Index(_) => {
                    return Err(format!(
                        "`{}` is not in the scenario, so it has no element to index; set the whole field instead",
                        tree::path_to_string(&path[..depth + 1])
                    ));
                }
            }
        }
        let NodeKind::Struct { fields, close, .. } = &parent.kind else {
            return Err("internal: a missing key outside a struct".into());
        };
        let needs_comma = match fields.last() {
            Some(last) => !self.text[last.value.end..*close].contains(','),
            None => false,
        };
        let mut inserted = String::new();
        if needs_comma {
            inserted.push_str(", ");
        }
        for (i, k) in keys.iter().enumerate() {
            inserted.push_str(k);
            inserted.push_str(": ");
            if i + 1 < keys.len() {
                inserted.push('(');
            }
        }
        let value_in_new = inserted.len();
        inserted.push_str(value);
        for _ in 1..keys.len() {
            inserted.push(')');
        }
        inserted.push_str(", ");
        let at = *close;
        self.text.insert_str(at, &inserted);
        Ok(Splice { at, old_len: 0, new_len: inserted.len(), argument: 0, value_in_new, value_in_argument: 0 })
    }

    /// Where a byte offset of `text` came from.
    pub fn locate(&self, offset: usize) -> Location {
        let mut p = offset;
        for s in self.splices.iter().rev() {
            if p >= s.at && p < s.at + s.new_len {
                let argument = &self.overrides[s.argument];
                let inner = p - s.at;
                let column = if inner >= s.value_in_new {
                    let in_arg = (s.value_in_argument + inner - s.value_in_new).min(argument.len());
                    1 + argument.get(..in_arg).map_or(in_arg, |a| a.chars().count())
                } else {
                    1
                };
                return Location { origin: Origin::Override(argument.clone()), line: 1, column };
            }
            if p >= s.at + s.new_len {
                p = p - s.new_len + s.old_len;
            }
        }
        let (line, column) = tree::line_col(&self.original, p);
        Location { origin: Origin::File(self.path.clone()), line, column }
    }

    /// Where a field path's value sits (or, when the path is absent, the nearest
    /// enclosing value that exists; the document's start when even the outline fails).
    pub fn locate_path(&self, path: &str) -> Location {
        let Ok(root) = tree::parse(&self.text) else { return self.locate(0) };
        let Some(segments) = tree::parse_path(path) else { return self.locate(root.start) };
        match root.lookup(&segments) {
            Lookup::Found(node) => self.locate(node.start),
            Lookup::Missing { parent, .. } => self.locate(parent.start),
            Lookup::Mismatch { node, .. } => self.locate(node.start),
        }
    }

    /// The field path at a byte offset of `text` (empty when outside every field).
    pub fn path_at(&self, offset: usize) -> String {
        match tree::parse(&self.text) {
            Ok(root) => tree::path_to_string(&root.path_at(offset)),
            Err(_) => String::new(),
        }
    }
}

/// Why `path` cannot be followed past `path[..depth]`, where `node` stands.
fn mismatch_problem(path: &[Segment], depth: usize, node: &tree::Node) -> String {
    let here = tree::path_to_string(&path[..depth]);
    let here = if here.is_empty() { "the scenario".to_string() } else { format!("`{here}`") };
    match (&path[depth], &node.kind) {
        (Segment::Index(i), NodeKind::List { items } | NodeKind::Tuple { items, .. }) => {
            format!("index {i} is out of range: {here} has {} element(s)", items.len())
        }
        (Segment::Index(i), _) => format!("{here} is not a list or tuple, so `[{i}]` does not apply"),
        (Segment::Key(k), NodeKind::Struct { .. }) => format!("no field `{k}` in {here}"),
        (Segment::Key(k), NodeKind::Tuple { name: Some(n), .. }) => {
            format!("{here} is `{n}(...)` with positional values; use an index like [0] instead of `.{k}`")
        }
        (Segment::Key(k), _) => format!("{here} is a single value with no fields, so `.{k}` does not apply"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const DOC: &str = "(\n  a: 1,\n  b: (c: 2.0, d: [1, 2]),\n  e: (x: 1)\n)";

    fn doc() -> Document {
        Document::new(Path::new("s.ron"), DOC.to_string())
    }

    #[test]
    fn replaces_existing_values() {
        let mut d = doc();
        d.apply("b.c=3.5").expect("b.c exists");
        d.apply("b.d[1] = 7").expect("b.d[1] exists");
        assert_eq!(d.text, "(\n  a: 1,\n  b: (c: 3.5, d: [1, 7]),\n  e: (x: 1)\n)");
    }

    #[test]
    fn inserts_missing_fields_into_their_struct() {
        let mut d = doc();
        d.apply("e.y=2").expect("insert into a struct without trailing comma");
        d.apply("f.g=Gpu").expect("insert nested");
        assert_eq!(d.text, "(\n  a: 1,\n  b: (c: 2.0, d: [1, 2]),\n  e: (x: 1, y: 2, )\n, f: (g: Gpu), )");
        assert!(tree::parse(&d.text).is_ok(), "the result must stay valid RON: {}", d.text);
    }

    #[test]
    fn positions_map_back_to_file_or_argument() {
        let mut d = doc();
        d.apply("b.c=123456").expect("apply");
        // `e` on line 4 of the original, after a splice that grew line 3.
        let e = d.text.find("e:").expect("e");
        let loc = d.locate(e);
        assert_eq!((loc.origin.clone(), loc.line, loc.column), (Origin::File("s.ron".into()), 4, 3), "{loc}");
        let v = d.text.find("123456").expect("value") + 2;
        let loc = d.locate(v);
        assert_eq!(loc.origin, Origin::Override("b.c=123456".into()));
        assert_eq!(loc.column, 7, "column of the third char of the value inside the argument");
        assert_eq!(d.path_at(v), "b.c");
        assert_eq!(d.locate_path("b.d[1]").line, 3);
    }

    #[test]
    fn bad_arguments_are_errors_naming_the_problem() {
        let cases = [
            ("b.c", "PATH=VALUE"),
            ("b..c=1", "not a field path"),
            ("b.c=", "empty"),
            ("b.c=(1,", "not one RON value"),
            ("b.d[5]=1", "out of range: `b.d` has 2"),
            ("a.x=1", "single value"),
            ("z[0]=1", "no element to index"),
        ];
        for (arg, want) in cases {
            let err = doc().apply(arg).expect_err(arg).to_string();
            assert!(err.contains(want) && err.contains(arg), "--set {arg}: got `{err}`, want it to contain `{want}`");
        }
    }
}
