//! The reference run on disk: a study's most expensive run is made once.
//!
//! In: a [`RunTrace`] and its key (blake3 of the format version, the running
//! executable's bytes (any change to the code that computed the trace makes
//! another key), the configured scenario, the run's settings, the motion and
//! the mesh's nodes and elements: [`key`]; `None` when the executable cannot
//! be read, and then nothing is cached). Out: `reference-<key>.trace` in the
//! cache folder, and the trace again on a later study with the same key.
//! Stays true: a file that is truncated, corrupt (its blake3 checksum), of
//! another format version or of another key is never used: [`load`] says why
//! and the study runs the reference again; the loaded trace equals the saved
//! one bit for bit (accuracy columns do not move); writing goes through a
//! temporary file and a rename, so a full disk or Ctrl-C leaves no half file.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::motion::{FrameKey, Motion};
use super::plan::Settings;
use super::runner::{FrameRecord, RunTrace};
use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::scenario::Scenario;
use crate::sim::{StageId, StageTimes};

/// Bumped whenever the layout below or what a trace means changes.
const FORMAT_VERSION: u32 = 1;
const MAGIC: &[u8; 8] = b"FISSREF\0";

/// blake3 of the running executable, read once: the build that computes a
/// trace. `None` when it cannot be read.
fn build_fingerprint() -> Option<[u8; 32]> {
    static FINGERPRINT: std::sync::OnceLock<Option<[u8; 32]>> = std::sync::OnceLock::new();
    *FINGERPRINT.get_or_init(|| {
        let exe = std::env::current_exe().ok()?;
        let bytes = std::fs::read(exe).ok()?;
        Some(*blake3::hash(&bytes).as_bytes())
    })
}

/// blake3 of everything that decides the reference's answers, the build
/// included; `None` (do not cache) when the executable cannot be read.
pub fn key(scene: &Scenario, settings: &Settings, motion: &Motion, mesh: &TetMesh) -> Option<[u8; 32]> {
    let build = build_fingerprint()?;
    let mut scene = scene.clone();
    // Where the compliance cache lives changes nothing the trace holds.
    scene.solver.cache_dir = None;
    let mut h = blake3::Hasher::new();
    h.update(&FORMAT_VERSION.to_le_bytes());
    h.update(&build);
    h.update(format!("{scene:?}\n{settings:?}\n{motion:?}").as_bytes());
    for p in &mesh.positions {
        for c in p.iter() {
            h.update(&c.to_bits().to_le_bytes());
        }
    }
    for t in &mesh.tets {
        for n in t {
            h.update(&n.to_le_bytes());
        }
    }
    Some(*h.finalize().as_bytes())
}

/// The file of `key` in `dir`.
pub fn path(dir: &Path, key: &[u8; 32]) -> PathBuf {
    let mut name = String::from("reference-");
    for b in &key[..8] {
        let _ = write!(name, "{b:02x}");
    }
    dir.join(name + ".trace")
}

/// Writes `trace` under `key` (through a temporary file and a rename).
pub fn save(dir: &Path, key: &[u8; 32], trace: &RunTrace) -> std::io::Result<PathBuf> {
    std::fs::create_dir_all(dir)?;
    let mut body = Vec::new();
    encode(trace, &mut body);
    let mut bytes = Vec::with_capacity(body.len() + 80);
    bytes.extend_from_slice(MAGIC);
    bytes.extend_from_slice(&FORMAT_VERSION.to_le_bytes());
    bytes.extend_from_slice(key);
    bytes.extend_from_slice(&(body.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&body);
    bytes.extend_from_slice(blake3::hash(&body).as_bytes());
    let file = path(dir, key);
    let tmp = file.with_extension("trace.tmp");
    std::fs::write(&tmp, &bytes)?;
    std::fs::rename(&tmp, &file)?;
    Ok(file)
}

/// The trace saved under `key`: `Ok(None)` when there is none, `Err(why)`
/// when a file is there but unusable (the caller warns and recomputes).
pub fn load(dir: &Path, key: &[u8; 32]) -> Result<Option<RunTrace>, String> {
    let file = path(dir, key);
    let bytes = match std::fs::read(&file) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(e) => return Err(format!("{}: {e}", file.display())),
    };
    decode_file(&bytes, key).map(Some).map_err(|why| format!("{}: {why}", file.display()))
}

