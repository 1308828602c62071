//! The scene's tethers (vessels and arachnoid bands), as written and as checked.
//!
//! In: the `tethers` field of a scenario file. Out: [`Tethers`] in SI, every value finite and in range, names
//! unique. What needs the mesh (a point within 2 mm of the surface, an anchor outside the tissue) is checked by the
//! preflight (`sim::preflight`), which names the same fields.
//!
//! The defaults come from the literature, each cited where it is defined; where the literature is thin the doc
//! says so and the value is one a neurosurgeon recognizes.

use serde::{Deserialize, Serialize};

use super::ScenarioError;
use crate::math::Vec3;

const MM: f64 = 1e-3;

/// `tethers: (vessels: [..], bands: [..])`.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TethersFile {
    /// Vessels: polylines tied to the surface (or to a fixed anchor) at each point.
    #[serde(default)]
    pub vessels: Vec<VesselFile>,
    /// Arachnoid bands: one tether each between two points of the surface (the fissure's two banks).
    #[serde(default)]
    pub bands: Vec<BandFile>,
}

/// What a vessel is; it chooses the defaults of its stiffness and stretch limits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum VesselKind {
    /// A cerebral artery (an MCA branch).
    Artery,
    /// A cortical vein (the superficial Sylvian vein).
    Vein,
    /// A bridging vein (cortex to a dural sinus).
    BridgingVein,
}

/// A point of a tether: on the brain's surface (snapped to the nearest boundary triangle and carried by it), or a
/// fixed anchor (a point of a sinus or the dura), in the scene's millimetres.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub enum TetherPointFile {
    Surface(f64, f64, f64),
    Anchor(f64, f64, f64),
}

/// One vessel: `(name: "superficial Sylvian vein", kind: Vein, points_mm: [Surface(..), ..], diameter_mm: 2.0)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VesselFile {
    /// Unique among the scene's tethers; events and outputs name it.
    pub name: String,
    pub kind: VesselKind,
    /// At least two points; each consecutive pair is one tether, its rest length their distance at rest.
    pub points_mm: Vec<TetherPointFile>,
    /// Outer diameter, mm, in (0, 10]: drawing only.
    pub diameter_mm: f64,
    /// Axial stiffness `E A` of the wall, N, in (0, 1000]: a segment of rest length L pulls `E A (stretch - 1)`,
    /// a spring of `E A / L` N/m. Default: the kind's ([`VesselKind::axial_stiffness_n`]).
    #[serde(default)]
    pub axial_stiffness_n: Option<f64>,
    /// Stretch past which the vessel is drawn and reported as at risk, in (1, rupture_stretch). Default: the kind's.
    #[serde(default)]
    pub warning_stretch: Option<f64>,
    /// Stretch at which a segment tears, in (1, 3]. Default: the kind's.
    #[serde(default)]
    pub rupture_stretch: Option<f64>,
}

/// One arachnoid band: `(name: "trabecula 1", from_mm: (..), to_mm: (..))`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BandFile {
    /// Unique among the scene's tethers.
    pub name: String,
    /// Its two ends, each snapped to the surface.
    pub from_mm: [f64; 3],
    pub to_mm: [f64; 3],
    /// Stiffness, N/mm, in (0, 100]. Default [`BAND_STIFFNESS_N_PER_MM`].
    #[serde(default = "default_band_stiffness")]
    pub stiffness_n_per_mm: f64,
    /// Tension at which it breaks, N, in (0, 10]. Default [`BAND_STRENGTH_N`].
    #[serde(default = "default_band_strength")]
    pub strength_n: f64,
    /// Slack before it pulls, mm, >= 0: its rest length is the distance of its ends at rest plus this. Default 0.
    #[serde(default)]
    pub slack_mm: f64,
}

/// Default strength of one arachnoid band, N. Blunt dissection of the arachnoid takes 0.22 N against 0.03 N for
/// sharp dissection (median peak forces, human cadaver brains: Marcus et al. 2014, Int J Med Robot Comput Assist
/// Surg, PMID 24431265, doi 10.1002/rcs.1568); the default lets a group of four to six bands under a blade hold
/// about that much together. Single-trabecula strengths are not measured: the literature is thin here (a 30 um
/// strand at the 2.7 MPa of ovine pia-arachnoid, Natividad et al. 2020, doi 10.1186/s12987-020-00229-w, holds
/// about 2 mN; a band of trabeculae 0.2 mm across about 85 mN).
pub const BAND_STRENGTH_N: f64 = 0.05;
/// Default stiffness of an arachnoid band, N/mm: it breaks at its strength after about 2.5 mm of stretch (a
/// band a surgeon sees tighten over a few millimetres of spread). Chosen, not measured.
pub const BAND_STIFFNESS_N_PER_MM: f64 = 0.02;

fn default_band_stiffness() -> f64 {
    BAND_STIFFNESS_N_PER_MM
}

fn default_band_strength() -> f64 {
    BAND_STRENGTH_N
}

