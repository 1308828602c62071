//! How fast faer's dense Cholesky (the W factor of the constrained solve) runs
//! here, on one thread and on two: the floor under a frame that must refactor
//! its contact compliance W (`src/fem/wfactor.rs`). Numbers in docs/design-notes.md.
//! Run: `cargo run --release --example dense_llt`.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltRegularization, cholesky_in_place, cholesky_in_place_scratch};
use faer::{Mat, Par, Spec};
use std::time::Instant;
fn main() {
    for n in [300usize, 900, 1500] {
        let a = Mat::<f64>::from_fn(n, n, |i, j| if i == j { n as f64 } else { 1.0 / (1.0 + (i as f64 - j as f64).abs()) });
        for par in [Par::Seq, Par::rayon(2)] {
            let req = cholesky_in_place_scratch::<f64>(n, par, Spec::default());
            let mut buf = MemBuffer::new(req);
            let mut best = f64::INFINITY;
            for _ in 0..20 {
                let mut l = a.clone();
                let t = Instant::now();
                cholesky_in_place(l.as_mut(), LltRegularization::default(), par, MemStack::new(&mut buf), Spec::default()).expect("SPD test matrix");
                best = best.min(t.elapsed().as_secs_f64());
            }
            println!("n {n} {:?}: {:.2} ms, {:.1} GFlop/s", par, best * 1e3, (n as f64).powi(3) / 3.0 / best / 1e9);
        }
    }
}
