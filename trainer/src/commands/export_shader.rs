//! `trainer export-shader MODEL --lang wgsl|glsl|hlsl|msl|spirv --out FILE`: the fitted model as a GPU
//! shader, through `nbrdf-shader` (the core itself stays free of naga).

use std::path::Path;

use crate::{Error, Result};

/// Exports `model` in `lang` to `out`; `weights` is `inline`, `buffer` or `buffer:G,B` (default: by size).
pub fn run(model: &Path, lang: &str, out: &Path, weights: Option<&str>) -> Result<()> {
    let shader_err = |e: nbrdf_shader::Error| Error::Invalid(e.to_string());
    let lang: nbrdf_shader::Lang = lang.parse().map_err(shader_err)?;
    let storage = weights.map(nbrdf_shader::parse_storage).transpose().map_err(shader_err)?;
    let options = nbrdf_shader::Options { storage, ..nbrdf_shader::Options::default() };
    let written = nbrdf_shader::write(model, lang, out, &options).map_err(shader_err)?;
    for path in &written.files {
        println!("wrote {}", path.display());
    }
    let cost = nbrdf_shader::Cost::of(&written.shader).map_err(shader_err)?;
    println!(
        "{}: {} SPIR-V instructions in nbrdf_eval and its callees, {} multiply-adds per evaluation",
        written.shader.description, cost.eval_instructions, cost.macs
    );
    Ok(())
}
