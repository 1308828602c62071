//! `fissure bench collision`: the collision benchmark from the release binary, so it
//! runs where no Rust toolchain is (a GPU machine), all backends in one run.

use std::path::PathBuf;

use fissure::collision::bench::{self, BenchSurface};
use fissure::perf::reports::{CollisionReport, CollisionRow};

#[derive(Debug, clap::Args)]
pub struct CollisionArgs {
    /// Folder with brain_pial_coarse and brain_pial_q15 (`.msh.gz` or `.msh`,
    /// millimetres) [default: the shipped assets/brain]; the real-brain cases
    /// are skipped, with a note, when a file is missing.
    #[arg(long)]
    pub mesh_dir: Option<PathBuf>,
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
    /// Also write the rows as JSON to this file (a row a case and backend: times in ms, the answer's hash).
    #[arg(long)]
    pub json: Option<PathBuf>,
}

pub fn collision(args: &CollisionArgs) -> anyhow::Result<()> {
    anyhow::ensure!(args.frames > 0, "--frames must be at least 1");
    let mesh_dir = args.mesh_dir.clone().unwrap_or_else(fissure::mesh::brain::shipped_dir);
    let mut notes = Vec::new();
    let surfaces = bench::standard_surfaces(&mesh_dir, args.only.as_deref(), &mut |n| {
        println!("note: {n}");
        notes.push(n);
    })
    .map_err(anyhow::Error::msg)?;
    anyhow::ensure!(!surfaces.is_empty(), "no case matches --only {:?}", args.only);
    let cases: Vec<(&BenchSurface, u32)> = surfaces.iter().flat_map(|(s, n)| n.iter().map(move |&k| (s, k))).collect();
    println!("collision stage, {} timed frames a case after {} warm-up; {} CPU threads in rayon's pool", args.frames, args.warmup, rayon::current_num_threads());
    println!("{}", bench::TABLE_HEADER);
    let mut table = vec![bench::TABLE_HEADER.to_string()];
    let rows = bench::run(&cases, &bench::ALL_BACKENDS, args.frames, args.warmup, &mut |r| match r {
        Ok(row) => {
            let line = bench::table_row(row);
            println!("{line}");
            table.push(line);
        }
        Err(note) => {
            eprintln!("note: {note}");
            notes.push(note);
        }
    });
    let footer = format!("GPU adapter: {}", bench::device(&rows));
    println!("{footer}");
    table.extend([String::new(), footer]);
    if let Some(path) = &args.out {
        fissure::fsio::write_atomic(path, (table.join("\n") + "\n").as_bytes()).map_err(|e| anyhow::anyhow!("writing {e}"))?;
    }
    if let Some(path) = &args.json {
        let report = CollisionReport {
            device: bench::device(&rows),
            notes,
            rows: rows
                .iter()
                .map(|r| CollisionRow {
                    surface: r.surface.clone(),
                    triangles: r.triangles,
                    nodes_a_face: r.nodes_a_face,
                    backend: r.backend.clone(),
                    p50_ms: r.p50_ms,
                    p95_ms: r.p95_ms,
                    cast_p50_ms: r.cast_p50_ms,
                    rest_p50_ms: r.rest_p50_ms,
                    candidates: r.candidates,
                    answer_hash: r.answer_hash.clone(),
                })
                .collect(),
        };
        let text = serde_json::to_string_pretty(&report)?;
        fissure::fsio::write_atomic(path, text.as_bytes()).map_err(|e| anyhow::anyhow!("writing {e}"))?;
    }
    let mismatch = bench::mismatches(&rows);
    anyhow::ensure!(mismatch.is_empty(), "backends gave different answers on: {}", mismatch.join(", "));
    Ok(())
}
