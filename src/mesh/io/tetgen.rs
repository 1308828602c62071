//! TetGen `.node` / `.ele` pairs: read and write.
//!
//! In: both files' bytes. `.node`: `n 3 attributes markers`, then
//! `index x y z [attributes] [marker]`; `.ele`: `m 4 regions`, then
//! `index n1 n2 n3 n4 [region]`; `#` starts a comment. Numbering may start at 0
//! or 1 (the `.ele` refers to the indices the `.node` lists). Out: a
//! [`TetMesh`] with coordinates as in the file and the region attribute as
//! region (0 without one). 10-node tets are an "unsupported" error.
//! Stays true: errors name the file (`.node` or `.ele`) and its line.

use std::fmt::Write as _;
use std::path::Path;

use super::cursor::{Cursor, capacity};
use super::error::{MeshFileError, MeshFileErrorKind as K};
use super::tets::{Place, RawTets};
use crate::math::Vec3;
use crate::mesh::TetMesh;

/// Parses a `.node` and an `.ele` file held in memory (paths only for messages).
pub fn parse(node_path: &Path, node: &[u8], ele_path: &Path, ele: &[u8]) -> Result<TetMesh, MeshFileError> {
    let mut raw = RawTets::default();
    let mut c = Cursor::new(node_path, node);
    c.comment = Some(b'#');
    let n = c.uint(|| "the number of nodes".into())?;
    let dim = c.uint(|| "the dimension".into())?;
    if dim != 3 {
        return Err(c.err(K::Unsupported(format!("dimension {dim} (only 3)"))));
    }
    let attributes = c.uint(|| "the number of attributes".into())?;
    let markers = c.uint(|| "the boundary marker flag (0 or 1)".into())?;
    if markers > 1 {
        return Err(c.err(K::Invalid(format!("boundary marker flag {markers} (expected 0 or 1)"))));
    }
    let cap = capacity(n, c.remaining(), 8);
    raw.positions.reserve(cap);
    raw.node_tags.reserve(cap);
    raw.node_places.reserve(cap);
    for i in 0..n {
        let tag = c.int(|| format!("index of node {} of {n}", i + 1))?;
        let line = c.line;
        let x = c.float(|| format!("x coordinate of node {tag}"))?;
        let y = c.float(|| format!("y coordinate of node {tag}"))?;
        let z = c.float(|| format!("z coordinate of node {tag}"))?;
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(c.err_at(line, K::NonFiniteCoordinate { node: tag }));
        }
        for _ in 0..attributes {
            c.float(|| format!("attribute of node {tag}"))?;
        }
        if markers == 1 {
            c.int(|| format!("boundary marker of node {tag}"))?;
        }
        raw.push_node(tag, Vec3::new(x, y, z), Place::line(line));
    }

    let mut c = Cursor::new(ele_path, ele);
    c.comment = Some(b'#');
    let m = c.uint(|| "the number of tetrahedra".into())?;
    let per = c.uint(|| "the number of nodes per tetrahedron".into())?;
    if per != 4 {
        return Err(c.err(K::Unsupported(format!("{per}-node tetrahedra (only 4)"))));
    }
    let has_region = c.uint(|| "the region attribute flag (0 or 1)".into())?;
    if has_region > 1 {
        return Err(c.err(K::Invalid(format!("region attribute flag {has_region} (expected 0 or 1)"))));
    }
    raw.tet_nodes.reserve(capacity(m, c.remaining(), 10));
    for i in 0..m {
        let tag = c.int(|| format!("index of tetrahedron {} of {m}", i + 1))?;
        let line = c.line;
        let mut nodes = [0i64; 4];
        for (k, node) in nodes.iter_mut().enumerate() {
            *node = c.int(|| format!("node {} of tetrahedron {tag}", k + 1))?;
        }
        let region = if has_region == 1 {
            let r = c.float(|| format!("region attribute of tetrahedron {tag}"))?;
            if !((0.0..4294967296.0).contains(&r) && r.fract() == 0.0) {
                return Err(c.err_at(line, K::Invalid(format!("region attribute {r} of tetrahedron {tag} is not an integer in 0..2^32"))));
            }
            r as u32
        } else {
            0
        };
        raw.push_tet(tag, nodes, region, Place::line(line));
    }
    // Nodes resolve through the .node file; errors about elements name the .ele.
    let node_error = |e: MeshFileError| {
        if matches!(e.kind, K::NonFiniteCoordinate { .. } | K::DuplicateNode { .. } | K::Mesh(crate::mesh::MeshError::NonFiniteNode { .. })) {
            MeshFileError { path: node_path.to_path_buf(), ..e }
        } else {
            e
        }
    };
    if raw.positions.is_empty() {
        return Err(MeshFileError::new(node_path, K::Empty("nodes")));
    }
    raw.finish(ele_path).map_err(node_error)
}

/// Writes a TetGen pair (0-based, region attribute included): (`.node`, `.ele`) texts.
pub fn write(mesh: &TetMesh) -> (String, String) {
    let mut node = String::with_capacity(48 * mesh.positions.len());
    let _ = writeln!(node, "{} 3 0 0", mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        let _ = writeln!(node, "{i} {:?} {:?} {:?}", p.x, p.y, p.z);
    }
    let mut ele = String::with_capacity(32 * mesh.tets.len());
    let _ = writeln!(ele, "{} 4 1", mesh.tets.len());
    for (i, (t, r)) in mesh.tets.iter().zip(&mesh.regions).enumerate() {
        let _ = writeln!(ele, "{i} {} {} {} {} {r}", t[0], t[1], t[2], t[3]);
    }
    (node, ele)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_based_with_comments_and_attributes() {
        let node = b"# nodes\n4 3 1 1\n1 0 0 0 9.5 1\n2 1 0 0 9.5 1\n3 0 1 0 9.5 1 # c\n4 0 0 1 9.5 0\n";
        let ele = b"1 4 1\n1 1 2 3 4 2\n";
        let m = parse(Path::new("a.node"), node, Path::new("a.ele"), ele).expect("valid pair");
        assert_eq!(m.tets.len(), 1);
        assert_eq!(m.regions, vec![2]);
        let e = parse(Path::new("a.node"), node, Path::new("a.ele"), b"1 4 0\n1 1 2 3 5\n").expect_err("node 5");
        assert_eq!(e.to_string(), "a.ele:2: element 1 refers to node 5, which the file does not define");
    }
}
