//! The drawing shared by the window, `fissure screenshot` and `replay --frames`:
//! a [`Snapshot`] of one simulation frame (owned plain data) and the
//! [`SceneBuffers`] that turn it into a [`SceneView`].
//!
//! In: the pipeline and its state after a step (the snapshot copies what it
//! needs), drawing switches ([`DrawOptions`]) and a camera. Out: a
//! `SceneView` borrowing the snapshot and the buffers. Stays true: the three
//! consumers draw through [`SceneBuffers::view`] only, so a screenshot looks
//! like the window; capturing a snapshot reuses its vectors (no allocation once
//! sized; a scene's vessels and bands, when it has them, through
//! [`super::tethers`]; its tissue over time, the relaxed pressures and the
//! infarct risk, from the pipeline's stages); nothing here touches the GPU.

use crate::geometry::Pose;
use crate::math::Vec3;
use crate::render::{
    FieldKind, OrbitCamera, Overlays, PairSegment, ScalarField, SceneView, SkullSphere, SpatulaView,
};
use crate::sim::{FrameReport, Pipeline, SimState};

/// Pascals in one mmHg.
pub const PASCALS_PER_MMHG: f64 = 133.322_387_415;

/// Which quantity colours the brain surface.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum SurfaceField {
    /// The plain brain colour.
    #[default]
    None,
    /// Displacement magnitude from rest, mm (0..[`DISPLACEMENT_FULL_SCALE_MM`]).
    Displacement,
    /// Contact pressure at each constrained vertex, mmHg (0..[`DrawOptions::pressure_max_mmhg`],
    /// white to dark red, the 20 mmHg injury line marked on the legend).
    Pressure,
    /// Largest principal strain of the tets under each vertex (0..[`STRAIN_FULL_SCALE`]);
    /// plain while the snapshot has no strain yet.
    Strain,
    /// Risk of infarct of each vertex under the retractors (0..1, white to dark
    /// purple, the levels 1/6, 1/2, 5/6 marked on the legend); plain in a scene
    /// without the `Ischemia` effect.
    Risk,
}

impl SurfaceField {
    /// The field the F key shows after `self`: none, displacement, pressure,
    /// strain, then infarct risk where the scene has it (`has_risk`: the
    /// `Ischemia` effect), then none again.
    pub fn next(self, has_risk: bool) -> Self {
        match self {
            SurfaceField::None => SurfaceField::Displacement,
            SurfaceField::Displacement => SurfaceField::Pressure,
            SurfaceField::Pressure => SurfaceField::Strain,
            SurfaceField::Strain if has_risk => SurfaceField::Risk,
            SurfaceField::Strain | SurfaceField::Risk => SurfaceField::None,
        }
    }
}

/// Displacement mapped to the top of the colour map, mm.
pub const DISPLACEMENT_FULL_SCALE_MM: f64 = 10.0;
/// Pressure mapped to the top of the colour map by default, mmHg: a real
/// retraction's 6-12 mmHg shows yellow to orange, the 20 mmHg line red.
pub const PRESSURE_FULL_SCALE_MMHG: f64 = crate::render::legend::DEFAULT_PRESSURE_MAX_MMHG;
/// Largest principal strain mapped to the top of the colour map (10 %: the low
/// end of the tissue strain thresholds for axonal injury reported in the
/// literature, about 10-20 %; strain above it shows at the top).
pub const STRAIN_FULL_SCALE: f64 = 0.1;

/// Switches that change what is drawn (not what is simulated).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DrawOptions {
    pub field: SurfaceField,
    pub source_nodes: bool,
    pub pairs: bool,
    pub skull: bool,
    /// Pressure at the top of the colour bar, mmHg (> 0; the scenario's
    /// `display.pressure_max_mmhg`, the panel's slider).
    pub pressure_max_mmhg: f64,
    /// The scenario's own cameras (`display.overview` / `display.microscope`).
    pub views: crate::scenario::Views,
}

impl Default for DrawOptions {
    fn default() -> Self {
        Self {
            field: SurfaceField::None,
            source_nodes: false,
            pairs: false,
            skull: true,
            pressure_max_mmhg: PRESSURE_FULL_SCALE_MMHG,
            views: crate::scenario::Views::default(),
        }
    }
}

