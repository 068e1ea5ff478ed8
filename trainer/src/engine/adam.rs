//! Adam (Kingma & Ba 2015), the optimiser of Sec. 5.2, over candle variables. The moments live in plain
//! vectors so that a checkpoint stores and restores them exactly.

use candle_core::{backprop::GradStore, Result, Tensor, Var};

/// Adam's hyper-parameters (the paper's optimiser with PyTorch's defaults).
#[derive(Clone, Copy, Debug, serde::Serialize, serde::Deserialize)]
pub struct AdamParams {
    pub beta1: f32,
    pub beta2: f32,
    pub eps: f32,
}

impl Default for AdamParams {
    fn default() -> Self {
        AdamParams { beta1: 0.9, beta2: 0.999, eps: 1e-8 }
    }
}

/// Optimiser state: step count and first/second moments per variable (file order).
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Adam {
    pub params: AdamParams,
    /// Updates applied so far.
    pub t: u64,
    #[serde(with = "crate::bits::vec2")]
    pub m: Vec<Vec<f32>>,
    #[serde(with = "crate::bits::vec2")]
    pub v: Vec<Vec<f32>>,
}

impl Adam {
    /// Zero moments for `vars`.
    pub fn new(vars: &[&Var], params: AdamParams) -> Adam {
        let sizes: Vec<usize> = vars.iter().map(|v| v.as_tensor().elem_count()).collect();
        Adam {
            params,
            t: 0,
            m: sizes.iter().map(|&n| vec![0.0; n]).collect(),
            v: sizes.iter().map(|&n| vec![0.0; n]).collect(),
        }
    }

    /// The gradients of `vars` as plain vectors (zeros for a variable the loss does not depend on).
    pub fn gradients(vars: &[&Var], grads: &GradStore) -> Result<Vec<Vec<f32>>> {
        vars.iter()
            .map(|v| match grads.get(v.as_tensor()) {
                Some(g) => g.flatten_all()?.to_vec1::<f32>(),
                None => Ok(vec![0.0; v.as_tensor().elem_count()]),
            })
            .collect()
    }

    /// One bias-corrected step with learning rate `lr`:
    /// `m ← β1 m + (1-β1) g`, `v ← β2 v + (1-β2) g²`, `θ ← θ - lr m̂ / (sqrt(v̂) + ε)`.
    pub fn step(&mut self, vars: &[&Var], grads: &[Vec<f32>], lr: f32) -> Result<()> {
        if vars.len() != self.m.len() {
            candle_core::bail!("optimiser state for {} variables, {} given", self.m.len(), vars.len());
        }
        self.t += 1;
        let AdamParams { beta1: b1, beta2: b2, eps } = self.params;
        let c1 = 1.0 - b1.powi(self.t as i32);
        let c2 = 1.0 - b2.powi(self.t as i32);
        for (i, var) in vars.iter().enumerate() {
            let mut theta = var.as_tensor().flatten_all()?.to_vec1::<f32>()?;
            let (m, v, g) = (&mut self.m[i], &mut self.v[i], &grads[i]);
            for k in 0..theta.len() {
                m[k] = b1 * m[k] + (1.0 - b1) * g[k];
                v[k] = b2 * v[k] + (1.0 - b2) * g[k] * g[k];
                theta[k] -= lr * (m[k] / c1) / ((v[k] / c2).sqrt() + eps);
            }
            var.set(&Tensor::from_vec(theta, var.as_tensor().shape(), var.as_tensor().device())?)?;
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use candle_core::Device;

    /// Adam walks a quadratic to its minimum; its first step has length `lr` per coordinate.
    #[test]
    fn minimises_a_quadratic() {
        let x = Var::from_slice(&[3.0f32, -2.0], 2, &Device::Cpu).unwrap();
        let vars = [&x];
        let mut adam = Adam::new(&vars, AdamParams::default());
        for i in 0..500 {
            let loss = (x.as_tensor() - 1.0).unwrap().sqr().unwrap().sum_all().unwrap();
            let g = Adam::gradients(&vars, &loss.backward().unwrap()).unwrap();
            adam.step(&vars, &g, 0.05).unwrap();
            if i == 0 {
                let v = x.as_tensor().to_vec1::<f32>().unwrap();
                assert!((v[0] - 2.95).abs() < 1e-5 && (v[1] + 1.95).abs() < 1e-5);
            }
        }
        for v in x.as_tensor().to_vec1::<f32>().unwrap() {
            assert!((v - 1.0).abs() < 1e-2, "{v}");
        }
    }
}
