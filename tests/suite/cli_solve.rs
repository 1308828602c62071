//! `fissure solve` run as a user would: the uniaxial patch test through the
//! binary (exact linear field read back from the written `.vtu`, reactions
//! summing to E A strain), Gmsh node tags with a mm mesh, the example in docs/usage.md,
//! and every bad input refused with a non-zero exit naming the file at fault.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Output;

use fissure::mesh::fixtures::{box_mesh, linspace};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::mesh::io::{self, Field, FieldData};

use crate::common;
use common::fissure;

fn text(bytes: &[u8]) -> String {
    String::from_utf8_lossy(bytes).into_owned()
}

fn s(p: &Path) -> &str {
    p.to_str().expect("utf-8 path")
}

const L: f64 = 0.1;
const W: f64 = 0.02;
const D: f64 = 0.002;
const E: f64 = 5e3;
const NU: f64 = 0.3;

/// Bar L x W x W m, a few cells each way.
fn bar() -> TetMesh {
    box_mesh(&linspace(0.0, L, 5), &linspace(0.0, W, 2), &linspace(0.0, W, 3)).expect("box")
}

/// Rollers: x held on x = 0, y on y = 0, z on z = 0; u_x = D enforced on x = L
/// (y, z free). `number` maps a node index to the number the JSON uses.
fn uniaxial_lists(mesh: &TetMesh, number: &dyn Fn(usize) -> i64) -> (String, String) {
    let mut fixed = Vec::new();
    let mut enforced = Vec::new();
    for (i, p) in mesh.positions.iter().enumerate() {
        let mut comps = String::new();
        for (c, letter) in ['x', 'y', 'z'].iter().enumerate() {
            if p[c] == 0.0 {
                comps.push(*letter);
            }
        }
        match comps.as_str() {
            "" => {}
            "xyz" => fixed.push(number(i).to_string()),
            _ => fixed.push(format!("{{\"node\": {}, \"components\": \"{comps}\"}}", number(i))),
        }
        if (p.x - L).abs() < 1e-12 {
            enforced.push(format!("{{\"node\": {}, \"displacement_m\": [{D}, null, null]}}", number(i)));
        }
    }
    (format!("[\n  {}\n]\n", fixed.join(",\n  ")), format!("[\n  {}\n]\n", enforced.join(",\n  ")))
}

fn exact(p: &Vec3) -> Vec3 {
    Vec3::new(D * p.x / L, -NU * D * p.y / L, -NU * D * p.z / L)
}

fn vector<'a>(fields: &'a FieldData, name: &str) -> &'a [Vec3] {
    match fields.point.iter().find(|(n, _)| n == name) {
        Some((_, Field::Vector(v))) => v,
        other => panic!("point data {name} must be a 3-vector field, found {other:?}"),
    }
}

fn scalar<'a>(fields: &'a FieldData, name: &str) -> &'a [f64] {
    match fields.point.iter().find(|(n, _)| n == name) {
        Some((_, Field::Scalar(v))) => v,
        other => panic!("point data {name} must be a scalar field, found {other:?}"),
    }
}

