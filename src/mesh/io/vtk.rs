//! VTK legacy `.vtk` unstructured grids: read ASCII and binary (big-endian),
//! versions 2.0 to 5.1 (5.1's OFFSETS/CONNECTIVITY cells included); write ASCII 3.0.
//!
//! In: the whole file. Out: a [`TetMesh`] from the tetrahedra (cell type 10),
//! coordinates as in the file; lower-dimensional cells (vertices, lines,
//! triangles, quads, polygons) are skipped; any other 3D cell type is an
//! "unsupported element type N" error. The region of each tet comes from the
//! cell scalars named `region`, `gmsh:physical` or `CellEntityIds` (first
//! found), else 0. Stays true: errors name the file and the line (or byte
//! offset in binary data); counts in headers never drive an allocation larger
//! than the file could fill.

use std::fmt::Write as _;
use std::path::Path;

use super::cursor::{Cursor, array, capacity, shown};
use super::error::{MeshFileError, MeshFileErrorKind as K};
use super::tets::{Place, RawTets};
use super::{Field, FieldData};
use crate::math::Vec3;
use crate::mesh::TetMesh;

/// VTK cell types of dimension 0 to 2 (skipped on import).
pub(crate) fn is_lower_dimensional_cell(cell_type: i64) -> bool {
    matches!(cell_type, 0..=9 | 21 | 22 | 23 | 28 | 30 | 34 | 35 | 36 | 68 | 69 | 70 | 75 | 76 | 77)
}

/// Names of cell scalars read as the region id, in order of preference.
pub(crate) const REGION_NAMES: [&str; 3] = ["region", "gmsh:physical", "CellEntityIds"];

/// Values of one data block, with the place of each value when asked.
struct Values {
    data: Vec<f64>,
    places: Vec<Place>,
}

fn type_size(c: &Cursor<'_>, line: usize, ty: &[u8]) -> Result<usize, MeshFileError> {
    let lower = ty.to_ascii_lowercase();
    Ok(match lower.as_slice() {
        b"unsigned_char" | b"char" => 1,
        b"unsigned_short" | b"short" => 2,
        b"unsigned_int" | b"int" | b"float" => 4,
        b"unsigned_long" | b"long" | b"double" | b"vtktypeint64" | b"vtktypeuint64" | b"vtkidtype" => 8,
        _ => return Err(c.err_at(line, K::Unsupported(format!("VTK data type \"{}\"", shown(ty))))),
    })
}

/// Reads `count` numbers of type `ty`. In binary mode the cursor must stand at
/// the first data byte; afterwards it stands after the block.
fn values(
    c: &mut Cursor<'_>,
    binary: bool,
    ty: (&[u8], usize),
    count: u64,
    what: &str,
    with_places: bool,
) -> Result<Values, MeshFileError> {
    let size = type_size(c, ty.1, ty.0)?;
    let mut out = Values { data: Vec::with_capacity(capacity(count, c.remaining(), size.min(2))), places: Vec::new() };
    if !binary {
        for i in 0..count {
            let x = c.float(|| format!("{what}, value {} of {count}", i + 1))?;
            if with_places {
                out.places.push(Place::line(c.line));
            }
            out.data.push(x);
        }
        return Ok(out);
    }
    let n = usize::try_from(count).unwrap_or(usize::MAX);
    let start = c.pos;
    let block = c.bytes(n.saturating_mul(size), &format!("binary {what}"))?;
    let lower = ty.0.to_ascii_lowercase();
    for (i, b) in block.chunks_exact(size).enumerate() {
        let x = match (lower.as_slice(), size) {
            (b"char", _) => b[0] as i8 as f64,
            (_, 1) => b[0] as f64,
            (b"short", _) => i16::from_be_bytes(array(b, 0)) as f64,
            (_, 2) => u16::from_be_bytes(array(b, 0)) as f64,
            (b"int", _) => i32::from_be_bytes(array(b, 0)) as f64,
            (b"float", _) => f32::from_be_bytes(array(b, 0)) as f64,
            (_, 4) => u32::from_be_bytes(array(b, 0)) as f64,
            (b"double", _) => f64::from_be_bytes(array(b, 0)),
            (b"unsigned_long" | b"vtktypeuint64", _) => u64::from_be_bytes(array(b, 0)) as f64,
            _ => i64::from_be_bytes(array(b, 0)) as f64,
        };
        if with_places {
            out.places.push(Place::Byte((start + i * size) as u64));
        }
        out.data.push(x);
    }
    Ok(out)
}

