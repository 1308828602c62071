//! OpenIGTLink wire format: the 58-byte header, CRC-64 (ECMA-182), TRANSFORM
//! decoding and SENSOR (force) encoding.
//!
//! In: raw bytes from a socket. Out: a [`Header`], then a [`Message`] (a
//! validated [`Transform`] or the type name of a message we skip). Stays true:
//! decoding never panics on any input (a proptest feeds random and truncated
//! bytes); every TRANSFORM that decodes has finite values and a rotation that is
//! orthonormal with determinant +1 within [`ORTHONORMAL_TOLERANCE`].
//!
//! Wire format (all big-endian), header v1 and v2 alike:
//! `u16 version | char[12] type | char[20] device | u32 seconds | u32 fraction
//! (2^-32 s) | u64 body size | u64 CRC-64 of the body`. Header version 2 puts a
//! 12-byte extended header at the start of the body (`u16 ext header size |
//! u16 metadata header size | u32 metadata size | u32 message id`), then the
//! content, then the metadata; the CRC covers the whole body.
//! TRANSFORM content: 12 float32, the rotation's columns (R11 R21 R31 R12 R22
//! R32 R13 R23 R33) then the translation (TX TY TZ) in millimetres.
//!
//! A TRANSFORM that carries no pose (PLUS's `Buttons` tool puts the stylus's
//! button states in the matrix's first column, see [`super::workspace`]) is
//! read with [`decode_body_raw`], which checks the CRC, the size and
//! finiteness but not orthonormality; [`decode_body`] adds that check.
//!
//! **Force feedback message** (what [`encode_force`] writes, for haptic bridges):
//! a header-version-1 `SENSOR` message whose device name is `Force_<spatula>`
//! (e.g. `Force_Left`), body = `u8 larray = 3 | u8 status = 0 | u64 unit =
//! newton (code 0x0B, exponent 1, no prefix: 0x02C4_0000_0000_0000) |
//! 3 x float64` = the reaction force on that spatula in newtons, world axes
//! (x, y, z). Body size 34 bytes; CRC-64 over it as for every message.

use crate::math::{Matrix3, Vec3};

/// Size of the OpenIGTLink header, bytes.
pub const HEADER_SIZE: usize = 58;
/// Size of the version-2 extended header at the start of the body, bytes.
pub const EXTENDED_HEADER_SIZE: usize = 12;
/// Size of the TRANSFORM content (12 float32), bytes.
pub const TRANSFORM_CONTENT_SIZE: usize = 48;
/// Largest body we accept, bytes; a larger declared size means a corrupt stream.
pub const MAX_BODY_SIZE: u64 = 16 * 1024 * 1024;
/// Largest allowed |R^T R - I| entry and |det R - 1| of a received rotation. The
/// matrix arrives as float32, so exact orthonormality is not expected.
pub const ORTHONORMAL_TOLERANCE: f64 = 1e-3;
/// The OpenIGTLink packed unit for newtons (SI derived 0x0B, exponent +1).
pub const UNIT_NEWTON: u64 = (0x0B_u64 << 54) | (1_u64 << 50);

/// Why a message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum IgtlError {
    #[error("message truncated: needed {needed} bytes, got {got}")]
    Truncated { needed: usize, got: usize },
    #[error("unsupported header version {version} (expected 1 or 2)")]
    UnsupportedVersion { version: u16 },
    #[error("declared body size {size} bytes exceeds the limit of {limit}")]
    BodyTooLarge { size: u64, limit: u64 },
    #[error(
        "{message_type} from '{device}': CRC mismatch (header {expected:#018x}, computed {computed:#018x})"
    )]
    CrcMismatch {
        message_type: String,
        device: String,
        expected: u64,
        computed: u64,
    },
    #[error("TRANSFORM from '{device}': extended header is inconsistent ({detail})")]
    BadExtendedHeader {
        device: String,
        detail: &'static str,
    },
    #[error("TRANSFORM from '{device}': content is {got} bytes, expected {expected}")]
    WrongContentSize {
        device: String,
        expected: usize,
        got: usize,
    },
    #[error("TRANSFORM from '{device}': value {index} is not finite")]
    NonFinite { device: String, index: usize },
    #[error("TRANSFORM from '{device}': rotation is not orthonormal with det +1 (error {error:e})")]
    NotOrthonormal { device: String, error: f64 },
}

