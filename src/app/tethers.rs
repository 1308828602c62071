//! Vessels and arachnoid bands in the drawing: what a [`super::draw::Snapshot`]
//! copies of the tether stage each frame, the tubes a
//! [`crate::render::SceneView`] draws, the vessel legend and the panel's
//! tethers section.
//!
//! In: the pipeline's tether stage after a step (its links, at the frame's
//! surface; its log of events), the scene's tethers (names, kinds, diameters,
//! limits, copied once per build). Out: [`TetherSnapshot`] (plain owned data),
//! [`TetherSegment`]s, a [`VesselLegend`], a [`TetherPanel`]. Stays true: a
//! scene without tethers copies nothing and draws nothing; capturing reuses
//! its vectors (events are only appended as they happen); a link whose
//! surface point lies outside the frame's positions, or a vessel index the
//! scene does not have (a snapshot of the scene before a reload), is skipped,
//! never a panic.

use crate::math::Vec3;
use crate::render::TetherSegment;
use crate::render::tethers::{
    ARTERY_RED, BAND_ALPHA, BAND_RADIUS_M, BAND_WHITE, TORN_END, VEIN_BLUE, VesselLegend, VesselLegendRow, vessel_color,
};
use crate::scenario::{Tethers, VesselKind};
use crate::sim::tethers::{LinkEnd, LinkOwner, LinkState, TetherEvent, TetherFrame, TetherKind, TetherStage};
use crate::ui::tethers::{EventLine, MAX_EVENT_LINES, TetherPanel, VesselReadout};

/// One link as the frame left it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkView {
    /// Its two ends now, m.
    pub a: Vec3,
    pub b: Vec3,
    pub owner: LinkOwner,
    pub state: LinkState,
    /// Length over rest length at the frame's last sub-step.
    pub stretch: f64,
}

/// The tethers of one frame (empty in a scene without).
#[derive(Debug, Clone, Default)]
pub struct TetherSnapshot {
    pub links: Vec<LinkView>,
    /// Every event so far in this scene, in order.
    pub events: Vec<TetherEvent>,
}

/// Where `end` is on `positions` (per surface vertex); `None` when its triangle is not in them.
fn end_at(end: &LinkEnd, positions: &[Vec3]) -> Option<Vec3> {
    match end {
        LinkEnd::Surface(s) if s.vertices.iter().any(|&v| v as usize >= positions.len()) => None,
        e => Some(e.at(positions)),
    }
}

impl TetherSnapshot {
    /// Copies `stage`'s links at `positions` (the frame's surface) and its new
    /// events; clears everything for a scene without a stage.
    pub fn capture(&mut self, stage: Option<&TetherStage>, positions: &[Vec3]) {
        self.links.clear();
        let Some(stage) = stage else {
            self.events.clear();
            return;
        };
        for l in stage.links() {
            let (Some(a), Some(b)) = (end_at(&l.ends[0], positions), end_at(&l.ends[1], positions)) else { continue };
            self.links.push(LinkView { a, b, owner: l.owner, state: l.state, stretch: l.stretch });
        }
        // The stage's log only grows within a scene: append what is new; a
        // log that is not a continuation of ours (another scene) is copied afresh.
        let all = stage.events();
        let n = self.events.len();
        let continues = n <= all.len() && (n == 0 || self.events.last() == all.get(n - 1));
        if !continues {
            self.events.clear();
        }
        let n = self.events.len();
        self.events.extend_from_slice(all.get(n..).unwrap_or(&[]));
    }
}

/// The intact colour of a kind of vessel.
pub fn base_colour(kind: VesselKind) -> [f32; 3] {
    match kind {
        VesselKind::Artery => ARTERY_RED,
        VesselKind::Vein | VesselKind::BridgingVein => VEIN_BLUE,
    }
}

/// The stub at each end of a torn vessel segment: this long at most, m.
const STUB_MAX_M: f64 = 1.5e-3;
/// A stub is this much thicker than its vessel (it reads as a marker).
const STUB_THICKER: f32 = 1.2;

