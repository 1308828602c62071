//! The quick study's motion on paper-9k (insert 30 mm, open 10 mm, close, withdraw), its mesh refined along the
//! motion to the blade's width over N edges as the study's `refine` knob refines it: each frame's force and
//! contact vertices, and with `--nodes` every node the blade pushes, in the blade's frame (along from the handle
//! to the tip, across its width, through its thickness: the front face at +0.5 mm, the back face at -0.5 mm).
//!
//! `cargo run --release --example study_contacts -- [EDGES_ACROSS] [--nodes]` (default 4).

use fissure::geometry::Pose;
use fissure::math::Vec3;
use fissure::sim::{BuildOptions, FrameInput, Pipeline};
use fissure::study::motion::Motion;
use fissure::study::plan::{MeshChoice, Settings, base_settings};
use fissure::study::runner::{MeshStore, configure};

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let across: f64 = args.iter().find_map(|a| a.parse().ok()).unwrap_or(4.0);
    let show_nodes = args.iter().any(|a| a == "--nodes");
    let scene = fissure::study::load_scene(None)?;
    let (mut meshes, motion) = (MeshStore::default(), Motion::default());
    let choice = MeshChoice::Phantom("paper-9k".into());
    let settings = Settings { refine: Some(across), ..base_settings(choice.clone()) };
    let configured = configure(&scene, &settings, &motion, meshes.get(&choice, &scene)?, None);
    let mesh = meshes.refined(&choice, across, &configured, &motion)?.clone();
    let initial: Vec<Pose> = configured.spatulas.iter().map(|s| s.initial_pose).collect();
    let frames = motion.frames(&initial, configured.spatulas[0].shape.thickness, settings.speed);
    let stride = (frames.len() / 200).max(1);
    let expected_poses = frames.iter().step_by(stride).map(|f| f.poses.clone()).collect();
    let (mut pipeline, mut state) = Pipeline::build_with_mesh(&configured, mesh, BuildOptions { expected_poses, ..BuildOptions::default() })?;
    let mut surface_index = vec![usize::MAX; pipeline.mesh().node_count()];
    for (i, &n) in pipeline.surface().vertices.iter().enumerate() {
        surface_index[n as usize] = i;
    }
    println!("{across} edges across: {} nodes", pipeline.mesh().node_count());
    println!("phase path_mm force_x_n force_y_n force_z_n contact_vertices");
    let mut input = FrameInput::default();
    for f in &frames {
        input.poses.clear();
        input.poses.extend(f.poses.iter().map(|p| Some(*p)));
        let r = pipeline.step(&mut state, &input)?;
        let force: Vec3 = r.spatulas.iter().map(|s| s.force).sum();
        let path_mm = motion.path_position_nm(f.key) as f64 * 1e-6;
        println!("{} {path_mm:.2} {:+.5} {:+.5} {:+.5} {}", f.key.phase, force.x, force.y, force.z, r.spatulas[0].contact_vertices);
        if !show_nodes {
            continue;
        }
        let pose = f.poses[0];
        for &(node, on_tissue) in pipeline.solver().last_forces() {
            let Some(&s) = surface_index.get(node as usize).filter(|&&s| s != usize::MAX && on_tissue.norm() > 0.0) else { continue };
            let at = pose.rotation.inverse() * (pipeline.mesh().positions[node as usize] + state.surface_displacement[s] - pose.position) * 1e3;
            let push = pose.rotation.inverse() * on_tissue;
            println!("    node {node}: along {:.2} across {:+.2} through {:+.3} mm; push on the tissue {:+.5} N through the blade", at.x, at.y, at.z, push.z);
        }
    }
    Ok(())
}
