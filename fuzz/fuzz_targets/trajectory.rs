//! The trajectory parser on arbitrary text: Ok or Err, never a panic; every
//! pose a parsed trajectory samples is finite with a unit quaternion.
#![no_main]

use fissure::scenario::Trajectory;
use libfuzzer_sys::fuzz_target;
use std::path::Path;

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    if let Ok(t) = Trajectory::parse(&text, Path::new("fuzz.csv")) {
        let end = t.duration();
        for k in 0..t.spatula_count() {
            for time in [-1.0, 0.0, 0.5 * end, end, end + 1.0, f64::NAN] {
                if let Some(p) = t.sample(k, time) {
                    assert!(p.is_valid(), "spatula {k} at {time} s samples an invalid pose {p:?}");
                }
            }
        }
        // Round trip: what we write, we read back the same.
        let again = Trajectory::parse(&t.to_csv(), Path::new("fuzz.csv")).expect("our own CSV parses");
        assert_eq!(again, t, "to_csv / parse round trip");
    }
});
