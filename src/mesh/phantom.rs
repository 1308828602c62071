//! Deterministic procedural phantoms: a brain with fissures, and the paper's
//! Fig. 12 test blocks, meshed by isosurface stuffing.
//!
//! In: a [`Preset`]. Out: a [`Phantom`]: a [`TetMesh`] in METRES plus the
//! [`Landmarks`] scenario files need (fissure planes, entry points, fixed
//! region, skull spheres). Stays true: the same preset gives a bitwise-identical
//! mesh; every tet respects the stuffing bound (see
//! [`crate::mesh::tetrahedralize`]); the body is one face-connected component
//! whose boundary is closed and outward.
//!
//! The brain (millimetres below; x left(-)/right(+), y back(-)/front(+), z up):
//! two hemispheres, each an ellipsoid (semi-axes 34 x 85 x 55 mm, centres at
//! x = ±36 mm: 140 mm wide, 170 mm long, 110 mm tall) cut flat on its medial
//! side, so that the inter-hemispheric fissure is a planar gap of width
//! [`BrainShape::interhemispheric_width_mm`] (at least 1.2 lattice edges, so the
//! mesh resolves it) from the top down to a bridge (the corpus-callosum-like
//! connection) that joins the hemispheres into one body. On each lateral side a
//! Sylvian fissure: a planar cleft, tilted up towards the back, from the lateral
//! surface inwards, separating the frontal-parietal lobe above from the temporal
//! lobe below. Gyri: smooth sinusoidal relief of a few mm on the outer surface.
//! A brain-stem cylinder (region 3) hangs below the middle. Regions: 1 left
//! hemisphere (x < 0), 2 right (x >= 0), 3 brain stem.
//!
//! The blocks (Fig. 12): 60 x 60 x 30 mm with a V-shaped valley or a U-shaped
//! channel along y on top; region 2 is the 6 mm base layer to fix, region 1 the rest.

use std::fmt;
use std::str::FromStr;

use crate::math::Vec3;
use crate::mesh::TetMesh;
use crate::mesh::tetrahedralize::{TetrahedralizeError, tetrahedralize_sdf};

/// The phantoms we can generate.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Preset {
    /// A coarse brain: about 5,000 tets, under 1,500 surface triangles.
    Small,
    /// Sized like the paper's Fig. 5c model (9,126 nodes, 34,401 tets, 12,608 surface triangles).
    Paper9k,
    /// Sized like the paper's Fig. 5d model (12,331 nodes, 48,316 tets, 15,865 surface triangles).
    Paper12k,
    /// Fig. 12a: a block with a V-shaped valley on top.
    VValley,
    /// Fig. 12c: a block with a U-shaped channel on top.
    UShape,
}

impl Preset {
    /// Every preset, in a fixed order.
    pub const ALL: [Preset; 5] = [Preset::Small, Preset::Paper9k, Preset::Paper12k, Preset::VValley, Preset::UShape];

    /// The name used on the command line and in scenario files.
    pub fn name(self) -> &'static str {
        match self {
            Preset::Small => "small",
            Preset::Paper9k => "paper-9k",
            Preset::Paper12k => "paper-12k",
            Preset::VValley => "v-valley",
            Preset::UShape => "u-shape",
        }
    }

    /// Lattice edge length of the preset, metres (tuned to the target counts).
    pub fn edge(self) -> f64 {
        1e-3 * match self {
            Preset::Small => 14.0,
            Preset::Paper9k => 7.5,
            Preset::Paper12k => 6.7,
            Preset::VValley => 6.6,
            Preset::UShape => 6.5,
        }
    }
}

impl fmt::Display for Preset {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// An unknown preset name.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown phantom preset {given:?}; valid presets: small, paper-9k, paper-12k, v-valley, u-shape")]
pub struct UnknownPreset {
    pub given: String,
}

impl FromStr for Preset {
    type Err = UnknownPreset;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Preset::ALL.into_iter().find(|p| p.name() == s).ok_or_else(|| UnknownPreset { given: s.to_string() })
    }
}

