//! `fissure solve MESH --young-modulus-pa E --poisson-ratio NU [--fixed F.json] [--enforced E.json] -o out.vtu`:
//! one static linear-elastic solve, for comparing fissure with another FEM code.
//!
//! In: a tet mesh (its length unit from `--units`, default m), one material
//! for the whole mesh, the node lists ([`boundary`]: FIXED.json holds nodes or
//! some of their components at 0, ENF.json prescribes displacements in m), and
//! how the lists number nodes (`--node-numbering index`: 0-based file order,
//! ParaView's Point ID; `gmsh-tag`: the `.msh` file's node tags). Out: `-o`
//! (`.vtu`, or `.vtk` / `.msh`) with the mesh as read (coordinates in the
//! file's unit, nodes in file order) and point data `displacement_m`,
//! `reaction_n` (the force the supports apply to the mesh at each prescribed
//! component, N; 0 elsewhere), `fixed_components` and `enforced_components`
//! (bits x = 1, y = 2, z = 4); optionally `--csv` with one row per prescribed
//! node; a summary on stdout (counts, max |u|, the reactions summed over the
//! fixed and over the enforced nodes, the solve time).
//! Stays true: everything is checked before the factorization (material,
//! node numbers, conflicting or absurd values, every rigid motion of every
//! connected component held, the output's format and folder); outputs are
//! written whole or not at all; the solve is [`fissure::fem::reference::solve_direct`],
//! exact up to round-off, no body force.

mod boundary;

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, bail};
use fissure::fem::reference::solve_direct;
use fissure::fem::{FemError, Material};
use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::mesh::io::{self, Field, FieldData, TetFormat};
use fissure::scenario::validate::LOCKING_POISSON_RATIO;

use self::boundary::{NodeNumbering, Source};
use super::SurfaceUnits;

/// How the JSON node lists number the mesh's nodes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum NodeNumberingArg {
    /// 0-based position in the mesh file's node list (ParaView's Point ID), any format.
    Index,
    /// Gmsh node tags as written in the `.msh` file (Gmsh counts from 1); `.msh` only.
    GmshTag,
}

#[derive(Debug, clap::Args)]
pub struct SolveArgs {
    /// The tet mesh (.msh, .vtk, .vtu, .node/.ele); one material for all its regions.
    pub mesh: PathBuf,
    /// Young's modulus, Pa (> 0).
    #[arg(long, allow_negative_numbers = true)]
    pub young_modulus_pa: f64,
    /// Poisson's ratio, in (-1, 0.5).
    #[arg(long, allow_negative_numbers = true)]
    pub poisson_ratio: f64,
    /// Nodes held at 0 (JSON): `[3, 7, {"node": 12, "components": "xz"}]`.
    #[arg(long, value_name = "FIXED.json")]
    pub fixed: Option<PathBuf>,
    /// Enforced displacements in metres (JSON): `[{"node": 5, "displacement_m": [0.001, null, 0.0]}]`; null = free.
    #[arg(long, value_name = "ENF.json")]
    pub enforced: Option<PathBuf>,
    /// Output mesh with point data displacement_m, reaction_n, fixed_components, enforced_components (.vtu, .vtk or .msh).
    #[arg(short, long)]
    pub output: PathBuf,
    /// Length unit of the mesh's coordinates (displacements are in metres whatever this says).
    #[arg(long, value_enum, default_value = "m")]
    pub units: SurfaceUnits,
    /// How the JSON files number nodes.
    #[arg(long, value_enum, default_value = "index")]
    pub node_numbering: NodeNumberingArg,
    /// Also write one CSV row per prescribed node: its number, components, displacement (m) and reaction (N).
    #[arg(long, value_name = "FILE.csv")]
    pub csv: Option<PathBuf>,
}

