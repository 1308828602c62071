//! `fissure mesh ...`: mesh inspection and conversion.
//!
//! In: mesh file paths. Out: a quality report (text or JSON) or a converted
//! file. Every error names the file (and line, where the reader knows it).

use std::path::Path;

use anyhow::Context as _;
use fissure::mesh::io::{self, FieldData};
use fissure::mesh::quality::QualityReport;

/// `fissure mesh info PATH [--json]`.
pub fn info(path: &Path, json: bool) -> anyhow::Result<()> {
    let mesh = io::load_tet_mesh(path).with_context(|| format!("cannot load the mesh {}", path.display()))?;
    let report = QualityReport::of(&mesh);
    if json {
        println!("{}", serde_json::to_string_pretty(&report).context("cannot write the report as JSON")?);
    } else {
        println!("{}", path.display());
        println!("{report}");
    }
    Ok(())
}

/// `fissure mesh convert IN OUT`: a tet mesh between .msh/.vtk/.vtu/.node+.ele
/// (a `.vtu` input keeps its point and cell data where the output format has
/// room for them), or a surface between .obj/.stl.
pub fn convert(input: &Path, output: &Path) -> anyhow::Result<()> {
    let is_surface = |p: &Path| {
        matches!(p.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase).as_deref(), Some("obj" | "stl"))
    };
    match (is_surface(input), is_surface(output)) {
        (true, true) => {
            let surface = io::load_surface(input).with_context(|| format!("cannot load the surface {}", input.display()))?;
            io::save_surface(output, &surface).with_context(|| format!("cannot write {}", output.display()))?;
            println!("{} -> {}: {} vertices, {} triangles", input.display(), output.display(), surface.positions.len(), surface.triangles.len());
        }
        (false, false) => {
            let is_vtu = input.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("vtu"));
            let (mesh, fields) = if is_vtu {
                io::load_vtu_with_fields(input)
            } else {
                io::load_tet_mesh(input).map(|m| (m, FieldData::none()))
            }
            .with_context(|| format!("cannot load the mesh {}", input.display()))?;
            io::save_tet_mesh(output, &mesh, &fields).with_context(|| format!("cannot write {}", output.display()))?;
            println!("{} -> {}: {} nodes, {} tetrahedra", input.display(), output.display(), mesh.positions.len(), mesh.tets.len());
        }
        _ => anyhow::bail!(
            "cannot convert between a surface and a tet mesh ({} -> {}); use `fissure mesh tetrahedralize` to fill a surface",
            input.display(),
            output.display()
        ),
    }
    Ok(())
}
