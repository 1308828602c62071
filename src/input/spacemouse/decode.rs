//! SpaceMouse wire formats: spacenavd's events and the device's HID reports,
//! decoded to one motion in the device's own axes.
//!
//! In: one 32-byte spacenavd event, or one HID report (one `read` of
//! `/dev/hidraw*`), or a `uevent` file of `/sys/class/hidraw/*/device`. Out:
//! [`SpaceEvent`]s (the six axes in the device's HID frame, counts; button
//! presses and releases) and the device's identity. Stays true: decoding never
//! panics on any bytes; both sources give the same [`SpaceMotion`] for the
//! same push of the cap (with spacenavd's default axis settings).
//!
//! **spacenavd** (its Unix socket, protocol 0, what libspnav's `spnav_open`
//! reads before it asks for more): each event is 8 native-endian `i32`
//! (little-endian on the machines fissure runs on): `type, data[7]`. Type 0 is
//! motion, `x, y, z, rx, ry, rz, period_ms`; type 1 a button press and 2 a
//! release, `data[0]` the 0-based button number; other types are skipped
//! (spacenavd `src/proto_unix.c`, `send_uevent`; libspnav `src/spnav.c`,
//! `proc_event`, <https://github.com/FreeSpacenav>). By default spacenavd swaps
//! the device's y and z axes and inverts y, z, ry and rz (`src/event.c`,
//! `map_axis`, and `src/cfgfile.c`, `def_axinv = {0, 1, 1, 0, 1, 1}`): an event
//! `(x, y, z, rx, ry, rz)` is the device's `(x, -z, -y, rx, -rz, -ry)`, which
//! [`decode_spnav`] undoes. A `/etc/spnavrc` with `swap-yz` or `invert-*`
//! changes the directions accordingly.
//!
//! **HID** (3Dconnexion devices, vendor 0x256f, or 0x046d with the product
//! ids spacenavd lists in `src/dev.c`): report 1 holds the translation x, y, z
//! as `i16` little-endian; report 2 the rotation rx, ry, rz likewise; newer
//! devices (SpaceMouse Wireless, Compact, the universal receiver) send all six
//! axes in report 1 (12 bytes after the id) and no report 2; report 3 is the
//! buttons' bitmask, bit 0 the left button and bit 1 the right one
//! (<https://github.com/johnhw/pyspacenavigator>, `spacenavigator.py`, the
//! `DeviceSpec` table). A full push reads about 350 counts on each axis (the
//! same table's `axis_scale`). The device's axes: x to the right, y towards
//! the user, z down (pressing the cap is +z), rotations right-handed about them.

/// Bytes of one spacenavd event.
pub const SPNAV_EVENT_SIZE: usize = 32;

/// The counts of a full push of the cap (see the module doc).
pub const FULL_SCALE_COUNTS: f64 = 350.0;

/// The six axes in the device's HID frame (x right, y towards the user, z
/// down; rotations about them), counts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct SpaceMotion {
    /// Translation x, y, z.
    pub translation: [i32; 3],
    /// Rotation about x, y, z.
    pub rotation: [i32; 3],
}

/// One input from the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpaceEvent {
    /// The cap's deflection now (it holds until the next motion).
    Motion(SpaceMotion),
    /// Button `index` (0: left, 1: right) pressed or released.
    Button { index: u32, pressed: bool },
}