impl VesselKind {
    /// Stretch (from the length at rest) at which the wall fails. Arteries: 1.24 +- 0.09 (human cerebral
    /// arteries in axial tension, Monson et al. 2003, J Biomech Eng 125:288, as quoted by Bell et al. 2013,
    /// J Biomech, PMC3529833). Cortical veins withstand about twice the arteries' stretch (Monson et al. 2003:
    /// "withstanding only half as much stretch" said of the arteries): 1.5. Bridging veins stretch less before
    /// failing than cortical veins of the same source (Monson et al. 2005, J Biomech, doi
    /// 10.1016/j.jbiomech.2004.05.004); the figure is not settled, 1.35 is chosen between the two.
    pub fn rupture_stretch(self) -> f64 {
        match self {
            VesselKind::Artery => 1.24,
            VesselKind::Vein => 1.5,
            VesselKind::BridgingVein => 1.35,
        }
    }

    /// Stretch past which a vessel is at risk: arteries at the lowest reported yield strain of cerebral
    /// vessels, 7 % (Zhao and Ji, review, PMC8792345); veins at half their rupture strain.
    pub fn warning_stretch(self) -> f64 {
        match self {
            VesselKind::Artery => 1.07,
            VesselKind::Vein => 1.25,
            VesselKind::BridgingVein => 1.175,
        }
    }

    /// Axial stiffness `E A` of the wall, N: the failure stress times the wall's area over the failure strain
    /// (a secant through the failure point; the real curve is softer first and stiffer last). Arteries:
    /// 3.29 MPa at failure (human, Bell et al. 2013 quoting Monson), a 1 mm branch with a 0.1 mm wall
    /// (0.31 mm^2): 1.03 N at 24 % strain, E A = 4.3 N. Veins carry about half the arteries' stress at failure
    /// (Monson et al. 2003): 1.6 MPa on a 2 mm vein with a 0.08 mm wall (0.50 mm^2): 0.8 N at 50 %, E A = 1.6 N.
    /// Bridging veins are stiffer than cortical veins (Monson et al. 2005): 2.5 N, chosen.
    pub fn axial_stiffness_n(self) -> f64 {
        match self {
            VesselKind::Artery => 4.3,
            VesselKind::Vein => 1.6,
            VesselKind::BridgingVein => 2.5,
        }
    }

    /// The word outputs use.
    pub fn word(self) -> &'static str {
        match self {
            VesselKind::Artery => "artery",
            VesselKind::Vein => "vein",
            VesselKind::BridgingVein => "bridging vein",
        }
    }
}

/// A point of a tether in SI (m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum TetherPoint {
    /// Snapped to the nearest boundary triangle by the build.
    Surface(Vec3),
    /// Fixed.
    Anchor(Vec3),
}

impl TetherPoint {
    pub fn position(&self) -> Vec3 {
        match *self {
            TetherPoint::Surface(p) | TetherPoint::Anchor(p) => p,
        }
    }
}

/// A checked vessel, SI.
#[derive(Debug, Clone, PartialEq)]
pub struct Vessel {
    pub name: String,
    pub kind: VesselKind,
    /// At least two.
    pub points: Vec<TetherPoint>,
    /// Outer diameter, m (> 0).
    pub diameter: f64,
    /// `E A`, N (> 0).
    pub axial_stiffness: f64,
    /// 1 < warning < rupture <= 3.
    pub warning_stretch: f64,
    pub rupture_stretch: f64,
}

/// A checked arachnoid band, SI.
#[derive(Debug, Clone, PartialEq)]
pub struct Band {
    pub name: String,
    pub from: Vec3,
    pub to: Vec3,
    /// N/m (> 0).
    pub stiffness: f64,
    /// N (> 0).
    pub strength: f64,
    /// m (>= 0).
    pub slack: f64,
}

/// The scene's tethers, SI.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Tethers {
    pub vessels: Vec<Vessel>,
    pub bands: Vec<Band>,
}

impl Tethers {
    /// No vessel and no band.
    pub fn is_empty(&self) -> bool {
        self.vessels.is_empty() && self.bands.is_empty()
    }

    /// The field path of a tether's point, for messages: `tethers.vessels[v].points_mm[p]` or
    /// `tethers.bands[b].from_mm` / `to_mm`.
    pub fn vessel_point_field(v: usize, p: usize) -> String {
        format!("tethers.vessels[{v}].points_mm[{p}]")
    }

    pub fn band_end_field(b: usize, end: usize) -> String {
        format!("tethers.bands[{b}].{}", if end == 0 { "from_mm" } else { "to_mm" })
    }
}

