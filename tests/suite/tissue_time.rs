//! Tissue over time on the paper's V valley (a blade wedged between two walls, then held): the relaxed force is the
//! hereditary integral of the elastic one to 1e-9, a held force halves in 6.6 minutes, the tissue's deformation
//! (and so the final state) is the elastic one, held frames are not solved again, and ischemia is dosed and
//! reported; both effects replay bit for bit.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use fissure::scenario::Scenario;
use fissure::sim::metrics::Summary;
use fissure::sim::replay::{ReplayOptions, replay};

const PLAIN: &str = "effects=[Collision, Culling, ForceOutput, ContactPressure]";
const OVER_TIME: &str = "effects=[Collision, Culling, ForceOutput, ContactPressure, Relaxation, Ischemia]";

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn run(effects: &str, duration_s: f64, out: &Path, extra: &[&str]) -> Summary {
    let mut sets = vec![effects.to_string(), format!("duration_s={duration_s}")];
    sets.extend(extra.iter().map(|s| s.to_string()));
    let scenario = Scenario::load(&root().join("config/v_valley.ron"), &sets).expect("scene");
    let options = ReplayOptions { out_dir: out.to_path_buf(), trajectory: None, vtk: false };
    replay(&scenario, &options, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay")
}

/// `(time_s, [force_x, force_y, force_z])` of the blade per frame.
fn forces(dir: &Path) -> Vec<(f64, [f64; 3])> {
    let text = std::fs::read_to_string(dir.join("metrics.csv")).expect("metrics.csv");
    let mut lines = text.lines();
    let header: Vec<&str> = lines.next().unwrap().split(',').collect();
    let col = |name: &str| header.iter().position(|h| *h == name).unwrap_or_else(|| panic!("no {name} in {header:?}"));
    let (t, x, y, z) = (col("time_s"), col("spatula_force_x_n"), col("spatula_force_y_n"), col("spatula_force_z_n"));
    lines
        .map(|l| {
            let f: Vec<f64> = l.split(',').map(|c| c.parse().unwrap_or(f64::NAN)).collect();
            (f[t], [f[x], f[y], f[z]])
        })
        .collect()
}

/// The default relaxation function's terms.
fn prony() -> (f64, Vec<(f64, f64)>) {
    let r = fissure::scenario::Relaxation::default();
    (r.long_term, r.terms)
}

/// The hereditary integral of a force linear in time between frames (0 at t = 0), in closed form at frame `n`:
/// `g_inf F(t_n) + sum_i g_i sum_k (dF_k / dt) tau_i (exp(-(t_n - t_k) / tau_i) - exp(-(t_n - t_k-1) / tau_i))`.
fn hereditary(elastic: &[(f64, [f64; 3])], n: usize) -> [f64; 3] {
    let (long_term, terms) = prony();
    let tn = elastic[n].0;
    let mut out = elastic[n].1.map(|f| long_term * f);
    for k in 0..=n {
        let (t0, f0) = if k == 0 { (0.0, [0.0; 3]) } else { elastic[k - 1] };
        let (t1, f1) = elastic[k];
        for &(g, tau) in &terms {
            let weight = g * tau * ((-(tn - t1) / tau).exp() - (-(tn - t0) / tau).exp()) / (t1 - t0);
            for a in 0..3 {
                out[a] += weight * (f1[a] - f0[a]);
            }
        }
    }
    out
}

#[test]
fn a_held_indentation_relaxes_as_the_hereditary_integral_and_halves_in_six_point_six_minutes() {
    let dir = std::env::temp_dir().join(format!("fissure-tissue-time-{}", std::process::id()));
    let out = |name: &str| -> PathBuf { dir.join(name) };
    let duration = 403.0;
    let elastic_run = run(PLAIN, duration, &out("elastic"), &[]);
    let relaxed_run = run(OVER_TIME, duration, &out("relaxed"), &[]);
    let (elastic, relaxed) = (forces(&out("elastic")), forces(&out("relaxed")));
    assert_eq!(elastic.len(), relaxed.len());
    // The deformation is the elastic one: the same final state, bit for bit, though held frames were not solved again.
    assert_eq!(elastic_run.final_state_hash, relaxed_run.final_state_hash);
    let peak = elastic.iter().map(|(_, f)| f.iter().map(|c| c * c).sum::<f64>().sqrt()).fold(0.0, f64::max);
    assert!(peak > 1e-3, "the blade presses the walls: {peak} N");
    let contact = elastic.iter().position(|(_, f)| f.iter().any(|c| *c != 0.0)).expect("contact");
    assert!(elastic[contact..].iter().all(|(_, f)| f.iter().any(|c| *c != 0.0)), "the blade never leaves the walls once in");
    for n in (0..elastic.len()).step_by(97).chain([elastic.len() - 1]) {
        let exact = hereditary(&elastic, n);
        for a in 0..3 {
            assert!((relaxed[n].1[a] - exact[a]).abs() <= 1e-9 * peak, "t = {} s, axis {a}: {} N against {} N", relaxed[n].0, relaxed[n].1[a], exact[a]);
        }
    }
    // The trajectory holds from 3 s: 6.6 minutes later the force is half (the ramp's own relaxation is small).
    let at = |t: f64| relaxed.iter().find(|(s, _)| (*s - t).abs() < 1e-6).map(|(_, f)| f.iter().map(|c| c * c).sum::<f64>().sqrt()).expect("a frame");
    let ratio = at(3.0 + 396.0) / at(3.0);
    assert!((ratio - 0.5).abs() < 0.025, "the held force after 6.6 minutes is {ratio} of its value at the hold's start");

    // Ischemia: dosed where the blade presses, reported, and nothing without the effect.
    let i = relaxed_run.ischemia.as_ref().expect("summary.json has ischemia");
    assert!(i.max_dose_mmhg_min > 0.0 && i.max_dose_time_s > 3.0, "{i:?}");
    assert!(i.levels.windows(2).all(|w| w[0].max_area_mm2 >= w[1].max_area_mm2), "{:?}", i.levels);
    assert!(elastic_run.ischemia.is_none());
    // Held frames are not solved again (0 sub-steps), once two held frames agreed; every frame of the plain run is.
    let unsolved = |d: &str| -> usize {
        let text = std::fs::read_to_string(out(d).join("metrics.csv")).unwrap();
        let col = text.lines().next().unwrap().split(',').position(|h| h == "substeps").expect("a substeps column");
        text.lines().skip(1).filter(|l| l.split(',').nth(col) == Some("0")).count()
    };
    assert_eq!(unsolved("elastic"), 0);
    assert!(unsolved("relaxed") > relaxed.len() * 9 / 10, "{} of {} frames not solved again", unsolved("relaxed"), relaxed.len());

    // Bit for bit again.
    let again = run(OVER_TIME, duration, &out("again"), &[]);
    assert_eq!(again.final_state_hash, relaxed_run.final_state_hash);
    let untimed = |d: &str| -> Vec<String> {
        let text = std::fs::read_to_string(out(d).join("metrics.csv")).unwrap();
        let header: Vec<String> = text.lines().next().unwrap().split(',').map(String::from).collect();
        text.lines().map(|l| l.split(',').zip(&header).filter(|(_, h)| !h.ends_with("_ms")).map(|(c, _)| c).collect::<Vec<_>>().join(",")).collect()
    };
    assert_eq!(untimed("relaxed"), untimed("again"));
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn hypotension_doses_more_under_the_same_blade() {
    let dir = std::env::temp_dir().join(format!("fissure-tissue-map-{}", std::process::id()));
    let normal = run(OVER_TIME, 60.0, &dir.join("normal"), &[]);
    let low = run(OVER_TIME, 60.0, &dir.join("low"), &["ischemia.mean_arterial_pressure_mmhg=60.0"]);
    let (a, b) = (normal.ischemia.unwrap(), low.ischemia.unwrap());
    assert!(b.max_dose_mmhg_min > a.max_dose_mmhg_min + 29.0 * 0.9, "30 mmHg of hypotension for about a minute: {} against {}", b.max_dose_mmhg_min, a.max_dose_mmhg_min);
    assert_eq!(b.mean_arterial_pressure_mmhg, 60.0);
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn the_effects_need_what_they_act_on() {
    let load = |effects: &str| Scenario::load(&root().join("config/v_valley.ron"), &[effects.to_string()]);
    let e = load("effects=[Collision, ForceOutput, Ischemia]").expect_err("ischemia without pressure");
    assert!(e.to_string().contains("Ischemia needs the ContactPressure effect"), "{e}");
    let e = load("effects=[Collision, Relaxation]").expect_err("relaxation without forces");
    assert!(e.to_string().contains("Relaxation needs ForceOutput or ContactPressure"), "{e}");
    let e = Scenario::load(&root().join("config/v_valley.ron"), &[OVER_TIME.into(), "relaxation.terms=[(weight: 0.6, tau_s: 10.0), (weight: 0.5, tau_s: 20.0)]".into()]).expect_err("weights over 1");
    assert!(e.to_string().contains("relaxation.terms"), "{e}");
    let e = Scenario::load(&root().join("config/v_valley.ron"), &[OVER_TIME.into(), "ischemia.mean_arterial_pressure_mmhg=-5.0".into()]).expect_err("a negative MAP");
    assert!(e.to_string().contains("ischemia.mean_arterial_pressure_mmhg"), "{e}");
    let plain = load(PLAIN).expect("plain");
    assert!(plain.tissue_time.relaxation.is_none() && plain.tissue_time.ischemia.is_none(), "a scene without the effects builds nothing of them");
}
