use fissure::scenario::Scenario;
use fissure::sim::replay::{ReplayOptions, replay};
use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let mut sets: Vec<String> = args[3..].to_vec();
    sets.push("solver.cache_dir=None".into());
    let s = Scenario::load(&PathBuf::from(&args[1]), &sets).unwrap();
    let opts = ReplayOptions { out_dir: PathBuf::from("/tmp/dbg"), trajectory: Some(PathBuf::from(&args[2])), vtk: false };
    let sum = replay(&s, &opts, &AtomicBool::new(false), &mut |_, _, _, _| Ok(()), None).unwrap();
    println!("{}", serde_json::to_string(&sum).unwrap());
}