/// Checks the file's tethers into SI; `invalid(field, problem)` makes the error at the field's position.
pub(super) fn validate(file: &TethersFile, invalid: &dyn Fn(&str, String) -> ScenarioError) -> Result<Tethers, ScenarioError> {
    let mut names: Vec<&str> = Vec::new();
    let check_name = |field: String, name: &'_ str| -> Result<(), ScenarioError> {
        if name.trim().is_empty() {
            return Err(invalid(&field, "must not be empty".into()));
        }
        Ok(())
    };
    let finite_point = |field: &str, p: [f64; 3]| -> Result<Vec3, ScenarioError> {
        if p.iter().all(|c| c.is_finite()) {
            Ok(Vec3::new(p[0], p[1], p[2]) * MM)
        } else {
            Err(invalid(field, format!("every coordinate must be a finite number of mm, got {p:?}")))
        }
    };
    let in_range = |field: &str, v: f64, lo: f64, hi: f64, unit: &str| -> Result<f64, ScenarioError> {
        if v.is_finite() && v > lo && v <= hi {
            Ok(v)
        } else {
            Err(invalid(field, format!("must be in ({lo}, {hi}]{unit}, got {v}")))
        }
    };
    let mut out = Tethers::default();
    for (v, f) in file.vessels.iter().enumerate() {
        let field = format!("tethers.vessels[{v}]");
        check_name(format!("{field}.name"), &f.name)?;
        names.push(&f.name);
        if f.points_mm.len() < 2 {
            return Err(invalid(&format!("{field}.points_mm"), format!("a vessel needs at least two points, got {}", f.points_mm.len())));
        }
        let mut points = Vec::with_capacity(f.points_mm.len());
        for (p, point) in f.points_mm.iter().enumerate() {
            let pf = Tethers::vessel_point_field(v, p);
            points.push(match *point {
                TetherPointFile::Surface(x, y, z) => TetherPoint::Surface(finite_point(&pf, [x, y, z])?),
                TetherPointFile::Anchor(x, y, z) => TetherPoint::Anchor(finite_point(&pf, [x, y, z])?),
            });
        }
        for (p, pair) in points.windows(2).enumerate() {
            if (pair[1].position() - pair[0].position()).norm() < 0.1 * MM {
                return Err(invalid(&Tethers::vessel_point_field(v, p + 1), "must be at least 0.1 mm from the point before it (a segment needs a length)".into()));
            }
            if matches!(pair, [TetherPoint::Anchor(_), TetherPoint::Anchor(_)]) {
                return Err(invalid(&Tethers::vessel_point_field(v, p + 1), "two anchors in a row tie nothing to the tissue: a segment needs a surface point".into()));
            }
        }
        let diameter = in_range(&format!("{field}.diameter_mm"), f.diameter_mm, 0.0, 10.0, " mm")? * MM;
        let axial_stiffness = in_range(&format!("{field}.axial_stiffness_n"), f.axial_stiffness_n.unwrap_or(f.kind.axial_stiffness_n()), 0.0, 1000.0, " N")?;
        let rupture_stretch = in_range(&format!("{field}.rupture_stretch"), f.rupture_stretch.unwrap_or(f.kind.rupture_stretch()), 1.0, 3.0, "")?;
        let warning = f.warning_stretch.unwrap_or_else(|| f.kind.warning_stretch().min(1.0 + 0.5 * (rupture_stretch - 1.0)));
        if !(warning.is_finite() && warning > 1.0 && warning < rupture_stretch) {
            return Err(invalid(&format!("{field}.warning_stretch"), format!("must be in (1, rupture_stretch = {rupture_stretch}), got {warning}")));
        }
        out.vessels.push(Vessel { name: f.name.clone(), kind: f.kind, points, diameter, axial_stiffness, warning_stretch: warning, rupture_stretch });
    }
    for (b, f) in file.bands.iter().enumerate() {
        let field = format!("tethers.bands[{b}]");
        check_name(format!("{field}.name"), &f.name)?;
        names.push(&f.name);
        let from = finite_point(&Tethers::band_end_field(b, 0), f.from_mm)?;
        let to = finite_point(&Tethers::band_end_field(b, 1), f.to_mm)?;
        if (to - from).norm() < 0.1 * MM {
            return Err(invalid(&Tethers::band_end_field(b, 1), "must be at least 0.1 mm from from_mm".into()));
        }
        let stiffness = in_range(&format!("{field}.stiffness_n_per_mm"), f.stiffness_n_per_mm, 0.0, 100.0, " N/mm")? / MM;
        let strength = in_range(&format!("{field}.strength_n"), f.strength_n, 0.0, 10.0, " N")?;
        if !(f.slack_mm.is_finite() && (0.0..=50.0).contains(&f.slack_mm)) {
            return Err(invalid(&format!("{field}.slack_mm"), format!("must be in [0, 50] mm, got {}", f.slack_mm)));
        }
        out.bands.push(Band { name: f.name.clone(), from, to, stiffness, strength, slack: f.slack_mm * MM });
    }
    let mut sorted = names.clone();
    sorted.sort_unstable();
    if let Some(w) = sorted.windows(2).find(|w| w[0] == w[1]) {
        let dup = w[0];
        let field = file
            .vessels
            .iter()
            .position(|v| v.name == dup)
            .map(|v| format!("tethers.vessels[{v}].name"))
            .or_else(|| file.bands.iter().rposition(|b| b.name == dup).map(|b| format!("tethers.bands[{b}].name")))
            .unwrap_or_else(|| "tethers".into());
        return Err(invalid(&field, format!("the name {dup:?} is used twice: every vessel and band needs its own")));
    }
    Ok(out)
}