/// Checks the written `.vtu` against the exact uniaxial field; `scale` is the
/// file's length unit in m. Returns the x-reactions summed on x = 0 and x = L.
fn check_uniaxial(out: &Path, mesh_m: &TetMesh, scale: f64) -> (f64, f64) {
    let (read, fields) = io::load_vtu_with_fields(out).expect("the output .vtu reads back");
    assert_eq!(read.positions.len(), mesh_m.positions.len());
    for (a, b) in read.positions.iter().zip(&mesh_m.positions) {
        assert!((a * scale - b).norm() < 1e-12, "coordinates stay as in the input file: {a} vs {b} m");
    }
    let u = vector(&fields, "displacement_m");
    let worst = mesh_m.positions.iter().zip(u).map(|(p, u)| (u - exact(p)).norm()).fold(0.0, f64::max);
    assert!(worst < 1e-12 * D.max(1.0) + 1e-10 * D, "uniaxial field must be exact, worst error {worst:e} m");
    let r = vector(&fields, "reaction_n");
    let fixed = scalar(&fields, "fixed_components");
    let enforced = scalar(&fields, "enforced_components");
    let (mut at_0, mut at_l) = (0.0, 0.0);
    for (i, p) in mesh_m.positions.iter().enumerate() {
        let expected_fixed = (0..3).filter(|&c| p[c] == 0.0).map(|c| 1 << c).sum::<i32>() as f64;
        assert_eq!(fixed[i], expected_fixed, "fixed_components of node {i} at {p}");
        let on_end = (p.x - L).abs() < 1e-12;
        assert_eq!(enforced[i], if on_end { 1.0 } else { 0.0 }, "enforced_components of node {i}");
        if expected_fixed == 0.0 && !on_end {
            assert_eq!(r[i], Vec3::zeros(), "free node {i} has no reaction");
        }
        if p.x == 0.0 {
            at_0 += r[i].x;
        }
        if on_end {
            at_l += r[i].x;
        }
    }
    (at_0, at_l)
}

#[test]
fn uniaxial_patch_test_through_the_binary_is_exact() {
    let dir = tempfile::tempdir().expect("tmp");
    let mesh = bar();
    let mesh_path = dir.path().join("bar.vtu");
    io::save_tet_mesh(&mesh_path, &mesh, &FieldData::none()).expect("write bar");
    let (fixed, enforced) = uniaxial_lists(&mesh, &|i| i as i64);
    let (fixed_path, enforced_path) = (dir.path().join("fixed.json"), dir.path().join("enforced.json"));
    std::fs::write(&fixed_path, fixed).expect("write");
    std::fs::write(&enforced_path, enforced).expect("write");
    let out = dir.path().join("out.vtu");
    let csv = dir.path().join("reactions.csv");
    let run = fissure(&[
        "solve", s(&mesh_path), "--young-modulus-pa", &E.to_string(), "--poisson-ratio", &NU.to_string(), "--fixed",
        s(&fixed_path), "--enforced", s(&enforced_path), "-o", s(&out), "--csv", s(&csv),
    ]);
    assert!(run.status.success(), "solve must succeed: {}", text(&run.stderr));
    let (at_0, at_l) = check_uniaxial(&out, &mesh, 1.0);
    let expected = E * W * W * D / L;
    assert!((at_l - expected).abs() < 1e-9 * expected, "end reaction {at_l} N vs E A strain {expected} N");
    assert!((at_0 + expected).abs() < 1e-9 * expected, "support reaction {at_0} N vs -E A strain {}", -expected);
    let summary = text(&run.stdout);
    for says in ["72 nodes", "180 tets", "enforced:   12 nodes, 12 components", "max |u|:    2.0", "sum (no other load: ~0)"] {
        assert!(summary.contains(says), "summary says {says:?}: {summary}");
    }
    let rows = std::fs::read_to_string(&csv).expect("csv written");
    let mut lines = rows.lines();
    assert_eq!(lines.next(), Some("node_index,fixed_components,enforced_components,ux_m,uy_m,uz_m,rx_n,ry_n,rz_n"));
    let end_force: f64 = lines
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|c| c[2] == "x")
        .map(|c| c[6].parse::<f64>().expect("rx_n"))
        .sum();
    assert!((end_force - expected).abs() < 1e-9 * expected, "csv end reactions {end_force} N vs {expected} N");
}

