//! Wavefront OBJ surfaces: read and write.
//!
//! In: `v x y z [w | r g b]` and `f a b c ...` lines, vertex references as
//! `i`, `i/t`, `i//n` or `i/t/n`, negative indices relative to the vertices so
//! far; polygons are fan-triangulated; every other statement (`vt`, `vn`, `o`,
//! `g`, `s`, `usemtl`, `l`, ...) is ignored, so several objects merge into one
//! surface. Out: a [`TriSurface`] with coordinates as in the file. Stays true:
//! errors name the file and line; indices are checked against the final vertex
//! count (forward references are allowed, missing vertices are not).

use std::fmt::Write as _;
use std::path::Path;

use super::cursor::{parse_float, parse_int, shown};
use super::error::{MeshFileError, MeshFileErrorKind as K};
use crate::math::Vec3;
use crate::mesh::TriSurface;

/// Parses an OBJ file held in memory; `path` is only used in messages.
pub fn parse(path: &Path, data: &[u8]) -> Result<TriSurface, MeshFileError> {
    let mut positions: Vec<Vec3> = Vec::new();
    let mut triangles: Vec<[u32; 3]> = Vec::new();
    // Raw references (already made absolute, 0-based) and the line of each triangle.
    let mut refs: Vec<[i64; 3]> = Vec::new();
    let mut lines: Vec<u32> = Vec::new();
    let mut face: Vec<i64> = Vec::new();
    for (k, line) in data.split(|&b| b == b'\n').enumerate() {
        let number = k + 1;
        let line = match line.iter().position(|&b| b == b'#') {
            Some(p) => &line[..p],
            None => line,
        };
        let mut tokens = line.split(|b| b.is_ascii_whitespace()).filter(|t| !t.is_empty());
        let Some(keyword) = tokens.next() else { continue };
        let err = |kind| MeshFileError::at_line(path, number, kind);
        match keyword {
            b"v" => {
                let mut xyz = [0.0; 3];
                for (axis, value) in xyz.iter_mut().enumerate() {
                    let what = || format!("{} coordinate of vertex {}", ["x", "y", "z"][axis], positions.len() + 1);
                    let tok = tokens.next().ok_or_else(|| err(K::Invalid(format!("missing {}", what()))))?;
                    *value = parse_float(tok).ok_or_else(|| err(K::BadNumber { token: shown(tok), what: what() }))?;
                }
                if !xyz.iter().all(|x| x.is_finite()) {
                    return Err(err(K::NonFiniteCoordinate { node: positions.len() as i64 + 1 }));
                }
                positions.push(Vec3::new(xyz[0], xyz[1], xyz[2]));
            }
            b"f" => {
                face.clear();
                for tok in tokens {
                    let index_token = tok.split(|&b| b == b'/').next().unwrap_or(tok);
                    let i = parse_int(index_token)
                        .ok_or_else(|| err(K::BadNumber { token: shown(tok), what: "face vertex index".into() }))?;
                    let absolute = match i {
                        0 => return Err(err(K::Invalid("face vertex index 0 (OBJ indices start at 1)".into()))),
                        i if i > 0 => i - 1,
                        i => positions.len() as i64 + i,
                    };
                    if absolute < 0 {
                        return Err(err(K::Invalid(format!("face vertex index {i} points before the first vertex"))));
                    }
                    face.push(absolute);
                }
                if face.len() < 3 {
                    return Err(err(K::Invalid(format!("face with {} vertices (at least 3)", face.len()))));
                }
                for j in 1..face.len() - 1 {
                    refs.push([face[0], face[j], face[j + 1]]);
                    lines.push(number.min(u32::MAX as usize) as u32);
                }
            }
            _ => {}
        }
    }
    let n = positions.len() as i64;
    triangles.reserve(refs.len());
    for (r, &line) in refs.iter().zip(&lines) {
        if let Some(&bad) = r.iter().find(|&&i| i >= n) {
            return Err(MeshFileError::at_line(
                path,
                line as usize,
                K::Invalid(format!("face refers to vertex {} but the file has {n}", bad + 1)),
            ));
        }
        triangles.push(r.map(|i| i as u32));
    }
    if triangles.is_empty() {
        return Err(MeshFileError::new(path, K::Empty("faces")));
    }
    Ok(TriSurface { positions, triangles })
}

/// Writes `v` and `f` lines (1-based) with shortest round-trip numbers.
pub fn write(surface: &TriSurface) -> String {
    let mut s = String::with_capacity(40 * surface.positions.len() + 24 * surface.triangles.len());
    s.push_str("# fissure surface\n");
    for p in &surface.positions {
        let _ = writeln!(s, "v {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    for t in &surface.triangles {
        let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quads_fan_and_negative_and_slashed_indices_resolve() {
        let text = b"o a\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\no b\nv 0 0 1\nf -1 -4/1 -3/1/1\n";
        let s = parse(Path::new("s.obj"), text).expect("valid");
        assert_eq!(s.positions.len(), 5);
        assert_eq!(s.triangles, vec![[0, 1, 2], [0, 2, 3], [4, 1, 2]]);
    }

    #[test]
    fn out_of_range_index_names_the_line() {
        let e = parse(Path::new("s.obj"), b"v 0 0 0\nv 1 0 0\nv 0 1 0\n\nf 1 2 9\n").expect_err("vertex 9");
        assert_eq!(e.to_string(), "s.obj:5: face refers to vertex 9 but the file has 3");
    }
}