/// A value that must be a non-negative integer below `limit`.
fn index(x: f64, limit: f64) -> Option<u64> {
    (x >= 0.0 && x < limit && x.fract() == 0.0).then_some(x as u64)
}

/// Parses a legacy VTK file held in memory; `path` is only used in messages.
pub fn parse(path: &Path, data: &[u8]) -> Result<TetMesh, MeshFileError> {
    let mut c = Cursor::new(path, data);
    let (major, binary) = header(&mut c)?;
    let mut s = Sections { binary, major, ..Sections::default() };
    while let Some((tok, line)) = c.token() {
        s.read(&mut c, tok, line)?;
    }
    let points = s.points.ok_or_else(|| c.eof("POINTS"))?;
    let (offsets, conn, cell_places) = s.cells.ok_or_else(|| c.eof("CELLS"))?;
    let (types, types_line) = s.types.ok_or_else(|| c.eof("CELL_TYPES"))?;
    s.region_candidates.sort_by_key(|&(rank, _, _)| rank);
    let regions = s.region_candidates.first().map(|(_, v, line)| (v.as_slice(), Place::line(*line)));
    let cells = Cells {
        offsets: &offsets,
        connectivity: &conn,
        places: &cell_places,
        types: &types.data,
        types_place: Place::line(types_line),
    };
    assemble(path, &points.data, &points.places, &cells, regions)
}

/// The header up to `DATASET UNSTRUCTURED_GRID`: the file's major version and whether its data is binary.
fn header(c: &mut Cursor<'_>) -> Result<(u8, bool), MeshFileError> {
    let header = c.rest_of_line();
    let Some(version) = header.strip_prefix(b"# vtk DataFile Version ") else {
        return Err(c.err_at(1, K::Expected { expected: "\"# vtk DataFile Version x.y\"".into(), found: shown(header) }));
    };
    let major = version.first().map(|d| d.wrapping_sub(b'0')).unwrap_or(0);
    if !(1..=5).contains(&major) {
        return Err(c.err_at(1, K::UnsupportedVersion { version: shown(version) }));
    }
    if c.pos >= c.data.len() {
        return Err(c.eof("a title line"));
    }
    c.rest_of_line();
    let (mode, line) = c.need("ASCII or BINARY")?;
    let binary = match mode.to_ascii_uppercase().as_slice() {
        b"ASCII" => false,
        b"BINARY" => true,
        _ => return Err(c.err_at(line, K::Expected { expected: "ASCII or BINARY".into(), found: shown(mode) })),
    };
    c.keyword("DATASET")?;
    let (dataset, line) = c.need("UNSTRUCTURED_GRID")?;
    if !dataset.eq_ignore_ascii_case(b"UNSTRUCTURED_GRID") {
        return Err(c.err_at(line, K::Unsupported(format!("VTK dataset {} (only UNSTRUCTURED_GRID)", shown(dataset)))));
    }
    Ok((major, binary))
}

/// Cells as (offsets into connectivity, connectivity), with the place of each cell.
type CellLists = (Vec<f64>, Vec<f64>, Vec<Place>);

/// What the sections after the header have given so far.
#[derive(Default)]
struct Sections {
    binary: bool,
    major: u8,
    points: Option<Values>,
    cells: Option<CellLists>,
    types: Option<(Values, usize)>,
    /// Cell scalars that may hold the region: (rank in [`REGION_NAMES`], values, line).
    region_candidates: Vec<(usize, Vec<f64>, usize)>,
    attribute_count: u64,
    in_cell_data: bool,
}

