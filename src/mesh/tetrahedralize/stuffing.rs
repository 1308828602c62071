//! Isosurface stuffing on a uniform body-centred-cubic (BCC) lattice
//! (Labelle & Shewchuk, SIGGRAPH 2007), the phases in order:
//! lattice and values -> cut points -> warping -> stencils -> compaction.
//!
//! In: a cutting function `f` (negative inside), a box, the lattice spacing `h`.
//! Out: nodes and positively oriented tets filling `{f < 0}` up to the lattice
//! resolution. Stays true: every phase iterates in lattice-index order and
//! `f` is only ever evaluated at points that depend on the input, so the same
//! input gives a bitwise-identical mesh whatever the thread count.
//!
//! Lattice, in doubled integer coordinates: corner vertices have all-even
//! coordinates, centre vertices all-odd ones; the point of coordinate `c` is
//! `origin + c * h / 2`. Black edges join two vertices of the same grid (length
//! `h`), red edges a corner to a centre (length `h * sqrt(3) / 2`). Each BCC tet
//! is one corner black edge plus the centre black edge opposite it.

use std::collections::HashMap;

use crate::math::Vec3;

/// Warping parameter on black (long) edges: the paper's pair for 10.7°..164.8°.
pub const ALPHA_LONG: f64 = 0.24999;
/// Warping parameter on red (short) edges: the paper's pair for 10.7°..164.8°.
pub const ALPHA_SHORT: f64 = 0.41189;

/// The uniform BCC lattice covering a box.
pub(crate) struct Lattice {
    pub origin: Vec3,
    pub h: f64,
    /// Cubes per axis.
    pub n: [usize; 3],
}

impl Lattice {
    pub fn corner_count(&self) -> usize {
        (self.n[0] + 1) * (self.n[1] + 1) * (self.n[2] + 1)
    }

    pub fn vertex_count(&self) -> usize {
        self.corner_count() + self.n[0] * self.n[1] * self.n[2]
    }

    fn corner(&self, i: usize, j: usize, k: usize) -> u32 {
        (i + (self.n[0] + 1) * (j + (self.n[1] + 1) * k)) as u32
    }

    fn centre(&self, i: usize, j: usize, k: usize) -> u32 {
        (self.corner_count() + i + self.n[0] * (j + self.n[1] * k)) as u32
    }

    /// Doubled integer coordinates of a lattice vertex.
    pub fn coord(&self, id: u32) -> [i64; 3] {
        let id = id as usize;
        let cc = self.corner_count();
        if id < cc {
            let (nx, ny) = (self.n[0] + 1, self.n[1] + 1);
            [(id % nx) as i64 * 2, ((id / nx) % ny) as i64 * 2, (id / (nx * ny)) as i64 * 2]
        } else {
            let r = id - cc;
            let (nx, ny) = (self.n[0], self.n[1]);
            [(r % nx) as i64 * 2 + 1, ((r / nx) % ny) as i64 * 2 + 1, (r / (nx * ny)) as i64 * 2 + 1]
        }
    }

    pub fn position(&self, id: u32) -> Vec3 {
        let c = self.coord(id);
        self.origin + Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64) * (0.5 * self.h)
    }

    /// Every BCC tet, in a fixed order: corner black edges by (axis, corner),
    /// then the four centre edges around each.
    pub fn tets(&self) -> Vec<[u32; 4]> {
        let n = self.n;
        let mut out = Vec::with_capacity(12 * n[0] * n[1] * n[2]);
        for axis in 0..3 {
            let (b, d) = ((axis + 1) % 3, (axis + 2) % 3);
            for k in 0..=n[2] {
                for j in 0..=n[1] {
                    for i in 0..=n[0] {
                        let c = [i, j, k];
                        // The edge needs its far end, and all four cubes around it.
                        if c[axis] >= n[axis] || c[b] == 0 || c[b] >= n[b] || c[d] == 0 || c[d] >= n[d] {
                            continue;
                        }
                        let mut e = c;
                        e[axis] += 1;
                        let p0 = self.corner(c[0], c[1], c[2]);
                        let p1 = self.corner(e[0], e[1], e[2]);
                        // Cube lower corners around the edge, in cyclic order.
                        let ring = [(c[b] - 1, c[d] - 1), (c[b], c[d] - 1), (c[b], c[d]), (c[b] - 1, c[d])];
                        let centres = ring.map(|(ub, ud)| {
                            let mut q = c;
                            q[b] = ub;
                            q[d] = ud;
                            self.centre(q[0], q[1], q[2])
                        });
                        for q in 0..4 {
                            out.push([p0, p1, centres[q], centres[(q + 1) % 4]]);
                        }
                    }
                }
            }
        }
        out
    }

    /// True for an edge between two vertices of the same grid.
    pub fn is_black(&self, a: u32, b: u32) -> bool {
        let cc = self.corner_count() as u32;
        (a < cc) == (b < cc)
    }
}

