//! Every mesh parser, fed random bytes, truncated prefixes of valid files and
//! valid files with one byte changed, returns Ok or Err: it never panics,
//! never loops forever, and never allocates what the input cannot back.

use std::path::Path;

use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::mesh::io::{self, FieldData, TetFormat};
use proptest::prelude::*;

fn tet() -> TetMesh {
    let p = vec![Vec3::zeros(), Vec3::x(), Vec3::y(), Vec3::z(), Vec3::new(1.0, 1.0, 1.0)];
    TetMesh::new(p, vec![[0, 1, 2, 3], [1, 2, 4, 3]], vec![1, 2]).expect("valid")
}

fn le32(b: &mut Vec<u8>, v: i32) {
    b.extend_from_slice(&v.to_le_bytes());
}
fn le64(b: &mut Vec<u8>, v: u64) {
    b.extend_from_slice(&v.to_le_bytes());
}
fn f64le(b: &mut Vec<u8>, v: f64) {
    b.extend_from_slice(&v.to_le_bytes());
}

fn gmsh22_binary(m: &TetMesh) -> Vec<u8> {
    let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
    le32(&mut b, 1);
    b.extend_from_slice(format!("\n$EndMeshFormat\n$Nodes\n{}\n", m.positions.len()).as_bytes());
    for (i, p) in m.positions.iter().enumerate() {
        le32(&mut b, i as i32 + 1);
        for x in [p.x, p.y, p.z] {
            f64le(&mut b, x);
        }
    }
    b.extend_from_slice(format!("\n$EndNodes\n$Elements\n{}\n", m.tets.len()).as_bytes());
    for v in [4, m.tets.len() as i32, 1] {
        le32(&mut b, v);
    }
    for (i, (t, r)) in m.tets.iter().zip(&m.regions).enumerate() {
        for v in [i as i32 + 1, *r as i32, t[0] as i32 + 1, t[1] as i32 + 1, t[2] as i32 + 1, t[3] as i32 + 1] {
            le32(&mut b, v);
        }
    }
    b.extend_from_slice(b"\n$EndElements\n");
    b
}

fn gmsh41_binary(m: &TetMesh) -> Vec<u8> {
    let mut b = b"$MeshFormat\n4.1 1 8\n".to_vec();
    le32(&mut b, 1);
    b.extend_from_slice(b"\n$EndMeshFormat\n$Entities\n");
    for v in [0, 0, 0, 1] {
        le64(&mut b, v);
    }
    le32(&mut b, 5);
    for x in [0.0, 0.0, 0.0, 1.0, 1.0, 1.0] {
        f64le(&mut b, x);
    }
    le64(&mut b, 1);
    le32(&mut b, 3);
    le64(&mut b, 0);
    b.extend_from_slice(b"\n$EndEntities\n$Nodes\n");
    let n = m.positions.len() as u64;
    for v in [1, n, 1, n] {
        le64(&mut b, v);
    }
    for v in [3, 5, 0] {
        le32(&mut b, v);
    }
    le64(&mut b, n);
    for k in 1..=n {
        le64(&mut b, k);
    }
    for p in &m.positions {
        for x in [p.x, p.y, p.z] {
            f64le(&mut b, x);
        }
    }
    b.extend_from_slice(b"\n$EndNodes\n$Elements\n");
    let e = m.tets.len() as u64;
    for v in [1, e, 1, e] {
        le64(&mut b, v);
    }
    for v in [3, 5, 4] {
        le32(&mut b, v);
    }
    le64(&mut b, e);
    for (i, t) in m.tets.iter().enumerate() {
        le64(&mut b, i as u64 + 1);
        for k in t {
            le64(&mut b, *k as u64 + 1);
        }
    }
    b.extend_from_slice(b"\n$EndElements\n");
    b
}

fn vtk_binary(m: &TetMesh) -> Vec<u8> {
    let mut b = format!("# vtk DataFile Version 3.0\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n", m.positions.len()).into_bytes();
    for p in &m.positions {
        for x in [p.x, p.y, p.z] {
            b.extend_from_slice(&x.to_be_bytes());
        }
    }
    b.extend_from_slice(format!("\nCELLS {} {}\n", m.tets.len(), 5 * m.tets.len()).as_bytes());
    for t in &m.tets {
        b.extend_from_slice(&4i32.to_be_bytes());
        for k in t {
            b.extend_from_slice(&(*k as i32).to_be_bytes());
        }
    }
    b.extend_from_slice(format!("\nCELL_TYPES {}\n", m.tets.len()).as_bytes());
    for _ in &m.tets {
        b.extend_from_slice(&10i32.to_be_bytes());
    }
    b.push(b'\n');
    b
}

