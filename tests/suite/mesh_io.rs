//! Mesh import/export: round trips through every writable format, readers of
//! formats we do not write (Gmsh 2.2 binary, 4.1 ASCII and binary, VTK legacy
//! binary, VTU ASCII and appended raw) fed by small writers in this file, and
//! every kind of bad input ending in an error that names the file and line.

use std::fmt::Write as _;
use std::path::Path;

use fissure::math::Vec3;
use fissure::mesh::io::{self, Field, FieldData, MeshFileErrorKind as K, TetFormat};
use fissure::mesh::{TetMesh, TriSurface};

/// An n x n x n block of Kuhn-split cubes (6 tets each) with irregular
/// coordinates (so round trips exercise all 17 significant digits), region 1
/// for the left half and 2 for the right, and the tet list in mixed orientation.
fn block(n: u32) -> TetMesh {
    let m = n + 1;
    let id = |i: u32, j: u32, k: u32| i + m * (j + m * k);
    let mut p = Vec::new();
    for k in 0..m {
        for j in 0..m {
            for i in 0..m {
                let jitter = 1e-3 * ((i * 7 + j * 13 + k * 29) as f64).sin();
                p.push(Vec3::new(i as f64 * 0.1 + jitter, j as f64 / 3.0, k as f64 * 1.1e-3 - 42.0));
            }
        }
    }
    let mut tets = Vec::new();
    let mut regions = Vec::new();
    for k in 0..n {
        for j in 0..n {
            for i in 0..n {
                let c = |di: u32, dj: u32, dk: u32| id(i + di, j + dj, k + dk);
                let (v0, v7) = (c(0, 0, 0), c(1, 1, 1));
                for [a, b] in [[c(1, 0, 0), c(1, 1, 0)], [c(1, 0, 0), c(1, 0, 1)], [c(0, 1, 0), c(1, 1, 0)], [c(0, 1, 0), c(0, 1, 1)], [c(0, 0, 1), c(1, 0, 1)], [c(0, 0, 1), c(0, 1, 1)]] {
                    tets.push([v0, a, b, v7]);
                    regions.push(if 2 * i < n { 1 } else { 2 });
                }
            }
        }
    }
    TetMesh::new(p, tets, regions).expect("block mesh is valid")
}

fn fields_for(mesh: &TetMesh) -> FieldData {
    FieldData {
        point: vec![
            ("displacement".into(), Field::Vector(mesh.positions.iter().map(|p| p * 1e-3 + Vec3::new(0.1, 0.0, -3e-7)).collect())),
            ("pressure".into(), Field::Scalar((0..mesh.positions.len()).map(|i| (i as f64).sqrt() * 1e5).collect())),
        ],
        cell: vec![("von_mises".into(), Field::Scalar((0..mesh.tets.len()).map(|i| 1.0 / (1.0 + i as f64)).collect()))],
    }
}

fn assert_same_mesh(a: &TetMesh, b: &TetMesh, what: &str) {
    assert_eq!(a.positions.len(), b.positions.len(), "{what}: node count");
    for (i, (p, q)) in a.positions.iter().zip(&b.positions).enumerate() {
        let bits = |v: &Vec3| [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()];
        assert_eq!(bits(p), bits(q), "{what}: node {i} must round-trip bit for bit ({p} vs {q})");
    }
    assert_eq!(a.tets, b.tets, "{what}: tets (already oriented, so unchanged)");
    assert_eq!(a.regions, b.regions, "{what}: regions");
}

#[test]
fn every_writable_format_round_trips_bitwise() {
    let dir = tempfile::tempdir().expect("temp dir");
    for mesh in [block(1), block(4)] {
        assert!(mesh.reoriented > 0, "the block's tet list mixes orientations");
        let fields = fields_for(&mesh);
        for ext in ["vtu", "msh", "vtk", "node", "ele"] {
            let path = dir.path().join(format!("m{}.{ext}", mesh.tets.len()));
            let f = if matches!(ext, "node" | "ele") { FieldData::none() } else { fields.clone() };
            io::save_tet_mesh(&path, &mesh, &f).unwrap_or_else(|e| panic!("save {ext}: {e}"));
            let back = io::load_tet_mesh(&path).unwrap_or_else(|e| panic!("load {ext}: {e}"));
            assert_same_mesh(&mesh, &back, ext);
            assert_eq!(back.reoriented, 0, "{ext}: saved tets are positive, none reordered on reload");
        }
        let path = dir.path().join("f.vtu");
        io::save_tet_mesh(&path, &mesh, &fields).expect("save vtu");
        let (back, back_fields) = io::load_vtu_with_fields(&path).expect("reload with fields");
        assert_same_mesh(&mesh, &back, "vtu with fields");
        assert_eq!(back_fields, fields, "VTU point and cell data must come back exactly");
    }
}

