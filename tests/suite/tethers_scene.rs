//! The phantom Sylvian scene with vessels and arachnoid bands: its careful trajectory (bands cut on the way in)
//! tears nothing, the rough one (no cut, wider, faster) tears bands, sharp dissection before spreading needs less
//! blade force than the same spread through the bands, and a run with tears replays bit for bit.

use std::path::{Path, PathBuf};
use std::sync::atomic::AtomicBool;

use fissure::scenario::Scenario;
use fissure::sim::metrics::Summary;
use fissure::sim::replay::{ReplayOptions, replay};

fn root() -> &'static Path {
    Path::new(env!("CARGO_MANIFEST_DIR"))
}

fn run(trajectory: &str, out: &Path) -> Summary {
    let scenario = Scenario::load(&root().join("config/sylvian_tethers.ron"), &["solver.cache_dir=None".into()]).expect("scene");
    let options = ReplayOptions { out_dir: out.to_path_buf(), trajectory: Some(root().join(trajectory)), vtk: false };
    replay(&scenario, &options, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).expect("replay")
}

fn peak(s: &Summary) -> f64 {
    s.spatulas.iter().map(|b| b.peak_force_n).fold(0.0, f64::max)
}

#[test]
fn careful_tears_nothing_rough_tears_bands_and_sharp_dissection_needs_less_force() {
    let dir = std::env::temp_dir().join(format!("fissure-tethers-{}", std::process::id()));
    let out = |name: &str| -> PathBuf { dir.join(name) };
    let careful = run("assets/trajectories/sylvian_tethers.csv", &out("careful"));
    assert!(careful.injuries.iter().all(|e| format!("{:?}", e.kind) == "Cut"), "the careful surgeon cuts, tears nothing: {:?}", careful.injuries);
    assert_eq!(careful.bands.map(|b| (b.cut, b.torn)), Some((8, 0)), "every band cut on the way in");
    assert!(careful.vessels.iter().all(|v| !v.torn && v.max_stretch < v.warning_stretch), "vessels under their warning stretch: {:?}", careful.vessels);
    assert!(careful.integrity.passed);

    let rough = run("assets/trajectories/sylvian_tethers_rough.csv", &out("rough"));
    let torn: Vec<_> = rough.injuries.iter().filter(|e| format!("{:?}", e.kind) == "Torn").collect();
    assert!(!torn.is_empty(), "the rough opening tears something");
    let bands = &Scenario::load(&root().join("config/sylvian_tethers.ron"), &[]).unwrap().tethers.bands;
    for e in &torn {
        let strength = bands.iter().find(|b| b.name == e.tether).map(|b| b.strength).expect("a band");
        assert!(e.tension_n >= strength, "{} tore at {} N, its strength {} N", e.tether, e.tension_n, strength);
    }

    // The careful motion without its cuts: blunt spreading through the uncut arachnoid.
    let blunt = run("assets/trajectories/paper_fig14_sylvian.csv", &out("blunt"));
    assert!(peak(&blunt) > 1.5 * peak(&careful), "blunt {} N against sharp {} N", peak(&blunt), peak(&careful));

    // Tears replay bit for bit.
    let again = run("assets/trajectories/sylvian_tethers_rough.csv", &out("rough_again"));
    assert_eq!(rough.final_state_hash, again.final_state_hash);
    assert_eq!(rough.injuries, again.injuries);
    let rows = |d: &str| std::fs::read_to_string(out(d).join("metrics.csv")).unwrap();
    // Every column but the timings (`_ms`) equal, byte for byte.
    let untimed = |text: String| -> Vec<String> {
        let header: Vec<String> = text.lines().next().unwrap().split(',').map(String::from).collect();
        text.lines().map(|l| l.split(',').zip(&header).filter(|(_, h)| !h.ends_with("_ms")).map(|(c, _)| c).collect::<Vec<_>>().join(",")).collect()
    };
    assert_eq!(untimed(rows("rough")), untimed(rows("rough_again")));
    let header = rows("rough").lines().next().unwrap().to_string();
    assert!(header.contains("superficial_Sylvian_vein_max_stretch") && header.ends_with("bands_intact,bands_torn,bands_cut,max_band_tension_n"), "{header}");
    std::fs::remove_dir_all(&dir).ok();
}