/// A decoded message header.
#[derive(Debug, Clone, PartialEq)]
pub struct Header {
    /// Header format version (1 or 2).
    pub version: u16,
    /// Message type, e.g. `TRANSFORM` (trailing NULs removed).
    pub message_type: String,
    /// Device name (trailing NULs removed; invalid UTF-8 replaced).
    pub device: String,
    /// Timestamp, seconds since the Unix epoch.
    pub timestamp_s: f64,
    /// Body size, bytes (at most [`MAX_BODY_SIZE`]).
    pub body_size: u64,
    /// CRC-64 of the body as sent.
    pub crc: u64,
}

/// A validated TRANSFORM.
#[derive(Debug, Clone, PartialEq)]
pub struct Transform {
    /// Device name from the header.
    pub device: String,
    /// Timestamp, seconds since the Unix epoch.
    pub timestamp_s: f64,
    /// Rotation (orthonormal within [`ORTHONORMAL_TOLERANCE`], det +1).
    pub rotation: Matrix3<f64>,
    /// Translation, millimetres (as on the wire).
    pub translation_mm: Vec3,
}

/// A TRANSFORM whose values are finite but whose 3x3 part need not be a
/// rotation (see [`decode_body_raw`]).
#[derive(Debug, Clone, PartialEq)]
pub struct RawTransform {
    /// Device name from the header.
    pub device: String,
    /// Timestamp, seconds since the Unix epoch.
    pub timestamp_s: f64,
    /// The upper-left 3x3 block as sent (finite; not checked otherwise).
    pub matrix: Matrix3<f64>,
    /// The translation column as sent (finite; millimetres for a pose).
    pub translation: Vec3,
}

/// A decoded message whose TRANSFORM, if any, is not yet held to be a rotation.
#[derive(Debug, Clone, PartialEq)]
pub enum RawMessage {
    /// A TRANSFORM with finite values.
    Transform(RawTransform),
    /// A message of another type (its CRC was checked).
    Other { message_type: String, device: String },
}

/// A decoded message.
#[derive(Debug, Clone, PartialEq)]
pub enum Message {
    /// A TRANSFORM that passed every check.
    Transform(Transform),
    /// A message of another type (its CRC was checked); we ignore its content.
    Other {
        message_type: String,
        device: String,
    },
}

const CRC64_POLY: u64 = 0x42F0_E1EB_A9EA_3693;

const CRC64_TABLE: [u64; 256] = {
    let mut table = [0u64; 256];
    let mut i = 0;
    while i < 256 {
        let mut crc = (i as u64) << 56;
        let mut bit = 0;
        while bit < 8 {
            crc = if crc & (1 << 63) != 0 {
                (crc << 1) ^ CRC64_POLY
            } else {
                crc << 1
            };
            bit += 1;
        }
        table[i] = crc;
        i += 1;
    }
    table
};

/// CRC-64 as OpenIGTLink uses it (ECMA-182 polynomial, initial value 0, not
/// reflected, no final xor).
pub fn crc64(bytes: &[u8]) -> u64 {
    let mut crc = 0u64;
    for &b in bytes {
        crc = CRC64_TABLE[(((crc >> 56) as u8) ^ b) as usize] ^ (crc << 8);
    }
    crc
}

fn be_u16(b: &[u8], at: usize) -> u16 {
    u16::from_be_bytes([b[at], b[at + 1]])
}
fn be_u32(b: &[u8], at: usize) -> u32 {
    u32::from_be_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}
fn be_u64(b: &[u8], at: usize) -> u64 {
    let mut a = [0u8; 8];
    a.copy_from_slice(&b[at..at + 8]);
    u64::from_be_bytes(a)
}

fn fixed_str(b: &[u8]) -> String {
    let end = b.iter().position(|&c| c == 0).unwrap_or(b.len());
    String::from_utf8_lossy(&b[..end]).trim_end().to_string()
}

