//! Every mesh parser on arbitrary bytes: the first byte picks the parser, the
//! rest is the file. Ok or Err, never a panic, a hang or an allocation the
//! input cannot back. A parsed mesh must be valid (finite, indices in range).
#![no_main]

use fissure::mesh::io::{self, TetFormat};
use libfuzzer_sys::fuzz_target;
use std::path::Path;

/// A valid TetGen partner file for the half that is not fuzzed.
const NODE: &str = "5 3 0 0\n1 0 0 0\n2 1 0 0\n3 0 1 0\n4 0 0 1\n5 1 1 1\n";
const ELE: &str = "2 4 0\n1 1 2 3 4\n2 2 3 5 4\n";

fuzz_target!(|data: &[u8]| {
    let Some((&which, bytes)) = data.split_first() else { return };
    let path = Path::new("fuzz");
    let tets = match which % 7 {
        0 => io::parse_tet_mesh(path, TetFormat::Gmsh, bytes).ok(),
        1 => io::parse_tet_mesh(path, TetFormat::VtkLegacy, bytes).ok(),
        2 => io::parse_tet_mesh(path, TetFormat::Vtu, bytes).ok(),
        3 => io::tetgen::parse(path, bytes, path, ELE.as_bytes()).ok(),
        4 => io::tetgen::parse(path, NODE.as_bytes(), path, bytes).ok(),
        5 => {
            if let Ok(s) = io::obj::parse(path, bytes) {
                assert!(s.triangles.iter().flatten().all(|&v| (v as usize) < s.positions.len()), "OBJ index out of range");
            }
            None
        }
        _ => {
            if let Ok(s) = io::stl::parse(path, bytes) {
                assert!(s.triangles.iter().flatten().all(|&v| (v as usize) < s.positions.len()), "STL index out of range");
            }
            None
        }
    };
    if let Some(m) = tets {
        assert!(m.positions.iter().all(|p| p.iter().all(|c| c.is_finite())), "a parsed mesh has a non-finite node");
        assert!(m.tets.iter().flatten().all(|&n| (n as usize) < m.positions.len()), "a parsed tet refers past the nodes");
        assert_eq!(m.regions.len(), m.tets.len());
    }
});
