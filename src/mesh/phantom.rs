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
//! Sulci (the paper-size presets; a real cortex has far more surface per volume
//! than an ellipsoid, and the paper's meshes have about one surface triangle
//! per three tets): eight grooves across the convexity, tilted like the central
//! sulcus, and two temporal grooves parallel to and below each Sylvian cleft,
//! all [`SULCUS_DEPTH`] deep and [`BrainShape::sulcus_width_mm`] wide. They stay
//! clear of what scenarios use: the medial walls of the inter-hemispheric
//! fissure stay flat (sulci keep |x| >= [`SULCUS_MEDIAL_KEEP`]), no sulcus
//! comes within 13 mm of the Sylvian cleft over y in [2, 18] mm where the
//! Sylvian landmark and its spatulas are, nor reaches the frontal underside
//! the skull-base sphere touches. The `small`
//! preset is smooth (no sulci, a shallow Sylvian cleft) so that it keeps under
//! 1,500 surface triangles at about 5,000 tets.
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
    /// A coarse, smooth brain: about 5,000 tets, under 1,500 surface triangles.
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
            Preset::Small => 15.5,
            Preset::Paper9k => 7.3,
            Preset::Paper12k => 6.6,
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
    /// Depth of each Sylvian cleft from the lateral extreme of its hemisphere
    /// (x = ±70 mm) inwards, mm (0..34).
    pub sylvian_depth_mm: f64,
    /// Amplitude of the gyri relief, mm (0..5).
    pub gyri_amplitude_mm: f64,
    /// Width of each sulcus groove, mm (>= 1.2 lattice edges).
    pub sulcus_width_mm: f64,
    /// Whether the sulci are carved (see the module notes).
    pub sulci: bool,
}

