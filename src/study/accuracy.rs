//! Accuracy of a run against the study's reference run.
//!
//! In: two [`RunTrace`]s with displacements and the study's [`Motion`]. Out:
//! an [`Accuracy`]: RMS and max surface-displacement error (m), the force's
//! RMS and maximum error (% of the reference's peak force), mean contact
//! pressure error (mmHg), missed-contact frames, frames compared. Stays true:
//! displacements and pressures are compared only where both runs stand at the
//! same point of the path (same [`FrameKey`](super::motion::FrameKey)); on the
//! same mesh vertex by vertex; across meshes at probe points (the reference's
//! surface vertices), where the run's displacement is interpolated
//! barycentrically at the closest point of its rest surface. RMS is over the
//! "moving" vertices (reference displacement above [`MOVING_FRACTION`] of its
//! peak in some compared frame), max over all. The force is compared at every
//! frame of the reference, the run's force interpolated linearly along the
//! path between its two frames around that point, so a run with fewer frames
//! (a faster blade) is judged at the same points as one with many, not only
//! where their frames happen to coincide.

use super::motion::Motion;
use super::runner::RunTrace;
use crate::math::Vec3;
use crate::geometry::closest_barycentric;

/// A vertex counts as moving when its reference displacement exceeds this
/// fraction of the reference's largest displacement in some compared frame.
pub const MOVING_FRACTION: f64 = 0.01;

/// How the displacements were compared.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Comparison {
    /// This run is the reference.
    Reference,
    /// Same mesh, per surface vertex.
    PerVertex,
    /// Different meshes, at this many probe points.
    Probes(usize),
}

/// Errors of one run against its reference.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Accuracy {
    pub comparison: Comparison,
    /// Frames compared (same path position in both runs).
    pub frames_compared: usize,
    /// RMS displacement error over moving vertices and compared frames, m.
    pub rms_error_m: f64,
    /// Largest displacement error, m.
    pub max_error_m: f64,
    /// RMS of |F - F_ref| over the reference's frames within the run's path
    /// (the run's force interpolated along the path), % of the reference's peak |F|.
    pub force_rms_pct: f64,
    /// Largest |F - F_ref| over the same points, % of the reference's peak |F|.
    pub force_max_pct: f64,
    /// Reference frames the force was compared at.
    pub force_points: usize,
    /// Largest |p - p_ref| of the highest mean contact pressure over compared frames, mmHg.
    pub pressure_error_mmhg: f64,
    /// Compared frames where the reference had contact and this run none.
    pub missed_contact_frames: usize,
    /// Compared frames where the reference had contact.
    pub reference_contact_frames: usize,
}

/// Maps each probe to (triangle of the run surface, barycentric weights).
struct ProbeMap {
    probes: Vec<usize>,
    weights: Vec<([u32; 3], [f64; 3])>,
}

fn probe_map(reference: &RunTrace, run: &RunTrace, probes: Vec<usize>) -> ProbeMap {
    let mut weights = Vec::with_capacity(probes.len());
    for &v in &probes {
        let p = reference.rest[v];
        let mut best = (f64::INFINITY, [0u32; 3], [1.0, 0.0, 0.0]);
        for t in &run.triangles {
            let [a, b, c] = t.map(|k| run.rest[k as usize]);
            let w = closest_barycentric(&p, &a, &b, &c);
            let q = a * w[0] + b * w[1] + c * w[2];
            let d = (q - p).norm_squared();
            if d < best.0 {
                best = (d, *t, w);
            }
        }
        weights.push((best.1, best.2));
    }
    ProbeMap { probes, weights }
}

/// The run's force at path position `s` (nm), linear between its frames
/// around `s`; `None` outside its first and last frame. `path` is
/// (position, force) in path order.
fn force_at(path: &[(i64, Vec3)], s: i64) -> Option<Vec3> {
    let k = path.partition_point(|p| p.0 < s);
    let hi = path.get(k)?;
    if hi.0 == s {
        return Some(hi.1);
    }
    let lo = path.get(k.checked_sub(1)?)?;
    let t = (s - lo.0) as f64 / (hi.0 - lo.0) as f64;
    Some(lo.1 + (hi.1 - lo.1) * t)
}

