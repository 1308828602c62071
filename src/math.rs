//! Shared small math types. SI units everywhere inside the library (m, Pa, N).
//!
//! `Vec3` is an f64 column vector; poses use a unit quaternion. GPU code converts
//! to f32 at its boundary and states the error it introduces.

pub use nalgebra::{Matrix3, Point3, UnitQuaternion, Vector3};

/// A 3-vector in metres (or a direction), f64.
pub type Vec3 = Vector3<f64>;
/// A rotation, unit quaternion, f64.
pub type Quat = UnitQuaternion<f64>;

/// The components' bits: two vectors are the same vector when these are (a key for "unchanged").
#[inline]
pub fn bits3(v: &Vec3) -> [u64; 3] {
    [v.x.to_bits(), v.y.to_bits(), v.z.to_bits()]
}

/// True when every component is finite (not NaN, not ±Inf).
#[inline]
pub fn is_finite3(v: &Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

/// Asks the CPU to bring the `BYTES` bytes from `p` (at most two cache lines) into cache (x86-64; elsewhere
/// nothing): a hint for a loop about to read data that lie apart, which the hardware's own prefetch cannot follow.
/// Both ends' lines are asked for, without a branch: this sits in hot loops. It reads nothing and changes no value,
/// whatever the address.
#[inline(always)]
pub fn prefetch<const BYTES: usize, T>(p: *const T) {
    #[cfg(target_arch = "x86_64")]
    {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        let p = p.cast::<i8>();
        // SAFETY: a prefetch never faults and never reads into the program: any address is allowed.
        unsafe {
            _mm_prefetch::<_MM_HINT_T0>(p);
            if BYTES > 1 {
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(BYTES - 1));
            }
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = p;
}

/// Deterministic test data.
#[cfg(test)]
pub(crate) mod test_rng {
    /// Draws in [0, 1) from xorshift64 started at `seed`: the same sequence on every machine.
    pub(crate) fn uniform(seed: u64) -> impl FnMut() -> f64 {
        let mut s = seed;
        move || {
            s ^= s << 13;
            s ^= s >> 7;
            s ^= s << 17;
            (s >> 11) as f64 / (1u64 << 53) as f64
        }
    }
}
