//! The layers of ARCHITECTURE.md's code map, checked on the source: every
//! `crate::<module>` a file of `src/` names in code (a `use`, grouped or not,
//! or a path inline; comments, strings and `#[cfg(test)]` items aside) is
//! allowed by the map, and the simulation core names no windowing, UI or
//! device crate; and the files of `src/sim/` use each other in one order, so
//! that no circle of imports forms among them. A failure lists each forbidden
//! import as `file:line`.

use crate::common::source::{code_only, line_of, paths_after, read, rust_files, without_tests};

/// The code map's layers, bottom up: a module uses only modules of lower
/// layers, or its own.
const LAYERS: [(&str, u8); 19] = [
    ("math", 1),
    ("fsio", 1),
    ("meminfo", 1),
    ("par", 1),
    ("geometry", 2),
    ("mesh", 2),
    ("linalg", 2),
    ("scenario", 3),
    ("collision", 3),
    ("fem", 3),
    ("sim", 4),
    ("study", 5),
    ("perf", 5),
    ("input", 5),
    ("render", 5),
    ("ui", 6),
    ("debrief", 6),
    ("app", 7),
    ("cli", 8),
];

/// Modules narrower than their layer: each uses only the modules listed.
const ONLY: [(&str, &[&str]); 3] = [
    ("input", &["math", "fsio", "meminfo", "geometry", "mesh", "linalg"]),
    ("render", &["math", "fsio", "meminfo", "geometry", "mesh", "linalg"]),
    ("ui", &["render"]),
];

/// What the map allows beyond the layers: (module, path prefix it may name).
/// The panel and the infarct risk legend print the tissue-time effect's
/// published thresholds where the scenario defines them.
const ALSO: [(&str, &str); 2] = [("render", "scenario::tissue_time"), ("ui", "scenario::tissue_time")];

/// Pairs of one layer that never use each other (`sim` is where they meet).
const APART: [(&str, &str); 1] = [("fem", "collision")];

/// The simulation core: the window and the headless replay drive it alike.
const CORE: [&str; 6] = ["fem", "collision", "sim", "mesh", "scenario", "geometry"];

/// Crates the core never names: the window, the panel, the devices.
const NOT_IN_CORE: [&str; 5] = ["winit", "egui", "egui_winit", "egui_wgpu", "gilrs"];

fn layer(module: &str) -> Option<u8> {
    LAYERS.iter().find(|(m, _)| *m == module).map(|&(_, l)| l)
}

/// The top-level module a file of `src/` belongs to; the binary's files are `cli`.
fn module_of(file: &str) -> Option<&str> {
    let rest = file.strip_prefix("src/")?;
    match rest {
        "lib.rs" => None,
        "main.rs" => Some("cli"),
        _ => Some(rest.split('/').next()?.trim_end_matches(".rs")),
    }
}

/// Why `from` may not name `crate::<path>`, or `None` when the map allows it.
fn forbidden(from: &str, path: &str) -> Option<String> {
    let to = path.split("::").next().unwrap_or(path);
    if to == from {
        return None;
    }
    if ALSO.iter().any(|&(m, prefix)| m == from && (path == prefix || path.starts_with(&format!("{prefix}::")))) {
        return None;
    }
    let (Some(from_layer), Some(to_layer)) = (layer(from), layer(to)) else {
        return Some(format!("`{to}` is not in the code map's layers"));
    };
    if APART.iter().any(|&(a, b)| (a, b) == (from, to) || (b, a) == (from, to)) {
        return Some(format!("`{from}` and `{to}` never use each other"));
    }
    if let Some((_, allowed)) = ONLY.iter().find(|(m, _)| *m == from) {
        return (!allowed.contains(&to)).then(|| format!("`{from}` uses only {}", allowed.join(", ")));
    }
    (to_layer >= from_layer).then(|| format!("`{from}` (layer {from_layer}) uses only lower layers; `{to}` is layer {to_layer}"))
}

