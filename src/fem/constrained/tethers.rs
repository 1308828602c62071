//! Tethers in the exact solve: tension-only elastic links between two points of the tissue, or between a point
//! of the tissue and a fixed anchor (a vessel's segment, an arachnoid band).
//!
//! In: the links ([`Tether`], set once by [`ConstrainedSolver::set_tethers`]), which of them still hold
//! ([`ConstrainedSolver::set_tether_enabled`]). Out: each link's tension in [`FrameSolution::tether_tension`]; the
//! links' pull is in every reaction, force and displacement of the frame.
//!
//! Method. A link's end is an affine combination of nodes (a point of a boundary triangle, barycentric weights) or
//! a fixed point. At the start of a frame the link is linearized along `n`, the unit direction from end a to end b
//! at the last frame's positions: its extension `e = n . (x_b - x_a) - L0` is linear in the displacement, `e =
//! target - c . u` with `c` the row `+w_i n` at a's nodes and `-w_j n` at b's, `target = n . (X_b - X_a) - L0`. A
//! taut link is one more row of `W = C K^-1 C^T` whose unknown is its tension `T >= 0`, with compliance `1 / k` on
//! its diagonal: `c . u + T / k = target`, so `T = k e` exactly, in the same solve as the blades and the skull
//! (the series compliance of spring and tissue comes out of the factor, not from iterating). Tension-only: a slack
//! link (`e <= 0`) is an inactive candidate that activates when the solution stretches it, and an active link
//! whose tension would be negative (it would push) is released, as a face row that pulls is.
//!
//! Stays true: a link with `k > 0` never makes W singular (its pivot is at least `1 / k` past what the other rows
//! explain), so no tether row is ever dropped; the active links carry over to the next frame; fixed iteration
//! order (links in the order given, ends a then b, nodes in triangle order).

use super::*;
use pairs::RowPairs;

/// One end of a tether.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TetherEnd {
    /// A point of the tissue: `sum w_i (X_i + u_i)` over a boundary triangle's nodes (weights finite, summing to 1).
    Tissue { nodes: [u32; 3], weights: [f64; 3] },
    /// A fixed point (m): a point of the dural sinus, the dura, the skull.
    Anchor { point: Vec3 },
}

/// A tension-only elastic link: `T = stiffness * max(0, length - rest_length)` (linearized each frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Tether {
    pub ends: [TetherEnd; 2],
    /// Length at which the link starts to pull, m (> 0).
    pub rest_length: f64,
    /// Axial stiffness, N/m (> 0 and finite).
    pub stiffness: f64,
}

/// Links given their [`TetherColumns`] in one step, at most (each reads its nodes' blocks over every stored row, a
/// few milliseconds on a real brain): a scene's links are all made within its first steps, none of them long, and
/// a link not made yet is read node by node. A count, not a time, so replays stay bit for bit.
const COLUMNS_PER_STEP: usize = 1;

/// Most memory the links' columns take together (72 bytes a stored row a link: a real brain's Sylvian scene, 3726
/// rows, 268 kB a link); links past it are read node by node, as a scene of thousands of vessel segments would be.
const COLUMNS_MAX_BYTES: usize = 256 << 20;

/// Most nodes a tether row touches (three a tissue end).
const TERMS: usize = 6;

/// A link linearized for the frame: `c . u + T / k = target` over its (node, coefficient) terms.
#[derive(Debug, Clone, Copy, Default)]
pub(super) struct LinearTether {
    terms: [(u32, Vec3); TERMS],
    count: usize,
    target: f64,
    /// The direction it is linearized along (a to b).
    dir: Vec3,
}

impl LinearTether {
    fn terms(&self) -> &[(u32, Vec3)] {
        &self.terms[..self.count]
    }
}

