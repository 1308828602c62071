//! Mesh import and export, chosen by file extension.
//!
//! In: a path. Tet meshes: Gmsh `.msh` (2.2 and 4.1, ASCII and binary), VTK
//! legacy `.vtk` (ASCII and binary), VTK XML `.vtu` (ASCII, inline base64,
//! appended raw or base64; uncompressed), TetGen `.node`/`.ele`. Surfaces: OBJ
//! and STL (ASCII and binary). Any of them may be gzip-compressed, named with
//! `.gz` after its own extension (`brain.msh.gz`): read and written through
//! the same readers and writers. Out: a validated [`TetMesh`] or a
//! [`TriSurface`], coordinates AS IN THE FILE (the scenario scales mm -> m).
//! Export: `.vtu` (point and cell data, ParaView opens it), `.msh` (Gmsh 2.2
//! ASCII), `.vtk` (legacy ASCII), surfaces to `.obj` / `.stl`, and `.pvd` time
//! collections. Stays true: no parser panics on any input; every error names
//! the file and, where there is one, the line (or byte offset in binary data);
//! only regular files within [`Cap::MESH`] / [`Cap::SURFACE`] are read (a FIFO,
//! a device or a directory is refused before it is opened); every file is
//! written whole or not at all ([`fsio::write_atomic`]);
//! writers print f64 in shortest round-trip form, so text files read back to
//! the same bits.

pub mod error;
pub mod gmsh;
pub mod obj;
pub mod stl;
pub mod tetgen;
pub mod vtk;
pub mod vtu;

mod cursor;
mod tets;

use std::path::Path;

pub use error::{MeshFileError, MeshFileErrorKind};

use crate::fsio::{self, Cap};
use crate::math::Vec3;
use crate::mesh::{TetMesh, TriSurface};

/// One field over the nodes or over the tetrahedra of a mesh.
#[derive(Debug, Clone, PartialEq)]
pub enum Field {
    /// One value per node (or tet), e.g. von Mises stress in Pa.
    Scalar(Vec<f64>),
    /// One 3-vector per node (or tet), e.g. displacement in m.
    Vector(Vec<Vec3>),
}

impl Field {
    /// Number of values (nodes or tets covered).
    pub fn len(&self) -> usize {
        match self {
            Field::Scalar(v) => v.len(),
            Field::Vector(v) => v.len(),
        }
    }

    /// True when the field holds no values.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Named fields written beside a mesh: `point` has one value per node, `cell`
/// one per tetrahedron. Names: non-empty, no whitespace, none of `<>&"'`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct FieldData {
    pub point: Vec<(String, Field)>,
    pub cell: Vec<(String, Field)>,
}

impl FieldData {
    /// No fields.
    pub fn none() -> Self {
        Self::default()
    }

    /// Checks names, lengths against `nodes` / `tets`, and finiteness.
    pub fn check(&self, path: &Path, nodes: usize, tets: usize) -> Result<(), MeshFileError> {
        for (list, expected, of) in [(&self.point, nodes, "nodes"), (&self.cell, tets, "tetrahedra")] {
            for (name, field) in list {
                let bad_name = name.is_empty()
                    || name.chars().any(|ch| ch.is_whitespace() || ch.is_control() || "<>&\"'".contains(ch));
                if bad_name || name == "region" {
                    return Err(MeshFileError::new(path, MeshFileErrorKind::FieldName { name: name.clone() }));
                }
                if field.len() != expected {
                    return Err(MeshFileError::new(
                        path,
                        MeshFileErrorKind::FieldLength { name: name.clone(), expected, found: field.len(), of },
                    ));
                }
                let first_bad = match field {
                    Field::Scalar(v) => v.iter().position(|x| !x.is_finite()),
                    Field::Vector(v) => v.iter().position(|x| !crate::math::is_finite3(x)),
                };
                if let Some(index) = first_bad {
                    return Err(MeshFileError::new(path, MeshFileErrorKind::NonFiniteField { name: name.clone(), index }));
                }
            }
        }
        Ok(())
    }
}

