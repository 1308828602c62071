//! Hardened entrances: bad poses from every input are refused and the last good
//! pose holds; a missing or corrupt compliance cache is rebuilt, never trusted;
//! a FIFO, a device, a directory or an oversize file where a scenario, mesh,
//! surface or trajectory should be is refused at once, naming the file;
//! a full disk (or a file-size limit) while writing replay output ends with a
//! clear error, the rows already written intact and summary.json complete or
//! absent (never empty or cut); a dropped OpenIGTLink client
//! or gamepad leaves the last good state; a recording cut off at any row (the
//! window closed) is replayable. The parsers' never-panic properties live in
//! `mesh_parsers_fuzz.rs`, `scenario_parsers_never_panic.rs` and the igtl codec's
//! unit tests; the `cargo fuzz` targets in `fuzz/` run the same entry points.

use crate::common;
use crate::fem_common;

use fissure::fem::{Compliance, ComplianceStorage, FemModel, FemOptions, Material, RegionMaterials};
use fissure::fsio::{Cap, read_regular};
use fissure::geometry::Pose;
use fissure::input::igtl::{IgtlConfig, IgtlServer};
use fissure::input::igtl_codec::{decode_body, decode_header, encode_transform, HEADER_SIZE};
use fissure::input::PoseGuard;
use fissure::math::{Matrix3, Quat, Vec3};
use fissure::scenario::{Scenario, Trajectory, TrajectoryRecorder};
use fissure::sim::replay::{ReplayOptions, replay};
use fissure::sim::{FrameInput, Pipeline};
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

// ---------------------------------------------------------------- poses

fn bad_poses(good: Pose) -> Vec<(&'static str, Pose)> {
    let mut v = Vec::new();
    let mut p = good;
    p.position.x = f64::NAN;
    v.push(("NaN position", p));
    let mut p = good;
    p.position.z = f64::INFINITY;
    v.push(("infinite position", p));
    let mut p = good;
    p.rotation = Quat::new_unchecked(good.rotation.into_inner() * 1.1);
    v.push(("quaternion of norm 1.1", p));
    let mut p = good;
    p.rotation = Quat::new_unchecked(nalgebra::Quaternion::new(0.0, 0.0, 0.0, 0.0));
    v.push(("zero quaternion", p));
    let mut p = good;
    p.rotation = Quat::new_unchecked(nalgebra::Quaternion::new(f64::NAN, 0.0, 0.0, 0.0));
    v.push(("NaN quaternion", p));
    v
}

fn two_blade_block(dir: &Path) -> (Pipeline, fissure::sim::SimState) {
    use common::scenes::{Blade, Scene};
    let mesh = common::block(6, 6, 3, Vec3::new(40.0, 40.0, 20.0), Vec3::new(-20.0, -20.0, 0.0));
    let blade = |name, base| Blade { along: 4, across: 2, ..Blade::flat(name, base) };
    Scene::new(mesh, vec![blade("a", [-18.0, -5.0, 21.0]), blade("b", [-2.0, 5.0, 21.0])]).build(dir)
}

