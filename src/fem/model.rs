//! The assembled and factored FEM model.
//!
//! In: a [`TetMesh`] (m), [`RegionMaterials`], per-node fixed flags, [`FemOptions`]. Out: a [`FemModel`] holding
//! `K_FF` (lower), its Cholesky factor (made at the build, or on first use: [`FemModel::new_deferred`]), the
//! boundary surface, the optional gravity displacement `u0 = K^-1 f`, build statistics and a fingerprint (blake3
//! of mesh, materials and fixed set) that keys caches.
//! Stays true: immutable after `new`; every solve is exact up to round-off.

use super::FemError;
use super::assembly::{DofMap, assemble_lower, body_force, check_components};
use super::element::RegionMaterials;
use crate::linalg::{FillOrdering, LowerCsc, SparseCholesky};
use crate::math::{Vec3, is_finite3};
use crate::mesh::{BoundarySurface, TetMesh};
use std::time::Instant;

/// Gravity as a body force.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BodyForce {
    /// Mass density, kg/m^3, finite and >= 0 (brain: about 1040).
    pub density: f64,
    /// Acceleration, m/s^2, finite (e.g. (0, 0, -9.81)).
    pub acceleration: Vec3,
}

/// Options of the model build.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FemOptions {
    /// Optional gravity; when present the rest state of every frame is the sagged one.
    pub gravity: Option<BodyForce>,
}

/// What building the model cost and produced.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FemStats {
    /// Free degrees of freedom (3 per free node).
    pub free_dofs: usize,
    /// Stored entries of the lower triangle of K_FF.
    pub nnz_k: usize,
    /// Stored entries of the Cholesky factor L.
    pub nnz_l: usize,
    /// Seconds: assembly, symbolic analysis, numeric factorization.
    pub assembly_seconds: f64,
    pub symbolic_seconds: f64,
    pub numeric_seconds: f64,
    /// Nodes used by no tetrahedron (no DOF, displacement 0).
    pub unused_nodes: usize,
}

/// Assembled stiffness over the free DOFs and its Cholesky factor.
#[derive(Debug)]
pub struct FemModel {
    pub(crate) mesh: TetMesh,
    pub(crate) surface: BoundarySurface,
    pub(crate) dofs: DofMap,
    pub(crate) lame: Vec<(f64, f64)>,
    /// `K_FF` and its factor (made at the build, or later: [`FemModel::new_deferred`]).
    pub(crate) chol: std::sync::Arc<LazyFactor>,
    /// Body force per free DOF (N), empty without gravity.
    pub(crate) body_force: Vec<f64>,
    /// K^-1 body force per free DOF (m), empty without gravity.
    pub(crate) u0: Vec<f64>,
    pub(crate) fingerprint: [u8; 32],
    stats: FemStats,
}

impl FemModel {
    /// Builds and factors the model. Errors: wrong `fixed` length, invalid material or gravity, a connected
    /// component with no fixed node ([`FemError::UnfixedComponent`]), no free DOF, a non-positive pivot.
    pub fn new(mesh: &TetMesh, materials: &RegionMaterials, fixed: &[bool], options: &FemOptions) -> Result<Self, FemError> {
        let model = Self::new_deferred(mesh, materials, fixed, options)?;
        model.chol.get()?;
        Ok(model)
    }