fn decode_file(bytes: &[u8], key: &[u8; 32]) -> Result<RunTrace, String> {
    let mut r = Reader { bytes, at: 0 };
    if r.take(8)? != MAGIC {
        return Err("not a fissure reference trace".into());
    }
    let version = r.u32()?;
    if version != FORMAT_VERSION {
        return Err(format!("format version {version}, this build reads {FORMAT_VERSION}"));
    }
    if r.take(32)? != key {
        return Err("made for another scene, mesh, motion or settings".into());
    }
    let len = usize::try_from(r.u64()?).map_err(|_| "absurd length")?;
    let body = r.take(len)?;
    if r.take(32)? != blake3::hash(body).as_bytes() {
        return Err("checksum mismatch (corrupt)".into());
    }
    let trace = decode(&mut Reader { bytes: body, at: 0 })?;
    Ok(trace)
}

fn put_u32(out: &mut Vec<u8>, x: u32) {
    out.extend_from_slice(&x.to_le_bytes());
}
fn put_u64(out: &mut Vec<u8>, x: u64) {
    out.extend_from_slice(&x.to_le_bytes());
}
fn put_f64(out: &mut Vec<u8>, x: f64) {
    out.extend_from_slice(&x.to_bits().to_le_bytes());
}
fn put_vec3(out: &mut Vec<u8>, v: &Vec3) {
    v.iter().for_each(|c| put_f64(out, *c));
}

fn encode(t: &RunTrace, out: &mut Vec<u8>) {
    put_u64(out, t.nodes as u64);
    put_f64(out, t.build_s);
    put_u64(out, t.compliance_bytes as u64);
    out.push(t.compliance_cached as u8);
    put_u64(out, t.rest.len() as u64);
    t.rest.iter().for_each(|p| put_vec3(out, p));
    put_u64(out, t.triangles.len() as u64);
    t.triangles.iter().flatten().for_each(|&i| put_u32(out, i));
    put_u32(out, StageId::ALL.len() as u32);
    put_u64(out, t.frames.len() as u64);
    for f in &t.frames {
        out.push(f.key.phase);
        out.extend_from_slice(&f.key.distance_nm.to_le_bytes());
        for s in &f.times.seconds {
            out.push(s.is_some() as u8);
            put_f64(out, s.unwrap_or(0.0));
        }
        put_u32(out, f.contact);
        put_vec3(out, &f.force);
        put_u32(out, f.crossed);
        put_u32(out, f.penetrating);
        put_f64(out, f.max_penetration_m);
        put_f64(out, f.pressure_mmhg);
        put_u32(out, f.inverted);
    }
    put_u64(out, t.displacements.len() as u64);
    for d in &t.displacements {
        put_u64(out, d.len() as u64);
        d.iter().for_each(|u| put_vec3(out, u));
    }
}

struct Reader<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Result<&'a [u8], String> {
        let end = self.at.checked_add(n).filter(|&e| e <= self.bytes.len()).ok_or("truncated")?;
        let s = &self.bytes[self.at..end];
        self.at = end;
        Ok(s)
    }
    fn u8(&mut self) -> Result<u8, String> {
        Ok(self.take(1)?[0])
    }
    fn u32(&mut self) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4)?.try_into().map_err(|_| "truncated")?))
    }
    fn u64(&mut self) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8)?.try_into().map_err(|_| "truncated")?))
    }
    fn f64(&mut self) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64()?))
    }
    fn vec3(&mut self) -> Result<Vec3, String> {
        Ok(Vec3::new(self.f64()?, self.f64()?, self.f64()?))
    }
    /// A count of items of at least `item_bytes` each that the rest can hold.
    fn count(&mut self, item_bytes: usize) -> Result<usize, String> {
        let n = usize::try_from(self.u64()?).map_err(|_| "absurd count")?;
        if n.saturating_mul(item_bytes) > self.bytes.len() - self.at {
            return Err("truncated".into());
        }
        Ok(n)
    }
}

