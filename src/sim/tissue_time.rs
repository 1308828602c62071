//! Tissue over time: the force a held blade needs relaxes ([`RelaxationStage`], the `Relaxation` effect), and
//! pressure held too long injures ([`IschemiaStage`], the `Ischemia` effect).
//!
//! In: each frame's elastic answer (the blades' forces and mean pressures, the tool rows' reactions) and the frame
//! step. Out: the relaxed forces and pressures written over the elastic ones in the frame's report (so the
//! metrics, the haptic force, the panel and the debrief all read them), and per surface vertex an ischemic dose,
//! its risk and the time its perfusion pressure spent under 10 mmHg.
//!
//! Relaxation keeps what makes fissure fast: with one homogeneous linear viscoelastic material and a fixed
//! Poisson's ratio, the tissue under blades that hold their pose keeps the elastic deformation and every force
//! scales with the relaxation function (the correspondence principle), so the precomputed compliance stays valid
//! and only the forces are relaxed, by the hereditary integral `F(t) = g_inf F_e(t) + sum_i h_i(t)` with one state
//! per Prony term, `h_i(t + dt) = exp(-dt / tau_i) h_i(t) + g_i (tau_i / dt) (1 - exp(-dt / tau_i)) (F_e(t + dt) -
//! F_e(t))`: exact for an elastic force linear in time within each frame. Where it is approximate:
//! - contact that releases: a blade whose elastic force falls to zero has left the tissue, and its states are
//!   cleared (the tissue's slow recovery is not modelled: it springs back elastically); a relaxed force that would
//!   point against the elastic one (linear theory's recovering tissue pulling the blade back) is taken as lost
//!   contact, zero;
//! - contact that grows while relaxing: new tissue enters at its elastic force, as the linear integral has it;
//! - several materials (a scene's `regions`): one relaxation function is applied to all of them, as if they shared
//!   it; the elastic deformation is then not the viscoelastic one where their moduli relax differently;
//! - the tethers: their pull reaches the blades through the tissue and relaxes with the blade's force; a band
//!   tears on its elastic tension (the conservative side).
//! Each vertex's contact pressure relaxes with its blade's force (the patch's pressures scale together).
//!
//! Ischemia: per surface vertex, the retractor pressure `p` (relaxed), the regional perfusion pressure `MAP - p`,
//! the dose `D = integral of max(0, p + max(0, 90 - MAP) - threshold) dt` while pressed (recovering as
//! `D exp(-dt / tau_r)` while released or under the threshold) and the risk `1 / (1 + exp(-(D - D50) / s))`
//! ([`crate::scenario::tissue_time`] for the figures each is calibrated to).
//! Stays true: the frame path allocates nothing once the pressed set stops growing; every value is finite; a
//! vertex nothing ever pressed has dose 0 and risk 0.

use crate::math::Vec3;
use crate::scenario::tissue_time::{Ischemia, RCPP_LIMIT_MMHG, RISK_LEVELS, Relaxation};

use super::report::{IschemiaFrame, PASCALS_PER_MMHG, SpatulaReport};

/// The recursive hereditary integral of one relaxation function at one frame step.
#[derive(Debug, Clone, PartialEq)]
pub struct Prony {
    long_term: f64,
    /// Per term: `exp(-dt / tau)` and `g (tau / dt) (1 - exp(-dt / tau))`.
    decay: Vec<f64>,
    gain: Vec<f64>,
}

impl Prony {
    pub fn new(relaxation: &Relaxation, dt_s: f64) -> Self {
        let decay = relaxation.terms.iter().map(|&(_, tau)| (-dt_s / tau).exp()).collect();
        let gain = relaxation.terms.iter().map(|&(g, tau)| g * (tau / dt_s) * -(-dt_s / tau).exp_m1()).collect();
        Self { long_term: relaxation.long_term, decay, gain }
    }

    /// Terms of the series (states per channel).
    pub fn terms(&self) -> usize {
        self.decay.len()
    }

    /// One frame of one channel: `states` (one per term) advanced from the elastic value `before` to `now`;
    /// returns the relaxed value.
    pub fn step(&self, states: &mut [f64], before: f64, now: f64) -> f64 {
        let mut relaxed = self.long_term * now;
        for ((h, decay), gain) in states.iter_mut().zip(&self.decay).zip(&self.gain) {
            *h = decay * *h + gain * (now - before);
            relaxed += *h;
        }
        relaxed
    }
}

