//! Fitted nbrdf models and NBRDF-json networks as self-contained GPU shaders.
//!
//! A renderer on the GPU cannot link the core: [`export`] turns a `.nbrdf` file (every model kind,
//! reciprocity, precision and position input) or an NBRDF-json network into one WGSL module holding the
//! angle map (Rusinkiewicz or Θ, with the core's hard cases), the positional encoding, the networks
//! with their weights, the output maps, the parametric formulas and the sampling, behind three
//! functions:
//!
//! ```wgsl
//! fn nbrdf_eval(wi: vec3<f32>, wo: vec3<f32>, p: array<f32, P>) -> vec3<f32>  // 1/sr, no cosine
//! fn nbrdf_sample(wo: vec3<f32>, u: vec3<f32>, p: array<f32, P>) -> NbrdfSample
//! fn nbrdf_pdf(wi: vec3<f32>, wo: vec3<f32>, p: array<f32, P>) -> f32
//! ```
//!
//! (`p` only where the model has a position input). [`translate`] writes it as GLSL, HLSL, MSL or
//! SPIR-V through naga, which validates it first. `docs/shader.md` documents the conventions and how
//! the values were checked against the core.
//!
//! ```
//! use nbrdf::file::{encode, ModelHeader, ModelKind, PositionEncoding, Reciprocity};
//! use nbrdf_shader::{export, translate, Lang, Options};
//! let mut h = ModelHeader::paper(ModelKind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Uniform, 2);
//! h.nets[0].width = 8; // a small network: weights inline
//! let w: Vec<f32> = (0..h.n_weights()).map(|i| ((i * 37 % 101) as f32 - 50.0) * 1e-2).collect();
//! let shader = export("small.nbrdf", &encode(&h, &w, None).unwrap(), &Options::default()).unwrap();
//! assert!(shader.wgsl.contains("fn nbrdf_eval(wi: vec3<f32>, wo: vec3<f32>) -> vec3<f32>"));
//! let glsl = translate(&shader, Lang::Glsl).unwrap();
//! assert!(String::from_utf8(glsl).unwrap().contains("nbrdf_eval"));
//! ```

mod cost;
mod entry;
mod error;
mod header;
mod json;
mod lang;
mod model;
mod network;
#[cfg(feature = "gpu")]
pub mod gpu;

pub use cost::Cost;
pub use entry::{TEST_ENTRY, TEST_IN_STRIDE_BASE, TEST_OUT_STRIDE};
pub use error::Error;
pub use lang::{parse_wgsl, translate, translate_wgsl, Lang};
pub use network::Storage;

use nbrdf::measured::nbrdf_json::NbrdfNetwork;
use nbrdf::sampling::Proxy;
use nbrdf::ModelBuf;

/// How to export.
#[derive(Clone, Copy, Debug)]
pub struct Options {
    /// Where the weights go; `None` chooses [`Storage::Inline`] up to `inline_limit` network weights
    /// and a storage buffer at `@group(0) @binding(2)` past it.
    pub storage: Option<Storage>,
    /// The most network weights written inline when `storage` is `None`.
    pub inline_limit: usize,
    /// The sampling proxy of an NBRDF-json network (which stores none): `None` fits one to the
    /// network (`NbrdfNetwork::proxy`, fitted at load). `.nbrdf` files carry their own.
    pub json_proxy: Option<Proxy>,
}

impl Default for Options {
    fn default() -> Self {
        Options { storage: None, inline_limit: 16_384, json_proxy: None }
    }
}

/// The default storage buffer of large networks.
pub const DEFAULT_BUFFER: Storage = Storage::Buffer { group: 0, binding: 2 };

/// An exported shader.
#[derive(Clone, Debug)]
pub struct Shader {
    /// The WGSL module: header comment, functions, the test compute entry point.
    pub wgsl: String,
    /// Where the weights are.
    pub storage: Storage,
    /// The storage buffer's contents (little-endian f32 when written to a file); empty for inline
    /// weights.
    pub weights: Vec<f32>,
    /// Length of `p`, the position input of `nbrdf_eval` (0: no such parameter).
    pub position_len: usize,
    /// Multiply-adds of the networks in one `nbrdf_eval`.
    pub macs: usize,
    /// What was exported, in words (the header comment's first line).
    pub description: String,
}

impl Shader {
    /// The storage buffer's bytes (little-endian f32).
    pub fn weight_bytes(&self) -> Vec<u8> {
        self.weights.iter().flat_map(|w| w.to_le_bytes()).collect()
    }
}

/// What a generator hands to the assembly: the model-specific WGSL and the weights buffer.
pub(crate) struct Body {
    pub code: String,
    pub buffer: Vec<f32>,
    pub position_len: usize,
    pub macs: usize,
    pub parametric: bool,
    pub json: bool,
}

/// Exports a `.nbrdf` file or an NBRDF-json network (told apart by their first bytes); `source` names
/// it in errors and in the shader's header comment. The WGSL is validated by naga before it is
/// returned.
pub fn export(source: &str, bytes: &[u8], options: &Options) -> Result<Shader, Error> {
    let first = bytes.iter().find(|b| !b.is_ascii_whitespace());
    if bytes.starts_with(&nbrdf::file::MAGIC) {
        export_model(source, bytes, options)
    } else if first == Some(&b'{') {
        export_json(source, bytes, options)
    } else {
        Err(Error::UnknownInput(source.to_string()))
    }
}

/// [`export`] of a file.
pub fn export_file(path: &std::path::Path, options: &Options) -> Result<Shader, Error> {
    let bytes = std::fs::read(path).map_err(|e| Error::Io { path: path.display().to_string(), message: e.to_string() })?;
    export(&path.display().to_string(), &bytes, options)
}