/// Decodes the 58-byte header at the start of `bytes`.
pub fn decode_header(bytes: &[u8]) -> Result<Header, IgtlError> {
    if bytes.len() < HEADER_SIZE {
        return Err(IgtlError::Truncated {
            needed: HEADER_SIZE,
            got: bytes.len(),
        });
    }
    let version = be_u16(bytes, 0);
    if version != 1 && version != 2 {
        return Err(IgtlError::UnsupportedVersion { version });
    }
    let message_type = fixed_str(&bytes[2..14]);
    let device = fixed_str(&bytes[14..34]);
    let seconds = be_u32(bytes, 34);
    let fraction = be_u32(bytes, 38);
    let timestamp_s = seconds as f64 + fraction as f64 / 4_294_967_296.0;
    let body_size = be_u64(bytes, 42);
    if body_size > MAX_BODY_SIZE {
        return Err(IgtlError::BodyTooLarge {
            size: body_size,
            limit: MAX_BODY_SIZE,
        });
    }
    let crc = be_u64(bytes, 50);
    Ok(Header {
        version,
        message_type,
        device,
        timestamp_s,
        body_size,
        crc,
    })
}

/// Decodes a body of the message `header` announced: checks the CRC, then for a
/// TRANSFORM the size, finiteness and orthonormality of its content.
pub fn decode_body(header: &Header, body: &[u8]) -> Result<Message, IgtlError> {
    match decode_body_raw(header, body)? {
        RawMessage::Transform(raw) => validate_rotation(raw).map(Message::Transform),
        RawMessage::Other { message_type, device } => Ok(Message::Other { message_type, device }),
    }
}

/// Holds a raw TRANSFORM's 3x3 block to be a rotation (orthonormal with det +1
/// within [`ORTHONORMAL_TOLERANCE`]).
pub fn validate_rotation(raw: RawTransform) -> Result<Transform, IgtlError> {
    let error = orthonormality_error(&raw.matrix);
    if error.is_nan() || error > ORTHONORMAL_TOLERANCE {
        return Err(IgtlError::NotOrthonormal { device: raw.device, error });
    }
    Ok(Transform { device: raw.device, timestamp_s: raw.timestamp_s, rotation: raw.matrix, translation_mm: raw.translation })
}

/// Like [`decode_body`] without the orthonormality check: the CRC, then for a
/// TRANSFORM the size and finiteness of its content. For TRANSFORMs that carry
/// data other than a pose (a stylus's buttons).
pub fn decode_body_raw(header: &Header, body: &[u8]) -> Result<RawMessage, IgtlError> {
    if (body.len() as u64) != header.body_size {
        return Err(IgtlError::Truncated {
            needed: header.body_size as usize,
            got: body.len(),
        });
    }
    let computed = crc64(body);
    if computed != header.crc {
        return Err(IgtlError::CrcMismatch {
            message_type: header.message_type.clone(),
            device: header.device.clone(),
            expected: header.crc,
            computed,
        });
    }
    if header.message_type != "TRANSFORM" {
        return Ok(RawMessage::Other {
            message_type: header.message_type.clone(),
            device: header.device.clone(),
        });
    }
    let content = transform_content(header, body)?;
    decode_transform_content(header, content).map(RawMessage::Transform)
}

fn transform_content<'a>(header: &Header, body: &'a [u8]) -> Result<&'a [u8], IgtlError> {
    if header.version == 1 {
        return Ok(body);
    }
    let bad = |detail| IgtlError::BadExtendedHeader {
        device: header.device.clone(),
        detail,
    };
    if body.len() < EXTENDED_HEADER_SIZE {
        return Err(bad("body shorter than the 12-byte extended header"));
    }
    let ext = be_u16(body, 0) as usize;
    let meta_header = be_u16(body, 2) as usize;
    let meta = be_u32(body, 4) as usize;
    if ext < EXTENDED_HEADER_SIZE {
        return Err(bad("extended header size below 12"));
    }
    let tail = meta_header
        .checked_add(meta)
        .ok_or_else(|| bad("metadata size overflows"))?;
    let end = body
        .len()
        .checked_sub(tail)
        .ok_or_else(|| bad("metadata larger than the body"))?;
    if end < ext {
        return Err(bad("extended header and metadata overlap"));
    }
    Ok(&body[ext..end])
}