impl Sections {
    /// Reads the section that keyword `tok` (on `line`) opens.
    fn read(&mut self, c: &mut Cursor<'_>, tok: &[u8], line: usize) -> Result<(), MeshFileError> {
        let binary = self.binary;
        let key = tok.to_ascii_uppercase();
        match key.as_slice() {
            b"POINTS" => {
                let n = c.uint(|| "the number of points".into())?;
                let ty = c.need("the point data type")?;
                self.points = Some(self.block(c, ty, n.saturating_mul(3), "point coordinates", true)?);
            }
            b"CELLS" => self.cells = Some(self.read_cells(c, line)?),
            b"CELL_TYPES" => {
                let n = c.uint(|| "the number of cell types".into())?;
                self.types = Some((self.block(c, (b"int", line), n, "cell types", false)?, line));
            }
            b"CELL_DATA" | b"POINT_DATA" => {
                self.attribute_count = c.uint(|| "the number of attribute values".into())?;
                self.in_cell_data = key == b"CELL_DATA";
            }
            b"SCALARS" => self.read_scalars(c, line)?,
            b"VECTORS" | b"NORMALS" | b"TENSORS" => {
                c.need("an attribute name")?;
                let ty = c.need("an attribute data type")?;
                let per = if key == b"TENSORS" { 9 } else { 3 };
                self.block(c, ty, self.attribute_count.saturating_mul(per), "attribute values", false)?;
            }
            b"TEXTURE_COORDINATES" => {
                c.need("an attribute name")?;
                let dim = c.uint(|| "texture dimension".into())?;
                let ty = c.need("an attribute data type")?;
                self.block(c, ty, self.attribute_count.saturating_mul(dim.min(3)), "texture coordinates", false)?;
            }
            b"COLOR_SCALARS" => {
                c.need("an attribute name")?;
                let per = c.uint(|| "number of colour values".into())?;
                let ty: &[u8] = if binary { b"unsigned_char" } else { b"float" };
                self.block(c, (ty, line), self.attribute_count.saturating_mul(per.min(4)), "colours", false)?;
            }
            b"LOOKUP_TABLE" => {
                c.need("a lookup table name")?;
                let n = c.uint(|| "lookup table size".into())?;
                let ty: &[u8] = if binary { b"unsigned_char" } else { b"float" };
                self.block(c, (ty, line), n.saturating_mul(4), "lookup table", false)?;
            }
            b"FIELD" => self.read_field(c, line)?,
            b"METADATA" => {
                // Runs to the next blank line.
                c.skip_line();
                while c.pos < c.data.len() && !c.rest_of_line().iter().all(|b| b.is_ascii_whitespace()) {}
            }
            _ => {
                return Err(c.err_at(line, K::Expected { expected: "a VTK section keyword such as POINTS".into(), found: shown(tok) }));
            }
        }
        Ok(())
    }

    /// A data block after its header line: binary data starts on the next line.
    fn block(&self, c: &mut Cursor<'_>, ty: (&[u8], usize), count: u64, what: &str, with_places: bool) -> Result<Values, MeshFileError> {
        if self.binary {
            c.skip_line();
        }
        values(c, self.binary, ty, count, what, with_places)
    }

    /// `CELLS`: version 5's OFFSETS and CONNECTIVITY arrays, or the older counted cell list.
    fn read_cells(&self, c: &mut Cursor<'_>, line: usize) -> Result<CellLists, MeshFileError> {
        let a = c.uint(|| "the number of cells".into())?;
        let b = c.uint(|| "the cell list size".into())?;
        if self.major < 5 {
            let list = self.block(c, (b"int", line), b, "cell list", true)?;
            return counted_cells(c, &list, (a, b), line);
        }
        c.keyword("OFFSETS")?;
        let ty = c.need("the offsets data type")?;
        let offsets = self.block(c, ty, a, "cell offsets", true)?;
        c.keyword("CONNECTIVITY")?;
        let ty = c.need("the connectivity data type")?;
        let conn = self.block(c, ty, b, "cell connectivity", false)?;
        let mut places = offsets.places;
        places.pop();
        Ok((offsets.data, conn.data, places))
    }

    /// `SCALARS name type [components]`, an optional `LOOKUP_TABLE`, the values; single-component cell scalars
    /// named as a region are kept.
    fn read_scalars(&mut self, c: &mut Cursor<'_>, line: usize) -> Result<(), MeshFileError> {
        let (name, _) = c.need("a scalar name")?;
        let ty = c.need("a scalar data type")?;
        let rest = c.rest_of_line();
        let ncomp = match rest.split(|b| b.is_ascii_whitespace()).find(|t| !t.is_empty()) {
            Some(t) => super::cursor::parse_int(t)
                .filter(|&n| (1..=4).contains(&n))
                .ok_or_else(|| c.err_at(line, K::BadNumber { token: shown(t), what: "number of components".into() }))?
                as u64,
            None => 1,
        };
        let save = (c.pos, c.line);
        match c.token() {
            Some((t, _)) if t.eq_ignore_ascii_case(b"LOOKUP_TABLE") => {
                c.need("a lookup table name")?;
                if self.binary {
                    c.skip_line();
                }
            }
            _ => (c.pos, c.line) = save,
        }
        let what = format!("scalars \"{}\"", shown(name));
        let v = values(c, self.binary, ty, self.attribute_count.saturating_mul(ncomp), &what, false)?;
        self.keep_region(name, ncomp, v.data, line);
        Ok(())
    }