impl BrainShape {
    /// The shape used by a brain preset. The paper-size presets keep the
    /// fissure widths their landmarks (and so the scenario files and recorded
    /// trajectories) were placed with: 1.25 times the lattice edges they were
    /// first tuned with (7.5 mm for paper-9k, 6.7 mm for paper-12k), still
    /// above 1.2 of today's edges; sulci are 1.25 edges wide. `small` is
    /// smooth, its fissures 1.25 edges wide.
    pub fn of(preset: Preset) -> Self {
        let edge_mm = preset.edge() * 1e3;
        let (fissure_width_mm, sylvian_depth_mm, sulci) = match preset {
            Preset::Paper9k => (1.25 * 7.5, SYLVIAN_DEPTH, true),
            Preset::Paper12k => (1.25 * 6.7, SYLVIAN_DEPTH, true),
            Preset::Small | Preset::VValley | Preset::UShape => (1.25 * edge_mm, 10.0, false),
        };
        Self {
            interhemispheric_width_mm: fissure_width_mm,
            sylvian_width_mm: fissure_width_mm,
            sylvian_depth_mm,
            gyri_amplitude_mm: 2.5,
            sulcus_width_mm: 1.25 * edge_mm,
            sulci,
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
/// Sulci across the convexity, each the slab around the plane
/// y - [`SULCUS_TILT`] z = y0, above a lowest z: (y0, lowest z), mm, about
/// 20 mm apart, so that every gyrus between two grooves stays over 1.2
/// lattice edges thick (thinner ones break off the mesh). None comes within
/// 13 mm of the Sylvian cleft's plane over y in [2, 18] mm (the Sylvian
/// landmark and the band its spatulas open): the two beside that band stop at
/// z = -5 mm, the one above it at z = 12 mm. The frontal one runs down the
/// lateral side to z = -25 mm (above the frontal underside the skull-base
/// sphere touches), the occipital ones to z = -35 mm, across the back of the
/// Sylvian cleft; the two at the poles only cut the upper half, so that no
/// pole is cut off.
const CONVEXITY_SULCI: [(f64, f64); 8] =
    [(-68.0, 0.0), (-48.0, -35.0), (-28.0, -35.0), (-8.0, -5.0), (10.0, 12.0), (28.0, -5.0), (48.0, -25.0), (68.0, 0.0)];
/// Backward lean of the convexity sulci (dy/dz), like the central sulcus.
const SULCUS_TILT: f64 = 0.3;
/// Temporal sulci: slabs parallel to the Sylvian plane at these signed
/// distances from it (mm, negative = below), on the lateral side
/// (|x| >= [`TEMPORAL_SULCI_X`]) over y in [`TEMPORAL_SULCI_Y`].
const TEMPORAL_SULCI: [f64; 2] = [-20.0, -34.0];
const TEMPORAL_SULCI_X: f64 = 45.0;
const TEMPORAL_SULCI_Y: (f64, f64) = (-40.0, 50.0);
/// Depth of every sulcus below the hemisphere's ellipsoid, mm.
pub const SULCUS_DEPTH: f64 = 30.0;
/// Sulci keep |x| >= this (mm): the inter-hemispheric fissure's medial walls
/// stay flat (the landmark's entry is found at |x| = half gap + 1 mm).
pub const SULCUS_MEDIAL_KEEP: f64 = 14.0;

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
    let n = sylvian_normal();
    let o = Vec3::new(0.0, 0.0, SYLVIAN_Z);
    if shape.sulci {
        // Each groove: a slab, cut to the SULCUS_DEPTH under the ellipsoid and
        // to its extent; the solid minus the groove is max(solid, -groove).
        let half_width = 0.5 * shape.sulcus_width_mm;
        let under_shell = -(shell + SULCUS_DEPTH);
        let medial = SULCUS_MEDIAL_KEEP - p.x.abs();
        for &(y0, lowest_z) in &CONVEXITY_SULCI {
            let groove = ((p.y - y0 - SULCUS_TILT * p.z).abs() - half_width).max(under_shell).max(lowest_z - p.z).max(medial);
            hemi = hemi.max(-groove);
        }
        let along = (p.y - 0.5 * (TEMPORAL_SULCI_Y.0 + TEMPORAL_SULCI_Y.1)).abs() - 0.5 * (TEMPORAL_SULCI_Y.1 - TEMPORAL_SULCI_Y.0);
        let lateral = TEMPORAL_SULCI_X - p.x.abs();
        for &offset in &TEMPORAL_SULCI {
            let groove = ((n.dot(&(p - o)) - offset).abs() - half_width).max(under_shell).max(along).max(lateral);
            hemi = hemi.max(-groove);
        }
    }
    // Flat medial face: the fissure wall at |x| = half_gap.
    let hemi = hemi.max(half_gap - p.x.abs());
    // Sylvian cleft on this side: slab around the tilted plane, from the
    // lateral surface inwards over the shape's Sylvian depth, within a y range.
    let slab = (n.dot(&(p - o))).abs() - 0.5 * shape.sylvian_width_mm;
    let lateral = (HEMI_X + SEMI[0] - shape.sylvian_depth_mm) - p.x.abs();
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
        let floor_x = side * (HEMI_X + SEMI[0] - shape.sylvian_depth_mm) * mm;
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
    fn sulci_leave_the_landmark_zones_as_they_were() {
        // The zones scenario files rely on keep their inside/outside: the
        // medial walls of the inter-hemispheric fissure (|x| in [4, 13] mm),
        // the band y in [2, 18] mm around the Sylvian landmark (13 mm either
        // side of the cleft's plane, where its blades spread), and the frontal
        // underside under the skull-base sphere.
        let mut zones: Vec<Vec3> = Vec::new();
        for i in 0..=40 {
            for j in 0..=40 {
                let (u, v) = (i as f64 / 40.0, j as f64 / 40.0);
                zones.push(Vec3::new(4.0 + 9.0 * u, -80.0 + 160.0 * v, -2.0 + 57.0 * u * v));
                let y = 2.0 + 16.0 * v;
                zones.push(Vec3::new(-72.0 + 24.0 * u, y, SYLVIAN_Z - y * SYLVIAN_TILT.tan() - 14.0 + 28.0 * u));
                zones.push(Vec3::new(5.0 + 30.0 * u, 25.0 + 40.0 * v, -60.0 + 30.0 * u * v));
            }
        }
        let inside = |p: &Vec3, s: &BrainShape| brain_sdf(p, s) < 0.0;
        for preset in [Preset::Paper9k, Preset::Paper12k] {
            let with = BrainShape::of(preset);
            let without = BrainShape { sulci: false, ..with };
            for p in &zones {
                for q in [*p, Vec3::new(-p.x, p.y, p.z)] {
                    assert_eq!(inside(&q, &with), inside(&q, &without), "{preset}: sulci reach the landmark zone at {q}");
                }
            }
            // Elsewhere they do cut: along a diagonal through both hemispheres.
            let carved = (0..2000)
                .map(|k| Vec3::new(-70.0 + 0.07 * k as f64, -80.0 + 0.08 * k as f64, 50.0 - 0.05 * k as f64))
                .filter(|p| inside(p, &without) && !inside(p, &with))
                .count();
            assert!(carved > 20, "{preset}: the sulci must carve the convexity, {carved} of 2000 samples");
        }
    }

    #[test]
    fn brain_field_has_gaps_where_the_fissures_are() {
        let s = BrainShape::of(Preset::Paper12k);
        // Inside a hemisphere, in the gap, in the Sylvian cleft, in the stem.
        assert!(brain_sdf(&Vec3::new(30.0, 10.0, 0.0), &s) < 0.0, "hemisphere interior (the wide gyrus above the Sylvian landmark)");
        assert!(brain_sdf(&Vec3::new(0.0, 0.0, 30.0), &s) > 0.0, "inter-hemispheric gap is outside");
        assert!(brain_sdf(&Vec3::new(0.0, 0.0, -10.0), &s) < 0.0, "bridge below the gap is inside");
        let n = sylvian_normal();
        let on_plane = Vec3::new(60.0, 10.0, SYLVIAN_Z - 10.0 * n.y / n.z);
        assert!(brain_sdf(&on_plane, &s) > 0.0, "Sylvian cleft is outside");
        assert!(brain_sdf(&Vec3::new(0.0, STEM_Y, -70.0), &s) < 0.0, "brain stem is inside");
        assert_eq!(brain_region(&Vec3::new(0.0, STEM_Y, -70.0)), 3);
        assert_eq!(brain_region(&Vec3::new(-30.0, 0.0, 0.0)), 1);
        assert_eq!(brain_region(&Vec3::new(30.0, 0.0, 0.0)), 2);
        // A convexity sulcus cuts the upper lateral surface; a temporal one the temporal lobe.
        let (y0, _) = CONVEXITY_SULCI[2];
        let top = Vec3::new(40.0, y0 + SULCUS_TILT * 40.0, 40.0);
        assert!(brain_sdf(&top, &s) > 0.0, "convexity sulcus at y0 = {y0} is open at {top}");
        assert!(brain_sdf(&(top - Vec3::y() * 8.0), &s) < 0.0, "the gyrus beside it is solid");
        let o = Vec3::new(-62.0, 10.0, SYLVIAN_Z - 10.0 * n.y / n.z);
        assert!(brain_sdf(&(o + n * TEMPORAL_SULCI[0]), &s) > 0.0, "superior temporal sulcus is open");
        assert!(brain_sdf(&(o + n * 0.5 * (TEMPORAL_SULCI[0] - 0.5 * s.sylvian_width_mm)), &s) < 0.0, "temporal gyrus between it and the Sylvian cleft is solid");
        assert!(block_sdf(&Vec3::new(0.0, 0.0, 25.0), true) > 0.0 && block_sdf(&Vec3::new(20.0, 0.0, 25.0), true) < 0.0);
        assert!(block_sdf(&Vec3::new(0.0, 0.0, 20.0), false) > 0.0 && block_sdf(&Vec3::new(0.0, 0.0, 10.0), false) < 0.0);
    }
}