/// Gmsh 2.2 ASCII with node tag `1000 + 3 i` for node `i` and coordinates in mm.
fn msh_with_sparse_tags_mm(mesh: &TetMesh) -> String {
    let mut t = String::from("$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n");
    let _ = writeln!(t, "{}", mesh.positions.len());
    for (i, p) in mesh.positions.iter().enumerate() {
        let _ = writeln!(t, "{} {:?} {:?} {:?}", 1000 + 3 * i, p.x * 1e3, p.y * 1e3, p.z * 1e3);
    }
    let _ = writeln!(t, "$EndNodes\n$Elements\n{}", mesh.tets.len());
    for (k, tet) in mesh.tets.iter().enumerate() {
        let tag = |n: u32| 1000 + 3 * n as usize;
        let _ = writeln!(t, "{} 4 2 1 1 {} {} {} {}", k + 1, tag(tet[0]), tag(tet[1]), tag(tet[2]), tag(tet[3]));
    }
    t.push_str("$EndElements\n");
    t
}

#[test]
fn gmsh_node_tags_and_a_millimetre_mesh_give_the_same_field() {
    let dir = tempfile::tempdir().expect("tmp");
    let mesh = bar();
    let mesh_path = dir.path().join("bar_mm.msh");
    std::fs::write(&mesh_path, msh_with_sparse_tags_mm(&mesh)).expect("write");
    let (fixed, enforced) = uniaxial_lists(&mesh, &|i| 1000 + 3 * i as i64);
    let (fixed_path, enforced_path) = (dir.path().join("fixed.json"), dir.path().join("enforced.json"));
    std::fs::write(&fixed_path, fixed).expect("write");
    std::fs::write(&enforced_path, enforced).expect("write");
    let out = dir.path().join("out.vtu");
    let args = |numbering: &'static str| {
        vec![
            "solve".to_string(), s(&mesh_path).into(), "--young-modulus-pa".into(), E.to_string(), "--poisson-ratio".into(),
            NU.to_string(), "--fixed".into(), s(&fixed_path).into(), "--enforced".into(), s(&enforced_path).into(), "-o".into(),
            s(&out).into(), "--units".into(), "mm".into(), "--node-numbering".into(), numbering.into(),
        ]
    };
    let run = |numbering| {
        let a = args(numbering);
        fissure(&a.iter().map(String::as_str).collect::<Vec<_>>())
    };
    let tags = run("gmsh-tag");
    assert!(tags.status.success(), "tags resolve: {}", text(&tags.stderr));
    let (_, at_l) = check_uniaxial(&out, &mesh, 1e-3);
    let expected = E * W * W * D / L;
    assert!((at_l - expected).abs() < 1e-9 * expected, "end reaction {at_l} N vs {expected} N with the mesh in mm");
    assert!(text(&tags.stdout).contains("max |u|:    2.0"), "{}", text(&tags.stdout));
    // The same lists read as 0-based indices name nodes the mesh does not have.
    let index = run("index");
    assert!(!index.status.success(), "tags are not indices");
    let err = text(&index.stderr);
    assert!(err.contains(s(&fixed_path)) && err.contains("out of range") && err.contains("--node-numbering gmsh-tag"), "{err}");
    // and gmsh-tag on a .vtu is refused
    let vtu = dir.path().join("bar.vtu");
    io::save_tet_mesh(&vtu, &mesh, &FieldData::none()).expect("write");
    let a: Vec<String> = args("gmsh-tag").into_iter().map(|x| if x == s(&mesh_path) { s(&vtu).to_string() } else { x }).collect();
    let refused = fissure(&a.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!refused.status.success());
    assert!(text(&refused.stderr).contains("needs a Gmsh .msh mesh"), "{}", text(&refused.stderr));
}