/// How a field is coloured: its kind, map and range (the field's own unit).
pub fn field_scale(field: SurfaceField, pressure_max_mmhg: f64) -> Option<(FieldKind, crate::render::ColorMap, (f64, f64))> {
    let pressure_max = if pressure_max_mmhg.is_finite() && pressure_max_mmhg > 0.0 { pressure_max_mmhg } else { PRESSURE_FULL_SCALE_MMHG };
    match field {
        SurfaceField::None => None,
        SurfaceField::Displacement => Some((FieldKind::DisplacementMm, FieldKind::DisplacementMm.default_map(), (0.0, DISPLACEMENT_FULL_SCALE_MM))),
        SurfaceField::Pressure => Some((FieldKind::ContactPressureMmHg, crate::render::ColorMap::WhiteYellowRed, (0.0, pressure_max))),
        SurfaceField::Strain => Some((FieldKind::Strain, FieldKind::Strain.default_map(), (0.0, STRAIN_FULL_SCALE))),
        SurfaceField::Risk => Some((FieldKind::InfarctRisk, FieldKind::InfarctRisk.default_map(), (0.0, 1.0))),
    }
}

/// The colour bar of what `options` shows on `snapshot` (`None`: no field,
/// strain not computed yet, or risk in a scene without it).
pub fn legend_for(options: &DrawOptions, snapshot: &Snapshot) -> Option<crate::render::legend::Legend> {
    let n = snapshot.surface_positions.len();
    match options.field {
        SurfaceField::Strain if snapshot.strain.len() != n => return None,
        SurfaceField::Risk if snapshot.risk.len() != n => return None,
        _ => {}
    }
    let (kind, map, range) = field_scale(options.field, options.pressure_max_mmhg)?;
    crate::render::legend::Legend::of(kind, map, range)
}

/// One simulation frame as plain owned data (what the window and the
/// screenshot draw; what the simulation thread publishes).
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    /// Frame index (frames done).
    pub frame: u64,
    /// Simulated time, s.
    pub time_s: f64,
    /// Deformed surface-vertex positions, m.
    pub surface_positions: Vec<Vec3>,
    /// |displacement| per surface vertex, mm.
    pub displacement_mm: Vec<f64>,
    /// Contact pressure per surface vertex, mmHg (0 where not in contact);
    /// relaxed where the scene has the `Relaxation` effect, as the report's
    /// forces are.
    pub pressure_mmhg: Vec<f64>,
    /// Risk of infarct per surface vertex, 0 to 1 (the `Ischemia` effect;
    /// empty without it).
    pub risk: Vec<f64>,
    /// Per blade: the simulated time its area at risk first passed zero, s
    /// (the `Ischemia` effect; empty without it).
    pub first_at_risk_s: Vec<Option<f64>>,
    /// Largest principal strain per surface vertex: the mean over the tets that
    /// own its boundary triangles, from the StressField stage or the window's
    /// background stress worker. Empty when neither has given stress.
    pub strain: Vec<f64>,
    /// Scratch of [`surface_strain`]: boundary triangles per vertex.
    strain_count: Vec<u32>,
    /// Spatula poses the frame used.
    pub poses: Vec<Pose>,
    /// The frame's report (timings, pairs, forces, pressures).
    pub report: FrameReport,
    /// Source nodes, m (empty without collision).
    pub source_nodes: Vec<Vec3>,
    /// Feasible and culled pairs as segments.
    pub pairs: Vec<PairSegment>,
    /// What moved each blade this frame (the window's simulation thread
    /// fills it; empty elsewhere).
    pub drivers: Vec<crate::input::drivers::Driver>,
    /// The blade a `--script` made active (it drives the keys then; `None`
    /// without a script: the window's own keyboard says which).
    pub scripted_spatula: Option<usize>,
    /// Vessels and bands at this frame, and what happened to them so far
    /// (empty in a scene without tethers).
    pub tethers: super::tethers::TetherSnapshot,
}

pub use crate::mesh::surface::vertex_areas;