/// A cut point: where `f` changes sign on the lattice edge (a, b).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Cut {
    pub a: u32,
    pub b: u32,
    /// Fraction of the edge from `a`, in (0, 1).
    pub t: f64,
    pub position: Vec3,
    pub black: bool,
}

/// Evaluates `f` at every item, split over the available threads; the result
/// does not depend on the split.
pub(crate) fn evaluate_parallel<T: Sync, R: Send + Copy + Default>(
    items: &[T],
    eval: &(dyn Fn(&T) -> R + Sync),
) -> Vec<R> {
    let threads = std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1).clamp(1, 8);
    let mut out = vec![R::default(); items.len()];
    if threads == 1 || items.len() < 4096 {
        for (o, it) in out.iter_mut().zip(items) {
            *o = eval(it);
        }
        return out;
    }
    let chunk = items.len().div_ceil(threads);
    std::thread::scope(|s| {
        for (oc, ic) in out.chunks_mut(chunk).zip(items.chunks(chunk)) {
            s.spawn(move || {
                for (o, it) in oc.iter_mut().zip(ic) {
                    *o = eval(it);
                }
            });
        }
    });
    out
}

/// Root of `g` on [0, 1] where g(0) and g(1) have opposite strict signs
/// (Illinois false position, then bisection safeguard), to ~1e-7 of the edge.
pub(crate) fn edge_root(g: &dyn Fn(f64) -> f64, g0: f64, g1: f64) -> f64 {
    let (mut s0, mut s1, mut f0, mut f1) = (0.0_f64, 1.0_f64, g0, g1);
    let mut side = 0i8;
    for _ in 0..60 {
        let mut s = (s0 * f1 - s1 * f0) / (f1 - f0);
        if !(s > s0 && s < s1) {
            s = 0.5 * (s0 + s1);
        }
        let fs = g(s);
        if !fs.is_finite() || fs == 0.0 {
            return s;
        }
        if (fs < 0.0) == (f0 < 0.0) {
            s0 = s;
            f0 = fs;
            if side == -1 {
                f1 *= 0.5;
            }
            side = -1;
        } else {
            s1 = s;
            f1 = fs;
            if side == 1 {
                f0 *= 0.5;
            }
            side = 1;
        }
        if s1 - s0 < 1e-7 {
            break;
        }
    }
    (s0 * f1 - s1 * f0) / (f1 - f0)
}

/// Output of the stencil phase: tets over "virtual" node ids, lattice vertex
/// `v` as `v`, cut `c` as `vertex_count + c`.
pub(crate) struct Stuffed {
    pub positions: Vec<Vec3>,
    pub tets: Vec<[u32; 4]>,
    /// Violated vertices made zero in place instead of warped (bound repair).
    pub snapped: usize,
}

/// Runs cut points, warping, stencils and compaction on lattice values.
/// `sign` is -1 inside, +1 outside, 0 on the surface, per lattice vertex.
pub(crate) fn stuff(
    lattice: &Lattice,
    values: &[f64],
    f: &(dyn Fn(&Vec3) -> f64 + Sync),
) -> Stuffed {
    let nv = lattice.vertex_count();
    let sign: Vec<i8> = values.iter().map(|&v| if v < 0.0 { -1 } else if v > 0.0 { 1 } else { 0 }).collect();
    let bcc = lattice.tets();
    let (cut_of, cuts) = cut_edges(lattice, values, &sign, &bcc, f);
    let (position, virt, snapped) = warp_and_fill(lattice, &sign, &bcc, &cut_of, &cuts);
    let (positions, tets) = compact(&virt, nv + cuts.len(), |id| virtual_position(id, lattice, &position, &cuts));
    Stuffed { positions, tets, snapped: snapped.iter().filter(|&&s| s).count() }
}

