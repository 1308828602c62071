//! Work split between the calling thread and one worker thread ([`join`]), for the frame's few large memory-bound
//! passes (the surface product on a wide contact).
//!
//! Why not rayon's `join`: called from the frame's thread, which is not one of the pool's, it hands both halves to
//! the pool and sleeps. On the 2-core VMs this project is measured on, the pool's second worker then woke too late to
//! take its half: the halves of the surface product ran one after the other in every large frame of the default
//! scene (9 of 9), and each call waited about 0.1 ms more for the pool to wake and to hand back. Here the caller
//! works on its half at once while a parked worker thread is woken for the other; if the worker has not taken it by
//! the time the caller is done, the caller runs it too. So a split is never slower than running both halves in
//! turn by more than a wake-up call, whatever the other core is doing. Measured in `docs/design-notes.md`.

use std::sync::{Condvar, Mutex, OnceLock};

/// Whether the machine has a second core to split onto.
pub fn available() -> bool {
    static CORES: OnceLock<usize> = OnceLock::new();
    *CORES.get_or_init(|| std::thread::available_parallelism().map_or(1, |n| n.get())) > 1
}

/// A job handed to the worker: the caller's closure, its lifetime erased. Sound because the caller does not return
/// (nor unwind) past [`Finish`] before the worker has finished it or it has been taken back.
struct JobPtr(*mut (dyn FnMut() + Send + 'static));
// SAFETY: the closure behind the pointer is `Send`, and only one thread runs it (the slot hands it over).
unsafe impl Send for JobPtr {}

enum Slot {
    Empty,
    Posted(JobPtr),
    /// The worker runs the job.
    Taken,
    /// The worker ran the job (`Err`: it panicked, the payload for the caller).
    Done(std::thread::Result<()>),
}

struct Worker {
    slot: Mutex<Slot>,
    posted: Condvar,
    done: Condvar,
}

/// The worker thread, started on first use (`None`: it could not be started).
fn worker() -> Option<&'static Worker> {
    static WORKER: OnceLock<Option<&'static Worker>> = OnceLock::new();
    *WORKER.get_or_init(|| {
        let h: &'static Worker = Box::leak(Box::new(Worker { slot: Mutex::new(Slot::Empty), posted: Condvar::new(), done: Condvar::new() }));
        std::thread::Builder::new().name("fissure-split".into()).spawn(move || h.serve()).ok().map(|_| h)
    })
}

impl Worker {
    fn serve(&self) {
        let Ok(mut slot) = self.slot.lock() else { return };
        loop {
            if let Slot::Posted(_) = &*slot {
                let Slot::Posted(job) = std::mem::replace(&mut *slot, Slot::Taken) else { unreachable!() };
                drop(slot);
                // SAFETY: the caller waits in `Finish` until the slot says Done, so the closure is alive; it was
                // handed over once, so no other thread runs it.
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| unsafe { (*job.0)() }));
                let Ok(mut again) = self.slot.lock() else { return };
                *again = Slot::Done(result);
                self.done.notify_one();
                slot = again;
            } else {
                slot = match self.posted.wait(slot) {
                    Ok(s) => s,
                    Err(_) => return,
                };
            }
        }
    }
}

/// Takes the posted job back, or waits for the worker to finish it, when the caller leaves [`join`] (returning or
/// unwinding). Says whether the worker ran it, with its panic if any.
struct Finish<'h> {
    worker: &'h Worker,
    outcome: Option<std::thread::Result<bool>>,
}

impl Finish<'_> {
    fn settle(&mut self) -> std::thread::Result<bool> {
        if let Some(o) = self.outcome.take() {
            return o;
        }
        let Ok(mut slot) = self.worker.slot.lock() else { return Ok(false) };
        loop {
            match std::mem::replace(&mut *slot, Slot::Empty) {
                Slot::Posted(_) => return Ok(false),
                Slot::Done(result) => return result.map(|()| true),
                Slot::Taken => {
                    *slot = Slot::Taken;
                    slot = match self.worker.done.wait(slot) {
                        Ok(s) => s,
                        // a poisoned lock: the worker died; abort rather than free what it may still use
                        Err(_) => std::process::abort(),
                    };
                }
                Slot::Empty => return Ok(false),
            }
        }
    }
}

impl Drop for Finish<'_> {
    fn drop(&mut self) {
        let _ = self.settle();
    }
}