/// A fissure on the brain: where a spatula enters and how the cleft lies.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fissure {
    /// Entry point on the outer surface at the fissure's mouth, metres.
    pub entry: Vec3,
    /// Unit direction from the entry into the depth of the fissure.
    pub inward: Vec3,
    /// Unit normal of the fissure's mid-plane (the direction spatulas open it).
    pub normal: Vec3,
    /// Depth from the entry to the fissure's floor along `inward`, metres.
    pub depth: f64,
    /// Gap between the fissure's walls, metres.
    pub width: f64,
}

/// An axis-aligned box, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: Vec3,
    pub max: Vec3,
}

/// A sphere, metres.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Sphere {
    pub centre: Vec3,
    /// Radius, metres (> 0).
    pub radius: f64,
}

/// What scenario files need to place tools, constraints and skull spheres.
#[derive(Debug, Clone, PartialEq)]
pub enum Landmarks {
    Brain(BrainLandmarks),
    Block(BlockLandmarks),
}

/// Landmarks of the brain presets (all in metres).
#[derive(Debug, Clone, PartialEq)]
pub struct BrainLandmarks {
    /// The inter-hemispheric fissure; its mid-plane is x = 0 (`normal` = +x),
    /// `entry` is the top of the gap, `inward` points down (-z).
    pub interhemispheric: Fissure,
    /// The left (x < 0) Sylvian fissure; `inward` points to +x.
    pub sylvian_left: Fissure,
    /// The right (x > 0) Sylvian fissure; `inward` points to -x.
    pub sylvian_right: Fissure,
    /// Region id of the brain stem (to fix).
    pub brain_stem_region: u32,
    /// Box around the brain stem's nodes.
    pub brain_stem_box: Aabb,
    /// A sphere that contains the whole brain (the skull's inside), with a few
    /// mm of clearance.
    pub skull_containing: Sphere,
    /// A sphere the brain stays outside of (the skull-base bump under the
    /// frontal lobes), touching the brain's nearest node (radius about 30 mm).
    pub skull_excluding: Sphere,
}

/// Landmarks of the test blocks (all in metres).
#[derive(Debug, Clone, PartialEq)]
pub struct BlockLandmarks {
    /// Middle of the valley/channel's mouth on the top face.
    pub entry: Vec3,
    /// Unit direction of the valley/channel (its axis), +y.
    pub axis: Vec3,
    /// Unit direction into the valley from the entry, -z.
    pub inward: Vec3,
    /// Width of the mouth at the top face, metres.
    pub width: f64,
    /// Depth of the valley/channel below the top face, metres.
    pub depth: f64,
    /// Region id of the base layer to fix.
    pub base_region: u32,
    /// Box around the base layer.
    pub base_box: Aabb,
}

/// A generated phantom.
#[derive(Debug, Clone, PartialEq)]
pub struct Phantom {
    /// The mesh, metres.
    pub mesh: TetMesh,
    pub landmarks: Landmarks,
}

/// Geometry of the brain (millimetres), chosen per preset.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BrainShape {
    /// Width of the inter-hemispheric gap, mm (>= 1.2 lattice edges).
    pub interhemispheric_width_mm: f64,
    /// Width of each Sylvian cleft, mm (>= 1.2 lattice edges).
    pub sylvian_width_mm: f64,
    /// Amplitude of the gyri relief, mm.
    pub gyri_amplitude_mm: f64,
    /// Width of each sulcus groove, mm (>= 1.2 lattice edges).
    pub sulcus_width_mm: f64,
}

impl BrainShape {
    /// The shape used by a brain preset: fissures 1.25 lattice edges wide.
    pub fn of(preset: Preset) -> Self {
        let edge_mm = preset.edge() * 1e3;
        Self {
            interhemispheric_width_mm: 1.25 * edge_mm,
            sylvian_width_mm: 1.25 * edge_mm,
            gyri_amplitude_mm: 2.5,
            sulcus_width_mm: 1.25 * edge_mm,
        }
    }
}