/// The relaxation of each blade's force (three channels a blade).
#[derive(Debug, Clone)]
pub struct RelaxationStage {
    prony: Prony,
    /// Per blade: three channels of `terms` states.
    states: Vec<f64>,
    /// Per blade: last frame's elastic force.
    elastic: Vec<Vec3>,
    /// Per blade: this frame's relaxed over elastic force magnitude (1 without contact).
    ratio: Vec<f64>,
}

impl RelaxationStage {
    pub fn new(relaxation: &Relaxation, dt_s: f64, blades: usize) -> Self {
        let prony = Prony::new(relaxation, dt_s);
        Self { states: vec![0.0; blades * 3 * prony.terms()], elastic: vec![Vec3::zeros(); blades], ratio: vec![1.0; blades], prony }
    }

    /// Per blade, the relaxed over the elastic force this frame (what the contact pressures are scaled by).
    pub fn ratios(&self) -> &[f64] {
        &self.ratio
    }

    /// Relaxes each blade's force and mean pressure in place (they hold the elastic answer on entry).
    pub fn apply(&mut self, spatulas: &mut [SpatulaReport]) {
        let n = self.prony.terms();
        for (b, s) in spatulas.iter_mut().enumerate() {
            let (Some(before), Some(ratio)) = (self.elastic.get(b).copied(), self.ratio.get_mut(b)) else { continue };
            let Some(states) = self.states.get_mut(b * 3 * n..(b + 1) * 3 * n) else { continue };
            let elastic = s.force;
            let magnitude = elastic.norm();
            if magnitude == 0.0 {
                // Out of the tissue: nothing to relax, and the next contact starts fresh.
                states.fill(0.0);
                self.elastic[b] = Vec3::zeros();
                *ratio = 1.0;
                continue;
            }
            let mut relaxed = Vec3::zeros();
            for axis in 0..3 {
                relaxed[axis] = self.prony.step(&mut states[axis * n..(axis + 1) * n], before[axis], elastic[axis]);
            }
            if relaxed.dot(&elastic) <= 0.0 {
                relaxed = Vec3::zeros();
            }
            self.elastic[b] = elastic;
            *ratio = relaxed.norm() / magnitude;
            s.force = relaxed;
            s.mean_pressure_pa *= *ratio;
        }
    }
}

/// Per surface vertex: the dose, the time under the perfusion limit, the blade that last pressed it.
#[derive(Debug, Clone)]
pub struct IschemiaStage {
    model: Ischemia,
    dt_s: f64,
    /// Lumped area of each surface vertex at rest, m^2.
    areas: Vec<f64>,
    /// Per vertex: dose, mmHg s.
    dose: Vec<f64>,
    /// Per vertex: this stretch of time with rCPP under the limit, s.
    low_perfusion: Vec<f64>,
    /// Per vertex: pressure this frame, mmHg (relaxed).
    pressure: Vec<f64>,
    /// Per vertex: the blade that last pressed it (`u16::MAX`: none).
    owner: Vec<u16>,
    /// Vertices with a dose, a low-perfusion time or a pressure: the only ones a frame visits.
    live: Vec<u32>,
    in_live: Vec<bool>,
    /// Per blade: the time its area at risk first passed zero, s.
    first_at_risk_s: Vec<Option<f64>>,
    /// The time any vertex first reached each of [`RISK_LEVELS`], s.
    first_over_s: [Option<f64>; 3],
    /// The largest dose any vertex reached, mmHg s, and when.
    peak_dose: (f64, f64),
    frame: IschemiaFrame,
}

/// A dose below this is gone (mmHg s): the vertex leaves the live set.
const DOSE_GONE_MMHG_S: f64 = 1e-6;

impl IschemiaStage {
    /// `areas`: per surface vertex, its lumped area at rest, m^2.
    pub fn new(model: &Ischemia, dt_s: f64, areas: Vec<f64>, blades: usize) -> Self {
        let n = areas.len();
        Self {
            model: model.clone(),
            dt_s,
            areas,
            dose: vec![0.0; n],
            low_perfusion: vec![0.0; n],
            pressure: vec![0.0; n],
            owner: vec![u16::MAX; n],
            live: Vec::new(),
            in_live: vec![false; n],
            first_at_risk_s: vec![None; blades],
            first_over_s: [None; 3],
            peak_dose: (0.0, 0.0),
            frame: IschemiaFrame { blade_area_at_risk_m2: vec![0.0; blades], ..Default::default() },
        }
    }

