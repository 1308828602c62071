//! Backend parity: `reference`, `bvh` and `gpu` give bit-identical outputs (pairs,
//! culling, targets) on every scene, on random poses and in contact (the surface each
//! frame deformed to its targets, triangles exactly on the blade planes), and on lines
//! chosen to be hard for f32 (through vertices, along axes, grazing, just outside a
//! silhouette edge). `gpu` tests skip when the machine has no adapter (CI has the
//! software Vulkan driver). Scenes: a sphere, the fissure boxes, a ridge over a slab,
//! and the real brain surfaces with 2000 nodes a face (random poses and the first
//! frames of the collision benchmark's motion).

use crate::common;

use fissure::collision::backend::gpu::GpuCaster;
use fissure::collision::backend::reference::ReferenceCaster;
use fissure::collision::backend::{PairLine, RayCaster};
use fissure::collision::scenes::{icosphere, merge, pose_from_axes, subdivided_box};
use fissure::collision::{BackendKind, CollisionConfig, CollisionStage, SpatulaSpec};
use fissure::geometry::{NodeLayout, SpatulaShape};
use fissure::math::Vec3;

const MM: f64 = 1e-3;

struct Rng(u64);
impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_F491_4F6C_DD1D) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn unit(&mut self) -> Vec3 {
        loop {
            let v = Vec3::new(self.f() * 2.0 - 1.0, self.f() * 2.0 - 1.0, self.f() * 2.0 - 1.0);
            let n = v.norm();
            if n > 0.1 && n < 1.0 {
                return v / n;
            }
        }
    }
}

fn specs() -> Vec<SpatulaSpec> {
    let shape = SpatulaShape { length: 40.0 * MM, width: 8.0 * MM, thickness: 1.0 * MM };
    vec![
        SpatulaSpec { shape, layout: NodeLayout::Grid { along: 15, across: 10 } },
        SpatulaSpec { shape, layout: NodeLayout::TipConcentrated { count: 30, tip_fraction: 0.3 } },
    ]
}

/// Random poses whose blades pass through the surface's bounding box.
fn random_poses(rng: &mut Rng, lo: Vec3, hi: Vec3, n: usize) -> Vec<Vec<fissure::geometry::Pose>> {
    (0..n)
        .map(|_| {
            (0..2)
                .map(|_| {
                    let tip = lo + (hi - lo).component_mul(&Vec3::new(rng.f(), rng.f(), rng.f()));
                    let blade = rng.unit();
                    pose_from_axes(tip - blade * 30.0 * MM, blade, rng.unit())
                })
                .collect()
        })
        .collect()
}

fn bbox(p: &[Vec3]) -> (Vec3, Vec3) {
    p.iter().fold((Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY)), |(a, b), q| (a.inf(q), b.sup(q)))
}

/// Random poses on a reference stage against bvh (see [`stage_parity`]).
fn cpu_parity(t: &[[u32; 3]], rest: &[Vec3], frames: usize, seed: u64) -> usize {
    let mut r = CollisionStage::new(CollisionConfig { backend: BackendKind::Reference, culling: true }, t, rest, &specs()).expect("stage");
    stage_parity(&mut r, t, rest, &specs(), frames, seed)
}

#[test]
fn reference_and_bvh_agree_bit_for_bit_on_sphere_and_fissure() {
    let (t, p) = icosphere(Vec3::new(0.0, 0.0, 0.0), 30.0 * MM, 4);
    let pairs = cpu_parity(&t, &p, 12, 7);
    assert!(pairs > 0, "the random poses must produce some pairs on the sphere");
    let left = subdivided_box(Vec3::new(-30.0, -20.0, -30.0) * MM, Vec3::new(-1.0, 20.0, 0.0) * MM, 29, 20);
    let right = subdivided_box(Vec3::new(1.0, -20.0, -30.0) * MM, Vec3::new(30.0, 20.0, 0.0) * MM, 29, 20);
    let (t, p) = merge(&[left, right]);
    assert!(cpu_parity(&t, &p, 12, 11) > 0, "the fissure poses must produce pairs");
}