// Brain constants, mm.
const SEMI: [f64; 3] = [34.0, 85.0, 55.0];
const HEMI_X: f64 = 36.0;
const BRIDGE_TOP: f64 = -2.0;
const BRIDGE_HALF_Y: f64 = 40.0;
const STEM_RADIUS: f64 = 13.0;
const STEM_BOTTOM: f64 = -80.0;
const STEM_Y: f64 = -12.0;
const STEM_REGION_TOP: f64 = -45.0;
const SYLVIAN_Z: f64 = -8.0;
const SYLVIAN_TILT: f64 = 0.35; // radians, rising towards the back (-y)
const SYLVIAN_DEPTH: f64 = 24.0;
const SYLVIAN_Y: (f64, f64) = (-45.0, 55.0);
const SULCI_Y: [f64; 6] = [-66.0, -42.0, -18.0, 6.0, 30.0, 54.0];
const SULCUS_DEPTH: f64 = 22.0;

/// Polynomial smooth minimum (blend radius k, mm).
fn smin(a: f64, b: f64, k: f64) -> f64 {
    let h = (0.5 + 0.5 * (b - a) / k).clamp(0.0, 1.0);
    b + (a - b) * h - k * h * (1.0 - h)
}

/// Approximate signed distance of an ellipsoid (exact on the surface).
fn ellipsoid(p: &Vec3, c: &Vec3, r: &[f64; 3]) -> f64 {
    let q = p - c;
    let k0 = Vec3::new(q.x / r[0], q.y / r[1], q.z / r[2]).norm();
    let k1 = Vec3::new(q.x / (r[0] * r[0]), q.y / (r[1] * r[1]), q.z / (r[2] * r[2])).norm();
    if k1 > 0.0 { k0 * (k0 - 1.0) / k1 } else { -r[0].min(r[1]).min(r[2]) }
}

fn sylvian_normal() -> Vec3 {
    // Plane rising towards -y: normal (0, sin t, cos t).
    Vec3::new(0.0, SYLVIAN_TILT.sin(), SYLVIAN_TILT.cos())
}

/// The brain's signed distance (mm in, mm out; negative inside).
fn brain_sdf(p: &Vec3, shape: &BrainShape) -> f64 {
    let half_gap = 0.5 * shape.interhemispheric_width_mm;
    let side = if p.x < 0.0 { -1.0 } else { 1.0 };
    let c = Vec3::new(side * HEMI_X, 0.0, 0.0);
    // Gyri: smooth relief, strongest on the upper lateral surface.
    let g = shape.gyri_amplitude_mm * (p.y / 14.0).sin() * (p.z / 12.0 + p.x / 20.0).sin();
    let shell = ellipsoid(p, &c, &SEMI);
    let mut hemi = shell + g;
    // Sulci: grooves across the upper convexity, SULCUS_DEPTH deep.
    for &y in &SULCI_Y {
        let groove = (p.y - y - 0.3 * p.z).abs() - 0.5 * shape.sulcus_width_mm;
        let groove = groove.max(-(shell + SULCUS_DEPTH)).max(-p.z - 5.0);
        hemi = hemi.max(-groove);
    }
    // Flat medial face: the fissure wall at |x| = half_gap.
    let hemi = hemi.max(half_gap - p.x.abs());
    // Sylvian cleft on this side: slab around the tilted plane, from the
    // lateral surface inwards over SYLVIAN_DEPTH, within a y range.
    let n = sylvian_normal();
    let o = Vec3::new(0.0, 0.0, SYLVIAN_Z);
    let slab = (n.dot(&(p - o))).abs() - 0.5 * shape.sylvian_width_mm;
    let lateral = (HEMI_X + SEMI[0] - SYLVIAN_DEPTH) - p.x.abs();
    let along = (p.y - 0.5 * (SYLVIAN_Y.0 + SYLVIAN_Y.1)).abs() - 0.5 * (SYLVIAN_Y.1 - SYLVIAN_Y.0);
    let cleft = slab.max(lateral).max(along);
    let hemi = hemi.max(-cleft);
    // Bridge joining the hemispheres below the fissure.
    let bridge = (p.x.abs() - (half_gap + 6.0))
        .max(p.y.abs() - BRIDGE_HALF_Y)
        .max(p.z - BRIDGE_TOP)
        .max(-30.0 - p.z);
    let body = smin(hemi, bridge, 3.0);
    // Brain stem: vertical cylinder below the middle.
    let radial = Vec3::new(p.x, p.y - STEM_Y, 0.0).norm() - STEM_RADIUS;
    let stem = radial.max(STEM_BOTTOM - p.z).max(p.z + 15.0);
    smin(body, stem, 4.0)
}

