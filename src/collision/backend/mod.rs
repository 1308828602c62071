//! Ray-casting backends: for every source ray, the nearest surface triangle behind
//! (t <= 0) and in front (t > 0) along its direction, in one pass.
//!
//! In: the surface's triangles (fixed at construction) and this frame's vertex
//! positions ([`RayCaster::update_surface`]), then one [`PairLine`] per node pair.
//! Out: one [`PairHits`] per line. Stays true: every backend applies the same rule
//! ([`LineAccumulator::offer`]: nearest by |t|, an exact tie goes to the lower
//! triangle index, a hit within the contact tolerance in front counts as behind) to
//! the same f64 hits ([`crate::geometry::LineQuery`]), so `reference`, `bvh` and
//! `gpu` (which only finds candidates in f32, see `gpu.rs`) agree bit for bit.

pub mod bvh;
pub mod gpu;
pub mod reference;

use super::CollisionError;
use crate::math::Vec3;

/// One source ray: a point on a face and that face's outward unit normal (world).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SourceRay {
    /// Source node, world, metres.
    pub origin: Vec3,
    /// Face outward normal, world, unit.
    pub direction: Vec3,
}

/// The line through one node PAIR: origin at the face-0 node, direction the face-0
/// normal; the face-1 node sits at line parameter `-thickness` and looks the other way.
/// Casting the pair's one line decides every triangle once for both nodes, so the
/// triangle in front of one node and the triangle behind its partner are chosen by
/// the very same arithmetic (the paper's culling relies on that correspondence).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairLine {
    /// Face-0 node, world, metres.
    pub origin: Vec3,
    /// Face-0 outward normal, world, unit.
    pub direction: Vec3,
    /// Blade thickness, metres (> 0).
    pub thickness: f64,
}

/// A hit of one triangle: its index and the line parameters (t signed, metres).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TriangleHit {
    pub triangle: u32,
    /// Signed distance from the node along its face normal, metres (negative: behind the face).
    pub t: f64,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f64,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f64,
}

/// Nearest hit behind (t <= e: B_i) and in front (t > e: F_i) of one source node
/// (e: the contact tolerance, [`CONTACT_TOLERANCE_RELATIVE`] x thickness).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct NearestHits {
    pub behind: Option<TriangleHit>,
    pub front: Option<TriangleHit>,
}

/// The nearest hits of both nodes of a pair.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PairHits {
    pub face0: NearestHits,
    pub face1: NearestHits,
}

#[inline]
fn keep(slot: &mut Option<TriangleHit>, hit: TriangleHit, nearer: impl Fn(f64, f64) -> bool) {
    let better = match slot {
        None => true,
        Some(b) => nearer(hit.t, b.t) || (hit.t == b.t && hit.triangle < b.triangle),
    };
    if better {
        *slot = Some(hit);
    }
}

/// Contact tolerance, relative to the blade thickness: a hit less than
/// `CONTACT_TOLERANCE_RELATIVE * thickness` in front of a node counts as behind it
/// (touching, depth 0). Last frame's constraint puts contact triangles exactly on
/// the face plane, where the sign of `t` is rounding noise; without this margin such
/// a triangle flickers between "behind" (pair) and "in front" (culls its neighbours).
pub const CONTACT_TOLERANCE_RELATIVE: f64 = 1e-6;

/// Accumulates hits along one [`PairLine`], all in the line's parameter `t`
/// (face-0 node at 0, face-1 node at `-h`). Order-independent: nearest wins, an
/// exact tie goes to the lower triangle index. With `e` the contact tolerance:
/// face 0 behind is t <= e, face 1 behind is t >= -h - e.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LineAccumulator {
    h: f64,
    e: f64,
    /// Face 0 behind: largest t <= e.
    a: Option<TriangleHit>,
    /// Face 0 front: smallest t > e.
    b: Option<TriangleHit>,
    /// Face 1 behind: smallest t >= -h - e.
    c: Option<TriangleHit>,
    /// Face 1 front: largest t < -h - e.
    d: Option<TriangleHit>,
}

impl LineAccumulator {
    pub fn new(thickness: f64) -> Self {
        Self { h: thickness, e: CONTACT_TOLERANCE_RELATIVE * thickness, a: None, b: None, c: None, d: None }
    }

    /// Offers a hit at line parameter `hit.t`.
    #[inline]
    pub fn offer(&mut self, hit: TriangleHit) {
        if hit.t <= self.e {
            keep(&mut self.a, hit, |x, y| x > y);
        } else {
            keep(&mut self.b, hit, |x, y| x < y);
        }
        if hit.t >= -self.h - self.e {
            keep(&mut self.c, hit, |x, y| x < y);
        } else {
            keep(&mut self.d, hit, |x, y| x > y);
        }
    }

    /// The interval of `t` where a hit could still change the result, widened by `margin`.
    #[inline]
    pub fn needed_interval(&self, margin: f64) -> (f64, f64) {
        let lo = match (self.a, self.d) {
            (Some(a), Some(d)) => a.t.min(d.t) - margin,
            _ => f64::NEG_INFINITY,
        };
        let hi = match (self.b, self.c) {
            (Some(b), Some(c)) => b.t.max(c.t) + margin,
            _ => f64::INFINITY,
        };
        (lo, hi)
    }

    /// Per-node hits, `t` re-expressed from each node along its own normal.
    pub fn finish(&self) -> PairHits {
        let flip = |o: Option<TriangleHit>| o.map(|x| TriangleHit { t: -(x.t + self.h), ..x });
        PairHits { face0: NearestHits { behind: self.a, front: self.b }, face1: NearestHits { behind: flip(self.c), front: flip(self.d) } }
    }
}

/// A ray-casting backend.
pub trait RayCaster: Send {
    /// The backend this is.
    fn kind(&self) -> super::BackendKind;
    /// Takes this frame's vertex positions (same count and order as at construction).
    fn update_surface(&mut self, positions: &[Vec3]) -> Result<(), CollisionError>;
    /// Fills `out` (resized to `lines.len()`) with the nearest hits of both nodes of every pair.
    fn cast(&mut self, lines: &[PairLine], out: &mut Vec<PairHits>) -> Result<(), CollisionError>;
    /// Test hook: a device-backed caster fails its next cast as a lost device would
    /// and returns true; the CPU casters return false.
    #[doc(hidden)]
    fn simulate_device_loss(&mut self) -> bool {
        false
    }
    /// Where the last cast spent its time, for a device-backed caster.
    fn gpu_timings(&self) -> Option<gpu::GpuTimings> {
        None
    }
    /// Splits the work over `threads` threads where the caster can (answers never change).
    fn set_threads(&mut self, _threads: usize) {}
    /// The device's name, for a device-backed caster.
    fn device_name(&self) -> Option<String> {
        None
    }
}
