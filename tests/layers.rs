//! The core's layering rule (docs/architecture.md): dependencies point down. `kernels` (the dense-layer
//! kernels) imports no other module of the crate, and the top-level modules import each other without
//! a cycle (`file` and `model` included).
//!
//! What is scanned: every `src/**/*.rs` file, counted for its top-level module (`src/NAME.rs` or
//! `src/NAME/`; `lib.rs` is the crate root, not a module). A reference is a path `crate::NAME…` or a
//! group `crate::{NAME::…, …}` naming a top-level module, or an item the root re-exports from one
//! (`pub use model::{Model, …}` in lib.rs counts as `model`). Skipped: comment lines (trimmed start
//! `//`, doc comments and their examples included) and `#[cfg(…test…)] mod tests { … }` blocks (their
//! braces counted). Module roots reach their siblings through `crate::` only (never `super::`).
//!
//! And the core's edge: meshes, renderers and images are the `nbrdf-scene` crate's (scene/), neither
//! modules of the core nor crates it depends on.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

type Graph = BTreeMap<String, BTreeSet<String>>;

fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let p = entry.unwrap().path();
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The source without comment lines and test modules.
fn code(text: &str) -> String {
    let (mut out, mut cfg_test, mut depth) = (String::new(), false, 0i64);
    for line in text.lines().map(str::trim).filter(|l| !l.starts_with("//")) {
        if depth > 0 || (cfg_test && line.contains("mod tests")) {
            depth += line.matches('{').count() as i64 - line.matches('}').count() as i64;
        } else {
            out.extend([line, "\n"]);
        }
        cfg_test = line.starts_with("#[cfg(") && line.contains("test");
    }
    out
}

/// The first name of each `crate::` path: `crate::a::b` gives `a`, `crate::{a::x, B}` gives `a`, `B`.
fn crate_names(code: &str) -> impl Iterator<Item = String> + '_ {
    code.split("crate::").skip(1).flat_map(|rest| {
        let items: Vec<&str> = match rest.strip_prefix('{') {
            Some(group) => group.split('}').next().unwrap().split(',').collect(),
            None => vec![rest],
        };
        items.into_iter().map(|i| i.trim().chars().take_while(|c| c.is_alphanumeric() || *c == '_').collect())
    })
}

/// Top-level module -> the other top-level modules it references.
fn graph() -> Graph {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    sources(&src, &mut files);
    // `src/NAME.rs` and everything under `src/NAME/` belong to module NAME.
    let module = |p: &PathBuf| {
        let first = p.strip_prefix(&src).unwrap().iter().next().unwrap();
        first.to_str().unwrap().trim_end_matches(".rs").to_string()
    };
    // Which module a name after `crate::` stands for: the modules themselves, and below their re-exports.
    let mut owner: BTreeMap<String, String> =
        files.iter().map(module).filter(|m| m != "lib").map(|m| (m.clone(), m)).collect();
    // Items the crate root re-exports from a module: `pub use model::{Model, Prepared};`.
    for line in std::fs::read_to_string(src.join("lib.rs")).unwrap().lines() {
        let Some((m, items)) = line.trim().strip_prefix("pub use ").and_then(|u| u.split_once("::")) else { continue };
        if owner.contains_key(m) {
            for item in items.trim_matches(|c| "{};".contains(c)).split(',') {
                owner.insert(item.trim().to_string(), m.to_string());
            }
        }
    }
    let mut g: Graph = owner.values().map(|m| (m.clone(), BTreeSet::new())).collect();
    for f in files.iter().filter(|f| module(f) != "lib") {
        let (from, code) = (module(f), code(&std::fs::read_to_string(f).unwrap()));
        let to = crate_names(&code).filter_map(|n| owner.get(&n).cloned()).filter(|m| *m != from);
        g.get_mut(&from).unwrap().extend(to);
    }
    g
}

/// A cycle through `at` (depth first), as the modules along it.
fn cycle(g: &Graph, at: &str, path: &mut Vec<String>, done: &mut BTreeSet<String>) -> Option<Vec<String>> {
    if let Some(i) = path.iter().position(|m| m == at) {
        return Some([&path[i..], &[at.to_string()]].concat());
    }
    if !done.insert(at.to_string()) {
        return None;
    }
    path.push(at.to_string());
    let found = g[at].iter().find_map(|next| cycle(g, next, path, done));
    path.pop();
    found
}

#[test]
fn kernels_import_no_other_module_of_the_crate() {
    let g = graph();
    assert!(g["model"].contains("file") && g["model"].contains("mlp"), "the scan finds known imports: {g:?}");
    assert!(g["kernels"].is_empty(), "kernels imports {:?}; it must sit below every other module", g["kernels"]);
}

#[test]
fn the_top_level_modules_import_each_other_without_a_cycle() {
    let g = graph();
    let mut done = BTreeSet::new();
    for m in g.keys() {
        if let Some(c) = cycle(&g, m, &mut Vec::new(), &mut done) {
            let lines: Vec<String> = g.iter().map(|(m, to)| format!("  {m} -> {to:?}")).collect();
            panic!("import cycle: {}\nmodule graph:\n{}", c.join(" -> "), lines.join("\n"));
        }
    }
}

/// The names of the core's `[dependencies]` (Cargo.toml), whatever feature turns them on.
fn core_dependencies() -> BTreeSet<String> {
    let manifest = std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("Cargo.toml")).unwrap();
    let section = manifest.split("\n[dependencies]\n").nth(1).expect("a [dependencies] table");
    let body = section.split("\n[").next().unwrap();
    body.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty() && !l.starts_with('#'))
        .filter_map(|l| l.split_once('=').map(|(name, _)| name.trim().to_string()))
        .collect()
}

/// The core is what a renderer links: meshes, the BVH, images, threads, random numbers and temporary
/// files are the `nbrdf-scene` crate's (scene/), never dependencies of the core under any feature, and
/// its `scene`, `pathtrace` and `image` modules are that crate's too.
#[test]
fn the_core_holds_no_scene_and_depends_on_no_scene_crate() {
    let deps = core_dependencies();
    assert!(deps.contains("glam") && deps.contains("postcard"), "the scan finds the core's dependencies: {deps:?}");
    let scene_crates = ["tobj", "ply-rs-bw", "obvhs", "obvhs-glam", "exr", "image", "rayon", "tempfile", "rand",
                        "rand_chacha", "rand_distr", "bvh", "nalgebra"];
    let found: Vec<&str> = scene_crates.into_iter().filter(|c| deps.contains(*c)).collect();
    assert!(found.is_empty(), "the core depends on {found:?}, which belong to nbrdf-scene (scene/Cargo.toml)");
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    for m in ["scene", "pathtrace", "image"] {
        assert!(!src.join(m).exists() && !src.join(format!("{m}.rs")).exists(), "src/{m} is nbrdf-scene's (scene/src/{m})");
    }
}