#[test]
fn pipeline_refuses_every_bad_pose_and_holds_the_last_good_one() {
    // Two identical pipelines; the twin gets the last good pose wherever the other gets a bad one.
    let dir = tempfile::tempdir().unwrap();
    let (mut p, mut state) = two_blade_block(dir.path());
    let twin_dir = tempfile::tempdir().unwrap();
    let (mut twin, mut twin_state) = two_blade_block(twin_dir.path());
    let pressed = |x: f64, y: f64| Pose { position: Vec3::new(x, y, 0.0195), rotation: Quat::identity() };
    let (a, b) = (pressed(-0.018, -0.005), pressed(-0.002, 0.005));
    for _ in 0..2 {
        p.step(&mut state, &FrameInput { poses: vec![Some(a), Some(b)] }).unwrap();
        twin.step(&mut twin_state, &FrameInput { poses: vec![Some(a), Some(b)] }).unwrap();
    }
    assert!(p.last_constraints().len() > 0);
    for (what, bad) in bad_poses(a) {
        // Spatula a gets the bad pose, b holds: the frame must equal the twin's frame with a's last good pose.
        let r = p.step(&mut state, &FrameInput { poses: vec![Some(bad), Some(b)] }).unwrap_or_else(|e| panic!("{what}: {e}")).clone();
        twin.step(&mut twin_state, &FrameInput { poses: vec![Some(a), Some(b)] }).unwrap();
        assert_eq!(r.rejected_poses, 1, "{what}: exactly one pose refused");
        assert_eq!(state.poses[0], a, "{what}: the last good pose of spatula a holds");
        assert_eq!(state.surface_displacement, twin_state.surface_displacement, "{what}: the bad pose must act as the last good one (bit for bit)");
        assert_eq!(p.state_hash(&state).expect("hash"), twin.state_hash(&twin_state).expect("hash"), "{what}: His-flags too");
        // A bad pose for a, a good new one for b: only a's is refused.
        let b2 = pressed(-0.002, 0.0045);
        let r = p.step(&mut state, &FrameInput { poses: vec![Some(bad), Some(b2)] }).unwrap().clone();
        assert_eq!(r.rejected_poses, 1, "{what}: only a's pose refused");
        assert_eq!((state.poses[0], state.poses[1]), (a, b2), "{what}: a holds, b moves");
        assert!(state.surface_positions.iter().all(|x| x.iter().all(|c| c.is_finite())), "{what}: the surface stays finite");
        twin.step(&mut twin_state, &FrameInput { poses: vec![Some(a), Some(b2)] }).unwrap();
        assert_eq!(state.surface_displacement, twin_state.surface_displacement, "{what}: and with b moving");
        // Back to the good poses.
        p.step(&mut state, &FrameInput { poses: vec![Some(a), Some(b)] }).unwrap();
        twin.step(&mut twin_state, &FrameInput { poses: vec![Some(a), Some(b)] }).unwrap();
    }
}

#[test]
fn pose_guard_refuses_bad_poses_and_counts_them() {
    let good = Pose { position: Vec3::new(0.01, 0.0, 0.0), rotation: Quat::identity() };
    let mut guard = PoseGuard::new(good, "test");
    let bad = bad_poses(good);
    for (what, p) in &bad {
        assert_eq!(guard.offer(*p), good, "{what}: the guard must hold the last good pose");
    }
    assert_eq!(guard.rejected(), bad.len() as u64);
    let next = Pose { position: Vec3::new(0.02, 0.0, 0.0), rotation: Quat::identity() };
    assert_eq!(guard.offer(next), next, "a good pose after bad ones is taken");
}

#[test]
fn trajectory_rows_with_nan_inf_or_non_unit_quaternions_are_refused_with_their_line() {
    let header = "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0.0,0,0,0,0,1,0,0,0\n";
    for (row, needle) in [
        ("0.1,0,NaN,0,0,1,0,0,0", "x_mm"),
        ("0.1,0,0,inf,0,1,0,0,0", "y_mm"),
        ("0.1,0,0,0,1e400,1,0,0,0", "z_mm"),
        ("0.1,0,0,0,0,2,0,0,0", "unit"),
        ("0.1,0,0,0,0,0,0,0,0", "unit"),
        ("0.1,0,0,0,0,NaN,0,0,0", "qw"),
    ] {
        let text = format!("{header}{row}\n");
        let e = Trajectory::parse(&text, Path::new("walk.csv")).expect_err(row).to_string();
        assert!(e.contains("walk.csv:3"), "the error must name the file and line 3: {e}");
        assert!(e.contains(needle), "the error for `{row}` must name `{needle}`: {e}");
    }
}

#[test]
fn scenario_poses_with_non_finite_values_or_non_unit_quaternions_are_refused_naming_the_field() {
    let text = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sylvian.ron")).unwrap();
    let origin = Path::new(concat!(env!("CARGO_MANIFEST_DIR"), "/config/sylvian.ron"));
    for (set, field) in [
        ("spatulas[0].pose.rotation=Quaternion(2.0, 0.0, 0.0, 0.0)", "rotation"),
        ("spatulas[0].pose.rotation=Quaternion(0.0, 0.0, 0.0, 0.0)", "rotation"),
        ("spatulas[0].pose.position_mm=(1e400, 0.0, 0.0)", "position_mm"),
        ("spatulas[1].pose.position_mm=(NaN, 0.0, 0.0)", "position_mm"),
        ("spatulas[1].pose.rotation=LookAt(direction: (1.0, 0.0, 0.0), up: (2.0, 0.0, 0.0))", "rotation"),
    ] {
        let e = Scenario::from_str(&text, origin, &[set.to_string()]).expect_err(set).to_string();
        assert!(e.contains(field), "`--set {set}` must be refused naming `{field}`: {e}");
    }
}

