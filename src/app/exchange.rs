//! A latest-value exchange between one producer thread and one consumer thread
//! (a triple buffer behind a mutex held only for a swap).
//!
//! In: values the producer fills in place ([`Exchange::publish`] swaps its back
//! buffer in). Out: the newest published value for the consumer
//! ([`Exchange::take_latest`] swaps it into the consumer's front buffer).
//! Stays true: neither side waits for the other beyond a pointer swap; no
//! allocation after the buffers are sized; the consumer sees each value at
//! most once and always the newest.

use std::sync::Mutex;

/// The shared middle slot.
#[derive(Debug, Default)]
pub struct Exchange<T> {
    slot: Mutex<(T, bool)>,
}

impl<T: Default> Exchange<T> {
    /// An exchange whose middle slot holds `T::default()` (not fresh).
    pub fn new() -> Self {
        Self { slot: Mutex::new((T::default(), false)) }
    }
}

impl<T> Exchange<T> {
    /// Swaps the producer's filled `back` in as the newest value; `back` gets an old buffer to refill.
    pub fn publish(&self, back: &mut T) {
        let mut g = self.slot.lock().unwrap_or_else(|p| p.into_inner());
        std::mem::swap(&mut g.0, back);
        g.1 = true;
    }

    /// If a value newer than the last taken one exists, swaps it into `front` and returns true.
    pub fn take_latest(&self, front: &mut T) -> bool {
        let mut g = self.slot.lock().unwrap_or_else(|p| p.into_inner());
        if !g.1 {
            return false;
        }
        std::mem::swap(&mut g.0, front);
        g.1 = false;
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn consumer_sees_only_the_newest_value_once() {
        let x: Exchange<u32> = Exchange::new();
        let mut front = 0;
        assert!(!x.take_latest(&mut front), "nothing published yet");
        let mut back = 1;
        x.publish(&mut back);
        back = 2;
        x.publish(&mut back);
        assert!(x.take_latest(&mut front));
        assert_eq!(front, 2, "the newest value wins");
        assert!(!x.take_latest(&mut front), "a value is seen once");
        assert_eq!(front, 2);
    }
}