fn storage_for(n_weights: usize, options: &Options) -> Storage {
    options.storage.unwrap_or(if n_weights <= options.inline_limit { Storage::Inline } else { DEFAULT_BUFFER })
}

/// Exports a `.nbrdf` model file (f16 files widened to f32 as the core's `ModelBuf` does).
pub fn export_model(source: &str, bytes: &[u8], options: &Options) -> Result<Shader, Error> {
    let buf = ModelBuf::from_bytes(bytes).map_err(|error| Error::Model { source: source.to_string(), error })?;
    let model = buf.model();
    let storage = storage_for(model.header().n_network_weights(), options);
    let description = format!(
        "{source}: {}{}",
        model::describe(&model),
        if buf.file_precision() == nbrdf::file::Precision::F16 { "; f16 weights widened to f32" } else { "" }
    );
    assemble(description, model::body(&model, storage), storage)
}

/// Exports an NBRDF-json network.
pub fn export_json(source: &str, bytes: &[u8], options: &Options) -> Result<Shader, Error> {
    let net = NbrdfNetwork::from_json_bytes(bytes).map_err(|error| Error::Model { source: source.to_string(), error })?;
    let network = json::network(&net, bytes, source)?;
    let storage = storage_for(network.n_weights(), options);
    // A proxy given in the options replaces the network's own sampling (its per-view table too).
    let (proxy, view) = match options.json_proxy {
        Some(p) => (p, None),
        None => (*net.proxy(), Some(*net.view_proxy())),
    };
    let widths: Vec<String> = net.widths().iter().map(usize::to_string).collect();
    let description = format!("{source}: NBRDF-json network {} ({})", net.name(), widths.join("-"));
    assemble(description, json::body(&network, &proxy, view.as_ref(), storage), storage)
}

fn assemble(description: String, body: Body, storage: Storage) -> Result<Shader, Error> {
    let mut wgsl = header::comment(&description, &body, storage);
    wgsl.push_str(include_str!("wgsl/math.wgsl"));
    wgsl.push('\n');
    wgsl.push_str(include_str!("wgsl/angles.wgsl"));
    wgsl.push('\n');
    wgsl.push_str(include_str!("wgsl/sampling.wgsl"));
    wgsl.push('\n');
    if body.parametric {
        wgsl.push_str(include_str!("wgsl/parametric.wgsl"));
        wgsl.push('\n');
        wgsl.push_str(include_str!("wgsl/sampling_parametric.wgsl"));
        wgsl.push('\n');
    }
    if body.json {
        wgsl.push_str(include_str!("wgsl/json_input.wgsl"));
        wgsl.push('\n');
    }
    wgsl.push_str("// ---- the model ------------------------------------------------------------------------------------\n\n");
    if let Storage::Buffer { group, binding } = storage {
        wgsl.push_str(&format!(
            "// The networks' weights (per layer the [in][out] matrix, then the bias), {} f32.\n\
             @group({group}) @binding({binding}) var<storage, read> nbrdf_weights: array<f32>;\n\n",
            body.buffer.len()
        ));
    }
    wgsl.push_str(&body.code);
    wgsl.push_str(&entry::test_entry(body.position_len));
    let shader = Shader {
        wgsl,
        storage,
        weights: body.buffer,
        position_len: body.position_len,
        macs: body.macs,
        description,
    };
    lang::parse_wgsl(&shader.wgsl)?;
    Ok(shader)
}

/// Parses `inline` or `buffer` (the storage buffer at `@group(0) @binding(2)`) or `buffer:G,B`.
pub fn parse_storage(s: &str) -> Result<Storage, Error> {
    let bad = || Error::Option(format!("unknown weight storage {s:?}; expected inline, buffer or buffer:GROUP,BINDING"));
    match s.split_once(':') {
        None if s == "inline" => Ok(Storage::Inline),
        None if s == "buffer" => Ok(DEFAULT_BUFFER),
        Some(("buffer", gb)) => {
            let (g, b) = gb.split_once(',').ok_or_else(bad)?;
            Ok(Storage::Buffer { group: g.trim().parse().map_err(|_| bad())?, binding: b.trim().parse().map_err(|_| bad())? })
        }
        _ => Err(bad()),
    }
}

/// What [`write`] wrote.
#[derive(Clone, Debug)]
pub struct Written {
    /// The shader exported.
    pub shader: Shader,
    /// The files: the shader, then the weights buffer where there is one.
    pub files: Vec<std::path::PathBuf>,
}

/// Exports the model or network at `model` and writes it in `lang` to `out` (atomically), and for
/// weights in a storage buffer their bytes to `out` with `.weights.bin` appended.
pub fn write(model: &std::path::Path, lang: Lang, out: &std::path::Path, options: &Options) -> Result<Written, Error> {
    let shader = export_file(model, options)?;
    let bytes = translate(&shader, lang)?;
    let save = |path: &std::path::Path, bytes: &[u8]| {
        nbrdf::file::save(path, bytes).map_err(|e| Error::Io { path: path.display().to_string(), message: e.to_string() })
    };
    save(out, &bytes)?;
    let mut files = vec![out.to_path_buf()];
    if matches!(shader.storage, Storage::Buffer { .. }) {
        let mut name = out.as_os_str().to_owned();
        name.push(".weights.bin");
        let path = std::path::PathBuf::from(name);
        save(&path, &shader.weight_bytes())?;
        files.push(path);
    }
    Ok(Written { shader, files })
}