impl Snapshot {
    /// Copies the frame just stepped (`report` is what `step` returned;
    /// `areas` from [`vertex_areas`]).
    pub fn capture(&mut self, pipeline: &Pipeline, state: &SimState, report: &FrameReport, areas: &[f64]) {
        self.frame = state.frame;
        self.time_s = state.time_s;
        self.surface_positions.clear();
        self.surface_positions.extend_from_slice(&state.surface_positions);
        self.displacement_mm.clear();
        self.displacement_mm.extend(state.surface_displacement.iter().map(|u| u.norm() * 1e3));
        self.poses.clear();
        self.poses.extend_from_slice(&state.poses);
        self.report.clone_from(report);
        let n = state.surface_positions.len();
        let surface = pipeline.surface();
        self.capture_pressure(pipeline, n, areas);
        self.risk.clear();
        self.first_at_risk_s.clear();
        if let Some(ischemia) = pipeline.ischemia() {
            self.risk.extend((0..n).map(|v| ischemia.risk(v)));
            self.first_at_risk_s.extend_from_slice(ischemia.first_at_risk_s());
        }
        self.set_strain(surface, &state.stress);
        self.tethers.capture(pipeline.tethers(), &state.surface_positions);
        self.source_nodes.clear();
        self.pairs.clear();
        if let Some(collision) = pipeline.collision() {
            let out = collision.output();
            self.source_nodes.extend(out.source_nodes.iter().map(|n| n.position));
            let segment = |spatula: u8, face: u8, node: u32, t: f64, feasible: bool| {
                out.source_nodes
                    .iter()
                    .find(|n| n.spatula == spatula && n.face == face && n.node == node)
                    .map(|n| PairSegment { from: n.position, to: n.position + n.normal * t, feasible })
            };
            for p in &out.feasible_pairs {
                self.pairs.extend(segment(p.spatula, p.face, p.node, p.t, true));
            }
            for (p, _) in &out.culled_pairs {
                self.pairs.extend(segment(p.spatula, p.face, p.node, p.t, false));
            }
        }
    }
}

impl Snapshot {
    /// Sets [`Snapshot::pressure_mmhg`] for `n` surface vertices: the
    /// ischemia stage's (relaxed) pressures where the scene has it, else
    /// |reaction| / vertex area at each blade's vertex, scaled by its blade's
    /// relaxation where the scene relaxes (the pressures of a patch relax with
    /// its blade's force).
    fn capture_pressure(&mut self, pipeline: &Pipeline, n: usize, areas: &[f64]) {
        self.pressure_mmhg.clear();
        if let Some(relaxed) = pipeline.ischemia().map(|i| i.pressure_mmhg()).filter(|p| p.len() == n) {
            self.pressure_mmhg.extend_from_slice(relaxed);
            return;
        }
        let solution = pipeline.last_solution();
        crate::sim::contact::vertex_pressures_mmhg(pipeline.surface(), pipeline.last_constraints(), &solution.reactions, areas, pipeline.relaxation_ratios(), &mut self.pressure_mmhg);
        self.pressure_mmhg.resize(n, 0.0);
    }

    /// Shows the surface beyond the working region (the vertices without
    /// compliance rows, which the frames leave as they were) at `nodes`,
    /// every node's displacement from the background solve of a recent
    /// frame; nothing when `nodes` is not one per mesh node.
    pub fn set_far_surface(&mut self, pipeline: &Pipeline, nodes: &[crate::math::Vec3]) {
        if nodes.len() != pipeline.mesh().node_count() {
            return;
        }
        let (vertices, rest) = (&pipeline.surface().vertices, pipeline.rest_positions());
        for &k in pipeline.solver().far_vertices() {
            let k = k as usize;
            let u = nodes[vertices[k] as usize];
            if let (Some(p), Some(d)) = (self.surface_positions.get_mut(k), self.displacement_mm.get_mut(k)) {
                *p = rest[k] + u;
                *d = u.norm() * 1e3;
            }
        }
    }

    /// Sets [`Snapshot::strain`] from per-tet stress (empty when `stress` is
    /// not one entry per tet of `surface`'s mesh).
    pub fn set_strain(&mut self, surface: &crate::mesh::BoundarySurface, stress: &[crate::fem::ElementStress]) {
        surface_strain(surface, stress, &mut self.strain, &mut self.strain_count);
    }
}

/// Per surface vertex, the mean largest principal strain of the tets that own
/// its boundary triangles, into `out`; empty when `stress` has no entry per tet
/// (the scene computes no stress). `count` is scratch.
pub fn surface_strain(
    surface: &crate::mesh::BoundarySurface,
    stress: &[crate::fem::ElementStress],
    out: &mut Vec<f64>,
    count: &mut Vec<u32>,
) {
    out.clear();
    if stress.is_empty() || surface.triangle_tet.iter().any(|&t| t as usize >= stress.len()) {
        return;
    }
    let n = surface.vertices.len();
    out.resize(n, 0.0);
    count.clear();
    count.resize(n, 0);
    for (tri, &tet) in surface.triangles.iter().zip(&surface.triangle_tet) {
        let e = stress[tet as usize].max_principal_strain;
        for &v in tri {
            if let (Some(slot), Some(c)) = (out.get_mut(v as usize), count.get_mut(v as usize)) {
                *slot += e;
                *c += 1;
            }
        }
    }
    for (slot, c) in out.iter_mut().zip(count.iter()) {
        if *c > 0 {
            *slot /= f64::from(*c);
        }
    }
}