#[test]
fn gzipped_files_round_trip_bitwise_and_read_as_the_plain_ones() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mesh = block(3);
    for ext in ["vtu", "msh", "vtk", "node", "ele"] {
        let plain = dir.path().join(format!("p.{ext}"));
        let packed = dir.path().join(format!("z.{ext}.gz"));
        io::save_tet_mesh(&plain, &mesh, &FieldData::none()).unwrap_or_else(|e| panic!("save {ext}: {e}"));
        io::save_tet_mesh(&packed, &mesh, &FieldData::none()).unwrap_or_else(|e| panic!("save {ext}.gz: {e}"));
        let gz_file = if ext == "ele" { dir.path().join("z.node.gz") } else { packed.clone() };
        let head = std::fs::read(&gz_file).expect("read gz");
        assert_eq!(&head[..2], &[0x1f, 0x8b], "{ext}.gz starts with the gzip magic");
        let a = io::load_tet_mesh(&plain).unwrap_or_else(|e| panic!("load {ext}: {e}"));
        let b = io::load_tet_mesh(&packed).unwrap_or_else(|e| panic!("load {ext}.gz: {e}"));
        assert_same_mesh(&a, &b, ext);
        assert_same_mesh(&mesh, &b, ext);
    }
    // The same mesh gives the same compressed bytes (no time stamp in the header).
    let again = dir.path().join("again.msh.gz");
    io::save_tet_mesh(&again, &mesh, &FieldData::none()).expect("save");
    assert_eq!(std::fs::read(&again).unwrap(), std::fs::read(dir.path().join("z.msh.gz")).unwrap());
    // Surfaces too.
    let surface = TriSurface { positions: mesh.positions.clone(), triangles: vec![[0, 1, 2], [1, 3, 2]] };
    for ext in ["obj", "stl"] {
        let path = dir.path().join(format!("s.{ext}.GZ"));
        io::save_surface(&path, &surface).unwrap_or_else(|e| panic!("save {ext}: {e}"));
        let back = io::load_surface(&path).unwrap_or_else(|e| panic!("load {ext}: {e}"));
        assert_eq!(back.triangles, surface.triangles, "{ext}");
    }
}

#[test]
fn a_broken_gzip_file_is_an_error_naming_it() {
    let dir = tempfile::tempdir().expect("temp dir");
    let good = dir.path().join("good.msh.gz");
    io::save_tet_mesh(&good, &block(2), &FieldData::none()).expect("save");
    let bytes = std::fs::read(&good).unwrap();
    // Truncated in the middle of the stream, then not gzip at all.
    let cut = dir.path().join("cut.msh.gz");
    std::fs::write(&cut, &bytes[..bytes.len() / 2]).unwrap();
    let plain = dir.path().join("plain.msh.gz");
    std::fs::write(&plain, "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n").unwrap();
    for path in [cut, plain] {
        let e = io::load_tet_mesh(&path).expect_err("a broken .gz must fail");
        assert!(matches!(e.kind, K::Gzip(_)), "{e}");
        let message = e.to_string();
        assert!(message.contains(path.file_name().unwrap().to_str().unwrap()) && message.contains("gzip"), "{message}");
    }
    // A plain mesh's extension with .gz missing is read as plain text, and a
    // gzip'd file named without .gz is not mistaken for text silently.
    let unnamed = dir.path().join("unnamed.msh");
    std::fs::write(&unnamed, &bytes).unwrap();
    assert!(io::load_tet_mesh(&unnamed).is_err());
}