fn le_i32(b: &[u8], at: usize) -> i32 {
    i32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn le_i16(b: &[u8], at: usize) -> i32 {
    i32::from(i16::from_le_bytes([b[at], b[at + 1]]))
}

/// Decodes one spacenavd event; `None` for event types other than motion and buttons.
pub fn decode_spnav(event: &[u8; SPNAV_EVENT_SIZE]) -> Option<SpaceEvent> {
    let d: [i32; 8] = std::array::from_fn(|i| le_i32(event, 4 * i));
    match d[0] {
        0 => {
            let (x, y, z, rx, ry, rz) = (d[1], d[2], d[3], d[4], d[5], d[6]);
            // Undo spacenavd's default axis swap and inversions.
            Some(SpaceEvent::Motion(SpaceMotion {
                translation: [x, z.saturating_neg(), y.saturating_neg()],
                rotation: [rx, rz.saturating_neg(), ry.saturating_neg()],
            }))
        }
        1 | 2 => u32::try_from(d[1]).ok().map(|index| SpaceEvent::Button { index, pressed: d[0] == 1 }),
        _ => None,
    }
}

/// Encodes the event spacenavd sends for `event` (its default axis settings;
/// `period_ms` for a motion). For tests and the fake daemon in them.
pub fn encode_spnav(event: &SpaceEvent, period_ms: i32) -> [u8; SPNAV_EVENT_SIZE] {
    let d: [i32; 8] = match *event {
        SpaceEvent::Motion(m) => {
            let [x, y, z] = m.translation;
            let [rx, ry, rz] = m.rotation;
            [0, x, z.saturating_neg(), y.saturating_neg(), rx, rz.saturating_neg(), ry.saturating_neg(), period_ms]
        }
        SpaceEvent::Button { index, pressed } => [if pressed { 1 } else { 2 }, index.min(i32::MAX as u32) as i32, 0, 0, 0, 0, 0, 0],
    };
    let mut out = [0u8; SPNAV_EVENT_SIZE];
    for (i, v) in d.iter().enumerate() {
        out[4 * i..4 * i + 4].copy_from_slice(&v.to_le_bytes());
    }
    out
}

/// The state HID reports update piecewise (translation and rotation may come
/// in separate reports; buttons as a mask).
#[derive(Debug, Clone, Default)]
pub struct HidDecoder {
    motion: SpaceMotion,
    buttons: u32,
}

impl HidDecoder {
    /// Decodes one report into `out` (cleared first): a motion when an axis
    /// report came, a press or release per button whose bit changed. Reports
    /// of other ids, or too short for their id, give nothing.
    pub fn report(&mut self, report: &[u8], out: &mut Vec<SpaceEvent>) {
        out.clear();
        match (report.first(), report.len()) {
            (Some(1), n) if n >= 7 => {
                self.motion.translation = [le_i16(report, 1), le_i16(report, 3), le_i16(report, 5)];
                if n >= 13 {
                    self.motion.rotation = [le_i16(report, 7), le_i16(report, 9), le_i16(report, 11)];
                }
                out.push(SpaceEvent::Motion(self.motion));
            }
            (Some(2), n) if n >= 7 => {
                self.motion.rotation = [le_i16(report, 1), le_i16(report, 3), le_i16(report, 5)];
                out.push(SpaceEvent::Motion(self.motion));
            }
            (Some(3), n) if n >= 2 => {
                let mut bytes = [0u8; 4];
                let k = (n - 1).min(4);
                bytes[..k].copy_from_slice(&report[1..1 + k]);
                let mask = u32::from_le_bytes(bytes);
                let changed = mask ^ self.buttons;
                self.buttons = mask;
                for index in 0..32 {
                    if changed & (1 << index) != 0 {
                        out.push(SpaceEvent::Button { index, pressed: mask & (1 << index) != 0 });
                    }
                }
            }
            _ => {}
        }
    }
}

/// Who a HID device is, from its `uevent` file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct HidIdentity {
    /// USB vendor id.
    pub vendor: u16,
    /// USB product id.
    pub product: u16,
    /// `HID_NAME` (e.g. `3Dconnexion SpaceNavigator`); empty when absent.
    pub name: String,
}

/// Reads `HID_ID=bus:vendor:product` (hex) and `HID_NAME=` from a `uevent` file's text.
pub fn parse_uevent(text: &str) -> Option<HidIdentity> {
    let mut id = None;
    let mut name = String::new();
    for line in text.lines() {
        if let Some(v) = line.strip_prefix("HID_ID=") {
            let mut parts = v.trim().split(':');
            let (_bus, vendor, product) = (parts.next()?, parts.next()?, parts.next()?);
            let vendor = u32::from_str_radix(vendor, 16).ok().and_then(|v| u16::try_from(v).ok())?;
            let product = u32::from_str_radix(product, 16).ok().and_then(|v| u16::try_from(v).ok())?;
            id = Some((vendor, product));
        } else if let Some(v) = line.strip_prefix("HID_NAME=") {
            name = v.trim().to_string();
        }
    }
    id.map(|(vendor, product)| HidIdentity { vendor, product, name })
}