fn rotation_z(deg: f64) -> Matrix3<f64> {
    *nalgebra::Rotation3::from_axis_angle(&Vec3::z_axis(), deg.to_radians()).matrix()
}

#[test]
fn igtl_decoder_refuses_nan_and_non_orthonormal_transforms() {
    let decode = |bytes: &[u8]| {
        let h = decode_header(&bytes[..HEADER_SIZE])?;
        decode_body(&h, &bytes[HEADER_SIZE..])
    };
    assert!(decode(&encode_transform("Left", 1.0, &rotation_z(30.0), &Vec3::new(1.0, 2.0, 3.0))).is_ok(), "a good transform decodes");
    let nan = encode_transform("Left", 1.0, &rotation_z(30.0), &Vec3::new(f64::NAN, 2.0, 3.0));
    assert!(decode(&nan).is_err(), "a NaN translation must be refused");
    let inf = encode_transform("Left", 1.0, &rotation_z(30.0), &Vec3::new(f64::INFINITY, 2.0, 3.0));
    assert!(decode(&inf).is_err(), "an infinite translation must be refused");
    let scaled = encode_transform("Left", 1.0, &(rotation_z(30.0) * 1.1), &Vec3::zeros());
    assert!(decode(&scaled).is_err(), "a scaled rotation must be refused");
    let mut mirror = rotation_z(30.0);
    mirror.set_column(2, &-mirror.column(2).into_owned());
    assert!(decode(&encode_transform("Left", 1.0, &mirror, &Vec3::zeros())).is_err(), "a reflection (det -1) must be refused");
}

