//! Where the time of a W update goes for a sliding window of contact nodes
//! (the `fem` bench's 300 constrained / 30 new pattern) on a synthetic SPD
//! kernel: `cargo run --release --example wfactor_probe`.

use fissure::fem::wfactor::ContactFactor;
use fissure::math::Matrix3;
use std::time::Instant;

fn main() {
    let count = 300usize;
    let fresh = 30usize;
    let nodes = 2400usize;
    // points on a line-ish strip; K^-1-like kernel: 1/(r + h) isotropic plus a diagonal
    let pos: Vec<[f64; 3]> = (0..nodes).map(|i| [i as f64 * 1e-3, ((i * 7919) % 13) as f64 * 1e-3, ((i * 104729) % 11) as f64 * 1e-3]).collect();
    let block = |p: u32, q: u32| -> Matrix3<f64> {
        let (a, b) = (pos[p as usize], pos[q as usize]);
        let r = ((a[0] - b[0]).powi(2) + (a[1] - b[1]).powi(2) + (a[2] - b[2]).powi(2)).sqrt();
        Matrix3::identity() * (1.0 / (r + 2e-3) + if p == q { 50.0 } else { 0.0 })
    };
    let mut f = ContactFactor::default();
    let mut order = Vec::new();
    let frames = (nodes - count) / fresh;
    let mut times = Vec::new();
    for k in 0..frames {
        let sorted: Vec<u32> = ((k * fresh) as u32..(k * fresh + count) as u32).collect();
        let t = Instant::now();
        f.order_for(&sorted, &mut order);
        f.update_enforced(&order, &block);
        let mut b = vec![1.0; f.rows()];
        f.solve_in_place(&mut b);
        times.push(t.elapsed().as_secs_f64() * 1e3);
    }
    times.remove(0);
    times.sort_by(|a, b| a.total_cmp(b));
    println!("{} frames, update {:?} each: p50 {:.2} ms, max {:.2} ms", times.len(), f.last_update(), times[times.len() / 2], times[times.len() - 1]);
}