/// The force on the tissue along the path: (path position nm, F in N) a
/// frame, in path order.
pub fn force_along(trace: &RunTrace, motion: &Motion) -> Vec<(i64, Vec3)> {
    trace.frames.iter().map(|f| (motion.path_position_nm(f.key), f.force)).collect()
}

/// (RMS, max, points) of |F - F_ref| at every point of `reference`'s path
/// within `run`'s, the run's force interpolated along the path; in N. The
/// abscissa is any key that grows along both series (`fissure plot` passes
/// time in nanoseconds).
pub fn force_error(reference: &[(i64, Vec3)], run: &[(i64, Vec3)]) -> (f64, f64, usize) {
    let (mut sum2, mut max, mut n) = (0.0, 0.0_f64, 0usize);
    for &(s, f) in reference {
        if let Some(force) = force_at(run, s) {
            let e = (f - force).norm();
            sum2 += e * e;
            max = max.max(e);
            n += 1;
        }
    }
    (if n > 0 { (sum2 / n as f64).sqrt() } else { 0.0 }, max, n)
}

/// (RMS, max) of `run`'s force against `reference`'s along the path, % of
/// the reference's peak |F| (0 without force): how a sweep's runs approach
/// its finest setting, the same measure as [`compare`]'s force columns.
pub fn force_error_pct(reference: &[(i64, Vec3)], run: &[(i64, Vec3)]) -> (f64, f64) {
    let peak = reference.iter().map(|p| p.1.norm()).fold(0.0, f64::max);
    let (rms, max, _) = force_error(reference, run);
    if peak > 0.0 { (100.0 * rms / peak, 100.0 * max / peak) } else { (0.0, 0.0) }
}

