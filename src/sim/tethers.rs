//! The tether stage: the scene's vessels and arachnoid bands tied to the brain's surface, pulling in the exact
//! solve, tearing past their limits and cut by the trainee (built only with the `Tethers` effect).
//!
//! In: the scenario's [`Tethers`] (SI), the boundary surface at rest. At build each surface point is snapped to
//! the nearest boundary triangle and carried by its barycentric coordinates; each vessel segment and each band
//! becomes one [`fem::Tether`] (a tension-only row of the solve, `fem::constrained::tethers`). Each sub-step,
//! after the solve: each link's length at the deformed surface and its tension; a vessel segment stretched to its
//! rupture stretch or a band pulled to its strength tears, and leaves the solve from the next sub-step. A cut
//! (microscissors at a blade's tip) takes the bands within [`CUT_RADIUS_M`] of the tip out at once.
//! Out: [`TetherFrame`] a frame (each vessel's largest stretch, bands intact / torn / cut) and the list of
//! [`TetherEvent`]s, in the order they happened.
//!
//! Stays true: a frame's decisions depend only on the frame's solution, in the links' order (vessels in file
//! order, segment by segment, then bands), so replays tear the same links at the same frames, bit for bit.

use crate::fem::{self, ConstrainedSolver, TetherEnd};
use crate::math::Vec3;
use crate::mesh::BoundarySurface;
use crate::scenario::{TetherPoint, Tethers, VesselKind};

/// A cut takes every band that passes within this distance of the active blade's tip (m): microscissors' reach.
pub const CUT_RADIUS_M: f64 = 0.002;
/// A tether's surface point may lie at most this far from the surface at rest (m); farther is refused.
pub const MAX_SNAP_DISTANCE_M: f64 = 0.002;

/// A point of the surface: the nearest boundary triangle's vertices (surface indices), barycentric weights, and
/// how far the given point was from it (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Snapped {
    pub vertices: [u32; 3],
    pub weights: [f64; 3],
    pub distance: f64,
}

impl Snapped {
    /// Its position on `positions` (per surface vertex).
    pub fn at(&self, positions: &[Vec3]) -> Vec3 {
        self.vertices.iter().zip(&self.weights).map(|(&v, &w)| positions[v as usize] * w).sum()
    }
}

/// Snaps `p` to the nearest triangle of `triangles` (surface vertex indices) at `positions`; the lower triangle
/// index on a tie. `None` for a surface without triangles.
pub fn snap(triangles: &[[u32; 3]], positions: &[Vec3], p: &Vec3) -> Option<Snapped> {
    let mut best: Option<(f64, usize)> = None;
    for (k, t) in triangles.iter().enumerate() {
        let q = crate::geometry::closest_point(p, &positions[t[0] as usize], &positions[t[1] as usize], &positions[t[2] as usize]);
        let d = (q - p).norm_squared();
        if best.is_none_or(|(b, _)| d < b) {
            best = Some((d, k));
        }
    }
    let (d, k) = best?;
    let t = triangles[k];
    let w = crate::geometry::closest_barycentric(p, &positions[t[0] as usize], &positions[t[1] as usize], &positions[t[2] as usize]);
    let sum: f64 = w.iter().sum();
    Some(Snapped { vertices: t, weights: w.map(|x| x / sum), distance: d.sqrt() })
}

/// What a link belongs to.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LinkOwner {
    /// Vessel index and segment index (points `segment` to `segment + 1`).
    Vessel { vessel: usize, segment: usize },
    Band(usize),
}

/// One end of a link in the stage: carried by the surface or fixed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LinkEnd {
    Surface(Snapped),
    Anchor(Vec3),
}

impl LinkEnd {
    /// Its position on the surface `positions` (per surface vertex), m.
    pub fn at(&self, positions: &[Vec3]) -> Vec3 {
        match self {
            LinkEnd::Surface(s) => s.at(positions),
            LinkEnd::Anchor(p) => *p,
        }
    }
}

/// A link's state.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LinkState {
    Intact,
    Torn,
    Cut,
}

/// One link of the stage.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    pub owner: LinkOwner,
    pub ends: [LinkEnd; 2],
    pub rest_length: f64,
    pub state: LinkState,
    /// Length at the last sub-step's deformed surface over the rest length.
    pub stretch: f64,
    /// Tension of the last sub-step, N.
    pub tension: f64,
}

