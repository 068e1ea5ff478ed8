//! `trainer bound`: an existing model file made energy-bounded (or unbounded again), without refitting
//! it (docs/models.md, "Energy bound"). The bound is fitted over surface points: none for a uniform
//! model, the rows of the file's per-vertex table for an intrinsic one, the training pixels of the
//! data set named for any other.

use std::path::PathBuf;

use nbrdf::file::PositionEncoding;

use crate::models::export::{bound_points, with_energy_bound};
use crate::{Error, Result};

/// Everything `trainer bound` takes.
#[derive(clap::Args, Clone, Debug)]
pub struct BoundArgs {
    /// The model file (.nbrdf)
    pub model: PathBuf,
    /// Where the bounded model goes (written atomically; may be the model file itself)
    #[arg(long)]
    pub out: PathBuf,
    /// Remove the bound instead: the model's unbounded values back
    #[arg(long)]
    pub remove: bool,
    /// Semi-synthetic data set the model was fitted on: the bound's surface points where the file has
    /// none of its own (an extrinsic position input)
    #[arg(long, conflicts_with = "diligent")]
    pub data: Option<PathBuf>,
    /// A DiLiGenT-MV copy, for the same
    #[arg(long)]
    pub diligent: Option<PathBuf>,
    /// DiLiGenT-MV object: bear, buddha, cow, pot2 or reading
    #[arg(long, default_value = "bear")]
    pub object: String,
    /// Where the intrinsic encoding's eigenpairs are cached per mesh
    #[arg(long, default_value = "out/cache")]
    pub cache: PathBuf,
}

/// What [`run`] wrote.
#[derive(Clone, Debug, PartialEq)]
pub struct Bounded {
    /// Surface points the bound was fitted over (0 for `--remove`).
    pub points: usize,
    /// The largest value of the table ([`nbrdf::energy::AlbedoBound::max`]); at most 1 means the
    /// bound changes no value. `None` for `--remove`.
    pub max_albedo: Option<f32>,
}

/// Runs `trainer bound`.
pub fn run(args: &BoundArgs) -> Result<Bounded> {
    let bytes = nbrdf::io::read(&args.model)?;
    let buf = nbrdf::ModelBuf::from_bytes(&bytes).map_err(|e| Error::Invalid(format!("{}: {e}", args.model.display())))?;
    if args.remove {
        let out = nbrdf::file::set_albedo_bound(&bytes, None)?;
        nbrdf::file::save(&args.out, &out)?;
        return Ok(Bounded { points: 0, max_albedo: None });
    }
    let model = buf.model();
    let k = model.position_len();
    let points = match (model.header().position, &args.data, &args.diligent) {
        (PositionEncoding::Uniform, _, _) => bound_points(&[], 0),
        (PositionEncoding::Intrinsic { .. }, None, None) if !model.position_table().is_empty() => bound_points(model.position_table(), k),
        (_, None, None) => {
            return Err(Error::Invalid(format!(
                "{}: the bound of a model with a position input is fitted over points of its surface, and the \
                 file holds none: give --data DIR or --diligent PATH (the data it was fitted on)",
                args.model.display()
            )));
        }
        (position, data, diligent) => {
            let data = crate::dataset::DataArgs { dataset: data.clone(), diligent: diligent.clone(), object: args.object.clone(), pixel_stride: 1 };
            let d = super::data::load(&data, position, &args.cache)?;
            bound_points(&d.obs.position, d.obs.n_position)
        }
    };
    let (out, bound) = with_energy_bound(&bytes, &points)?;
    nbrdf::file::save(&args.out, &out)?;
    Ok(Bounded { points: points.len(), max_albedo: Some(bound.max()) })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{Config, Kind, Model, PositionEncoding, Reciprocity};
    use candle_core::Device;

    fn args(model: PathBuf, out: PathBuf) -> BoundArgs {
        BoundArgs { model, out, remove: false, data: None, diligent: None, object: "bear".into(), cache: "out/cache".into() }
    }

    /// A model with its own per-vertex table is bounded over those rows; `--remove` gives the original
    /// file back, byte for byte; one with an extrinsic input and no data is refused, naming the flags.
    #[test]
    fn bound_and_remove_round_trip_and_extrinsic_models_need_data() {
        let dir = tempfile::tempdir().unwrap();
        let config = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 3 });
        let model = Model::init(config, 5, &Device::Cpu).unwrap();
        let table: Vec<f32> = (0..4 * 3).map(|i| (i as f32 * 0.37).sin()).collect();
        let src = dir.path().join("m.nbrdf");
        crate::models::export::save(&model, &src, Some(&table)).unwrap();
        let out = dir.path().join("b.nbrdf");
        let b = run(&args(src.clone(), out.clone())).unwrap();
        assert_eq!(b.points, 4);
        let bounded = nbrdf::ModelBuf::load(&out).unwrap();
        assert_eq!(bounded.model().albedo_bound().map(|t| t.max()), b.max_albedo);
        let back = dir.path().join("back.nbrdf");
        run(&BoundArgs { remove: true, ..args(out, back.clone()) }).unwrap();
        assert_eq!(std::fs::read(&back).unwrap(), std::fs::read(&src).unwrap());

        let config = Config::paper(Kind::SingleMlp, false, Reciprocity::Exact, PositionEncoding::Extrinsic { frequencies: 1 });
        let ext = dir.path().join("x.nbrdf");
        crate::models::export::save(&Model::init(config, 5, &Device::Cpu).unwrap(), &ext, None).unwrap();
        let e = run(&args(ext, dir.path().join("never.nbrdf"))).unwrap_err().to_string();
        assert!(e.contains("--data") && e.contains("--diligent"), "{e}");
        assert!(!dir.path().join("never.nbrdf").exists());
    }
}
