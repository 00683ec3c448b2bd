//! Native inference of a trained conditional ensemble GAN generator (the GAN paper's III-A).
//!
//! Training stays in torch (`genplan.gan`); the trained weights are handed over once, and the
//! planner then draws GAN samples without Python or the GIL: a sample is one member of the
//! ensemble, chosen at random, fed Gaussian noise and a target position drawn uniformly in a box.
//! The forward pass mirrors `EnsembleGenerator.forward` and `Codec.decode` exactly (checked against
//! torch in the tests).

use std::sync::Arc;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use crate::codec::Codec;
use crate::error::{Error, Result};
use crate::planning::{PlanResult, Sampler};

/// One dense layer of every member: weights (n_net, inputs, outputs) and biases (n_net, outputs),
/// row-major.
#[derive(Debug, Clone)]
pub struct Layer {
    /// Inputs per member.
    pub inputs: usize,
    /// Outputs per member.
    pub outputs: usize,
    /// n_net x inputs x outputs numbers, row-major.
    pub weights: Vec<f64>,
    /// n_net x outputs numbers, row-major.
    pub biases: Vec<f64>,
}

/// An ensemble generator plus the codec from its output features to configurations.
#[derive(Debug, Clone)]
pub struct Generator {
    /// Members of the ensemble.
    pub n_net: usize,
    /// Length of a member's noise input (the target position, 3 numbers, follows it).
    pub noise_dim: usize,
    /// The dense layers, input first.
    pub layers: Vec<Layer>,
    /// Output features to configurations.
    pub codec: Codec,
}

impl Generator {
    /// A generator, its shapes and weights checked.
    pub fn new(n_net: usize, noise_dim: usize, layers: Vec<Layer>, mean: Vec<f64>, std: Vec<f64>, floating_base: bool) -> Result<Generator> {
        let bad = |m: String| Err(Error::Invalid(format!("GAN generator: {m}")));
        if n_net == 0 || layers.is_empty() {
            return bad("needs at least one member and one layer".into());
        }
        if layers[0].inputs != noise_dim + 3 {
            return bad(format!("the first layer takes {} inputs, expected noise ({noise_dim}) + target (3)", layers[0].inputs));
        }
        for (i, l) in layers.iter().enumerate() {
            if l.weights.len() != n_net * l.inputs * l.outputs || l.biases.len() != n_net * l.outputs {
                return bad(format!("layer {i}: weights/biases do not have the shape ({n_net}, {}, {})", l.inputs, l.outputs));
            }
            if i > 0 && layers[i - 1].outputs != l.inputs {
                return bad(format!("layer {i} takes {} inputs but layer {} gives {}", l.inputs, i - 1, layers[i - 1].outputs));
            }
            if l.weights.iter().chain(&l.biases).any(|x| !x.is_finite()) {
                return bad(format!("layer {i} has non-finite weights"));
            }
        }
        let dim = layers.last().map(|l| l.outputs).unwrap_or(0);
        if mean.len() != dim || std.len() != dim {
            return bad(format!("codec mean/std must have {dim} values"));
        }
        let codec = Codec::new(mean, std, floating_base, "GAN generator")?;
        Ok(Generator { n_net, noise_dim, layers, codec })
    }

    /// Length of a generated configuration.
    pub fn nq(&self) -> usize {
        self.codec.nq()
    }

    /// The configuration member `member` makes of `noise` and `target`; `scratch` is reused.
    pub fn generate(&self, member: usize, noise: &[f64], target: &[f64; 3], out: &mut [f64], scratch: &mut (Vec<f64>, Vec<f64>)) {
        let (h, next) = scratch;
        h.clear();
        h.extend_from_slice(noise);
        h.extend_from_slice(target);
        let last = self.layers.len() - 1;
        for (li, l) in self.layers.iter().enumerate() {
            next.clear();
            next.extend_from_slice(&l.biases[member * l.outputs..(member + 1) * l.outputs]);
            let w = &l.weights[member * l.inputs * l.outputs..(member + 1) * l.inputs * l.outputs];
            for (i, &x) in h.iter().enumerate() {
                if x == 0.0 {
                    continue;
                }
                let row = &w[i * l.outputs..(i + 1) * l.outputs];
                for (o, &wv) in next.iter_mut().zip(row) {
                    *o += x * wv;
                }
            }
            if li < last {
                next.iter_mut().for_each(|v| *v = v.max(0.0));
            }
            std::mem::swap(h, next);
        }
        self.codec.decode(h, out);
    }
}

/// GAN samples conditioned on targets drawn uniformly in a box (the paper's planning sampler).
#[derive(Debug, Clone)]
pub struct GanSampler {
    /// The trained generator.
    pub generator: Arc<Generator>,
    /// Lower corner of the target box.
    pub lower: [f64; 3],
    /// Upper corner of the target box.
    pub upper: [f64; 3],
    rng: StdRng,
    scratch: (Vec<f64>, Vec<f64>),
}

impl GanSampler {
    /// A sampler drawing targets in `lower..=upper`; `seed` seeds its random numbers.
    pub fn new(generator: Arc<Generator>, lower: [f64; 3], upper: [f64; 3], seed: u64) -> Result<GanSampler> {
        if !crate::planning::valid_box(&lower, &upper) {
            return Err(Error::Invalid(format!("GAN sampler: bad target box {lower:?} .. {upper:?}")));
        }
        Ok(GanSampler { generator, lower, upper, rng: StdRng::seed_from_u64(seed), scratch: Default::default() })
    }
}

impl Sampler for GanSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let nq = self.generator.nq();
        let mut noise = vec![0.0; self.generator.noise_dim];
        for row in out.chunks_mut(nq).take(n) {
            let member = self.rng.random_range(0..self.generator.n_net);
            let target = crate::planning::uniform_in_box(&mut self.rng, &self.lower, &self.upper);
            for z in noise.iter_mut() {
                *z = crate::planning::standard_normal(&mut self.rng);
            }
            let generator = self.generator.clone();
            generator.generate(member, &noise, &target, row, &mut self.scratch);
        }
        Ok(())
    }
}
