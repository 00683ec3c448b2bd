//! The learned samplers' feature space (python/genplan/gan/model.py, `Codec`): a model outputs
//! standardised features, which are mapped back to configurations here. Fixed-base robots: the
//! features are the joint angles. A free-flyer: base position (3), base rotation vector (3), then
//! the joints; the configuration holds the base as [x, y, z, qx, qy, qz, qw].

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
        Ok(Codec { mean, std, floating_base })
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
        assert!(Codec::new(vec![0.0; 2], vec![1.0], false, "t").is_err());
    }
}
