//! Every model kind exports, and naga parses and validates the WGSL and writes GLSL, HLSL, MSL and
//! SPIR-V from it; where glslangValidator and spirv-val are installed they check the GLSL and SPIR-V
//! too (SKIPPED is printed where they are not). No GPU needed: seconds.

mod common;

use std::process::Command;

use nbrdf_shader::{export, translate, Cost, Error, Lang, Options, Storage, DEFAULT_BUFFER};

/// Runs `tool args.. file` on `bytes` written to a temporary file with `extension`; `None` when the
/// tool is not installed.
fn external_check(tool: &str, args: &[&str], bytes: &[u8], extension: &str) -> Option<Result<(), String>> {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("shader.{extension}"));
    std::fs::write(&path, bytes).unwrap();
    let out = match Command::new(tool).args(args).arg(&path).output() {
        Ok(out) => out,
        Err(_) => return None,
    };
    Some(if out.status.success() {
        Ok(())
    } else {
        Err(format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr)))
    })
}

#[test]
fn every_model_kind_exports_and_translates_to_every_language() {
    let models = common::all_models();
    let (mut glslang, mut spirv_val) = (0, 0);
    for m in &models {
        for storage in [Storage::Inline, DEFAULT_BUFFER] {
            let options = Options { storage: Some(storage), ..Options::default() };
            let shader = export(&m.name, &m.bytes, &options).unwrap_or_else(|e| panic!("{}: {e}", m.name));
            assert_eq!(shader.storage, storage);
            assert_eq!(shader.weights.is_empty(), storage == Storage::Inline);
            for lang in Lang::ALL {
                let out = translate(&shader, lang).unwrap_or_else(|e| panic!("{} {storage:?} {lang:?}: {e}", m.name));
                let check = match lang {
                    Lang::Glsl => external_check("glslangValidator", &[], &out, "comp").inspect(|_| glslang += 1),
                    Lang::Spirv => external_check("spirv-val", &[], &out, "spv").inspect(|_| spirv_val += 1),
                    _ => None,
                };
                if let Some(Err(e)) = check {
                    panic!("{} {storage:?} {lang:?} rejected:\n{e}", m.name);
                }
            }
        }
    }
    for (tool, n) in [("glslangValidator", glslang), ("spirv-val", spirv_val)] {
        if n == 0 {
            println!("SKIPPED: {tool} is not installed (apt-get install glslang-tools spirv-tools); naga's validation ran");
        } else {
            println!("{tool} accepted {n} shaders");
        }
    }
}

#[test]
fn nbrdf_json_networks_export_with_a_fitted_proxy() {
    let shader = export("random.json", &common::json_network(3), &Options::default()).unwrap();
    assert!(shader.description.contains("6-21-21-3"), "{}", shader.description);
    assert_eq!(shader.position_len, 0);
    assert!(shader.wgsl.contains("fn nbrdf_sample(wo_in: vec3<f32>, u: vec3<f32>) -> NbrdfSample"));
    for lang in Lang::ALL {
        translate(&shader, lang).unwrap();
    }
}

#[test]
fn the_entry_points_take_the_position_only_where_the_model_has_one() {
    for m in common::all_models() {
        let shader = export(&m.name, &m.bytes, &Options::default()).unwrap();
        let p = shader.position_len;
        let sig = if p > 0 { format!("wo: vec3<f32>, p: array<f32, {p}>) -> vec3<f32>") } else { "wo: vec3<f32>) -> vec3<f32>".into() };
        assert!(shader.wgsl.contains(&format!("fn nbrdf_eval(wi: vec3<f32>, {sig}")), "{}", m.name);
        assert_eq!(p > 0, !m.name.contains("Uniform"), "{}", m.name);
        assert!(shader.wgsl.starts_with("// nbrdf shader"), "the conventions head every file");
    }
}

#[test]
fn small_networks_go_inline_and_paper_size_ones_to_a_storage_buffer_by_default() {
    use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
    let small = &common::all_models()[5];
    assert_eq!(export(&small.name, &small.bytes, &Options::default()).unwrap().storage, Storage::Inline);
    let h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 4);
    let big = common::model("paper SingleMlp", h, Precision::F32, 9);
    let shader = export(&big.name, &big.bytes, &Options::default()).unwrap();
    assert_eq!(shader.storage, DEFAULT_BUFFER);
    assert_eq!(shader.weights.len(), h.n_network_weights());
    let cost = Cost::of(&shader).unwrap();
    assert_eq!(cost.macs, h.nets()[0].n_weights() - 6 * 128 - 3, "every weight but the biases is one multiply-add");
    assert!(cost.eval_instructions > 0 && cost.eval_instructions < cost.module_instructions);
}