    pub fn model(&self) -> &Ischemia {
        &self.model
    }

    /// Per surface vertex: the pressure this frame (mmHg).
    pub fn pressure_mmhg(&self) -> &[f64] {
        &self.pressure
    }

    /// Per surface vertex: its dose, mmHg s.
    pub fn dose_mmhg_s(&self) -> &[f64] {
        &self.dose
    }

    /// Per surface vertex: its risk of infarct (0 where it took no dose).
    pub fn risk(&self, vertex: usize) -> f64 {
        match self.dose.get(vertex) {
            Some(&d) if d > 0.0 => self.model.risk(d / 60.0),
            _ => 0.0,
        }
    }

    /// This frame's figures.
    pub fn frame(&self) -> &IschemiaFrame {
        &self.frame
    }

    /// Per blade: when its area at risk first passed zero, s.
    pub fn first_at_risk_s(&self) -> &[Option<f64>] {
        &self.first_at_risk_s
    }

    /// When any vertex first reached each of [`RISK_LEVELS`], s.
    pub fn first_over_s(&self) -> [Option<f64>; 3] {
        self.first_over_s
    }

    /// The largest dose any vertex reached (mmHg s) and when (s).
    pub fn peak_dose(&self) -> (f64, f64) {
        self.peak_dose
    }

    fn make_live(&mut self, v: usize) {
        if !self.in_live[v] {
            self.in_live[v] = true;
            self.live.push(v as u32);
        }
    }