fn brain_region(p: &Vec3) -> u32 {
    let radial = Vec3::new(p.x, p.y - STEM_Y, 0.0).norm();
    if p.z < STEM_REGION_TOP && radial < STEM_RADIUS + 6.0 {
        3
    } else if p.x < 0.0 {
        1
    } else {
        2
    }
}

// Block constants, mm.
const BLOCK: [f64; 3] = [60.0, 60.0, 30.0];
const BASE_LAYER: f64 = 6.0;
const VALLEY_WIDTH: f64 = 24.0;
const VALLEY_DEPTH: f64 = 16.0;
const CHANNEL_WIDTH: f64 = 16.0;
const CHANNEL_DEPTH: f64 = 16.0;

fn box_sdf(p: &Vec3, half: &[f64; 3], centre: &Vec3) -> f64 {
    let q = p - centre;
    let d = Vec3::new(q.x.abs() - half[0], q.y.abs() - half[1], q.z.abs() - half[2]);
    let outside = Vec3::new(d.x.max(0.0), d.y.max(0.0), d.z.max(0.0)).norm();
    outside + d.x.max(d.y).max(d.z).min(0.0)
}

/// Block with a valley (V) or channel (U) along y; top face at z = 30 mm.
fn block_sdf(p: &Vec3, v_shape: bool) -> f64 {
    let half = [BLOCK[0] / 2.0, BLOCK[1] / 2.0, BLOCK[2] / 2.0];
    let block = box_sdf(p, &half, &Vec3::new(0.0, 0.0, half[2]));
    let top = BLOCK[2];
    let cut = if v_shape {
        // Wedge: |x| < (z - (top - depth)) * (width/2)/depth.
        let slope = 0.5 * VALLEY_WIDTH / VALLEY_DEPTH;
        let n = Vec3::new(1.0, 0.0, -slope).normalize();
        let apex = top - VALLEY_DEPTH;
        n.dot(&Vec3::new(p.x.abs(), 0.0, p.z - apex))
    } else {
        // U: slot of half-width r above a half-cylinder of radius r.
        let r = 0.5 * CHANNEL_WIDTH;
        let centre_z = top - CHANNEL_DEPTH + r;
        if p.z > centre_z { p.x.abs() - r } else { Vec3::new(p.x, 0.0, p.z - centre_z).norm() - r }
    };
    block.max(-cut)
}

