//! The SpaceMouse decoders on arbitrary bytes: every 32-byte window as a
//! spacenavd event, every chunk (its first byte a length) as a HID report,
//! and the whole as a `uevent` file and an `/etc/spnavrc`. Never a panic; a
//! decoded motion maps to a finite velocity.
#![no_main]

use fissure::input::spacemouse::decode::{HidDecoder, SPNAV_EVENT_SIZE, SpaceEvent, decode_spnav, parse_uevent, socket_from_spnavrc};
use fissure::input::spacemouse::{SpaceMouseMapping, map_motion};
use libfuzzer_sys::fuzz_target;

fn check(event: SpaceEvent) {
    if let SpaceEvent::Motion(m) = event {
        let v = map_motion(&m, false, &SpaceMouseMapping::default());
        assert!(v.linear_m_s.iter().chain(v.angular_rad_s.iter()).all(|c| c.is_finite()), "a motion mapped to {v:?}");
    }
}

fuzz_target!(|data: &[u8]| {
    for window in data.chunks_exact(SPNAV_EVENT_SIZE) {
        let event: [u8; SPNAV_EVENT_SIZE] = window.try_into().expect("exact chunk");
        if let Some(e) = decode_spnav(&event) {
            check(e);
        }
    }
    let mut hid = HidDecoder::default();
    let mut events = Vec::new();
    let mut rest = data;
    while let Some((&len, tail)) = rest.split_first() {
        let n = usize::from(len).min(tail.len());
        hid.report(&tail[..n], &mut events);
        events.iter().copied().for_each(check);
        rest = &tail[n..];
    }
    let text = String::from_utf8_lossy(data);
    let _ = parse_uevent(&text);
    let _ = socket_from_spnavrc(&text);
});
