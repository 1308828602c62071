//! A zero-copy reader over a whole file in memory, shared by the text parsers.
//!
//! In: the file's bytes. Out: whitespace-separated tokens (slices of the input,
//! no allocation), numbers parsed from them, raw binary blocks, and the 1-based
//! line of every token for error messages. Stays true: the cursor never reads
//! past the end (every access is checked) and every failure is a
//! [`MeshFileError`] naming the file and line (or byte offset in binary data).

use std::path::Path;

use super::error::{MeshFileError, MeshFileErrorKind as K};

/// Byte order of a binary block.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Endian {
    Little,
    Big,
}

impl Endian {
    #[inline]
    pub fn u16(self, b: [u8; 2]) -> u16 {
        match self {
            Endian::Little => u16::from_le_bytes(b),
            Endian::Big => u16::from_be_bytes(b),
        }
    }
    #[inline]
    pub fn u32(self, b: [u8; 4]) -> u32 {
        match self {
            Endian::Little => u32::from_le_bytes(b),
            Endian::Big => u32::from_be_bytes(b),
        }
    }
    #[inline]
    pub fn u64(self, b: [u8; 8]) -> u64 {
        match self {
            Endian::Little => u64::from_le_bytes(b),
            Endian::Big => u64::from_be_bytes(b),
        }
    }
    #[inline]
    pub fn f64(self, b: [u8; 8]) -> f64 {
        f64::from_bits(self.u64(b))
    }
    #[inline]
    pub fn f32(self, b: [u8; 4]) -> f32 {
        f32::from_bits(self.u32(b))
    }
}

/// Reads `N` bytes at `at` of `b` (the caller has checked the length).
#[inline]
pub(crate) fn array<const N: usize>(b: &[u8], at: usize) -> [u8; N] {
    let mut out = [0u8; N];
    out.copy_from_slice(&b[at..at + N]);
    out
}

/// A capacity hint that cannot be abused by a lying header: at most what the
/// remaining bytes could hold at `min_bytes` per item.
#[inline]
pub(crate) fn capacity(announced: u64, remaining_bytes: usize, min_bytes: usize) -> usize {
    (announced.min(usize::MAX as u64) as usize).min(remaining_bytes / min_bytes.max(1))
}

/// Text/binary cursor over a file held in memory.
pub(crate) struct Cursor<'a> {
    pub path: &'a Path,
    pub data: &'a [u8],
    pub pos: usize,
    /// 1-based line at `pos`.
    pub line: usize,
    /// A byte that starts a comment running to the end of the line, if the format has one.
    pub comment: Option<u8>,
}

impl<'a> Cursor<'a> {
    pub fn new(path: &'a Path, data: &'a [u8]) -> Self {
        Self { path, data, pos: 0, line: 1, comment: None }
    }

    /// An error at the given line.
    pub fn err_at(&self, line: usize, kind: K) -> MeshFileError {
        MeshFileError::at_line(self.path, line, kind)
    }

    /// An error at the current line.
    pub fn err(&self, kind: K) -> MeshFileError {
        self.err_at(self.line, kind)
    }

    /// "unexpected end of file (expected ...)".
    pub fn eof(&self, expected: impl Into<String>) -> MeshFileError {
        self.err(K::UnexpectedEof { expected: expected.into() })
    }

    /// Skips whitespace and comments, counting lines.
    #[inline]
    pub fn skip_ws(&mut self) {
        let data = self.data;
        while self.pos < data.len() {
            let c = data[self.pos];
            if c == b'\n' {
                self.line += 1;
            } else if Some(c) == self.comment {
                while self.pos < data.len() && data[self.pos] != b'\n' {
                    self.pos += 1;
                }
                continue;
            } else if !c.is_ascii_whitespace() {
                return;
            }
            self.pos += 1;
        }
    }

    /// The next token and its line, or `None` at the end of the file.
    #[inline]
    pub fn token(&mut self) -> Option<(&'a [u8], usize)> {
        self.skip_ws();
        let data = self.data;
        let start = self.pos;
        while self.pos < data.len() && !data[self.pos].is_ascii_whitespace() && Some(data[self.pos]) != self.comment {
            self.pos += 1;
        }
        if self.pos == start { None } else { Some((&data[start..self.pos], self.line)) }
    }

    /// The next token; the end of the file is an error naming what was expected.
    #[inline]
    pub fn need(&mut self, expected: &str) -> Result<(&'a [u8], usize), MeshFileError> {
        match self.token() {
            Some(t) => Ok(t),
            None => Err(self.eof(expected)),
        }
    }

    /// The next token must be exactly `keyword`.
    pub fn keyword(&mut self, keyword: &str) -> Result<usize, MeshFileError> {
        let (tok, line) = self.need(keyword)?;
        if tok != keyword.as_bytes() {
            return Err(self.err_at(line, K::Expected { expected: keyword.into(), found: shown(tok) }));
        }
        Ok(line)
    }

    /// A signed integer token.
    #[inline]
    pub fn int(&mut self, what: impl FnOnce() -> String) -> Result<i64, MeshFileError> {
        self.skip_ws();
        if self.pos >= self.data.len() {
            return Err(self.eof(what()));
        }
        let (tok, line) = self.need("")?;
        parse_int(tok).ok_or_else(|| self.err_at(line, K::BadNumber { token: shown(tok), what: what() }))
    }

