//! Tissue over time: stress relaxation (the `Relaxation` effect) and ischemia under a retractor (the `Ischemia`
//! effect), as written and as checked.
//!
//! In: the `relaxation` and `ischemia` fields of a scenario file. Out: [`Relaxation`] and [`Ischemia`] in SI, every
//! value finite and in range. The defaults come from the literature, each cited where it is defined; where the
//! literature is thin the doc says so and the value is one a neurosurgeon recognizes.

use serde::{Deserialize, Serialize};

use super::ScenarioError;

/// `relaxation: (terms: [(weight: 0.7, tau_s: 316.0)])`: the tissue's relaxation function as a Prony series,
/// `G(t) / G(0) = g_inf + sum_i g_i exp(-t / tau_i)` with `g_inf = 1 - sum_i g_i`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RelaxationFile {
    /// One to four terms; their weights sum to less than 1 (what is left is the long-term modulus). Default
    /// [`DEFAULT_PRONY`].
    #[serde(default = "default_terms")]
    pub terms: Vec<PronyTermFile>,
}

/// One term of the series.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PronyTermFile {
    /// `g_i`, in (0, 1).
    pub weight: f64,
    /// `tau_i`, s, in [0.01, 1e6].
    pub tau_s: f64,
}

/// The default relaxation: one term, fitted so that the force a held retraction needs halves in 6.6 minutes
/// (396 s), the mean time the retractor pressure needed for a given exposure took to halve in dogs and patients
/// (strain-gauge retractors, "Monitoring retraction pressure on the brain", J Neurosurg 1987;66(2):270-5, PMID 3806207, doi
/// 10.3171/jns.1987.66.2.0270). How far the tissue relaxes in the end is not measured there, and the literature on
/// brain tissue relaxing over tens of minutes in vivo is thin: the long-term share `g_inf = 0.3` is chosen (a
/// retraction held for an hour still needs a third of its first force, the order a surgeon who re-tightens a
/// retractor recognizes). Then `0.3 + 0.7 exp(-396 / tau) = 0.5` gives `tau = 396 / ln 3.5 = 316.1 s`.
pub const DEFAULT_PRONY: [(f64, f64); 1] = [(0.7, 396.0 / 1.252_762_968_495_368)];

fn default_terms() -> Vec<PronyTermFile> {
    DEFAULT_PRONY.iter().map(|&(weight, tau_s)| PronyTermFile { weight, tau_s }).collect()
}

impl Default for RelaxationFile {
    fn default() -> Self {
        Self { terms: default_terms() }
    }
}

/// `ischemia: (mean_arterial_pressure_mmhg: 90.0)`: the model of injury under a retractor; every field has a
/// default.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IschemiaFile {
    /// The patient's mean arterial pressure, mmHg, in [30, 200]. Default [`DEFAULT_MAP_MMHG`]. Lower it to train
    /// what hypotension does: the regional perfusion pressure under a blade is `MAP - retractor pressure`, and the
    /// dose counts the retractor pressure plus the fall of the MAP below the calibration's.
    #[serde(default = "default_map")]
    pub mean_arterial_pressure_mmhg: f64,
    /// Retractor pressure below which a pressed vertex takes no dose (and recovers), mmHg, in [0, 40]. Default
    /// [`DOSE_THRESHOLD_MMHG`].
    #[serde(default = "default_threshold")]
    pub dose_threshold_mmhg: f64,
    /// Dose at which half the vertices so treated infarct, mmHg min, > 0. Default [`DOSE_50_MMHG_MIN`].
    #[serde(default = "default_dose_50")]
    pub dose_50_mmhg_min: f64,
    /// Spread of the logistic risk curve, mmHg min, > 0. Default [`DOSE_SPREAD_MMHG_MIN`].
    #[serde(default = "default_dose_spread")]
    pub dose_spread_mmhg_min: f64,
    /// Time constant of recovery while released, s, in [1, 1e5]. Default [`RECOVERY_TAU_S`].
    #[serde(default = "default_recovery")]
    pub recovery_tau_s: f64,
}

