//! The learned samplers' feature space (python/genplan/gan/model.py, `Codec`): a model outputs
//! standardised features, which are mapped back to configurations here. Fixed-base robots: the
//! features are the joint angles. A free-flyer: base position (3), base rotation vector (3), then
//! the joints; the configuration holds the base as [x, y, z, qx, qy, qz, qw]. A continuous joint
//! is its [cos, sin] pair as the configuration holds it (two features), scaled back to unit norm
//! when decoded.

use crate::error::{Error, Result};

/// Feature standardisation and the free-flyer's rotation vector, shared by the GAN
/// (`crate::gan`) and the flow (`crate::flow`) samplers.
#[derive(Debug, Clone)]
pub struct Codec {
    /// features = output * std + mean.
    pub mean: Vec<f64>,
    /// See `mean`.
    pub std: Vec<f64>,
    /// Features start with [base position (3), base rotation vector (3)].
    pub floating_base: bool,
    /// Configuration indices of each continuous joint's cos (its sin follows), normalised by
    /// [`Codec::decode`].
    pub continuous: Vec<usize>,
}

impl Codec {
    /// A codec, its sizes checked; `what` names the model in errors.
    pub fn new(mean: Vec<f64>, std: Vec<f64>, floating_base: bool, what: &str) -> Result<Codec> {
        let bad = |m: String| Err(Error::Invalid(format!("{what}: {m}")));
        if mean.is_empty() || mean.len() != std.len() {
            return bad(format!("codec mean and std must have the same non-zero length, got {} and {}", mean.len(), std.len()));
        }
        if mean.iter().chain(&std).any(|x| !x.is_finite()) {
            return bad("codec mean/std hold non-finite values".into());
        }
        if floating_base && mean.len() < 6 {
            return bad("a free-flyer codec needs at least 6 features".into());
        }
        Ok(Codec { mean, std, floating_base, continuous: Vec::new() })
    }

    /// The codec with the continuous joints' pairs at configuration indices `continuous` (each
    /// pair inside the configuration and apart from the others and the free-flyer's 7 values);
    /// `what` names the model in errors.
    pub fn with_continuous(mut self, continuous: Vec<usize>, what: &str) -> Result<Codec> {
        let first = if self.floating_base { 7 } else { 0 };
        let mut previous_end = first;
        for &i in &continuous {
            if i < previous_end || i + 2 > self.nq() {
                return Err(Error::Invalid(format!(
                    "{what}: continuous joint index {i} must be increasing, at least {first} and leave room for [cos, sin] in {} values",
                    self.nq()
                )));
            }
            previous_end = i + 2;
        }
        self.continuous = continuous;
        Ok(self)
    }

    /// Number of features.
    pub fn dim(&self) -> usize {
        self.mean.len()
    }

    /// Length of a configuration.
    pub fn nq(&self) -> usize {
        self.mean.len() + usize::from(self.floating_base)
    }

    /// The configuration (`out`, nq numbers) of standardised features `x` (dim numbers).
    pub fn decode(&self, x: &[f64], out: &mut [f64]) {
        let feature = |i: usize| x[i] * self.std[i] + self.mean[i];
        if !self.floating_base {
            for (i, o) in out.iter_mut().enumerate().take(self.dim()) {
                *o = feature(i);
            }
            self.normalise_pairs(out);
            return;
        }
        let rv = [feature(3), feature(4), feature(5)];
        let angle = (rv[0] * rv[0] + rv[1] * rv[1] + rv[2] * rv[2] + 1e-12).sqrt();
        let s = (angle / 2.0).sin() / angle;
        for (k, o) in out.iter_mut().enumerate().take(3) {
            *o = feature(k);
        }
        out[3] = rv[0] * s;
        out[4] = rv[1] * s;
        out[5] = rv[2] * s;
        out[6] = (angle / 2.0).cos();
        for i in 6..self.dim() {
            out[i + 1] = feature(i);
        }
        self.normalise_pairs(out);
    }

    /// Each continuous joint's [cos, sin] scaled to unit norm, the norm floored as the torch
    /// codec's (samplers/base.py `Codec.decode`): sqrt(c^2 + s^2 + 1e-12).
    fn normalise_pairs(&self, out: &mut [f64]) {
        for &i in &self.continuous {
            let norm = (out[i] * out[i] + out[i + 1] * out[i + 1] + 1e-12).sqrt();
            out[i] /= norm;
            out[i + 1] /= norm;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decode_is_affine_for_a_fixed_base_and_a_unit_quaternion_for_a_free_flyer() {
        let c = Codec::new(vec![1.0, -2.0], vec![0.5, 2.0], false, "t").unwrap();
        let mut q = [0.0; 2];
        c.decode(&[2.0, 1.0], &mut q);
        assert_eq!(q, [2.0, 0.0]);
        let c = Codec::new(vec![0.0; 7], vec![1.0; 7], true, "t").unwrap();
        let mut q = [0.0; 8];
        let half = std::f64::consts::FRAC_PI_4; // a rotation of pi/2 about z
        c.decode(&[1.0, 2.0, 3.0, 0.0, 0.0, 2.0 * half, 0.7], &mut q);
        assert_eq!(&q[..3], &[1.0, 2.0, 3.0]);
        assert!((q[5] - half.sin()).abs() < 1e-12 && (q[6] - half.cos()).abs() < 1e-12 && q[3] == 0.0 && q[4] == 0.0);
        assert_eq!(q[7], 0.7);
        assert!(Codec::new(vec![0.0; 5], vec![1.0; 5], true, "t").is_err());
        // a continuous joint's pair comes back on the unit circle, the other features unchanged
        let c = Codec::new(vec![0.0; 3], vec![1.0; 3], false, "t").unwrap().with_continuous(vec![1], "t").unwrap();
        let mut q = [0.0; 3];
        c.decode(&[0.5, 3.0, 4.0], &mut q);
        assert_eq!(q[0], 0.5);
        assert!((q[1] - 0.6).abs() < 1e-12 && (q[2] - 0.8).abs() < 1e-12);
        let c = Codec::new(vec![0.0; 3], vec![1.0; 3], false, "t").unwrap();
        assert!(c.clone().with_continuous(vec![2], "t").is_err()); // no room for the sin
        assert!(c.clone().with_continuous(vec![0, 1], "t").is_err()); // overlapping pairs
        let f = Codec::new(vec![0.0; 8], vec![1.0; 8], true, "t").unwrap();
        assert!(f.clone().with_continuous(vec![6], "t").is_err()); // inside the free-flyer's values
        assert!(f.with_continuous(vec![7], "t").is_ok());
        assert!(Codec::new(vec![0.0; 2], vec![1.0], false, "t").is_err());
    }
}