fn decode_transform_content(header: &Header, content: &[u8]) -> Result<RawTransform, IgtlError> {
    if content.len() != TRANSFORM_CONTENT_SIZE {
        return Err(IgtlError::WrongContentSize {
            device: header.device.clone(),
            expected: TRANSFORM_CONTENT_SIZE,
            got: content.len(),
        });
    }
    let mut v = [0f64; 12];
    for (index, slot) in v.iter_mut().enumerate() {
        let x = f32::from_bits(be_u32(content, 4 * index));
        if !x.is_finite() {
            return Err(IgtlError::NonFinite {
                device: header.device.clone(),
                index,
            });
        }
        *slot = x as f64;
    }
    // Columns first: v[0..3] is the first column.
    let matrix = Matrix3::new(v[0], v[3], v[6], v[1], v[4], v[7], v[2], v[5], v[8]);
    Ok(RawTransform {
        device: header.device.clone(),
        timestamp_s: header.timestamp_s,
        matrix,
        translation: Vec3::new(v[9], v[10], v[11]),
    })
}

/// max(|R^T R - I| entries, |det R - 1|): 0 for a proper rotation.
pub fn orthonormality_error(r: &Matrix3<f64>) -> f64 {
    let gram = r.transpose() * r - Matrix3::identity();
    let worst = gram.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    worst.max((r.determinant() - 1.0).abs())
}

fn write_header(
    out: &mut Vec<u8>,
    message_type: &str,
    device: &str,
    timestamp_s: f64,
    body: &[u8],
) {
    out.extend_from_slice(&1u16.to_be_bytes());
    let mut name = [0u8; 12];
    let t = message_type.as_bytes();
    name[..t.len().min(12)].copy_from_slice(&t[..t.len().min(12)]);
    out.extend_from_slice(&name);
    let mut dev = [0u8; 20];
    let d = device.as_bytes();
    dev[..d.len().min(20)].copy_from_slice(&d[..d.len().min(20)]);
    out.extend_from_slice(&dev);
    let ts = if timestamp_s.is_finite() && timestamp_s >= 0.0 {
        timestamp_s
    } else {
        0.0
    };
    let seconds = ts.floor().min(u32::MAX as f64) as u32;
    let fraction = ((ts - ts.floor()) * 4_294_967_296.0).min(u32::MAX as f64) as u32;
    out.extend_from_slice(&seconds.to_be_bytes());
    out.extend_from_slice(&fraction.to_be_bytes());
    out.extend_from_slice(&(body.len() as u64).to_be_bytes());
    out.extend_from_slice(&crc64(body).to_be_bytes());
}

/// Encodes a header-version-1 TRANSFORM (rotation columns, translation in mm).
/// Used by tests and by tools that replay poses to another OpenIGTLink peer.
pub fn encode_transform(
    device: &str,
    timestamp_s: f64,
    rotation: &Matrix3<f64>,
    translation_mm: &Vec3,
) -> Vec<u8> {
    let mut out = Vec::with_capacity(TRANSFORM_MESSAGE_SIZE);
    encode_transform_into(&mut out, device, timestamp_s, rotation, translation_mm);
    out
}

/// Size of an encoded header-version-1 TRANSFORM, bytes.
pub const TRANSFORM_MESSAGE_SIZE: usize = HEADER_SIZE + TRANSFORM_CONTENT_SIZE;

/// [`encode_transform`] into `out` (cleared first; no allocation once `out`
/// has [`TRANSFORM_MESSAGE_SIZE`] capacity). The translation column is written
/// as given: millimetres for a pose, newtons for PLUS's force tool.
pub fn encode_transform_into(out: &mut Vec<u8>, device: &str, timestamp_s: f64, rotation: &Matrix3<f64>, translation: &Vec3) {
    let mut body = [0u8; TRANSFORM_CONTENT_SIZE];
    let mut at = 0;
    for col in 0..3 {
        for row in 0..3 {
            body[at..at + 4].copy_from_slice(&(rotation[(row, col)] as f32).to_be_bytes());
            at += 4;
        }
    }
    for k in 0..3 {
        body[at..at + 4].copy_from_slice(&(translation[k] as f32).to_be_bytes());
        at += 4;
    }
    out.clear();
    write_header(out, "TRANSFORM", device, timestamp_s, &body);
    out.extend_from_slice(&body);
}