#[test]
fn vtu_is_the_paraview_layout() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("a.vtu");
    io::save_tet_mesh(&path, &block(1), &FieldData::none()).expect("save");
    let text = std::fs::read_to_string(&path).expect("text");
    for needle in [
        "<VTKFile type=\"UnstructuredGrid\"",
        "header_type=\"UInt64\"",
        "<DataArray type=\"Float64\" Name=\"Points\" NumberOfComponents=\"3\" format=\"binary\">",
        "<DataArray type=\"Int64\" Name=\"connectivity\"",
        "<DataArray type=\"Int64\" Name=\"offsets\"",
        "<DataArray type=\"UInt8\" Name=\"types\"",
        "<DataArray type=\"UInt32\" Name=\"region\"",
    ] {
        assert!(text.contains(needle), "VTU lacks {needle}:\n{text}");
    }
}

#[test]
fn field_length_mismatch_and_bad_names_are_errors() {
    let dir = tempfile::tempdir().expect("temp dir");
    let mesh = block(1);
    let path = dir.path().join("a.vtu");
    let short = FieldData { point: vec![("u".into(), Field::Scalar(vec![1.0; 3]))], cell: vec![] };
    let e = io::save_tet_mesh(&path, &mesh, &short).expect_err("3 values for 8 nodes");
    assert!(matches!(e.kind, K::FieldLength { expected: 8, found: 3, .. }), "{e}");
    let spaced = FieldData { point: vec![], cell: vec![("a b".into(), Field::Scalar(vec![0.0; 6]))] };
    assert!(matches!(io::save_tet_mesh(&path, &mesh, &spaced).expect_err("space").kind, K::FieldName { .. }));
    let nan = FieldData { point: vec![], cell: vec![("s".into(), Field::Scalar(vec![f64::NAN; 6]))] };
    assert!(matches!(io::save_tet_mesh(&path, &mesh, &nan).expect_err("NaN").kind, K::NonFiniteField { index: 0, .. }));
    assert!(matches!(io::save_tet_mesh(&dir.path().join("a.xyz"), &mesh, &FieldData::none()).expect_err("ext").kind, K::UnknownExtension { .. }));
}

// ---------- small writers for formats fissure reads but does not write ----------

fn gmsh22_binary(mesh: &TetMesh) -> Vec<u8> {
    let mut b = b"$MeshFormat\n2.2 1 8\n".to_vec();
    b.extend_from_slice(&1i32.to_le_bytes());
    b.extend_from_slice(format!("\n$EndMeshFormat\n$Nodes\n{}\n", mesh.positions.len()).as_bytes());
    for (i, p) in mesh.positions.iter().enumerate() {
        b.extend_from_slice(&(i as i32 + 1).to_le_bytes());
        for x in [p.x, p.y, p.z] {
            b.extend_from_slice(&x.to_le_bytes());
        }
    }
    b.extend_from_slice(format!("\n$EndNodes\n$Elements\n{}\n", mesh.tets.len() + 1).as_bytes());
    // One triangle (type 2) first, to be skipped, then all tets in one block.
    for v in [2i32, 1, 2, 1, 5, 5, 1, 2, 3] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for v in [4i32, mesh.tets.len() as i32, 2] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    for (i, (t, &r)) in mesh.tets.iter().zip(&mesh.regions).enumerate() {
        for v in [i as i32 + 2, r as i32, 9, t[0] as i32 + 1, t[1] as i32 + 1, t[2] as i32 + 1, t[3] as i32 + 1] {
            b.extend_from_slice(&v.to_le_bytes());
        }
    }
    b.extend_from_slice(b"\n$EndElements\n");
    b
}