#[test]
fn the_usage_example_runs() {
    let dir = tempfile::tempdir().expect("tmp");
    let mesh = dir.path().join("p.msh");
    let made = fissure(&["mesh", "phantom", "--preset", "small", "-o", s(&mesh)]);
    assert!(made.status.success(), "{}", text(&made.stderr));
    let out = dir.path().join("p_solved.vtu");
    let run = fissure(&[
        "solve", s(&mesh), "--young-modulus-pa", "3000", "--poisson-ratio", "0.45", "--fixed", "assets/solve/phantom_small_fixed.json",
        "--enforced", "assets/solve/phantom_small_enforced.json", "-o", s(&out),
    ]);
    assert!(run.status.success(), "the example in docs/usage.md must run: {}", text(&run.stderr));
    let usage = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("docs/usage.md")).expect("docs/usage.md");
    assert!(
        usage.contains("fissure solve /tmp/p.msh --young-modulus-pa 3000 --poisson-ratio 0.45 --fixed assets/solve/phantom_small_fixed.json"),
        "docs/usage.md shows this command"
    );
    let (_, fields) = io::load_vtu_with_fields(&out).expect("reads back");
    let u = vector(&fields, "displacement_m");
    assert!((u[947].z + 0.002).abs() < 1e-15 && u[947].x == 0.0, "enforced node 947: {}", u[947]);
}

struct Case {
    dir: tempfile::TempDir,
    mesh: PathBuf,
    fixed: PathBuf,
    enforced: PathBuf,
    out: PathBuf,
}

/// A bar in a folder with valid lists (the bottom face fixed, one top node pulled 1 mm).
fn case() -> Case {
    let dir = tempfile::tempdir().expect("tmp");
    let mesh = dir.path().join("bar.vtu");
    let m = bar();
    io::save_tet_mesh(&mesh, &m, &FieldData::none()).expect("write");
    let bottom: Vec<String> = m.positions.iter().enumerate().filter(|(_, p)| p.z == 0.0).map(|(i, _)| i.to_string()).collect();
    let fixed = dir.path().join("fixed.json");
    std::fs::write(&fixed, format!("[{}]", bottom.join(", "))).expect("write");
    let enforced = dir.path().join("enforced.json");
    std::fs::write(&enforced, "[{\"node\": 71, \"displacement_m\": [0.0, 0.0, 0.001]}]").expect("write");
    let out = dir.path().join("out.vtu");
    Case { dir, mesh, fixed, enforced, out }
}

impl Case {
    /// Runs with the case's files, `replace` swapping (flag or "MESH", value) pairs.
    fn run(&self, replace: &[(&str, &str)]) -> Output {
        let mut a = vec![
            "solve", s(&self.mesh), "--young-modulus-pa", "3000", "--poisson-ratio", "0.45", "--fixed", s(&self.fixed),
            "--enforced", s(&self.enforced), "-o", s(&self.out),
        ];
        for &(flag, value) in replace {
            if flag == "MESH" {
                a[1] = value;
            } else if let Some(k) = a.iter().position(|x| *x == flag) {
                a[k + 1] = value;
            } else {
                a.extend_from_slice(&[flag, value]);
            }
        }
        fissure(&a)
    }

    /// Expects failure, nothing written, and stderr saying each of `says`.
    fn refused(&self, replace: &[(&str, &str)], says: &[&str]) {
        let out = self.run(replace);
        let err = text(&out.stderr);
        assert!(!out.status.success(), "{replace:?} must fail; stdout {}", text(&out.stdout));
        assert_eq!(out.status.code(), Some(1), "{replace:?}: an error exits 1: {err}");
        for w in says {
            assert!(err.contains(w), "{replace:?}: stderr says {w:?}: {err}");
        }
        assert!(!self.out.exists(), "{replace:?}: nothing written on failure");
        let left: Vec<_> = std::fs::read_dir(self.dir.path()).expect("dir").map(|e| e.expect("entry").file_name()).collect();
        assert!(!left.iter().any(|n| n.to_string_lossy().contains(".tmp-")), "no temporary file left: {left:?}");
    }

    /// Writes `content` as `name` in the case's folder; returns its path.
    fn file(&self, name: &str, content: &str) -> String {
        let path = self.dir.path().join(name);
        std::fs::write(&path, content).expect("write");
        s(&path).to_string()
    }
}

#[test]
fn the_valid_case_solves() {
    let c = case();
    let out = c.run(&[]);
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert!(c.out.exists());
}