/// Tet mesh file formats.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TetFormat {
    /// Gmsh `.msh`.
    Gmsh,
    /// VTK legacy `.vtk`.
    VtkLegacy,
    /// VTK XML `.vtu`.
    Vtu,
    /// TetGen `.node` + `.ele`.
    TetGen,
}

impl TetFormat {
    const EXPECTED: &'static str = ".msh, .vtk, .vtu, .node or .ele (each may end in .gz)";

    /// The format named by `path`'s extension (case-insensitive).
    pub fn from_path(path: &Path) -> Result<Self, MeshFileError> {
        match extension(path).as_str() {
            "msh" => Ok(TetFormat::Gmsh),
            "vtk" => Ok(TetFormat::VtkLegacy),
            "vtu" => Ok(TetFormat::Vtu),
            "node" | "ele" => Ok(TetFormat::TetGen),
            other => Err(MeshFileError::new(
                path,
                MeshFileErrorKind::UnknownExtension { extension: other.into(), expected: Self::EXPECTED },
            )),
        }
    }
}

/// The format's extension, lower case, looking through a trailing `.gz`
/// (`brain.msh.gz` -> `msh`).
fn extension(path: &Path) -> String {
    let outer = |p: &Path| p.extension().map(|e| e.to_string_lossy().to_ascii_lowercase()).unwrap_or_default();
    if is_gzip(path) { path.file_stem().map(|stem| outer(Path::new(stem))).unwrap_or_default() } else { outer(path) }
}

/// Whether `path` names a gzip-compressed file (`.gz`, any case).
fn is_gzip(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gz"))
}

/// `path` with its format extension replaced by `ext`, keeping a trailing `.gz`
/// (the TetGen sibling of `mesh.ele.gz` is `mesh.node.gz`).
fn sibling(path: &Path, ext: &str) -> std::path::PathBuf {
    if is_gzip(path) {
        let inner = path.with_extension("");
        inner.with_extension(format!("{ext}.gz"))
    } else {
        path.with_extension(ext)
    }
}

/// Reads a mesh or surface file: a regular file within `cap`, else an error
/// naming it; a `.gz` file is decompressed, its content within `cap` too (a
/// small file that inflates without end is refused, not read into memory).
fn read_capped(path: &Path, cap: Cap) -> Result<Vec<u8>, MeshFileError> {
    let bytes = fsio::read_regular(path, cap).map_err(|e| match e {
        fsio::ReadError::Refused { refusal, .. } => MeshFileError::new(path, MeshFileErrorKind::Refused(refusal)),
        fsio::ReadError::Io { source, .. } => MeshFileError::io(path, source),
    })?;
    if is_gzip(path) { gunzip(path, &bytes, cap) } else { Ok(bytes) }
}

/// The content of the gzip stream `bytes` (every member, as `gzip -d` reads them).
fn gunzip(path: &Path, bytes: &[u8], cap: Cap) -> Result<Vec<u8>, MeshFileError> {
    use std::io::Read;
    let mut out = Vec::with_capacity(bytes.len().saturating_mul(4));
    flate2::read::MultiGzDecoder::new(bytes)
        .take(cap.bytes.saturating_add(1))
        .read_to_end(&mut out)
        .map_err(|e| MeshFileError::new(path, MeshFileErrorKind::Gzip(e.to_string())))?;
    if out.len() as u64 > cap.bytes {
        return Err(MeshFileError::new(path, MeshFileErrorKind::Inflated { cap: cap.bytes, what: cap.what }));
    }
    Ok(out)
}

fn read(path: &Path) -> Result<Vec<u8>, MeshFileError> {
    read_capped(path, Cap::MESH)
}