    /// A non-negative integer token.
    #[inline]
    pub fn uint(&mut self, what: impl FnOnce() -> String) -> Result<u64, MeshFileError> {
        self.skip_ws();
        if self.pos >= self.data.len() {
            return Err(self.eof(what()));
        }
        let (tok, line) = self.need("")?;
        match parse_int(tok) {
            Some(v) if v >= 0 => Ok(v as u64),
            _ => Err(self.err_at(line, K::BadNumber { token: shown(tok), what: what() })),
        }
    }

    /// A floating-point token (may be non-finite: the caller decides).
    #[inline]
    pub fn float(&mut self, what: impl FnOnce() -> String) -> Result<f64, MeshFileError> {
        self.skip_ws();
        if self.pos >= self.data.len() {
            return Err(self.eof(what()));
        }
        let (tok, line) = self.need("")?;
        parse_float(tok).ok_or_else(|| self.err_at(line, K::BadNumber { token: shown(tok), what: what() }))
    }

    /// Moves past the end of the current line (past its `\n`).
    pub fn skip_line(&mut self) {
        while self.pos < self.data.len() {
            let c = self.data[self.pos];
            self.pos += 1;
            if c == b'\n' {
                self.line += 1;
                return;
            }
        }
    }

    /// The rest of the current line (without `\r\n`), moving past it.
    pub fn rest_of_line(&mut self) -> &'a [u8] {
        let start = self.pos;
        while self.pos < self.data.len() && self.data[self.pos] != b'\n' {
            self.pos += 1;
        }
        let mut line = &self.data[start..self.pos];
        if let [head @ .., b'\r'] = line {
            line = head;
        }
        self.skip_line();
        line
    }

    /// `n` raw bytes (a binary block), counting the newlines inside it so that
    /// later line numbers stay those of a text editor.
    pub fn bytes(&mut self, n: usize, expected: &str) -> Result<&'a [u8], MeshFileError> {
        let end = self.pos.checked_add(n).filter(|&e| e <= self.data.len()).ok_or_else(|| {
            MeshFileError::at_offset(self.path, self.data.len(), K::UnexpectedEof { expected: expected.into() })
        })?;
        let block = &self.data[self.pos..end];
        self.line += block.iter().filter(|&&c| c == b'\n').count();
        self.pos = end;
        Ok(block)
    }

    /// Bytes left after the cursor.
    pub fn remaining(&self) -> usize {
        self.data.len() - self.pos
    }
}

/// A token shown in a message: lossy UTF-8, at most 40 characters.
pub(crate) fn shown(tok: &[u8]) -> String {
    let s = String::from_utf8_lossy(tok);
    if s.chars().count() > 40 { format!("{}...", s.chars().take(40).collect::<String>()) } else { s.into_owned() }
}

/// Parses a decimal integer with an optional sign; `None` on anything else or overflow.
#[inline]
pub(crate) fn parse_int(tok: &[u8]) -> Option<i64> {
    let (neg, digits) = match tok.first()? {
        b'-' => (true, &tok[1..]),
        b'+' => (false, &tok[1..]),
        _ => (false, tok),
    };
    if digits.is_empty() {
        return None;
    }
    let mut v: i64 = 0;
    for &c in digits {
        let d = c.wrapping_sub(b'0');
        if d > 9 {
            return None;
        }
        v = v.checked_mul(10)?.checked_sub(d as i64)?;
    }
    if neg { Some(v) } else { v.checked_neg() }
}

/// Parses a floating-point number (Rust's correctly rounded parser).
#[inline]
pub(crate) fn parse_float(tok: &[u8]) -> Option<f64> {
    std::str::from_utf8(tok).ok()?.parse::<f64>().ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn integers_parse_with_sign_and_reject_overflow() {
        assert_eq!(parse_int(b"0"), Some(0));
        assert_eq!(parse_int(b"-12"), Some(-12));
        assert_eq!(parse_int(b"+7"), Some(7));
        assert_eq!(parse_int(b"-9223372036854775808"), Some(i64::MIN));
        assert_eq!(parse_int(b"9223372036854775808"), None, "overflow must be an error, not a wrap");
        assert_eq!(parse_int(b"1.5"), None);
        assert_eq!(parse_int(b"-"), None);
        assert_eq!(parse_int(b""), None);
    }

    #[test]
    fn tokens_carry_their_line_and_skip_comments() {
        let data = b"a b\n# note\n  c\r\nd";
        let mut c = Cursor::new(Path::new("x"), data);
        c.comment = Some(b'#');
        let toks: Vec<(String, usize)> =
            std::iter::from_fn(|| c.token().map(|(t, l)| (String::from_utf8_lossy(t).into_owned(), l))).collect();
        assert_eq!(toks, vec![("a".into(), 1), ("b".into(), 1), ("c".into(), 3), ("d".into(), 4)]);
    }

    #[test]
    fn binary_block_past_end_is_an_error() {
        let mut c = Cursor::new(Path::new("x"), b"abc");
        assert!(c.bytes(4, "data").is_err());
        assert_eq!(c.bytes(3, "data").expect("three bytes are there"), b"abc");
    }
}
