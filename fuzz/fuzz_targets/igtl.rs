//! The OpenIGTLink decoder on arbitrary bytes: a header, then a body of the
//! size the header states (or what is left). Ok or Err, never a panic; every
//! TRANSFORM that decodes is finite and orthonormal, and its pose is valid;
//! one decoded raw (a stylus's buttons) is finite.
#![no_main]

use fissure::input::igtl::transform_to_pose;
use fissure::input::igtl_codec::{HEADER_SIZE, Message, RawMessage, decode_body, decode_body_raw, decode_header, decode_sensor_body, orthonormality_error, ORTHONORMAL_TOLERANCE};
use fissure::input::workspace::plus_buttons;
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = decode_sensor_body(data);
    if data.len() < HEADER_SIZE {
        let _ = decode_header(data);
        return;
    }
    let Ok(header) = decode_header(&data[..HEADER_SIZE]) else { return };
    let rest = &data[HEADER_SIZE..];
    let body = &rest[..rest.len().min(header.body_size.min(usize::MAX as u64) as usize)];
    if let Ok(RawMessage::Transform(raw)) = decode_body_raw(&header, body) {
        // A stylus's buttons: any finite matrix reads as four states.
        assert!(raw.matrix.iter().chain(raw.translation.iter()).all(|c| c.is_finite()), "decoded a non-finite raw transform");
        let _ = plus_buttons(&raw.matrix);
    }
    if let Ok(Message::Transform(t)) = decode_body(&header, body) {
        assert!(t.rotation.iter().chain(t.translation_mm.iter()).all(|c| c.is_finite()), "decoded a non-finite transform");
        assert!(orthonormality_error(&t.rotation) <= ORTHONORMAL_TOLERANCE, "decoded a non-orthonormal rotation");
        if let Some(p) = transform_to_pose(&t) {
            assert!(p.is_valid(), "a decoded transform gave an invalid pose {p:?}");
        }
    }
});