/// Writes a whole output file (temporary name, then rename: never a partial
/// file), gzip-compressed when `path` ends in `.gz` (no time stamp in the
/// header, so the same mesh gives the same bytes).
fn write(path: &Path, bytes: &[u8]) -> Result<(), MeshFileError> {
    let compressed;
    let bytes = if is_gzip(path) {
        use std::io::Write;
        let mut encoder = flate2::GzBuilder::new().mtime(0).write(Vec::new(), flate2::Compression::best());
        compressed = encoder.write_all(bytes).and_then(|()| encoder.finish()).map_err(|e| MeshFileError::io(path, e))?;
        &compressed[..]
    } else {
        bytes
    };
    fsio::write_atomic(path, bytes).map_err(|e| MeshFileError::io(path, e.source))
}

/// Loads a tetrahedral mesh, choosing the reader by extension (see the module doc).
/// For TetGen either `x.node` or `x.ele` may be given; the sibling is found.
pub fn load_tet_mesh(path: &Path) -> Result<TetMesh, MeshFileError> {
    match TetFormat::from_path(path)? {
        TetFormat::Gmsh => gmsh::parse(path, &read(path)?),
        TetFormat::VtkLegacy => vtk::parse(path, &read(path)?),
        TetFormat::Vtu => vtu::parse(path, &read(path)?),
        TetFormat::TetGen => {
            let node_path = sibling(path, "node");
            let ele_path = sibling(path, "ele");
            tetgen::parse(&node_path, &read(&node_path)?, &ele_path, &read(&ele_path)?)
        }
    }
}

/// Loads a Gmsh `.msh` mesh with the node tag of every node (see [`gmsh::parse_with_node_tags`]).
pub fn load_gmsh_with_node_tags(path: &Path) -> Result<(TetMesh, Vec<i64>), MeshFileError> {
    gmsh::parse_with_node_tags(path, &read(path)?)
}

/// Loads a `.vtu` mesh with its point and cell data (see [`vtu::parse_with_fields`]).
pub fn load_vtu_with_fields(path: &Path) -> Result<(TetMesh, FieldData), MeshFileError> {
    vtu::parse_with_fields(path, &read(path)?)
}

/// Parses tet mesh bytes in the given single-file format (`path` is only used
/// in messages). TetGen needs two files: use [`tetgen::parse`].
pub fn parse_tet_mesh(path: &Path, format: TetFormat, bytes: &[u8]) -> Result<TetMesh, MeshFileError> {
    match format {
        TetFormat::Gmsh => gmsh::parse(path, bytes),
        TetFormat::VtkLegacy => vtk::parse(path, bytes),
        TetFormat::Vtu => vtu::parse(path, bytes),
        TetFormat::TetGen => Err(MeshFileError::new(
            path,
            MeshFileErrorKind::Unsupported("TetGen meshes span two files; use tetgen::parse".into()),
        )),
    }
}

/// Loads a triangle surface from `.obj` or `.stl` (ASCII or binary).
pub fn load_surface(path: &Path) -> Result<TriSurface, MeshFileError> {
    match extension(path).as_str() {
        "obj" => obj::parse(path, &read_capped(path, Cap::SURFACE)?),
        "stl" => stl::parse(path, &read_capped(path, Cap::SURFACE)?),
        other => Err(MeshFileError::new(
            path,
            MeshFileErrorKind::UnknownExtension { extension: other.into(), expected: ".obj or .stl" },
        )),
    }
}

