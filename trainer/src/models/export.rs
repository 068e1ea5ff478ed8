//! Export of a fitted model to the core's `.nbrdf` file: the header of its configuration and the
//! weight vector in file order, which the `Var`s already hold layer by layer (a copy, no reordering).

use std::path::Path;

use super::Model;
use crate::{Error, Result};

/// The file bytes of `model`; `position_table` is the per-vertex intrinsic encoding (`n_vertices × k`)
/// a renderer interpolates itself, if it should travel with the model.
///
/// Purely neural models also get their importance-sampling proxy: a cosine + GGX mixture
/// fitted to the exported network averaged over a few surface points — rows of the position table,
/// points on the unit sphere for the extrinsic encoding, the one point of a uniform material — so that a
/// renderer can sample the model without knowing anything about it. Parametric models sample their own
/// predicted lobes and carry no proxy.
pub fn encode(model: &Model, position_table: Option<&[f32]>) -> Result<Vec<u8>> {
    let header = model.config.header();
    let weights = model.weights()?;
    let bytes = nbrdf::file::encode(&header, &weights, position_table)?;
    if matches!(header.kind, nbrdf::file::ModelKind::Parametric(_)) {
        return Ok(bytes);
    }
    let buf = nbrdf::ModelBuf::from_bytes(&bytes)?;
    let core = buf.model();
    let points: Vec<Vec<f32>> = match header.position {
        nbrdf::file::PositionEncoding::Uniform => vec![Vec::new()],
        nbrdf::file::PositionEncoding::Extrinsic { .. } => (0..8)
            .map(|i| {
                // Fibonacci points on the unit sphere, where normalised meshes live.
                let z = 1.0 - (2.0 * i as f32 + 1.0) / 8.0;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let phi = i as f32 * 2.399_963;
                vec![r * phi.cos(), r * phi.sin(), z]
            })
            .collect(),
        nbrdf::file::PositionEncoding::Intrinsic { k } => match position_table {
            Some(t) if k > 0 && t.len() >= k as usize => {
                let rows = t.len() / k as usize;
                (0..8).map(|i| t[(i * rows / 8) * k as usize..][..k as usize].to_vec()).collect()
            }
            _ => Vec::new(),
        },
    };
    let prepared = points.iter().map(|p| core.prepare(p)).collect::<core::result::Result<Vec<_>, _>>()?;
    let proxy = core.fit_proxy(&prepared);
    let view = core.fit_view_proxy(&prepared, &proxy);
    Ok(nbrdf::file::encode(&header.with_proxy(proxy).with_view_proxy(view), &weights, position_table)?)
}

/// Most surface points an energy bound is fitted over (each costs 300k evaluations).
pub const BOUND_POINTS: usize = 32;

/// Up to [`BOUND_POINTS`] position inputs spread evenly over the rows of `positions` (`n` values per
/// row: the training pixels' points); the one empty point of a uniform model (`n = 0`).
pub fn bound_points(positions: &[f32], n: usize) -> Vec<Vec<f32>> {
    if n == 0 {
        return vec![Vec::new()];
    }
    let rows = positions.len() / n;
    let take = rows.min(BOUND_POINTS);
    (0..take).map(|i| positions[(i * rows / take) * n..][..n].to_vec()).collect()
}

/// The model file `bytes` energy-bounded: [`nbrdf::file::set_albedo_bound`] with the envelope of the
/// unbounded model's albedo curves at `points` (position inputs, curves computed in parallel;
/// `docs/models.md`, "Energy bound"), and that bound. A model already bounded is bounded again from
/// its own values.
pub fn with_energy_bound(bytes: &[u8], points: &[Vec<f32>]) -> Result<(Vec<u8>, nbrdf::energy::AlbedoBound)> {
    use rayon::prelude::*;
    if points.is_empty() {
        return Err(Error::Invalid("the energy bound needs at least one surface point".into()));
    }
    let buf = nbrdf::ModelBuf::from_bytes(bytes)?;
    let core = buf.model();
    let prepared = points.iter().map(|p| core.prepare(p)).collect::<core::result::Result<Vec<_>, _>>()?;
    let curves: Vec<nbrdf::energy::AlbedoCurve> = prepared.par_iter().map(|p| core.albedo_curve(p)).collect();
    let bound = nbrdf::energy::AlbedoBound::envelope(curves);
    Ok((nbrdf::file::set_albedo_bound(bytes, Some(bound))?, bound))
}

