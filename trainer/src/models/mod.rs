//! Candle twins of every core model (docs/models.md): the same networks, wiring and output
//! nonlinearities, with weights held as candle `Var`s in file order so that export is a copy.
//! [`Model::forward`] composes plain candle ops, the definition the training engine
//! (`crate::engine`) must meet; the engine trains these variables.

pub mod activation;
pub mod arch;
pub mod export;
pub mod features;
pub mod mlp;
pub mod parametric;

use candle_core::{Device, Result, Tensor, Var};
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use arch::{Config, Kind, NetDesc, ParametricKind, PositionEncoding, Reciprocity};
pub use features::{Inputs, RawBatch};
pub use mlp::Mlp;

/// The BRDF of a batch and, for additive models, its parts (the regularisers of Sec. 4.4 need them).
pub struct Output {
    /// `[N, 3]`: `f(x, wi, wo)` in 1/sr, 0 for invalid pairs.
    pub f: Tensor,
    /// `[N, 3]`: the diffuse part `f_d = σ(d)/π` (additive models).
    pub diffuse: Option<Tensor>,
    /// `[N, 3]`: the specular part `f_s = softplus(s)` (additive models).
    pub specular: Option<Tensor>,
}

/// What a model's networks output, before the nonlinearities of its head ([`Model::raw`]).
pub enum Raw {
    /// `[N, 3]`: the BRDF itself (a parametric model's formula is part of its networks' op).
    Brdf(Tensor),
    /// `[N, 3]`: the Single MLP's pre-activation; `f = softplus(out)`.
    Softplus(Tensor),
    /// The additive models' diffuse `d` (`[N, 3]`) and specular `s` (`[N, 3]`, enhanced `[N, 6]` with
    /// the Eq. 8 weight's pre-activation in the last three columns).
    Additive { d: Tensor, s: Tensor },
}

/// Start of the specular (and Single MLP) output logit: `softplus(-4) = 0.018`/sr.
///
/// PyTorch's default start (`f_s + f_d ≈ 0.85`/sr) is brighter than almost every measured material
/// away from its highlight; the first steps then push the specular network into dead ReLUs. Starting
/// dark lets the highlight grow from below (docs/training.md, "Initialisation", has the losses).
pub const SPECULAR_START: f32 = -4.0;

/// Start of the diffuse logit of the additive models: `σ(-3)/π = 0.015`/sr (albedo 0.047); see
/// [`SPECULAR_START`].
pub const DIFFUSE_START: f32 = -3.0;

/// Where a fresh model's outputs start: the logits added to its output biases. For the purely neural
/// models `f_s = softplus(specular)` (the Single MLP's whole `f`) and `f_d = σ(diffuse)/π` at a typical
/// input; for the parametric ones the diffuse albedo `σ(albedo)` (raw outputs 0–2 of every parametric
/// table: RP's and Torrance-Sparrow's `kd`, FMBRDF's `rho`, Disney's base colour, Lambert's `kd`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OutputStart {
    pub specular: f32,
    pub diffuse: f32,
    pub albedo: f32,
}

impl OutputStart {
    /// The fixed start for models without data to see: the purely neural outputs dark
    /// ([`SPECULAR_START`], [`DIFFUSE_START`]), the parametric albedo at the tables' `σ(0) = 0.5`.
    pub const DARK: OutputStart = OutputStart { specular: SPECULAR_START, diffuse: DIFFUSE_START, albedo: 0.0 };