/// The lattice edges the surface cuts (signs of opposite kind at their ends), in first-seen order over the
/// tets, keyed by their ends (lower first), and the cut point on each: the root of `f` along it.
fn cut_edges(
    lattice: &Lattice,
    values: &[f64],
    sign: &[i8],
    bcc: &[[u32; 4]],
    f: &(dyn Fn(&Vec3) -> f64 + Sync),
) -> (HashMap<(u32, u32), u32>, Vec<Cut>) {
    let mut cut_of: HashMap<(u32, u32), u32> = HashMap::new();
    let mut edges: Vec<(u32, u32)> = Vec::new();
    for t in bcc {
        for (i, j) in EDGES {
            let (a, b) = (t[i].min(t[j]), t[i].max(t[j]));
            if sign[a as usize] * sign[b as usize] < 0 {
                cut_of.entry((a, b)).or_insert_with(|| {
                    edges.push((a, b));
                    (edges.len() - 1) as u32
                });
            }
        }
    }
    let roots = evaluate_parallel(&edges, &|&(a, b): &(u32, u32)| {
        let (pa, pb) = (lattice.position(a), lattice.position(b));
        let g = |s: f64| f(&(pa + (pb - pa) * s));
        edge_root(&g, values[a as usize], values[b as usize])
    });
    let cuts = edges
        .iter()
        .zip(&roots)
        .map(|(&(a, b), &t)| {
            let t = t.clamp(1e-9, 1.0 - 1e-9);
            let (pa, pb) = (lattice.position(a), lattice.position(b));
            Cut { a, b, t, position: pa + (pb - pa) * t, black: lattice.is_black(a, b) }
        })
        .collect();
    (cut_of, cuts)
}

/// Where a virtual node is: lattice vertex `id` where it stands or where warping moved it, a cut `nv + c` at
/// its cut point.
fn virtual_position(id: u32, lattice: &Lattice, position: &[Option<Vec3>], cuts: &[Cut]) -> Vec3 {
    let nv = position.len();
    if (id as usize) < nv {
        position[id as usize].unwrap_or_else(|| lattice.position(id))
    } else {
        cuts[id as usize - nv].position
    }
}

/// Warping and stencils, repeated while a stencil tet breaks the bound: the warped vertices of such a lattice
/// tet are then "snapped" instead (made zero where they stand) and everything is redone. Snapped vertices only
/// accumulate, so this ends; with none snapped it is the paper's algorithm. Returns the warped positions, the
/// stencils' tets over virtual ids, and which vertices were snapped.
fn warp_and_fill(
    lattice: &Lattice,
    sign: &[i8],
    bcc: &[[u32; 4]],
    cut_of: &HashMap<(u32, u32), u32>,
    cuts: &[Cut],
) -> (Vec<Option<Vec3>>, Vec<[u32; 4]>, Vec<bool>) {
    let nv = lattice.vertex_count();
    let mut incident: Vec<(u32, u32)> = Vec::with_capacity(cuts.len() * 2);
    for (c, cut) in cuts.iter().enumerate() {
        incident.push((cut.a, c as u32));
        incident.push((cut.b, c as u32));
    }
    incident.sort_unstable();
    let cut_node = |a: u32, b: u32| -> u32 {
        let key = (a.min(b), a.max(b));
        nv as u32 + cut_of[&key]
    };
    let mut snapped = vec![false; nv];
    let mut rounds = 0;
    loop {
        rounds += 1;
        let (position, zero) = warp(cuts, &incident, &snapped, nv);
        let state: Vec<i8> = (0..nv).map(|v| if zero[v] { 0 } else { sign[v] }).collect();
        let pos_of = |id: u32| virtual_position(id, lattice, &position, cuts);
        let mut virt: Vec<[u32; 4]> = Vec::new();
        let mut repaired = false;
        for t in bcc {
            let before = virt.len();
            fill(lattice, t, &state, &cut_node, &pos_of, &mut virt);
            let bad = virt[before..].iter().any(|tet| {
                let (lo, hi) = super::dihedral_range_deg(&tet.map(|v| pos_of(v)));
                !(lo >= super::MIN_DIHEDRAL_DEG && hi <= super::MAX_DIHEDRAL_DEG)
            });
            if bad {
                for &v in t {
                    if position[v as usize].is_some() && !snapped[v as usize] {
                        snapped[v as usize] = true;
                        repaired = true;
                    }
                }
            }
        }
        if !repaired || rounds >= 16 {
            return (position, virt, snapped);
        }
    }
}