    /// As [`FemModel::new`], without making the factor of `K_FF` unless gravity needs it: the first solve makes it,
    /// or a thread started by [`FemModel::start_factor`]. For a scene whose compliance comes from a cache (its first
    /// frame reads no factor); a failing factor fails that first solve instead of the build.
    pub fn new_deferred(mesh: &TetMesh, materials: &RegionMaterials, fixed: &[bool], options: &FemOptions) -> Result<Self, FemError> {
        if fixed.len() != mesh.node_count() {
            return Err(FemError::FixedLength { expected: mesh.node_count(), got: fixed.len() });
        }
        let sorted = materials.validated()?;
        if let Some(g) = &options.gravity {
            if !(g.density.is_finite() && g.density >= 0.0) {
                return Err(FemError::InvalidOption { field: "gravity.density", value: g.density, reason: "must be finite and >= 0 kg/m^3" });
            }
            if !is_finite3(&g.acceleration) {
                return Err(FemError::InvalidOption { field: "gravity.acceleration", value: f64::NAN, reason: "must be finite" });
            }
        }
        check_components(mesh, fixed)?;
        let t0 = Instant::now();
        let dofs = DofMap::new(mesh, fixed);
        if dofs.dof_count() == 0 {
            return Err(FemError::NoFreeDofs);
        }
        let lame: Vec<(f64, f64)> =
            mesh.regions.iter().map(|&r| RegionMaterials::lookup(&sorted, materials.default, r).lame()).collect();
        let k = assemble_lower(mesh, &lame, &dofs);
        let assembly_seconds = t0.elapsed().as_secs_f64();
        let nnz_k = k.values.len();
        let chol = LazyFactor::new(k, dofs.clone(), FillOrdering::from_env());
        let (body, u0) = match &options.gravity {
            Some(g) => {
                let chol = chol.get()?;
                let f = body_force(mesh, &dofs, g.density, g.acceleration);
                let mut u = f.clone();
                let mut scratch = chol.scratch(1)?;
                chol.solve_vec_in_place(&mut u, &mut scratch);
                (f, u)
            }
            None => (Vec::new(), Vec::new()),
        };
        let fingerprint = fingerprint(mesh, &sorted, materials, fixed);
        let stats = FemStats { free_dofs: dofs.dof_count(), nnz_k, assembly_seconds, unused_nodes: dofs.unused_nodes, ..FemStats::default() };
        Ok(Self { surface: mesh.boundary(), mesh: mesh.clone(), dofs, lame, chol: std::sync::Arc::new(chol), body_force: body, u0, fingerprint, stats })
    }

    /// Starts making the factor of `K_FF` on its own thread if it is not made yet; the first solve waits for it.
    pub fn start_factor(&self) {
        self.chol.start_background();
    }

    /// Build statistics (the factor's figures wait for the factor; zero if it failed).
    pub fn stats(&self) -> FemStats {
        let mut s = self.stats;
        if let Ok(chol) = self.chol.get() {
            s.nnz_l = chol.nnz_l();
            s.symbolic_seconds = chol.symbolic_seconds;
            s.numeric_seconds = chol.numeric_seconds;
        }
        s
    }

    /// The mesh the model was built from.
    pub fn mesh(&self) -> &TetMesh {
        &self.mesh
    }

    /// Its boundary surface (defines the surface-vertex order of every output).
    pub fn surface(&self) -> &BoundarySurface {
        &self.surface
    }

    /// Node <-> free DOF numbering.
    pub fn dofs(&self) -> &DofMap {
        &self.dofs
    }

    /// Lamé parameters (lambda, mu) per tet, Pa.
    pub fn lame(&self) -> &[(f64, f64)] {
        &self.lame
    }

    /// blake3 of mesh, materials and fixed set.
    pub fn fingerprint(&self) -> [u8; 32] {
        self.fingerprint
    }

    /// True when the node is fixed or unused (zero displacement, no DOF).
    pub fn is_fixed(&self, node: u32) -> bool {
        self.dofs.dof(node).is_none()
    }

    /// The sparse factor of K_FF (made now, or waited for, when deferred).
    pub fn factor(&self) -> Result<&SparseCholesky, FemError> {
        self.chol.get()
    }

    /// Lower triangle of K_FF.
    pub fn stiffness(&self) -> &LowerCsc {
        self.chol.stiffness()
    }