/// Gmsh 4.1 with one volume entity per region (entity 10 + region, physical = region),
/// nodes tagged from 100 (sparse tags), one triangle block to skip.
fn gmsh41(mesh: &TetMesh, binary: bool) -> Vec<u8> {
    let mut regions: Vec<u32> = mesh.regions.clone();
    regions.sort_unstable();
    regions.dedup();
    // Element blocks: maximal runs of consecutive tets in one region (keeps the tet order).
    let mut runs: Vec<(u32, usize, usize)> = Vec::new();
    for (i, &r) in mesh.regions.iter().enumerate() {
        match runs.last_mut() {
            Some(run) if run.0 == r => run.2 = i + 1,
            _ => runs.push((r, i, i + 1)),
        }
    }
    let n = mesh.positions.len();
    let tag = |k: u32| 100 + 2 * k as u64;
    let mut b: Vec<u8> = Vec::new();
    if !binary {
        let mut s = String::from("$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$PhysicalNames\n1\n3 1 \"x\"\n$EndPhysicalNames\n$Entities\n0 0 1 ");
        let _ = writeln!(s, "{}", regions.len());
        s.push_str("1 0 0 0 1 1 1 0 0\n");
        for r in &regions {
            let _ = writeln!(s, "{} -1 -1 -1 1 1 1 1 {r} 1 1", 10 + r);
        }
        let _ = write!(s, "$EndEntities\n$Nodes\n1 {n} {} {}\n3 {} 0 {n}\n", tag(0), tag(n as u32 - 1), 10 + regions[0]);
        for k in 0..n as u32 {
            let _ = writeln!(s, "{}", tag(k));
        }
        for p in &mesh.positions {
            let _ = writeln!(s, "{:?} {:?} {:?}", p.x, p.y, p.z);
        }
        let total = mesh.tets.len() + 1;
        let _ = write!(s, "$EndNodes\n$Elements\n{} {total} 1 {total}\n2 1 2 1\n1 {} {} {}\n", runs.len() + 1, tag(0), tag(1), tag(2));
        let mut e = 2;
        for &(r, start, end) in &runs {
            let _ = writeln!(s, "3 {} 4 {}", 10 + r, end - start);
            for t in &mesh.tets[start..end] {
                let _ = writeln!(s, "{e} {} {} {} {}", tag(t[0]), tag(t[1]), tag(t[2]), tag(t[3]));
                e += 1;
            }
        }
        s.push_str("$EndElements\n");
        return s.into_bytes();
    }
    let sz = |b: &mut Vec<u8>, v: u64| b.extend_from_slice(&v.to_le_bytes());
    let int = |b: &mut Vec<u8>, v: i32| b.extend_from_slice(&v.to_le_bytes());
    let dbl = |b: &mut Vec<u8>, v: f64| b.extend_from_slice(&v.to_le_bytes());
    b.extend_from_slice(b"$MeshFormat\n4.1 1 8\n");
    int(&mut b, 1);
    b.extend_from_slice(b"\n$EndMeshFormat\n$Entities\n");
    for v in [0, 0, 1, regions.len() as u64] {
        sz(&mut b, v);
    }
    int(&mut b, 1);
    for x in [0.0, 0.0, 0.0, 1.0, 1.0, 1.0] {
        dbl(&mut b, x);
    }
    sz(&mut b, 0);
    sz(&mut b, 0);
    for r in &regions {
        int(&mut b, 10 + *r as i32);
        for x in [-1.0, -1.0, -1.0, 1.0, 1.0, 1.0] {
            dbl(&mut b, x);
        }
        sz(&mut b, 1);
        int(&mut b, *r as i32);
        sz(&mut b, 1);
        int(&mut b, 1);
    }
    b.extend_from_slice(b"\n$EndEntities\n$Nodes\n");
    for v in [1, n as u64, tag(0), tag(n as u32 - 1)] {
        sz(&mut b, v);
    }
    int(&mut b, 3);
    int(&mut b, 10 + regions[0] as i32);
    int(&mut b, 0);
    sz(&mut b, n as u64);
    for k in 0..n as u32 {
        sz(&mut b, tag(k));
    }
    for p in &mesh.positions {
        for x in [p.x, p.y, p.z] {
            dbl(&mut b, x);
        }
    }
    b.extend_from_slice(b"\n$EndNodes\n$Elements\n");
    let total = mesh.tets.len() as u64 + 1;
    for v in [runs.len() as u64 + 1, total, 1, total] {
        sz(&mut b, v);
    }
    for v in [2, 1, 2] {
        int(&mut b, v);
    }
    sz(&mut b, 1);
    for v in [1, tag(0), tag(1), tag(2)] {
        sz(&mut b, v);
    }
    let mut e = 2;
    for &(r, start, end) in &runs {
        for v in [3, 10 + r as i32, 4] {
            int(&mut b, v);
        }
        sz(&mut b, (end - start) as u64);
        for t in &mesh.tets[start..end] {
            sz(&mut b, e);
            for k in t {
                sz(&mut b, tag(*k));
            }
            e += 1;
        }
    }
    b.extend_from_slice(b"\n$EndElements\n");
    b
}