/// The solver's tethers: the links, which hold, which pull, and this iteration's rows.
#[derive(Default)]
pub(super) struct TetherSet {
    links: Vec<Tether>,
    enabled: Vec<bool>,
    /// Taut (a row of W) at the end of the last iteration; carried between frames.
    active: Vec<bool>,
    linear: Vec<LinearTether>,
    /// This iteration's tether rows: (link, the slot of each term's node in `System::nodes`).
    pub(super) rows: Vec<(usize, [usize; TERMS])>,
    /// Per link, the tension of the last frame, N.
    tension: Vec<f64>,
    /// Per link, its columns over the stored rows ([`TetherColumns`]) once made; `None` where a node has no ROI
    /// column (the link is then gathered node by node).
    columns: Vec<Option<TetherColumns>>,
    /// Per link, whether its columns were tried.
    columns_tried: Vec<bool>,
    /// Bytes of the links' columns made so far (at most [`COLUMNS_MAX_BYTES`]).
    columns_bytes: usize,
    /// This iteration's pull of each row of a link with columns: (link, `T n`), in row order.
    pub(super) pulls: Vec<(usize, Vec3)>,
}

/// A link's compliance over every stored row: `M[r] = sum_k s_k w_k K^-1[row r, node_k]` (3x3, 9 f64 a row, row
/// major), `s_k` = +1 at end a's nodes, -1 at end b's. The link's row at direction `n` is `K^-1 c^T = M n`, fixed
/// for the link's life whatever its direction, so a frame reads 9 values a row for a taut link instead of the 3x3
/// blocks of its six nodes: its entries of W against a contact row at node p along d are `d . M[p] n`, its pull
/// on the surface `M (T n)`.
#[derive(Debug, Clone)]
pub(super) struct TetherColumns {
    m: Vec<f64>,
}

impl TetherColumns {
    /// `M[r] v`.
    #[inline]
    fn apply(&self, r: usize, v: &Vec3) -> Vec3 {
        let b = &self.m[9 * r..9 * r + 9];
        Vec3::new(b[0] * v.x + b[1] * v.y + b[2] * v.z, b[3] * v.x + b[4] * v.y + b[5] * v.z, b[6] * v.x + b[7] * v.y + b[8] * v.z)
    }
}

impl TetherSet {
    /// Whether the solver has any link that still holds.
    pub(super) fn any(&self) -> bool {
        self.enabled.iter().any(|e| *e)
    }

    /// How many links were set (held or not).
    pub(super) fn count(&self) -> usize {
        self.links.len()
    }
}

impl ConstrainedSolver {
    /// Sets the tethers (replacing any before; all holding, all slack). Refuses a node out of range, a non-finite
    /// weight or anchor, a weight sum off 1 by more than 1e-9, or a rest length or stiffness not > 0.
    pub fn set_tethers(&mut self, links: &[Tether]) -> Result<(), FemError> {
        let count = self.model.mesh.node_count();
        for (index, t) in links.iter().enumerate() {
            for end in &t.ends {
                match end {
                    TetherEnd::Tissue { nodes, weights } => {
                        if let Some(&node) = nodes.iter().find(|&&n| n as usize >= count) {
                            return Err(FemError::NodeOutOfRange { what: "tether", node, count });
                        }
                        let sum: f64 = weights.iter().sum();
                        if !weights.iter().all(|w| w.is_finite()) || (sum - 1.0).abs() > 1e-9 {
                            return Err(FemError::InvalidConstraint { index, node: nodes[0], reason: "tether weights must be finite and sum to 1" });
                        }
                    }
                    TetherEnd::Anchor { point } => {
                        if !is_finite3(point) {
                            return Err(FemError::InvalidConstraint { index, node: u32::MAX, reason: "tether anchor is not finite" });
                        }
                    }
                }
            }
            if !(t.rest_length.is_finite() && t.rest_length > 0.0 && t.stiffness.is_finite() && t.stiffness > 0.0) {
                return Err(FemError::InvalidConstraint { index, node: u32::MAX, reason: "tether rest length and stiffness must be finite and > 0" });
            }
        }
        let n = links.len();
        self.tethers = TetherSet {
            links: links.to_vec(),
            enabled: vec![true; n],
            active: vec![false; n],
            linear: vec![LinearTether::default(); n],
            rows: Vec::new(),
            tension: vec![0.0; n],
            columns: vec![None; n],
            columns_tried: vec![false; n],
            columns_bytes: 0,
            pulls: Vec::new(),
        };
        Ok(())
    }

