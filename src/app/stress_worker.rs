//! Every node's displacement, and per-tet stress when asked, on a background thread: for a display that wants
//! strain colour without the synchronous StressField stage, or the surface beyond the working region up to date.
//!
//! In: after a frame, its nodal forces on the tissue ([`crate::fem::ConstrainedSolver::last_forces`]) and whether stress
//! is wanted. Out: now and then, every node's displacement (and every tet's stress) for the newest frame the worker
//! finished (one interior sparse solve and the stress pass, on the other core).
//! Stays true: the simulation never waits for it (a newer request replaces one not yet started, so the worker is
//! at most one solve behind); values equal [`crate::fem::element_stress`]'s for the same forces; buffers go back and
//! forth, so a steady state allocates nothing; a failing worker reports once and stops; dropping this ends the
//! thread after its current solve. Not for replays: which frames get stress depends on timing.

use crate::fem::assembly::DofMap;
use crate::fem::model::{LazyFactor, displacements_from_forces};
use crate::fem::{ElementStress, FemError, FemModel, tet_stress};
use crate::math::Vec3;
use crate::mesh::TetMesh;
use std::sync::{Arc, Condvar, Mutex, MutexGuard};

/// What the worker keeps of the model.
struct Inputs {
    chol: Arc<LazyFactor>,
    dofs: DofMap,
    body_force: Vec<f64>,
    mesh: TetMesh,
    lame: Vec<(f64, f64)>,
}

#[derive(Default)]
struct Exchange {
    /// The newest frame's forces not yet taken by the worker, and whether stress is wanted.
    request: Option<(u64, Vec<(u32, Vec3)>, bool)>,
    /// The newest finished frame ([`Solved`]), until taken.
    result: Option<Solved>,
    /// Set when the owner is dropped.
    closed: bool,
    /// Set (with the reason) when the worker failed.
    failed: Option<String>,
    /// Buffers handed back for reuse.
    spare_forces: Vec<(u32, Vec3)>,
    spare_stress: Vec<ElementStress>,
    spare_nodes: Vec<Vec3>,
}

/// A finished frame: its number, stress (empty unless asked), every node's displacement.
type Solved = (u64, Vec<ElementStress>, Vec<Vec3>);

type Shared = Arc<(Mutex<Exchange>, Condvar)>;

fn lock(shared: &Shared) -> MutexGuard<'_, Exchange> {
    shared.0.lock().unwrap_or_else(std::sync::PoisonError::into_inner)
}

/// The background stress worker of one model.
pub struct StressWorker {
    shared: Shared,
    failure_reported: bool,
}

impl std::fmt::Debug for StressWorker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StressWorker").finish_non_exhaustive()
    }
}

impl StressWorker {
    /// Starts the worker thread for `model` (a copy of its mesh and materials, the shared factor); Err if it cannot.
    pub fn start(model: &FemModel) -> Result<Self, FemError> {
        let inputs = Inputs {
            chol: Arc::clone(&model.chol),
            dofs: model.dofs.clone(),
            body_force: model.body_force.clone(),
            mesh: model.mesh.clone(),
            lame: model.lame.clone(),
        };
        let shared: Shared = Arc::default();
        let theirs = Arc::clone(&shared);
        std::thread::Builder::new()
            .name("fissure-stress".into())
            .spawn(move || work(&inputs, &theirs))
            .map_err(|e| FemError::ThreadStart { what: "background stress", reason: e.to_string() })?;
        Ok(Self { shared, failure_reported: false })
    }

    /// Asks for the displacement (and with `stress`, the stress) of frame `frame` with these forces, replacing a
    /// request the worker has not started. Never waits.
    pub fn post(&self, frame: u64, forces: &[(u32, Vec3)], stress: bool) {
        let mut x = lock(&self.shared);
        match x.request.as_mut() {
            Some((f, v, s)) => {
                *f = frame;
                *s = stress;
                v.clear();
                v.extend_from_slice(forces);
            }
            None => {
                let mut v = std::mem::take(&mut x.spare_forces);
                v.clear();
                v.extend_from_slice(forces);
                x.request = Some((frame, v, stress));
            }
        }
        drop(x);
        self.shared.1.notify_one();
    }