fn wait_for(mut done: impl FnMut() -> bool, what: &str) {
    let start = Instant::now();
    while !done() {
        assert!(start.elapsed() < Duration::from_secs(20), "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

#[test]
fn igtl_server_holds_the_last_good_pose_through_bad_messages_and_a_dropped_client() {
    let config = IgtlConfig { bind: std::net::SocketAddr::from(([127, 0, 0, 1], 0)), ..IgtlConfig::default() };
    let server = IgtlServer::start(&config).expect("server on an ephemeral port");
    let addr = server.local_addr();
    let mut client = std::net::TcpStream::connect(addr).expect("connect");
    client.write_all(&encode_transform("Left", 1.0, &rotation_z(30.0), &Vec3::new(10.0, -20.0, 35.5))).unwrap();
    wait_for(|| server.latest("Left").is_some(), "the first pose");
    let good = server.latest("Left").unwrap();
    // Bad messages: NaN, non-orthonormal, a corrupt CRC.
    client.write_all(&encode_transform("Left", 2.0, &rotation_z(30.0), &Vec3::new(f64::NAN, 0.0, 0.0))).unwrap();
    client.write_all(&encode_transform("Left", 3.0, &(rotation_z(10.0) * 1.2), &Vec3::zeros())).unwrap();
    wait_for(|| server.stats().messages_rejected >= 2, "two rejections");
    assert_eq!(server.latest("Left").unwrap(), good, "refused messages must leave the last good pose");
    // Drop the client mid-message: half a header, then close.
    let half = encode_transform("Left", 4.0, &rotation_z(60.0), &Vec3::zeros());
    client.write_all(&half[..20]).unwrap();
    drop(client);
    wait_for(|| server.stats().clients_dropped >= 1, "the drop to be noticed");
    assert_eq!(server.latest("Left").unwrap(), good, "a dropped client leaves its last good pose");
    assert!(good.pose.is_valid());
    // A new client is served.
    let mut again = std::net::TcpStream::connect(addr).expect("reconnect");
    again.write_all(&encode_transform("Left", 5.0, &rotation_z(45.0), &Vec3::new(1.0, 2.0, 3.0))).unwrap();
    wait_for(|| server.latest("Left").is_some_and(|p| p.sequence == good.sequence + 1), "the reconnected client's pose");
    let p = server.latest("Left").unwrap();
    assert!((p.pose.position - Vec3::new(0.001, 0.002, 0.003)).norm() < 1e-9, "mm -> m: {:?}", p.pose.position);
    println!("igtl: {:?}", server.stats());
}

#[test]
fn unplugged_gamepad_stops_the_spatula() {
    use fissure::input::gamepad::{GamepadController, GamepadMapping, PadAxis, PadEvent};
    let mut pad = GamepadController::new(GamepadMapping::default());
    pad.apply(PadEvent::Connected);
    pad.apply(PadEvent::Axis(PadAxis::LeftStickY, 1.0));
    assert!(!pad.command().velocity.is_zero(), "a full stick moves the spatula");
    pad.apply(PadEvent::Disconnected);
    assert!(pad.command().velocity.is_zero(), "an unplugged pad must stop the spatula: {:?}", pad.command().velocity);
    pad.apply(PadEvent::Axis(PadAxis::LeftStickX, f32::NAN));
    assert!(pad.command().velocity.is_zero(), "a NaN axis reads as 0");
}

#[test]
fn a_recording_cut_off_at_any_row_is_replayable() {
    // The window closes at an arbitrary moment: the recorder is dropped without any finish call.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("rec.csv");
    {
        let mut rec = TrajectoryRecorder::create(&path).expect("recorder");
        for k in 0..50 {
            let pose = Pose { position: Vec3::new(0.001 * k as f64, 0.0, 0.02), rotation: Quat::identity() };
            rec.record(0.01 * k as f64, k % 2, &pose).expect("record");
        }
    }
    let t = Trajectory::load(&path).expect("the dropped recording loads");
    assert_eq!(t.samples(0).len() + t.samples(1).len(), 50, "every recorded row is in the file");
    // A crash mid-row leaves a partial last line: every complete row before it is still readable.
    let text = std::fs::read_to_string(&path).unwrap();
    let cut = &text[..text.len() - 7];
    let e = Trajectory::parse(cut, &path).expect_err("a torn last row is reported");
    assert!(e.to_string().contains(':'), "{e}");
    let complete = &cut[..cut.rfind('\n').unwrap() + 1];
    let t = Trajectory::parse(complete, &path).expect("the complete rows load");
    assert_eq!(t.samples(0).len() + t.samples(1).len(), 49);
}

// ---------------------------------------------------------------- files a user names

/// Things that are not regular files, each at a path with the extension `ext`
/// (so the reader chosen by extension is the one that meets it).
fn not_regular_files(dir: &Path, ext: &str) -> Vec<(&'static str, PathBuf)> {
    let mut v = Vec::new();
    let fifo = dir.join(format!("fifo.{ext}"));
    match std::process::Command::new("mkfifo").arg(&fifo).status() {
        Ok(s) if s.success() => v.push(("FIFO", fifo)),
        _ => println!("SKIP the FIFO case: mkfifo is not available"),
    }
    if Path::new("/dev/zero").exists() {
        let zero = dir.join(format!("zero.{ext}"));
        std::os::unix::fs::symlink("/dev/zero", &zero).unwrap();
        v.push(("character device", zero));
    }
    let folder = dir.join(format!("folder.{ext}"));
    std::fs::create_dir(&folder).unwrap();
    v.push(("directory", folder));
    v
}

/// Runs `load` on another thread: a reader that blocks on a FIFO or reads
/// /dev/zero without end fails the test instead of hanging it.
fn refused_in_time<T: Send + 'static>(path: &Path, load: fn(&Path) -> Result<T, String>) -> String {
    let (tx, rx) = std::sync::mpsc::channel();
    let p = path.to_path_buf();
    std::thread::spawn(move || {
        let _ = tx.send(load(&p).err());
    });
    match rx.recv_timeout(Duration::from_secs(10)) {
        Ok(Some(e)) => e,
        Ok(None) => panic!("{} was read as if it were a file", path.display()),
        Err(_) => panic!("reading {} hangs (a FIFO or a device read without end)", path.display()),
    }
}

type Loader = fn(&Path) -> Result<(), String>;

fn loaders() -> [(&'static str, Loader); 5] {
    [
        ("ron", |p| Scenario::load(p, &[]).map(drop).map_err(|e| e.to_string())),
        ("msh", |p| fissure::mesh::io::load_tet_mesh(p).map(drop).map_err(|e| e.to_string())),
        ("vtu", |p| fissure::mesh::io::load_vtu_with_fields(p).map(drop).map_err(|e| e.to_string())),
        ("stl", |p| fissure::mesh::io::load_surface(p).map(drop).map_err(|e| e.to_string())),
        ("csv", |p| Trajectory::load(p).map(drop).map_err(|e| e.to_string())),
    ]
}

#[test]
fn fifo_device_and_directory_inputs_are_refused_at_once_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    for (ext, load) in loaders() {
        for (what, path) in not_regular_files(dir.path(), ext) {
            let start = Instant::now();
            let e = refused_in_time(&path, load);
            println!("{what} as .{ext} ({:.1} ms): {e}", start.elapsed().as_secs_f64() * 1e3);
            assert!(e.contains(&path.display().to_string()), "{what} as .{ext}: the error must name the file: {e}");
            assert!(e.contains(what) && e.contains("not a regular file"), "{what} as .{ext}: the error must say what it is: {e}");
        }
    }
}

#[test]
fn oversize_inputs_are_refused_unread_with_their_size_and_the_cap() {
    let dir = tempfile::tempdir().unwrap();
    // Sparse files: as large as claimed, nothing on disk, and nothing read.
    for (ext, load) in loaders() {
        let cap = match ext {
            "ron" => Cap::SCENARIO,
            "msh" | "vtu" => Cap::MESH,
            "stl" => Cap::SURFACE,
            _ => Cap::TRAJECTORY,
        };
        let path = dir.path().join(format!("big.{ext}"));
        std::fs::File::create(&path).unwrap().set_len(cap.bytes + 1).unwrap();
        let e = refused_in_time(&path, load);
        println!("oversize .{ext}: {e}");
        assert!(e.contains(&path.display().to_string()), "the error must name the file: {e}");
        assert!(e.contains(&format!("({} bytes)", cap.bytes + 1)) && e.contains(&format!("({} bytes) limit for {}", cap.bytes, cap.what)), "size and cap: {e}");
    }
    // The cap is inclusive and the reader takes any cap (a small one here).
    let path = dir.path().join("ten.csv");
    std::fs::write(&path, b"0123456789").unwrap();
    assert!(read_regular(&path, Cap { bytes: 10, what: "a test file" }).is_ok());
    let e = read_regular(&path, Cap { bytes: 9, what: "a test file" }).expect_err("over by one").to_string();
    assert!(e.contains("ten.csv") && e.contains("10 bytes is over the 9 bytes limit for a test file"), "{e}");
}

#[test]
fn the_fine_real_brain_is_within_the_mesh_cap() {
    let path = common::real_brain(fissure::mesh::brain::FINE);
    // The cap applies to the decompressed text.
    let mut text = Vec::new();
    std::io::Read::read_to_end(&mut flate2::read::GzDecoder::new(std::fs::File::open(&path).unwrap()), &mut text).unwrap();
    let size = text.len() as u64;
    assert!(size > 10_000_000, "{} decompresses to {size} bytes", path.display());
    assert!(size < Cap::MESH.bytes / 100, "{} is {size} bytes: the mesh cap must leave room for much finer meshes", path.display());
    let mesh = fissure::mesh::io::load_tet_mesh(&path).expect("the fine brain loads");
    assert!(mesh.tets.len() > 100_000, "{} tets", mesh.tets.len());
}

// ---------------------------------------------------------------- compliance cache

fn small_model() -> FemModel {
    let mesh = common::block(3, 3, 2, Vec3::new(0.03, 0.03, 0.02), Vec3::zeros());
    let fixed: Vec<bool> = mesh.positions.iter().map(|p| p.z == 0.0).collect();
    let m = Material { young_modulus: 3000.0, poisson_ratio: 0.45 };
    FemModel::new(&mesh, &RegionMaterials { default: m, by_region: vec![] }, &fixed, &FemOptions::default()).expect("model")
}

fn cache_file(dir: &Path) -> PathBuf {
    let files: Vec<PathBuf> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).filter(|p| p.extension().is_some_and(|e| e == "bin")).collect();
    assert_eq!(files.len(), 1, "one cache file expected in {}: {files:?}", dir.display());
    files[0].clone()
}

#[test]
fn corrupt_or_missing_compliance_cache_is_rebuilt_not_trusted() {
    let model = small_model();
    let roi = model.surface().vertices.clone();
    let dir = tempfile::tempdir().unwrap();
    let compute = || Compliance::compute(&model, &roi, ComplianceStorage::F64, Some(dir.path()), &mut |_, _| {}).expect("compute");
    let first = compute();
    assert!(!first.stats().from_cache, "no cache yet: computed");
    let reference = fem_common::all_block_bits(&first);
    let path = cache_file(dir.path());
    let good_bytes = std::fs::read(&path).unwrap();
    assert!(compute().stats().from_cache, "an intact cache is used");

    let mut corruptions: Vec<(&str, Vec<u8>)> = vec![
        ("truncated to half", good_bytes[..good_bytes.len() / 2].to_vec()),
        ("truncated by one byte", good_bytes[..good_bytes.len() - 1].to_vec()),
        ("empty", Vec::new()),
        ("one more byte", [good_bytes.as_slice(), &[0]].concat()),
    ];
    for (what, at) in [("magic", 0usize), ("header key", 20), ("row nodes", 80), ("a value", good_bytes.len() / 2), ("the checksum", good_bytes.len() - 3)] {
        let mut b = good_bytes.clone();
        b[at] ^= 0x10;
        corruptions.push((what, b));
    }
    for (what, bytes) in corruptions {
        std::fs::write(&path, &bytes).unwrap();
        let c = compute();
        assert!(!c.stats().from_cache, "cache with {what} must not be trusted");
        assert_eq!(fem_common::all_block_bits(&c), reference, "cache with {what}: the rebuilt compliance must equal the original bit for bit");
        assert_eq!(std::fs::read(&path).unwrap(), good_bytes, "cache with {what}: the rebuilt file is rewritten intact");
    }
    // Missing: deleted between runs.
    std::fs::remove_file(&path).unwrap();
    let c = compute();
    assert!(!c.stats().from_cache);
    assert_eq!(fem_common::all_block_bits(&c), reference);
    assert!(compute().stats().from_cache, "the rewritten cache is used next time");
}

#[test]
fn an_unwritable_cache_folder_never_gives_a_wrong_compliance() {
    let model = small_model();
    let roi = model.surface().vertices.clone();
    let dir = tempfile::tempdir().unwrap();
    // A regular file where the cache folder should be: no folder can be created there (even as root).
    let blocker = dir.path().join("not-a-folder");
    std::fs::write(&blocker, b"x").unwrap();
    let cache = blocker.join("cache");
    let c = Compliance::compute(&model, &roi, ComplianceStorage::F64, Some(&cache), &mut |_, _| {});
    match c {
        Ok(c) => {
            let direct = Compliance::compute(&model, &roi, ComplianceStorage::F64, None, &mut |_, _| {}).unwrap();
            assert_eq!(fem_common::all_block_bits(&c), fem_common::all_block_bits(&direct), "the compliance is the same without its cache");
        }
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("not-a-folder"), "if refused, the error must name the cache path: {msg}");
            println!("unwritable cache folder is an error: {msg}");
        }
    }
}