/// Size of an encoded force message, bytes.
pub const FORCE_MESSAGE_SIZE: usize = HEADER_SIZE + 10 + 24;

/// Encodes the force-feedback `SENSOR` message (see the module docs) into `out`
/// (cleared first; no allocation once `out` has [`FORCE_MESSAGE_SIZE`] capacity).
/// `spatula` is appended to `Force_` and cut to the 20-byte device-name field.
pub fn encode_force(out: &mut Vec<u8>, spatula: &str, timestamp_s: f64, force_n: [f64; 3]) {
    let mut body = [0u8; 34];
    body[0] = 3;
    body[1] = 0;
    body[2..10].copy_from_slice(&UNIT_NEWTON.to_be_bytes());
    for (k, f) in force_n.iter().enumerate() {
        body[10 + 8 * k..18 + 8 * k].copy_from_slice(&f.to_be_bytes());
    }
    let mut name = [0u8; 20];
    let prefix = b"Force_";
    name[..prefix.len()].copy_from_slice(prefix);
    let s = spatula.as_bytes();
    let n = s.len().min(20 - prefix.len());
    name[prefix.len()..prefix.len() + n].copy_from_slice(&s[..n]);
    let end = name.iter().position(|&c| c == 0).unwrap_or(20);
    let device = String::from_utf8_lossy(&name[..end]);
    out.clear();
    write_header(out, "SENSOR", &device, timestamp_s, &body);
    out.extend_from_slice(&body);
}