/// Default mean arterial pressure, mmHg: a normotensive anaesthetised adult (the range anaesthetists hold during
/// a craniotomy, 70-100 mmHg; 90 also stands for the calibration's, against which a lower MAP adds dose).
pub const DEFAULT_MAP_MMHG: f64 = 90.0;
/// Regional perfusion pressure under which a vertex's time is counted, mmHg: in 120 recordings under
/// self-retaining retractors in 23 patients, rCPP (MAP - retractor pressure) stayed under 10 mmHg for more than six
/// to eight minutes in six patients, and five of them developed an infarct under the retractor (Rosenørn, Acta
/// Neurochir 1987, PMID 3111189, doi 10.1007/BF01402364).
pub const RCPP_LIMIT_MMHG: f64 = 10.0;
/// How long rCPP under [`RCPP_LIMIT_MMHG`] is tolerated, s (the six minutes of the patient series above).
pub const RCPP_TOLERANCE_S: f64 = 360.0;
/// Default dose threshold, mmHg. The dose is `integral of max(0, p - 10 mmHg) dt` (with `p` the retractor
/// pressure plus the MAP's fall below 90 mmHg), so that a constant pressure for a fixed time gives a dose linear
/// in the pressure, and the rat figures below fix a logistic risk. The threshold itself is chosen: below it
/// capillary perfusion is taken as kept (the literature does not give a floor).
pub const DOSE_THRESHOLD_MMHG: f64 = 10.0;
/// Default dose at a risk of one half, mmHg min. Rats under a retractor for 15 minutes: at 20 mmHg one brain in six
/// infarcted, at 30 mmHg five in six, at 40 mmHg all six (Rosenørn and Diemer, J Neurosurg 1985;63(4):608-11,
/// PMID 4032025, doi 10.3171/jns.1985.63.4.0608). With the 10 mmHg threshold the doses are 150, 300 and 450
/// mmHg min; the logistic through the first two has its middle at 225 mmHg min and its spread 75 / ln 5 = 46.6
/// mmHg min, and gives 0.992 at the third.
pub const DOSE_50_MMHG_MIN: f64 = 225.0;
/// Default spread of the logistic, mmHg min (see [`DOSE_50_MMHG_MIN`]).
pub const DOSE_SPREAD_MMHG_MIN: f64 = 75.0 / 1.609_437_912_434_100_3;
/// Default recovery time constant, s. Intermittent retraction injured less than continuous retraction at the same
/// force (dogs, 60 minutes: Yokoh et al., J Neurosurg 1983;58(6):918-23, PMID 6854385; rats: Rosenørn 1988,
/// PMID 3414411); how fast the tissue recovers is not given as a time constant. One minute is chosen: blood flow
/// under a released retractor returns within about a minute (the hyperaemia of reperfusion), so a minute's release
/// takes most (63 %) of the dose away, while a blade lifted for a few seconds takes little. With a slower recovery
/// an intermittent hold would come out worse than a continuous one here (the re-pressed tissue starts unrelaxed),
/// against the dogs' and rats' findings.
pub const RECOVERY_TAU_S: f64 = 60.0;

fn default_map() -> f64 {
    DEFAULT_MAP_MMHG
}
fn default_threshold() -> f64 {
    DOSE_THRESHOLD_MMHG
}
fn default_dose_50() -> f64 {
    DOSE_50_MMHG_MIN
}
fn default_dose_spread() -> f64 {
    DOSE_SPREAD_MMHG_MIN
}
fn default_recovery() -> f64 {
    RECOVERY_TAU_S
}

impl Default for IschemiaFile {
    fn default() -> Self {
        Self {
            mean_arterial_pressure_mmhg: DEFAULT_MAP_MMHG,
            dose_threshold_mmhg: DOSE_THRESHOLD_MMHG,
            dose_50_mmhg_min: DOSE_50_MMHG_MIN,
            dose_spread_mmhg_min: DOSE_SPREAD_MMHG_MIN,
            recovery_tau_s: RECOVERY_TAU_S,
        }
    }
}