    /// Solves `K u = f` for nodal forces (N, one per node; fixed ones ignored): displacements (m), gravity included.
    pub fn solve_nodal_forces(&self, forces: &[Vec3]) -> Result<Vec<Vec3>, FemError> {
        if forces.len() != self.mesh.node_count() {
            return Err(FemError::LengthMismatch { what: "nodal forces", expected: self.mesh.node_count(), got: forces.len() });
        }
        let forces: Vec<(u32, Vec3)> = forces.iter().enumerate().map(|(node, f)| (node as u32, *f)).collect();
        let mut out = Vec::new();
        displacements_from_forces((self.chol.get()?, &self.dofs, &self.body_force), self.mesh.node_count(), &forces, (&mut Vec::new(), &mut None), &mut out)?;
        Ok(out)
    }

    /// Gravity displacement of a node (zero without gravity or when fixed).
    #[inline]
    pub(crate) fn gravity_displacement(&self, node: u32) -> Vec3 {
        match (self.u0.is_empty(), self.dofs.dof(node)) {
            (false, Some(d)) => Vec3::new(self.u0[d], self.u0[d + 1], self.u0[d + 2]),
            _ => Vec3::zeros(),
        }
    }
}

fn fingerprint(mesh: &TetMesh, sorted: &[(u32, super::Material)], materials: &RegionMaterials, fixed: &[bool]) -> [u8; 32] {
    let mut h = blake3::Hasher::new();
    h.update(b"fissure-fem-model-v1");
    h.update(&(mesh.positions.len() as u64).to_le_bytes());
    for c in mesh.positions.iter().flat_map(|p| [p.x, p.y, p.z]) {
        h.update(&c.to_bits().to_le_bytes());
    }
    h.update(&(mesh.tets.len() as u64).to_le_bytes());
    for n in mesh.tets.iter().flatten().chain(&mesh.regions) {
        h.update(&n.to_le_bytes());
    }
    // The default material, then each region's followed by its number.
    for (m, r) in std::iter::once((&materials.default, None)).chain(sorted.iter().map(|(r, m)| (m, Some(r)))) {
        h.update(&m.young_modulus.to_bits().to_le_bytes());
        h.update(&m.poisson_ratio.to_bits().to_le_bytes());
        if let Some(r) = r {
            h.update(&r.to_le_bytes());
        }
    }
    let bits: Vec<u8> = fixed.iter().map(|&f| f as u8).collect();
    h.update(&bits);
    *h.finalize().as_bytes()
}

/// The right-hand side of `K u = f` in free DOFs for nodal `forces` plus the body force (`body_force` empty: none),
/// into `rhs`; the DOFs a force lands on are appended to `forced` when given.
pub(crate) fn force_rhs((dofs, body_force): (&DofMap, &[f64]), forces: &[(u32, Vec3)], rhs: &mut Vec<f64>, mut forced: Option<&mut Vec<usize>>) {
    rhs.clear();
    if body_force.is_empty() {
        rhs.resize(dofs.dof_count(), 0.0);
    } else {
        rhs.extend_from_slice(body_force);
    }
    for &(node, f) in forces {
        if let Some(d) = dofs.dof(node) {
            rhs[d] += f.x;
            rhs[d + 1] += f.y;
            rhs[d + 2] += f.z;
            if let Some(forced) = forced.as_deref_mut() {
                forced.extend(d..d + 3);
            }
        }
    }
}

/// Every node's displacement (m) for nodal `forces` (N, on free nodes) plus the body force: one sparse solve; fixed
/// nodes get 0. `rhs` and `scratch` are reused between calls. Shared by [`FemModel::solve_nodal_forces`],
/// `ConstrainedSolver::interior_displacements` and the background stress worker.
pub(crate) fn displacements_from_forces(
    (chol, dofs, body_force): (&SparseCholesky, &DofMap, &[f64]),
    node_count: usize,
    forces: &[(u32, Vec3)],
    (rhs, scratch): (&mut Vec<f64>, &mut Option<faer::dyn_stack::MemBuffer>),
    out: &mut Vec<Vec3>,
) -> Result<(), FemError> {
    force_rhs((dofs, body_force), forces, rhs, None);
    if scratch.is_none() {
        *scratch = Some(chol.scratch(1)?);
    }
    if let Some(scratch) = scratch.as_mut() {
        chol.solve_vec_in_place(rhs, scratch);
    }
    out.clear();
    out.resize(node_count, Vec3::zeros());
    for (k, &n) in dofs.free_nodes.iter().enumerate() {
        out[n as usize] = Vec3::new(rhs[3 * k], rhs[3 * k + 1], rhs[3 * k + 2]);
    }
    Ok(())
}