/// The camera presets.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ViewPreset {
    /// The whole brain from the front-left, above.
    #[default]
    Overview,
    /// The surgeon's microscope: down the spatulas' insertion direction at the tips.
    Microscope,
}

/// A camera for `preset` on the pipeline's mesh and the given spatula poses
/// (the scenario's own view of that name when `views` has one).
pub fn camera_for(preset: ViewPreset, pipeline: &Pipeline, poses: &[Pose], views: &crate::scenario::Views) -> OrbitCamera {
    camera_from_parts(preset, pipeline.mesh().bounding_box(), pipeline.spatula_shapes(), poses, views)
}

/// Tilt of the default microscope's line of sight off the blades' axis,
/// towards their width (depth cue; the handles stay edge-on), rad.
const MICROSCOPE_TILT_RAD: f64 = 15.0 * std::f64::consts::PI / 180.0;

/// [`camera_for`] from the mesh box (m) and the blades (what the window keeps).
pub fn camera_from_parts(
    preset: ViewPreset,
    (lo, hi): (Vec3, Vec3),
    shapes: &[crate::geometry::SpatulaShape],
    poses: &[Pose],
    views: &crate::scenario::Views,
) -> OrbitCamera {
    let named = match preset {
        ViewPreset::Overview => views.overview,
        ViewPreset::Microscope => views.microscope,
    };
    if let Some(v) = named {
        return OrbitCamera::looking(v.eye, v.target, v.fov_y_rad);
    }
    let n = poses.len().min(shapes.len());
    if n == 0 {
        return OrbitCamera::framing(lo, hi);
    }
    let mut tip_sum = Vec3::zeros();
    let mut blade = Vec3::zeros();
    let mut normal = Vec3::zeros();
    let mut width = Vec3::zeros();
    let (mut box_lo, mut box_hi) = (lo, hi);
    for (pose, shape) in poses.iter().zip(shapes) {
        let along = pose.rotation * Vec3::x();
        tip_sum += pose.position + along * shape.length * 0.85;
        blade += along;
        normal += pose.rotation * Vec3::z();
        width += pose.rotation * Vec3::y();
        for end in [pose.position, pose.position + along * shape.length] {
            box_lo = box_lo.inf(&end);
            box_hi = box_hi.sup(&end);
        }
    }
    let blade = if blade.norm() > 1e-9 { blade.normalize() } else { Vec3::x() };
    let up = if normal.norm() > 1e-9 { normal.normalize() } else { Vec3::z() };
    match preset {
        ViewPreset::Overview => {
            // The brain and the blades, from the side the blades come in, a
            // little anterior and above.
            let mut cam = OrbitCamera::framing(box_lo, box_hi);
            cam.yaw_rad = (-blade.y).atan2(-blade.x) - 35f64.to_radians();
            cam.pitch_rad = 30f64.to_radians();
            cam.distance_m *= 0.85;
            cam
        }
        ViewPreset::Microscope => {
            // The surgeon's line of sight: from behind the handles, down the
            // blades' insertion direction into the fissure at the tips, in the
            // plane of the blades' faces (so two blades that open the fissure
            // along their normal stand apart on screen, the gap between them
            // in view, neither hiding the other), tilted a little across the
            // blades' width.
            let target = tip_sum / n as f64;
            let across = width - blade * blade.dot(&width);
            let across = if across.norm() > 1e-9 { across.normalize() } else { up.cross(&blade) };
            let direction = blade * MICROSCOPE_TILT_RAD.cos() + across * MICROSCOPE_TILT_RAD.sin();
            // Far enough that the handles' ends, nearest the eye, do not fill the view.
            let longest = shapes.iter().map(|s| s.length).fold(0.0, f64::max);
            let distance = ((hi - lo).norm() * 0.55).max(2.0 * longest);
            OrbitCamera::microscope(target, direction, distance)
        }
    }
}

/// Owned buffers a [`SceneView`] borrows (spatula views, skull spheres,
/// tether tubes), reused each frame.
#[derive(Debug, Default)]
pub struct SceneBuffers {
    spatulas: Vec<SpatulaView>,
    skull: Vec<SkullSphere>,
    tethers: Vec<crate::render::TetherSegment>,
}