/// VTK legacy binary (big-endian), version 3.0 cells, region as cell scalars,
/// plus one triangle cell to skip.
fn vtk_binary(mesh: &TetMesh) -> Vec<u8> {
    let mut b = format!("# vtk DataFile Version 3.0\nt\nBINARY\nDATASET UNSTRUCTURED_GRID\nPOINTS {} double\n", mesh.positions.len()).into_bytes();
    for p in &mesh.positions {
        for x in [p.x, p.y, p.z] {
            b.extend_from_slice(&x.to_be_bytes());
        }
    }
    let m = mesh.tets.len() + 1;
    b.extend_from_slice(format!("\nCELLS {m} {}\n", 5 * mesh.tets.len() + 4).as_bytes());
    for v in [3, 0, 1, 2] {
        b.extend_from_slice(&(v as i32).to_be_bytes());
    }
    for t in &mesh.tets {
        b.extend_from_slice(&4i32.to_be_bytes());
        for k in t {
            b.extend_from_slice(&(*k as i32).to_be_bytes());
        }
    }
    b.extend_from_slice(format!("\nCELL_TYPES {m}\n").as_bytes());
    b.extend_from_slice(&5i32.to_be_bytes());
    for _ in &mesh.tets {
        b.extend_from_slice(&10i32.to_be_bytes());
    }
    b.extend_from_slice(format!("\nCELL_DATA {m}\nSCALARS region int 1\nLOOKUP_TABLE default\n").as_bytes());
    b.extend_from_slice(&0i32.to_be_bytes());
    for r in &mesh.regions {
        b.extend_from_slice(&(*r as i32).to_be_bytes());
    }
    b.push(b'\n');
    b
}

/// VTU with ASCII arrays (Float32 points would lose bits; use Float64 text) or appended raw data.
fn vtu_text(mesh: &TetMesh, appended: bool) -> Vec<u8> {
    let n = mesh.positions.len();
    let m = mesh.tets.len();
    let points: Vec<f64> = mesh.positions.iter().flat_map(|p| [p.x, p.y, p.z]).collect();
    let conn: Vec<i32> = mesh.tets.iter().flatten().map(|&k| k as i32).collect();
    let offsets: Vec<i32> = (1..=m as i32).map(|k| 4 * k).collect();
    let regions: Vec<i32> = mesh.regions.iter().map(|&r| r as i32).collect();
    let mut s = format!("<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"0.1\" byte_order=\"LittleEndian\">\n<UnstructuredGrid><Piece NumberOfPoints=\"{n}\" NumberOfCells=\"{m}\">\n");
    if !appended {
        let join = |v: &[String]| v.join(" ");
        let _ = write!(s, "<CellData><DataArray type=\"Int32\" Name=\"gmsh:physical\" format=\"ascii\">{}</DataArray></CellData>\n", join(&regions.iter().map(|x| x.to_string()).collect::<Vec<_>>()));
        let _ = write!(s, "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"ascii\">\n{}\n</DataArray></Points>\n", join(&points.iter().map(|x| format!("{x:e}")).collect::<Vec<_>>()));
        let _ = write!(s, "<Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"ascii\">{}</DataArray>\n", join(&conn.iter().map(|x| x.to_string()).collect::<Vec<_>>()));
        let _ = write!(s, "<DataArray type=\"Int32\" Name=\"offsets\" format=\"ascii\">{}</DataArray>\n", join(&offsets.iter().map(|x| x.to_string()).collect::<Vec<_>>()));
        let _ = write!(s, "<DataArray type=\"UInt8\" Name=\"types\" format=\"ascii\">{}</DataArray></Cells>\n", vec!["10"; m].join(" "));
        s.push_str("</Piece></UnstructuredGrid></VTKFile>\n");
        return s.into_bytes();
    }
    let mut data: Vec<u8> = Vec::new();
    let mut block = |bytes: Vec<u8>| {
        let at = data.len();
        data.extend_from_slice(&(bytes.len() as u32).to_le_bytes());
        data.extend_from_slice(&bytes);
        at
    };
    let o_reg = block(regions.iter().flat_map(|x| x.to_le_bytes()).collect());
    let o_pts = block(points.iter().flat_map(|x| x.to_le_bytes()).collect());
    let o_conn = block(conn.iter().flat_map(|x| x.to_le_bytes()).collect());
    let o_off = block(offsets.iter().flat_map(|x| x.to_le_bytes()).collect());
    let o_ty = block(vec![10u8; m]);
    let _ = write!(s, "<CellData><DataArray type=\"Int32\" Name=\"CellEntityIds\" format=\"appended\" offset=\"{o_reg}\"/></CellData>\n");
    let _ = write!(s, "<Points><DataArray type=\"Float64\" NumberOfComponents=\"3\" format=\"appended\" offset=\"{o_pts}\"/></Points>\n");
    let _ = write!(s, "<Cells><DataArray type=\"Int32\" Name=\"connectivity\" format=\"appended\" offset=\"{o_conn}\"/>\n");
    let _ = write!(s, "<DataArray type=\"Int32\" Name=\"offsets\" format=\"appended\" offset=\"{o_off}\"/>\n");
    let _ = write!(s, "<DataArray type=\"UInt8\" Name=\"types\" format=\"appended\" offset=\"{o_ty}\"/></Cells>\n");
    s.push_str("</Piece></UnstructuredGrid>\n<AppendedData encoding=\"raw\">\n_");
    let mut b = s.into_bytes();
    b.extend_from_slice(&data);
    b.extend_from_slice(b"\n</AppendedData>\n</VTKFile>\n");
    b
}