/// The relaxation function, checked: `G(t) / G(0) = long_term + sum weight_i exp(-t / tau_i)`.
#[derive(Debug, Clone, PartialEq)]
pub struct Relaxation {
    /// `(g_i, tau_i in s)`.
    pub terms: Vec<(f64, f64)>,
    /// `g_inf = 1 - sum g_i`, in (0, 1].
    pub long_term: f64,
}

impl Default for Relaxation {
    fn default() -> Self {
        let terms = DEFAULT_PRONY.to_vec();
        Self { long_term: 1.0 - terms.iter().map(|t| t.0).sum::<f64>(), terms }
    }
}

impl Relaxation {
    /// `G(t) / G(0)`.
    pub fn modulus_ratio(&self, t_s: f64) -> f64 {
        self.long_term + self.terms.iter().map(|(g, tau)| g * (-t_s / tau).exp()).sum::<f64>()
    }
}

/// The ischemia model, checked, in mmHg and seconds (the clinical units its figures are given in).
#[derive(Debug, Clone, PartialEq)]
pub struct Ischemia {
    pub mean_arterial_pressure_mmhg: f64,
    pub dose_threshold_mmhg: f64,
    pub dose_50_mmhg_min: f64,
    pub dose_spread_mmhg_min: f64,
    pub recovery_tau_s: f64,
}

impl Default for Ischemia {
    fn default() -> Self {
        let f = IschemiaFile::default();
        Self {
            mean_arterial_pressure_mmhg: f.mean_arterial_pressure_mmhg,
            dose_threshold_mmhg: f.dose_threshold_mmhg,
            dose_50_mmhg_min: f.dose_50_mmhg_min,
            dose_spread_mmhg_min: f.dose_spread_mmhg_min,
            recovery_tau_s: f.recovery_tau_s,
        }
    }
}

impl Ischemia {
    /// The risk of infarct of a vertex that took `dose_mmhg_min`: the logistic calibrated to the rat figures.
    pub fn risk(&self, dose_mmhg_min: f64) -> f64 {
        1.0 / (1.0 + (-(dose_mmhg_min - self.dose_50_mmhg_min) / self.dose_spread_mmhg_min).exp())
    }

    /// The dose rate, mmHg, of a vertex under `pressure_mmhg` (0 where no blade presses it).
    pub fn dose_rate_mmhg(&self, pressure_mmhg: f64) -> f64 {
        if pressure_mmhg <= 0.0 {
            return 0.0;
        }
        let hypotension = (DEFAULT_MAP_MMHG - self.mean_arterial_pressure_mmhg).max(0.0);
        (pressure_mmhg + hypotension - self.dose_threshold_mmhg).max(0.0)
    }
}

/// The risk levels the outputs count area over: the rats' 20 mmHg for 15 minutes (one in six), even odds, and
/// their 30 mmHg for 15 minutes (five in six).
pub const RISK_LEVELS: [(f64, &str); 3] = [(1.0 / 6.0, "watch"), (0.5, "at_risk"), (5.0 / 6.0, "likely")];

type Invalid<'a> = &'a dyn Fn(&str, String) -> ScenarioError;

