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

/// `fissure mesh phantom --preset NAME -o OUT`: generates a phantom (metres)
/// and prints its counts, quality and landmarks (in mm, for scenario files).
pub fn phantom(preset: &str, output: &Path, json: bool) -> anyhow::Result<()> {
    use fissure::mesh::phantom::{self, Landmarks, Preset};
    let preset: Preset = preset.parse()?;
    let started = std::time::Instant::now();
    let generated = phantom::generate(preset).with_context(|| format!("cannot generate the phantom {preset}"))?;
    let seconds = started.elapsed().as_secs_f64();
    io::save_tet_mesh(output, &generated.mesh, &FieldData::none()).with_context(|| format!("cannot write {}", output.display()))?;
    let report = QualityReport::of(&generated.mesh);
    if json {
        println!("{}", serde_json::to_string_pretty(&report).context("cannot write the report as JSON")?);
        return Ok(());
    }
    println!("phantom {preset} -> {} (coordinates in metres: use units: Metres in a scenario), generated in {seconds:.2} s", output.display());
    println!("{report}");
    let mm = |v: &fissure::math::Vec3| format!("({:.1}, {:.1}, {:.1}) mm", v.x * 1e3, v.y * 1e3, v.z * 1e3);
    let dir = |v: &fissure::math::Vec3| format!("({:.3}, {:.3}, {:.3})", v.x, v.y, v.z);
    println!("landmarks:");
    match &generated.landmarks {
        Landmarks::Brain(b) => {
            for (name, f) in [("inter-hemispheric", &b.interhemispheric), ("Sylvian left", &b.sylvian_left), ("Sylvian right", &b.sylvian_right)] {
                println!(
                    "  {name}: entry {}, inward {}, normal {}, depth {:.1} mm, width {:.1} mm",
                    mm(&f.entry),
                    dir(&f.inward),
                    dir(&f.normal),
                    f.depth * 1e3,
                    f.width * 1e3
                );
            }
            println!("  brain stem: region {}, box {} .. {}", b.brain_stem_region, mm(&b.brain_stem_box.min), mm(&b.brain_stem_box.max));
            println!("  skull containing: centre {}, radius {:.1} mm", mm(&b.skull_containing.centre), b.skull_containing.radius * 1e3);
            println!("  skull excluding: centre {}, radius {:.1} mm", mm(&b.skull_excluding.centre), b.skull_excluding.radius * 1e3);
        }
        Landmarks::Block(b) => {
            println!("  entry {}, axis {}, inward {}, width {:.1} mm, depth {:.1} mm", mm(&b.entry), dir(&b.axis), dir(&b.inward), b.width * 1e3, b.depth * 1e3);
            println!("  base: region {}, box {} .. {}", b.base_region, mm(&b.base_box.min), mm(&b.base_box.max));
        }
    }
    Ok(())
}

/// `fissure mesh tetrahedralize SURFACE -o OUT --edge 2.5mm`: fills a closed
/// surface with quality tetrahedra. The output keeps the surface's length unit.
pub fn tetrahedralize(surface: &Path, output: &Path, edge_m: f64, surface_units: fissure::scenario::LengthUnit) -> anyhow::Result<()> {
    let loaded = io::load_surface(surface).with_context(|| format!("cannot load the surface {}", surface.display()))?;
    let edge_in_file_units = edge_m / surface_units.to_metres();
    let started = std::time::Instant::now();
    let mesh = fissure::mesh::tetrahedralize::tetrahedralize_surface(&loaded, edge_in_file_units)
        .with_context(|| format!("cannot tetrahedralize {}", surface.display()))?;
    let seconds = started.elapsed().as_secs_f64();
    io::save_tet_mesh(output, &mesh, &FieldData::none()).with_context(|| format!("cannot write {}", output.display()))?;
    println!(
        "{} -> {} (edge {} mm, coordinates in {:?} like the surface), {seconds:.2} s",
        surface.display(),
        output.display(),
        edge_m * 1e3,
        surface_units
    );
    println!("{}", QualityReport::of(&mesh));
    Ok(())
}