/// The weight vector of a core model in file order (what [`Model::weights`] gives and
/// [`nbrdf::file::encode`] takes): its network weights, widened from half precision where stored so,
/// and its per-object parameters.
pub fn core_weights(core: &nbrdf::model::Model<'_>) -> Vec<f32> {
    let mut w: Vec<f32> = match core.weights() {
        nbrdf::model::Weights::F32(w) => w.to_vec(),
        nbrdf::model::Weights::F16(w) => w.iter().map(|h| h.to_f32()).collect(),
    };
    w.extend_from_slice(core.object_parameters());
    w
}

/// The trainer's twin of a core model that the trainer could have written (the inverse of
/// [`encode`]'s networks): its variant from the header ([`Config::of_header`]) and its weights.
///
/// [`Config::of_header`]: super::Config::of_header
pub fn from_core(core: &nbrdf::model::Model<'_>) -> Result<Model> {
    let header = core.header();
    let config = super::Config::of_header(header).ok_or_else(|| {
        Error::Invalid(format!(
            "a {:?} model with networks {:?} is not one the trainer builds (another width or layout), so it has no backward pass here",
            header.kind,
            header.nets()
        ))
    })?;
    let model = Model::init(config, 0, &candle_core::Device::Cpu)?;
    model.set_weights(&core_weights(core))?;
    Ok(model)
}

/// The file bytes of a freshly initialised model of `config` (seed `seed`, outputs starting where a
/// fit of an image of median `median` starts: [`OutputStart::for_median`]). It samples the cosine
/// lobe: a proxy fitted to untrained weights would follow nothing; [`encode`] fits one once the
/// weights mean something.
///
/// [`OutputStart::for_median`]: super::OutputStart::for_median
pub fn initial(config: super::Config, seed: u64, median: Option<f32>) -> Result<Vec<u8>> {
    let start = super::OutputStart::for_median(median);
    let model = Model::init_at(config, seed, &candle_core::Device::Cpu, start)?;
    Ok(nbrdf::file::encode(&config.header(), &model.weights()?, None)?)
}