#[test]
fn readers_of_formats_we_do_not_write() {
    let mesh = block(3);
    let cases: Vec<(&str, TetFormat, Vec<u8>)> = vec![
        ("gmsh 2.2 binary", TetFormat::Gmsh, gmsh22_binary(&mesh)),
        ("gmsh 4.1 ascii", TetFormat::Gmsh, gmsh41(&mesh, false)),
        ("gmsh 4.1 binary", TetFormat::Gmsh, gmsh41(&mesh, true)),
        ("vtk legacy binary", TetFormat::VtkLegacy, vtk_binary(&mesh)),
        ("vtu ascii", TetFormat::Vtu, vtu_text(&mesh, false)),
        ("vtu appended raw", TetFormat::Vtu, vtu_text(&mesh, true)),
    ];
    for (what, format, bytes) in cases {
        let back = io::parse_tet_mesh(Path::new(what), format, &bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_same_mesh(&mesh, &back, what);
    }
}

#[test]
fn gmsh_41_without_physical_tags_gives_region_zero() {
    let text = "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\n1 4 1 4\n3 1 0 4\n1\n2\n3\n4\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n$EndNodes\n$Elements\n1 1 1 1\n3 1 4 1\n1 1 2 3 4\n$EndElements\n";
    let m = io::parse_tet_mesh(Path::new("a.msh"), TetFormat::Gmsh, text.as_bytes()).expect("valid");
    assert_eq!(m.regions, vec![0]);
}

// ---------------------------------- bad input ----------------------------------

const GOOD_MSH: &str = "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n4\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n$EndNodes\n$Elements\n1\n1 4 2 1 1 1 2 3 4\n$EndElements\n";

fn msh_error(text: &str) -> String {
    let e = io::parse_tet_mesh(Path::new("brain.msh"), TetFormat::Gmsh, text.as_bytes()).expect_err("bad input must fail");
    e.to_string()
}

#[test]
fn gmsh_bad_inputs_name_file_line_and_problem() {
    assert!(io::parse_tet_mesh(Path::new("brain.msh"), TetFormat::Gmsh, GOOD_MSH.as_bytes()).is_ok(), "the base file is valid");
    let cases: [(&str, String, &str); 9] = [
        ("truncated", GOOD_MSH[..GOOD_MSH.len() - 13].to_string(), "brain.msh:14: unexpected end of file (expected $EndElements)"),
        ("truncated nodes", GOOD_MSH[..60].to_string(), "unexpected end of file (expected"),
        ("malformed number", GOOD_MSH.replace("3 0 1 0", "3 0 1x 0"), "brain.msh:8: malformed number \"1x\" (y coordinate of node 3)"),
        ("unsupported element", GOOD_MSH.replace("1 4 2 1 1 1 2 3 4", "1 5 2 1 1 1 2 3 4 1 2 3 4"), "brain.msh:13: unsupported element type 5"),
        ("index out of range", GOOD_MSH.replace("1 2 3 4\n$EndE", "1 2 3 77\n$EndE"), "brain.msh:13: element 1 refers to node 77, which the file does not define"),
        ("NaN coordinate", GOOD_MSH.replace("2 1 0 0", "2 nan 0 0"), "brain.msh:7: node 2 has a non-finite coordinate"),
        ("Inf coordinate", GOOD_MSH.replace("4 0 0 1", "4 0 0 inf"), "brain.msh:9: node 4 has a non-finite coordinate"),
        ("zero volume", GOOD_MSH.replace("4 0 0 1", "4 1 1 0"), "brain.msh:13: tetrahedron 0 has zero volume"),
        ("empty mesh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n0\n$EndNodes\n$Elements\n0\n$EndElements\n".into(), "brain.msh: the file holds no nodes"),
    ];
    for (what, text, expected) in cases {
        let msg = msh_error(&text);
        assert!(msg.contains(expected), "{what}: got \"{msg}\", expected it to contain \"{expected}\"");
    }
    assert!(msh_error("$MeshFormat\n3.0 0 8\n$EndMeshFormat\n").contains("unsupported file format version 3.0"));
    assert!(msh_error("").contains("unexpected end of file (expected $MeshFormat)"));
}

#[test]
fn other_formats_bad_inputs_name_file_and_line() {
    let vtk = "# vtk DataFile Version 2.0\nt\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 4 double\n0 0 0\n1 0 0\n0 1 0\n0 0 1\nCELLS 1 5\n4 0 1 2 3\nCELL_TYPES 1\n10\n";
    assert!(io::parse_tet_mesh(Path::new("a.vtk"), TetFormat::VtkLegacy, vtk.as_bytes()).is_ok());
    let vtk_cases = [
        (vtk.replace("1 0 0\n0 1", "1 0 zero\n0 1"), "a.vtk:7: malformed number \"zero\""),
        (vtk.replace("4 0 1 2 3", "4 0 1 2 9"), "a.vtk:11: element 0 refers to node 9"),
        (vtk.replace("0 0 1\nCELLS", "0 0 NaN\nCELLS"), "a.vtk:9: node 3 has a non-finite coordinate"),
        (vtk.replace("CELL_TYPES 1\n10", "CELL_TYPES 1\n13"), "a.vtk:11: unsupported element type 13"),
        (vtk.replace("0 0 1\nCELLS", "1 1 0\nCELLS"), "a.vtk:11: tetrahedron 0 has zero volume"),
        (vtk[..vtk.len() - 4].to_string(), "a.vtk:12: unexpected end of file (expected cell types, value 1 of 1)"),
    ];
    for (text, expected) in vtk_cases {
        let e = io::parse_tet_mesh(Path::new("a.vtk"), TetFormat::VtkLegacy, text.as_bytes()).expect_err(expected);
        assert!(e.to_string().contains(expected), "got \"{e}\", expected \"{expected}\"");
    }
    let vtu = String::from_utf8(vtu_text(&block(1), false)).expect("utf8");
    let e = io::parse_tet_mesh(Path::new("a.vtu"), TetFormat::Vtu, vtu.replacen("0e0", "0e0q", 1).as_bytes()).expect_err("bad number");
    assert!(e.to_string().starts_with("a.vtu:6: malformed number \"0e0q\""), "{e}");
    let e = io::parse_tet_mesh(Path::new("a.vtu"), TetFormat::Vtu, &vtu.as_bytes()[..vtu.len() / 2]).expect_err("truncated");
    assert!(e.to_string().starts_with("a.vtu"), "{e}");
    let e = io::parse_tet_mesh(Path::new("a.vtu"), TetFormat::Vtu, vtu.replace("LittleEndian\"", "LittleEndian\" compressor=\"vtkZLibDataCompressor\"").as_bytes()).expect_err("compressed");
    assert!(e.to_string().contains("unsupported: compressed VTU"), "{e}");

    let node = b"4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 1\n";
    let e = io::tetgen::parse(Path::new("a.node"), node, Path::new("a.ele"), b"1 10 0\n").expect_err("10-node");
    assert_eq!(e.to_string(), "a.ele:1: unsupported: 10-node tetrahedra (only 4)");
    let e = io::tetgen::parse(Path::new("a.node"), b"4 3 0 0\n0 0 0 0\n1 1 0 0\n2 0 1 0\n3 0 0 -inf\n", Path::new("a.ele"), b"1 4 0\n0 0 1 2 3\n").expect_err("inf");
    assert_eq!(e.to_string(), "a.node:5: node 3 has a non-finite coordinate");
}

#[test]
fn missing_file_and_unknown_extension_are_errors() {
    let e = io::load_tet_mesh(Path::new("/nonexistent/brain.msh")).expect_err("missing");
    assert!(e.to_string().starts_with("/nonexistent/brain.msh: cannot access the file"), "{e}");
    assert!(std::error::Error::source(&e).is_some(), "the io::Error is the source");
    let e = io::load_tet_mesh(Path::new("brain.ply")).expect_err("ply");
    assert!(e.to_string().contains("unknown mesh file extension \"ply\""), "{e}");
}

// ---------------------------------- surfaces ----------------------------------

fn octahedron() -> TriSurface {
    let positions = vec![
        Vec3::new(1.0 / 3.0, 0.0, 0.0),
        Vec3::new(-1.0, 1e-300, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, -1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0 + 1e-15),
        Vec3::new(0.0, 0.0, -1.0),
    ];
    let triangles = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
    TriSurface { positions, triangles }
}

#[test]
fn surfaces_round_trip_through_obj_and_stl() {
    let dir = tempfile::tempdir().expect("temp dir");
    let s = octahedron();
    for ext in ["obj", "stl"] {
        let path = dir.path().join(format!("s.{ext}"));
        io::save_surface(&path, &s).unwrap_or_else(|e| panic!("save {ext}: {e}"));
        let back = io::load_surface(&path).unwrap_or_else(|e| panic!("load {ext}: {e}"));
        // STL has no shared vertices: compare each triangle's corners bit for bit.
        let corners = |m: &TriSurface| {
            m.triangles.iter().map(|t| t.map(|k| { let p = m.positions[k as usize]; [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()] })).collect::<Vec<_>>()
        };
        assert_eq!(corners(&back), corners(&s), "{ext}: triangle corners bit for bit, same winding");
        assert_eq!(back.positions.len(), s.positions.len(), "{ext}: shared corners merge back into 6 vertices");
        if ext == "obj" {
            assert_eq!(back, s, "OBJ keeps the vertex numbering");
        }
    }
}

#[test]
fn surface_bad_inputs() {
    let e = io::obj::parse(Path::new("s.obj"), b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2\n").expect_err("2-vertex face");
    assert_eq!(e.to_string(), "s.obj:4: face with 2 vertices (at least 3)");
    let e = io::obj::parse(Path::new("s.obj"), b"v 0 0 0\nv 1 0 nan\n").expect_err("nan");
    assert_eq!(e.to_string(), "s.obj:2: node 2 has a non-finite coordinate");
    let e = io::obj::parse(Path::new("s.obj"), b"v 0 0 0\n").expect_err("no faces");
    assert_eq!(e.to_string(), "s.obj: the file holds no faces");
    let e = io::stl::parse(Path::new("s.stl"), b"solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0\nendloop\n").expect_err("short vertex");
    assert!(e.to_string().starts_with("s.stl:6: malformed number \"endloop\""), "{e}");
    let e = io::stl::parse(Path::new("s.stl"), b"garbage").expect_err("neither");
    assert!(e.to_string().contains("neither ASCII STL"), "{e}");
}

#[test]
fn pvd_lists_time_steps() {
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("run.pvd");
    io::write_pvd(&path, &[(0.0, "f0.vtu".into()), (0.016, "f1.vtu".into())]).expect("write");
    let text = std::fs::read_to_string(&path).expect("read");
    assert!(text.contains("<VTKFile type=\"Collection\""), "{text}");
    assert!(text.contains("timestep=\"0.016\"") && text.contains("file=\"f1.vtu\""), "{text}");
    assert_eq!(text.matches("<DataSet ").count(), 2);
}
