//! `trainer`: fits the neural and parametric BRDFs of the paper and runs its comparison study.
//!
//! - [`metrics`]: the study's image, BRDF-space, reciprocity and energy metrics (paper Sec. 6).

pub mod metrics;