/// Checks the relaxation function (`field` prefix `relaxation`).
pub fn validate_relaxation(file: &RelaxationFile, invalid: Invalid<'_>) -> Result<Relaxation, ScenarioError> {
    if file.terms.is_empty() || file.terms.len() > 4 {
        return Err(invalid("relaxation.terms", format!("needs one to four terms, got {}", file.terms.len())));
    }
    let mut terms = Vec::with_capacity(file.terms.len());
    for (i, t) in file.terms.iter().enumerate() {
        if !(t.weight.is_finite() && t.weight > 0.0 && t.weight < 1.0) {
            return Err(invalid(&format!("relaxation.terms[{i}].weight"), format!("must be in (0, 1), got {}", t.weight)));
        }
        if !(t.tau_s.is_finite() && (0.01..=1e6).contains(&t.tau_s)) {
            return Err(invalid(&format!("relaxation.terms[{i}].tau_s"), format!("must be a time constant in [0.01, 1e6] s, got {}", t.tau_s)));
        }
        terms.push((t.weight, t.tau_s));
    }
    let sum: f64 = terms.iter().map(|t| t.0).sum();
    if sum >= 1.0 - 1e-6 {
        return Err(invalid("relaxation.terms", format!("the weights sum to {sum}: they must leave a long-term share (sum < 1), or the held tissue would carry no force at all")));
    }
    Ok(Relaxation { terms, long_term: 1.0 - sum })
}

/// Checks the ischemia model (`field` prefix `ischemia`).
pub fn validate_ischemia(file: &IschemiaFile, invalid: Invalid<'_>) -> Result<Ischemia, ScenarioError> {
    let check = |field: &str, v: f64, ok: bool, what: &str| if v.is_finite() && ok { Ok(v) } else { Err(invalid(&format!("ischemia.{field}"), format!("must be {what}, got {v}"))) };
    let map = file.mean_arterial_pressure_mmhg;
    Ok(Ischemia {
        mean_arterial_pressure_mmhg: check("mean_arterial_pressure_mmhg", map, (30.0..=200.0).contains(&map), "a mean arterial pressure in [30, 200] mmHg")?,
        dose_threshold_mmhg: check("dose_threshold_mmhg", file.dose_threshold_mmhg, (0.0..=40.0).contains(&file.dose_threshold_mmhg), "in [0, 40] mmHg")?,
        dose_50_mmhg_min: check("dose_50_mmhg_min", file.dose_50_mmhg_min, file.dose_50_mmhg_min > 0.0 && file.dose_50_mmhg_min <= 1e6, "in (0, 1e6] mmHg min")?,
        dose_spread_mmhg_min: check("dose_spread_mmhg_min", file.dose_spread_mmhg_min, file.dose_spread_mmhg_min > 0.0 && file.dose_spread_mmhg_min <= 1e6, "in (0, 1e6] mmHg min")?,
        recovery_tau_s: check("recovery_tau_s", file.recovery_tau_s, (1.0..=1e5).contains(&file.recovery_tau_s), "a time constant in [1, 1e5] s")?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_default_relaxation_halves_in_six_point_six_minutes() {
        let r = Relaxation::default();
        assert!((r.modulus_ratio(396.0) - 0.5).abs() < 1e-12, "{}", r.modulus_ratio(396.0));
        assert!((r.modulus_ratio(0.0) - 1.0).abs() < 1e-15);
        assert!((r.long_term - 0.3).abs() < 1e-15);
    }

    #[test]
    fn fifteen_minutes_at_the_rats_pressures_give_their_risks() {
        let m = Ischemia::default();
        let risk = |p: f64| m.risk(m.dose_rate_mmhg(p) * 15.0);
        assert!((risk(20.0) - 1.0 / 6.0).abs() < 1e-12, "{}", risk(20.0));
        assert!((risk(30.0) - 5.0 / 6.0).abs() < 1e-12, "{}", risk(30.0));
        assert!(risk(40.0) > 0.99, "{}", risk(40.0));
        assert_eq!(m.dose_rate_mmhg(0.0), 0.0);
        assert_eq!(m.dose_rate_mmhg(5.0), 0.0);
        // Hypotension: at a MAP of 60 mmHg, 20 mmHg doses as 50 would at 90.
        let low = Ischemia { mean_arterial_pressure_mmhg: 60.0, ..Ischemia::default() };
        assert_eq!(low.dose_rate_mmhg(20.0), m.dose_rate_mmhg(50.0));
        assert_eq!(low.dose_rate_mmhg(0.0), 0.0);
    }
}