    /// Takes link `index` out of the solve from the next frame on (torn or cut), or puts it back.
    pub fn set_tether_enabled(&mut self, index: usize, enabled: bool) {
        if let Some(e) = self.tethers.enabled.get_mut(index) {
            *e = enabled;
            if !enabled {
                self.tethers.active[index] = false;
            }
        }
    }

    /// The tethers as set.
    pub fn tethers(&self) -> &[Tether] {
        &self.tethers.links
    }

    /// Every node a tether end is tied to (ascending, no repeats), for a caller that wants them in the ROI.
    pub fn tether_nodes(links: &[Tether]) -> Vec<u32> {
        let mut nodes: Vec<u32> = links
            .iter()
            .flat_map(|t| t.ends.iter())
            .filter_map(|e| match e {
                TetherEnd::Tissue { nodes, .. } => Some(*nodes),
                TetherEnd::Anchor { .. } => None,
            })
            .flatten()
            .collect();
        nodes.sort_unstable();
        nodes.dedup();
        nodes
    }

    /// The displacement a frame starts from at `node`: its row's last value, a far vertex's as last brought up to
    /// date, or gravity's.
    fn start_displacement(&self, node: u32) -> Vec3 {
        match (self.compliance.row_of(node), self.model.surface.node_to_vertex.get(node as usize)) {
            (Some(r), _) => self.surface.prev_u_rows[r],
            (None, Some(&k)) => self.surface.held.get(k as usize).copied().unwrap_or_else(|| self.model.gravity_displacement(node)),
            (None, None) => self.model.gravity_displacement(node),
        }
    }

    /// An end's position at rest and at the frame's start (m).
    fn end_positions(&self, end: &TetherEnd) -> (Vec3, Vec3) {
        match *end {
            TetherEnd::Anchor { point } => (point, point),
            TetherEnd::Tissue { nodes, weights } => {
                let (mut rest, mut now) = (Vec3::zeros(), Vec3::zeros());
                for (&n, &w) in nodes.iter().zip(&weights) {
                    let x = self.model.mesh.positions[n as usize];
                    rest += x * w;
                    now += (x + self.start_displacement(n)) * w;
                }
                (rest, now)
            }
        }
    }

    /// Linearizes every holding link at the frame's start positions (module doc), and makes sure the nodes of
    /// the links have K^-1 columns or rows to be evaluated with.
    pub(super) fn linearize_tethers(&mut self) -> Result<(), FemError> {
        if !self.tethers.any() {
            return Ok(());
        }
        let mut extra: Vec<u32> = Vec::new();
        let mut made = 0;
        for i in 0..self.tethers.links.len() {
            if !self.tethers.enabled[i] {
                continue;
            }
            let link = self.tethers.links[i];
            let (rest_a, now_a) = self.end_positions(&link.ends[0]);
            let (rest_b, now_b) = self.end_positions(&link.ends[1]);
            let span = now_b - now_a;
            let rest_span = rest_b - rest_a;
            // Coincident ends have no direction: the rest one, else +z.
            let n = if span.norm() > 0.0 {
                span.normalize()
            } else if rest_span.norm() > 0.0 {
                rest_span.normalize()
            } else {
                Vec3::z()
            };
            let mut lin = LinearTether { target: n.dot(&rest_span) - link.rest_length, dir: n, ..Default::default() };
            for (end, sign) in link.ends.iter().zip([1.0, -1.0]) {
                if let TetherEnd::Tissue { nodes, weights } = *end {
                    for (&node, &w) in nodes.iter().zip(&weights) {
                        if self.model.is_fixed(node) || w == 0.0 {
                            continue;
                        }
                        lin.terms[lin.count] = (node, n * (sign * w));
                        lin.count += 1;
                        if self.compliance.row_of(node).is_none() {
                            extra.push(node);
                        }
                    }
                }
            }
            self.tethers.linear[i] = lin;
            let bytes = 72 * self.compliance.row_nodes().len();
            if !self.tethers.columns_tried[i]
                && made < COLUMNS_PER_STEP
                && self.tethers.columns_bytes + bytes <= COLUMNS_MAX_BYTES
                && self.tuning.enabled(Optimisation::TetherColumns)
            {
                self.tethers.columns_tried[i] = true;
                self.tethers.columns[i] = self.make_tether_columns(&link);
                if self.tethers.columns[i].is_some() {
                    self.tethers.columns_bytes += bytes;
                }
                made += 1;
            }
        }
        self.ensure_lazy(&extra)
    }

