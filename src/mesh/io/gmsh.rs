//! Gmsh `.msh` files: read 2.2 and 4.1 (ASCII and binary), write 2.2 ASCII.
//!
//! In: the whole file in memory. Out: a [`TetMesh`] with coordinates as in the
//! file (no unit conversion), nodes in file order, the 4-node tetrahedra (type 4)
//! with their physical tag as region (2.2: first element tag; 4.1: first
//! physical tag of the volume entity; 0 when there is none). Points, lines,
//! triangles and quads are skipped; any other 3D element type is an
//! "unsupported element type N" error. Stays true: every failure names the
//! file and the line (or byte offset inside binary data); the parser never
//! panics and never allocates more than the file could hold.

use std::fmt::Write as _;
use std::path::Path;

use super::cursor::{Cursor, Endian, array, capacity, shown};
use super::error::{MeshFileError, MeshFileErrorKind as K};
use super::tets::{Place, RawTets};
use super::{Field, FieldData};
use crate::math::Vec3;
use crate::mesh::TetMesh;

/// Dimension and node count of a Gmsh element type, `None` when unknown.
pub fn element_type_info(element_type: i64) -> Option<(u8, usize)> {
    Some(match element_type {
        15 => (0, 1),
        1 => (1, 2),
        8 => (1, 3),
        26 => (1, 4),
        27 => (1, 5),
        28 => (1, 6),
        2 => (2, 3),
        3 => (2, 4),
        9 => (2, 6),
        10 => (2, 9),
        16 => (2, 8),
        20 => (2, 9),
        21 => (2, 10),
        22 => (2, 12),
        23 => (2, 15),
        24 => (2, 15),
        25 => (2, 21),
        4 => (3, 4),
        5 => (3, 8),
        6 => (3, 6),
        7 => (3, 5),
        11 => (3, 10),
        12 => (3, 27),
        13 => (3, 18),
        14 => (3, 14),
        17 => (3, 20),
        18 => (3, 15),
        19 => (3, 13),
        29 => (3, 20),
        30 => (3, 35),
        31 => (3, 56),
        92 => (3, 64),
        93 => (3, 125),
        _ => return None,
    })
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Version {
    V2,
    V41,
}

/// Binary layout of a file: byte order and the size of `size_t` (4.1).
#[derive(Clone, Copy)]
struct Binary {
    endian: Endian,
    size_t: usize,
}

impl Binary {
    #[inline]
    fn i32(self, b: &[u8], at: usize) -> i64 {
        self.endian.u32(array(b, at)) as i32 as i64
    }
    #[inline]
    fn f64(self, b: &[u8], at: usize) -> f64 {
        self.endian.f64(array(b, at))
    }
    #[inline]
    fn size(self, b: &[u8], at: usize) -> u64 {
        if self.size_t == 4 { self.endian.u32(array(b, at)) as u64 } else { self.endian.u64(array(b, at)) }
    }
}

/// Parses a `.msh` file held in memory; `path` is only used in messages.
pub fn parse(path: &Path, data: &[u8]) -> Result<TetMesh, MeshFileError> {
    parse_raw(path, data)?.finish(path)
}

/// [`parse`], plus the Gmsh node tag of every node (`tags[i]` is node `i`'s tag;
/// Gmsh numbers from 1 and may leave gaps), for users who name nodes by tag.
pub fn parse_with_node_tags(path: &Path, data: &[u8]) -> Result<(TetMesh, Vec<i64>), MeshFileError> {
    let raw = parse_raw(path, data)?;
    let tags = raw.node_tags.clone();
    Ok((raw.finish(path)?, tags))
}

fn parse_raw(path: &Path, data: &[u8]) -> Result<RawTets, MeshFileError> {
    let mut c = Cursor::new(path, data);
    c.keyword("$MeshFormat")?;
    let (version_token, version_line) = c.need("the format version")?;
    let version = match version_token {
        b"2" | b"2.0" | b"2.1" | b"2.2" => Version::V2,
        b"4.1" => Version::V41,
        other => return Err(c.err_at(version_line, K::UnsupportedVersion { version: shown(other) })),
    };
    let file_type = c.uint(|| "file type (0 ASCII, 1 binary)".into())?;
    let size_t = c.uint(|| "data size".into())?;
    let binary = match file_type {
        0 => None,
        1 => {
            if !(size_t == 4 || size_t == 8) {
                return Err(c.err(K::Invalid(format!("data size {size_t} (expected 4 or 8)"))));
            }
            c.skip_line();
            let at = c.pos;
            let one = c.bytes(4, "the binary byte-order marker")?;
            let endian = if u32::from_le_bytes(array(one, 0)) == 1 {
                Endian::Little
            } else if u32::from_be_bytes(array(one, 0)) == 1 {
                Endian::Big
            } else {
                return Err(MeshFileError::at_offset(path, at, K::Invalid("binary byte-order marker is not 1".into())));
            };
            Some(Binary { endian, size_t: size_t as usize })
        }
        other => return Err(c.err(K::Invalid(format!("file type {other} (expected 0 ASCII or 1 binary)")))),
    };
    c.keyword("$EndMeshFormat")?;

    let mut raw = RawTets::default();
    // 4.1: volume entity of each tet, resolved to a physical tag at the end.
    let mut tet_entities: Vec<i64> = Vec::new();
    let mut volume_physical: Vec<(i64, u32)> = Vec::new();
    let (mut seen_nodes, mut seen_elements) = (false, false);
    while let Some((tok, line)) = c.token() {
        match tok {
            b"$Nodes" => {
                if seen_nodes {
                    return Err(c.err_at(line, K::Invalid("a second $Nodes section".into())));
                }
                seen_nodes = true;
                match (version, binary) {
                    (Version::V2, None) => nodes_v2_ascii(&mut c, &mut raw)?,
                    (Version::V2, Some(b)) => nodes_v2_binary(&mut c, &mut raw, b)?,
                    (Version::V41, None) => nodes_v41_ascii(&mut c, &mut raw)?,
                    (Version::V41, Some(b)) => nodes_v41_binary(&mut c, &mut raw, b)?,
                }
                c.keyword("$EndNodes")?;
            }
            b"$Elements" => {
                if seen_elements {
                    return Err(c.err_at(line, K::Invalid("a second $Elements section".into())));
                }
                seen_elements = true;
                match (version, binary) {
                    (Version::V2, None) => elements_v2_ascii(&mut c, &mut raw)?,
                    (Version::V2, Some(b)) => elements_v2_binary(&mut c, &mut raw, b)?,
                    (Version::V41, None) => elements_v41_ascii(&mut c, &mut raw, &mut tet_entities)?,
                    (Version::V41, Some(b)) => elements_v41_binary(&mut c, &mut raw, &mut tet_entities, b)?,
                }
                c.keyword("$EndElements")?;
            }
            b"$Entities" if version == Version::V41 => {
                volume_physical = match binary {
                    None => entities_ascii(&mut c)?,
                    Some(b) => entities_binary(&mut c, b)?,
                };
                c.keyword("$EndEntities")?;
            }
            [b'$', name @ ..] if !name.starts_with(b"End") && !name.is_empty() => skip_section(&mut c, name)?,
            other => {
                return Err(c.err_at(line, K::Expected { expected: "a section such as $Nodes".into(), found: shown(other) }));
            }
        }
    }
    if !seen_nodes {
        return Err(c.eof("a $Nodes section"));
    }
    if !seen_elements {
        return Err(c.eof("an $Elements section"));
    }
    if version == Version::V41 {
        volume_physical.sort_unstable();
        for (region, entity) in raw.regions.iter_mut().zip(&tet_entities) {
            *region = match volume_physical.binary_search_by_key(entity, |&(e, _)| e) {
                Ok(i) => volume_physical[i].1,
                Err(_) => 0,
            };
        }
    }
    Ok(raw)
}

/// Skips an unknown section `$name ... $Endname`.
fn skip_section(c: &mut Cursor<'_>, name: &[u8]) -> Result<(), MeshFileError> {
    let mut end = b"$End".to_vec();
    end.extend_from_slice(name);
    let rest = &c.data[c.pos..];
    match rest.windows(end.len()).position(|w| w == end.as_slice()) {
        Some(k) => {
            c.bytes(k + end.len(), "")?;
            Ok(())
        }
        None => Err(c.eof(String::from_utf8_lossy(&end).into_owned())),
    }
}

fn region_of(c: &Cursor<'_>, line: usize, element: i64, physical: i64) -> Result<u32, MeshFileError> {
    u32::try_from(physical).map_err(|_| {
        c.err_at(line, K::Invalid(format!("element {element} has physical tag {physical} (expected 0 to 2^32 - 1)")))
    })
}

fn nodes_v2_ascii(c: &mut Cursor<'_>, raw: &mut RawTets) -> Result<(), MeshFileError> {
    let count = c.uint(|| "the number of nodes".into())?;
    let cap = capacity(count, c.remaining(), 8);
    raw.node_tags.reserve(cap);
    raw.positions.reserve(cap);
    raw.node_places.reserve(cap);
    for i in 0..count {
        let tag = c.int(|| format!("tag of node {} of {count}", i + 1))?;
        let line = c.line;
        let x = c.float(|| format!("x coordinate of node {tag}"))?;
        let y = c.float(|| format!("y coordinate of node {tag}"))?;
        let z = c.float(|| format!("z coordinate of node {tag}"))?;
        if !(x.is_finite() && y.is_finite() && z.is_finite()) {
            return Err(c.err_at(line, K::NonFiniteCoordinate { node: tag }));
        }
        raw.push_node(tag, Vec3::new(x, y, z), Place::line(line));
    }
    Ok(())
}

fn nodes_v2_binary(c: &mut Cursor<'_>, raw: &mut RawTets, b: Binary) -> Result<(), MeshFileError> {
    let count = c.uint(|| "the number of nodes".into())?;
    c.skip_line();
    let start = c.pos;
    let len = usize::try_from(count).ok().and_then(|n| n.checked_mul(28)).unwrap_or(usize::MAX);
    let block = c.bytes(len, "binary node data and $EndNodes")?;
    for (i, rec) in block.chunks_exact(28).enumerate() {
        let tag = b.i32(rec, 0);
        let p = Vec3::new(b.f64(rec, 4), b.f64(rec, 12), b.f64(rec, 20));
        let place = Place::Byte((start + 28 * i) as u64);
        if !crate::math::is_finite3(&p) {
            return Err(place.error(c.path, K::NonFiniteCoordinate { node: tag }));
        }
        raw.push_node(tag, p, place);
    }
    Ok(())
}

fn elements_v2_ascii(c: &mut Cursor<'_>, raw: &mut RawTets) -> Result<(), MeshFileError> {
    let count = c.uint(|| "the number of elements".into())?;
    let cap = capacity(count, c.remaining(), 16);
    raw.tet_nodes.reserve(cap);
    for i in 0..count {
        let tag = c.int(|| format!("tag of element {} of {count}", i + 1))?;
        let line = c.line;
        let ty = c.int(|| format!("type of element {tag}"))?;
        let ntags = c.uint(|| format!("number of tags of element {tag}"))?;
        let mut physical = 0;
        for k in 0..ntags {
            let v = c.int(|| format!("tag {} of element {tag}", k + 1))?;
            if k == 0 {
                physical = v;
            }
        }
        match element_type_info(ty) {
            Some((3, 4)) if ty == 4 => {
                let mut nodes = [0i64; 4];
                for (k, n) in nodes.iter_mut().enumerate() {
                    *n = c.int(|| format!("node {} of element {tag}", k + 1))?;
                }
                let region = region_of(c, line, tag, physical)?;
                raw.push_tet(tag, nodes, region, Place::line(line));
            }
            Some((dim, n)) if dim < 3 => {
                for k in 0..n {
                    c.int(|| format!("node {} of element {tag}", k + 1))?;
                }
            }
            _ => return Err(c.err_at(line, K::UnsupportedElementType { element_type: ty })),
        }
    }
    Ok(())
}

fn elements_v2_binary(c: &mut Cursor<'_>, raw: &mut RawTets, b: Binary) -> Result<(), MeshFileError> {
    let count = c.uint(|| "the number of elements".into())?;
    c.skip_line();
    let mut done = 0u64;
    while done < count {
        let at = c.pos;
        let head = c.bytes(12, "a binary element header and $EndElements")?;
        let ty = b.i32(head, 0);
        let follow = b.endian.u32(array(head, 4)) as u64;
        let ntags = b.endian.u32(array(head, 8)) as usize;
        let err = |kind| MeshFileError::at_offset(c.path, at, kind);
        if follow == 0 || follow > count - done {
            return Err(err(K::Invalid(format!("element block of {follow} elements where {} remain", count - done))));
        }
        let nodes_per = match element_type_info(ty) {
            Some((3, _)) if ty != 4 => return Err(err(K::UnsupportedElementType { element_type: ty })),
            Some((_, n)) => n,
            None => return Err(err(K::UnsupportedElementType { element_type: ty })),
        };
        let ints = 1 + ntags + nodes_per;
        let len = (follow as usize).saturating_mul(ints * 4);
        let start = c.pos;
        let block = c.bytes(len, "binary element data and $EndElements")?;
        if ty == 4 {
            for (i, rec) in block.chunks_exact(ints * 4).enumerate() {
                let tag = b.i32(rec, 0);
                let physical = if ntags > 0 { b.i32(rec, 4) } else { 0 };
                let place = Place::Byte((start + i * ints * 4) as u64);
                let region = u32::try_from(physical).map_err(|_| {
                    place.error(c.path, K::Invalid(format!("element {tag} has physical tag {physical}")))
                })?;
                let o = 4 * (1 + ntags);
                let nodes = [b.i32(rec, o), b.i32(rec, o + 4), b.i32(rec, o + 8), b.i32(rec, o + 12)];
                raw.push_tet(tag, nodes, region, place);
            }
        }
        done += follow;
    }
    Ok(())
}

/// 4.1 `$Entities`: (volume tag, first physical tag or 0).
fn entities_ascii(c: &mut Cursor<'_>) -> Result<Vec<(i64, u32)>, MeshFileError> {
    let mut counts = [0u64; 4];
    for (d, n) in counts.iter_mut().enumerate() {
        *n = c.uint(|| format!("number of {}-dimensional entities", d))?;
    }
    let mut volumes = Vec::with_capacity(capacity(counts[3], c.remaining(), 16));
    for (dim, &n) in counts.iter().enumerate() {
        for _ in 0..n {
            let tag = c.int(|| format!("tag of a {dim}-dimensional entity"))?;
            let line = c.line;
            for _ in 0..if dim == 0 { 3 } else { 6 } {
                c.float(|| format!("bounding box of entity {tag}"))?;
            }
            let nphys = c.uint(|| format!("number of physical tags of entity {tag}"))?;
            let mut first = 0i64;
            for k in 0..nphys {
                let p = c.int(|| format!("physical tag of entity {tag}"))?;
                if k == 0 {
                    first = p;
                }
            }
            if dim > 0 {
                let nb = c.uint(|| format!("number of bounding entities of entity {tag}"))?;
                for _ in 0..nb {
                    c.int(|| format!("bounding entity of entity {tag}"))?;
                }
            }
            if dim == 3 {
                // Gmsh writes negative physical tags only for orientation of lower-dimensional ones.
                volumes.push((tag, region_of(c, line, tag, first.saturating_abs())?));
            }
        }
    }
    Ok(volumes)
}

fn entities_binary(c: &mut Cursor<'_>, b: Binary) -> Result<Vec<(i64, u32)>, MeshFileError> {
    c.skip_line();
    let s = b.size_t;
    let head = c.bytes(4 * s, "the binary entity counts")?;
    let counts: Vec<u64> = (0..4).map(|k| b.size(head, k * s)).collect();
    let mut volumes = Vec::with_capacity(capacity(counts[3], c.remaining(), 4 + 48));
    for (dim, &n) in counts.iter().enumerate() {
        for _ in 0..n {
            let at = c.pos;
            let fixed = 4 + if dim == 0 { 24 } else { 48 };
            let rec = c.bytes(fixed + s, "binary entity data and $EndEntities")?;
            let tag = b.i32(rec, 0);
            let nphys = b.size(rec, fixed);
            let len = usize::try_from(nphys).ok().and_then(|n| n.checked_mul(4)).unwrap_or(usize::MAX);
            let phys = c.bytes(len, "binary physical tags and $EndEntities")?;
            let first = if nphys > 0 { b.i32(phys, 0) } else { 0 };
            if dim > 0 {
                let nb = b.size(c.bytes(s, "the number of bounding entities")?, 0);
                let len = usize::try_from(nb).ok().and_then(|n| n.checked_mul(4)).unwrap_or(usize::MAX);
                c.bytes(len, "binary bounding entities and $EndEntities")?;
            }
            if dim == 3 {
                let region = u32::try_from(first.abs()).map_err(|_| {
                    MeshFileError::at_offset(c.path, at, K::Invalid(format!("entity {tag} has physical tag {first}")))
                })?;
                volumes.push((tag, region));
            }
        }
    }
    Ok(volumes)
}

fn nodes_v41_ascii(c: &mut Cursor<'_>, raw: &mut RawTets) -> Result<(), MeshFileError> {
    let blocks = c.uint(|| "the number of node blocks".into())?;
    let total = c.uint(|| "the number of nodes".into())?;
    c.uint(|| "the minimum node tag".into())?;
    c.uint(|| "the maximum node tag".into())?;
    let cap = capacity(total, c.remaining(), 8);
    raw.positions.reserve(cap);
    raw.node_tags.reserve(cap);
    raw.node_places.reserve(cap);
    let mut tags = Vec::new();
    let mut found = 0u64;
    for _ in 0..blocks {
        let dim = c.int(|| "entity dimension of a node block".into())?;
        c.int(|| "entity tag of a node block".into())?;
        let parametric = c.int(|| "parametric flag of a node block".into())?;
        let n = c.uint(|| "number of nodes in a node block".into())?;
        let params = if parametric != 0 { dim.clamp(0, 3) as usize } else { 0 };
        tags.clear();
        for _ in 0..n {
            tags.push(c.int(|| "node tag".into())?);
        }
        for &tag in &tags {
            let line = c.line;
            let x = c.float(|| format!("x coordinate of node {tag}"))?;
            let y = c.float(|| format!("y coordinate of node {tag}"))?;
            let z = c.float(|| format!("z coordinate of node {tag}"))?;
            for _ in 0..params {
                c.float(|| format!("parametric coordinate of node {tag}"))?;
            }
            if !(x.is_finite() && y.is_finite() && z.is_finite()) {
                return Err(c.err_at(line, K::NonFiniteCoordinate { node: tag }));
            }
            raw.push_node(tag, Vec3::new(x, y, z), Place::line(line));
        }
        found += n;
    }
    if found != total {
        return Err(c.err(K::CountMismatch { what: "nodes", announced: total, found }));
    }
    Ok(())
}

fn nodes_v41_binary(c: &mut Cursor<'_>, raw: &mut RawTets, b: Binary) -> Result<(), MeshFileError> {
    c.skip_line();
    let s = b.size_t;
    let head = c.bytes(4 * s, "the binary node counts")?;
    let blocks = b.size(head, 0);
    let total = b.size(head, s);
    let cap = capacity(total, c.remaining(), s + 24);
    raw.positions.reserve(cap);
    raw.node_tags.reserve(cap);
    raw.node_places.reserve(cap);
    let mut found = 0u64;
    for _ in 0..blocks {
        let h = c.bytes(12 + s, "a binary node block header and $EndNodes")?;
        let dim = b.i32(h, 0);
        let parametric = b.i32(h, 8);
        let n = b.size(h, 12);
        let params = if parametric != 0 { dim.clamp(0, 3) as usize } else { 0 };
        let n_usize = usize::try_from(n).unwrap_or(usize::MAX);
        let tag_bytes = c.bytes(n_usize.saturating_mul(s), "binary node tags and $EndNodes")?;
        let rec = 8 * (3 + params);
        let start = c.pos;
        let coords = c.bytes(n_usize.saturating_mul(rec), "binary node coordinates and $EndNodes")?;
        for i in 0..n_usize {
            let tag = b.size(tag_bytes, i * s) as i64;
            let p = Vec3::new(b.f64(coords, i * rec), b.f64(coords, i * rec + 8), b.f64(coords, i * rec + 16));
            let place = Place::Byte((start + i * rec) as u64);
            if !crate::math::is_finite3(&p) {
                return Err(place.error(c.path, K::NonFiniteCoordinate { node: tag }));
            }
            raw.push_node(tag, p, place);
        }
        found += n;
    }
    if found != total {
        return Err(MeshFileError::at_offset(c.path, c.pos, K::CountMismatch { what: "nodes", announced: total, found }));
    }
    Ok(())
}

fn elements_v41_ascii(c: &mut Cursor<'_>, raw: &mut RawTets, entities: &mut Vec<i64>) -> Result<(), MeshFileError> {
    let blocks = c.uint(|| "the number of element blocks".into())?;
    let total = c.uint(|| "the number of elements".into())?;
    c.uint(|| "the minimum element tag".into())?;
    c.uint(|| "the maximum element tag".into())?;
    raw.tet_nodes.reserve(capacity(total, c.remaining(), 10));
    let mut found = 0u64;
    for _ in 0..blocks {
        c.int(|| "entity dimension of an element block".into())?;
        let line = c.line;
        let entity = c.int(|| "entity tag of an element block".into())?;
        let ty = c.int(|| "element type of an element block".into())?;
        let n = c.uint(|| "number of elements in an element block".into())?;
        match element_type_info(ty) {
            Some(_) if ty == 4 => {
                for _ in 0..n {
                    let tag = c.int(|| "element tag".into())?;
                    let line = c.line;
                    let mut nodes = [0i64; 4];
                    for (k, node) in nodes.iter_mut().enumerate() {
                        *node = c.int(|| format!("node {} of element {tag}", k + 1))?;
                    }
                    raw.push_tet(tag, nodes, 0, Place::line(line));
                    entities.push(entity);
                }
            }
            Some((dim, per)) if dim < 3 => {
                for _ in 0..n {
                    for _ in 0..=per {
                        c.int(|| format!("element of type {ty}"))?;
                    }
                }
            }
            _ => return Err(c.err_at(line, K::UnsupportedElementType { element_type: ty })),
        }
        found += n;
    }
    if found != total {
        return Err(c.err(K::CountMismatch { what: "elements", announced: total, found }));
    }
    Ok(())
}

fn elements_v41_binary(
    c: &mut Cursor<'_>,
    raw: &mut RawTets,
    entities: &mut Vec<i64>,
    b: Binary,
) -> Result<(), MeshFileError> {
    c.skip_line();
    let s = b.size_t;
    let head = c.bytes(4 * s, "the binary element counts")?;
    let blocks = b.size(head, 0);
    let total = b.size(head, s);
    raw.tet_nodes.reserve(capacity(total, c.remaining(), 5 * s));
    let mut found = 0u64;
    for _ in 0..blocks {
        let at = c.pos;
        let h = c.bytes(12 + s, "a binary element block header and $EndElements")?;
        let entity = b.i32(h, 4);
        let ty = b.i32(h, 8);
        let n = b.size(h, 12);
        let per = match element_type_info(ty) {
            Some((3, _)) if ty != 4 => None,
            Some((_, per)) => Some(per),
            None => None,
        }
        .ok_or_else(|| MeshFileError::at_offset(c.path, at, K::UnsupportedElementType { element_type: ty }))?;
        let rec = (1 + per) * s;
        let n_usize = usize::try_from(n).unwrap_or(usize::MAX);
        let start = c.pos;
        let block = c.bytes(n_usize.saturating_mul(rec), "binary element data and $EndElements")?;
        if ty == 4 {
            for (i, r) in block.chunks_exact(rec).enumerate() {
                let tag = b.size(r, 0) as i64;
                let nodes = [1, 2, 3, 4].map(|k| b.size(r, k * s) as i64);
                raw.push_tet(tag, nodes, 0, Place::Byte((start + i * rec) as u64));
                entities.push(entity);
            }
        }
        found += n;
    }
    if found != total {
        return Err(MeshFileError::at_offset(c.path, c.pos, K::CountMismatch { what: "elements", announced: total, found }));
    }
    Ok(())
}

/// Writes Gmsh 2.2 ASCII: nodes tagged 1..n, tets tagged 1..m with physical tag
/// = region (elementary tag = region, or 1 for region 0), and each field as
/// `$NodeData` / `$ElementData` (time 0). Numbers use Rust's shortest
/// round-trip formatting, so reading the file back gives the same bits.
pub fn write(mesh: &TetMesh, fields: &FieldData) -> String {
    let mut s = String::with_capacity(64 * (mesh.positions.len() + mesh.tets.len()));
    s.push_str("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    let _ = writeln!(s, "{}", mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        let _ = writeln!(s, "{} {:?} {:?} {:?}", i + 1, p.x, p.y, p.z);
    }
    s.push_str("$EndNodes\n$Elements\n");
    let _ = writeln!(s, "{}", mesh.tets.len());
    for (i, (t, &r)) in mesh.tets.iter().zip(&mesh.regions).enumerate() {
        let elementary = if r == 0 { 1 } else { r };
        let _ = writeln!(s, "{} 4 2 {r} {elementary} {} {} {} {}", i + 1, t[0] + 1, t[1] + 1, t[2] + 1, t[3] + 1);
    }
    s.push_str("$EndElements\n");
    for (section, list, count) in
        [("NodeData", &fields.point, mesh.positions.len()), ("ElementData", &fields.cell, mesh.tets.len())]
    {
        for (name, field) in list {
            let components = match field {
                Field::Scalar(_) => 1,
                Field::Vector(_) => 3,
            };
            let _ = write!(s, "${section}\n1\n\"{name}\"\n1\n0\n3\n0\n{components}\n{count}\n");
            match field {
                Field::Scalar(v) => {
                    for (i, x) in v.iter().enumerate() {
                        let _ = writeln!(s, "{} {x:?}", i + 1);
                    }
                }
                Field::Vector(v) => {
                    for (i, x) in v.iter().enumerate() {
                        let _ = writeln!(s, "{} {:?} {:?} {:?}", i + 1, x.x, x.y, x.z);
                    }
                }
            }
            let _ = writeln!(s, "$End{section}");
        }
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    const TWO_TETS: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n5\n\
        1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n$EndNodes\n$Elements\n4\n\
        1 15 2 0 1 1\n2 2 2 0 1 1 2 3\n3 4 2 7 1 1 2 3 4\n4 4 2 8 2 2 3 5 4\n$EndElements\n";

    #[test]
    fn reads_tets_skips_points_and_triangles() {
        let m = parse(Path::new("a.msh"), TWO_TETS.as_bytes()).expect("valid file");
        assert_eq!(m.positions.len(), 5);
        assert_eq!(m.tets.len(), 2, "the point and the triangle are skipped");
        assert_eq!(m.regions, vec![7, 8], "physical tags become regions");
    }

    #[test]
    fn reports_line_of_bad_number_and_unsupported_type() {
        let bad = TWO_TETS.replace("3 0 1 0", "3 0 1.2.3 0");
        let e = parse(Path::new("a.msh"), bad.as_bytes()).expect_err("malformed number");
        assert_eq!(e.line, Some(8), "{e}");
        assert!(e.to_string().contains("malformed number \"1.2.3\" (y coordinate of node 3)"), "{e}");
        let hex = TWO_TETS.replace("4 4 2 8 2 2 3 5 4", "4 5 2 8 2 2 3 5 4 1 2 3 4");
        let e = parse(Path::new("a.msh"), hex.as_bytes()).expect_err("hexahedron");
        assert_eq!(e.to_string(), "a.msh:17: unsupported element type 5");
    }

    #[test]
    fn truncated_file_names_the_missing_end() {
        let cut = &TWO_TETS[..TWO_TETS.len() - "$EndElements\n".len()];
        let e = parse(Path::new("a.msh"), cut.as_bytes()).expect_err("truncated");
        assert!(e.to_string().contains("unexpected end of file (expected $EndElements)"), "{e}");
    }
}