// ---------------------------------------------------------------- full disk

/// Writes the inputs of [`replay_scene`] into `dir` (mesh and trajectory).
fn write_replay_inputs(dir: &Path) {
    let mesh = common::block(6, 6, 3, Vec3::new(40.0, 40.0, 20.0), Vec3::new(-20.0, -20.0, 0.0));
    common::write_mesh(dir, "block.msh", &mesh);
    let traj = "time_s,spatula,x_mm,y_mm,z_mm,qw,qx,qy,qz\n0.0,0,-10.0,0.0,21.0,1.0,0.0,0.0,0.0\n\
        0.1,0,-10.0,0.0,18.0,1.0,0.0,0.0,0.0\n0.2,0,-6.0,2.0,18.0,1.0,0.0,0.0,0.0\n0.3,0,-6.0,2.0,25.0,1.0,0.0,0.0,0.0\n";
    std::fs::write(dir.join("press.csv"), traj).unwrap();
}

/// The replay scene of `replay_determinism.rs` (inputs from [`write_replay_inputs`]):
/// a blade presses, slides and leaves (30 frames).
fn replay_scene(dir: &Path) -> Scenario {
    let mesh_path = dir.join("block.msh");
    let text = format!(
        r#"(
    name: "full disk",
    mesh: File(path: "{}", units: Millimetres),
    material: (young_modulus_pa: 3000.0, poisson_ratio: 0.45),
    fixed: [LowestPerComponent(height_mm: 1.0)],
    spatulas: [(name: "blade", shape: (length_mm: 20.0, width_mm: 10.0, thickness_mm: 1.0), layout: Grid(along: 6, across: 3),
        pose: (position_mm: (-10.0, 0.0, 21.0), rotation: Quaternion(1.0, 0.0, 0.0, 0.0)), input: Trajectory)],
    effects: [Collision, Culling, ForceOutput, ContactPressure],
    solver: (compliance_storage: F64, region_of_interest: All, cache_dir: None),
    time_step_s: 0.01,
    duration_s: 0.3,
    trajectory: Some("press.csv"),
)"#,
        mesh_path.display()
    );
    Scenario::from_str(&text, &dir.join("scene.ron"), &[]).expect("valid")
}

