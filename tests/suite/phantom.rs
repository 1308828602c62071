//! Every phantom preset: counts in range, one component, closed outward
//! boundary, the stuffing dihedral bound, no inverted tets, determinism, and
//! landmarks that point at the right places. Each preset is generated once per
//! test binary (`OnceLock`); generation times are printed (`--nocapture`).

use std::sync::OnceLock;
use std::time::Instant;

use fissure::math::Vec3;
use fissure::mesh::TetMesh;
use fissure::mesh::phantom::{Landmarks, Phantom, Preset, generate};
use fissure::mesh::tetrahedralize::{MAX_DIHEDRAL_DEG, MIN_DIHEDRAL_DEG, dihedral_range_deg};

fn phantom(preset: Preset) -> &'static Phantom {
    static CELLS: [OnceLock<Phantom>; 5] = [const { OnceLock::new() }; 5];
    let i = Preset::ALL.iter().position(|&p| p == preset).expect("preset is listed in ALL");
    CELLS[i].get_or_init(|| {
        let t = Instant::now();
        let p = generate(preset).unwrap_or_else(|e| panic!("{preset}: generation failed: {e}"));
        println!("{preset}: generated in {:.3} s", t.elapsed().as_secs_f64());
        p
    })
}

/// Face-connected components (tets sharing a triangle).
fn components(mesh: &TetMesh) -> usize {
    let mut faces: Vec<([u32; 3], u32)> = Vec::with_capacity(mesh.tets.len() * 4);
    for (t, tet) in mesh.tets.iter().enumerate() {
        for skip in 0..4 {
            let mut f = [0u32; 3];
            let mut k = 0;
            for (j, &n) in tet.iter().enumerate() {
                if j != skip {
                    f[k] = n;
                    k += 1;
                }
            }
            f.sort_unstable();
            faces.push((f, t as u32));
        }
    }
    faces.sort_unstable();
    let mut parent: Vec<u32> = (0..mesh.tets.len() as u32).collect();
    fn find(parent: &mut [u32], mut x: u32) -> u32 {
        while parent[x as usize] != x {
            parent[x as usize] = parent[parent[x as usize] as usize];
            x = parent[x as usize];
        }
        x
    }
    for w in faces.windows(2) {
        if w[0].0 == w[1].0 {
            let (a, b) = (find(&mut parent, w[0].1), find(&mut parent, w[1].1));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    (0..mesh.tets.len() as u32).filter(|&t| find(&mut parent, t) == t).count()
}

struct Counts {
    nodes: usize,
    tets: usize,
    surface: usize,
}

fn check(preset: Preset) -> Counts {
    let p = phantom(preset);
    let m = &p.mesh;
    let s = m.boundary();
    let pos = s.gather_positions(&m.positions);
    let (area_vector, volume) = s.area_vector_and_volume(&pos);
    let total_area: f64 = s
        .triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|k| pos[k as usize]);
            0.5 * (b - a).cross(&(c - a)).norm()
        })
        .sum();
    assert!(area_vector.norm() < 1e-12 * total_area.max(1e-30) * 1e3, "{preset}: boundary area vectors must sum to ~0, got {area_vector} for area {total_area}");
    let tet_volume = m.volume();
    assert!((volume - tet_volume).abs() <= 1e-9 * tet_volume, "{preset}: divergence volume {volume} != tet volume {tet_volume}");
    assert_eq!(components(m), 1, "{preset}: the phantom must be one face-connected body");
    assert_eq!(m.reoriented, 0, "{preset}: stuffing emits positively oriented tets");
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for t in &m.tets {
        assert!(m.tet_volume(t) > 0.0, "{preset}: inverted tet {t:?}");
        let (a, b) = dihedral_range_deg(&t.map(|k| m.positions[k as usize]));
        lo = lo.min(a);
        hi = hi.max(b);
    }
    assert!(lo >= MIN_DIHEDRAL_DEG, "{preset}: min dihedral {lo} below the stated bound {MIN_DIHEDRAL_DEG}");
    assert!(hi <= MAX_DIHEDRAL_DEG, "{preset}: max dihedral {hi} above the stated bound {MAX_DIHEDRAL_DEG}");
    let c = Counts { nodes: m.node_count(), tets: m.tets.len(), surface: s.triangles.len() };
    println!(
        "{preset}: {} nodes, {} tets, {} surface triangles, dihedral {:.2}..{:.2} deg, volume {:.1} cm^3",
        c.nodes, c.tets, c.surface, lo, hi, tet_volume * 1e6
    );
    c
}

fn within(value: usize, target: usize, tolerance: f64) -> bool {
    let v = value as f64;
    let t = target as f64;
    v >= t * (1.0 - tolerance) && v <= t * (1.0 + tolerance)
}

fn assert_paper(preset: Preset, nodes: usize, tets: usize, surface: usize) {
    let c = check(preset);
    assert!(within(c.nodes, nodes, 0.15), "{preset}: {} nodes, paper {nodes} (±15%)", c.nodes);
    assert!(within(c.tets, tets, 0.15), "{preset}: {} tets, paper {tets} (±15%)", c.tets);
    assert!(within(c.surface, surface, 0.15), "{preset}: {} surface triangles, paper {surface} (±15%, the paper's count)", c.surface);
}