/// Compares `run` with `reference` (both with displacements, both along `motion`).
pub fn compare(reference: &RunTrace, run: &RunTrace, same_mesh: bool, motion: &Motion) -> Accuracy {
    // Matched frames: (reference index, run index), in run order. Keys grow
    // along the path (phase, then distance), so the frames are sorted by key.
    let mut pairs = Vec::new();
    for (k, f) in run.frames.iter().enumerate() {
        if let Ok(r) = reference.frames.binary_search_by(|g| g.key.cmp(&f.key)) {
            pairs.push((r, k));
        }
    }
    let peak = pairs
        .iter()
        .filter_map(|&(r, _)| reference.displacements.get(r))
        .flat_map(|u| u.iter().map(|x| x.norm()))
        .fold(0.0, f64::max);
    let mut moving = vec![false; reference.rest.len()];
    for &(r, _) in &pairs {
        if let Some(u) = reference.displacements.get(r) {
            for (m, x) in moving.iter_mut().zip(u) {
                *m |= x.norm() > MOVING_FRACTION * peak;
            }
        }
    }
    let same = same_mesh && reference.rest.len() == run.rest.len();
    let map = (!same).then(|| probe_map(reference, run, (0..reference.rest.len()).filter(|&v| moving[v]).collect()));
    let (mut sum2, mut count, mut max) = (0.0, 0usize, 0.0_f64);
    for &(r, k) in &pairs {
        let (Some(ur), Some(uk)) = (reference.displacements.get(r), run.displacements.get(k)) else { continue };
        match &map {
            None => {
                for (v, (a, b)) in ur.iter().zip(uk).enumerate() {
                    let e = (a - b).norm();
                    max = max.max(e);
                    if moving[v] {
                        sum2 += e * e;
                        count += 1;
                    }
                }
            }
            Some(m) => {
                for (&v, (tri, w)) in m.probes.iter().zip(&m.weights) {
                    let u = uk[tri[0] as usize] * w[0] + uk[tri[1] as usize] * w[1] + uk[tri[2] as usize] * w[2];
                    let e = (ur[v] - u).norm();
                    max = max.max(e);
                    sum2 += e * e;
                    count += 1;
                }
            }
        }
    }
    let peak_force = reference.frames.iter().map(|f| f.force.norm()).fold(0.0, f64::max);
    let (force_rms, force_max, force_points) = force_error(&force_along(reference, motion), &force_along(run, motion));
    let pct = |e: f64| if peak_force > 0.0 { 100.0 * e / peak_force } else { 0.0 };
    let pressure_error = pairs.iter().map(|&(r, k)| (reference.frames[r].pressure_mmhg - run.frames[k].pressure_mmhg).abs()).fold(0.0, f64::max);
    let reference_contact_frames = pairs.iter().filter(|&&(r, _)| reference.frames[r].contact > 0).count();
    let missed = pairs.iter().filter(|&&(r, k)| reference.frames[r].contact > 0 && run.frames[k].contact == 0).count();
    Accuracy {
        comparison: match &map {
            None => Comparison::PerVertex,
            Some(m) => Comparison::Probes(m.probes.len()),
        },
        frames_compared: pairs.len(),
        rms_error_m: if count > 0 { (sum2 / count as f64).sqrt() } else { 0.0 },
        max_error_m: max,
        force_rms_pct: pct(force_rms),
        force_max_pct: pct(force_max),
        force_points,
        pressure_error_mmhg: pressure_error,
        missed_contact_frames: missed,
        reference_contact_frames,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::math::Vec3;
    use crate::study::motion::FrameKey;
    use crate::study::runner::FrameRecord;

    fn trace(keys: &[i64], u: &[f64]) -> RunTrace {
        let rest = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0)];
        RunTrace {
            frames: keys
                .iter()
                .zip(u)
                .map(|(&k, &x)| FrameRecord {
                    key: FrameKey { phase: 1, distance_nm: k },
                    times: Default::default(),
                    contact: (x > 0.0) as u32,
                    force: Vec3::new(x, 0.0, 0.0),
                    crossed: 0,
                    penetrating: 0,
                    max_penetration_m: 0.0,
                    pressure_mmhg: 10.0 * x,
                    inverted: 0,
                })
                .collect(),
            displacements: u.iter().map(|&x| vec![Vec3::new(x, 0.0, 0.0); 3]).collect(),
            rest,
            triangles: vec![[0, 1, 2]],
            ..Default::default()
        }
    }

    #[test]
    fn identical_runs_have_zero_error_and_shifted_runs_do_not() {
        let m = Motion::default();
        let r = trace(&[1, 2, 3], &[0.0, 1.0, 2.0]);
        let a = compare(&r, &r.clone(), true, &m);
        assert_eq!((a.rms_error_m, a.max_error_m, a.force_rms_pct, a.force_max_pct, a.missed_contact_frames), (0.0, 0.0, 0.0, 0.0, 0));
        assert_eq!((a.frames_compared, a.force_points), (3, 3));
        // A faster run visiting keys 2 only, with half the displacement there; key 4 is unknown to the reference.
        let fast = trace(&[2, 4], &[0.5, 9.0]);
        let b = compare(&r, &fast, true, &m);
        assert_eq!(b.frames_compared, 1, "only the shared path position is compared");
        assert!((b.max_error_m - 0.5).abs() < 1e-12 && (b.rms_error_m - 0.5).abs() < 1e-12, "{b:?}");
        // The force at keys 2 (0.5 against 1) and 3 (4.75 half way to key 4's 9, against 2); key 1 lies before the run.
        assert_eq!(b.force_points, 2);
        assert!((b.force_max_pct - 137.5).abs() < 1e-9, "2.75 N off a 2 N peak: {}", b.force_max_pct);
        let rms = ((0.5f64 * 0.5 + 2.75 * 2.75) / 2.0).sqrt() / 2.0 * 100.0;
        assert!((b.force_rms_pct - rms).abs() < 1e-9, "{} against {rms}", b.force_rms_pct);
        let none = trace(&[2], &[0.0]);
        assert_eq!(compare(&r, &none, true, &m).missed_contact_frames, 1, "contact in the reference, none here");
    }

    /// A run with every other frame is judged at every reference frame: on a
    /// force that is linear along the path it is exact; a peak between its
    /// frames is an error, where comparing only the shared frames saw none.
    #[test]
    fn the_force_is_compared_along_the_path_not_only_at_shared_frames() {
        let m = Motion::default();
        let keys: Vec<i64> = (1..=8).collect();
        let ramp = trace(&keys, &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let coarse = trace(&[2, 4, 6, 8], &[1.0, 3.0, 5.0, 7.0]);
        let a = compare(&ramp, &coarse, true, &m);
        assert_eq!((a.frames_compared, a.force_points), (4, 7));
        assert!(a.force_max_pct < 1e-9 && a.force_rms_pct < 1e-9, "{a:?}");
        let bump = trace(&keys, &[0.0, 0.0, 0.0, 4.0, 0.0, 0.0, 0.0, 0.0]);
        let blind = trace(&[2, 6], &[0.0, 0.0]);
        let b = compare(&bump, &blind, true, &m);
        assert_eq!(b.force_points, 5, "keys 2 to 6");
        assert!((b.force_max_pct - 100.0).abs() < 1e-9, "{b:?}");
        assert!((b.force_rms_pct - 100.0 / 5f64.sqrt()).abs() < 1e-9, "{b:?}");
    }

    /// Against a sweep's finest run: the same measure as the reference's
    /// force columns, in % of the finest run's peak.
    #[test]
    fn force_error_pct_is_the_compare_force_measure() {
        let m = Motion::default();
        let keys: Vec<i64> = (1..=8).collect();
        let fine = trace(&keys, &[0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0]);
        let coarse = trace(&[2, 5, 8], &[1.0, 3.0, 8.0]);
        let (rms, max) = force_error_pct(&force_along(&fine, &m), &force_along(&coarse, &m));
        let a = compare(&fine, &coarse, true, &m);
        assert_eq!((rms, max), (a.force_rms_pct, a.force_max_pct));
        assert!(max > 0.0 && rms > 0.0 && rms <= max);
        assert_eq!(force_error_pct(&force_along(&fine, &m), &force_along(&fine, &m)), (0.0, 0.0));
    }

    #[test]
    fn path_positions_follow_the_phases() {
        let m = Motion { insert_m: 0.03, insert_step_m: 0.002, open_m: 0.01 };
        let at = |phase, mm: i64| m.path_position_nm(FrameKey { phase, distance_nm: mm * 1_000_000 });
        assert_eq!([at(0, 2), at(1, 0), at(2, 1), at(3, 30)], [2_000_000, 30_000_000, 41_000_000, 80_000_000]);
    }

    #[test]
    fn probes_interpolate_on_the_closest_triangle() {
        let w = closest_barycentric(&Vec3::new(0.25, 0.25, 1.0), &Vec3::zeros(), &Vec3::x(), &Vec3::y());
        assert!((w[0] - 0.5).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12 && (w[2] - 0.25).abs() < 1e-12, "{w:?}");
        let w = closest_barycentric(&Vec3::new(2.0, -1.0, 0.0), &Vec3::zeros(), &Vec3::x(), &Vec3::y());
        assert_eq!(w, [0.0, 1.0, 0.0], "beyond vertex b");
        // A uniform field is reproduced exactly across meshes.
        let r = trace(&[1], &[0.003]);
        let a = compare(&r, &r.clone(), false, &Motion::default());
        assert_eq!(a.comparison, Comparison::Probes(3));
        assert!(a.max_error_m < 1e-15);
    }
}