fn vtu_appended(m: &TetMesh) -> Vec<u8> {
    let pts: Vec<u8> = m.positions.iter().flat_map(|p| [p.x, p.y, p.z]).flat_map(|x| x.to_le_bytes()).collect();
    let conn: Vec<u8> = m.tets.iter().flatten().flat_map(|&k| (k as i32).to_le_bytes()).collect();
    let offs: Vec<u8> = (1..=m.tets.len() as i32).flat_map(|k| (4 * k).to_le_bytes()).collect();
    let types = vec![10u8; m.tets.len()];
    let mut data = Vec::new();
    let mut offsets = Vec::new();
    for block in [&pts, &conn, &offs, &types] {
        offsets.push(data.len());
        data.extend_from_slice(&(block.len() as u32).to_le_bytes());
        data.extend_from_slice(block);
    }
    let mut b = format!(
        "<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\"><UnstructuredGrid><Piece NumberOfPoints=\"{}\" NumberOfCells=\"{}\">\
<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{}\"/></Points><Cells>\
<DataArray type=\"Int32\" Name=\"connectivity\" format=\"appended\" offset=\"{}\"/>\
<DataArray type=\"Int32\" Name=\"offsets\" format=\"appended\" offset=\"{}\"/>\
<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"{}\"/></Cells></Piece></UnstructuredGrid>\
<AppendedData encoding=\"raw\">_",
        m.positions.len(),
        m.tets.len(),
        offsets[0],
        offsets[1],
        offsets[2],
        offsets[3]
    )
    .into_bytes();
    b.extend_from_slice(&data);
    b.extend_from_slice(b"</AppendedData></VTKFile>");
    b
}

fn stl_binary() -> Vec<u8> {
    let mut b = vec![0u8; 80];
    b.extend_from_slice(&4u32.to_le_bytes());
    let p = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
    for f in [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] {
        b.extend_from_slice(&[0u8; 12]);
        for k in f {
            for x in p[k] {
                b.extend_from_slice(&x.to_le_bytes());
            }
        }
        b.extend_from_slice(&[0u8; 2]);
    }
    b
}

/// A single-file parser under test.
#[derive(Debug, Clone, Copy)]
enum Parser {
    Tet(TetFormat),
    Obj,
    Stl,
    TetGenNode,
    TetGenEle,
}

fn run(parser: Parser, bytes: &[u8]) {
    let path = Path::new("fuzz");
    let (node, ele) = io::tetgen::write(&tet());
    // The result may be Ok or Err; what matters is that we get here without a panic.
    let _ = match parser {
        Parser::Tet(f) => io::parse_tet_mesh(path, f, bytes).map(|_| ()),
        Parser::Obj => io::obj::parse(path, bytes).map(|_| ()),
        Parser::Stl => io::stl::parse(path, bytes).map(|_| ()),
        Parser::TetGenNode => io::tetgen::parse(path, bytes, path, ele.as_bytes()).map(|_| ()),
        Parser::TetGenEle => io::tetgen::parse(path, node.as_bytes(), path, bytes).map(|_| ()),
    };
}

/// Valid files of every format (checked to parse), each with its parser; built once.
fn seeds() -> &'static [(Parser, Vec<u8>)] {
    static SEEDS: std::sync::OnceLock<Vec<(Parser, Vec<u8>)>> = std::sync::OnceLock::new();
    SEEDS.get_or_init(build_seeds)
}

