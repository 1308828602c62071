//! Sub-steps and a tracker's jitter: a blade held in the tissue while its
//! samples jitter by +-0.5 mm a coordinate every frame. With
//! `solver.substep_jitter: Discount` (the default) the jitter does not count as
//! travel, so the hold runs one step a frame; with `Follow` every jitter is
//! split into sub-steps of an eighth of the thickness. Smooth motion runs the
//! same sub-steps and gives the same bits either way, and the jittered hold's
//! forces differ between the two by less than the jitter itself moves them.
//!
//! Scene units: millimetres in the mesh file, metres inside.

use crate::common;

use common::scenes::{Scene, pose_mm, step_checked};
use fissure::math::Vec3;

const IDENTITY: [f64; 4] = [1.0, 0.0, 0.0, 0.0];
/// Block top (mm); the blade lies flat over it, face 1 down.
const TOP_MM: f64 = 20.0;
/// The blade's mid-plane at the start (0.2 mm clear of the top) and held (its lower face 2 mm into the block).
const START_Z_MM: f64 = TOP_MM + 0.5 + 0.2;
const HELD_Z_MM: f64 = TOP_MM + 0.5 - 2.0;
const PRESS_FRAMES: usize = 16;
const HOLD_FRAMES: usize = 80;
/// The jitter estimate reads 16 frames; the frames after it are compared.
const SETTLED: usize = 16;

/// The block press, 0.2 mm above the block, with `solver.substep_travel` (and what follows it) as given.
fn press_scene(jitter: &'static str) -> Scene {
    let mut s = common::scenes::block_press(START_Z_MM);
    s.substep_travel = jitter;
    s
}

/// A deterministic uniform sample in [-0.5, 0.5) mm.
fn jitter_mm(seed: &mut u64) -> f64 {
    *seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
    (*seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5
}

/// The press at a constant speed (with a stop at its end), then the hold, its
/// samples jittered when `jittered`. Returns each frame's (sub-steps, force).
fn run(jitter: &'static str, jittered: bool) -> Vec<(u32, Vec3)> {
    let dir = tempfile::tempdir().unwrap();
    let (mut p, mut state) = press_scene(jitter).build(dir.path());
    let mut out = Vec::new();
    let mut seed = 11;
    for k in 1..=PRESS_FRAMES + HOLD_FRAMES {
        let z = START_Z_MM + (HELD_Z_MM - START_Z_MM) * (k.min(PRESS_FRAMES) as f64 / PRESS_FRAMES as f64);
        let mut at = [-6.0, 0.0, z];
        if jittered && k > PRESS_FRAMES {
            for c in &mut at {
                *c += jitter_mm(&mut seed);
            }
        }
        let (r, _) = step_checked(&mut p, &mut state, &[pose_mm(at, IDENTITY)], &format!("{jitter} frame {k}"));
        assert!(!r.solver_capped, "{jitter} frame {k}: the contact solve hit its cap");
        assert_eq!(r.crossed_vertices, 0, "{jitter} frame {k}: tissue passed through the blade");
        out.push((r.substeps, r.spatulas[0].force));
    }
    out
}

const DISCOUNT: &str = "Some(0.125), substep_jitter: Discount";
const FOLLOW: &str = "Some(0.125), substep_jitter: Follow";

#[test]
fn smooth_motion_takes_the_same_substeps_and_bits_whether_jitter_is_discounted_or_not() {
    let (d, f) = (run(DISCOUNT, false), run(FOLLOW, false));
    // 0.1375 mm a frame: two sub-steps of an eighth of the thickness in contact.
    assert!(d[..PRESS_FRAMES].iter().filter(|r| r.0 == 2).count() >= PRESS_FRAMES / 2, "the press: {:?}", &d[..PRESS_FRAMES]);
    assert!(d[..PRESS_FRAMES].iter().any(|r| r.1.norm() > 0.0), "the press never touched the block");
    for (k, (a, b)) in d.iter().zip(&f).enumerate() {
        assert_eq!(a.0, b.0, "frame {}: sub-steps", k + 1);
        assert_eq!(a.1.map(f64::to_bits), b.1.map(f64::to_bits), "frame {}: force", k + 1);
    }
}

#[test]
fn a_jittered_hold_runs_one_step_a_frame_and_its_forces_stay_within_the_jitters_own_spread() {
    let (d, f, clean) = (run(DISCOUNT, true), run(FOLLOW, true), run(DISCOUNT, false));
    let hold = PRESS_FRAMES + SETTLED..PRESS_FRAMES + HOLD_FRAMES;
    let n = hold.len();
    let one = d[hold.clone()].iter().filter(|r| r.0 == 1).count();
    let split = f[hold.clone()].iter().filter(|r| r.0 > 1).count();
    println!("jittered hold, {n} frames: one step in {one} discounted; split in {split} followed");
    assert!(one * 10 >= n * 9, "discounted: only {one} of {n} jittered frames ran as one step");
    assert!(split * 10 >= n * 9, "followed: only {split} of {n} jittered frames were split");
    let rms = |a: &[(u32, Vec3)], b: &[(u32, Vec3)]| (hold.clone().map(|k| (a[k].1 - b[k].1).norm_squared()).sum::<f64>() / n as f64).sqrt();
    let mean = |a: &[(u32, Vec3)]| hold.clone().map(|k| a[k].1.norm()).sum::<f64>() / n as f64;
    let (between, spread_d, spread_f) = (rms(&d, &f), rms(&d, &clean), rms(&f, &clean));
    println!(
        "force: mean {:.4} N discounted, {:.4} N followed, {:.4} N clean; rms discounted-followed {between:.2e} N, from clean {spread_d:.2e} / {spread_f:.2e} N",
        mean(&d),
        mean(&f),
        mean(&clean)
    );
    // The jitter moves the force far more than how it is stepped does.
    assert!(between < 0.5 * spread_f, "discounting the jitter changed the forces by {between:e} N rms, the jitter itself {spread_f:e} N");
    assert!(spread_d < 1.25 * spread_f, "discounted forces lie {spread_d:e} N rms from the clean hold's, followed {spread_f:e} N");
    assert!((mean(&d) - mean(&f)).abs() < 0.05 * mean(&f), "mean force {} against {} N", mean(&d), mean(&f));
}
