//! Assembly of the global stiffness over the free degrees of freedom.
//!
//! In: a [`TetMesh`], per-tet Lamé parameters, the per-node fixed flags. Out: a [`DofMap`] (node -> free DOF
//! block), the lower triangle of `K_FF` in compressed sparse columns (faer layout), a lumped body-force vector, and
//! the connected-component check that turns a would-be singular factorization into a named error.
//! Stays true: DOF `3 * free_index(node) + component`; assembly visits tets in index order, so the values are
//! bitwise reproducible; fixed nodes and nodes used by no tet carry no DOF (their displacement is zero).

use super::FemError;
use super::element::tet_stiffness;
use crate::linalg::LowerCsc;
use crate::math::Vec3;
use crate::mesh::TetMesh;

/// Marks a node without free DOFs in [`DofMap::free_index`].
pub const NO_DOF: u32 = u32::MAX;

/// Node <-> free DOF numbering.
#[derive(Debug, Clone, PartialEq)]
pub struct DofMap {
    /// Per mesh node: index of its free DOF block, or [`NO_DOF`] (fixed or unused).
    pub free_index: Vec<u32>,
    /// Free block k is mesh node `free_nodes[k]` (ascending).
    pub free_nodes: Vec<u32>,
    /// Nodes used by no tetrahedron (they carry no DOF).
    pub unused_nodes: usize,
}

impl DofMap {
    /// Numbers the free nodes in ascending order.
    pub fn new(mesh: &TetMesh, fixed: &[bool]) -> Self {
        let mut used = vec![false; mesh.node_count()];
        for t in &mesh.tets {
            for &n in t {
                used[n as usize] = true;
            }
        }
        let mut free_index = vec![NO_DOF; mesh.node_count()];
        let mut free_nodes = Vec::new();
        for n in 0..mesh.node_count() {
            if used[n] && !fixed[n] {
                free_index[n] = free_nodes.len() as u32;
                free_nodes.push(n as u32);
            }
        }
        let unused_nodes = used.iter().filter(|u| !**u).count();
        Self { free_index, free_nodes, unused_nodes }
    }

    /// Number of free DOFs (3 per free node).
    pub fn dof_count(&self) -> usize {
        3 * self.free_nodes.len()
    }

    /// First free DOF of `node`, or `None` when it has none.
    #[inline]
    pub fn dof(&self, node: u32) -> Option<usize> {
        match self.free_index.get(node as usize) {
            Some(&k) if k != NO_DOF => Some(3 * k as usize),
            _ => None,
        }
    }

    /// The (node, component) of free DOF `dof` (node `u32::MAX` past the end): how errors name a pivot.
    pub fn name(&self, dof: usize) -> (u32, usize) {
        (self.free_nodes.get(dof / 3).copied().unwrap_or(u32::MAX), dof % 3)
    }
}

/// Union-find root of `x` (path halving); roots are the lowest node of their set.
pub(crate) fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let p = parent[x as usize];
        parent[x as usize] = parent[p as usize];
        x = p;
    }
    x
}

/// Joins the sets of `a` and `b` under the lower root.
pub(crate) fn join(parent: &mut [u32], a: u32, b: u32) {
    let (a, b) = (find(parent, a), find(parent, b));
    if a != b {
        let (lo, hi) = if a < b { (a, b) } else { (b, a) };
        parent[hi as usize] = lo;
    }
}

/// Errors with [`FemError::UnfixedComponent`] when a connected component of the
/// tet graph has no fixed node. Components are numbered by their lowest node.
pub fn check_components(mesh: &TetMesh, fixed: &[bool]) -> Result<(), FemError> {
    let n = mesh.node_count();
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for t in &mesh.tets {
        for k in 1..4 {
            join(&mut parent, t[0], t[k]);
        }
    }
    let mut used = vec![false; n];
    for t in &mesh.tets {
        for &v in t {
            used[v as usize] = true;
        }
    }
    // root -> (size, has_fixed); roots are the lowest node of their component.
    let mut size = vec![0usize; n];
    let mut has_fixed = vec![false; n];
    for v in 0..n {
        if !used[v] {
            continue;
        }
        let r = find(&mut parent, v as u32) as usize;
        size[r] += 1;
        has_fixed[r] |= fixed[v];
    }
    let mut component = 0;
    for r in 0..n {
        if size[r] == 0 {
            continue;
        }
        if !has_fixed[r] {
            return Err(FemError::UnfixedComponent { component, nodes: size[r], first_node: r as u32 });
        }
        component += 1;
    }
    Ok(())
}