/// Compaction: the used lattice vertices ascending, then the used cuts ascending; each tet positively oriented.
fn compact(virt: &[[u32; 4]], total: usize, pos_of: impl Fn(u32) -> Vec3) -> (Vec<Vec3>, Vec<[u32; 4]>) {
    let mut remap = vec![u32::MAX; total];
    for tet in virt {
        for &v in tet {
            remap[v as usize] = 0;
        }
    }
    let mut positions = Vec::new();
    for (id, slot) in remap.iter_mut().enumerate() {
        if *slot == 0 {
            *slot = positions.len() as u32;
            positions.push(pos_of(id as u32));
        }
    }
    let tets = virt
        .iter()
        .map(|t| {
            let mut m = t.map(|v| remap[v as usize]);
            let [a, b, c, d] = m.map(|k| positions[k as usize]);
            if crate::mesh::signed_volume(&a, &b, &c, &d) < 0.0 {
                m.swap(2, 3);
            }
            m
        })
        .collect();
    (positions, tets)
}

/// Warping: a vertex violated by a cut point (closer than alpha times the edge)
/// moves to its closest violating cut point and becomes zero; the cut points on
/// its edges are dropped. Vertices in lattice order. A `snapped` vertex that is
/// violated becomes zero where it stands. Returns (moved position, zero flag).
fn warp(cuts: &[Cut], incident: &[(u32, u32)], snapped: &[bool], nv: usize) -> (Vec<Option<Vec3>>, Vec<bool>) {
    let mut position: Vec<Option<Vec3>> = vec![None; nv];
    let mut zero = vec![false; nv];
    let mut i = 0;
    while i < incident.len() {
        let v = incident[i].0;
        let mut j = i;
        let mut best: Option<(f64, u32)> = None;
        while j < incident.len() && incident[j].0 == v {
            let c = incident[j].1;
            let cut = &cuts[c as usize];
            let other = if cut.a == v { cut.b } else { cut.a };
            if !zero[other as usize] {
                let frac = if cut.a == v { cut.t } else { 1.0 - cut.t };
                let alpha = if cut.black { ALPHA_LONG } else { ALPHA_SHORT };
                if frac < alpha {
                    let length = if cut.black { 1.0 } else { 0.75_f64.sqrt() };
                    let d = frac * length;
                    if best.is_none_or(|(bd, _)| d < bd) {
                        best = Some((d, c));
                    }
                }
            }
            j += 1;
        }
        if let Some((_, c)) = best {
            zero[v as usize] = true;
            if !snapped[v as usize] {
                position[v as usize] = Some(cuts[c as usize].position);
            }
        }
        i = j;
    }
    (position, zero)
}