/// Generates a preset phantom (deterministic; metres).
pub fn generate(preset: Preset) -> Result<Phantom, TetrahedralizeError> {
    let edge = preset.edge();
    match preset {
        Preset::Small | Preset::Paper9k | Preset::Paper12k => {
            let shape = BrainShape::of(preset);
            let sdf = move |p: &Vec3| 1e-3 * brain_sdf(&(p * 1e3), &shape);
            let region = |p: &Vec3| brain_region(&(p * 1e3));
            let bounds = (Vec3::new(-0.075, -0.092, -0.085), Vec3::new(0.075, 0.092, 0.062));
            let mesh = tetrahedralize_sdf(&sdf, bounds, edge, &region)?;
            let landmarks = Landmarks::Brain(brain_landmarks(&mesh, &shape, &sdf));
            Ok(Phantom { mesh, landmarks })
        }
        Preset::VValley | Preset::UShape => {
            let v = preset == Preset::VValley;
            let sdf = move |p: &Vec3| 1e-3 * block_sdf(&(p * 1e3), v);
            let region = |p: &Vec3| if p.z * 1e3 < BASE_LAYER { 2 } else { 1 };
            let bounds = (Vec3::new(-0.032, -0.032, -0.002), Vec3::new(0.032, 0.032, 0.032));
            let mesh = tetrahedralize_sdf(&sdf, bounds, edge, &region)?;
            let (width, depth) = if v { (VALLEY_WIDTH, VALLEY_DEPTH) } else { (CHANNEL_WIDTH, CHANNEL_DEPTH) };
            let landmarks = Landmarks::Block(BlockLandmarks {
                entry: Vec3::new(0.0, 0.0, BLOCK[2] * 1e-3),
                axis: Vec3::y(),
                inward: -Vec3::z(),
                width: width * 1e-3,
                depth: depth * 1e-3,
                base_region: 2,
                base_box: region_box(&mesh, 2),
            });
            Ok(Phantom { mesh, landmarks })
        }
    }
}

/// Box around the nodes of the tets of one region (empty box at 0 if none).
fn region_box(mesh: &TetMesh, region: u32) -> Aabb {
    let (mut min, mut max) = (Vec3::repeat(f64::INFINITY), Vec3::repeat(f64::NEG_INFINITY));
    for (t, tet) in mesh.tets.iter().enumerate() {
        if mesh.regions[t] == region {
            for &n in tet {
                min = min.inf(&mesh.positions[n as usize]);
                max = max.sup(&mesh.positions[n as usize]);
            }
        }
    }
    if min.x > max.x { Aabb { min: Vec3::zeros(), max: Vec3::zeros() } } else { Aabb { min, max } }
}

/// Walks from `start` along `dir` (metres) until the field turns negative;
/// returns the first inside point (to 0.05 mm), or `start` if none within `reach`.
fn first_inside(sdf: &dyn Fn(&Vec3) -> f64, start: Vec3, dir: Vec3, reach: f64) -> Vec3 {
    let step = 0.5e-3;
    let mut s = 0.0;
    while s < reach {
        let p = start + dir * s;
        if sdf(&p) < 0.0 {
            // Bisect back to the surface.
            let (mut a, mut b) = (s - step, s);
            for _ in 0..20 {
                let m = 0.5 * (a + b);
                if sdf(&(start + dir * m)) < 0.0 { b = m } else { a = m }
            }
            return start + dir * b;
        }
        s += step;
    }
    start
}