/// Writes `model` to `path` atomically.
pub fn save(model: &Model, path: &Path, position_table: Option<&[f32]>) -> Result<()> {
    let bytes = encode(model, position_table)?;
    nbrdf::file::save(path, &bytes).map_err(Error::Core)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::{arch, Config, Inputs, Kind, PositionEncoding, RawBatch, Reciprocity};
    use candle_core::Device;
    use nbrdf::ModelBuf;
    use rand::{RngExt, SeedableRng};

    /// Every variant the study fits, plus the other reciprocity strategies and the Tab. 2 layer counts.
    fn variants(position: PositionEncoding) -> Vec<Config> {
        let mut v = arch::study_variants(position, Reciprocity::Exact);
        for r in [Reciprocity::None, Reciprocity::Swap] {
            v.push(Config::paper(Kind::AdditiveShared, true, r, position));
        }
        for (kind, n) in [(Kind::SingleMlp, 3), (Kind::AdditiveSeparate, 2), (Kind::AdditiveShared, 4)] {
            let mut c = Config::paper(kind, false, Reciprocity::None, position);
            c.direction_layers = Some(n);
            v.push(c);
        }
        v.into_iter().map(|mut c| {
            c.angle_frequencies = 3;
            c
        }).collect()
    }

    /// Perturbs the freshly initialised weights so that every output nonlinearity is exercised away
    /// from its value at 0, and biases are not all tiny.
    fn scramble(model: &Model, seed: u64) {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(seed);
        let w: Vec<f32> = model.weights().unwrap().iter().map(|w| w * rng.random_range(0.5..2.0)).collect();
        model.set_weights(&w).unwrap();
    }

    /// The candle forward pass and the core's evaluation of the exported file agree within 1e-5
    /// relative, for every variant and both kinds of position input.
    #[test]
    fn exported_models_evaluate_like_the_candle_twin() {
        let device = Device::Cpu;
        for position in [PositionEncoding::Intrinsic { k: 5 }, PositionEncoding::Extrinsic { frequencies: 2 }] {
            for (i, config) in variants(position).into_iter().enumerate() {
                let model = Model::init(config, 11 + i as u64, &device).unwrap();
                scramble(&model, i as u64);
                let n = 48;
                let (wi, wo) = crate::toy::direction_pairs(n, 5 + i as u64);
                let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(i as u64);
                let np = position.input_len();
                let pos: Vec<f32> = (0..n * np).map(|_| rng.random_range(-1.0..1.0)).collect();
                let x = Inputs::build(&config, &RawBatch { position: &pos, wi: &wi, wo: &wo, swap: None }, &device).unwrap();
                let ours = crate::models::to_rgb(&model.forward(&x).unwrap().f).unwrap();

                let buf = ModelBuf::from_bytes(&encode(&model, None).unwrap()).unwrap();
                let core = buf.model();
                for s in 0..n {
                    let prepared = core.prepare(&pos[s * np..(s + 1) * np]).unwrap();
                    let theirs = core.eval(&prepared, wi[s], wo[s]);
                    for c in 0..3 {
                        let (a, b) = (ours[s][c], theirs[c]);
                        assert!(
                            (a - b).abs() <= 1e-5 * a.abs().max(b.abs()) + 1e-30,
                            "{} ({position:?}) sample {s} channel {c}: candle {a} vs core {b}",
                            config.name()
                        );
                    }
                    if config.reciprocity == Reciprocity::Exact {
                        assert_eq!(theirs, core.eval(&prepared, wo[s], wi[s]), "{}: bitwise reciprocity", config.name());
                    }
                }
            }
        }
    }

    /// The exported file carries the configuration's header and every weight.
    #[test]
    fn export_round_trips_header_and_size() {
        let c = Config::paper(Kind::AdditiveSeparate, true, Reciprocity::Exact, PositionEncoding::Intrinsic { k: 4 });
        let model = Model::init(c, 0, &Device::Cpu).unwrap();
        let buf = ModelBuf::from_bytes(&encode(&model, Some(&[0.5; 4 * 10])).unwrap()).unwrap();
        assert_eq!(buf.header().nets(), c.header().nets());
        assert_eq!(buf.header().n_vertices, 10);
        assert_eq!(model.weights().unwrap().len(), c.header().n_weights());
    }

    /// A neural export carries a sampling proxy whose pdf is a proper density; a parametric one none.
    #[test]
    fn neural_exports_carry_a_fitted_sampling_proxy() {
        let position = PositionEncoding::Extrinsic { frequencies: 1 };
        for (kind, want) in [(Kind::SingleMlp, true), (Kind::Parametric(nbrdf::parametric::ParametricKind::Phong), false)] {
            let model = Model::init(Config::paper(kind, false, Reciprocity::Exact, position), 3, &Device::Cpu).unwrap();
            let buf = nbrdf::ModelBuf::from_bytes(&encode(&model, None).unwrap()).unwrap();
            let proxy = buf.header().proxy;
            assert_eq!(proxy.is_some(), want, "{kind:?}");
            if let Some(p) = proxy {
                assert!(p.validate().is_ok());
            }
        }
    }
}