/// A GPU stage, or None (with the reason printed) when the machine has no adapter.
fn gpu_stage(t: &[[u32; 3]], p: &[Vec3], specs: &[SpatulaSpec], backend: BackendKind) -> Option<CollisionStage> {
    let g = CollisionStage::new(CollisionConfig { backend, culling: true }, t, p, specs).expect("stage");
    if backend == BackendKind::Gpu && g.backend() != BackendKind::Gpu {
        assert!(!g.warnings().is_empty(), "a fallback must be reported in warnings()");
        common::skip(&format!("no GPU adapter ({:?})", g.warnings()));
        return None;
    }
    Some(g)
}

/// Runs random poses on a bvh stage and on `other` with a kinematic surface (each
/// frame's targets applied, so later frames have triangles exactly on the blade
/// planes: the contact configuration); every output must be identical bit for bit.
fn stage_parity(other: &mut CollisionStage, t: &[[u32; 3]], rest: &[Vec3], specs: &[SpatulaSpec], frames: usize, seed: u64) -> usize {
    let (lo, hi) = bbox(rest);
    let mut rng = Rng(seed);
    let poses = random_poses(&mut rng, lo, hi, frames);
    let mut b = CollisionStage::new(CollisionConfig { backend: BackendKind::Bvh, culling: true }, t, rest, specs).expect("stage");
    let mut cur = rest.to_vec();
    let mut pairs = 0;
    for (f, pose) in poses.iter().enumerate() {
        // Each pose twice: the second frame sees the surface the first one deformed.
        for _ in 0..2 {
            let bo = b.step(&cur, pose).expect("bvh").clone();
            let kind = other.backend();
            let go = other.step(&cur, pose).expect("other backend");
            assert_eq!(&bo, go, "frame {f}: {kind:?} output differs from bvh");
            pairs += bo.candidate_pairs.len();
            cur = rest.to_vec();
            for tg in &bo.targets {
                cur[tg.vertex as usize] = rest[tg.vertex as usize] + tg.displacement;
            }
        }
    }
    pairs
}

/// Lines that stress the f32 candidate search: random, through vertices, along
/// axes, from points on the surface, grazing, from far away.
fn hard_lines(p: &[Vec3], n: usize, seed: u64, scale: f64) -> Vec<PairLine> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|k| {
            let dir = match k % 5 {
                0 | 1 => rng.unit(),
                2 => [Vec3::x(), -Vec3::y(), Vec3::z()][k % 3],
                3 => Vec3::new(rng.f() - 0.5, 0.0, rng.f() - 0.5).normalize(),
                _ => rng.unit(),
            };
            let v = p[(rng.f() * p.len() as f64) as usize];
            let origin = match k % 4 {
                0 => v - dir * (2.0 * MM),
                1 => v,
                2 => v * (0.3 + rng.f()),
                _ => rng.unit() * scale * rng.f(),
            };
            PairLine { origin, direction: dir, thickness: (0.5 + 2.0 * rng.f()) * MM }
        })
        .collect()
}

