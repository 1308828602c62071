//! Accuracy of a run against the study's reference run.
//!
//! In: two [`RunTrace`]s with displacements. Out: an [`Accuracy`]: RMS and max
//! surface-displacement error (m), reaction-force error (% of the reference's
//! peak force), mean contact pressure error (mmHg), missed-contact frames,
//! frames compared. Stays true: frames are
//! compared only where both runs stand at the same point of the path (same
//! [`FrameKey`]); on the same mesh vertex by vertex; across meshes at probe
//! points (the reference's surface vertices), where the run's displacement is
//! interpolated barycentrically at the closest point of its rest surface.
//! RMS is over the "moving" vertices (reference displacement above
//! [`MOVING_FRACTION`] of its peak in some compared frame), max over all.

use super::runner::RunTrace;
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
    /// Largest |F - F_ref| over compared frames, % of the reference's peak |F| over its whole run.
    pub force_error_pct: f64,
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

/// Compares `run` with `reference` (both with displacements).
pub fn compare(reference: &RunTrace, run: &RunTrace, same_mesh: bool) -> Accuracy {
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
    let force_error = pairs.iter().map(|&(r, k)| (reference.frames[r].force - run.frames[k].force).norm()).fold(0.0, f64::max);
    let pressure_error = pairs.iter().map(|&(r, k)| (reference.frames[r].pressure_mmhg - run.frames[k].pressure_mmhg).abs()).fold(0.0, f64::max);
    let reference_contact_frames = pairs.iter().filter(|&&(r, _)| reference.frames[r].constrained > 0).count();
    let missed = pairs.iter().filter(|&&(r, k)| reference.frames[r].constrained > 0 && run.frames[k].constrained == 0).count();
    Accuracy {
        comparison: match &map {
            None => Comparison::PerVertex,
            Some(m) => Comparison::Probes(m.probes.len()),
        },
        frames_compared: pairs.len(),
        rms_error_m: if count > 0 { (sum2 / count as f64).sqrt() } else { 0.0 },
        max_error_m: max,
        force_error_pct: if peak_force > 0.0 { 100.0 * force_error / peak_force } else { 0.0 },
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
                    constrained: (x > 0.0) as u32,
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
        let r = trace(&[1, 2, 3], &[0.0, 1.0, 2.0]);
        let a = compare(&r, &r.clone(), true);
        assert_eq!((a.rms_error_m, a.max_error_m, a.force_error_pct, a.missed_contact_frames), (0.0, 0.0, 0.0, 0));
        assert_eq!(a.frames_compared, 3);
        // A faster run visiting keys 2 only, with half the displacement there; key 4 is unknown to the reference.
        let fast = trace(&[2, 4], &[0.5, 9.0]);
        let b = compare(&r, &fast, true);
        assert_eq!(b.frames_compared, 1, "only the shared path position is compared");
        assert!((b.max_error_m - 0.5).abs() < 1e-12 && (b.rms_error_m - 0.5).abs() < 1e-12, "{b:?}");
        assert!((b.force_error_pct - 25.0).abs() < 1e-9, "0.5 N off a 2 N peak: {}", b.force_error_pct);
        let none = trace(&[2], &[0.0]);
        assert_eq!(compare(&r, &none, true).missed_contact_frames, 1, "contact in the reference, none here");
    }

    #[test]
    fn probes_interpolate_on_the_closest_triangle() {
        let w = closest_barycentric(&Vec3::new(0.25, 0.25, 1.0), &Vec3::zeros(), &Vec3::x(), &Vec3::y());
        assert!((w[0] - 0.5).abs() < 1e-12 && (w[1] - 0.25).abs() < 1e-12 && (w[2] - 0.25).abs() < 1e-12, "{w:?}");
        let w = closest_barycentric(&Vec3::new(2.0, -1.0, 0.0), &Vec3::zeros(), &Vec3::x(), &Vec3::y());
        assert_eq!(w, [0.0, 1.0, 0.0], "beyond vertex b");
        // A uniform field is reproduced exactly across meshes.
        let r = trace(&[1], &[0.003]);
        let a = compare(&r, &r.clone(), false);
        assert_eq!(a.comparison, Comparison::Probes(3));
        assert!(a.max_error_m < 1e-15);
    }
}