/// Decodes a SENSOR body written by [`encode_force`]: `(unit, values)`, or
/// `None` when the body is not a well-formed SENSOR body.
pub fn decode_sensor_body(body: &[u8]) -> Option<(u64, Vec<f64>)> {
    let count = *body.first()? as usize;
    if body.len() != 10 + 8 * count {
        return None;
    }
    let unit = be_u64(body, 2);
    Some((
        unit,
        (0..count)
            .map(|k| f64::from_bits(be_u64(body, 10 + 8 * k)))
            .collect(),
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn rot_z(angle: f64) -> Matrix3<f64> {
        *nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), angle).matrix()
    }

    #[test]
    fn crc64_matches_the_ecma182_check_value() {
        // CRC-64/ECMA-182 check value for "123456789" (init 0, no reflection, no xorout).
        assert_eq!(crc64(b"123456789"), 0x6C40_DF5F_0B49_7347);
        assert_eq!(crc64(b""), 0);
    }

    #[test]
    fn transform_round_trips() {
        let r = rot_z(0.3);
        let t = Vec3::new(12.5, -3.0, 40.25);
        let bytes = encode_transform("SpatulaL", 1234.5, &r, &t);
        let header = decode_header(&bytes).expect("header");
        assert_eq!(header.message_type, "TRANSFORM");
        assert_eq!(header.device, "SpatulaL");
        assert!((header.timestamp_s - 1234.5).abs() < 1e-6);
        let msg = decode_body(&header, &bytes[HEADER_SIZE..]).expect("body");
        let Message::Transform(tr) = msg else {
            panic!("expected a TRANSFORM, got {msg:?}")
        };
        assert!(
            (tr.rotation - r).abs().max() < 1e-7,
            "rotation {:?}",
            tr.rotation
        );
        assert!((tr.translation_mm - t).norm() < 1e-5);
    }

    fn v2_message(content: &[u8], metadata_header: &[u8], metadata: &[u8]) -> Vec<u8> {
        let mut body = Vec::new();
        body.extend_from_slice(&12u16.to_be_bytes());
        body.extend_from_slice(&(metadata_header.len() as u16).to_be_bytes());
        body.extend_from_slice(&(metadata.len() as u32).to_be_bytes());
        body.extend_from_slice(&7u32.to_be_bytes());
        body.extend_from_slice(content);
        body.extend_from_slice(metadata_header);
        body.extend_from_slice(metadata);
        let mut out = Vec::new();
        write_header(&mut out, "TRANSFORM", "Tool", 5.0, &body);
        out[0..2].copy_from_slice(&2u16.to_be_bytes());
        out.extend_from_slice(&body);
        out
    }

    #[test]
    fn header_v2_with_metadata_decodes() {
        let v1 = encode_transform("Tool", 5.0, &rot_z(-1.0), &Vec3::new(1.0, 2.0, 3.0));
        let content = &v1[HEADER_SIZE..];
        // One metadata entry: key "k" (1 byte), encoding 3, value "vv" (2 bytes).
        let meta_header = [0u8, 1, 0, 1, 0, 3, 0, 0, 0, 2];
        let bytes = v2_message(content, &meta_header, b"kvv");
        let header = decode_header(&bytes).expect("header");
        assert_eq!(header.version, 2);
        let Message::Transform(tr) = decode_body(&header, &bytes[HEADER_SIZE..]).expect("v2 body")
        else {
            panic!("expected a TRANSFORM")
        };
        assert!((tr.translation_mm - Vec3::new(1.0, 2.0, 3.0)).norm() < 1e-6);
        // Metadata sizes pointing past the body are refused, not sliced out of range.
        let broken = v2_message(content, &[0u8; 4], &[]);
        let mut broken = broken;
        broken[HEADER_SIZE + 4..HEADER_SIZE + 8].copy_from_slice(&1000u32.to_be_bytes());
        let crc = crc64(&broken[HEADER_SIZE..]);
        broken[50..58].copy_from_slice(&crc.to_be_bytes());
        let header = decode_header(&broken).expect("header");
        assert!(matches!(
            decode_body(&header, &broken[HEADER_SIZE..]),
            Err(IgtlError::BadExtendedHeader { .. })
        ));
    }

    #[test]
    fn refuses_bad_crc_nan_and_skew() {
        let mut bytes = encode_transform("T", 0.0, &rot_z(0.1), &Vec3::zeros());
        bytes[HEADER_SIZE + 3] ^= 0x40;
        let header = decode_header(&bytes).expect("header");
        assert!(
            matches!(
                decode_body(&header, &bytes[HEADER_SIZE..]),
                Err(IgtlError::CrcMismatch { .. })
            ),
            "flipped bit must fail the CRC"
        );

        let mut r = rot_z(0.1);
        r[(0, 0)] = f64::NAN;
        let bytes = encode_transform("T", 0.0, &r, &Vec3::zeros());
        let header = decode_header(&bytes).expect("header");
        assert!(matches!(
            decode_body(&header, &bytes[HEADER_SIZE..]),
            Err(IgtlError::NonFinite { index: 0, .. })
        ));

        let skew = rot_z(0.1) * 1.1;
        let bytes = encode_transform("T", 0.0, &skew, &Vec3::zeros());
        let header = decode_header(&bytes).expect("header");
        assert!(
            matches!(
                decode_body(&header, &bytes[HEADER_SIZE..]),
                Err(IgtlError::NotOrthonormal { .. })
            ),
            "a scaled matrix is not a rotation"
        );

        let mirror = Matrix3::from_diagonal(&Vec3::new(1.0, 1.0, -1.0));
        let bytes = encode_transform("T", 0.0, &mirror, &Vec3::zeros());
        let header = decode_header(&bytes).expect("header");
        assert!(
            matches!(
                decode_body(&header, &bytes[HEADER_SIZE..]),
                Err(IgtlError::NotOrthonormal { .. })
            ),
            "a reflection (det -1) is not a rotation"
        );
    }

    #[test]
    fn a_raw_transform_keeps_a_matrix_that_is_no_rotation() {
        // PLUS's Buttons tool: button 1 pressed, the rest of the 3x3 block zero.
        let mut buttons = Matrix3::zeros();
        buttons[(0, 0)] = 1.0;
        let bytes = encode_transform("ButtonsToBase", 2.0, &buttons, &Vec3::zeros());
        let header = decode_header(&bytes).expect("header");
        let RawMessage::Transform(raw) = decode_body_raw(&header, &bytes[HEADER_SIZE..]).expect("raw body") else {
            panic!("expected a TRANSFORM")
        };
        assert_eq!((raw.device.as_str(), raw.matrix), ("ButtonsToBase", buttons));
        assert!(matches!(decode_body(&header, &bytes[HEADER_SIZE..]), Err(IgtlError::NotOrthonormal { .. })), "no rotation: refused as a pose");
        let mut out = Vec::with_capacity(TRANSFORM_MESSAGE_SIZE);
        encode_transform_into(&mut out, "ButtonsToBase", 2.0, &buttons, &Vec3::zeros());
        assert_eq!(out, bytes, "the buffer form writes the same message");
        let mut nan = buttons;
        nan[(2, 1)] = f64::NAN;
        let bytes = encode_transform("ButtonsToBase", 2.0, &nan, &Vec3::zeros());
        let header = decode_header(&bytes).expect("header");
        assert!(matches!(decode_body_raw(&header, &bytes[HEADER_SIZE..]), Err(IgtlError::NonFinite { index: 5, .. })), "a NaN is refused raw too");
    }

    #[test]
    fn refuses_wrong_size_and_huge_body() {
        let mut bytes = encode_transform("T", 0.0, &Matrix3::identity(), &Vec3::zeros());
        bytes.truncate(bytes.len() - 4);
        let body = bytes[HEADER_SIZE..].to_vec();
        bytes[42..50].copy_from_slice(&(body.len() as u64).to_be_bytes());
        bytes[50..58].copy_from_slice(&crc64(&body).to_be_bytes());
        let header = decode_header(&bytes).expect("header");
        assert!(matches!(
            decode_body(&header, &body),
            Err(IgtlError::WrongContentSize {
                expected: 48,
                got: 44,
                ..
            })
        ));
        bytes[42..50].copy_from_slice(&u64::MAX.to_be_bytes());
        assert!(matches!(
            decode_header(&bytes),
            Err(IgtlError::BodyTooLarge { .. })
        ));
        assert!(matches!(
            decode_header(&bytes[..20]),
            Err(IgtlError::Truncated {
                needed: 58,
                got: 20
            })
        ));
    }

    #[test]
    fn force_message_is_a_newton_sensor() {
        let mut out = Vec::with_capacity(FORCE_MESSAGE_SIZE);
        encode_force(&mut out, "Left", 10.25, [0.5, -1.25, 3.0]);
        assert_eq!(out.len(), FORCE_MESSAGE_SIZE);
        let header = decode_header(&out).expect("header");
        assert_eq!(header.message_type, "SENSOR");
        assert_eq!(header.device, "Force_Left");
        assert_eq!(header.body_size, 34);
        assert!(
            matches!(
                decode_body(&header, &out[HEADER_SIZE..]),
                Ok(Message::Other { .. })
            ),
            "CRC must match"
        );
        let (unit, values) = decode_sensor_body(&out[HEADER_SIZE..]).expect("sensor body");
        assert_eq!(unit, UNIT_NEWTON);
        assert_eq!(unit, 0x02C4_0000_0000_0000, "documented constant");
        assert_eq!(values, vec![0.5, -1.25, 3.0]);
    }

    proptest! {
        #[test]
        fn random_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..200)) {
            if let Ok(header) = decode_header(&bytes) {
                let body = &bytes[HEADER_SIZE.min(bytes.len())..];
                let _ = decode_body(&header, body);
            }
        }

        #[test]
        fn truncated_or_mutated_transforms_never_panic(cut in 0usize..106, flip in 0usize..106, bit in 0u8..8, version2 in any::<bool>()) {
            let mut bytes = encode_transform("T", 3.0, &rot_z(0.7), &Vec3::new(1.0, 2.0, 3.0));
            if version2 { bytes[1] = 2; }
            if flip < bytes.len() { bytes[flip] ^= 1 << bit; }
            let cut = cut.min(bytes.len());
            let bytes = &bytes[..cut];
            if let Ok(header) = decode_header(bytes) {
                let body = &bytes[HEADER_SIZE..];
                let result = decode_body(&header, body);
                if let Ok(Message::Transform(t)) = result {
                    prop_assert!(orthonormality_error(&t.rotation) <= ORTHONORMAL_TOLERANCE);
                    prop_assert!(t.translation_mm.iter().all(|x| x.is_finite()));
                }
            }
        }
    }
}