    /// [`OutputStart::DARK`], dimmed to the data's median BRDF value `m` (1/sr;
    /// [`crate::observations::Observations::median_brdf`]): a purely neural part that would start
    /// brighter than `2m` starts at `2m`, a parametric albedo brighter than `10m` at `10m`.
    ///
    /// The fixed start overshoots a dark material so far that the first steps drive the logits into
    /// the flat tails of softplus and σ, where Adam's steps vanish; the parametric albedo keeps more
    /// headroom because its formulas add their lobes to it (docs/training.md, "Initialisation", has
    /// the measured stalls and what each limit cost). No usable median keeps the fixed start.
    ///
    /// ```
    /// use trainer::models::OutputStart;
    /// assert_eq!(OutputStart::for_median(None), OutputStart::DARK);
    /// let (bright, dim) = (OutputStart::for_median(Some(0.3)), OutputStart::for_median(Some(1e-3)));
    /// assert_eq!(bright, OutputStart::DARK);
    /// assert!(dim.specular < bright.specular && dim.diffuse < bright.diffuse && dim.albedo < bright.albedo);
    /// ```
    pub fn for_median(median: Option<f32>) -> OutputStart {
        let Some(m) = median.filter(|m| m.is_finite() && *m > 0.0) else { return OutputStart::DARK };
        let ceiling = 2.0 * f64::from(m);
        // Never darker than this: softplus(-16) = 1e-7/sr still lets a highlight grow.
        const FLOOR: f64 = -16.0;
        let sigmoid = |x: f64| 1.0 / (1.0 + (-x).exp());
        // σ⁻¹(p) = ln(p / (1 - p)), at p = π · ceiling < 1 (the fixed starts are below 1/π)
        let logit_of_brdf = |f: f64| {
            let p = std::f64::consts::PI * f;
            (p / (1.0 - p)).ln().max(FLOOR) as f32
        };
        let specular = if f64::from(SPECULAR_START).exp().ln_1p() > ceiling {
            // softplus⁻¹(y) = ln(eʸ - 1)
            ceiling.exp_m1().ln().max(FLOOR) as f32
        } else {
            SPECULAR_START
        };
        let diffuse = if sigmoid(f64::from(DIFFUSE_START)) / std::f64::consts::PI > ceiling {
            logit_of_brdf(ceiling)
        } else {
            DIFFUSE_START
        };
        let albedo_ceiling = 10.0 * f64::from(m);
        let albedo = if 0.5 / std::f64::consts::PI > albedo_ceiling { logit_of_brdf(albedo_ceiling) } else { 0.0 };
        OutputStart { specular, diffuse, albedo }
    }
}

/// A model: its configuration, networks and object parameters.
pub struct Model {
    pub config: Config,
    pub nets: Vec<Mlp>,
    /// Per-object raw parameters (FMBRDF's NDF normalisation), `[n_object]`.
    pub object: Option<Var>,
}

impl Model {
    /// A freshly initialised model; the same seed gives the same weights. Layers start as PyTorch's
    /// `nn.Linear`, then the outputs are shifted to [`OutputStart::DARK`].
    pub fn init(config: Config, seed: u64, device: &Device) -> Result<Model> {
        Model::init_at(config, seed, device, OutputStart::DARK)
    }

