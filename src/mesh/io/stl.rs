//! STL surfaces: read ASCII and binary, write ASCII.
//!
//! In: binary STL (80-byte header, u32 count, 50 bytes a facet) when the size
//! fits that layout and the file does not read as ASCII; ASCII otherwise
//! (`solid` / `facet normal` / `outer loop` / 3 `vertex` / `endloop` /
//! `endfacet` / `endsolid`, several solids allowed). Out: a [`TriSurface`]
//! whose vertices are the distinct corner positions, merged when bitwise equal
//! (+0 and -0 are one), numbered in order of first appearance. Stays true:
//! facet normals in the file are ignored (the winding defines orientation);
//! errors name the file and line (or byte offset).

use std::collections::HashMap;
use std::fmt::Write as _;
use std::path::Path;

use super::cursor::{Cursor, Endian, array, capacity, shown};
use super::error::{MeshFileError, MeshFileErrorKind as K};
use crate::math::Vec3;
use crate::mesh::TriSurface;

/// Merges bitwise-equal positions; indices in order of first appearance.
struct Welder {
    index: HashMap<[u64; 3], u32>,
    surface: TriSurface,
}

impl Welder {
    fn new(triangles: usize) -> Self {
        Self {
            index: HashMap::with_capacity(triangles / 2 + 3),
            surface: TriSurface { positions: Vec::with_capacity(triangles / 2 + 3), triangles: Vec::with_capacity(triangles) },
        }
    }

    fn vertex(&mut self, p: Vec3) -> u32 {
        // +0.0 and -0.0 are the same point: adding 0.0 turns -0.0 into +0.0.
        let key = [(p.x + 0.0).to_bits(), (p.y + 0.0).to_bits(), (p.z + 0.0).to_bits()];
        let positions = &mut self.surface.positions;
        *self.index.entry(key).or_insert_with(|| {
            positions.push(p);
            (positions.len() - 1) as u32
        })
    }
}

fn looks_ascii(data: &[u8]) -> bool {
    let start = data.iter().position(|b| !b.is_ascii_whitespace()).unwrap_or(data.len());
    let rest = &data[start..];
    rest.len() >= 5 && rest[..5].eq_ignore_ascii_case(b"solid") && {
        // Binary files may start with "solid" too: ASCII ones have "facet" or "endsolid" soon after.
        let head = &rest[..rest.len().min(1000)];
        head.windows(5).any(|w| w.eq_ignore_ascii_case(b"facet")) || head.windows(8).any(|w| w.eq_ignore_ascii_case(b"endsolid"))
    }
}

/// Parses an STL file held in memory; `path` is only used in messages.
pub fn parse(path: &Path, data: &[u8]) -> Result<TriSurface, MeshFileError> {
    let binary_count = (data.len() >= 84).then(|| u32::from_le_bytes(array(data, 80)) as usize);
    let fits_binary = binary_count.is_some_and(|n| n.checked_mul(50).and_then(|b| b.checked_add(84)) == Some(data.len()));
    let surface = if fits_binary && !looks_ascii(data) {
        parse_binary(path, data)?
    } else if looks_ascii(data) {
        parse_ascii(path, data)?
    } else if binary_count.is_some() && !data.starts_with(b"solid") {
        parse_binary(path, data)?
    } else {
        return Err(MeshFileError::new(
            path,
            K::Invalid("neither ASCII STL (starting with \"solid\") nor binary STL (84 + 50 n bytes)".into()),
        ));
    };
    if surface.triangles.is_empty() {
        return Err(MeshFileError::new(path, K::Empty("facets")));
    }
    Ok(surface)
}

fn parse_binary(path: &Path, data: &[u8]) -> Result<TriSurface, MeshFileError> {
    let count = u32::from_le_bytes(array(data, 80)) as u64;
    let mut weld = Welder::new(capacity(count, data.len() - 84, 50));
    let needed = 84 + 50 * count as usize;
    if data.len() < needed {
        return Err(MeshFileError::at_offset(
            path,
            data.len(),
            K::UnexpectedEof { expected: format!("{count} facets of 50 bytes ({needed} bytes in all)") },
        ));
    }
    for (f, rec) in data[84..needed].chunks_exact(50).enumerate() {
        let mut tri = [0u32; 3];
        for (k, corner) in tri.iter_mut().enumerate() {
            let at = 12 + 12 * k;
            let p = Vec3::new(
                Endian::Little.f32(array(rec, at)) as f64,
                Endian::Little.f32(array(rec, at + 4)) as f64,
                Endian::Little.f32(array(rec, at + 8)) as f64,
            );
            if !crate::math::is_finite3(&p) {
                return Err(MeshFileError::at_offset(path, 84 + 50 * f + at, K::NonFiniteCoordinate { node: 3 * f as i64 + k as i64 }));
            }
            *corner = weld.vertex(p);
        }
        weld.surface.triangles.push(tri);
    }
    Ok(weld.surface)
}

