pub mod intrinsic;
