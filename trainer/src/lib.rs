//! `trainer`: fits neural and parametric BRDFs from posed HDR images and runs the paper's comparison
//! study. This library holds the commands' bodies; `main.rs` only parses the command line.

pub mod dataset;
pub mod intrinsic;
