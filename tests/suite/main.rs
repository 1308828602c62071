//! The integration tests, one module a file, in one test binary: each file
//! as its own binary linked the whole crate again (about sixty links a
//! build), and one binary runs tests of different files side by side.
//! Tests here share the process, so none may change what is process-wide
//! (environment, current directory, `fem::tuning`'s switches, the global
//! allocator): those live in their own binaries (`tests/fem_tuning.rs`,
//! `tests/hard_endurance.rs`), and the window tests, which measure what a
//! window does in real time, run one at a time in `tests/window/`.
//! A file added to this folder runs once it has its `mod` line below.

#[path = "../common/mod.rs"]
mod common;
#[path = "../fem_common/mod.rs"]
mod fem_common;

mod architecture_doc;
mod check_replay_agree;
mod cli;
mod cli_solve;
mod code_size;
mod collision_backends;
mod collision_paper_cases;
mod collision_stage;
mod collision_watertight;
mod debrief;
mod fem_background_stress;
mod fem_cache;
mod fem_contact;
mod fem_early_start;
mod fem_errors;
mod fem_factor_reuse;
mod fem_fast_path;
mod fem_skull;
mod fem_tethers;
mod fem_verification;
mod fem_working_rows;
mod golden_paper;
mod hard_entrances;
mod hard_fast_tools;
mod hard_geometry;
mod hard_material;
mod hard_penetration;
mod input_igtl;
mod input_mapping;
mod input_plus;
mod input_spacemouse;
mod interrupt;
mod layers;
mod mesh_io;
mod mesh_parsers_fuzz;
mod perf_page;
mod performance_doc;
mod phantom;
mod pipeline_block;
mod plot;
mod process_words;
mod readme_controls;
mod real_brain_meshes;
mod render_offscreen;
mod replay_determinism;
mod scenario;
mod scenario_devices;
mod scenario_parsers_never_panic;
mod screenshot;
mod study_preset;
mod study_quick;
mod substep_jitter;
mod tethers_scene;
mod tetrahedralize;
mod tissue_time;
