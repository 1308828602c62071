//! Forced columns projected on their one direction, kept from call to call ([`ProjectedStore`]): the surface
//! product's third of the memory traffic for a node held by a single row.
//!
//! A node a blade rests on by one face-plane row carries the force `F = n lambda` along the face's normal `n`, and
//! adds `K^-1[rows, c] n lambda` to the surface: with `P = K^-1[rows, c] n` (3 values a row instead of a 3x3 block)
//! kept while the node stays forced along the same `n`, a frame streams a third of the bytes. A blade that holds
//! or slides without turning keeps its normals frame after frame; one that turns changes them every frame, and
//! building `P` would cost more than the plain product, so a column is projected only from the second call in a
//! row that forces it along the same normal (the first takes the 3x3 blocks), and at most
//! [`PROJECTIONS_PER_CALL`] anew a call. The rule depends on the calls
//! before, never on timing: replays stay bit for bit the same. `P` rounds differently from the blocks times `F`,
//! so the surface's last bits differ from the plain product's (the contact forces do not: they come before it).
//! Stays true: in a steady state nothing is allocated (vectors are reused).

use super::Layout;
use super::product::Entry;
use crate::math::Vec3;

/// At most this many columns are projected anew in one call; the others wait for a later one on the 3x3 blocks. A
/// projection reads the whole column (its upper part strided), about 50 us on the refined default scene: a blade
/// settling on 150 vertices at once would otherwise spend 7 ms of one frame on them.
pub const PROJECTIONS_PER_CALL: usize = 16;

/// A direction by its bits (a normal is the same when its bits are).
pub(super) type DirBits = [u64; 3];

fn bits(n: &Vec3) -> DirBits {
    [n.x.to_bits(), n.y.to_bits(), n.z.to_bits()]
}

/// The projected columns of the last call, ascending, and those asked for along a direction but not yet projected.
#[derive(Debug, Default)]
pub(super) struct ProjectedStore {
    cols: Vec<(usize, DirBits)>,
    /// `vals[k]` = `K^-1[rows of the component, cols[k]] n`: 3 values a row, the component's ROI rows, then its
    /// other rows.
    pub(super) vals: Vec<Vec<f64>>,
    /// (column, direction) asked in the last call and taken by the blocks.
    pending: Vec<(usize, DirBits)>,
    next_cols: Vec<(usize, DirBits)>,
    next_vals: Vec<Vec<f64>>,
    next_pending: Vec<(usize, DirBits)>,
    spare: Vec<Vec<f64>>,
    /// Columns projected anew in the last call.
    pub(super) built: usize,
}

impl ProjectedStore {
    pub(super) fn clear(&mut self) {
        self.spare.append(&mut self.vals);
        self.cols.clear();
        self.pending.clear();
    }

    pub(super) fn bytes(&self) -> usize {
        8 * self.vals.iter().chain(&self.spare).map(Vec::capacity).sum::<usize>()
    }

    /// Splits `along` (`(column, unit n, lambda)`, ascending, none in `forces`) into the columns projected this call
    /// (`proj`: `(column, lambda)`, in the order of [`Self::vals`]) and those taken by the blocks (merged into `full`
    /// with `forces`, as `n lambda`), building the newly projected ones from the storage.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn prepare<'a, T: Entry + 'a>(
        &mut self,
        region: &impl Fn(usize) -> (&'a [T], usize),
        layout: &Layout,
        along: &[(usize, Vec3, f64)],
        forces: &[(usize, Vec3)],
        full: &mut Vec<(usize, Vec3)>,
        proj: &mut Vec<(usize, f64)>,
    ) {
        self.next_cols.clear();
        self.next_pending.clear();
        full.clear();
        proj.clear();
        self.built = 0;
        let mut k = 0;
        for &(c, n, lambda) in along {
            let key = (c, bits(&n));
            while k < self.cols.len() && self.cols[k].0 < c {
                self.spare.push(std::mem::take(&mut self.vals[k]));
                k += 1;
            }
            let kept = k < self.cols.len() && self.cols[k] == key;
            let vals = if kept {
                k += 1;
                Some(std::mem::take(&mut self.vals[k - 1]))
            } else if self.built < PROJECTIONS_PER_CALL && self.pending.binary_search(&key).is_ok() {
                let mut v = self.spare.pop().unwrap_or_default();
                project(region, layout, c, &n, &mut v);
                self.built += 1;
                Some(v)
            } else {
                None
            };
            match vals {
                Some(v) => {
                    self.next_cols.push(key);
                    self.next_vals.push(v);
                    proj.push((c, lambda));
                }
                None => {
                    self.next_pending.push(key);
                    full.push((c, n * lambda));
                }
            }
        }
        for v in &mut self.vals[k..] {
            self.spare.push(std::mem::take(v));
        }
        self.vals.clear();
        std::mem::swap(&mut self.cols, &mut self.next_cols);
        std::mem::swap(&mut self.vals, &mut self.next_vals);
        std::mem::swap(&mut self.pending, &mut self.next_pending);
        if !full.is_empty() {
            full.extend_from_slice(forces);
            full.sort_unstable_by_key(|f| f.0);
        } else {
            full.extend_from_slice(forces);
        }
    }
}

/// `out` = `K^-1[rows of c's component, c] n`, 3 values a row: the ROI rows (those before `c` from the stored row
/// of `c`, transposed blocks; from `c` on its own column), then the component's other rows.
fn project<'a, T: Entry + 'a>(region: &impl Fn(usize) -> (&'a [T], usize), layout: &Layout, c: usize, n: &Vec3, out: &mut Vec<f64>) {
    let k = layout.row_comp[c] as usize;
    let s = layout.spans[k];
    out.clear();
    out.reserve(3 * (s[1] - s[0] + s[3] - s[2]));
    let (v, base) = region(k);
    let block = |o: usize| -> [f64; 9] { std::array::from_fn(|e| v[(o - base) * 9 + e].f()) };
    let (nx, ny, nz) = (n.x, n.y, n.z);
    for i in s[0]..c {
        // block (row c, column i) holds K^-1[3i + j, 3c + r] at 3r + j
        let b = block(layout.col_off[i] + c - i);
        for row in 0..3 {
            out.push(b[3 * row] * nx + b[3 * row + 1] * ny + b[3 * row + 2] * nz);
        }
    }
    let lower = |i: usize| if i < s[1] { layout.col_off[c] + i - c } else { layout.col_off[c] + (s[1] - c) + (i - s[2]) };
    for i in (c..s[1]).chain(s[2]..s[3]) {
        // block (row i, column c) holds K^-1[3i + r, 3c + j] at 3j + r
        let b = block(lower(i));
        for row in 0..3 {
            out.push(b[row] * nx + b[3 + row] * ny + b[6 + row] * nz);
        }
    }
}
