//! `fissure bench collision`: the collision benchmark from the release binary, so it
//! runs where no Rust toolchain is (a GPU machine), all backends in one run.

use std::path::{Path, PathBuf};

use anyhow::Context;
use fissure::collision::bench::{self, BenchBackend, BenchSurface};
use fissure::math::Vec3;

#[derive(Debug, clap::Args)]
pub struct CollisionArgs {
    /// Folder with brain_pial_coarse.msh and brain_pial_q15.msh (millimetres); the
    /// real-brain cases are skipped, with a note, when a file is missing.
    #[arg(long, default_value = "../shared/data/brain")]
    pub mesh_dir: PathBuf,
    /// Timed frames per case (after the warm-up).
    #[arg(long, default_value_t = 40)]
    pub frames: usize,
    /// Untimed frames first (device start-up, caches).
    #[arg(long, default_value_t = 5)]
    pub warmup: usize,
    /// Only the cases whose surface name contains this (paper-12k, brain-coarse, brain-q15).
    #[arg(long)]
    pub only: Option<String>,
    /// Also write the table (Markdown) to this file.
    #[arg(long)]
    pub out: Option<PathBuf>,
}

fn brain(path: &Path, name: &str) -> anyhow::Result<Option<BenchSurface>> {
    if !path.exists() {
        println!("note: {} not found; the {name} cases are skipped", path.display());
        return Ok(None);
    }
    let mut mesh = fissure::mesh::io::load_tet_mesh(path).with_context(|| format!("loading {}", path.display()))?;
    mesh.scale(1e-3);
    let s = mesh.boundary();
    let positions: Vec<Vec3> = s.gather_positions(&mesh.positions);
    Ok(Some(BenchSurface { name: name.into(), triangles: s.triangles.clone(), positions }))
}

pub fn collision(args: &CollisionArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.frames > 0, "--frames must be at least 1");
    let wanted = |name: &str| args.only.as_deref().is_none_or(|o| name.contains(o));
    let mut surfaces = Vec::new();
    if wanted("paper-12k") {
        let ph = fissure::mesh::phantom::generate(fissure::mesh::phantom::Preset::Paper12k).context("generating paper-12k")?;
        let s = ph.mesh.boundary();
        surfaces.push((BenchSurface { name: "paper-12k".into(), triangles: s.triangles.clone(), positions: s.gather_positions(&ph.mesh.positions) }, vec![150, 500, 2000]));
    }
    for (file, name) in [("brain_pial_coarse.msh", "brain-coarse"), ("brain_pial_q15.msh", "brain-q15")] {
        if wanted(name) {
            if let Some(s) = brain(&args.mesh_dir.join(file), name)? {
                surfaces.push((s, vec![500, 2000]));
            }
        }
    }
    anyhow::ensure!(!surfaces.is_empty(), "no case matches --only {:?}", args.only);
    let cases: Vec<(&BenchSurface, u32)> = surfaces.iter().flat_map(|(s, n)| n.iter().map(move |&k| (s, k))).collect();
    let backends = [BenchBackend::Bvh, BenchBackend::BvhAllCores, BenchBackend::Gpu, BenchBackend::Reference];
    println!("collision stage, {} timed frames a case after {} warm-up; {} CPU threads in rayon's pool", args.frames, args.warmup, rayon::current_num_threads());
    println!("{}", bench::TABLE_HEADER);
    let mut table = vec![bench::TABLE_HEADER.to_string()];
    let mut device = None;
    let rows = bench::run(&cases, &backends, args.frames, args.warmup, &mut |r| match r {
        Ok(row) => {
            let line = bench::table_row(row);
            println!("{line}");
            table.push(line);
        }
        Err(note) => eprintln!("note: {note}"),
    });
    if let Some((s, _)) = surfaces.first() {
        device = fissure::collision::bench::device_name(s);
    }
    // Same answers per case across backends (the motion depends on them).
    let mut mismatch = Vec::new();
    for (s, n) in &cases {
        let hashes: Vec<&str> = rows.iter().filter(|r| r.surface == s.name && r.nodes_a_face == *n).map(|r| r.answer_hash.as_str()).collect();
        if hashes.windows(2).any(|w| w[0] != w[1]) {
            mismatch.push(format!("{} {n}/face", s.name));
        }
    }
    let footer = format!("GPU adapter: {}", device.unwrap_or_else(|| "none".into()));
    println!("{footer}");
    table.push(String::new());
    table.push(footer);
    if let Some(path) = &args.out {
        std::fs::write(path, table.join("\n") + "\n").with_context(|| format!("writing {}", path.display()))?;
    }
    anyhow::ensure!(mismatch.is_empty(), "backends gave different answers on: {}", mismatch.join(", "));
    Ok(())
}