/// Runs `fissure solve`.
pub fn run(args: &SolveArgs) -> anyhow::Result<()> {
    let material = material(args.young_modulus_pa, args.poisson_ratio)?;
    check_output(&args.output, "-o")?;
    if let Some(csv) = &args.csv {
        check_output(csv, "--csv")?;
    }
    if args.fixed.is_none() && args.enforced.is_none() {
        bail!(
            "no fixed or enforced node: the mesh can move freely (rigid-body motion); give --fixed FIXED.json and/or \
             --enforced ENF.json"
        );
    }

    let t_load = Instant::now();
    let (file_mesh, numbering) = load_mesh(args)?;
    let load_seconds = t_load.elapsed().as_secs_f64();
    let (unit_name, metres_per_unit) = match args.units {
        SurfaceUnits::M => ("m", 1.0),
        SurfaceUnits::Mm => ("mm", 1e-3),
    };
    let mut mesh = file_mesh.clone();
    mesh.scale(metres_per_unit);

    let prescription = boundary::load(args.fixed.as_deref(), args.enforced.as_deref(), &numbering, &mesh.positions)?;
    boundary::check_rigid_motions(&mesh, &prescription, &numbering).with_context(|| {
        let files: Vec<String> = [&args.fixed, &args.enforced].into_iter().flatten().map(|p| p.display().to_string()).collect();
        format!("the nodes in {} do not hold the mesh", files.join(" and "))
    })?;

    let t_solve = Instant::now();
    let lame = vec![material.lame(); mesh.tets.len()];
    let solution = solve_direct(&mesh, &lame, &prescription.dofs, &[]).map_err(|e| match e {
        FemError::NotPositiveDefinite { node, component, .. } => anyhow::anyhow!(
            "the stiffness is singular at node {} component {}: the mesh can move freely there; fix more nodes ({e})",
            numbering.number_of(node),
            ['x', 'y', 'z'][component.min(2)]
        ),
        other => anyhow::Error::new(other).context("the solve failed"),
    })?;
    let solve_seconds = t_solve.elapsed().as_secs_f64();

    let n = mesh.node_count();
    let (reaction, sum_fixed, sum_enforced) = reactions(&prescription, &solution.reactions, n);
    if let Some(bad) = solution.displacement.iter().position(|u| !fissure::math::is_finite3(u)) {
        bail!("the solve gave a non-finite displacement at node {}; nothing written", numbering.number_of(bad as u32));
    }
    write_outputs(args, &file_mesh, &numbering, &prescription, &solution.displacement, &reaction)?;

    let (max_node, max_u) = solution
        .displacement
        .iter()
        .enumerate()
        .map(|(i, u)| (i, u.norm()))
        .fold((0, 0.0), |best, (i, u)| if u > best.1 { (i, u) } else { best });
    let diagonal = boundary::bounding_diagonal(&mesh.positions);
    let v = |p: Vec3| format!("({:+.6e}, {:+.6e}, {:+.6e})", p.x, p.y, p.z);
    println!(
        "mesh:       {} ({unit_name}): {} nodes, {} tets, bounding-box diagonal {:.4e} m, read in {load_seconds:.3} s",
        args.mesh.display(),
        n,
        mesh.tets.len(),
        diagonal
    );
    println!(
        "material:   E = {} Pa, nu = {} (every region)",
        material.young_modulus, material.poisson_ratio
    );
    println!(
        "fixed:      {} nodes, {} components{}",
        prescription.node_count(Source::Fixed),
        prescription.dof_count(Source::Fixed),
        args.fixed.as_ref().map_or(String::new(), |p| format!(" ({})", p.display()))
    );
    println!(
        "enforced:   {} nodes, {} components{}",
        prescription.node_count(Source::Enforced),
        prescription.dof_count(Source::Enforced),
        args.enforced.as_ref().map_or(String::new(), |p| format!(" ({})", p.display()))
    );
    println!(
        "solve:      {} free DOFs, {solve_seconds:.3} s (assembly, sparse Cholesky, solve)",
        3 * n - prescription.dofs.len()
    );
    println!("max |u|:    {max_u:.6e} m at node {}", numbering.number_of(max_node as u32));
    println!("reactions:  on the fixed nodes    {} N", v(sum_fixed));
    println!("            on the enforced nodes {} N", v(sum_enforced));
    println!("            sum (no other load: ~0) {} N", v(sum_fixed + sum_enforced));
    println!("wrote {}{}", args.output.display(), args.csv.as_ref().map_or(String::new(), |c| format!(" and {}", c.display())));
    Ok(())
}

/// The mesh as the file gives it and the numbering its node files use.
fn load_mesh(args: &SolveArgs) -> anyhow::Result<(TetMesh, NodeNumbering)> {
    let load_context = || format!("cannot load the mesh {}", args.mesh.display());
    Ok(match args.node_numbering {
        NodeNumberingArg::Index => {
            let mesh = io::load_tet_mesh(&args.mesh).with_context(load_context)?;
            let count = mesh.node_count();
            (mesh, NodeNumbering::Index { count })
        }
        NodeNumberingArg::GmshTag => {
            if TetFormat::from_path(&args.mesh).ok() != Some(TetFormat::Gmsh) {
                bail!("--node-numbering gmsh-tag needs a Gmsh .msh mesh, not {}", args.mesh.display());
            }
            let (mesh, tags) = io::load_gmsh_with_node_tags(&args.mesh).with_context(load_context)?;
            (mesh, NodeNumbering::gmsh(&tags))
        }
    })
}