#[test]
fn metrics_on_a_full_disk_end_with_a_clear_error() {
    if !Path::new("/dev/full").exists() {
        println!("SKIP: /dev/full is absent");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    write_replay_inputs(dir.path());
    let s = replay_scene(dir.path());
    let out = dir.path().join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink("/dev/full", out.join("metrics.csv")).unwrap();
    let opts = ReplayOptions { out_dir: out.clone(), trajectory: None, vtk: false };
    let e = replay(&s, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect_err("a full disk is an error").to_string();
    println!("full disk: {e}");
    assert!(e.contains("metrics.csv"), "the error must name the file: {e}");
    assert!(e.to_lowercase().contains("no space"), "the error must say the disk is full: {e}");
}

/// Runs in a child process under `ulimit -f` (see the parent test below); ignored otherwise.
#[test]
#[ignore = "child of replay_cut_by_a_file_size_limit_keeps_every_row_written_so_far"]
fn child_replay_under_a_file_size_limit() {
    let Ok(dir) = std::env::var("FISSURE_HARD_FSIZE_DIR") else { return };
    let dir = PathBuf::from(dir);
    let s = replay_scene(&dir);
    let opts = ReplayOptions { out_dir: dir.join("out"), trajectory: None, vtk: false };
    match replay(&s, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None) {
        Ok(summary) => println!("REPLAY_OK frames {}", summary.frames),
        Err(e) => println!("REPLAY_ERROR {e}"),
    }
}

/// Replays [`replay_scene`] in a child process whose files cannot grow past
/// `kib` KiB (EFBIG: the same path as a disk filling up mid-run; the child
/// ignores SIGXFSZ so the write returns an error instead). Returns the folder
/// and the child's `REPLAY_` line; `None` without bash.
fn replay_under_a_file_size_limit(kib: u32) -> Option<(tempfile::TempDir, String)> {
    let dir = tempfile::tempdir().unwrap();
    write_replay_inputs(dir.path());
    let exe = std::env::current_exe().unwrap();
    // The child test's name in this binary: its module path without the crate's name.
    let child = match module_path!().split_once("::") {
        Some((_, module)) => format!("{module}::child_replay_under_a_file_size_limit"),
        None => "child_replay_under_a_file_size_limit".to_string(),
    };
    let out = std::process::Command::new("bash")
        .arg("-c")
        .arg(format!("trap '' XFSZ; ulimit -f {kib} && exec \"$0\" --exact {child} --ignored --nocapture --test-threads=1"))
        .arg(&exe)
        .env("FISSURE_HARD_FSIZE_DIR", dir.path())
        .output();
    let Ok(out) = out else {
        println!("SKIP: bash is not available");
        return None;
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "child failed: {:?}\n{stdout}\n{}", out.status, String::from_utf8_lossy(&out.stderr));
    let line = stdout.lines().find_map(|l| l.find("REPLAY_").map(|k| l[k..].to_string())).unwrap_or_else(|| panic!("no REPLAY_ line in {stdout}"));
    println!("child under {kib} KiB: {line}");
    Some((dir, line))
}

/// summary.json is complete or absent, and no temporary file is left beside it.
fn summary_whole_or_absent(out: &Path) -> Option<serde_json::Value> {
    let leftovers: Vec<_> = std::fs::read_dir(out).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).filter(|n| n.contains(".tmp-")).collect();
    assert!(leftovers.is_empty(), "temporary files left in {}: {leftovers:?}", out.display());
    let path = out.join("summary.json");
    let text = std::fs::read_to_string(&path).ok()?;
    let v: serde_json::Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("summary.json exists but is cut or empty ({} bytes, {e}): {text:?}", text.len()));
    Some(v)
}