/// The tubes of `snapshot` in the scene `info`, into `out` (cleared): intact
/// vessel segments at their diameter, coloured by stretch; a torn segment as a
/// short bright stub at each end; intact bands as fine translucent strands;
/// torn and cut bands not at all.
pub fn segments(info: &Tethers, snapshot: &TetherSnapshot, out: &mut Vec<TetherSegment>) {
    out.clear();
    for l in &snapshot.links {
        match l.owner {
            LinkOwner::Vessel { vessel, .. } => {
                let Some(v) = info.vessels.get(vessel) else { continue };
                let radius_m = (0.5 * v.diameter) as f32;
                if l.state == LinkState::Intact {
                    let color = vessel_color(base_colour(v.kind), l.stretch, v.warning_stretch, v.rupture_stretch);
                    out.push(TetherSegment { a: l.a, b: l.b, radius_m, color, alpha: 1.0 });
                    continue;
                }
                let axis = l.b - l.a;
                let length = axis.norm();
                if !(length > 1e-9 && length.is_finite()) {
                    continue;
                }
                let stub = (0.25 * length).min(STUB_MAX_M);
                let d = axis / length;
                let radius_m = radius_m * STUB_THICKER;
                out.push(TetherSegment { a: l.a, b: l.a + d * stub, radius_m, color: TORN_END, alpha: 1.0 });
                out.push(TetherSegment { a: l.b, b: l.b - d * stub, radius_m, color: TORN_END, alpha: 1.0 });
            }
            LinkOwner::Band(_) if l.state == LinkState::Intact => {
                out.push(TetherSegment { a: l.a, b: l.b, radius_m: BAND_RADIUS_M, color: BAND_WHITE, alpha: BAND_ALPHA });
            }
            LinkOwner::Band(_) => {}
        }
    }
}

/// The vessel-stretch legend of `info` (`None` without vessels).
pub fn vessel_legend(info: &Tethers) -> Option<VesselLegend> {
    if info.vessels.is_empty() {
        return None;
    }
    let mut legend = VesselLegend::default();
    for v in &info.vessels {
        legend.add(VesselLegendRow { label: v.kind.word().into(), base: base_colour(v.kind), warning: v.warning_stretch, rupture: v.rupture_stretch });
    }
    Some(legend)
}