/// Each forbidden name in one file's text, as `file:line: ...`.
fn violations(file: &str, text: &str) -> Vec<String> {
    let Some(module) = module_of(file) else { return Vec::new() };
    let mut out = Vec::new();
    if layer(module).is_none() {
        out.push(format!("{file}: module `{module}` is not in the code map's layers (add it to ARCHITECTURE.md and this test)"));
        return out;
    }
    let code = without_tests(code_only(text));
    // The binary's `crate::` is the binary; it may use the whole library.
    if module != "cli" {
        for (at, path) in paths_after(&code, "crate") {
            if let Some(why) = forbidden(module, &path) {
                out.push(format!("{file}:{}: crate::{path}: {why}", line_of(&code, at)));
            }
        }
    }
    if CORE.contains(&module) {
        for name in NOT_IN_CORE {
            for (at, path) in paths_after(&code, name) {
                out.push(format!("{file}:{}: {name}::{path}: the simulation core names no window, UI or device crate", line_of(&code, at)));
            }
        }
    }
    out
}

/// The files of `src/sim/`, bottom up: each uses only those before it (its
/// root, `mod.rs`, re-exports from any). The shared error, the sub-step count,
/// the rest positions' grid and the stages the frame runs, the frame's report, the pipeline, the poses a run plays, the
/// scene's mesh, the preflight that checks it, the build, the replay.
const SIM_ORDER: [&str; 18] = [
    "error",
    "substeps",
    "rest_grid",
    "surface_sync",
    "barrier",
    "monitor",
    "pose_filter",
    "tethers",
    "report",
    "tissue_time",
    "contact",
    "metrics",
    "pipeline",
    "poses",
    "scene_mesh",
    "preflight",
    "build",
    "replay",
];

/// Each use in a file of `src/sim/` of a file of `src/sim/` that is not
/// before it in [`SIM_ORDER`], as `file:line: ...`.
fn sim_order_violations(file: &str, text: &str) -> Vec<String> {
    let Some(name) = file.strip_prefix("src/sim/").and_then(|f| f.strip_suffix(".rs")) else { return Vec::new() };
    if name == "mod" {
        return Vec::new();
    }
    let Some(own) = SIM_ORDER.iter().position(|&f| f == name) else {
        return vec![format!("{file}: not in the order of src/sim/'s files (place it in SIM_ORDER, after the files it uses)")];
    };
    let code = without_tests(code_only(text));
    let mut used: Vec<(usize, String)> = paths_after(&code, "super").into_iter().filter(|(_, p)| p != "super" && !p.starts_with("super::")).collect();
    used.extend(paths_after(&code, "crate").into_iter().filter_map(|(at, p)| p.strip_prefix("sim::").map(|p| (at, p.to_string()))));
    let mut out = Vec::new();
    for (at, path) in used {
        let sibling = path.split("::").next().unwrap_or(&path);
        let line = line_of(&code, at);
        match SIM_ORDER.iter().position(|&f| f == sibling) {
            Some(k) if k < own => {}
            Some(_) if sibling == name => {}
            Some(_) => out.push(format!("{file}:{line}: sim::{path}: `{name}` comes before `{sibling}` in src/sim/'s order, so it may not use it")),
            None => out.push(format!("{file}:{line}: sim::{path}: name the file it is in (the order of src/sim/'s files is checked by file)")),
        }
    }
    out
}

#[test]
fn the_files_of_sim_use_only_those_before_them() {
    let found: Vec<String> = rust_files().iter().flat_map(|f| sim_order_violations(f, &read(f))).collect();
    assert!(found.is_empty(), "imports against the order of src/sim/'s files:\n{}", found.join("\n"));
}

#[test]
fn a_use_against_sims_order_is_named() {
    let text = "use super::report::StageId;\nuse super::{build::BuildOptions, error::BuildError};\nfn f() { crate::sim::replay::replay(); super::Pipeline::new(); }\n#[cfg(test)]\nmod tests { use super::super::replay::replay; }\n";
    let found = sim_order_violations("src/sim/pipeline.rs", text);
    assert_eq!(found.len(), 3, "{found:?}");
    assert!(found[0].starts_with("src/sim/pipeline.rs:2: sim::build::BuildOptions"), "{found:?}");
    assert!(found[1].starts_with("src/sim/pipeline.rs:3: sim::Pipeline::new"), "{found:?}");
    assert!(found[2].starts_with("src/sim/pipeline.rs:3: sim::replay::replay"), "{found:?}");
    assert_eq!(sim_order_violations("src/sim/new_stage.rs", "").len(), 1);
}

