//! Native inference of a trained conditional flow-matching sampler (python/genplan/gan/flow.py).
//!
//! The model is a velocity field `v(x, t, c)` over the standardised features `x` (see
//! `crate::codec`), conditioned on the standardised target position `c`: a sample starts from
//! Gaussian noise at `t = 0` and follows `steps` Euler steps of `v` to `t = 1`, then is decoded
//! into a configuration. Training stays in torch; the weights are handed over once, and the planner
//! then draws samples without Python or the GIL, a batch at a time: every layer is one matrix
//! product over the batch (the forward pass mirrors `FlowNet.forward` and `FlowModel.generate`,
//! checked against torch in tests/test_flow.py).

use std::sync::Arc;

use nalgebra::DMatrix;
use rand::rngs::StdRng;
use rand::SeedableRng;

use crate::codec::Codec;
use crate::error::{Error, Result};
use crate::planning::{PlanResult, Sampler};

/// Samples generated per matrix product (bounds the scratch memory of a large `sample(n)`).
const BLOCK: usize = 256;

/// One dense layer, `y = W x + b`, in float32 as trained (the matrix products of a batch run at
/// twice the float64 rate; the decoded configurations are float64).
#[derive(Debug, Clone)]
pub struct Dense {
    /// (outputs, inputs).
    pub weight: DMatrix<f32>,
    /// outputs numbers.
    pub bias: Vec<f32>,
}

/// A velocity field MLP (SiLU between layers) with its codec and integration settings.
#[derive(Debug, Clone)]
pub struct Flow {
    /// Input first; the first layer takes [features, t, standardised target].
    pub layers: Vec<Dense>,
    /// Euler steps from noise to a sample.
    pub steps: usize,
    /// Target standardisation: c = (target - mean) / std.
    pub target_mean: [f64; 3],
    /// See `target_mean`.
    pub target_std: [f64; 3],
    /// Features to configurations.
    pub codec: Codec,
}

impl Flow {
    /// A flow, its shapes and numbers checked.
    pub fn new(layers: Vec<Dense>, steps: usize, target_mean: [f64; 3], target_std: [f64; 3], codec: Codec) -> Result<Flow> {
        let bad = |m: String| Err(Error::Invalid(format!("flow sampler: {m}")));
        let dim = codec.dim();
        if layers.is_empty() || steps == 0 {
            return bad("needs at least one layer and one step".into());
        }
        if layers[0].weight.ncols() != dim + 4 {
            return bad(format!("the first layer takes {} inputs, expected features ({dim}) + t (1) + target (3)", layers[0].weight.ncols()));
        }
        if layers.last().map(|l| l.weight.nrows()) != Some(dim) {
            return bad(format!("the last layer must give {dim} outputs (the features)"));
        }
        for (i, l) in layers.iter().enumerate() {
            if l.bias.len() != l.weight.nrows() {
                return bad(format!("layer {i}: {} biases for {} outputs", l.bias.len(), l.weight.nrows()));
            }
            if i > 0 && layers[i - 1].weight.nrows() != l.weight.ncols() {
                return bad(format!("layer {i} takes {} inputs but layer {} gives {}", l.weight.ncols(), i - 1, layers[i - 1].weight.nrows()));
            }
            if l.weight.iter().chain(&l.bias).any(|x| !x.is_finite()) {
                return bad(format!("layer {i} has non-finite weights"));
            }
        }
        if target_mean.iter().chain(&target_std).any(|x| !x.is_finite()) || target_std.iter().any(|&s| s <= 0.0) {
            return bad(format!("bad target standardisation: mean {target_mean:?}, std {target_std:?}"));
        }
        Ok(Flow { layers, steps, target_mean, target_std, codec })
    }

    /// Length of a generated configuration.
    pub fn nq(&self) -> usize {
        self.codec.nq()
    }

    /// The configurations (`out`, n x nq, row-major) of `noise` (n x dim) and `targets` (n x 3).
    pub fn generate(&self, noise: &[f64], targets: &[f64], out: &mut [f64]) {
        let (dim, nq) = (self.codec.dim(), self.nq());
        let n = targets.len() / 3;
        let mut x = vec![0.0; dim]; // a sample's features, float64 for the codec
        for start in (0..n).step_by(BLOCK) {
            let m = BLOCK.min(n - start);
            // column j: [x, t, c] of sample start + j
            let mut input = DMatrix::<f32>::zeros(dim + 4, m);
            for j in 0..m {
                let mut col = input.column_mut(j);
                for k in 0..dim {
                    col[k] = noise[(start + j) * dim + k] as f32;
                }
                for k in 0..3 {
                    col[dim + 1 + k] = ((targets[(start + j) * 3 + k] - self.target_mean[k]) / self.target_std[k]) as f32;
                }
            }
            let dt = 1.0 / self.steps as f32;
            for s in 0..self.steps {
                input.row_mut(dim).fill(s as f32 * dt);
                let v = self.velocity(&input);
                for j in 0..m {
                    for k in 0..dim {
                        input[(k, j)] += dt * v[(k, j)];
                    }
                }
            }
            for j in 0..m {
                x.iter_mut().zip(input.column(j).iter()).for_each(|(a, &v)| *a = f64::from(v));
                self.codec.decode(&x, &mut out[(start + j) * nq..(start + j + 1) * nq]);
            }
        }
    }