/// Each node's reaction, and their sums over the fixed and over the enforced components, N.
fn reactions(prescription: &boundary::Prescription, values: &[f64], n: usize) -> (Vec<Vec3>, Vec3, Vec3) {
    let mut reaction = vec![Vec3::zeros(); n];
    let (mut sum_fixed, mut sum_enforced) = (Vec3::zeros(), Vec3::zeros());
    for ((&(dof, _), &r), &source) in prescription.dofs.iter().zip(values).zip(&prescription.sources) {
        reaction[dof / 3][dof % 3] = r;
        let sum = if source == Source::Fixed { &mut sum_fixed } else { &mut sum_enforced };
        sum[dof % 3] += r;
    }
    (reaction, sum_fixed, sum_enforced)
}

/// The mesh with its displacement, reactions and masks, and the reaction table where asked.
fn write_outputs(
    args: &SolveArgs,
    file_mesh: &TetMesh,
    numbering: &NodeNumbering,
    prescription: &boundary::Prescription,
    displacement: &[Vec3],
    reaction: &[Vec3],
) -> anyhow::Result<()> {
    let mask = |m: &[u8]| Field::Scalar(m.iter().map(|&b| b as f64).collect());
    let fields = FieldData {
        point: vec![
            ("displacement_m".into(), Field::Vector(displacement.to_vec())),
            ("reaction_n".into(), Field::Vector(reaction.to_vec())),
            ("fixed_components".into(), mask(&prescription.fixed_mask)),
            ("enforced_components".into(), mask(&prescription.enforced_mask)),
        ],
        cell: Vec::new(),
    };
    io::save_tet_mesh(&args.output, file_mesh, &fields).with_context(|| format!("cannot write {}", args.output.display()))?;
    if let Some(csv) = &args.csv {
        let text = reaction_csv(numbering, prescription, displacement, reaction);
        fissure::fsio::write_atomic(csv, text.as_bytes()).with_context(|| format!("cannot write {}", csv.display()))?;
    }
    Ok(())
}

/// E and nu checked by the library's rule ([`Material::validate`]); nu above
/// [`LOCKING_POISSON_RATIO`] is a warning (volumetric locking).
fn material(young_modulus_pa: f64, poisson_ratio: f64) -> anyhow::Result<Material> {
    let m = Material { young_modulus: young_modulus_pa, poisson_ratio };
    if let Err(e) = m.validate(None) {
        return Err(match e {
            FemError::InvalidMaterial { field, value, reason, .. } => {
                let flag = if field == "young_modulus" { "--young-modulus-pa" } else { "--poisson-ratio" };
                anyhow::anyhow!("{flag} {value}: {field} {reason}")
            }
            other => other.into(),
        });
    }
    if poisson_ratio > LOCKING_POISSON_RATIO {
        eprintln!(
            "warning: --poisson-ratio {poisson_ratio} is above {LOCKING_POISSON_RATIO}: linear tetrahedra lock volumetrically \
             (too stiff) as nu -> 0.5"
        );
    }
    Ok(m)
}

/// Fails before any work when `path` cannot be an output: a format that cannot
/// hold point data, or a folder that does not exist.
fn check_output(path: &Path, flag: &str) -> anyhow::Result<()> {
    let is_csv = flag == "--csv";
    if !is_csv {
        match TetFormat::from_path(path) {
            Ok(TetFormat::Vtu | TetFormat::VtkLegacy | TetFormat::Gmsh) => {}
            _ => bail!("{flag} {}: the output must be .vtu (or .vtk / .msh) to hold the point data", path.display()),
        }
    }
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !parent.is_dir() {
        bail!("{flag} {}: the folder {} does not exist", path.display(), parent.display());
    }
    if path.is_dir() {
        bail!("{flag} {}: is a folder", path.display());
    }
    Ok(())
}

fn letters(mask: u8) -> String {
    ['x', 'y', 'z'].iter().enumerate().filter(|(c, _)| mask & (1 << c) != 0).map(|(_, l)| *l).collect()
}

/// One row per node with a prescribed component, in node order.
fn reaction_csv(numbering: &NodeNumbering, p: &boundary::Prescription, u: &[Vec3], r: &[Vec3]) -> String {
    let mut s = format!("{},fixed_components,enforced_components,ux_m,uy_m,uz_m,rx_n,ry_n,rz_n\n", numbering.column());
    for node in 0..u.len() {
        let (f, e) = (p.fixed_mask[node], p.enforced_mask[node]);
        if f | e == 0 {
            continue;
        }
        let (u, r) = (u[node], r[node]);
        let _ = writeln!(
            s,
            "{},{},{},{:e},{:e},{:e},{:e},{:e},{:e}",
            numbering.number_of(node as u32),
            letters(f),
            letters(e),
            u.x,
            u.y,
            u.z,
            r.x,
            r.y,
            r.z
        );
    }
    s
}