fn decode(r: &mut Reader) -> Result<RunTrace, String> {
    let nodes = usize::try_from(r.u64()?).map_err(|_| "absurd node count")?;
    let build_s = r.f64()?;
    let compliance_bytes = usize::try_from(r.u64()?).map_err(|_| "absurd size")?;
    let compliance_cached = r.u8()? != 0;
    let n = r.count(24)?;
    let rest = (0..n).map(|_| r.vec3()).collect::<Result<_, _>>()?;
    let n = r.count(12)?;
    let triangles = (0..n).map(|_| Ok([r.u32()?, r.u32()?, r.u32()?])).collect::<Result<_, String>>()?;
    if r.u32()? as usize != StageId::ALL.len() {
        return Err("made with another set of stages".into());
    }
    let n = r.count(9)?;
    let mut frames = Vec::with_capacity(n);
    for _ in 0..n {
        let phase = r.u8()?;
        let distance_nm = i64::from_le_bytes(r.take(8)?.try_into().map_err(|_| "truncated")?);
        let mut times = StageTimes::default();
        for s in times.seconds.iter_mut() {
            let some = r.u8()? != 0;
            let x = r.f64()?;
            *s = some.then_some(x);
        }
        frames.push(FrameRecord {
            key: FrameKey { phase, distance_nm },
            times,
            contact: r.u32()?,
            force: r.vec3()?,
            crossed: r.u32()?,
            penetrating: r.u32()?,
            max_penetration_m: r.f64()?,
            pressure_mmhg: r.f64()?,
            inverted: r.u32()?,
        });
    }
    let n = r.count(8)?;
    let mut displacements = Vec::with_capacity(n);
    for _ in 0..n {
        let m = r.count(24)?;
        displacements.push((0..m).map(|_| r.vec3()).collect::<Result<Vec<_>, _>>()?);
    }
    if r.at != r.bytes.len() {
        return Err("trailing bytes".into());
    }
    Ok(RunTrace { frames, displacements, rest, triangles, nodes, build_s, compliance_bytes, compliance_cached })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn trace() -> RunTrace {
        let mut times = StageTimes::default();
        times.set(StageId::Collision, 1.5e-3);
        RunTrace {
            frames: vec![FrameRecord {
                key: FrameKey { phase: 1, distance_nm: -7 },
                times,
                contact: 3,
                force: Vec3::new(0.1, -0.2, f64::MIN_POSITIVE),
                crossed: 1,
                penetrating: 2,
                max_penetration_m: 1e-5,
                pressure_mmhg: 6.5,
                inverted: 0,
            }],
            displacements: vec![vec![Vec3::new(1e-3, 0.0, -2e-3), Vec3::new(0.1 + 0.2, 0.0, 0.0)]],
            rest: vec![Vec3::zeros(), Vec3::x()],
            triangles: vec![[0, 1, 0]],
            nodes: 2,
            build_s: 3.25,
            compliance_bytes: 1234,
            compliance_cached: true,
        }
    }

    fn same(a: &RunTrace, b: &RunTrace) -> bool {
        let bits = |t: &RunTrace| {
            let mut v = Vec::new();
            encode(t, &mut v);
            v
        };
        a.frames == b.frames && bits(a) == bits(b)
    }

    #[test]
    fn a_saved_trace_loads_bit_for_bit_and_a_damaged_one_never() {
        let dir = std::env::temp_dir().join(format!("fissure-refcache-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let key = [7u8; 32];
        assert!(load(&dir, &key).expect("no file is not an error").is_none());
        let file = save(&dir, &key, &trace()).expect("saved");
        let back = load(&dir, &key).expect("readable").expect("present");
        assert!(same(&back, &trace()));
        assert!(load(&dir, &[8u8; 32]).expect("another key has no file").is_none());

        let bytes = std::fs::read(&file).expect("read");
        // Another key's file under this name, a truncated file, a flipped bit.
        let mut other = bytes.clone();
        other[12] ^= 1;
        std::fs::write(&file, &other).expect("write");
        assert!(load(&dir, &key).expect_err("another key").contains("another scene"));
        std::fs::write(&file, &bytes[..bytes.len() - 40]).expect("write");
        assert!(load(&dir, &key).expect_err("truncated").contains("truncated"));
        let mut flipped = bytes.clone();
        flipped[60] ^= 0x10;
        std::fs::write(&file, &flipped).expect("write");
        assert!(load(&dir, &key).expect_err("corrupt").contains("checksum"));
        let mut version = bytes.clone();
        version[8] = 99;
        std::fs::write(&file, &version).expect("write");
        assert!(load(&dir, &key).expect_err("version").contains("format version 99"));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