    /// The velocity (dim x m) at the columns of `input`.
    fn velocity(&self, input: &DMatrix<f32>) -> DMatrix<f32> {
        let last = self.layers.len() - 1;
        let mut h = &self.layers[0].weight * input;
        for (li, l) in self.layers.iter().enumerate() {
            if li > 0 {
                h = &l.weight * &h;
            }
            for mut col in h.column_iter_mut() {
                for (v, b) in col.iter_mut().zip(&l.bias) {
                    *v += b;
                    if li < last {
                        *v /= 1.0 + (-*v).exp(); // SiLU
                    }
                }
            }
        }
        h
    }
}

/// Flow samples conditioned on targets drawn uniformly in a box (as `crate::gan::GanSampler`).
#[derive(Debug, Clone)]
pub struct FlowSampler {
    /// The trained flow.
    pub flow: Arc<Flow>,
    /// Lower corner of the target box.
    pub lower: [f64; 3],
    /// Upper corner of the target box.
    pub upper: [f64; 3],
    rng: StdRng,
}

impl FlowSampler {
    /// A sampler drawing targets in `lower..=upper`; `seed` seeds its random numbers.
    pub fn new(flow: Arc<Flow>, lower: [f64; 3], upper: [f64; 3], seed: u64) -> Result<FlowSampler> {
        if !crate::planning::valid_box(&lower, &upper) {
            return Err(Error::Invalid(format!("flow sampler: bad target box {lower:?} .. {upper:?}")));
        }
        Ok(FlowSampler { flow, lower, upper, rng: StdRng::seed_from_u64(seed) })
    }
}

impl Sampler for FlowSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let dim = self.flow.codec.dim();
        let mut targets = vec![0.0; 3 * n];
        let mut noise = vec![0.0; dim * n];
        for i in 0..n {
            // row by row, target then noise: a sample of n rows in chunks draws the same stream
            let target = crate::planning::uniform_in_box(&mut self.rng, &self.lower, &self.upper);
            targets[3 * i..3 * i + 3].copy_from_slice(&target);
            for k in 0..dim {
                noise[i * dim + k] = crate::planning::standard_normal(&mut self.rng);
            }
        }
        self.flow.generate(&noise, &targets, &mut out[..n * self.flow.nq()]);
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A one-layer flow with velocity `W [x, t, c] + b` integrates as the explicit Euler sum.
    #[test]
    fn euler_steps_of_a_linear_field() {
        // dim 1: v = 0.5 x + 1.0 t + 2.0 c0 + 0.25
        let w = DMatrix::from_row_slice(1, 5, &[0.5, 1.0, 2.0, 0.0, 0.0]);
        let codec = Codec::new(vec![0.0], vec![1.0], false, "t").unwrap();
        let flow = Flow::new(vec![Dense { weight: w, bias: vec![0.25] }], 4, [1.0, 0.0, 0.0], [2.0, 1.0, 1.0], codec).unwrap();
        let (x0, target) = (0.3, [2.0, 5.0, -1.0]);
        let c0 = (target[0] - 1.0) / 2.0;
        let mut x: f32 = x0 as f32;
        for s in 0..4 {
            x += 0.25 * (0.5 * x + s as f32 * 0.25 + 2.0 * c0 as f32 + 0.25);
        }
        let mut out = [0.0];
        flow.generate(&[x0], &target, &mut out);
        assert!((out[0] - f64::from(x)).abs() < 1e-6, "{} vs {x}", out[0]);
    }

    #[test]
    fn shapes_are_checked() {
        let codec = Codec::new(vec![0.0; 2], vec![1.0; 2], false, "t").unwrap();
        let layer = |o: usize, i: usize| Dense { weight: DMatrix::zeros(o, i), bias: vec![0.0; o] };
        assert!(Flow::new(vec![layer(2, 6)], 2, [0.0; 3], [1.0; 3], codec.clone()).is_ok());
        assert!(Flow::new(vec![layer(2, 5)], 2, [0.0; 3], [1.0; 3], codec.clone()).is_err());
        assert!(Flow::new(vec![layer(4, 6), layer(2, 3)], 2, [0.0; 3], [1.0; 3], codec.clone()).is_err());
        assert!(Flow::new(vec![layer(2, 6)], 0, [0.0; 3], [1.0; 3], codec.clone()).is_err());
        assert!(Flow::new(vec![layer(2, 6)], 2, [0.0; 3], [0.0, 1.0, 1.0], codec).is_err());
    }
}