/// Which kind of tether a link belongs to (`vessel` or `band` in `summary.json`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum TetherKind {
    Vessel,
    Band,
}

/// What happened to a tether.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TetherEvent {
    pub time_s: f64,
    pub frame: u64,
    /// `torn` or `cut`.
    pub kind: LinkState,
    /// The vessel's or band's name.
    pub tether: String,
    pub what: TetherKind,
    /// Its stretch and tension when it happened.
    pub stretch: f64,
    pub tension_n: f64,
}

/// Per frame: each vessel's largest segment stretch, and the bands' count by state.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct TetherFrame {
    /// Per vessel (scene order): its largest segment stretch this frame (torn segments count at their last).
    pub vessel_stretch: Vec<f64>,
    /// Per vessel: torn.
    pub vessel_torn: Vec<bool>,
    pub bands_intact: u32,
    pub bands_torn: u32,
    pub bands_cut: u32,
    /// Largest tension of any band this frame, N.
    pub max_band_tension_n: f64,
    /// Events of this frame (all of them in [`TetherStage::events`]).
    pub events: Vec<TetherEvent>,
}

impl TetherFrame {
    /// Becomes a copy of `other`, reusing its buffers (the frame report's copy allocates nothing on a frame without
    /// events; a derived `clone_from` would replace every vector).
    pub fn copy_from(&mut self, other: &Self) {
        self.vessel_stretch.clone_from(&other.vessel_stretch);
        self.vessel_torn.clone_from(&other.vessel_torn);
        self.bands_intact = other.bands_intact;
        self.bands_torn = other.bands_torn;
        self.bands_cut = other.bands_cut;
        self.max_band_tension_n = other.max_band_tension_n;
        self.events.clone_from(&other.events);
    }
}

/// The stage: the links, their limits and what happened to them.
#[derive(Debug, Clone)]
pub struct TetherStage {
    tethers: Tethers,
    links: Vec<Link>,
    events: Vec<TetherEvent>,
    frame: TetherFrame,
    /// Cuts asked for since the last sub-step (a blade index each).
    pending_cuts: Vec<usize>,
}

impl TetherStage {
    /// Snaps the tethers to `surface` at rest (`rest`: per surface vertex) and makes the solver's links. A point's
    /// distance is not checked here (the preflight refuses one over [`MAX_SNAP_DISTANCE_M`]).
    pub fn new(tethers: &Tethers, surface: &BoundarySurface, rest: &[Vec3]) -> Self {
        let end = |p: &TetherPoint| match *p {
            TetherPoint::Surface(x) => snap(&surface.triangles, rest, &x).map_or(LinkEnd::Anchor(x), LinkEnd::Surface),
            TetherPoint::Anchor(x) => LinkEnd::Anchor(x),
        };
        let mut links = Vec::new();
        for (v, vessel) in tethers.vessels.iter().enumerate() {
            let ends: Vec<LinkEnd> = vessel.points.iter().map(end).collect();
            for (segment, pair) in ends.windows(2).enumerate() {
                let rest_length = (pair[1].at(rest) - pair[0].at(rest)).norm().max(1e-6);
                links.push(Link { owner: LinkOwner::Vessel { vessel: v, segment }, ends: [pair[0], pair[1]], rest_length, state: LinkState::Intact, stretch: 1.0, tension: 0.0 });
            }
        }
        for (b, band) in tethers.bands.iter().enumerate() {
            let ends = [end(&TetherPoint::Surface(band.from)), end(&TetherPoint::Surface(band.to))];
            let rest_length = (ends[1].at(rest) - ends[0].at(rest)).norm().max(1e-6) + band.slack;
            links.push(Link { owner: LinkOwner::Band(b), ends, rest_length, state: LinkState::Intact, stretch: 1.0, tension: 0.0 });
        }
        let frame = TetherFrame { vessel_stretch: vec![1.0; tethers.vessels.len()], vessel_torn: vec![false; tethers.vessels.len()], ..Default::default() };
        Self { tethers: tethers.clone(), links, events: Vec::new(), frame, pending_cuts: Vec::new() }
    }