/// The stencils: the part of lattice tet `t` inside the surface, by the signs
/// of its vertices after warping (-1 inside, 0 on, +1 outside).
fn fill(
    lattice: &Lattice,
    t: &[u32; 4],
    state: &[i8],
    cut_node: &dyn Fn(u32, u32) -> u32,
    pos_of: &dyn Fn(u32) -> Vec3,
    out: &mut Vec<[u32; 4]>,
) {
    let s = t.map(|v| state[v as usize]);
    let ins: Vec<u32> = (0..4).filter(|&k| s[k] < 0).map(|k| t[k]).collect();
    let outs: Vec<u32> = (0..4).filter(|&k| s[k] > 0).map(|k| t[k]).collect();
    let zeros: Vec<u32> = (0..4).filter(|&k| s[k] == 0).map(|k| t[k]).collect();
    match (ins.len(), outs.len()) {
        // No inside vertex (all four on the surface included: such a tet is
        // flattened onto the surface and is not part of the stencils).
        (0, _) => {}
        (_, 0) => out.push(*t),
        (1, _) => {
            let a = ins[0];
            let mut tet = [a, 0, 0, 0];
            let mut k = 1;
            for &z in &zeros {
                tet[k] = z;
                k += 1;
            }
            for &o in &outs {
                tet[k] = cut_node(a, o);
                k += 1;
            }
            out.push(tet);
        }
        (2, 1) => {
            // Pyramid: apex the zero vertex, base quad (a, b, c(b,o), c(a,o)).
            let (a, b, o, z) = (ins[0], ins[1], outs[0], zeros[0]);
            let (ca, cb) = (cut_node(a, o), cut_node(b, o));
            if diagonal_from_first(lattice, a, b, o) {
                out.push([z, a, b, cb]);
                out.push([z, a, cb, ca]);
            } else {
                out.push([z, a, b, ca]);
                out.push([z, b, cb, ca]);
            }
        }
        (2, 2) => {
            // Prism: columns a->b, c(a,o1)->c(b,o1), c(a,o2)->c(b,o2).
            let (a, b, o1, o2) = (ins[0], ins[1], outs[0], outs[1]);
            let bottom = [a, cut_node(a, o1), cut_node(a, o2)];
            let top = [b, cut_node(b, o1), cut_node(b, o2)];
            // diag[q] for quad (column q, column q+1): true = bottom_q - top_{q+1}.
            let d01 = diagonal_from_first(lattice, a, b, o1);
            let d20 = !diagonal_from_first(lattice, a, b, o2);
            // Quad (1,2) lies on the surface: free; avoid a cycle, else shorter.
            let free = {
                let cyc_true = d01 && d20; // all "bottom_q - top_{q+1}" = cycle
                let cyc_false = !d01 && !d20;
                if cyc_true {
                    false
                } else if cyc_false {
                    true
                } else {
                    let l_true = (pos_of(bottom[1]) - pos_of(top[2])).norm();
                    let l_false = (pos_of(bottom[2]) - pos_of(top[1])).norm();
                    l_true <= l_false
                }
            };
            prism(&bottom, &top, [d01, free, d20], out);
        }
        (3, 1) => {
            let o = outs[0];
            let bottom = [ins[0], ins[1], ins[2]];
            let top = bottom.map(|v| cut_node(v, o));
            let d = [0, 1, 2].map(|q| diagonal_from_first(lattice, bottom[q], bottom[(q + 1) % 3], o));
            prism(&bottom, &top, d, out);
        }
        _ => unreachable!("sign counts of a tet sum to four"),
    }
}

/// The six edges of a tet by local index.
const EDGES: [(usize, usize); 6] = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)];

/// For the quad (a, b, c(b,o), c(a,o)) on the lattice face (a, b, o) with a, b
/// inside and o outside: true when its diagonal is a - c(b,o), false when it is
/// b - c(a,o). A function of the face alone, so both tets sharing the face agree.
///
/// - If (a, o) is black, the diagonal ends at the cut point on it: b - c(a,o).
/// - If (b, o) is black: a - c(b,o).
/// - Otherwise (a, b) is black, along axis k (the parity rule): with s1, s2 the
///   offsets of o from the edge in the two other axes, the diagonal leaves the
///   endpoint with the smaller k-coordinate when s1 * s2 > 0, the other one when
///   s1 * s2 < 0. This rule is invariant under the half-turn that maps each BCC
///   tet onto itself while swapping its black edges' endpoints, so the two
///   parity quads of one tet are always half-turn images of each other, the
///   configuration of the paper's stencils.
fn diagonal_from_first(lattice: &Lattice, a: u32, b: u32, o: u32) -> bool {
    if lattice.is_black(a, o) {
        return false;
    }
    if lattice.is_black(b, o) {
        return true;
    }
    let (ca, cb, co) = (lattice.coord(a), lattice.coord(b), lattice.coord(o));
    let k = (0..3).find(|&k| ca[k] != cb[k]).unwrap_or(0);
    let (k1, k2) = ((k + 1) % 3, (k + 2) % 3);
    let s = (co[k1] - ca[k1]) * (co[k2] - ca[k2]);
    let a_is_low = ca[k] < cb[k];
    if s > 0 { a_is_low } else { !a_is_low }
}