#[test]
fn gpu_agrees_with_reference_bit_for_bit_on_hard_lines() {
    let (t, p) = icosphere(Vec3::new(0.0, 0.0, 0.0), 30.0 * MM, 4);
    let mut gpu = match GpuCaster::new(&t, &p, 2020) {
        Ok(g) => g,
        Err(e) => {
            common::skip(&format!("no GPU adapter ({e})"));
            return;
        }
    };
    println!("gpu adapter: {}", gpu.adapter_name());
    let mut reference = ReferenceCaster::new(&t, &p);
    let mut lines = hard_lines(&p, 2000, 3, 35.0 * MM);
    // Origins metres away (past the f32 error bounds' range): cast on the CPU.
    let mut rng = Rng(17);
    lines.extend((0..20).map(|_| {
        let dir = rng.unit();
        PairLine { origin: rng.unit() * 5.0 * MM - dir * 5.0, direction: dir, thickness: 1.0 * MM }
    }));
    // Deform a little so the partial upload path runs.
    let mut cur = p.clone();
    for v in cur.iter_mut().take(50) {
        *v *= 1.01;
    }
    gpu.update_surface(&cur).expect("upload");
    let up = gpu.last_upload();
    assert!(!up.whole_buffer && up.changed_vertices == 50 && up.written_vertices >= 50, "partial upload expected: {up:?}");
    reference.update_surface(&cur).expect("reference");
    let (mut g, mut r) = (Vec::new(), Vec::new());
    gpu.cast(&lines, &mut g).expect("gpu cast");
    reference.cast(&lines, &mut r).expect("reference cast");
    let timings = gpu.last_timings();
    println!("{} of {} lines flagged for the CPU; timings {timings:?}", timings.flagged_lines, timings.lines);
    for (k, (gh, rh)) in g.iter().zip(&r).enumerate() {
        assert_eq!(gh, rh, "line {k} ({:?}): gpu differs from reference", lines[k]);
    }
    assert!(r.iter().filter(|h| h.face0.behind.is_some()).count() > 500, "the lines must hit the sphere");
    // Half of the hard lines pass exactly through a vertex (the fan's near misses make
    // clusters the CPU decides); lines in general position are nearly all decided
    // from the GPU's candidates.
    let generic: Vec<PairLine> = hard_lines(&p, 2000, 9, 35.0 * MM).into_iter().enumerate().filter(|(k, _)| k % 4 >= 2).map(|(_, l)| l).collect();
    gpu.cast(&generic, &mut g).expect("gpu cast");
    reference.cast(&generic, &mut r).expect("reference cast");
    assert_eq!(g, r, "gpu differs from reference on lines in general position");
    let t = gpu.last_timings();
    assert!(t.flagged_lines * 20 < t.lines, "lines in general position must be decided from the GPU's candidates: {t:?}");
    // Whole-buffer path when most vertices moved; still bit for bit.
    let moved: Vec<Vec3> = p.iter().map(|v| v * 1.02).collect();
    gpu.update_surface(&moved).expect("upload");
    assert!(gpu.last_upload().whole_buffer, "most vertices moved: whole-buffer upload expected");
    reference.update_surface(&moved).expect("reference");
    gpu.cast(&lines, &mut g).expect("gpu cast");
    reference.cast(&lines, &mut r).expect("reference cast");
    assert_eq!(g, r, "gpu differs from reference after a whole-buffer upload");
}

#[test]
fn stage_with_gpu_backend_matches_bvh_bit_for_bit_in_contact() {
    let left = subdivided_box(Vec3::new(-30.0, -20.0, -30.0) * MM, Vec3::new(-1.0, 20.0, 0.0) * MM, 29, 20);
    let right = subdivided_box(Vec3::new(1.0, -20.0, -30.0) * MM, Vec3::new(30.0, 20.0, 0.0) * MM, 29, 20);
    let (t, p) = merge(&[left, right]);
    let Some(mut g) = gpu_stage(&t, &p, &specs(), BackendKind::Gpu) else { return };
    assert!(stage_parity(&mut g, &t, &p, &specs(), 10, 11) > 0, "the fissure poses must produce pairs");
    // Axis-aligned blades on the axis-aligned boxes: lines along grid lines, through
    // vertices and edges, triangles exactly on the blade planes after the first frame.
    let mut b = CollisionStage::new(CollisionConfig { backend: BackendKind::Bvh, culling: true }, &t, &p, &specs()).expect("stage");
    let mut cur = p.clone();
    for k in 0..6 {
        let x = (0.5 * k as f64) * MM;
        let poses = [
            pose_from_axes(Vec3::new(x, 0.0, 25.0 * MM), -Vec3::z(), Vec3::x()),
            pose_from_axes(Vec3::new(-x, 5.0 * MM, 25.0 * MM), Vec3::new(0.1, 0.0, -1.0), -Vec3::x()),
        ];
        for _ in 0..2 {
            let bo = b.step(&cur, &poses).expect("bvh").clone();
            let go = g.step(&cur, &poses).expect("gpu");
            assert_eq!(&bo, go, "frame {k}: gpu output differs from bvh");
            cur = p.clone();
            for tg in &bo.targets {
                cur[tg.vertex as usize] = p[tg.vertex as usize] + tg.displacement;
            }
        }
    }
    let (t, p) = icosphere(Vec3::new(0.0, 0.0, 0.0), 30.0 * MM, 4);
    let Some(mut g) = gpu_stage(&t, &p, &specs(), BackendKind::Gpu) else { return };
    assert!(stage_parity(&mut g, &t, &p, &specs(), 10, 7) > 0, "the sphere poses must produce pairs");
}

