//! Serde adapters that store `f32` values as their IEEE bit patterns, so checkpoints restore weights
//! and optimiser moments exactly (a decimal round trip through JSON's f64 could round twice).

use serde::{Deserialize, Deserializer, Serialize, Serializer};

/// `Vec<f32>` as `Vec<u32>` bit patterns.
pub mod vec {
    use super::*;

    pub fn serialize<S: Serializer>(v: &[f32], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|x| x.to_bits()).collect::<Vec<u32>>().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f32>, D::Error> {
        Ok(Vec::<u32>::deserialize(d)?.into_iter().map(f32::from_bits).collect())
    }
}

/// `Vec<Vec<f32>>` as nested `u32` bit patterns.
pub mod vec2 {
    use super::*;

    pub fn serialize<S: Serializer>(v: &[Vec<f32>], s: S) -> Result<S::Ok, S::Error> {
        v.iter().map(|r| r.iter().map(|x| x.to_bits()).collect::<Vec<u32>>()).collect::<Vec<_>>().serialize(s)
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<Vec<f32>>, D::Error> {
        Ok(Vec::<Vec<u32>>::deserialize(d)?.into_iter().map(|r| r.into_iter().map(f32::from_bits).collect()).collect())
    }
}