    /// One frame: `pressed` lists (surface vertex, blade, elastic pressure in Pa) of the tool rows this frame;
    /// `ratios` each blade's relaxation of its force (1 without relaxation); `time_s` the frame's end.
    pub fn step(&mut self, pressed: &[(u32, u16, f64)], ratios: Option<&[f64]>, time_s: f64) {
        for &v in &self.live {
            self.pressure[v as usize] = 0.0;
        }
        for &(v, blade, pa) in pressed {
            let v = v as usize;
            if v >= self.pressure.len() || !(pa.is_finite() && pa > 0.0) {
                continue;
            }
            let ratio = ratios.and_then(|r| r.get(usize::from(blade)).copied()).unwrap_or(1.0);
            self.make_live(v);
            self.pressure[v] += pa * ratio / PASCALS_PER_MMHG;
            self.owner[v] = blade;
        }
        let recovery = (-self.dt_s / self.model.recovery_tau_s).exp();
        let map = self.model.mean_arterial_pressure_mmhg;
        let frame = &mut self.frame;
        frame.area_over_m2 = [0.0; 3];
        frame.blade_area_at_risk_m2.fill(0.0);
        frame.max_dose_mmhg_s = 0.0;
        frame.longest_low_perfusion_s = 0.0;
        let mut k = 0;
        while k < self.live.len() {
            let v = self.live[k] as usize;
            let p = self.pressure[v];
            let rate = self.model.dose_rate_mmhg(p);
            if rate > 0.0 {
                self.dose[v] += rate * self.dt_s;
            } else {
                self.dose[v] *= recovery;
            }
            if p > 0.0 && map - p < RCPP_LIMIT_MMHG {
                self.low_perfusion[v] += self.dt_s;
            } else {
                self.low_perfusion[v] = 0.0;
            }
            if self.dose[v] < DOSE_GONE_MMHG_S && p == 0.0 {
                self.dose[v] = 0.0;
                self.in_live[v] = false;
                self.live.swap_remove(k);
                continue;
            }
            let risk = self.model.risk(self.dose[v] / 60.0);
            for (area, (level, _)) in frame.area_over_m2.iter_mut().zip(RISK_LEVELS) {
                if risk >= level {
                    *area += self.areas[v];
                }
            }
            if risk >= RISK_LEVELS[1].0 {
                if let Some(a) = frame.blade_area_at_risk_m2.get_mut(usize::from(self.owner[v])) {
                    *a += self.areas[v];
                }
            }
            frame.max_dose_mmhg_s = frame.max_dose_mmhg_s.max(self.dose[v]);
            frame.longest_low_perfusion_s = frame.longest_low_perfusion_s.max(self.low_perfusion[v]);
            k += 1;
        }
        frame.max_risk = if frame.max_dose_mmhg_s > 0.0 { self.model.risk(frame.max_dose_mmhg_s / 60.0) } else { 0.0 };
        if frame.max_dose_mmhg_s > self.peak_dose.0 {
            self.peak_dose = (frame.max_dose_mmhg_s, time_s);
        }
        for (first, area) in self.first_over_s.iter_mut().zip(frame.area_over_m2) {
            if first.is_none() && area > 0.0 {
                *first = Some(time_s);
            }
        }
        for (first, area) in self.first_at_risk_s.iter_mut().zip(&frame.blade_area_at_risk_m2) {
            if first.is_none() && *area > 0.0 {
                *first = Some(time_s);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_step_held_follows_the_relaxation_function_of_its_ramp() {
        // An elastic force ramped linearly from 0 to 1 over the first frame, then held: the exact hereditary
        // integral at t >= dt is g_inf + sum g (tau / dt) (1 - exp(-dt / tau)) exp(-(t - dt) / tau).
        let relaxation = Relaxation { terms: vec![(0.5, 2.0), (0.2, 30.0)], long_term: 0.3 };
        let dt = 0.01;
        let prony = Prony::new(&relaxation, dt);
        let mut states = vec![0.0; 2];
        let mut before = 0.0;
        for k in 1..=5000 {
            let relaxed = prony.step(&mut states, before, 1.0);
            before = 1.0;
            let t = k as f64 * dt;
            let exact = 0.3 + relaxation.terms.iter().map(|&(g, tau)| g * (tau / dt) * (1.0 - (-dt / tau).exp()) * (-(t - dt) / tau).exp()).sum::<f64>();
            assert!((relaxed - exact).abs() < 1e-12, "t = {t}: {relaxed} against {exact}");
        }
    }

    #[test]
    fn a_vertex_at_constant_pressure_takes_its_closed_form_dose() {
        let model = Ischemia::default();
        let mut stage = IschemiaStage::new(&model, 0.5, vec![1e-6; 3], 1);
        let pa = 25.0 * PASCALS_PER_MMHG;
        for k in 1..=1800 {
            stage.step(&[(1, 0, pa)], None, k as f64 * 0.5);
        }
        // 15 minutes at 25 mmHg: (25 - 10) mmHg for 900 s.
        assert!((stage.dose_mmhg_s()[1] - 15.0 * 900.0).abs() < 1e-6, "{}", stage.dose_mmhg_s()[1]);
        assert!((stage.risk(1) - 0.5).abs() < 1e-9, "{}", stage.risk(1));
        assert_eq!((stage.risk(0), stage.risk(2)), (0.0, 0.0));
        assert_eq!(stage.frame().blade_area_at_risk_m2, vec![1e-6]);
        // Released: the dose recovers with its time constant.
        let held = stage.dose_mmhg_s()[1];
        for k in 1..=600 {
            stage.step(&[], None, 900.0 + k as f64 * 0.5);
        }
        let expect = held * (-300.0_f64 / model.recovery_tau_s).exp();
        assert!((stage.dose_mmhg_s()[1] - expect).abs() < 1e-6 * held, "{} against {expect}", stage.dose_mmhg_s()[1]);
    }

    #[test]
    fn perfusion_under_ten_mmhg_is_timed_and_resets_on_release() {
        let model = Ischemia { mean_arterial_pressure_mmhg: 60.0, ..Ischemia::default() };
        let mut stage = IschemiaStage::new(&model, 1.0, vec![1e-6; 2], 1);
        for k in 1..=10 {
            stage.step(&[(0, 0, 55.0 * PASCALS_PER_MMHG)], None, k as f64);
        }
        assert_eq!(stage.frame().longest_low_perfusion_s, 10.0);
        stage.step(&[(0, 0, 40.0 * PASCALS_PER_MMHG)], None, 11.0);
        assert_eq!(stage.frame().longest_low_perfusion_s, 0.0);
    }
}