/// Assembles `K_FF` (lower triangle). `lame[t]` = (lambda, mu) of tet t.
pub fn assemble_lower(mesh: &TetMesh, lame: &[(f64, f64)], dofs: &DofMap) -> LowerCsc {
    let nf = dofs.free_nodes.len();
    // Node-level lower pattern: pairs (col node j, row node i), i >= j, free indices.
    let mut pairs: Vec<(u32, u32)> = Vec::with_capacity(mesh.tets.len() * 10 + nf);
    for j in 0..nf as u32 {
        pairs.push((j, j));
    }
    for t in &mesh.tets {
        let f = t.map(|n| dofs.free_index[n as usize]);
        for a in 0..4 {
            for b in 0..4 {
                if f[a] != NO_DOF && f[b] != NO_DOF && f[a] > f[b] {
                    pairs.push((f[b], f[a]));
                }
            }
        }
    }
    pairs.sort_unstable();
    pairs.dedup();
    // node_ptr[j]..node_ptr[j+1]: row nodes of column node j (first is j itself).
    let mut node_ptr = vec![0usize; nf + 1];
    for &(j, _) in &pairs {
        node_ptr[j as usize + 1] += 1;
    }
    for j in 0..nf {
        node_ptr[j + 1] += node_ptr[j];
    }
    let row_nodes: Vec<u32> = pairs.iter().map(|p| p.1).collect();
    let dim = 3 * nf;
    let mut col_ptr = vec![0usize; dim + 1];
    for j in 0..nf {
        let others = node_ptr[j + 1] - node_ptr[j] - 1;
        for c in 0..3 {
            col_ptr[3 * j + c + 1] = col_ptr[3 * j + c] + (3 - c) + 3 * others;
        }
    }
    let nnz = col_ptr[dim];
    let mut row_idx = vec![0usize; nnz];
    for j in 0..nf {
        let list = &row_nodes[node_ptr[j]..node_ptr[j + 1]];
        for c in 0..3 {
            let mut p = col_ptr[3 * j + c];
            for r in c..3 {
                row_idx[p] = 3 * j + r;
                p += 1;
            }
            for &i in &list[1..] {
                for r in 0..3 {
                    row_idx[p] = 3 * i as usize + r;
                    p += 1;
                }
            }
        }
    }
    let mut values = vec![0.0; nnz];
    add_element_stiffness(mesh, lame, dofs, &row_nodes, &node_ptr, &col_ptr, &mut values);
    LowerCsc { dim, col_ptr, row_idx, values }
}

/// Adds every tetrahedron's stiffness into `values`, the lower CSC laid out by [`assemble_lower`]
/// (`row_nodes[node_ptr[j]..]`: column node `j`'s row nodes, itself first; `col_ptr`: the DOF columns' starts).
fn add_element_stiffness(mesh: &TetMesh, lame: &[(f64, f64)], dofs: &DofMap, row_nodes: &[u32], node_ptr: &[usize], col_ptr: &[usize], values: &mut [f64]) {
    for (t, tet) in mesh.tets.iter().enumerate() {
        let f = tet.map(|n| dofs.free_index[n as usize]);
        if f.iter().all(|&x| x == NO_DOF) {
            continue;
        }
        let p = tet.map(|n| mesh.positions[n as usize]);
        let (lambda, mu) = lame[t];
        let k = tet_stiffness(&p, lambda, mu);
        for a in 0..4 {
            for b in 0..4 {
                let (fi, fj) = (f[a], f[b]);
                if fi == NO_DOF || fj == NO_DOF || fi < fj {
                    continue;
                }
                let list = &row_nodes[node_ptr[fj as usize]..node_ptr[fj as usize + 1]];
                // position of row node fi in column node fj's list (binary search after the diagonal)
                let k_pos = if fi == fj { 0 } else { 1 + list[1..].binary_search(&fi).unwrap_or(0) };
                for c in 0..3 {
                    let base = col_ptr[3 * fj as usize + c];
                    for r in 0..3 {
                        let offset = if fi == fj {
                            if r < c {
                                continue;
                            }
                            r - c
                        } else {
                            (3 - c) + 3 * (k_pos - 1) + r
                        };
                        values[base + offset] += k[3 * a + r][3 * b + c];
                    }
                }
            }
        }
    }
}

/// Full stiffness of ALL nodes (fixed or not) as sorted (row, col, value) triplets with duplicates summed, DOF
/// `3 * node + component`. For tests and direct reference solves; not on any per-frame path.
pub fn assemble_full_triplets(mesh: &TetMesh, lame: &[(f64, f64)]) -> Vec<(usize, usize, f64)> {
    let mut trip: Vec<(usize, usize, f64)> = Vec::with_capacity(mesh.tets.len() * 144);
    for (t, tet) in mesh.tets.iter().enumerate() {
        let p = tet.map(|n| mesh.positions[n as usize]);
        let k = tet_stiffness(&p, lame[t].0, lame[t].1);
        for a in 0..4 {
            for b in 0..4 {
                for r in 0..3 {
                    for c in 0..3 {
                        trip.push((3 * tet[a] as usize + r, 3 * tet[b] as usize + c, k[3 * a + r][3 * b + c]));
                    }
                }
            }
        }
    }
    // stable sort keeps the element order of equal keys: deterministic sums
    trip.sort_by_key(|&(r, c, _)| (c, r));
    let mut out: Vec<(usize, usize, f64)> = Vec::with_capacity(trip.len() / 4);
    for (r, c, v) in trip {
        match out.last_mut() {
            Some(last) if last.0 == r && last.1 == c => last.2 += v,
            _ => out.push((r, c, v)),
        }
    }
    out
}

/// Lumped body force (N) per free DOF: each tet's weight `density * V * g` split equally over its four nodes.
/// `density` kg/m^3, `acceleration` m/s^2.
pub fn body_force(mesh: &TetMesh, dofs: &DofMap, density: f64, acceleration: Vec3) -> Vec<f64> {
    let mut f = vec![0.0; dofs.dof_count()];
    for tet in &mesh.tets {
        let w = acceleration * (density * mesh.tet_volume(tet) / 4.0);
        for &n in tet {
            if let Some(d) = dofs.dof(n) {
                f[d] += w.x;
                f[d + 1] += w.y;
                f[d + 2] += w.z;
            }
        }
    }
    f
}
