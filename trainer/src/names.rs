//! The names of a model variant's choices — model kind, reciprocity strategy, position input — as the
//! command line, the study configs and Python write them: each parsed and named in one place, so that
//! every front end holds the typed value and writes it back as the same canonical string.
//!
//! The serde adapters ([`kind`], [`reciprocity`], [`position`]) let a JSON config hold the typed value
//! while its text stays the name (`"rp"`, `"exact"`, `"intrinsic:32"`); the core's own serde of these
//! enums is the model file's and is left alone.

use crate::models::arch::{Kind, PositionEncoding, Reciprocity};
use crate::{Error, Result};

/// The model kind named `name` (the core's name table for the parametric ones, with its aliases).
///
/// ```
/// use trainer::names::{parse_kind, kind_name};
/// // An alias parses to the kind, which is named by its canonical (short) name.
/// assert_eq!(kind_name(parse_kind("phong").unwrap()), "rp");
/// assert!(parse_kind("mlp").unwrap_err().to_string().contains("single-mlp"));
/// ```
pub fn parse_kind(name: &str) -> Result<Kind> {
    crate::models::arch::parse_kind(name).ok_or_else(|| {
        Error::Invalid(format!(
            "unknown model {name:?}; expected one of rp, ts, fmbrdf, disney, lambert, single-mlp, \
             additive-separate, additive-shared"
        ))
    })
}

pub use crate::models::arch::{kind_name, reciprocity_name};

/// Parses `none|swap|exact` (the names [`reciprocity_name`] writes).
pub fn parse_reciprocity(s: &str) -> Result<Reciprocity> {
    match s {
        "none" => Ok(Reciprocity::None),
        "swap" => Ok(Reciprocity::Swap),
        "exact" => Ok(Reciprocity::Exact),
        _ => Err(Error::Invalid(format!("unknown reciprocity strategy {s:?}; expected none, swap or exact"))),
    }
}

/// Parses `uniform`, `intrinsic:K` or `extrinsic:F`.
pub fn parse_position(s: &str) -> Result<PositionEncoding> {
    let bad = || Error::Invalid(format!("unknown position encoding {s:?}; expected uniform, intrinsic:K or extrinsic:F"));
    // A number out of range is named as such, with what is allowed (not as an unknown encoding).
    let number = |v: &str, what: &str, max: u64| -> Result<u64> {
        let n: u64 = v.parse().map_err(|_| bad())?;
        if n == 0 && what == "eigenfunctions" || n > max {
            return Err(Error::Invalid(format!("position encoding {s:?}: {n} {what}; allowed 1..={max}")));
        }
        Ok(n)
    };
    match s.split_once(':') {
        None if s == "uniform" => Ok(PositionEncoding::Uniform),
        Some(("intrinsic", k)) => {
            Ok(PositionEncoding::Intrinsic { k: number(k, "eigenfunctions", nbrdf::file::MAX_INTRINSIC as u64)? as u16 })
        }
        Some(("extrinsic", f)) => Ok(PositionEncoding::Extrinsic {
            frequencies: number(f, "frequencies", nbrdf::file::MAX_FREQUENCIES as u64)? as u8,
        }),
        _ => Err(bad()),
    }
}

/// The name [`parse_position`] reads.
///
/// ```
/// use trainer::names::{parse_position, position_name};
/// for s in ["uniform", "intrinsic:32", "extrinsic:6"] {
///     assert_eq!(position_name(parse_position(s).unwrap()), s);
/// }
/// ```
pub fn position_name(p: PositionEncoding) -> String {
    match p {
        PositionEncoding::Uniform => "uniform".to_string(),
        PositionEncoding::Intrinsic { k } => format!("intrinsic:{k}"),
        PositionEncoding::Extrinsic { frequencies } => format!("extrinsic:{frequencies}"),
    }
}

/// [`parse_kind`], [`parse_reciprocity`] and [`parse_position`] as clap's value parsers: the command
/// line holds the typed values, checked as it is parsed.
pub fn kind_arg(s: &str) -> std::result::Result<Kind, String> {
    parse_kind(s).map_err(|e| e.to_string())
}