    /// [`Model::init`] with the outputs starting at `start` (a fit starts at [`OutputStart::for_median`]
    /// of its data).
    pub fn init_at(config: Config, seed: u64, device: &Device, start: OutputStart) -> Result<Model> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        let nets: Vec<Mlp> = config.nets().into_iter().map(|d| Mlp::init(d, &mut rng, device)).collect::<Result<_>>()?;
        // The specular (Single MLP: whole) output is the last network; the diffuse one is the
        // position-only network before it (Additive Shared: the diffuse head after the trunk).
        match config.kind {
            Kind::Parametric(_) => nets[nets.len() - 1].shift_output_bias(3, start.albedo)?,
            Kind::SingleMlp => nets[nets.len() - 1].shift_output_bias(3, start.specular)?,
            Kind::AdditiveSeparate | Kind::AdditiveShared => {
                nets[nets.len() - 1].shift_output_bias(3, start.specular)?;
                nets[nets.len() - 2].shift_output_bias(3, start.diffuse)?;
            }
        }
        let object = match config.n_object() {
            0 => None,
            n => Some(Var::from_vec(parametric::initial_object(&config), n, device)?),
        };
        Ok(Model { config, nets, object })
    }

    /// All variables in file order.
    pub fn vars(&self) -> Vec<&Var> {
        let mut v: Vec<&Var> = self.nets.iter().flat_map(Mlp::vars).collect();
        v.extend(self.object.iter());
        v
    }

    /// The weight vector in file order (`ModelHeader::n_weights` values).
    pub fn weights(&self) -> Result<Vec<f32>> {
        let mut out = Vec::with_capacity(self.config.n_weights());
        for n in &self.nets {
            n.write_weights(&mut out)?;
        }
        if let Some(o) = &self.object {
            out.extend(o.as_tensor().to_vec1::<f32>()?);
        }
        Ok(out)
    }

    /// Loads a weight vector in file order.
    pub fn set_weights(&self, values: &[f32]) -> Result<()> {
        if values.len() != self.config.n_weights() {
            candle_core::bail!(
                "{} weights given for {} ({} expected)",
                values.len(),
                self.config.name(),
                self.config.n_weights()
            );
        }
        mlp::read_into(&self.vars(), values).map(|_| ())
    }

    /// The networks' outputs before the head, wired as docs/models.md "Models" says.
    pub fn raw(&self, x: &Inputs) -> Result<Raw> {
        let n = &self.nets;
        Ok(match self.config.kind {
            Kind::Parametric(kind) => {
                let raw = n[0].forward(&x.position, &x.ones)?;
                Raw::Brdf(parametric::eval(kind, &raw, self.object.as_ref().map(Var::as_tensor), x)?)
            }
            Kind::SingleMlp if n.len() == 1 => Raw::Softplus(n[0].forward(&x.joint, &x.ones)?),
            Kind::SingleMlp => {
                let trunk = n[0].forward(&x.position, &x.ones)?;
                Raw::Softplus(n[1].forward(&Tensor::cat(&[&trunk, &x.angles], 1)?, &x.ones)?)
            }
            Kind::AdditiveSeparate => {
                Raw::Additive { d: n[0].forward(&x.position, &x.ones)?, s: n[1].forward(&x.joint, &x.ones)? }
            }
            Kind::AdditiveShared => {
                let trunk = n[0].forward(&x.position, &x.ones)?;
                let d = n[1].forward(&trunk, &x.ones)?;
                let s = n[2].forward(&Tensor::cat(&[&trunk, &x.angles], 1)?, &x.ones)?;
                Raw::Additive { d, s }
            }
        })
    }

    /// The forward pass of docs/models.md "Models": [`Model::raw`], then the head.
    pub fn forward(&self, x: &Inputs) -> Result<Output> {
        let (f, diffuse, specular) = match self.raw(x)? {
            Raw::Brdf(f) => (f, None, None),
            Raw::Softplus(out) => (activation::softplus(&out)?, None, None),
            Raw::Additive { d, s } => self.additive(&d, &s)?,
        };
        // Invalid pairs are black in the core; multiplying keeps their gradient at zero too.
        let f = f.broadcast_mul(&x.valid)?;
        Ok(Output { f, diffuse, specular })
    }

    /// `f_d = σ(d)/π`, `f_s = softplus(s[0..3])`, and `f = f_d + f_s` or, enhanced (Eq. 8),
    /// `f = (1 - ξ) ∘ f_d + f_s` with `ξ = σ(s[3..6])`.
    fn additive(&self, d: &Tensor, s: &Tensor) -> Result<(Tensor, Option<Tensor>, Option<Tensor>)> {
        let f_d = (activation::sigmoid(d)? * std::f64::consts::FRAC_1_PI)?;
        let f_s = activation::softplus(&s.narrow(1, 0, 3)?)?;
        let f = if self.config.has_xi() {
            let xi = activation::sigmoid(&s.narrow(1, 3, 3)?)?;
            ((1.0 - xi)? * &f_d)?.add(&f_s)?
        } else {
            f_d.add(&f_s)?
        };
        Ok((f, Some(f_d), Some(f_s)))
    }
}

