//! What the renderer draws: plain data the pipeline (or a test) fills each frame.
//!
//! In: borrowed slices of the deformed surface, an optional per-vertex scalar
//! field, spatula shapes and poses, overlays, skull spheres, tether tubes
//! (vessels, arachnoid bands), a camera. Out:
//! nothing (data only). Stays true: no simulation types beyond `Vec3`, `Pose`
//! and `SpatulaShape`; everything is in metres, world frame.

use super::camera::OrbitCamera;
use super::colormap::ColorMap;
use crate::geometry::{Pose, SpatulaShape};
use crate::math::Vec3;

/// Linear-RGB brain colour used when no field is shown: the pia's pale pink under the microscope's light (darkened
/// in the sulci by the surface's ambient factor, [`super::occlusion`]).
pub const BRAIN_PINK: [f32; 3] = [0.80, 0.40, 0.35];
/// Linear-RGB colour of the blades (brushed steel grey).
pub const STEEL_GREY: [f32; 3] = [0.55, 0.57, 0.60];
/// Linear-RGB default background (dark blue-grey).
pub const BACKGROUND: [f32; 3] = [0.015, 0.018, 0.025];

/// Which physical quantity a scalar field carries (for the legend and defaults).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum FieldKind {
    /// Displacement magnitude, millimetres.
    DisplacementMm,
    /// Largest principal strain, dimensionless.
    Strain,
    /// Contact (retraction) pressure, mmHg.
    ContactPressureMmHg,
    /// Risk of infarct under a retractor, 0 to 1, dimensionless.
    InfarctRisk,
}

impl FieldKind {
    /// A short label with the unit.
    pub fn label(self) -> &'static str {
        match self {
            FieldKind::DisplacementMm => "displacement (mm)",
            FieldKind::Strain => "max principal strain (-)",
            FieldKind::ContactPressureMmHg => "contact pressure (mmHg)",
            FieldKind::InfarctRisk => "infarct risk (0 to 1)",
        }
    }

    /// The colour map this quantity uses by default.
    pub fn default_map(self) -> ColorMap {
        match self {
            FieldKind::DisplacementMm => ColorMap::Viridis,
            FieldKind::Strain => ColorMap::Viridis,
            FieldKind::ContactPressureMmHg => ColorMap::Inferno,
            FieldKind::InfarctRisk => ColorMap::WhitePurple,
        }
    }
}

/// A per-vertex scalar shown as colour.
#[derive(Debug, Clone, Copy)]
pub struct ScalarField<'a> {
    /// One value per surface vertex, in the unit of `kind`.
    pub values: &'a [f64],
    /// What the values are.
    pub kind: FieldKind,
    /// The colour map.
    pub map: ColorMap,
    /// Values mapped to the two ends of the map (min < max; values outside are clamped).
    pub range: (f64, f64),
}

/// The deformed brain surface.
#[derive(Debug, Clone, Copy)]
pub struct SurfaceView<'a> {
    /// Current (deformed) vertex positions, metres.
    pub positions: &'a [Vec3],
    /// Triangles in vertex indices, counter-clockwise seen from outside.
    pub triangles: &'a [[u32; 3]],
    /// Optional colouring; `None` draws the plain brain colour, shaded by `occlusion` and wet.
    pub field: Option<ScalarField<'a>>,
    /// Per vertex, the ambient factor of the surface at rest ([`super::occlusion::surface_occlusion`]); empty: 1.
    pub occlusion: &'a [f32],
}

/// One spatula, drawn as a solid box over its blade.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatulaView {
    pub shape: SpatulaShape,
    pub pose: Pose,
    /// Linear RGB, each 0..1 (default [`STEEL_GREY`]).
    pub color: [f32; 3],
}

impl SpatulaView {
    /// A steel-grey spatula.
    pub fn new(shape: SpatulaShape, pose: Pose) -> Self {
        Self {
            shape,
            pose,
            color: STEEL_GREY,
        }
    }
}

/// A line from a source node to the triangle it pairs with.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairSegment {
    /// Source node, metres.
    pub from: Vec3,
    /// Hit point on the triangle, metres.
    pub to: Vec3,
    /// True for a feasible pair (green), false for a culled one (red).
    pub feasible: bool,
}

/// Debug overlays, drawn on top of everything (no depth test) so they stay visible.
#[derive(Debug, Clone, Copy, Default)]
pub struct Overlays<'a> {
    /// Source nodes, metres; drawn as small camera-facing squares.
    pub source_nodes: &'a [Vec3],
    /// Side of a source-node square, metres (> 0; 0 picks 0.6 % of the camera distance).
    pub node_size_m: f64,
    /// Pairs, feasible or culled.
    pub pairs: &'a [PairSegment],
}

/// A skull sphere, drawn translucent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SkullSphere {
    /// Centre, metres.
    pub center: Vec3,
    /// Radius, metres (> 0).
    pub radius: f64,
    /// Linear RGBA; alpha 0..1 (e.g. 0.15).
    pub color: [f32; 4],
}

/// A tube between two points: a vessel segment, an arachnoid band, the stub
/// of a torn vessel's end.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TetherSegment {
    /// The two ends, metres.
    pub a: Vec3,
    pub b: Vec3,
    /// Tube radius, metres (> 0; a segment with none, or not finite, is not drawn).
    pub radius_m: f32,
    /// Linear RGB, each 0..1.
    pub color: [f32; 3],
    /// Opacity 0..1: 1 draws a lit solid tube with rounded ends, below 1 a
    /// translucent strand (blended, after the opaque parts).
    pub alpha: f32,
}

/// Everything one frame draws.
#[derive(Debug, Clone, Copy)]
pub struct SceneView<'a> {
    pub surface: SurfaceView<'a>,
    pub spatulas: &'a [SpatulaView],
    pub overlays: Overlays<'a>,
    pub skull: &'a [SkullSphere],
    /// Vessels and bands tied to the surface (empty in a scene without them).
    pub tethers: &'a [TetherSegment],
    pub camera: OrbitCamera,
    /// Linear RGB background.
    pub background: [f32; 3],
}

impl<'a> SceneView<'a> {
    /// A view of a surface with the default background and nothing else.
    pub fn new(positions: &'a [Vec3], triangles: &'a [[u32; 3]], camera: OrbitCamera) -> Self {
        Self {
            surface: SurfaceView {
                positions,
                triangles,
                field: None,
                occlusion: &[],
            },
            spatulas: &[],
            overlays: Overlays::default(),
            skull: &[],
            tethers: &[],
            camera,
            background: BACKGROUND,
        }
    }
}