fn build_seeds() -> Vec<(Parser, Vec<u8>)> {
    let m = tet();
    let dir = tempfile::tempdir().expect("temp dir");
    let mut out = Vec::new();
    for (ext, parser) in [("msh", Parser::Tet(TetFormat::Gmsh)), ("vtk", Parser::Tet(TetFormat::VtkLegacy)), ("vtu", Parser::Tet(TetFormat::Vtu))] {
        let path = dir.path().join(format!("a.{ext}"));
        io::save_tet_mesh(&path, &m, &FieldData::none()).expect("save");
        out.push((parser, std::fs::read(&path).expect("read")));
    }
    let gmsh41_ascii = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n0 0 0 1\n5 0 0 0 1 1 1 1 3 0\n$EndEntities\n\
        $Nodes\n1 4 1 4\n3 5 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n$Elements\n1 1 1 1\n3 5 4 1\n1 1 2 3 4\n$EndElements\n";
    out.push((Parser::Tet(TetFormat::Gmsh), gmsh41_ascii.as_bytes().to_vec()));
    out.push((Parser::Tet(TetFormat::Gmsh), gmsh22_binary(&m)));
    out.push((Parser::Tet(TetFormat::Gmsh), gmsh41_binary(&m)));
    out.push((Parser::Tet(TetFormat::VtkLegacy), vtk_binary(&m)));
    out.push((Parser::Tet(TetFormat::Vtu), vtu_appended(&m)));
    let (node, ele) = io::tetgen::write(&m);
    out.push((Parser::TetGenNode, node.into_bytes()));
    out.push((Parser::TetGenEle, ele.into_bytes()));
    let surface = fissure::mesh::TriSurface { positions: m.positions.clone(), triangles: vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]] };
    out.push((Parser::Obj, io::obj::write(&surface).into_bytes()));
    out.push((Parser::Stl, io::stl::write(&surface).into_bytes()));
    out.push((Parser::Stl, stl_binary()));
    for (parser, bytes) in &out {
        let path = Path::new("seed");
        let ok = match parser {
            Parser::Tet(f) => io::parse_tet_mesh(path, *f, bytes).map(|_| ()).map_err(|e| e.to_string()),
            Parser::Obj => io::obj::parse(path, bytes).map(|_| ()).map_err(|e| e.to_string()),
            Parser::Stl => io::stl::parse(path, bytes).map(|_| ()).map_err(|e| e.to_string()),
            Parser::TetGenNode | Parser::TetGenEle => Ok(()),
        };
        assert!(ok.is_ok(), "seed for {parser:?} must be valid: {ok:?}");
    }
    out
}

const PARSERS: [Parser; 7] = [
    Parser::Tet(TetFormat::Gmsh),
    Parser::Tet(TetFormat::VtkLegacy),
    Parser::Tet(TetFormat::Vtu),
    Parser::Obj,
    Parser::Stl,
    Parser::TetGenNode,
    Parser::TetGenEle,
];

/// Headers that steer random bytes into the binary and deeper branches.
const PREFIXES: [&[u8]; 8] = [
    b"",
    b"$MeshFormat\n2.2 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n$Nodes\n",
    b"$MeshFormat\n4.1 1 8\n\x01\x00\x00\x00\n$EndMeshFormat\n$Elements\n",
    b"$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Entities\n",
    b"# vtk DataFile Version 5.1\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nCELLS ",
    b"<VTKFile type=\"UnstructuredGrid\"><UnstructuredGrid><Piece><Points><DataArray format=\"binary\" type=\"Float64\">",
    b"solid x\nfacet normal ",
    b"v 1 2 3\nf ",
];

proptest! {
    // 256 cases each in CI; FISSURE_FUZZ_CASES=100000 for a longer hunt.
    #![proptest_config(ProptestConfig {
        cases: std::env::var("FISSURE_FUZZ_CASES").ok().and_then(|v| v.parse().ok()).unwrap_or(256),
        failure_persistence: None,
        ..ProptestConfig::default()
    })]

    #[test]
    fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400), prefix in 0..PREFIXES.len()) {
        let mut input = PREFIXES[prefix].to_vec();
        input.extend_from_slice(&bytes);
        for parser in PARSERS {
            run(parser, &input);
        }
    }

    #[test]
    fn truncated_valid_files_never_panic(seed in 0usize..14, cut in any::<prop::sample::Index>()) {
        let seeds = seeds();
        let (parser, bytes) = &seeds[seed % seeds.len()];
        let k = cut.index(bytes.len() + 1);
        run(*parser, &bytes[..k]);
    }

    #[test]
    fn one_changed_byte_never_panics(seed in 0usize..14, at in any::<prop::sample::Index>(), byte in any::<u8>()) {
        let seeds = seeds();
        let (parser, bytes) = &seeds[seed % seeds.len()];
        let mut changed = bytes.to_vec();
        let i = at.index(changed.len());
        changed[i] = byte;
        run(*parser, &changed);
    }
}

#[test]
fn every_truncation_of_every_seed_is_an_error_or_a_mesh() {
    // Exhaustive over cut points for the small seeds: no panic, and a cut file
    // never silently yields more tetrahedra than the whole one.
    for &(parser, ref bytes) in seeds() {
        for k in 0..bytes.len() {
            run(parser, &bytes[..k]);
            if let Parser::Tet(f) = parser {
                if let Ok(m) = io::parse_tet_mesh(Path::new("cut"), f, &bytes[..k]) {
                    assert!(m.tets.len() <= 2, "{parser:?} cut at {k} produced {} tets", m.tets.len());
                }
            }
        }
    }
}
