//! A lint over `capi/src` that keeps the boundary free of undefined behaviour as entry points are
//! added: no exported function takes a type C can fill with a bit pattern Rust may not hold (an
//! enum, a `bool`, a reference), and slices of caller memory are made in one place only,
//! `src/args.rs`, each after its length was checked.

use std::path::Path;

/// Parameter types every bit pattern of which is a valid Rust value.
const ALLOWED: &[&str] = &["usize", "i32", "u32", "NbrdfParametricKindValue", "NbrdfDirections", "NbrdfRgbArrays"];

fn sources() -> Vec<(String, String)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| (p.file_name().unwrap().to_string_lossy().into_owned(), std::fs::read_to_string(&p).unwrap()))
        .collect();
    files.sort();
    files
}

/// The parameter list of every `extern "C" fn` in `source`: (function, [(name, type)]).
fn exported(source: &str) -> Vec<(String, Vec<(String, String)>)> {
    let mut found = Vec::new();
    for (at, _) in source.match_indices("extern \"C\" fn ") {
        let rest = &source[at + "extern \"C\" fn ".len()..];
        let open = rest.find('(').unwrap();
        let name = rest[..open].trim().to_string();
        let close = rest.find(')').unwrap();
        let params = rest[open + 1..close]
            .split(',')
            .map(str::trim)
            .filter(|p| !p.is_empty())
            .map(|p| {
                let (n, t) = p.split_once(':').unwrap_or_else(|| panic!("{name}: parameter {p:?}"));
                (n.trim().to_string(), t.split_whitespace().collect::<Vec<_>>().join(" "))
            })
            .collect();
        found.push((name, params));
    }
    found
}

#[test]
fn exported_functions_take_only_types_any_bit_pattern_fills() {
    let mut count = 0;
    for (file, source) in sources() {
        for (function, params) in exported(&source) {
            count += 1;
            for (name, ty) in params {
                let ok = ty.starts_with("*const ") || ty.starts_with("*mut ") || ALLOWED.contains(&ty.as_str());
                assert!(ok, "{file}: {function}({name}: {ty}): receive enums and flags as integers and check them (src/args.rs)");
            }
        }
    }
    assert!(count >= 20, "found only {count} exported functions: the lint no longer reads the sources");
}

#[test]
fn slices_of_caller_memory_are_made_only_after_their_length_is_checked() {
    for (file, source) in sources() {
        let lines: Vec<&str> = source.lines().filter(|l| !l.trim_start().starts_with("//")).collect();
        for (i, line) in lines.iter().enumerate() {
            if !line.contains("from_raw_parts") {
                continue;
            }
            assert_eq!(file, "args.rs", "{file}: `{}`: make slices of caller memory through src/args.rs", line.trim());
            // The function this line belongs to checks the range first.
            let start = lines[..i].iter().rposition(|l| l.contains("fn ")).unwrap();
            let body = lines[start..i].join("\n");
            assert!(
                body.contains("span(") || body.contains("out_floats("),
                "{file}: `{}` is not preceded by a span check in its function",
                line.trim()
            );
        }
    }
}