    /// Moves the newest finished stress (empty unless asked) and node displacements into `stress` and `nodes` and
    /// returns its frame; `None` when nothing new has finished since the last call.
    pub fn take(&self, stress: &mut Vec<ElementStress>, nodes: &mut Vec<Vec3>) -> Option<u64> {
        let mut x = lock(&self.shared);
        let solved = x.result.take()?;
        Some(give(&mut x, solved, stress, nodes))
    }

    /// The reason the worker stopped, the first time it is asked after the failure.
    pub fn take_failure(&mut self) -> Option<String> {
        if self.failure_reported {
            return None;
        }
        let reason = lock(&self.shared).failed.clone()?;
        self.failure_reported = true;
        Some(reason)
    }

    /// Waits until the worker has finished frame `frame` or a later one and moves its results as [`Self::take`]
    /// does (tests and tools; the frame loop never waits). `None` when the worker failed.
    pub fn wait_for(&self, frame: u64, stress: &mut Vec<ElementStress>, nodes: &mut Vec<Vec3>) -> Option<u64> {
        let mut x = lock(&self.shared);
        loop {
            if x.failed.is_some() {
                return None;
            }
            if let Some((f, _, _)) = &x.result
                && *f >= frame
            {
                let solved = x.result.take()?;
                return Some(give(&mut x, solved, stress, nodes));
            }
            x = self.shared.1.wait(x).unwrap_or_else(std::sync::PoisonError::into_inner);
        }
    }
}

impl Drop for StressWorker {
    fn drop(&mut self) {
        lock(&self.shared).closed = true;
        self.shared.1.notify_all();
    }
}

/// Hands a finished frame's buffers out, keeping the caller's old ones as spares.
fn give(x: &mut Exchange, (frame, stress, nodes): Solved, stress_out: &mut Vec<ElementStress>, nodes_out: &mut Vec<Vec3>) -> u64 {
    x.spare_stress = std::mem::replace(stress_out, stress);
    x.spare_nodes = std::mem::replace(nodes_out, nodes);
    frame
}

fn work(inputs: &Inputs, shared: &Shared) {
    // The frames come first: this thread yields to them.
    crate::fem::compliance::lower_thread_priority();
    let (mut rhs, mut scratch) = (Vec::new(), None);
    loop {
        let (frame, forces, want_stress, mut stress, mut nodes) = {
            let mut x = lock(shared);
            loop {
                if x.closed {
                    return;
                }
                if let Some((frame, forces, want_stress)) = x.request.take() {
                    break (frame, forces, want_stress, std::mem::take(&mut x.spare_stress), std::mem::take(&mut x.spare_nodes));
                }
                x = shared.1.wait(x).unwrap_or_else(std::sync::PoisonError::into_inner);
            }
        };
        let result = inputs
            .chol
            .get()
            .and_then(|chol| {
                displacements_from_forces(
                    (chol, &inputs.dofs, &inputs.body_force),
                    inputs.mesh.node_count(),
                    &forces,
                    (&mut rhs, &mut scratch),
                    &mut nodes,
                )
            })
            .and_then(|()| {
                if want_stress {
                    tet_stress(&inputs.mesh, &inputs.lame, &nodes, &mut stress)
                } else {
                    stress.clear();
                    Ok(())
                }
            });
        let mut x = lock(shared);
        x.spare_forces = forces;
        match result {
            // an unread older result goes back as a spare
            Ok(()) => {
                if let Some((_, old, old_nodes)) = x.result.replace((frame, stress, nodes)) {
                    x.spare_stress = old;
                    x.spare_nodes = old_nodes;
                }
            }
            Err(e) => {
                x.failed = Some(format!("background stress stopped: {e}"));
                drop(x);
                shared.1.notify_all();
                return;
            }
        }
        drop(x);
        shared.1.notify_all();
    }
}