#[test]
fn every_import_is_allowed_by_the_code_map() {
    let files = rust_files();
    assert!(files.len() > 100, "the source tree is read ({} files)", files.len());
    let found: Vec<String> = files.iter().flat_map(|f| violations(f, &read(f))).collect();
    assert!(found.is_empty(), "imports the code map in ARCHITECTURE.md forbids:\n{}", found.join("\n"));
}

#[test]
fn every_module_of_the_library_has_a_layer() {
    let lib = read("src/lib.rs");
    let unplaced: Vec<&str> = lib.lines().filter_map(|l| l.trim().strip_prefix("pub mod ")).map(|m| m.trim_end_matches(';')).filter(|m| layer(m).is_none()).collect();
    assert!(unplaced.is_empty(), "modules of src/lib.rs with no layer: {unplaced:?}");
}

#[test]
fn a_forbidden_import_is_named_with_its_line() {
    let text = "//! crate::app in a comment is no import\nuse crate::{math::Vec3, render::Camera};\nfn f() { crate::fem::solve(); }\n#[cfg(test)]\nmod tests { use crate::app::Window; }\n";
    let found = violations("src/collision/x.rs", text);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(found[0].starts_with("src/collision/x.rs:2: crate::render::Camera"), "{found:?}");
    assert!(found[1].starts_with("src/collision/x.rs:3: crate::fem::solve"), "{found:?}");
    let found = violations("src/sim/x.rs", "use winit::event::Event;\n");
    assert_eq!(found.len(), 1, "{found:?}");
    let found = violations("src/render/x.rs", "use crate::scenario::tissue_time::RISK_LEVELS;\nuse crate::scenario::Scenario;\n");
    assert_eq!(found.len(), 1, "{found:?}");
    assert!(found[0].starts_with("src/render/x.rs:2:"), "{found:?}");
    assert!(violations("src/ui/x.rs", "use crate::geometry::Pose;\n").len() == 1);
    assert!(violations("src/app/x.rs", "use crate::{ui, render, sim, debrief};\n").is_empty());
    assert!(violations("src/newthing.rs", "").len() == 1);
}

#[test]
fn comments_and_literals_are_blanked_in_place() {
    let text = "let a = \"crate::x\"; // crate::y\n/* crate::z /* nested */ */ let c = '\"'; let r = r#\"crate::w\"#; fn f<'a>(x: &'a str) {}";
    let code = String::from_utf8(code_only(text)).unwrap();
    assert_eq!(code.len(), text.len());
    assert!(!code.contains("crate::"), "{code}");
    assert!(code.contains("fn f<'a>(x: &'a str) {}"), "{code}");
    assert_eq!(code.lines().count(), 2);
    // byte literals too: an unmatched `b'{'` must not open a block for the function-size count
    let bytes = String::from_utf8(code_only("match c { b'{' => 1, b'\\'' => 2, _ => 3 } sub'x'")).unwrap();
    assert_eq!(bytes, "match c { b' ' => 1, b'  ' => 2, _ => 3 } sub'x'");
}

#[test]
fn grouped_inline_and_renamed_paths_are_read() {
    let text = "use crate::{a::b, c::{d, e::*}};\nuse crate::f as g;\nlet x = crate::h::i(1) + $crate::j::k + fissure_crate::l;";
    let code = code_only(text);
    let paths: Vec<(usize, String)> = paths_after(&code, "crate").into_iter().map(|(at, p)| (line_of(&code, at), p)).collect();
    let want = [(1, "a::b"), (1, "c::d"), (1, "c::e"), (2, "f"), (3, "h::i")];
    assert_eq!(paths, want.map(|(l, p)| (l, p.to_string())));
}

#[test]
fn test_items_are_removed() {
    let text = "use crate::a;\n#[cfg(test)]\nuse crate::b;\n#[cfg(test)]\n#[allow(unused)]\nmod tests {\n    fn t() { crate::c::d(); }\n}\nfn e() { crate::f::g(); }";
    let code = without_tests(code_only(text));
    let paths: Vec<String> = paths_after(&code, "crate").into_iter().map(|(_, p)| p).collect();
    assert_eq!(paths, ["a", "f::g"]);
}