#[test]
fn a_lost_gpu_mid_run_switches_to_bvh_with_one_warning_and_the_same_answers() {
    let (t, p) = icosphere(Vec3::new(0.0, 0.0, 0.0), 30.0 * MM, 4);
    let Some(mut g) = gpu_stage(&t, &p, &specs(), BackendKind::Gpu) else { return };
    stage_parity(&mut g, &t, &p, &specs(), 2, 5);
    assert!(g.warnings().is_empty(), "no warning before the loss: {:?}", g.warnings());
    assert!(g.simulate_gpu_loss(), "the gpu stage has a device to lose");
    stage_parity(&mut g, &t, &p, &specs(), 3, 5);
    assert_eq!(g.backend(), BackendKind::Bvh, "the stage must run on bvh after the loss");
    assert_eq!(g.warnings().len(), 1, "one warning: {:?}", g.warnings());
    assert!(g.warnings()[0].contains("GPU collision backend failed") && g.warnings()[0].contains("device lost"), "{:?}", g.warnings());
}

#[test]
fn auto_times_both_backends_then_keeps_one_with_the_same_answers() {
    let (t, p) = icosphere(Vec3::new(0.0, 0.0, 0.0), 30.0 * MM, 4);
    let mut a = gpu_stage(&t, &p, &specs(), BackendKind::Auto).expect("auto always builds");
    let trial = a.auto_trial_running();
    stage_parity(&mut a, &t, &p, &specs(), 6, 21);
    assert!(!a.auto_trial_running(), "12 frames end the trial");
    assert!(matches!(a.backend(), BackendKind::Bvh | BackendKind::Gpu));
    let said: Vec<&String> = a.warnings().iter().filter(|w| w.starts_with("auto collision backend: ")).collect();
    assert_eq!(said.len(), 1, "one line says which backend auto kept: {:?}", a.warnings());
    if trial {
        assert!(said[0].contains("median over"), "{}", said[0]);
    }
    println!("{}", said[0]);
}

#[test]
fn reference_and_bvh_agree_on_the_real_brain() {
    let (t, p) = read_msh_surface(&fissure::mesh::brain::shipped(fissure::mesh::brain::COARSE));
    assert_eq!(t.len(), 40_960, "the coarse brain surface has 40,960 triangles");
    let pairs = cpu_parity(&t, &p, 4, 99);
    println!("real brain: {pairs} candidate pairs over 4 random frames");
}

/// The boundary surface of a real brain tet mesh (millimetres) in metres.
fn read_msh_surface(path: &std::path::Path) -> (Vec<[u32; 3]>, Vec<Vec3>) {
    let s = fissure::collision::bench::BenchSurface::tet_mesh_mm(path, "brain").unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    (s.triangles, s.positions)
}

/// Two spatulas with 2000 nodes a face (100 x 20 grid).
fn dense_specs() -> Vec<SpatulaSpec> {
    let shape = SpatulaShape { length: 40.0 * MM, width: 8.0 * MM, thickness: 1.0 * MM };
    vec![SpatulaSpec { shape, layout: NodeLayout::Grid { along: 100, across: 20 } }; 2]
}

#[test]
fn gpu_agrees_with_bvh_on_the_real_brains_at_2000_nodes_a_face() {
    use fissure::mesh::brain;
    for (name, stem) in [("coarse", brain::COARSE), ("q15", brain::FINE)] {
        let (t, p) = read_msh_surface(&brain::shipped(stem));
        let Some(mut g) = gpu_stage(&t, &p, &dense_specs(), BackendKind::Gpu) else { return };
        let pairs = stage_parity(&mut g, &t, &p, &dense_specs(), 2, 99);
        println!("real brain {name} ({} triangles): {pairs} candidate pairs, gpu = bvh bit for bit", t.len());
        assert!(pairs > 0, "the random poses must touch the {name} brain");
    }
}