    /// `FIELD name count` and its arrays; single-component cell arrays named as a region are kept.
    fn read_field(&mut self, c: &mut Cursor<'_>, line: usize) -> Result<(), MeshFileError> {
        c.need("a field name")?;
        let arrays = c.uint(|| "number of field arrays".into())?;
        for _ in 0..arrays {
            let (name, _) = c.need("a field array name")?;
            let ncomp = c.uint(|| "number of components".into())?;
            let tuples = c.uint(|| "number of tuples".into())?;
            let ty = c.need("a field array data type")?;
            let what = format!("field array \"{}\"", shown(name));
            let v = self.block(c, ty, ncomp.saturating_mul(tuples), &what, false)?;
            self.keep_region(name, ncomp, v.data, line);
        }
        Ok(())
    }

    /// Keeps cell data `name` as a region candidate when it has one component and a region's name.
    fn keep_region(&mut self, name: &[u8], ncomp: u64, data: Vec<f64>, line: usize) {
        if self.in_cell_data && ncomp == 1 {
            if let Some(rank) = REGION_NAMES.iter().position(|r| r.as_bytes() == name) {
                self.region_candidates.push((rank, data, line));
            }
        }
    }
}

/// The older cell list (`npts id id ...` for each of `a` cells, `b` numbers) as offsets and connectivity.
fn counted_cells(c: &Cursor<'_>, list: &Values, (a, b): (u64, u64), line: usize) -> Result<CellLists, MeshFileError> {
    let path = c.path;
    let mut offsets = Vec::with_capacity(capacity(a, list.data.len(), 1) + 1);
    let mut conn = Vec::with_capacity(list.data.len());
    let mut places = Vec::with_capacity(offsets.capacity());
    offsets.push(0.0);
    let mut k = 0usize;
    for cell in 0..a {
        let Some(&npts) = list.data.get(k) else {
            return Err(c.err_at(line, K::CountMismatch { what: "cells", announced: a, found: cell }));
        };
        let place = list.places[k];
        let npts = index(npts, 1e9).ok_or_else(|| place.error(path, K::Invalid(format!("cell {cell} has {npts} points"))))? as usize;
        let ids = list
            .data
            .get(k + 1..k + 1 + npts)
            .ok_or_else(|| place.error(path, K::Invalid(format!("cell {cell} runs past the cell list size {b}"))))?;
        conn.extend_from_slice(ids);
        offsets.push(conn.len() as f64);
        places.push(place);
        k += 1 + npts;
    }
    if k != list.data.len() {
        return Err(c.err_at(line, K::Invalid(format!("cell list size {b} but the cells use {k}"))));
    }
    Ok((offsets, conn, places))
}

/// Cells as VTK states them: `offsets` has one more entry than there are cells
/// (starting at 0), cell i uses `connectivity[offsets[i]..offsets[i + 1]]`.
pub(crate) struct Cells<'a> {
    pub offsets: &'a [f64],
    pub connectivity: &'a [f64],
    /// Place of each cell for messages (may be shorter: missing ones use `types_place`).
    pub places: &'a [Place],
    pub types: &'a [f64],
    pub types_place: Place,
}

/// Builds the mesh from VTK arrays: `points` is x0 y0 z0 x1 ...; `point_places`
/// has the place of each coordinate (or is empty); `regions` the cell scalars
/// read as regions with their place.
pub(crate) fn assemble(
    path: &Path,
    points: &[f64],
    point_places: &[Place],
    cells: &Cells<'_>,
    regions: Option<(&[f64], Place)>,
) -> Result<TetMesh, MeshFileError> {
    if !points.len().is_multiple_of(3) {
        return Err(MeshFileError::new(path, K::Invalid(format!("{} point coordinates (not a multiple of 3)", points.len()))));
    }
    let ncells = cells.offsets.len().saturating_sub(1);
    if cells.types.len() != ncells {
        return Err(cells.types_place.error(
            path,
            K::CountMismatch { what: "cell types", announced: cells.types.len() as u64, found: ncells as u64 },
        ));
    }
    if let Some((v, place)) = regions {
        if v.len() != ncells {
            return Err(place.error(path, K::CountMismatch { what: "region values", announced: v.len() as u64, found: ncells as u64 }));
        }
    }
    let conn = cells.connectivity;
    let mut raw = RawTets::default();
    raw.positions.reserve(points.len() / 3);
    for (i, p) in points.chunks_exact(3).enumerate() {
        let place = point_places.get(3 * i).copied().unwrap_or(Place::Nowhere);
        raw.push_node(i as i64, Vec3::new(p[0], p[1], p[2]), place);
    }
    for cell in 0..ncells {
        let place = cells.places.get(cell).copied().unwrap_or(cells.types_place);
        let ty = cells.types[cell];
        let (start, end) = (cells.offsets[cell], cells.offsets[cell + 1]);
        let limit = conn.len() as f64 + 1.0;
        let range = index(start, limit)
            .zip(index(end, limit))
            .filter(|(s, e)| s <= e)
            .ok_or_else(|| place.error(path, K::Invalid(format!("cell {cell} has offsets {start}..{end}"))))?;
        if ty == 10.0 {
            let ids = &conn[range.0 as usize..range.1 as usize];
            if ids.len() != 4 {
                return Err(place.error(path, K::Invalid(format!("tetrahedron (cell {cell}) has {} points", ids.len()))));
            }
            let mut nodes = [0i64; 4];
            for (k, &id) in ids.iter().enumerate() {
                nodes[k] = index(id, 9.0e15).map(|v| v as i64).unwrap_or(-1);
            }
            let region = match regions {
                None => 0,
                Some((v, rplace)) => index(v[cell], 4294967296.0).ok_or_else(|| {
                    rplace.error(path, K::Invalid(format!("region {} of cell {cell} is not an integer in 0..2^32", v[cell])))
                })? as u32,
            };
            raw.push_tet(cell as i64, nodes, region, place);
        } else if ty.fract() != 0.0 || !is_lower_dimensional_cell(ty as i64) {
            return Err(place.error(path, K::UnsupportedElementType { element_type: ty as i64 }));
        }
    }
    raw.finish(path)
}