#[test]
fn replay_cut_by_a_file_size_limit_keeps_every_row_written_so_far() {
    // EFBIG once metrics.csv reaches 4 KiB; the summary is smaller and is written.
    let Some((dir, line)) = replay_under_a_file_size_limit(4) else { return };
    assert!(line.starts_with("REPLAY_ERROR"), "the replay must fail when the file cannot grow: {line}");
    assert!(line.contains("metrics.csv") && line.contains("too large"), "the error must name the file and the cause: {line}");
    let csv = std::fs::read_to_string(dir.path().join("out/metrics.csv")).expect("metrics.csv exists");
    let columns = csv.lines().next().unwrap().split(',').count();
    let complete: Vec<&str> = csv.split_inclusive('\n').filter(|l| l.ends_with('\n')).collect();
    let torn = csv.len() - complete.iter().map(|l| l.len()).sum::<usize>();
    assert!(complete.len() > 2, "some rows were written before the limit: {}", complete.len());
    for (k, l) in complete.iter().enumerate() {
        assert_eq!(l.trim_end().split(',').count(), columns, "row {k} is complete");
        if k > 0 {
            let frame: u64 = l.split(',').next().unwrap().parse().unwrap_or_else(|_| panic!("row {k} starts with its frame: {l}"));
            assert_eq!(frame, k as u64 - 1, "rows are in frame order");
        }
    }
    println!("file-size limit: {} complete rows kept, {torn} bytes of a torn last row", complete.len() - 1);
    assert_eq!(torn, 0, "the row being written when the disk filled must not be left torn ({torn} bytes)");
    let summary = summary_whole_or_absent(&dir.path().join("out")).expect("a summary under 4 KiB is written");
    assert_eq!(summary["interrupted"], true, "the summary says the run was cut");
    assert_eq!(summary["frames"].as_u64(), Some(complete.len() as u64 - 1), "the summary counts the rows kept");
}

#[test]
fn a_summary_that_cannot_be_written_whole_is_not_written_at_all() {
    // 1 KiB: metrics.csv stops after its header and a few rows, and the summary (over 1 KiB:
    // stage percentiles, a 64-digit hash) cannot be written whole either. Before
    // summary.json went through a temporary file, this left a summary cut at 1 KiB.
    let Some((dir, line)) = replay_under_a_file_size_limit(1) else { return };
    assert!(line.starts_with("REPLAY_ERROR") && line.contains("metrics.csv"), "{line}");
    let out = dir.path().join("out");
    match summary_whole_or_absent(&out) {
        None => println!("summary.json absent, as it could not be written whole"),
        Some(v) => {
            let bytes = std::fs::metadata(out.join("summary.json")).unwrap().len();
            assert!(bytes <= 1024, "a summary over the limit cannot be whole: {bytes} bytes");
            assert_eq!(v["interrupted"], true);
        }
    }
    let csv = std::fs::read_to_string(out.join("metrics.csv")).expect("metrics.csv");
    assert!(csv.ends_with('\n'), "metrics.csv ends at a whole row");
}