/// A line passing within f32 rounding of a silhouette edge (a ridge whose two
/// triangles both lie on one side of the line) is an f32 near miss of both and an
/// f64 miss of both; it must not hide the true hit farther along the line (here a
/// slab 50 mm below the ridge) from the GPU's candidates.
#[test]
fn gpu_finds_the_hit_behind_a_silhouette_edge_that_the_line_just_misses() {
    let l = 10.0 * MM;
    let ridge: (Vec<[u32; 3]>, Vec<Vec3>) =
        (vec![[0, 1, 2], [1, 0, 3]], vec![Vec3::new(0.0, -l, 0.0), Vec3::new(0.0, l, 0.0), Vec3::new(l, 0.0, 0.5 * l), Vec3::new(l, 0.0, -0.5 * l)]);
    let slab = subdivided_box(Vec3::new(-20.0, -20.0, -52.0) * MM, Vec3::new(20.0, 20.0, -50.0) * MM, 10, 10);
    let (t, p) = merge(&[ridge, slab]);
    let mut gpu = match GpuCaster::new(&t, &p, 256) {
        Ok(g) => g,
        Err(e) => {
            common::skip(&format!("no GPU adapter ({e})"));
            return;
        }
    };
    let mut reference = ReferenceCaster::new(&t, &p);
    gpu.update_surface(&p).expect("upload");
    reference.update_surface(&p).expect("reference");
    // Lines through a point just beside the ridge's edge (x = -gap), tilted a little,
    // their origin 5 mm above it: the ridge is 5 mm behind, the slab about 55 mm.
    let mut rng = Rng(5);
    let lines: Vec<PairLine> = (0..200)
        .map(|k| {
            let gap = [1e-11, 1e-10, 1e-9][k % 3];
            let d = Vec3::new(0.3 * rng.f() - 0.15, 0.3 * rng.f() - 0.15, 1.0).normalize();
            let beside = Vec3::new(-gap, (rng.f() - 0.5) * l, 0.0);
            PairLine { origin: beside + d * (5.0 * MM), direction: d, thickness: 1.0 * MM }
        })
        .collect();
    let (mut g, mut r) = (Vec::new(), Vec::new());
    gpu.cast(&lines, &mut g).expect("gpu cast");
    reference.cast(&lines, &mut r).expect("reference cast");
    assert!(r.iter().all(|h| h.face0.behind.is_some_and(|b| b.triangle >= 2)), "every line misses the ridge and hits the slab behind");
    for (k, (gh, rh)) in g.iter().zip(&r).enumerate() {
        assert_eq!(gh, rh, "line {k} ({:?}): gpu differs from reference", lines[k]);
    }
}

/// The first frames of `fissure bench collision --frames 3 --warmup 1` on the coarse
/// brain at 2000 nodes a face (the blades' poses of `bench::poses` at s = 0, 1/4,
/// 1/2, the surface deformed to each frame's targets): at s = 1/2 a line of the
/// first blade passes within f32 rounding outside a silhouette edge 64 mm behind
/// its node, and its true hit lies 96 mm behind.
#[test]
fn gpu_agrees_with_bvh_on_the_first_frames_of_the_bench_motion() {
    use fissure::mesh::brain;
    let (t, p) = read_msh_surface(&brain::shipped(brain::COARSE));
    let (lo, hi) = bbox(&p);
    let length = 0.35 * (hi.x - lo.x);
    let shape = SpatulaShape { length, width: 10.0 * MM, thickness: 1.0 * MM };
    let specs = vec![SpatulaSpec { shape, layout: NodeLayout::Grid { along: 100, across: 20 } }; 2];
    let Some(mut g) = gpu_stage(&t, &p, &specs, BackendKind::Gpu) else { return };
    let mut b = CollisionStage::new(CollisionConfig { backend: BackendKind::Bvh, culling: true }, &t, &p, &specs).expect("stage");
    let mut cur = p.clone();
    for f in 0..3 {
        let poses = fissure::collision::bench::poses(lo, hi, length, f as f64 / 4.0);
        let bo = b.step(&cur, &poses).expect("bvh").clone();
        g.step(&cur, &poses).expect("gpu");
        assert_eq!(b.nearest_hits(), g.nearest_hits(), "frame {f}: gpu nearest hits differ from bvh");
        assert_eq!(&bo, g.output(), "frame {f}: gpu output differs from bvh");
        cur = p.clone();
        for tg in &bo.targets {
            cur[tg.vertex as usize] = p[tg.vertex as usize] + tg.displacement;
        }
    }
}