/// Writes a legacy ASCII (version 3.0) unstructured grid: points as double,
/// tets as cell type 10, cell scalars `region`, then the cell and point fields.
pub fn write(mesh: &TetMesh, fields: &FieldData) -> String {
    let mut s = String::with_capacity(64 * (mesh.positions.len() + mesh.tets.len()));
    let n = mesh.positions.len();
    let m = mesh.tets.len();
    let _ = write!(s, "# vtk DataFile Version 3.0\nfissure tetrahedral mesh\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS {n} double\n");
    for p in &mesh.positions {
        let _ = writeln!(s, "{:?} {:?} {:?}", p.x, p.y, p.z);
    }
    let _ = writeln!(s, "CELLS {m} {}", 5 * m);
    for t in &mesh.tets {
        let _ = writeln!(s, "4 {} {} {} {}", t[0], t[1], t[2], t[3]);
    }
    let _ = writeln!(s, "CELL_TYPES {m}");
    for _ in 0..m {
        s.push_str("10\n");
    }
    let _ = write!(s, "CELL_DATA {m}\nSCALARS region int 1\nLOOKUP_TABLE default\n");
    for r in &mesh.regions {
        let _ = writeln!(s, "{r}");
    }
    write_fields(&mut s, &fields.cell);
    if !fields.point.is_empty() {
        let _ = writeln!(s, "POINT_DATA {n}");
        write_fields(&mut s, &fields.point);
    }
    s
}

fn write_fields(s: &mut String, fields: &[(String, Field)]) {
    for (name, field) in fields {
        match field {
            Field::Scalar(v) => {
                let _ = write!(s, "SCALARS {name} double 1\nLOOKUP_TABLE default\n");
                for x in v {
                    let _ = writeln!(s, "{x:?}");
                }
            }
            Field::Vector(v) => {
                let _ = writeln!(s, "VECTORS {name} double");
                for x in v {
                    let _ = writeln!(s, "{:?} {:?} {:?}", x.x, x.y, x.z);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const ONE_TET: &str = "# vtk DataFile Version 2.0\ntitle\nASCII\nDATASET UNSTRUCTURED_GRID\n\
        POINTS 4 float\n0 0 0\n1 0 0\n0 1 0\n0 0 1\nCELLS 2 9\n3 0 1 2\n4 0 1 2 3\n\
        CELL_TYPES 2\n5\n10\nCELL_DATA 2\nSCALARS region int 1\nLOOKUP_TABLE default\n4\n3\n";

    #[test]
    fn reads_tets_and_region_scalars_skipping_triangles() {
        let m = parse(Path::new("a.vtk"), ONE_TET.as_bytes()).expect("valid file");
        assert_eq!(m.tets.len(), 1);
        assert_eq!(m.regions, vec![3], "the tet is the second cell; its region is 3");
    }

    #[test]
    fn hexahedron_is_unsupported_with_its_line() {
        let bad = ONE_TET.replace("CELL_TYPES 2\n5\n", "CELL_TYPES 2\n12\n");
        let e = parse(Path::new("a.vtk"), bad.as_bytes()).expect_err("hexahedron");
        assert_eq!(e.to_string(), "a.vtk:11: unsupported element type 12");
    }
}