#[test]
fn paper_9k_matches_the_papers_counts() {
    assert_paper(Preset::Paper9k, 9_126, 34_401, 12_608);
}

#[test]
fn paper_12k_matches_the_papers_counts() {
    assert_paper(Preset::Paper12k, 12_331, 48_316, 15_865);
}

#[test]
fn small_and_blocks_are_about_5000_tets_under_1500_triangles() {
    for preset in [Preset::Small, Preset::VValley, Preset::UShape] {
        let c = check(preset);
        // The small presets' target: about 5,000 tets, taken as 4,250..5,750.
        assert!((4_250..=5_750).contains(&c.tets), "{preset}: {} tets, expected about 5,000 (4,250..5,750)", c.tets);
        assert!(c.surface < 1_500, "{preset}: {} surface triangles, expected under 1,500", c.surface);
    }
}

#[test]
fn generation_is_deterministic() {
    for preset in [Preset::Small, Preset::VValley] {
        let again = generate(preset).expect("second generation");
        assert!(again == *phantom(preset), "{preset}: generating twice must give an identical mesh and landmarks");
    }
}

#[test]
fn regions_are_the_documented_ones() {
    let m = &phantom(Preset::Small).mesh;
    for (t, tet) in m.tets.iter().enumerate() {
        let c = tet.iter().map(|&k| m.positions[k as usize]).sum::<Vec3>() / 4.0;
        let r = m.regions[t];
        assert!((1..=3).contains(&r), "brain regions are 1, 2, 3; got {r}");
        if r == 1 {
            assert!(c.x < 0.0, "region 1 is the left hemisphere, centroid {c}");
        }
        if r == 2 {
            assert!(c.x >= 0.0, "region 2 is the right hemisphere, centroid {c}");
        }
    }
    for r in 1..=3 {
        assert!(m.regions.contains(&r), "region {r} is present");
    }
    for preset in [Preset::VValley, Preset::UShape] {
        let m = &phantom(preset).mesh;
        assert!(m.regions.contains(&2) && m.regions.contains(&1), "{preset}: base layer (2) and body (1)");
    }
}

#[test]
fn landmarks_point_at_the_fissures() {
    let Landmarks::Brain(l) = &phantom(Preset::Paper12k).landmarks else {
        panic!("a brain preset has brain landmarks");
    };
    let m = &phantom(Preset::Paper12k).mesh;
    let (lo, hi) = m.bounding_box();
    let ih = &l.interhemispheric;
    assert!(ih.entry.x.abs() < 1e-9 && ih.normal == Vec3::x(), "inter-hemispheric plane is x = 0");
    assert!(ih.entry.z > 0.015 && ih.entry.z <= hi.z + 1e-9, "its entry is on the upper medial edge, got {}", ih.entry.z);
    assert!(ih.depth > 0.02 && ih.width >= 1.2 * Preset::Paper12k.edge(), "deep and resolved: {ih:?}");
    // No node lies inside the gap above the bridge on the mid-plane.
    let half = 0.5 * ih.width;
    let below = ih.entry.z - ih.depth;
    let inside_gap = m.positions.iter().filter(|p| p.x.abs() < 0.45 * half && p.z > below + 0.01 && p.z < ih.entry.z - 0.005 && p.y.abs() < 0.03).count();
    assert_eq!(inside_gap, 0, "the inter-hemispheric gap is open in the mesh");
    for (s, f) in [(-1.0, &l.sylvian_left), (1.0, &l.sylvian_right)] {
        assert!(f.entry.x * s > 0.04, "Sylvian entry lies on its lateral side: {f:?}");
        assert!((f.inward.x + s).abs() < 1e-12, "Sylvian inward points to the middle");
        assert!(f.depth > 0.01 && f.width >= 1.2 * Preset::Paper12k.edge(), "Sylvian depth and width: {f:?}");
    }
    assert_eq!(l.brain_stem_region, 3);
    assert!(l.brain_stem_box.min.z <= lo.z + 1e-9, "the brain stem reaches the bottom");
    for p in &m.positions {
        assert!((p - l.skull_containing.centre).norm() < l.skull_containing.radius, "containing sphere holds every node");
        assert!((p - l.skull_excluding.centre).norm() > l.skull_excluding.radius - 2e-3, "excluding sphere stays (nearly) outside the brain");
    }
    for preset in [Preset::VValley, Preset::UShape] {
        let Landmarks::Block(b) = &phantom(preset).landmarks else { panic!("{preset}: block landmarks") };
        assert!(b.width > 0.01 && b.depth > 0.01 && b.base_region == 2, "{preset}: {b:?}");
        assert!(b.base_box.max.z <= 0.006 + preset.edge(), "{preset}: base layer is the bottom 6 mm (+ one lattice edge), got {:?}", b.base_box);
    }
}