    /// [`TetherColumns`] of `link` from the ROI columns of its nodes: on the ROI rows the exact blocks W is made
    /// of, on the others the blocks the surface product reads; `None` when a free node of it has no ROI column or
    /// a column cannot be read.
    fn make_tether_columns(&self, link: &Tether) -> Option<TetherColumns> {
        let mut forces: Vec<(usize, f64)> = Vec::new();
        for (end, sign) in link.ends.iter().zip([1.0, -1.0]) {
            if let TetherEnd::Tissue { nodes, weights } = *end {
                for (&node, &w) in nodes.iter().zip(&weights) {
                    if self.model.is_fixed(node) || w == 0.0 {
                        continue;
                    }
                    let col = self.compliance.col_of(node)?;
                    self.compliance.wait_column(col).ok()?;
                    forces.push((col, sign * w));
                }
            }
        }
        let row_nodes = self.compliance.row_nodes();
        let mut m = vec![0.0; 9 * row_nodes.len()];
        for (r, &node) in row_nodes.iter().enumerate() {
            let roi = self.compliance.col_of(node).is_some();
            let mut block = Matrix3::zeros();
            for &(c, sw) in &forces {
                let b = if roi {
                    self.compliance.wait_column(r.min(c)).ok()?;
                    self.compliance.block(r, c)
                } else {
                    self.compliance.product_block(r, c)
                };
                block += b * sw;
            }
            m[9 * r..9 * r + 9].copy_from_slice(&[block[(0, 0)], block[(0, 1)], block[(0, 2)], block[(1, 0)], block[(1, 1)], block[(1, 2)], block[(2, 0)], block[(2, 1)], block[(2, 2)]]);
        }
        Some(TetherColumns { m })
    }

    /// The columns of link `i` when it has them and every node in `nodes` is an ROI node (where they are exact).
    fn columns_for(&self, i: usize, nodes: impl IntoIterator<Item = u32>) -> Option<&TetherColumns> {
        let c = self.tethers.columns[i].as_ref()?;
        nodes.into_iter().all(|n| self.model.is_fixed(n) || self.compliance.col_of(n).is_some()).then_some(c)
    }

    /// `K^-1[node, ..] c_i^T` of link `i` (its row's column at `node`), from its columns at an ROI node, else node
    /// by node.
    fn tether_column_at(&self, i: usize, node: u32) -> Vec3 {
        if self.model.is_fixed(node) {
            return Vec3::zeros();
        }
        let lin = &self.tethers.linear[i];
        match (self.tethers.columns[i].as_ref(), self.compliance.col_of(node)) {
            (Some(c), Some(r)) => c.apply(r, &lin.dir),
            _ => lin.terms().iter().filter(|(n, _)| !self.model.is_fixed(*n)).map(|(n, coeff)| self.kinv(node, *n) * coeff).sum(),
        }
    }

    /// The displacement at `node` from this iteration's pulls of links with columns (the rest are node forces):
    /// read from the columns at an ROI node, else node by node.
    pub(super) fn tether_pull_at(&self, node: u32) -> Vec3 {
        let mut u = Vec3::zeros();
        if self.tethers.pulls.is_empty() || self.model.is_fixed(node) {
            return u;
        }
        match self.compliance.col_of(node) {
            Some(r) => {
                for (i, f) in &self.tethers.pulls {
                    if let Some(c) = &self.tethers.columns[*i] {
                        u += c.apply(r, f);
                    }
                }
            }
            None => {
                for &(i, f) in &self.tethers.pulls {
                    let lin = &self.tethers.linear[i];
                    let tension = f.dot(&lin.dir);
                    for (n, coeff) in lin.terms() {
                        if !self.model.is_fixed(*n) {
                            u += self.kinv(node, *n) * (coeff * tension);
                        }
                    }
                }
            }
        }
        u
    }