/// Colours of the two blades: cool steel (first) and warm brass (second), so they can be told apart.
const BLADE_COLOURS: [[f32; 3]; 2] = [[0.52, 0.60, 0.74], [0.74, 0.64, 0.46]];

impl SceneBuffers {
    /// The view of `snapshot` with `options` through `camera`.
    pub fn view<'a>(
        &'a mut self,
        pipeline_view: &'a SceneStatic,
        snapshot: &'a Snapshot,
        options: &DrawOptions,
        camera: OrbitCamera,
    ) -> SceneView<'a> {
        self.spatulas.clear();
        for (k, (shape, pose)) in pipeline_view.shapes.iter().zip(&snapshot.poses).enumerate() {
            let mut v = SpatulaView::new(*shape, *pose);
            v.color = BLADE_COLOURS[k % 2];
            self.spatulas.push(v);
        }
        self.skull.clear();
        if options.skull {
            self.skull.extend(pipeline_view.skull.iter().copied());
        }
        let mut view = SceneView::new(&snapshot.surface_positions, &pipeline_view.triangles, camera);
        view.surface.occlusion = &pipeline_view.occlusion;
        view.surface.field = field_scale(options.field, options.pressure_max_mmhg).and_then(|(kind, map, range)| {
            let values: &[f64] = match options.field {
                SurfaceField::Displacement => &snapshot.displacement_mm,
                SurfaceField::Pressure => &snapshot.pressure_mmhg,
                SurfaceField::Strain if snapshot.strain.len() == snapshot.surface_positions.len() => &snapshot.strain,
                SurfaceField::Risk if snapshot.risk.len() == snapshot.surface_positions.len() => &snapshot.risk,
                _ => return None,
            };
            Some(ScalarField { values, kind, map, range })
        });
        match &pipeline_view.tethers {
            Some(info) => super::tethers::segments(info, &snapshot.tethers, &mut self.tethers),
            None => self.tethers.clear(),
        }
        view.spatulas = &self.spatulas;
        view.skull = &self.skull;
        view.tethers = &self.tethers;
        view.overlays = Overlays {
            source_nodes: if options.source_nodes { &snapshot.source_nodes } else { &[] },
            node_size_m: 0.0,
            pairs: if options.pairs { &snapshot.pairs } else { &[] },
        };
        view
    }
}

/// What does not change between frames of one pipeline: triangles, blade
/// shapes, skull spheres, the vessels' and bands' names and limits (copied once so the window's render thread needs no
/// access to the pipeline, which lives on the simulation thread).
#[derive(Debug, Clone, Default)]
pub struct SceneStatic {
    pub triangles: Vec<[u32; 3]>,
    pub shapes: Vec<crate::geometry::SpatulaShape>,
    pub skull: Vec<SkullSphere>,
    /// Mesh bounding box, m.
    pub bounds: (Vec3, Vec3),
    /// The scenario's display settings (colour-bar top, named cameras), for a
    /// window that loads another scene; `None` where only the pipeline was known.
    pub display: Option<crate::scenario::Display>,
    /// The scene's vessels and bands (`None`: it has none).
    pub tethers: Option<crate::scenario::Tethers>,
    /// The vessel-stretch legend (`None`: the scene has no vessels).
    pub vessel_legend: Option<crate::render::tethers::VesselLegend>,
    /// The scene relaxes (the `Relaxation` effect): the forces and pressures
    /// shown are the held tissue's.
    pub relaxing: bool,
    /// The time its relaxation function takes to halve, s (`None`: it never
    /// halves, the scene does not relax, or only the pipeline was known).
    pub relaxation_half_time_s: Option<f64>,
    /// The ischemia model (`None`: the scene has no `Ischemia` effect).
    pub ischemia: Option<crate::scenario::Ischemia>,
    /// Per surface vertex, the ambient factor at rest (the sulci darker; [`crate::render::occlusion`]).
    pub occlusion: Vec<f32>,
}

