//! Output nonlinearities of Sec. 4.1 as candle ops with their own backward pass.
//!
//! They map their tensors through the core's [`nbrdf::math::softplus_slice`] and
//! [`nbrdf::math::sigmoid_slice`], the output maps of the exported models (vectorised where the CPU
//! allows, and per value a function of that value alone), so the candle twin and the exported model
//! apply bitwise the same function to the same pre-activation;
//! composing them from candle's `exp`/`log` would differ by rounding and, for sigmoid, overflow to NaN
//! gradients at large |x|.

use candle_core::{CpuStorage, CustomOp1, Layout, Result, Shape, Tensor};

/// Which scalar function an [`Elementwise`] op applies.
#[derive(Clone, Copy, Debug)]
enum Func {
    Softplus,
    Sigmoid,
}

impl Func {
    fn apply(self, x: &mut [f32]) {
        match self {
            Func::Softplus => nbrdf::math::softplus_slice(x),
            Func::Sigmoid => nbrdf::math::sigmoid_slice(x),
        }
    }
}

struct Elementwise(Func);

impl CustomOp1 for Elementwise {
    fn name(&self) -> &'static str {
        match self.0 {
            Func::Softplus => "softplus",
            Func::Sigmoid => "sigmoid",
        }
    }

    fn cpu_fwd(&self, storage: &CpuStorage, layout: &Layout) -> Result<(CpuStorage, Shape)> {
        let CpuStorage::F32(data) = storage else {
            candle_core::bail!("{} is implemented for f32 only", self.name())
        };
        let Some((start, end)) = layout.contiguous_offsets() else {
            candle_core::bail!("{} expects a contiguous tensor", self.name())
        };
        let mut out = data[start..end].to_vec();
        self.0.apply(&mut out);
        Ok((CpuStorage::F32(out), layout.shape().clone()))
    }

    /// softplus' = σ(x); σ' = σ(x) (1 - σ(x)) = res (1 - res).
    fn bwd(&self, arg: &Tensor, res: &Tensor, grad_res: &Tensor) -> Result<Option<Tensor>> {
        let d = match self.0 {
            Func::Softplus => arg.contiguous()?.apply_op1_no_bwd(&Elementwise(Func::Sigmoid))?,
            Func::Sigmoid => (res * (1.0 - res)?)?,
        };
        Ok(Some(grad_res.mul(&d)?))
    }
}

/// `softplus(x) = ln(1 + e^x)` element-wise (positivity of Sec. 4.1, Eq. 2).
pub fn softplus(x: &Tensor) -> Result<Tensor> {
    x.contiguous()?.apply_op1(Elementwise(Func::Softplus))
}

/// Logistic sigmoid `1 / (1 + e^-x)` element-wise (parameters in [0, 1], Sec. 4.1).
pub fn sigmoid(x: &Tensor) -> Result<Tensor> {
    x.contiguous()?.apply_op1(Elementwise(Func::Sigmoid))
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::{Device, Var};

    /// The hand-written backward passes agree with central differences.
    #[test]
    fn gradients_match_finite_differences() {
        let xs = [-30.0f32, -2.0, -0.3, 0.0, 0.7, 4.0, 30.0];
        let x = Var::from_slice(&xs, xs.len(), &Device::Cpu).unwrap();
        for (f, name) in [(softplus as fn(&Tensor) -> Result<Tensor>, "softplus"), (sigmoid, "sigmoid")] {
            let y = f(x.as_tensor()).unwrap();
            let g = y.sum_all().unwrap().backward().unwrap();
            let g = g.get(x.as_tensor()).unwrap().to_vec1::<f32>().unwrap();
            for (i, &xi) in xs.iter().enumerate() {
                let h = 1e-2f64;
                let e = |v: f64| {
                    let t = Tensor::new(&[v as f32], &Device::Cpu).unwrap();
                    f(&t).unwrap().to_vec1::<f32>().unwrap()[0] as f64
                };
                let fd = (e(xi as f64 + h) - e(xi as f64 - h)) / (2.0 * h);
                assert!((fd - g[i] as f64).abs() < 1e-3, "{name}'({xi}): {} vs {fd}", g[i]);
                assert!(g[i].is_finite());
            }
        }
    }
}