/// 3Dconnexion's own vendor id: every product is a 6-DoF device.
pub const VENDOR_3DCONNEXION: u16 = 0x256f;
/// Logitech's vendor id, under which the older 3Dconnexion devices came.
pub const VENDOR_LOGITECH: u16 = 0x046d;
/// The 3Dconnexion products under Logitech's id (spacenavd `src/dev.c`,
/// `devid_list`): a Logitech keyboard or mouse is not taken for one.
pub const LOGITECH_3DCONNEXION_PRODUCTS: [u16; 12] = [0xc603, 0xc605, 0xc606, 0xc621, 0xc623, 0xc625, 0xc626, 0xc627, 0xc628, 0xc629, 0xc62b, 0xc640];

/// Whether the device is a 3Dconnexion 6-DoF device.
pub fn is_space_mouse(id: &HidIdentity) -> bool {
    id.vendor == VENDOR_3DCONNEXION
        || (id.vendor == VENDOR_LOGITECH && (LOGITECH_3DCONNEXION_PRODUCTS.contains(&id.product) || id.name.contains("3Dconnexion")))
}

/// The `socket = PATH` line of a `/etc/spnavrc` (where libspnav also looks).
pub fn socket_from_spnavrc(text: &str) -> Option<String> {
    text.lines().map(str::trim).filter(|l| !l.starts_with('#')).find_map(|l| {
        let (key, value) = l.split_once('=')?;
        (key.trim() == "socket" && !value.trim().is_empty()).then(|| value.trim().to_string())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A push to the right and away with a twist, in a SpaceNavigator's
    /// reports (built byte for byte in its format, no device at hand): report 1
    /// the translation, report 2 the rotation.
    const NAVIGATOR_TRANSLATION: [u8; 7] = [0x01, 0x78, 0x00, 0x38, 0xff, 0x23, 0x00];
    const NAVIGATOR_ROTATION: [u8; 7] = [0x02, 0xf6, 0xff, 0x3c, 0x00, 0xfa, 0x00];

    #[test]
    fn hid_reports_and_spacenavd_events_give_the_same_motion() {
        // x = 120, y = -200, z = 35; rx = -10, ry = 60, rz = 250.
        let expected = SpaceMotion { translation: [120, -200, 35], rotation: [-10, 60, 250] };
        let mut hid = HidDecoder::default();
        let mut out = Vec::new();
        hid.report(&NAVIGATOR_TRANSLATION, &mut out);
        hid.report(&NAVIGATOR_ROTATION, &mut out);
        assert_eq!(out, [SpaceEvent::Motion(expected)], "report 2 completes the motion report 1 began");
        // The same motion from a newer device: all six axes in report 1.
        let mut wireless = [0u8; 13];
        wireless[0] = 1;
        for (k, v) in [120i16, -200, 35, -10, 60, 250].iter().enumerate() {
            wireless[1 + 2 * k..3 + 2 * k].copy_from_slice(&v.to_le_bytes());
        }
        HidDecoder::default().report(&wireless, &mut out);
        assert_eq!(out, [SpaceEvent::Motion(expected)], "12-byte report 1");
        // spacenavd's event for it, its default axis settings applied by
        // hand: y and z swapped, then y, z, ry and rz inverted.
        let mut spnav = [0u8; SPNAV_EVENT_SIZE];
        for (k, v) in [0i32, 120, -35, 200, -10, -250, -60, 16].iter().enumerate() {
            spnav[4 * k..4 * k + 4].copy_from_slice(&v.to_le_bytes());
        }
        assert_eq!(decode_spnav(&spnav), Some(SpaceEvent::Motion(expected)));
        assert_eq!(encode_spnav(&SpaceEvent::Motion(expected), 16), spnav, "the encoder is the decoder's inverse");
    }

    #[test]
    fn buttons_from_both_sources() {
        let mut hid = HidDecoder::default();
        let mut out = Vec::new();
        hid.report(&[0x03, 0x01, 0x00], &mut out);
        assert_eq!(out, [SpaceEvent::Button { index: 0, pressed: true }]);
        hid.report(&[0x03, 0x02, 0x00], &mut out);
        assert_eq!(out, [SpaceEvent::Button { index: 0, pressed: false }, SpaceEvent::Button { index: 1, pressed: true }], "left up, right down");
        hid.report(&[0x03, 0x02, 0x00], &mut out);
        assert!(out.is_empty(), "an unchanged mask is no event");
        let press = encode_spnav(&SpaceEvent::Button { index: 1, pressed: true }, 0);
        assert_eq!(decode_spnav(&press), Some(SpaceEvent::Button { index: 1, pressed: true }));
        let mut release = press;
        release[0] = 2;
        assert_eq!(decode_spnav(&release), Some(SpaceEvent::Button { index: 1, pressed: false }));
        let mut device_event = press;
        device_event[0] = 3;
        assert_eq!(decode_spnav(&device_event), None, "a device event (protocol 1) is skipped");
        let mut negative = press;
        negative[4..8].copy_from_slice(&(-1i32).to_le_bytes());
        assert_eq!(decode_spnav(&negative), None, "no negative button number");
    }

    #[test]
    fn short_reports_and_extreme_values_never_panic() {
        let mut hid = HidDecoder::default();
        let mut out = Vec::new();
        for report in [&[][..], &[1], &[1, 2, 3], &[2, 0, 0, 0, 0, 0], &[3], &[7, 1, 2, 3, 4, 5, 6, 7]] {
            hid.report(report, &mut out);
            assert!(out.is_empty(), "{report:?}");
        }
        let mut spnav = [0u8; SPNAV_EVENT_SIZE];
        for k in 1..8 {
            spnav[4 * k..4 * k + 4].copy_from_slice(&i32::MIN.to_le_bytes());
        }
        let Some(SpaceEvent::Motion(m)) = decode_spnav(&spnav) else { panic!("a motion") };
        assert_eq!(m.translation[1], i32::MAX, "-i32::MIN saturates");
    }

    #[test]
    fn the_device_is_told_from_its_uevent() {
        let navigator = "DRIVER=hid-generic\nHID_ID=0003:0000046D:0000C626\nHID_NAME=3Dconnexion SpaceNavigator\nHID_PHYS=usb-0000:00:14.0-2/input0\n";
        let id = parse_uevent(navigator).expect("parsed");
        assert_eq!((id.vendor, id.product, id.name.as_str()), (0x046d, 0xc626, "3Dconnexion SpaceNavigator"));
        assert!(is_space_mouse(&id));
        let compact = parse_uevent("HID_ID=0003:0000256F:0000C635\nHID_NAME=3Dconnexion SpaceMouse Compact\n").expect("parsed");
        assert!(is_space_mouse(&compact));
        let keyboard = parse_uevent("HID_ID=0003:0000046D:0000C31C\nHID_NAME=Logitech USB Keyboard\n").expect("parsed");
        assert!(!is_space_mouse(&keyboard), "a Logitech keyboard is not a SpaceMouse");
        assert_eq!(parse_uevent("HID_ID=zz\n"), None);
        assert_eq!(parse_uevent("HID_ID=0003:FFFFFFFF:1\n"), None, "ids beyond 16 bits are refused");
        assert_eq!(socket_from_spnavrc("# socket = /x\nsensitivity = 1.0\nsocket = /run/spnav.sock\n").as_deref(), Some("/run/spnav.sock"));
        assert_eq!(socket_from_spnavrc("dead-zone = 2\n"), None);
    }
}
