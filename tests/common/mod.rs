//! Shared code for the integration tests: small structured meshes and scenario text.
#![allow(dead_code)]

pub mod scenes;
pub mod source;

use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use std::path::{Path, PathBuf};

/// A box [0, size] split into nx*ny*nz cells of 6 tets each (Kuhn), metres.
pub fn block(nx: usize, ny: usize, nz: usize, size: Vec3, origin: Vec3) -> TetMesh {
    let idx = |i: usize, j: usize, k: usize| (i + (nx + 1) * (j + (ny + 1) * k)) as u32;
    let mut p = Vec::new();
    for k in 0..=nz {
        for j in 0..=ny {
            for i in 0..=nx {
                p.push(origin + Vec3::new(size.x * i as f64 / nx as f64, size.y * j as f64 / ny as f64, size.z * k as f64 / nz as f64));
            }
        }
    }
    let mut tets = Vec::new();
    for k in 0..nz {
        for j in 0..ny {
            for i in 0..nx {
                let c = |b: u32| idx(i + (b & 1) as usize, j + ((b >> 1) & 1) as usize, k + ((b >> 2) & 1) as usize);
                for t in [[0, 1, 3, 7], [0, 1, 5, 7], [0, 2, 3, 7], [0, 2, 6, 7], [0, 4, 5, 7], [0, 4, 6, 7]] {
                    tets.push(t.map(c));
                }
            }
        }
    }
    TetMesh::new(p, tets, vec![]).expect("block mesh is valid")
}

/// Writes `mesh` as `.msh` into `dir` and returns the path.
pub fn write_mesh(dir: &Path, name: &str, mesh: &TetMesh) -> PathBuf {
    let path = dir.join(name);
    fissure::mesh::io::save_tet_mesh(&path, mesh, &Default::default()).expect("write test mesh");
    path
}

/// The path of a shipped real brain mesh (`fissure::mesh::brain::COARSE` or `FINE`).
pub fn real_brain(stem: &str) -> PathBuf {
    let p = fissure::mesh::brain::shipped(stem);
    assert!(p.is_file(), "{} is missing from the checkout", p.display());
    p
}
pub mod xvfb;

/// A test that cannot run on this machine (no Xvfb, no GPU adapter, no pyigtl) says why and passes, unless
/// `FISSURE_NO_SKIP` is set (CI sets it): there a missing piece fails the run instead of leaving it green.
pub fn skip(reason: &str) {
    if std::env::var_os("FISSURE_NO_SKIP").is_some_and(|v| !v.is_empty() && v != "0") {
        panic!("{reason}; FISSURE_NO_SKIP is set, so this machine must run every test");
    }
    eprintln!("skipping: {reason}");
}

/// Runs the `fissure` binary with `args` in the repository root, as a user would.
pub fn fissure(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_fissure"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("the fissure binary runs")
}