    /// `u[r] += M_i[r] (T n)` over every stored row for this iteration's pulls of links with columns.
    pub(super) fn add_tether_pulls(&self, u: &mut [Vec3]) {
        for (i, f) in &self.tethers.pulls {
            if let Some(c) = &self.tethers.columns[*i] {
                for (r, x) in u.iter_mut().enumerate() {
                    *x += c.apply(r, f);
                }
            }
        }
    }

    /// Appends a row for every active link, giving its nodes slots in `sys.nodes`.
    pub(super) fn build_tether_rows(&mut self) {
        self.tethers.rows.clear();
        for i in 0..self.tethers.links.len() {
            if !(self.tethers.enabled[i] && self.tethers.active[i]) || self.tethers.linear[i].count == 0 {
                continue;
            }
            let mut slots = [0usize; TERMS];
            for (k, &(node, _)) in self.tethers.linear[i].terms().iter().enumerate() {
                slots[k] = match self.sys.nodes.iter().position(|&n| n == node) {
                    Some(p) => p,
                    None => {
                        self.sys.nodes.push(node);
                        self.sys.nodes.len() - 1
                    }
                };
            }
            self.tethers.rows.push((i, slots));
        }
    }

    /// `K^-1` between two nodes applied as `a . K^-1[p, q] b`, or zero where either is fixed.
    fn kinv_dot(&self, p: u32, a: &Vec3, q: u32, b: &Vec3) -> f64 {
        if self.model.is_fixed(p) || self.model.is_fixed(q) {
            return 0.0;
        }
        a.dot(&(self.kinv(p, q) * b))
    }

    /// Fills the tether rows' part of `w_es` (against the enforced rows) and `w_ss` (against the candidate rows,
    /// which come first in the s block, and among themselves, with `1 / k` on the diagonal). With `pairs`, the
    /// entries between s rows are read from / kept in the step's [`RowPairs`] (`slots`: each s row's slot).
    pub(super) fn gather_tether_rows(&self, e: usize, s: usize, w_es: &mut [f64], w_ss: &mut [f64], mut pairs: Option<(&mut RowPairs, &[usize])>) {
        let s_c = s - self.tethers.rows.len();
        for (k, &(i, _)) in self.tethers.rows.iter().enumerate() {
            let t = s_c + k;
            let terms = self.tethers.linear[i].terms();
            for l in 0..self.tools.enforced_nodes {
                let q = self.sys.nodes[l];
                let v = self.tether_column_at(i, q);
                for c in 0..3 {
                    w_es[t * e + 3 * l + c] = v[c];
                }
            }
            let mut entry = |u: usize, compute: &dyn Fn() -> f64| match pairs.as_mut() {
                Some((p, slots)) => p.get_or(slots[t], slots[u], compute),
                None => compute(),
            };
            let columns = self.columns_for(i, std::iter::empty());
            for u in 0..s_c {
                let row = self.sys.rows[e + u];
                let p = self.sys.nodes[row.slot];
                let value = entry(u, &|| match columns.filter(|_| self.compliance.col_of(p).is_some()) {
                    Some(_) => row.dir.dot(&self.tether_column_at(i, p)),
                    None => terms.iter().map(|(node, coeff)| self.kinv_dot(p, &row.dir, *node, coeff)).sum(),
                });
                w_ss[u * s + t] = value;
                w_ss[t * s + u] = value;
            }
            for (m, &(j, _)) in self.tethers.rows[..=k].iter().enumerate() {
                let other = self.tethers.linear[j].terms();
                let u = s_c + m;
                let mut value = entry(u, &|| match self.columns_for(i, other.iter().map(|x| x.0)) {
                    Some(_) => other.iter().map(|(b, cb)| cb.dot(&self.tether_column_at(i, *b))).sum(),
                    None => terms.iter().map(|(a, ca)| other.iter().map(|(b, cb)| self.kinv_dot(*a, ca, *b, cb)).sum::<f64>()).sum(),
                });
                if u == t {
                    value += 1.0 / self.tethers.links[i].stiffness;
                }
                w_ss[u * s + t] = value;
                w_ss[t * s + u] = value;
            }
        }
    }