    /// The links as the solver takes them (mesh node ids), in the stage's order.
    pub fn solver_links(&self, surface: &BoundarySurface) -> Vec<fem::Tether> {
        self.links
            .iter()
            .map(|l| {
                let end = |e: &LinkEnd| match e {
                    LinkEnd::Surface(s) => TetherEnd::Tissue { nodes: s.vertices.map(|v| surface.vertices[v as usize]), weights: s.weights },
                    LinkEnd::Anchor(p) => TetherEnd::Anchor { point: *p },
                };
                fem::Tether { ends: [end(&l.ends[0]), end(&l.ends[1])], rest_length: l.rest_length, stiffness: self.stiffness(l) }
            })
            .collect()
    }

    /// A link's spring constant, N/m: a vessel segment's `E A / L`, a band's own.
    fn stiffness(&self, l: &Link) -> f64 {
        match l.owner {
            LinkOwner::Vessel { vessel, .. } => self.tethers.vessels[vessel].axial_stiffness / l.rest_length,
            LinkOwner::Band(b) => self.tethers.bands[b].stiffness,
        }
    }

    /// The scene's tethers.
    pub fn tethers(&self) -> &Tethers {
        &self.tethers
    }

    /// The links, in the stage's order.
    pub fn links(&self) -> &[Link] {
        &self.links
    }

    /// Every event so far.
    pub fn events(&self) -> &[TetherEvent] {
        &self.events
    }

    /// The last frame's figures.
    pub fn frame(&self) -> &TetherFrame {
        &self.frame
    }

    /// Asks for a cut at blade `spatula`'s tip, carried out at the next sub-step.
    pub fn request_cut(&mut self, spatula: usize) {
        self.pending_cuts.push(spatula);
    }

    /// Whether a cut waits for the next sub-step.
    pub fn has_pending_cuts(&self) -> bool {
        !self.pending_cuts.is_empty()
    }

    /// Starts a frame's figures (the stretch maxima restart; states and events carry on).
    pub fn begin_frame(&mut self) {
        self.frame.vessel_stretch.iter_mut().for_each(|s| *s = 0.0);
        self.frame.max_band_tension_n = 0.0;
        self.frame.events.clear();
    }

    /// Carries out the cuts asked for: every intact band whose segment (at `positions`) passes within
    /// [`CUT_RADIUS_M`] of a named blade's tip (`tips`, per spatula) is cut. Returns the links cut.
    pub fn apply_cuts(&mut self, tips: &[Vec3], positions: &[Vec3], time_s: f64, frame: u64, solver: &mut ConstrainedSolver) -> usize {
        let mut cut = 0;
        let cuts = std::mem::take(&mut self.pending_cuts);
        for &spatula in &cuts {
            let Some(tip) = tips.get(spatula) else { continue };
            for k in 0..self.links.len() {
                let l = &self.links[k];
                let LinkOwner::Band(b) = l.owner else { continue };
                if l.state != LinkState::Intact {
                    continue;
                }
                let (a, c) = (l.ends[0].at(positions), l.ends[1].at(positions));
                if crate::geometry::distance_to_segment(tip, &a, &c) <= CUT_RADIUS_M {
                    let (stretch, tension) = (l.stretch, l.tension);
                    self.links[k].state = LinkState::Cut;
                    solver.set_tether_enabled(k, false);
                    let name = self.tethers.bands[b].name.clone();
                    let event = TetherEvent { time_s, frame, kind: LinkState::Cut, tether: name, what: TetherKind::Band, stretch, tension_n: tension };
                    self.frame.events.push(event.clone());
                    self.events.push(event);
                    cut += 1;
                }
            }
        }
        self.pending_cuts = cuts;
        self.pending_cuts.clear();
        self.count_bands();
        cut
    }

