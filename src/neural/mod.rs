//! The neural BRDF architectures of Sec. 4.1: per-architecture `prepare` (position-only work) and `eval`
//! (per direction pair) over [`crate::mlp`] networks. The exact forward pass is `docs/models.md`; the
//! file-level dispatch lives in [`crate::model::Model`].

pub mod additive_separate;
pub mod additive_shared;
pub mod parametric_net;
pub mod single_mlp;
pub mod split;
