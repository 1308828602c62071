//! Our side of `scripts/cholmod_compare.sh`: the stiffness `K_FF` of a mesh as
//! the fem bench builds it (E 3 kPa, nu 0.45, each piece clamped 10 mm up from
//! its bottom), written as a Matrix Market file for CHOLMOD, and our factor of
//! it timed the same way (one thread, best of 3: numeric factor, a 96-column
//! solve): `cargo run --release --example factor_compare -- MESH.msh OUT.mtx`.
//! The mesh file is in mm.
use fissure::linalg::SparseCholesky;
use fissure::linalg::FillOrdering;
use fissure::fem::{FemModel, FemOptions, Material, RegionMaterials};
use fissure::mesh::fixtures;
use std::io::Write;
use std::time::Instant;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh_path, out] = args.as_slice() else {
        anyhow::bail!("usage: factor_compare MESH.msh OUT.mtx");
    };
    let mut mesh = fissure::mesh::io::load_tet_mesh(std::path::Path::new(mesh_path)).map_err(|e| anyhow::anyhow!("{mesh_path}: {e}"))?;
    mesh.scale(1e-3);
    let fixed = fixtures::fix_bottom_of_each_component(&mesh, 0.010);
    let materials = RegionMaterials::uniform(Material { young_modulus: 3.0e3, poisson_ratio: 0.45 });
    let model = FemModel::new(&mesh, &materials, &fixed, &FemOptions::default())?;
    let k = model.stiffness();
    let nnz: usize = k.col_ptr[k.dim];
    let mut w = std::io::BufWriter::new(std::fs::File::create(out).map_err(|e| anyhow::anyhow!("{out}: {e}"))?);
    writeln!(w, "%%MatrixMarket matrix coordinate real symmetric\n{} {} {nnz}", k.dim, k.dim)?;
    for j in 0..k.dim {
        for p in k.col_ptr[j]..k.col_ptr[j + 1] {
            writeln!(w, "{} {} {:e}", k.row_idx[p] + 1, j + 1, k.values[p])?;
        }
    }
    w.flush().map_err(|e| anyhow::anyhow!("{out}: {e}"))?;
    for ordering in [FillOrdering::NestedDissection, FillOrdering::Amd] {
        let (mut analyse, mut numeric, mut solve) = (f64::INFINITY, f64::INFINITY, f64::INFINITY);
        let mut counts = (0, 0);
        for rep in 0..3 {
            let chol = SparseCholesky::new(k, ordering, &|d| model.dofs().name(d))?;
            analyse = analyse.min(chol.symbolic_seconds);
            numeric = numeric.min(chol.numeric_seconds);
            counts = (chol.exact_nnz_l(k)?, chol.nnz_l());
            let mut rhs = faer::Mat::<f64>::zeros(k.dim, 96);
            for c in 0..96 {
                rhs[((c * 7919 + rep) % k.dim, c)] = 1.0;
            }
            let mut scratch = chol.scratch(96)?;
            let t = Instant::now();
            chol.solve_in_place(rhs.as_mut(), &mut scratch);
            solve = solve.min(t.elapsed().as_secs_f64());
        }
        let name = if ordering == FillOrdering::Amd { "amd" } else { "metis" };
        println!(
            "fissure {name}: n {}, nnz(L) exact {:.3} M, stored {:.3} M, analysis {analyse:.3} s, numeric {numeric:.3} s, 96-column solve {:.1} ms",
            k.dim,
            counts.0 as f64 / 1e6,
            counts.1 as f64 / 1e6,
            solve * 1e3
        );
    }
    Ok(())
}