/// The panel's tethers section: band counts and each vessel's stretch from the
/// frame's figures (`frame`; from the links when it has none), the latest events.
pub fn panel(info: &Tethers, snapshot: &TetherSnapshot, frame: Option<&TetherFrame>) -> TetherPanel {
    let mut p = TetherPanel::default();
    match frame {
        Some(f) => (p.bands_intact, p.bands_torn, p.bands_cut) = (f.bands_intact, f.bands_torn, f.bands_cut),
        None => {
            for l in snapshot.links.iter().filter(|l| matches!(l.owner, LinkOwner::Band(_))) {
                match l.state {
                    LinkState::Intact => p.bands_intact += 1,
                    LinkState::Torn => p.bands_torn += 1,
                    LinkState::Cut => p.bands_cut += 1,
                }
            }
        }
    }
    for (k, v) in info.vessels.iter().enumerate() {
        let mine = || snapshot.links.iter().filter(move |l| matches!(l.owner, LinkOwner::Vessel { vessel, .. } if vessel == k));
        let stretch = frame
            .and_then(|f| f.vessel_stretch.get(k).copied())
            .unwrap_or_else(|| mine().map(|l| l.stretch).fold(1.0, f64::max));
        let torn = frame.and_then(|f| f.vessel_torn.get(k).copied()).unwrap_or_else(|| mine().any(|l| l.state != LinkState::Intact));
        p.vessels.push(VesselReadout { name: v.name.clone(), kind: v.kind.word(), stretch, warning: v.warning_stretch, rupture: v.rupture_stretch, torn });
    }
    p.event_count = snapshot.events.len();
    let first = snapshot.events.len().saturating_sub(MAX_EVENT_LINES);
    for e in snapshot.events.get(first..).unwrap_or(&[]) {
        let band = e.what == TetherKind::Band;
        let noun = if band {
            "band".to_string()
        } else {
            info.vessels.iter().find(|v| v.name == e.tether).map_or("vessel", |v| v.kind.word()).to_string()
        };
        p.events.push(EventLine {
            time_s: e.time_s,
            noun,
            name: e.tether.clone(),
            cut: e.kind == LinkState::Cut,
            band,
            stretch: e.stretch,
            tension_n: e.tension_n,
        });
    }
    p
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scenario::{Band, TetherPoint, Vessel};

    fn scene() -> Tethers {
        let vessel = Vessel {
            name: "superficial Sylvian vein".into(),
            kind: VesselKind::Vein,
            points: vec![TetherPoint::Anchor(Vec3::zeros()); 3],
            diameter: 2e-3,
            axial_stiffness: 1.6,
            warning_stretch: 1.25,
            rupture_stretch: 1.5,
        };
        let band = Band { name: "trabecula 3".into(), from: Vec3::zeros(), to: Vec3::x(), stiffness: 20.0, strength: 0.05, slack: 0.0 };
        Tethers { vessels: vec![vessel], bands: vec![band.clone(), band] }
    }

    fn link(owner: LinkOwner, state: LinkState, stretch: f64) -> LinkView {
        LinkView { a: Vec3::zeros(), b: Vec3::new(0.01, 0.0, 0.0), owner, state, stretch }
    }

    /// Intact vessels are tubes of their radius coloured by stretch, a torn
    /// segment leaves two stubs, only intact bands are drawn, and a vessel
    /// the scene does not have is skipped.
    #[test]
    fn segments_follow_the_link_states() {
        let info = scene();
        let snapshot = TetherSnapshot {
            links: vec![
                link(LinkOwner::Vessel { vessel: 0, segment: 0 }, LinkState::Intact, 1.0),
                link(LinkOwner::Vessel { vessel: 0, segment: 1 }, LinkState::Torn, 1.5),
                link(LinkOwner::Vessel { vessel: 7, segment: 0 }, LinkState::Intact, 1.0),
                link(LinkOwner::Band(0), LinkState::Intact, 1.0),
                link(LinkOwner::Band(1), LinkState::Cut, 1.0),
            ],
            events: Vec::new(),
        };
        let mut out = Vec::new();
        segments(&info, &snapshot, &mut out);
        assert_eq!(out.len(), 4, "{out:?}");
        assert_eq!((out[0].radius_m, out[0].color, out[0].alpha), (1e-3, VEIN_BLUE, 1.0));
        assert!(out[1..3].iter().all(|s| s.color == TORN_END && ((s.b - s.a).norm() - 1.5e-3).abs() < 1e-12), "{out:?}");
        assert_eq!((out[3].radius_m, out[3].alpha), (BAND_RADIUS_M, BAND_ALPHA));
        let mut none = vec![out[0]];
        segments(&Tethers::default(), &TetherSnapshot::default(), &mut none);
        assert!(none.is_empty());
        assert!(vessel_legend(&Tethers::default()).is_none());
        assert_eq!(vessel_legend(&info).map(|l| l.rows.len()), Some(1));
    }

    #[test]
    fn panel_counts_bands_and_names_events_by_kind() {
        let info = scene();
        let event = |what: TetherKind, tether: &str, kind| TetherEvent { time_s: 1.2, frame: 120, kind, tether: tether.into(), what, stretch: 1.5, tension_n: 0.051 };
        let snapshot = TetherSnapshot {
            links: vec![
                link(LinkOwner::Vessel { vessel: 0, segment: 0 }, LinkState::Torn, 1.5),
                link(LinkOwner::Band(0), LinkState::Intact, 1.0),
                link(LinkOwner::Band(1), LinkState::Cut, 1.0),
            ],
            events: vec![event(TetherKind::Vessel, "superficial Sylvian vein", LinkState::Torn), event(TetherKind::Band, "trabecula 3", LinkState::Cut)],
        };
        let p = panel(&info, &snapshot, None);
        assert_eq!((p.bands_intact, p.bands_torn, p.bands_cut), (1, 0, 1));
        assert!(p.vessels[0].torn && p.vessels[0].stretch == 1.5);
        assert_eq!(p.events[0].text(), "1.20 s  vein 'superficial Sylvian vein' torn at stretch 1.50");
        assert_eq!(p.events[1].text(), "1.20 s  band 'trabecula 3' cut");
        let frame = TetherFrame { vessel_stretch: vec![1.1], vessel_torn: vec![false], bands_intact: 2, ..TetherFrame::default() };
        let p = panel(&info, &snapshot, Some(&frame));
        assert_eq!((p.bands_intact, p.vessels[0].stretch, p.vessels[0].torn), (2, 1.1, false), "the frame's figures win");
    }
}