#[test]
fn bad_inputs_are_refused_naming_the_file() {
    let c = case();
    let fixed = s(&c.fixed).to_string();
    // a mesh that does not load
    let garbage = c.file("garbage.msh", "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\nnot a number\n");
    c.refused(&[("MESH", &garbage)], &[&garbage, "cannot load the mesh"]);
    c.refused(&[("MESH", "no/such/mesh.vtu")], &["no/such/mesh.vtu"]);
    // JSON that does not parse: file, line and column
    let broken = c.file("broken.json", "[0, 1,\n 2,, 3]");
    c.refused(&[("--fixed", &broken)], &[&broken, "line 2 column 4"]);
    let wrong_field = c.file("wrong_field.json", "[{\"node\": 71,\n \"displacement\": [0, 0, 0.001]}]");
    c.refused(&[("--enforced", &wrong_field)], &[&wrong_field, "unknown field `displacement`", "line 2"]);
    let roller = c.file("roller.json", "[0, {\"node\": 1, \"components\": \"xq\"}]");
    c.refused(&[("--fixed", &roller)], &[&roller, "expected letters x, y, z"]);
    // a node out of range (72 nodes: 0..=71)
    let far = c.file("far.json", "[0, 1, 72]");
    c.refused(&[("--fixed", &far)], &[&far, "[2]: node 72 is out of range: the mesh has 72 nodes, numbered 0 to 71"]);
    // a node both fixed and enforced with a different value (node 0 is on the fixed bottom)
    let clash = c.file("clash.json", "[{\"node\": 0, \"displacement_m\": [null, 0.001, null]}]");
    c.refused(&[("--enforced", &clash)], &[&fixed, &clash, "node 0 component y is fixed", "enforced to 0.001 m"]);
    // infinite, absurd (the bar's diagonal is 0.104 m) and NaN displacements
    let huge = c.file("huge.json", "[{\"node\": 71, \"displacement_m\": [0, 0, 1e999]}]");
    c.refused(&[("--enforced", &huge)], &[&huge, "out of range"]);
    let absurd = c.file("absurd.json", "[{\"node\": 71, \"displacement_m\": [0, 0, 0.5]}]");
    c.refused(&[("--enforced", &absurd)], &[&absurd, "larger than the whole mesh", "1.0392e-1 m"]);
    let nan = c.file("nan.json", "[{\"node\": 71, \"displacement_m\": [0, 0, NaN]}]");
    c.refused(&[("--enforced", &nan)], &[&nan, "line 1"]);
    // non-physical material
    c.refused(&[("--poisson-ratio", "0.5")], &["--poisson-ratio 0.5", "(-1, 0.5)"]);
    c.refused(&[("--young-modulus-pa", "-3000")], &["--young-modulus-pa -3000", "> 0"]);
    c.refused(&[("--young-modulus-pa", "nan")], &["--young-modulus-pa NaN"]);
    // nothing or too little held: the mesh can move freely
    let none = c.file("none.json", "[]");
    c.refused(&[("--fixed", &none), ("--enforced", &none)], &["the mesh can move freely", &none]);
    let one = c.file("one.json", "[0]");
    let free = c.file("free.json", "[{\"node\": 71, \"displacement_m\": [null, null, 0.001]}]");
    c.refused(&[("--fixed", &one), ("--enforced", &free)], &["the mesh can move freely", "fix more nodes", &one, &free]);
    // an output that cannot be written, before any work and leaving nothing
    c.refused(&[("-o", "no/such/folder/out.vtu")], &["no/such/folder/out.vtu", "does not exist"]);
    let dir_out = c.dir.path().join("a_folder.vtu");
    std::fs::create_dir(&dir_out).expect("mkdir");
    c.refused(&[("-o", s(&dir_out))], &[s(&dir_out), "is a folder"]);
    c.refused(&[("-o", "out.node")], &["out.node", "must be .vtu"]);
}