/// The model's BRDF values as plain numbers, `[N][3]`.
pub fn to_rgb(t: &Tensor) -> Result<Vec<[f32; 3]>> {
    Ok(t.to_vec2::<f32>()?.into_iter().map(|r| [r[0], r[1], r[2]]).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::RngExt;

    /// Every purely neural variant starts dark — near `softplus(SPECULAR_START)` (+ `σ(DIFFUSE_START)/π`
    /// for the additive ones), far below the `0.69 + 0.16`/sr of an unshifted start — at random
    /// positions and directions, and its output still responds to the inputs (it is not a constant).
    #[test]
    fn neural_models_start_dark() {
        let device = Device::Cpu;
        let position = PositionEncoding::Intrinsic { k: 8 };
        let n = 256;
        let (wi, wo) = crate::toy::direction_pairs(n, 7);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let pos: Vec<f32> = (0..n * position.input_len()).map(|_| rng.random_range(-1.0..1.0)).collect();
        let start = (1.0 + (SPECULAR_START as f64).exp()).ln() + 1.0 / (1.0 + (-DIFFUSE_START as f64).exp()) / std::f64::consts::PI;
        for config in arch::study_variants(position, Reciprocity::Exact).into_iter().filter(|c| !matches!(c.kind, Kind::Parametric(_))) {
            let model = Model::init(config, 5, &device).unwrap();
            let x = Inputs::build(&config, &RawBatch { position: &pos, wi: &wi, wo: &wo, swap: None }, &device).unwrap();
            let f: Vec<f32> = to_rgb(&model.forward(&x).unwrap().f).unwrap().into_iter().flatten().filter(|&v| v > 0.0).collect();
            assert!(f.len() > n, "{}: too few valid pairs", config.name());
            let mean = f.iter().map(|&v| f64::from(v)).sum::<f64>() / f.len() as f64;
            let max = f.iter().cloned().fold(0.0f32, f32::max);
            let min = f.iter().cloned().fold(f32::INFINITY, f32::min);
            assert!(mean < 2.0 * start && mean > 0.25 * start, "{}: mean {mean} vs start {start}", config.name());
            assert!(max < 0.2, "{}: max {max}", config.name());
            assert!(max > 1.05 * min, "{}: constant output {min}..{max}", config.name());
        }
    }

    /// A dark material's start puts each neural part at twice the median and the parametric albedo at
    /// ten times it, exactly; the built-in study materials and bright ones keep the fixed start, and no
    /// usable median keeps it too.
    #[test]
    fn output_start_follows_a_dark_material() {
        assert_eq!(OutputStart::for_median(Some(0.1)), OutputStart::DARK);
        for bad in [None, Some(0.0), Some(-1.0), Some(f32::NAN), Some(f32::INFINITY)] {
            assert_eq!(OutputStart::for_median(bad), OutputStart::DARK, "{bad:?}");
        }
        let m = 1.4e-3f64;
        let s = OutputStart::for_median(Some(m as f32));
        let f_s = f64::from(s.specular).exp().ln_1p();
        let f_d = 1.0 / (1.0 + (-f64::from(s.diffuse)).exp()) / std::f64::consts::PI;
        assert!((f_s / (2.0 * m) - 1.0).abs() < 1e-5, "f_s {f_s}");
        assert!((f_d / (2.0 * m) - 1.0).abs() < 1e-5, "f_d {f_d}");
        let albedo = 1.0 / (1.0 + (-f64::from(s.albedo)).exp());
        assert!((albedo / std::f64::consts::PI / (10.0 * m) - 1.0).abs() < 1e-5, "albedo {albedo}");
        assert_eq!(OutputStart::for_median(Some(0.018)), OutputStart::DARK, "sphere / two-lobe-metal");
        assert_eq!(OutputStart::for_median(Some(0.022)), OutputStart::DARK, "torus / clear-coat");
        // A black material starts at the floor, finite.
        let black = OutputStart::for_median(Some(1e-30));
        assert_eq!((black.specular, black.diffuse, black.albedo), (-16.0, -16.0, -16.0));
    }
}