/// Splits the prism bottom[q] -> top[q] into three tets. `diag[q]` describes
/// the quad of columns q and q+1 (mod 3): true = bottom_q - top_{q+1}, false =
/// bottom_{q+1} - top_q. The three must not form a cycle.
fn prism(bottom: &[u32; 3], top: &[u32; 3], diag: [bool; 3], out: &mut Vec<[u32; 4]>) {
    // Vertex incident to the diagonals of both quads around column i:
    // bottom_i when diag[i] (bottom_i - top_{i+1}) and !diag[i-1] (bottom_i - top_{i-1});
    // top_i when !diag[i] (bottom_{i+1} - top_i) and diag[i-1] (bottom_{i-1} - top_i).
    for i in 0..3 {
        let (j, k) = ((i + 1) % 3, (i + 2) % 3);
        let prev = diag[k]; // quad (k, i)
        // quad (j, k) diagonal: true = bottom_j - top_k.
        let djk = diag[j];
        if diag[i] && !prev {
            let apex = bottom[i];
            out.push([apex, top[i], top[j], top[k]]);
            pyramid(apex, bottom[j], bottom[k], top[k], top[j], djk, out);
            return;
        }
        if !diag[i] && prev {
            let apex = top[i];
            out.push([apex, bottom[i], bottom[j], bottom[k]]);
            pyramid(apex, bottom[j], bottom[k], top[k], top[j], djk, out);
            return;
        }
    }
    unreachable!("prism diagonals form a cycle: {diag:?}");
}

/// Pyramid `apex` over the quad (bj, bk, tk, tj); `bj_tk` selects diagonal bj - tk.
fn pyramid(apex: u32, bj: u32, bk: u32, tk: u32, tj: u32, bj_tk: bool, out: &mut Vec<[u32; 4]>) {
    if bj_tk {
        out.push([apex, bj, bk, tk]);
        out.push([apex, bj, tk, tj]);
    } else {
        out.push([apex, bj, bk, tj]);
        out.push([apex, bk, tk, tj]);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn lattice(n: usize) -> Lattice {
        Lattice { origin: Vec3::zeros(), h: 1.0, n: [n, n, n] }
    }

    #[test]
    fn bcc_tets_tile_the_interior_cubes() {
        let l = lattice(4);
        let tets = l.tets();
        // Tets around interior corner edges: 3 axes * 4 * 3 * 3 edges * 4 tets.
        assert_eq!(tets.len(), 3 * 4 * 3 * 3 * 4);
        for t in &tets {
            let [a, b, c, d] = t.map(|v| l.position(v));
            let v = crate::mesh::signed_volume(&a, &b, &c, &d).abs();
            assert!((v - 1.0 / 12.0).abs() < 1e-12, "every BCC tet has volume h^3/12, got {v}");
            assert!(l.is_black(t[0], t[1]) && l.is_black(t[2], t[3]) && !l.is_black(t[0], t[2]));
        }
        let mut sorted: Vec<[u32; 4]> = tets.iter().map(|t| { let mut s = *t; s.sort(); s }).collect();
        sorted.sort();
        sorted.dedup();
        assert_eq!(sorted.len(), tets.len(), "no BCC tet is listed twice");
    }

    #[test]
    fn edge_root_finds_a_linear_zero() {
        let g = |s: f64| s - 0.3;
        assert!((edge_root(&g, -0.3, 0.7) - 0.3).abs() < 1e-9);
        let g = |s: f64| (s - 0.8) * (s + 2.0);
        assert!((edge_root(&g, g(0.0), g(1.0)) - 0.8).abs() < 1e-6);
    }

    #[test]
    fn prism_rejects_nothing_acyclic_and_covers_its_volume() {
        // A right prism: unit triangle extruded by 1, volume 0.5.
        let pts = [
            Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0),
        ];
        for mask in 0..8u8 {
            let diag = [mask & 1 != 0, mask & 2 != 0, mask & 4 != 0];
            if diag == [true; 3] || diag == [false; 3] {
                continue;
            }
            let mut out = Vec::new();
            prism(&[0, 1, 2], &[3, 4, 5], diag, &mut out);
            assert_eq!(out.len(), 3);
            let vol: f64 = out
                .iter()
                .map(|t| { let [a, b, c, d] = t.map(|k| pts[k as usize]); crate::mesh::signed_volume(&a, &b, &c, &d).abs() })
                .sum();
            assert!((vol - 0.5).abs() < 1e-12, "diagonals {diag:?} must tile the prism, volume {vol}");
        }
    }
}