/// See [`kind_arg`].
pub fn reciprocity_arg(s: &str) -> std::result::Result<Reciprocity, String> {
    parse_reciprocity(s).map_err(|e| e.to_string())
}

/// See [`kind_arg`].
pub fn position_arg(s: &str) -> std::result::Result<PositionEncoding, String> {
    parse_position(s).map_err(|e| e.to_string())
}

/// A serde adapter (`#[serde(with = ...)]`) writing a value as its name and reading it back through
/// its parser, whose error becomes the deserialiser's (serde_json adds the line and column).
macro_rules! by_name {
    ($(#[$doc:meta])* $module:ident, $ty:ty, $name:expr, $parse:expr) => {
        $(#[$doc])*
        pub mod $module {
            use super::*;
            use serde::{de::Error as _, Deserialize, Deserializer, Serializer};

            pub fn serialize<S: Serializer>(v: &$ty, s: S) -> std::result::Result<S::Ok, S::Error> {
                s.serialize_str(&$name(*v))
            }

            pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<$ty, D::Error> {
                let s = String::deserialize(d)?;
                $parse(&s).map_err(|e| D::Error::custom(e))
            }

            /// The same for an optional value (`null` or absent is `None`).
            pub mod option {
                use super::*;

                pub fn serialize<S: Serializer>(v: &Option<$ty>, s: S) -> std::result::Result<S::Ok, S::Error> {
                    match v {
                        Some(v) => s.serialize_some(&$name(*v)),
                        None => s.serialize_none(),
                    }
                }

                pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> std::result::Result<Option<$ty>, D::Error> {
                    Option::<String>::deserialize(d)?.map(|s| $parse(&s).map_err(|e| D::Error::custom(e))).transpose()
                }
            }
        }
    };
}

by_name!(
    /// A [`Kind`] as its name ([`kind_name`], [`parse_kind`]).
    kind, Kind, kind_name, parse_kind
);
by_name!(
    /// A [`Reciprocity`] as its name ([`reciprocity_name`], [`parse_reciprocity`]).
    reciprocity, Reciprocity, reciprocity_name, parse_reciprocity
);
by_name!(
    /// A [`PositionEncoding`] as its name ([`position_name`], [`parse_position`]).
    position, PositionEncoding, position_name, parse_position
);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_name_reads_back_as_itself() {
        for r in [Reciprocity::None, Reciprocity::Swap, Reciprocity::Exact] {
            assert_eq!(parse_reciprocity(reciprocity_name(r)).unwrap(), r);
        }
        for name in ["rp", "ts", "fmbrdf", "disney", "lambert", "single-mlp", "additive-separate", "additive-shared"] {
            assert_eq!(kind_name(parse_kind(name).unwrap()), name);
        }
        assert_eq!(kind_name(parse_kind("torrance-sparrow").unwrap()), "ts");
    }

    #[test]
    fn a_typed_field_is_written_as_its_name() {
        #[derive(serde::Serialize, serde::Deserialize, Debug, PartialEq)]
        struct Spec {
            #[serde(with = "kind")]
            model: Kind,
            #[serde(with = "position")]
            position: PositionEncoding,
            #[serde(with = "reciprocity::option", default, skip_serializing_if = "Option::is_none")]
            reciprocity: Option<Reciprocity>,
        }
        let read: Spec = serde_json::from_str(r#"{"model":"phong","position":"extrinsic:4"}"#).unwrap();
        assert_eq!(read.reciprocity, None);
        assert_eq!(serde_json::to_string(&read).unwrap(), r#"{"model":"rp","position":"extrinsic:4"}"#);
        let swap: Spec = serde_json::from_str(r#"{"model":"single-mlp","position":"uniform","reciprocity":"swap"}"#).unwrap();
        assert_eq!(swap.reciprocity, Some(Reciprocity::Swap));
        let err = serde_json::from_str::<Spec>(r#"{"model":"rp","position":"intrinsic:0"}"#).unwrap_err().to_string();
        assert!(err.contains("0 eigenfunctions; allowed 1..=4096") && err.contains("column"), "{err}");
    }
}