#[test]
fn bad_input_gets_an_error_naming_the_problem() {
    let m = &common::all_models()[0];
    let mut corrupt = m.bytes.clone();
    let mid = corrupt.len() / 2;
    corrupt[mid] ^= 0x40;
    let e = export("corrupt.nbrdf", &corrupt, &Options::default()).unwrap_err();
    assert!(matches!(e, Error::Model { .. }) && e.to_string().starts_with("corrupt.nbrdf: "), "{e}");
    let e = export("short.nbrdf", &m.bytes[..40], &Options::default()).unwrap_err();
    assert!(e.to_string().contains("short.nbrdf"), "{e}");
    let e = export("notes.txt", b"hello", &Options::default()).unwrap_err();
    assert!(matches!(e, Error::UnknownInput(_)) && e.to_string().contains("neither a .nbrdf model"), "{e}");
    let e = export("bad.json", br#"{"input": "angles"}"#, &Options::default()).unwrap_err();
    assert!(e.to_string().starts_with("bad.json: "), "{e}");
    let e = "cuda".parse::<Lang>().unwrap_err();
    assert_eq!(e.to_string(), "unknown shader language \"cuda\"; expected wgsl, glsl, hlsl, msl or spirv");
    assert!(nbrdf_shader::parse_storage("buffer:1").is_err());
    assert_eq!(nbrdf_shader::parse_storage("buffer:1,4").unwrap(), Storage::Buffer { group: 1, binding: 4 });
    let e = nbrdf_shader::export_file(std::path::Path::new("/nonexistent/m.nbrdf"), &Options::default()).unwrap_err();
    assert!(e.to_string().starts_with("/nonexistent/m.nbrdf: "), "{e}");
}

/// The cost table of README.md ("Accuracy against cost", GPU columns): the paper's nine variants
/// (intrinsic k = 32, 4 angle octaves, Θ) with weights in a storage buffer, and the NBRDF-json shape
/// inline. Prints the rows; asserts that the instruction counts are what a shader of that size holds.
#[test]
fn cost_of_the_papers_architectures() {
    use nbrdf::file::{ModelHeader, ModelKind, PositionEncoding, Precision, Reciprocity};
    use nbrdf::parametric::ParametricKind;
    let position = PositionEncoding::Intrinsic { k: 32 };
    let mut rows: Vec<(String, ModelHeader)> = Vec::new();
    for k in [ParametricKind::Phong, ParametricKind::TorranceSparrow, ParametricKind::FresnelMicrofacet, ParametricKind::Disney] {
        rows.push((k.name().into(), ModelHeader::paper(ModelKind::Parametric(k), false, Reciprocity::None, position, 0)));
    }
    for (name, kind, enhanced) in [
        ("Single MLP", ModelKind::SingleMlp, false),
        ("Additive Separate", ModelKind::AdditiveSeparate, false),
        ("Additive Shared", ModelKind::AdditiveShared, false),
        ("Additive Separate (enhanced)", ModelKind::AdditiveSeparate, true),
        ("Additive Shared (enhanced)", ModelKind::AdditiveShared, true),
    ] {
        rows.push((name.into(), ModelHeader::paper(kind, enhanced, Reciprocity::Exact, position, 4)));
    }
    println!("| model | SPIR-V instructions of nbrdf_eval (static) | multiply-adds per eval | weights |");
    for (name, h) in rows {
        let m = common::model(&name, h, Precision::F32, 1);
        let shader = export(&name, &m.bytes, &Options::default()).unwrap();
        let c = Cost::of(&shader).unwrap();
        assert!(c.macs > 10_000 && c.eval_instructions > 500, "{name}: {c:?}");
        println!("| {name} | {} | {} | buffer, {} f32 |", c.eval_instructions, c.macs, shader.weights.len());
    }
    let shader = export("nbrdf-json", &common::json_network(3), &Options::default()).unwrap();
    let c = Cost::of(&shader).unwrap();
    assert_eq!(c.macs, 6 * 21 + 21 * 21 + 21 * 3);
    println!("| NBRDF-json 6-21-21-3 | {} | {} | inline |", c.eval_instructions, c.macs);
}