    /// After a sub-step's solve: each link's stretch at `positions` (per surface vertex) and its tension
    /// (`tensions`, the solution's, in link order); tears what passed its limit (a vessel segment at its rupture
    /// stretch, a band at its strength), taking it out of `solver` from the next sub-step.
    pub fn after_solve(&mut self, positions: &[Vec3], tensions: &[f64], time_s: f64, frame: u64, solver: &mut ConstrainedSolver) {
        for k in 0..self.links.len() {
            let l = &mut self.links[k];
            if l.state != LinkState::Intact {
                continue;
            }
            l.stretch = (l.ends[1].at(positions) - l.ends[0].at(positions)).norm() / l.rest_length;
            l.tension = tensions.get(k).copied().unwrap_or(0.0);
            let (torn, name, what) = match l.owner {
                LinkOwner::Vessel { vessel, .. } => {
                    let v = &self.tethers.vessels[vessel];
                    (l.stretch >= v.rupture_stretch, &v.name, TetherKind::Vessel)
                }
                LinkOwner::Band(b) => {
                    let band = &self.tethers.bands[b];
                    (l.tension >= band.strength, &band.name, TetherKind::Band)
                }
            };
            if torn {
                l.state = LinkState::Torn;
                solver.set_tether_enabled(k, false);
                let event = TetherEvent { time_s, frame, kind: LinkState::Torn, tether: name.clone(), what, stretch: l.stretch, tension_n: l.tension };
                self.frame.events.push(event.clone());
                self.events.push(event);
            }
        }
        for l in &self.links {
            match l.owner {
                LinkOwner::Vessel { vessel, .. } => {
                    let s = &mut self.frame.vessel_stretch[vessel];
                    *s = s.max(l.stretch);
                    if l.state == LinkState::Torn {
                        self.frame.vessel_torn[vessel] = true;
                    }
                }
                LinkOwner::Band(_) => {
                    if l.state == LinkState::Intact {
                        self.frame.max_band_tension_n = self.frame.max_band_tension_n.max(l.tension);
                    }
                }
            }
        }
        self.count_bands();
    }

    fn count_bands(&mut self) {
        let (mut intact, mut torn, mut cut) = (0, 0, 0);
        for l in self.links.iter().filter(|l| matches!(l.owner, LinkOwner::Band(_))) {
            match l.state {
                LinkState::Intact => intact += 1,
                LinkState::Torn => torn += 1,
                LinkState::Cut => cut += 1,
            }
        }
        (self.frame.bands_intact, self.frame.bands_torn, self.frame.bands_cut) = (intact, torn, cut);
    }

    /// Vessels torn so far.
    pub fn torn_vessels(&self) -> usize {
        self.frame.vessel_torn.iter().filter(|t| **t).count()
    }

    /// Each vessel's kind and name, in scene order.
    pub fn vessel_names(&self) -> impl Iterator<Item = (&str, VesselKind)> {
        self.tethers.vessels.iter().map(|v| (v.name.as_str(), v.kind))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_copy_is_equal_and_keeps_its_buffers() {
        let event = TetherEvent { time_s: 0.5, frame: 49, kind: LinkState::Torn, tether: "band".into(), what: TetherKind::Band, stretch: 1.2, tension_n: 0.05 };
        let a = TetherFrame { vessel_stretch: vec![1.1, 1.02], vessel_torn: vec![false, true], bands_intact: 3, bands_torn: 1, bands_cut: 2, max_band_tension_n: 0.04, events: vec![event] };
        let mut b = TetherFrame { vessel_stretch: Vec::with_capacity(8), ..TetherFrame::default() };
        let buffer = b.vessel_stretch.as_ptr();
        b.copy_from(&a);
        assert_eq!(b, a);
        assert_eq!(b.vessel_stretch.as_ptr(), buffer, "the stretch buffer is reused");
    }

    #[test]
    fn a_point_snaps_to_the_nearest_triangle_with_its_barycentric_weights() {
        let positions = vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.0, 1.0, 0.0), Vec3::new(5.0, 5.0, 0.0), Vec3::new(6.0, 5.0, 0.0), Vec3::new(5.0, 6.0, 0.0)];
        let triangles = vec![[3, 4, 5], [0, 1, 2]];
        let s = snap(&triangles, &positions, &Vec3::new(0.25, 0.25, 0.5)).unwrap();
        assert_eq!(s.vertices, [0, 1, 2]);
        assert!((s.distance - 0.5).abs() < 1e-15);
        assert!((s.at(&positions) - Vec3::new(0.25, 0.25, 0.0)).norm() < 1e-15);
        assert!((s.weights.iter().sum::<f64>() - 1.0).abs() < 1e-15);
    }
}
