//! Fill-reducing ordering of `K_FF`: AMD (faer) or nested dissection (METIS).
//!
//! In: the lower triangle of `K_FF` (3 DOFs a free node, DOF `3 i + c`). Out: a DOF permutation (`fwd[new] = old`)
//! that keeps each node's three DOFs together: METIS orders the node graph (a third of the DOF graph's size, and
//! its separators cut through nodes, not single DOFs). Nested dissection keeps the factor of a 3-D mesh near
//! `n^(4/3)` entries where minimum degree grows faster; which wins on a mesh is measured, not assumed
//! ([`FillOrdering::Best`]; `benches/fem.rs` prints both).
//! Stays true: the result is a permutation of `0..dim` that depends only on the matrix pattern (METIS runs with a
//! fixed seed).

use super::LowerCsc;

/// Which fill-reducing ordering a factor uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FillOrdering {
    /// faer's approximate minimum degree over DOFs.
    Amd,
    /// METIS's nested dissection of the node graph.
    NestedDissection,
    /// Both analysed, the one with fewer entries in L kept.
    Best,
}

impl FillOrdering {
    /// `FISSURE_ORDERING=amd|nd` forces one ordering (to compare them on a whole run); unset, [`FillOrdering::Best`].
    /// Another value is named in a warning and ignored.
    pub fn from_env() -> Self {
        match std::env::var("FISSURE_ORDERING").as_deref() {
            Err(_) | Ok("") | Ok("best") => Self::Best,
            Ok("amd") => Self::Amd,
            Ok("nd") => Self::NestedDissection,
            Ok(other) => {
                tracing::warn!("FISSURE_ORDERING={other:?} is not amd, nd or best; using best");
                Self::Best
            }
        }
    }
}

/// Node adjacency (compressed rows, both directions, no self loops).
struct Graph {
    start: Vec<usize>,
    adj: Vec<u32>,
}

impl Graph {
    fn of_nodes(k: &LowerCsc) -> Self {
        let n = k.dim / 3;
        let mut pairs: Vec<(u32, u32)> = Vec::new();
        for b in 0..n {
            let j = 3 * b;
            let mut last = u32::MAX;
            for &i in &k.row_idx[k.col_ptr[j]..k.col_ptr[j + 1]] {
                let a = (i / 3) as u32;
                if a as usize != b && a != last {
                    pairs.push((a, b as u32));
                    pairs.push((b as u32, a));
                    last = a;
                }
            }
        }
        pairs.sort_unstable();
        pairs.dedup();
        let mut start = vec![0usize; n + 1];
        for &(a, _) in &pairs {
            start[a as usize + 1] += 1;
        }
        for i in 0..n {
            start[i + 1] += start[i];
        }
        Self { start, adj: pairs.into_iter().map(|(_, b)| b).collect() }
    }
}

/// The DOF permutation (`fwd[new] = old`) of `k` by METIS's nested dissection (`METIS_NodeND`) of its node graph;
/// `None` when METIS fails (the caller falls back to AMD).
pub fn nested_dissection(k: &LowerCsc) -> Option<Vec<usize>> {
    use metis_sys::idx_t;
    let n = k.dim / 3;
    if n < 2 {
        return Some((0..k.dim).collect());
    }
    let graph = Graph::of_nodes(k);
    let mut xadj: Vec<idx_t> = graph.start.iter().map(|&s| idx_t::try_from(s).ok()).collect::<Option<_>>()?;
    let mut adjncy: Vec<idx_t> = graph.adj.iter().map(|&v| idx_t::try_from(v).ok()).collect::<Option<_>>()?;
    let mut nvtxs = idx_t::try_from(n).ok()?;
    let mut options = [0 as idx_t; metis_sys::METIS_NOPTIONS as usize];
    // SAFETY: `options` has METIS_NOPTIONS entries, as METIS_SetDefaultOptions writes.
    unsafe { metis_sys::METIS_SetDefaultOptions(options.as_mut_ptr()) };
    options[metis_sys::moptions_et_METIS_OPTION_NUMBERING as usize] = 0;
    // Fixed seed: the same mesh always gets the same ordering (deterministic replays).
    options[metis_sys::moptions_et_METIS_OPTION_SEED as usize] = 7;
    let (mut perm, mut iperm) = (vec![0 as idx_t; n], vec![0 as idx_t; n]);
    // METIS seeds one process-wide random state (libc's srand/rand, as metis-sys builds GKlib) at each call: two
    // calls at once (parallel tests, a study building several models) would draw from each other's sequence and
    // order the same mesh differently, breaking bitwise replays. One call at a time.
    static METIS: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _one_at_a_time = METIS.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: xadj has n + 1 entries, adjncy xadj[n], perm and iperm n each;
    // the graph is symmetric without self loops, as METIS requires.
    let status = unsafe {
        metis_sys::METIS_NodeND(&mut nvtxs, xadj.as_mut_ptr(), adjncy.as_mut_ptr(), std::ptr::null_mut(), options.as_mut_ptr(), perm.as_mut_ptr(), iperm.as_mut_ptr())
    };
    if status != metis_sys::rstatus_et_METIS_OK {
        tracing::warn!("METIS nested dissection failed (status {status}); using AMD");
        return None;
    }
    // METIS's `perm[new] = old` (row i of the permuted matrix is row perm[i]); `iperm[old] = new`.
    let mut fwd = Vec::with_capacity(3 * n);
    for &v in &perm {
        for c in 0..3 {
            fwd.push(3 * v as usize + c);
        }
    }
    Some(fwd)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fem::assembly::{DofMap, assemble_lower};
    use crate::mesh::fixtures;

    #[test]
    fn nested_dissection_is_a_node_blocked_permutation() {
        let mesh = fixtures::box_mesh(&fixtures::linspace(0.0, 0.09, 10), &fixtures::linspace(0.0, 0.07, 8), &fixtures::linspace(0.0, 0.06, 7)).unwrap();
        let fixed: Vec<bool> = mesh.positions.iter().map(|p| p.z <= 1e-12).collect();
        let dofs = DofMap::new(&mesh, &fixed);
        let lame = vec![(1.0e3, 1.0e4); mesh.regions.len()];
        let k = assemble_lower(&mesh, &lame, &dofs);
        let fwd = nested_dissection(&k).expect("METIS orders a box");
        assert_eq!(fwd.len(), k.dim);
        let mut seen = vec![false; k.dim];
        for (i, &d) in fwd.iter().enumerate() {
            assert!(!seen[d], "DOF {d} twice");
            seen[d] = true;
            assert_eq!(d % 3, i % 3, "a node's DOFs stay together in x, y, z order");
            assert_eq!(d / 3, fwd[i - i % 3] / 3);
        }
        // Deterministic.
        assert_eq!(fwd, nested_dissection(&k).unwrap());
    }
}