/// Saves a tet mesh with fields: `.vtu` (binary base64, Float64 points, Int64
/// connectivity/offsets, UInt8 types, cell data "region"), `.msh` (Gmsh 2.2
/// ASCII, physical tag = region, fields as `$NodeData`/`$ElementData`), `.vtk`
/// (legacy ASCII), or TetGen `.node`/`.ele` (both files written, fields dropped:
/// the format has no place for them, so non-empty fields are an error).
pub fn save_tet_mesh(path: &Path, mesh: &TetMesh, fields: &FieldData) -> Result<(), MeshFileError> {
    if mesh.regions.len() != mesh.tets.len() {
        return Err(MeshFileError::new(
            path,
            MeshFileErrorKind::Mesh(crate::mesh::MeshError::RegionCount {
                tets: mesh.tets.len(),
                regions: mesh.regions.len(),
            }),
        ));
    }
    fields.check(path, mesh.positions.len(), mesh.tets.len())?;
    match TetFormat::from_path(path)? {
        TetFormat::Gmsh => write(path, gmsh::write(mesh, fields).as_bytes()),
        TetFormat::VtkLegacy => write(path, vtk::write(mesh, fields).as_bytes()),
        TetFormat::Vtu => write(path, vtu::write(mesh, fields).as_bytes()),
        TetFormat::TetGen => {
            if !(fields.point.is_empty() && fields.cell.is_empty()) {
                return Err(MeshFileError::new(
                    path,
                    MeshFileErrorKind::Unsupported("fields in TetGen files (use .vtu, .msh or .vtk)".into()),
                ));
            }
            let (node, ele) = tetgen::write(mesh);
            write(&sibling(path, "node"), node.as_bytes())?;
            write(&sibling(path, "ele"), ele.as_bytes())
        }
    }
}

/// Saves a triangle surface to `.obj` or `.stl` (ASCII STL, full f64 precision).
pub fn save_surface(path: &Path, surface: &TriSurface) -> Result<(), MeshFileError> {
    let n = surface.positions.len();
    if let Some(i) = surface.positions.iter().position(|p| !crate::math::is_finite3(p)) {
        return Err(MeshFileError::new(path, MeshFileErrorKind::NonFiniteCoordinate { node: i as i64 }));
    }
    if let Some((t, tri)) = surface.triangles.iter().enumerate().find(|(_, t)| t.iter().any(|&k| k as usize >= n)) {
        return Err(MeshFileError::new(
            path,
            MeshFileErrorKind::Invalid(format!("triangle {t} refers to vertex {:?}, but there are {n}", tri)),
        ));
    }
    match extension(path).as_str() {
        "obj" => write(path, obj::write(surface).as_bytes()),
        "stl" => write(path, stl::write(surface).as_bytes()),
        other => Err(MeshFileError::new(
            path,
            MeshFileErrorKind::UnknownExtension { extension: other.into(), expected: ".obj or .stl" },
        )),
    }
}

/// Writes a ParaView collection (`.pvd`) of time steps: each entry is (time in
/// s, file name relative to the `.pvd`). Times must be finite.
pub fn write_pvd(path: &Path, entries: &[(f64, String)]) -> Result<(), MeshFileError> {
    write(path, vtu::write_pvd(path, entries)?.as_bytes())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_format_is_named_through_a_trailing_gz() {
        assert_eq!(extension(Path::new("a/brain.msh.gz")), "msh");
        assert_eq!(extension(Path::new("brain.VTU.GZ")), "vtu");
        assert_eq!(extension(Path::new("brain.msh")), "msh");
        assert_eq!(extension(Path::new("brain.gz")), "");
        assert_eq!(sibling(Path::new("d/m.ele.gz"), "node"), Path::new("d/m.node.gz"));
        assert_eq!(sibling(Path::new("d/m.ele"), "node"), Path::new("d/m.node"));
    }

    #[test]
    fn a_stream_that_inflates_past_the_cap_is_refused() {
        use std::io::Write;
        let mut encoder = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
        encoder.write_all(&vec![b'0'; 1 << 20]).unwrap();
        let bomb = encoder.finish().unwrap();
        assert!(bomb.len() < 4096, "a MiB of zeros packs small ({} bytes)", bomb.len());
        let cap = Cap { bytes: 1000, what: "a mesh file" };
        let e = gunzip(Path::new("bomb.msh.gz"), &bomb, cap).expect_err("over the cap");
        assert!(matches!(e.kind, MeshFileErrorKind::Inflated { .. }), "{e}");
        assert!(e.to_string().starts_with("bomb.msh.gz: decompresses to more than"), "{e}");
        let fits = Cap { bytes: 1 << 20, what: "a mesh file" };
        assert_eq!(gunzip(Path::new("ok.gz"), &bomb, fits).unwrap().len(), 1 << 20);
    }
}