    /// The tether rows' right-hand sides `target - c . u0`, appended to `rhs`.
    pub(super) fn tether_rhs(&self, rhs: &mut Vec<f64>) {
        for &(i, _) in &self.tethers.rows {
            let lin = &self.tethers.linear[i];
            let cu0: f64 = lin.terms().iter().map(|(node, coeff)| coeff.dot(&self.model.gravity_displacement(*node))).sum();
            rhs.push(lin.target - cu0);
        }
    }

    /// Adds the tether rows' forces `coeff * T` to their nodes' slots; a link without columns adds them to the
    /// direct forces too, one with columns its pull `T n` to [`TetherSet::pulls`].
    pub(super) fn add_tether_forces(&mut self, first_row: usize) {
        self.tethers.pulls.clear();
        for (k, &(i, slots)) in self.tethers.rows.iter().enumerate() {
            let tension = self.sys.lambda[first_row + k];
            let columns = self.tethers.columns[i].is_some();
            if columns {
                self.tethers.pulls.push((i, self.tethers.linear[i].dir * tension));
            }
            for (&(_, coeff), &slot) in self.tethers.linear[i].terms().iter().zip(&slots) {
                self.sys.node_force[slot] += coeff * tension;
                if !columns {
                    self.sys.direct_force[slot] += coeff * tension;
                }
            }
        }
    }

    /// Activates every holding slack link the current solution stretches past its rest length; returns (any
    /// activated, the largest such extension, m).
    pub(super) fn evaluate_tethers(&mut self) -> (bool, f64) {
        let mut any = false;
        let mut worst: f64 = 0.0;
        for i in 0..self.tethers.links.len() {
            if !self.tethers.enabled[i] || self.tethers.active[i] || self.tethers.linear[i].count == 0 {
                continue;
            }
            let lin = self.tethers.linear[i];
            let cu: f64 = lin.terms().iter().map(|(node, coeff)| coeff.dot(&self.displacement_of(*node))).sum();
            let extension = lin.target - cu;
            let tol = CONTACT_TOLERANCE_M + CONTACT_TOLERANCE * self.tethers.links[i].rest_length;
            if extension > tol {
                self.tethers.active[i] = true;
                any = true;
                worst = worst.max(extension);
            }
        }
        (any, worst)
    }

    /// The most compressive active tether row (T < 0 would push), if any: (its link, its T).
    pub(super) fn most_compressive_tether(&self, first_row: usize, scale: f64) -> Option<(usize, f64)> {
        let mut most: Option<(usize, f64)> = None;
        for (k, &(i, _)) in self.tethers.rows.iter().enumerate() {
            let l = self.sys.lambda[first_row + k];
            if l < -1e-12 * scale && most.is_none_or(|(_, m)| l < m) {
                most = Some((i, l));
            }
        }
        most
    }

    /// Releases every active tether row that would push (T < 0); returns whether any.
    pub(super) fn release_compressive_tethers(&mut self, first_row: usize, scale: f64) -> bool {
        let mut any = false;
        for k in 0..self.tethers.rows.len() {
            let (i, _) = self.tethers.rows[k];
            if self.sys.lambda[first_row + k] < -1e-12 * scale {
                self.tethers.active[i] = false;
                any = true;
            }
        }
        any
    }

    /// Releases link `i` (slack: no row until stretched again).
    pub(super) fn release_tether(&mut self, i: usize) {
        self.tethers.active[i] = false;
    }

    /// Each link's tension at the end of the frame, N (zero when slack or no longer holding; a link whose every
    /// node is fixed has no row: `k max(0, e)` at its start positions).
    pub(super) fn write_tether_tensions(&mut self, first_row: usize, out: &mut Vec<f64>) {
        let t = &mut self.tethers;
        t.tension.iter_mut().for_each(|x| *x = 0.0);
        for (k, &(i, _)) in t.rows.iter().enumerate() {
            t.tension[i] = self.sys.lambda[first_row + k];
        }
        for i in 0..t.links.len() {
            if t.enabled[i] && t.linear[i].count == 0 {
                t.tension[i] = t.links[i].stiffness * t.linear[i].target.max(0.0);
            }
        }
        out.clear();
        out.extend_from_slice(&t.tension);
    }
}