fn parse_ascii(path: &Path, data: &[u8]) -> Result<TriSurface, MeshFileError> {
    let mut c = Cursor::new(path, data);
    let mut weld = Welder::new(capacity(data.len() as u64 / 200, data.len(), 1));
    c.keyword("solid")?;
    c.rest_of_line();
    loop {
        let (tok, line) = c.need("facet or endsolid")?;
        match tok {
            b"facet" => {
                c.keyword("normal")?;
                for _ in 0..3 {
                    c.float(|| "facet normal component".into())?;
                }
                c.keyword("outer")?;
                c.keyword("loop")?;
                let mut tri = [0u32; 3];
                for (k, corner) in tri.iter_mut().enumerate() {
                    c.keyword("vertex")?;
                    let vline = c.line;
                    let mut xyz = [0.0; 3];
                    for x in xyz.iter_mut() {
                        *x = c.float(|| format!("coordinate of corner {} of a facet", k + 1))?;
                    }
                    let p = Vec3::new(xyz[0], xyz[1], xyz[2]);
                    if !crate::math::is_finite3(&p) {
                        return Err(c.err_at(vline, K::NonFiniteCoordinate { node: weld.surface.positions.len() as i64 }));
                    }
                    *corner = weld.vertex(p);
                }
                c.keyword("endloop")?;
                c.keyword("endfacet")?;
                weld.surface.triangles.push(tri);
            }
            b"endsolid" => {
                c.rest_of_line();
                match c.token() {
                    None => break,
                    Some((b"solid", _)) => {
                        c.rest_of_line();
                    }
                    Some((other, l)) => {
                        return Err(c.err_at(l, K::Expected { expected: "solid or the end of the file".into(), found: shown(other) }));
                    }
                }
            }
            other => return Err(c.err_at(line, K::Expected { expected: "facet or endsolid".into(), found: shown(other) })),
        }
    }
    Ok(weld.surface)
}

/// Writes ASCII STL with unit facet normals and shortest round-trip numbers
/// (so the f64 coordinates survive, unlike binary STL's f32).
pub fn write(surface: &TriSurface) -> String {
    let mut s = String::with_capacity(64 + 200 * surface.triangles.len());
    s.push_str("solid fissure\n");
    for t in &surface.triangles {
        let [a, b, c] = t.map(|k| surface.positions[k as usize]);
        let n = (b - a).cross(&(c - a));
        let n = if n.norm() > 0.0 { n / n.norm() } else { Vec3::zeros() };
        let _ = writeln!(s, "facet normal {:?} {:?} {:?}\nouter loop", n.x, n.y, n.z);
        for p in [a, b, c] {
            let _ = writeln!(s, "vertex {:?} {:?} {:?}", p.x, p.y, p.z);
        }
        s.push_str("endloop\nendfacet\n");
    }
    s.push_str("endsolid fissure\n");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn binary(facets: &[[[f32; 3]; 3]]) -> Vec<u8> {
        let mut b = vec![0u8; 80];
        b.extend_from_slice(&(facets.len() as u32).to_le_bytes());
        for f in facets {
            b.extend_from_slice(&[0u8; 12]);
            for p in f {
                for x in p {
                    b.extend_from_slice(&x.to_le_bytes());
                }
            }
            b.extend_from_slice(&[0u8; 2]);
        }
        b
    }

    #[test]
    fn binary_merges_shared_corners_including_signed_zero() {
        let data = binary(&[[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]], [[-0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]]);
        let s = parse(Path::new("a.stl"), &data).expect("valid binary");
        assert_eq!(s.positions.len(), 4, "corners shared by both facets are one vertex");
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    }

    #[test]
    fn ascii_reads_and_truncation_is_an_error() {
        let text = "solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\nvertex 0 1 0\nendloop\nendfacet\nendsolid x\n";
        let s = parse(Path::new("a.stl"), text.as_bytes()).expect("valid ascii");
        assert_eq!(s.triangles.len(), 1);
        let e = parse(Path::new("a.stl"), &text.as_bytes()[..60]).expect_err("truncated");
        assert!(e.to_string().starts_with("a.stl:"), "{e}");
    }
}
