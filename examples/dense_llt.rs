//! How fast faer's dense Cholesky (the W factor of the constrained solve) runs
//! here, in f64 and f32, on one thread and on two: the floor under a frame that
//! must refactor its contact compliance W (`src/linalg/kept_factor.rs`). Numbers in
//! docs/design-notes.md. Run: `cargo run --release --example dense_llt`.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::linalg::cholesky::llt::factor::{LltRegularization, cholesky_in_place, cholesky_in_place_scratch};
use faer::traits::RealField;
use faer::{Mat, Par, Spec};
use std::time::Instant;

/// Best of 20 factorizations of an SPD test matrix of order `n`, seconds.
fn best_llt<T: RealField + Copy + From<f32>>(n: usize, par: Par) -> f64 {
    let a = Mat::<T>::from_fn(n, n, |i, j| {
        T::from(if i == j { n as f32 } else { 1.0 / (1.0 + (i as f32 - j as f32).abs()) })
    });
    let req = cholesky_in_place_scratch::<T>(n, par, Spec::default());
    let mut buf = MemBuffer::new(req);
    let mut best = f64::INFINITY;
    for _ in 0..20 {
        let mut l = a.clone();
        let t = Instant::now();
        cholesky_in_place(l.as_mut(), LltRegularization::default(), par, MemStack::new(&mut buf), Spec::default()).expect("SPD test matrix");
        best = best.min(t.elapsed().as_secs_f64());
    }
    best
}

fn main() {
    for n in [300usize, 900, 1500] {
        for par in [Par::Seq, Par::rayon(2)] {
            for (name, best) in [("f64", best_llt::<f64>(n, par)), ("f32", best_llt::<f32>(n, par))] {
                println!("n {n} {name} {:?}: {:.2} ms, {:.1} GFlop/s", par, best * 1e3, (n as f64).powi(3) / 3.0 / best / 1e9);
            }
        }
    }
}