fn brain_landmarks(mesh: &TetMesh, shape: &BrainShape, sdf: &dyn Fn(&Vec3) -> f64) -> BrainLandmarks {
    let mm = 1e-3;
    // Inter-hemispheric: the fissure's mouth is the top of the gap at y = 0.
    let top = SEMI[2] * mm;
    let inter_width = shape.interhemispheric_width_mm * mm;
    // Entry: where the medial wall's top edge lies (just beside the gap, walking down at x = half gap + 1 mm).
    let wall = first_inside(sdf, Vec3::new(0.5 * inter_width + mm, 0.0, top + 10.0 * mm), -Vec3::z(), 0.1);
    let interhemispheric = Fissure {
        entry: Vec3::new(0.0, 0.0, wall.z),
        inward: -Vec3::z(),
        normal: Vec3::x(),
        depth: wall.z - BRIDGE_TOP * mm,
        width: inter_width,
    };
    let n = sylvian_normal();
    let sylvian = |side: f64| {
        // Mouth on the lateral surface at y = 10 mm, on the cleft's mid-plane.
        let y = 10.0;
        let z = SYLVIAN_Z - y * n.y / n.z;
        let start = Vec3::new(side * 80.0 * mm, y * mm, z * mm);
        // Walk inwards just above the cleft to find the lateral surface.
        let probe = first_inside(sdf, start + n * (0.5 * shape.sylvian_width_mm + 1.5) * mm, Vec3::new(-side, 0.0, 0.0), 0.08);
        let entry = Vec3::new(probe.x, start.y, start.z);
        let floor_x = side * (HEMI_X + SEMI[0] - SYLVIAN_DEPTH) * mm;
        Fissure {
            entry,
            inward: Vec3::new(-side, 0.0, 0.0),
            normal: n,
            depth: (entry.x - floor_x).abs(),
            width: shape.sylvian_width_mm * mm,
        }
    };
    let (lo, hi) = mesh.bounding_box();
    let centre = (lo + hi) * 0.5;
    let radius = mesh.positions.iter().map(|p| (p - centre).norm()).fold(0.0, f64::max) + 5.0 * mm;
    // Skull base bump: a sphere below the frontal lobes touching the underside.
    let bump_radius = 30.0 * mm;
    let under = first_inside(sdf, Vec3::new(20.0 * mm, 45.0 * mm, -0.09), Vec3::z(), 0.1);
    // Centre below that point; radius so that it touches the nearest node.
    let bump_centre = under - Vec3::z() * bump_radius;
    let bump_touch = mesh.positions.iter().map(|p| (p - bump_centre).norm()).fold(f64::INFINITY, f64::min);
    let skull_excluding = Sphere { centre: bump_centre, radius: bump_touch };
    BrainLandmarks {
        interhemispheric,
        sylvian_left: sylvian(-1.0),
        sylvian_right: sylvian(1.0),
        brain_stem_region: 3,
        brain_stem_box: region_box(mesh, 3),
        skull_containing: Sphere { centre, radius },
        skull_excluding,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_lists_valid_ones() {
        for p in Preset::ALL {
            assert_eq!(p.name().parse::<Preset>(), Ok(p));
        }
        let e = "paper9k".parse::<Preset>().unwrap_err();
        let msg = e.to_string();
        assert!(Preset::ALL.iter().all(|p| msg.contains(p.name())), "error lists every valid name: {msg}");
    }

    #[test]
    fn fissures_are_wider_than_1_2_edges() {
        for p in [Preset::Small, Preset::Paper9k, Preset::Paper12k] {
            let s = BrainShape::of(p);
            let e = p.edge() * 1e3;
            assert!(s.interhemispheric_width_mm >= 1.2 * e && s.sylvian_width_mm >= 1.2 * e, "{p}: fissures must be resolved");
        }
    }

    #[test]
    fn brain_field_has_gaps_where_the_fissures_are() {
        let s = BrainShape::of(Preset::Paper12k);
        // Inside a hemisphere, in the gap, in the Sylvian cleft, in the stem.
        assert!(brain_sdf(&Vec3::new(30.0, 0.0, 20.0), &s) < 0.0, "hemisphere interior");
        assert!(brain_sdf(&Vec3::new(0.0, 0.0, 30.0), &s) > 0.0, "inter-hemispheric gap is outside");
        assert!(brain_sdf(&Vec3::new(0.0, 0.0, -10.0), &s) < 0.0, "bridge below the gap is inside");
        let n = sylvian_normal();
        let on_plane = Vec3::new(60.0, 10.0, SYLVIAN_Z - 10.0 * n.y / n.z);
        assert!(brain_sdf(&on_plane, &s) > 0.0, "Sylvian cleft is outside");
        assert!(brain_sdf(&Vec3::new(0.0, STEM_Y, -70.0), &s) < 0.0, "brain stem is inside");
        assert_eq!(brain_region(&Vec3::new(0.0, STEM_Y, -70.0)), 3);
        assert_eq!(brain_region(&Vec3::new(-30.0, 0.0, 0.0)), 1);
        assert_eq!(brain_region(&Vec3::new(30.0, 0.0, 0.0)), 2);
        assert!(block_sdf(&Vec3::new(0.0, 0.0, 25.0), true) > 0.0 && block_sdf(&Vec3::new(20.0, 0.0, 25.0), true) < 0.0);
        assert!(block_sdf(&Vec3::new(0.0, 0.0, 20.0), false) > 0.0 && block_sdf(&Vec3::new(0.0, 0.0, 10.0), false) < 0.0);
    }
}