impl SceneStatic {
    /// Copies the static parts of `pipeline`; skull spheres translucent blue
    /// (containing) and red (excluding), as in the paper's Fig. 5d.
    pub fn of(pipeline: &Pipeline) -> Self {
        let mut skull = Vec::new();
        if let Some(s) = pipeline.skull() {
            let s = s.skull();
            if let Some(c) = &s.containing {
                skull.push(SkullSphere { center: c.center, radius: c.radius, color: [0.2, 0.35, 0.9, 0.08] });
            }
            if let Some(e) = &s.excluding {
                skull.push(SkullSphere { center: e.center, radius: e.radius, color: [0.9, 0.2, 0.15, 0.25] });
            }
        }
        let tethers = pipeline.tethers().map(|t| t.tethers().clone()).filter(|t| !t.is_empty());
        Self {
            triangles: pipeline.surface().triangles.clone(),
            shapes: pipeline.spatula_shapes().to_vec(),
            skull,
            bounds: pipeline.mesh().bounding_box(),
            display: None,
            vessel_legend: tethers.as_ref().and_then(super::tethers::vessel_legend),
            tethers,
            relaxing: pipeline.relaxation_ratios().is_some(),
            relaxation_half_time_s: None,
            ischemia: pipeline.ischemia().map(|i| i.model().clone()),
            occlusion: crate::render::occlusion::surface_occlusion(pipeline.rest_positions(), &pipeline.surface().triangles),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Screen position (NDC x, y) and depth of `p` through `cam`, 16:10.
    fn project(cam: &OrbitCamera, p: Vec3) -> (f64, f64, f64) {
        let q = cam.view_projection(1.6) * nalgebra::Vector4::new(p.x - cam.target.x, p.y - cam.target.y, p.z - cam.target.z, 1.0);
        (q.x / q.w, q.y / q.w, q.z / q.w)
    }

    /// The default microscope looks down the blades into the fissure with both
    /// tips on screen and apart, whatever the blades' orientation (the
    /// default scene's horizontal blades, the valley scenes' vertical ones);
    /// a scenario's named view wins.
    #[test]
    fn the_microscope_sees_both_tips_apart_and_a_named_view_wins() {
        use crate::geometry::{SpatulaShape, Pose};
        use nalgebra::UnitQuaternion;
        let shape = SpatulaShape { length: 0.06, width: 0.008, thickness: 0.001 };
        let bounds = (Vec3::new(-0.1, -0.1, -0.1), Vec3::new(0.1, 0.1, 0.1));
        // Blade along +x, faces +z (the default scene, roughly), and along -z, faces +x (a valley).
        for rotation in [UnitQuaternion::identity(), UnitQuaternion::rotation_between(&Vec3::x(), &-Vec3::z()).expect("turn")] {
            let along = rotation * Vec3::x();
            let normal = rotation * Vec3::z();
            let tip_target = Vec3::new(0.0, 0.01, 0.02);
            // Two blades 8 mm apart along their normal, tips at the target.
            let poses: Vec<Pose> = [-0.004, 0.004]
                .iter()
                .map(|o| Pose { position: tip_target + normal * *o - along * shape.length, rotation })
                .collect();
            let cam = camera_from_parts(ViewPreset::Microscope, bounds, &[shape, shape], &poses, &crate::scenario::Views::default());
            let forward = -cam.back_direction();
            assert!(forward.dot(&normal).abs() < 1e-6, "the line of sight lies in the blades' face plane: {forward:?}");
            assert!(forward.dot(&along) > 0.9, "down the insertion direction: {forward:?}");
            let tips: Vec<(f64, f64, f64)> = poses.iter().map(|p| project(&cam, p.position + p.rotation * Vec3::x() * shape.length)).collect();
            for (x, y, z) in &tips {
                assert!(x.abs() < 1.0 && y.abs() < 1.0 && (0.0..1.0).contains(z), "tip on screen: {tips:?}");
            }
            let apart = ((tips[0].0 - tips[1].0).powi(2) + (tips[0].1 - tips[1].1).powi(2)).sqrt();
            assert!(apart > 0.02, "the two tips stand apart on screen: {tips:?}");
        }
        let views = crate::scenario::Views {
            overview: None,
            microscope: Some(crate::scenario::NamedView { eye: Vec3::new(0.1, -0.05, 0.2), target: Vec3::zeros(), fov_y_rad: 0.5 }),
        };
        let cam = camera_from_parts(ViewPreset::Microscope, bounds, &[], &[], &views);
        assert!((cam.eye() - Vec3::new(0.1, -0.05, 0.2)).norm() < 1e-9 && cam.target == Vec3::zeros() && cam.fov_y_rad == 0.5, "{cam:?}");
    }

    /// F goes none, displacement, pressure, strain, then infarct risk only
    /// where the scene has it, and back to none; a risk field left over from
    /// another scene goes to none.
    #[test]
    fn the_f_cycle_includes_risk_only_with_ischemia() {
        let cycle = |has_risk: bool| {
            let mut seen = vec![SurfaceField::None];
            let mut f = SurfaceField::None.next(has_risk);
            while f != SurfaceField::None && seen.len() < 10 {
                seen.push(f);
                f = f.next(has_risk);
            }
            seen
        };
        use SurfaceField::*;
        assert_eq!(cycle(true), vec![None, Displacement, Pressure, Strain, Risk]);
        assert_eq!(cycle(false), vec![None, Displacement, Pressure, Strain]);
        assert_eq!(Risk.next(false), None);
        let (kind, map, range) = field_scale(Risk, 30.0).expect("risk has a scale");
        assert_eq!((kind, map, range), (FieldKind::InfarctRisk, crate::render::ColorMap::WhitePurple, (0.0, 1.0)));
    }

    /// The risk field is drawn and gets its colour bar only when the snapshot
    /// has one value per surface vertex (a scene without `Ischemia` has none).
    #[test]
    fn the_risk_field_needs_one_value_per_vertex() {
        let options = DrawOptions { field: SurfaceField::Risk, ..DrawOptions::default() };
        let mut snapshot = Snapshot { surface_positions: vec![Vec3::zeros(); 3], ..Snapshot::default() };
        assert!(legend_for(&options, &snapshot).is_none(), "no risk, no colour bar");
        let scene = SceneStatic { triangles: vec![[0, 1, 2]], ..SceneStatic::default() };
        let mut buffers = SceneBuffers::default();
        assert!(buffers.view(&scene, &snapshot, &options, OrbitCamera::default()).surface.field.is_none());
        snapshot.risk = vec![0.0, 0.5, 0.9];
        let legend = legend_for(&options, &snapshot).expect("a colour bar");
        assert_eq!(legend.markers.len(), 3);
        let view = buffers.view(&scene, &snapshot, &options, OrbitCamera::default());
        let field = view.surface.field.expect("the risk field is drawn");
        assert_eq!((field.values, field.kind), (&[0.0, 0.5, 0.9][..], FieldKind::InfarctRisk));
    }

    /// The snapshot of a scene with tissue over time (the V valley, its blade
    /// wedged and held): its pressure is the relaxed one, each blade's elastic
    /// pressure times its relaxation without the ischemia stage and the
    /// stage's own with it (the two agree), and its risk is the stage's, one
    /// value per surface vertex; without `Ischemia` it has no risk.
    #[test]
    fn the_snapshot_captures_the_relaxed_pressure_and_the_risk() {
        use crate::sim::poses::TrajectoryPoses;
        use crate::sim::{BuildOptions, FrameInput};
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR"));
        let run = |effects: &str| {
            // A dose the wedged blade gives in a fraction of a second has even odds.
            let sets = [
                format!("effects=[Collision, Culling, ForceOutput, ContactPressure, {effects}]"),
                "ischemia.dose_50_mmhg_min=0.02".to_string(),
                "ischemia.dose_spread_mmhg_min=0.005".to_string(),
            ];
            let scenario = crate::scenario::Scenario::load(&root.join("config/v_valley.ron"), &sets).expect("the V valley loads");
            let source = TrajectoryPoses::for_scenario(&scenario, None).expect("its trajectory");
            let options = BuildOptions { expected_poses: source.samples(scenario.duration, 200), progress: None, ..BuildOptions::default() };
            let (mut pipeline, mut state) = Pipeline::build(&scenario, options).expect("it builds");
            let (mut input, mut report) = (FrameInput::default(), FrameReport::default());
            // Down the valley for 2 s (wedged from about 1.8 s), then held.
            for k in 1..=250 {
                source.poses_at(k as f64 * scenario.time_step, &mut input);
                report = pipeline.step(&mut state, &input).expect("a frame").clone();
            }
            let areas = vertex_areas(pipeline.rest_positions(), &pipeline.surface().triangles);
            let mut snapshot = Snapshot::default();
            snapshot.capture(&pipeline, &state, &report, &areas);
            (pipeline, snapshot, areas)
        };
        let (relaxing, relaxed, areas) = run("Relaxation");
        let n = relaxed.surface_positions.len();
        assert!(relaxed.risk.is_empty() && relaxed.first_at_risk_s.is_empty(), "no Ischemia, no risk");
        let ratio = relaxing.relaxation_ratios().and_then(|r| r.first().copied()).expect("one blade relaxing");
        assert!(ratio > 0.9 && ratio < 1.0, "a ramp of a second relaxes a little: {ratio}");
        let mut elastic = vec![0.0; n];
        for (c, f) in relaxing.last_constraints().iter().zip(&relaxing.last_solution().reactions) {
            let v = relaxing.surface().node_to_vertex[c.node as usize];
            if c.kind.is_tool() && v != crate::mesh::surface::NOT_ON_SURFACE && areas[v as usize] > 0.0 {
                elastic[v as usize] += f.norm() / areas[v as usize] / PASCALS_PER_MMHG;
            }
        }
        let peak = elastic.iter().copied().fold(0.0, f64::max);
        assert!(peak > 1.0, "the blade presses the walls: {peak} mmHg");
        assert_eq!(relaxed.pressure_mmhg.len(), n);
        for (v, (got, e)) in relaxed.pressure_mmhg.iter().zip(&elastic).enumerate() {
            assert!((got - e * ratio).abs() <= 1e-12 * peak, "vertex {v}: {got} against {e} x {ratio}");
        }
        let (dosing, dosed, _) = run("Relaxation, Ischemia");
        let stage = dosing.ischemia().expect("the ischemia stage");
        assert_eq!(dosed.pressure_mmhg, stage.pressure_mmhg(), "the stage's relaxed pressures");
        for (v, (a, b)) in dosed.pressure_mmhg.iter().zip(&relaxed.pressure_mmhg).enumerate() {
            assert!((a - b).abs() <= 1e-9 * peak, "vertex {v}: the stage's {a} against the relaxed elastic {b}");
        }
        assert_eq!(dosed.risk.len(), n);
        assert!(dosed.risk.iter().enumerate().all(|(v, &r)| r == stage.risk(v)));
        assert!(dosed.risk.iter().any(|&r| r > 0.5), "the wedged walls are at risk");
        assert!(dosed.first_at_risk_s.first().copied().flatten().is_some(), "{:?}", dosed.first_at_risk_s);
    }

    #[test]
    fn vertex_areas_split_each_triangle_in_thirds() {
        let rest = [Vec3::zeros(), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)];
        let areas = vertex_areas(&rest, &[[0, 1, 2], [1, 3, 2]]);
        let total: f64 = areas.iter().sum();
        assert!((total - 1.0).abs() < 1e-12, "areas must sum to the surface area 1, got {total}");
        assert!((areas[0] - 1.0 / 6.0).abs() < 1e-12, "corner 0 touches one triangle: {}", areas[0]);
        assert!((areas[1] - 1.0 / 3.0).abs() < 1e-12, "vertex 1 touches two triangles: {}", areas[1]);
        let bad = vertex_areas(&rest[..2], &[[0, 1, 7]]);
        assert_eq!(bad.len(), 2, "an out-of-range index must not panic or grow the list");
    }

    /// Each vertex gets the mean strain of the tets owning its boundary
    /// triangles; no stress (or too little) gives no field, never a panic.
    #[test]
    fn surface_strain_averages_the_boundary_tets_of_each_vertex() {
        let mesh = crate::mesh::fixtures::box_mesh(&[0.0, 1.0, 2.0], &[0.0, 1.0], &[0.0, 1.0]).unwrap();
        let surface = crate::mesh::BoundarySurface::of(&mesh);
        let stress: Vec<crate::fem::ElementStress> =
            (0..mesh.tets.len()).map(|t| crate::fem::ElementStress { von_mises: 0.0, max_principal_strain: 0.01 * (t as f64 + 1.0) }).collect();
        let (mut out, mut count) = (Vec::new(), Vec::new());
        surface_strain(&surface, &stress, &mut out, &mut count);
        assert_eq!(out.len(), surface.vertices.len());
        for (v, &got) in out.iter().enumerate() {
            let owners: Vec<f64> = surface
                .triangles
                .iter()
                .zip(&surface.triangle_tet)
                .filter(|(tri, _)| tri.contains(&(v as u32)))
                .map(|(_, &t)| stress[t as usize].max_principal_strain)
                .collect();
            let mean = owners.iter().sum::<f64>() / owners.len() as f64;
            assert!((got - mean).abs() < 1e-15, "vertex {v}: {got} vs {mean}");
        }
        surface_strain(&surface, &[], &mut out, &mut count);
        assert!(out.is_empty(), "no stress, no field");
        surface_strain(&surface, &stress[..1], &mut out, &mut count);
        assert!(out.is_empty(), "stress of another mesh, no field");
    }
}
