//! The target languages and their translation from WGSL through naga: parse, validate, write.

use std::str::FromStr;

use naga::back;
use naga::valid::{Capabilities, ModuleInfo, ValidationFlags, Validator};

use crate::entry::TEST_ENTRY;
use crate::{Error, Shader};

/// A shading language (or SPIR-V) to export to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Lang {
    /// WGSL, as generated.
    Wgsl,
    /// GLSL 4.50 core (OpenGL); one compute entry point, `main` (the test harness).
    Glsl,
    /// HLSL, shader model 5.1.
    Hlsl,
    /// Metal Shading Language.
    Msl,
    /// SPIR-V 1.0 binary (Vulkan).
    Spirv,
}

impl Lang {
    /// Every language, WGSL first.
    pub const ALL: [Lang; 5] = [Lang::Wgsl, Lang::Glsl, Lang::Hlsl, Lang::Msl, Lang::Spirv];

    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Lang::Wgsl => "wgsl",
            Lang::Glsl => "glsl",
            Lang::Hlsl => "hlsl",
            Lang::Msl => "msl",
            Lang::Spirv => "spirv",
        }
    }

    /// The usual file extension.
    pub fn extension(self) -> &'static str {
        match self {
            Lang::Wgsl => "wgsl",
            Lang::Glsl => "comp",
            Lang::Hlsl => "hlsl",
            Lang::Msl => "metal",
            Lang::Spirv => "spv",
        }
    }
}

impl FromStr for Lang {
    type Err = Error;

    fn from_str(s: &str) -> Result<Self, Error> {
        Lang::ALL.into_iter().find(|l| l.name() == s.to_ascii_lowercase()).ok_or_else(|| Error::UnknownLanguage(s.to_string()))
    }
}

/// Parses and validates WGSL with naga.
pub fn parse_wgsl(wgsl: &str) -> Result<(naga::Module, ModuleInfo), Error> {
    let module = naga::front::wgsl::parse_str(wgsl)
        .map_err(|e| Error::Invalid { stage: "WGSL parse", message: e.emit_to_string(wgsl) })?;
    let info = Validator::new(ValidationFlags::all(), Capabilities::default())
        .validate(&module)
        .map_err(|e| Error::Invalid { stage: "validation", message: e.emit_to_string(wgsl) })?;
    Ok((module, info))
}

/// The exported shader in `lang`: text (UTF-8) for the shading languages, the SPIR-V words
/// little-endian for SPIR-V.
pub fn translate(shader: &Shader, lang: Lang) -> Result<Vec<u8>, Error> {
    translate_wgsl(&shader.wgsl, lang)
}

/// [`translate`] of any WGSL module with a compute entry point `nbrdf_test_main` (GLSL needs one entry
/// point). The header comment of the WGSL (its leading `//` lines) is written at the top of the text
/// languages too: naga carries no comments.
pub fn translate_wgsl(wgsl: &str, lang: Lang) -> Result<Vec<u8>, Error> {
    if lang == Lang::Wgsl {
        return Ok(wgsl.as_bytes().to_vec());
    }
    let (module, info) = parse_wgsl(wgsl)?;
    let header: String = wgsl.lines().take_while(|l| l.starts_with("//")).map(|l| format!("{l}\n")).collect();
    let err = |stage: &'static str| move |e: &dyn std::fmt::Display| Error::Invalid { stage, message: e.to_string() };
    let text = match lang {
        Lang::Wgsl => unreachable!(),
        Lang::Glsl => {
            let options = back::glsl::Options { version: back::glsl::Version::Desktop(450), ..Default::default() };
            let pipeline = back::glsl::PipelineOptions {
                shader_stage: naga::ShaderStage::Compute,
                entry_point: TEST_ENTRY.to_string(),
                multiview: None,
            };
            let mut out = String::new();
            let mut w = back::glsl::Writer::new(
                &mut out,
                &module,
                &info,
                &options,
                &pipeline,
                naga::proc::BoundsCheckPolicies::default(),
            )
            .map_err(|e| err("GLSL writer")(&e))?;
            w.write().map_err(|e| err("GLSL writer")(&e))?;
            // The version directive must come first.
            let (version, rest) = out.split_once('\n').unwrap_or((&out, ""));
            format!("{version}\n{header}{rest}")
        }
        Lang::Hlsl => {
            let options = back::hlsl::Options::default();
            let pipeline = back::hlsl::PipelineOptions::default();
            let mut out = String::new();
            back::hlsl::Writer::new(&mut out, &options, &pipeline)
                .write(&module, &info, None)
                .map_err(|e| err("HLSL writer")(&e))?;
            format!("{header}{out}")
        }
        Lang::Msl => {
            let options = back::msl::Options::default();
            let pipeline = back::msl::PipelineOptions::default();
            let (out, _) =
                back::msl::write_string(&module, &info, &options, &pipeline).map_err(|e| err("MSL writer")(&e))?;
            format!("{header}{out}")
        }
        Lang::Spirv => {
            let words = spirv_words(&module, &info)?;
            return Ok(words.iter().flat_map(|w| w.to_le_bytes()).collect());
        }
    };
    Ok(text.into_bytes())
}

/// The SPIR-V of a validated module.
pub(crate) fn spirv_words(module: &naga::Module, info: &ModuleInfo) -> Result<Vec<u32>, Error> {
    // Debug names in every build: they name the functions for a renderer (and for `Cost`).
    let mut options = back::spv::Options::default();
    options.flags |= back::spv::WriterFlags::DEBUG;
    back::spv::write_vec(module, info, &options, None)
        .map_err(|e| Error::Invalid { stage: "SPIR-V writer", message: e.to_string() })
}
