//! `nbrdf-shader MODEL --lang wgsl|glsl|hlsl|msl|spirv --out FILE`: a fitted model as a GPU shader.

use std::path::PathBuf;
use std::process::ExitCode;

use nbrdf_shader::{Lang, Options};

const USAGE: &str = "usage: nbrdf-shader MODEL.nbrdf|NETWORK.json --lang wgsl|glsl|hlsl|msl|spirv --out FILE \
                     [--weights inline|buffer] [--cost]";

fn main() -> ExitCode {
    match run(std::env::args().skip(1).collect()) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("nbrdf-shader: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Vec<String>) -> Result<(), String> {
    let (mut model, mut lang, mut out, mut storage, mut cost) = (None, Lang::Wgsl, None, None, false);
    let mut it = args.into_iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--lang" => lang = it.next().ok_or(USAGE)?.parse().map_err(|e: nbrdf_shader::Error| e.to_string())?,
            "--out" => out = Some(PathBuf::from(it.next().ok_or(USAGE)?)),
            "--weights" => storage = Some(nbrdf_shader::parse_storage(&it.next().ok_or(USAGE)?).map_err(|e| e.to_string())?),
            "--cost" => cost = true,
            "-h" | "--help" => {
                println!("{USAGE}");
                return Ok(());
            }
            _ if model.is_none() && !a.starts_with("--") => model = Some(PathBuf::from(a)),
            _ => return Err(format!("unexpected argument {a:?}\n{USAGE}")),
        }
    }
    let model = model.ok_or(USAGE)?;
    let out = out.ok_or(USAGE)?;
    let options = Options { storage, ..Options::default() };
    let written = nbrdf_shader::write(&model, lang, &out, &options).map_err(|e| e.to_string())?;
    for path in &written.files {
        println!("wrote {}", path.display());
    }
    if cost {
        let c = nbrdf_shader::Cost::of(&written.shader).map_err(|e| e.to_string())?;
        println!(
            "cost: {} SPIR-V instructions in nbrdf_eval and its callees ({} in the module, {} bytes), {} multiply-adds per evaluation",
            c.eval_instructions, c.module_instructions, c.spirv_bytes, c.macs
        );
    }
    Ok(())
}