/// The factor of `K_FF`, made on first use or on a background thread.
///
/// In: `K_FF` (lower) and the DOF names, moved in. Out: the factor, or its build's error, to every caller of
/// [`LazyFactor::get`] (which waits while it is made). Stays true: made once, by one thread, exactly as
/// [`factor_k`] makes it, so answers never depend on when. A scene whose compliance comes from a valid
/// cache starts without it; lazy columns, interior displacements and rebuilt cache batches wait for it.
pub struct LazyFactor {
    cell: std::sync::OnceLock<Result<SparseCholesky, FemError>>,
    k: LowerCsc,
    dofs: DofMap,
    /// The ordering asked for ([`FillOrdering::Best`] is resolved by the factor).
    pub(crate) requested: FillOrdering,
    started: std::sync::atomic::AtomicBool,
}

impl std::fmt::Debug for LazyFactor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LazyFactor").field("dim", &self.k.dim).field("ready", &self.is_ready()).finish()
    }
}

impl LazyFactor {
    pub(crate) fn new(k: LowerCsc, dofs: DofMap, requested: FillOrdering) -> Self {
        Self { cell: std::sync::OnceLock::new(), k, dofs, requested, started: std::sync::atomic::AtomicBool::new(false) }
    }

    /// The factor: made here if nobody has started it, else waits for the thread making it.
    pub fn get(&self) -> Result<&SparseCholesky, FemError> {
        self.cell.get_or_init(|| factor_k(&self.k, &self.dofs, self.requested)).as_ref().map_err(Clone::clone)
    }

    /// True once the factor (or its error) is there.
    pub fn is_ready(&self) -> bool {
        self.cell.get().is_some()
    }

    /// The lower triangle of `K_FF` it factors.
    pub(crate) fn stiffness(&self) -> &LowerCsc {
        &self.k
    }

    /// Starts making the factor on its own thread (once; nothing when made or being made). If the thread cannot
    /// start, the first caller of [`Self::get`] makes it.
    pub(crate) fn start_background(self: &std::sync::Arc<Self>) {
        if self.is_ready() || self.started.swap(true, std::sync::atomic::Ordering::AcqRel) {
            return;
        }
        let this = std::sync::Arc::clone(self);
        let spawned = std::thread::Builder::new().name("fissure-factor".into()).spawn(move || {
            let t = std::time::Instant::now();
            match this.get() {
                Ok(_) => tracing::debug!("factor of K_FF ready after {:.2} s in the background", t.elapsed().as_secs_f64()),
                Err(e) => tracing::error!("factor of K_FF in the background: {e}"),
            }
        });
        if let Err(e) = spawned {
            tracing::warn!("factor thread did not start ({e}); the first solve makes the factor");
        }
    }
}

/// `K_FF`'s factor as every part of the FEM stage makes it: pivots named by node, the row-major solve as
/// `fem::tuning` says.
pub(crate) fn factor_k(k: &LowerCsc, dofs: &DofMap, ordering: FillOrdering) -> Result<SparseCholesky, FemError> {
    let mut chol = SparseCholesky::new(k, ordering, &|d| dofs.name(d))?;
    chol.set_row_major(super::tuning::Tuning::current().enabled(super::tuning::Optimisation::RowMajorSolve));
    Ok(chol)
}