/// Runs `a` on the calling thread and `b` on the worker thread beside it, and returns both results. `b` runs on
/// the caller instead (after `a`) when the machine has one core, the worker is busy with another call or has not
/// taken `b` by the time `a` is done: the results are the same either way. A panic in `b` is resumed on the caller.
pub fn join<A, B, RA, RB>(a: A, b: B) -> (RA, RB)
where
    A: FnOnce() -> RA,
    B: FnOnce() -> RB + Send,
    RB: Send,
{
    let Some(worker) = available().then(worker).flatten() else { return (a(), b()) };
    let mut b = Some(b);
    let mut rb = None;
    let mut job = || {
        if let Some(b) = b.take() {
            rb = Some(b());
        }
    };
    let posted = match worker.slot.lock() {
        Ok(mut slot) if matches!(*slot, Slot::Empty) => {
            let ptr: *mut (dyn FnMut() + Send + '_) = &mut job;
            // SAFETY: lifetime erasure only; `finish` below keeps `job` alive until the worker is done with it.
            let ptr: *mut (dyn FnMut() + Send + 'static) = unsafe { std::mem::transmute(ptr) };
            *slot = Slot::Posted(JobPtr(ptr));
            worker.posted.notify_one();
            true
        }
        // busy with another call: both here
        _ => false,
    };
    let ra = if posted {
        let mut finish = Finish { worker, outcome: None };
        let ra = a();
        let outcome = finish.settle();
        finish.outcome = Some(Ok(true));
        drop(finish);
        match outcome {
            Err(panic) => std::panic::resume_unwind(panic),
            Ok(true) => {}
            // taken back: `b` runs here
            Ok(false) => job(),
        }
        ra
    } else {
        let ra = a();
        job();
        ra
    };
    match rb {
        Some(rb) => (ra, rb),
        None => unreachable!("the second half ran on one of the two threads"),
    }
}

/// Runs `f` on every item of `items`, on the calling thread and the worker ([`join`]) at once: each takes the next
/// `chunk` items not yet taken, so a worker that starts late takes what is left and one that never starts takes
/// nothing. Each item is given to one thread only.
pub fn for_each_mut<T: Send>(items: &mut [T], chunk: usize, f: impl Fn(&mut T) + Sync) {
    use std::sync::atomic::{AtomicUsize, Ordering};
    let chunk = chunk.max(1);
    let (n, next) = (items.len(), AtomicUsize::new(0));
    let base = SendPtr(items.as_mut_ptr());
    let claim = || {
        let base = &base;
        loop {
            let start = next.fetch_add(chunk, Ordering::Relaxed);
            if start >= n {
                break;
            }
            let end = (start + chunk).min(n);
            // SAFETY: `fetch_add` hands each range `start..end` (inside `items`) to one thread once, and `items` is
            // borrowed mutably for the whole call, so the ranges are the only access to those items.
            let part = unsafe { std::slice::from_raw_parts_mut(base.0.add(start), end - start) };
            part.iter_mut().for_each(&f);
        }
    };
    join(claim, claim);
}

/// A pointer to items handed out by range ([`for_each_mut`]).
struct SendPtr<T>(*mut T);
// SAFETY: the items are `Send`, and each range behind the pointer is reached by one thread only.
unsafe impl<T: Send> Send for SendPtr<T> {}
// SAFETY: as above: threads share the pointer, never an item.
unsafe impl<T: Send> Sync for SendPtr<T> {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_halves_run_and_write_their_own_parts() {
        for round in 0..50 {
            let mut v = vec![0u64; 1000];
            let (lo, hi) = v.split_at_mut(400);
            let (a, b) = join(
                || {
                    lo.iter_mut().enumerate().for_each(|(i, x)| *x = i as u64);
                    lo.len()
                },
                || {
                    hi.iter_mut().enumerate().for_each(|(i, x)| *x = 400 + i as u64);
                    hi.len()
                },
            );
            assert_eq!((a, b), (400, 600), "round {round}");
            assert!(v.iter().enumerate().all(|(i, &x)| x == i as u64), "round {round}");
        }
    }

    #[test]
    fn every_item_is_run_once() {
        for chunk in [1, 3, 64] {
            let mut v: Vec<(usize, u32)> = (0..1000).map(|i| (i, 0)).collect();
            for_each_mut(&mut v, chunk, |(i, runs)| {
                *runs += 1;
                *i *= 2;
            });
            assert!(v.iter().enumerate().all(|(i, &(x, runs))| x == 2 * i && runs == 1), "chunks of {chunk}");
        }
    }

    #[test]
    fn calls_from_two_threads_at_once_both_finish() {
        let sums: Vec<u64> = std::thread::scope(|s| {
            let hs: Vec<_> = (0..4u64)
                .map(|k| s.spawn(move || (0..200).map(|_| join(|| k, || 10 * k)).map(|(a, b)| a + b).sum::<u64>()))
                .collect();
            hs.into_iter().map(|h| h.join().unwrap()).collect()
        });
        assert_eq!(sums, (0..4u64).map(|k| 200 * 11 * k).collect::<Vec<_>>());
    }

    #[test]
    fn a_panic_in_either_half_reaches_the_caller_and_the_worker_serves_on() {
        assert!(std::panic::catch_unwind(|| join(|| 1, || -> u32 { panic!("second half") })).is_err());
        assert!(std::panic::catch_unwind(|| join(|| -> u32 { panic!("first half") }, || 2)).is_err());
        assert_eq!(join(|| 3, || 4), (3, 4));
    }
}
