//! The exporter's error: every failure names its input and the problem, never a panic.

use std::fmt;

/// What went wrong while exporting or translating a shader.
#[derive(Debug)]
pub enum Error {
    /// The model file or NBRDF-json network was rejected by the core's loader.
    Model {
        /// The file (or "model bytes").
        source: String,
        /// The core's error.
        error: nbrdf::Error,
    },
    /// A file could not be read or written.
    Io {
        /// The path.
        path: String,
        /// The operating system's message.
        message: String,
    },
    /// A target language name that is not one of wgsl, glsl, hlsl, msl, spirv.
    UnknownLanguage(String),
    /// A file that is neither a `.nbrdf` model nor an NBRDF-json network.
    UnknownInput(String),
    /// naga rejected the generated WGSL: a bug of the generator, reported with naga's message.
    Invalid {
        /// The stage (parse, validation, or the target language's writer).
        stage: &'static str,
        /// naga's message.
        message: String,
    },
    /// An option that does not fit the model (e.g. inline weights past the limit).
    Option(String),
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Error::Model { source, error } => write!(f, "{source}: {error}"),
            Error::Io { path, message } => write!(f, "{path}: {message}"),
            Error::UnknownLanguage(s) => {
                write!(f, "unknown shader language {s:?}; expected wgsl, glsl, hlsl, msl or spirv")
            }
            Error::UnknownInput(s) => write!(
                f,
                "{s}: neither a .nbrdf model (magic NBRDFMDL) nor an NBRDF-json network (a JSON object)"
            ),
            Error::Invalid { stage, message } => {
                write!(f, "the generated shader failed naga's {stage} (a bug of nbrdf-shader): {message}")
            }
            Error::Option(s) => f.write_str(s),
        }
    }
}

impl std::error::Error for Error {}
