//! Samplers: the [`Sampler`] trait and the native ones, uniform within the joint limits
//! ([`UniformSampler`], optionally with a free-flyer base drawn in a box, its numbers random or
//! a seeded [`Halton`] sequence: [`Sampling`]), rows of a data set
//! ([`DataSampler`]) and the paper's hybrid ([`MixtureSampler`]); [`valid_box`] checks the boxes
//! they (and the GAN sampler) draw in.

use std::sync::Arc;

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::{Named, PlanError, PlanResult};
use crate::kinematics::{KinematicModel, Motion};
use crate::lie::unit_quaternion;

/// `Err(PlanError::Input(msg))`: a native sampler's constructor got a bad argument.
fn input<T>(msg: impl Into<String>) -> PlanResult<T> {
    Err(PlanError::Input(msg.into()))
}

/// Draws configurations.
pub trait Sampler: Send {
    /// Fill `out` (n rows of nq, row-major) with n configurations.
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()>;
}

/// A standard normal number from `rng` (Box-Muller on a uniform in (0, 1], so its magnitude is at
/// most sqrt(106 ln 2) = 8.57): the learned samplers' noise (`crate::gan`, `crate::flow`).
pub fn standard_normal(rng: &mut impl rand::Rng) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random::<f64>();
    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
}

/// A point uniform in the box `lower..upper` (a degenerate side gives its bound): the learned
/// samplers' targets (`crate::gan`, `crate::flow`).
pub fn uniform_in_box(rng: &mut impl rand::Rng, lower: &[f64; 3], upper: &[f64; 3]) -> [f64; 3] {
    std::array::from_fn(|k| if upper[k] > lower[k] { rng.random_range(lower[k]..upper[k]) } else { lower[k] })
}

/// True when `lower..=upper` is a box: finite bounds, each lower <= upper, and a finite width
/// (so that it can be sampled uniformly; -1e308..1e308 cannot) (the samplers' target and base
/// boxes).
pub fn valid_box(lower: &[f64; 3], upper: &[f64; 3]) -> bool {
    (0..3).all(|k| sampleable(lower[k], upper[k]))
}

/// `lower..=upper` can be sampled uniformly: finite, not reversed, of finite width.
fn sampleable(lower: f64, upper: f64) -> bool {
    lower.is_finite() && upper.is_finite() && lower <= upper && (upper - lower).is_finite()
}

/// `out` holds `n` rows of `nq` (the [`Sampler::sample`] contract), as the samplers check it.
fn check_out(what: &str, n: usize, nq: usize, out: &[f64]) -> PlanResult<()> {
    match n.checked_mul(nq) {
        Some(len) if out.len() >= len => Ok(()),
        _ => input(format!("{what}: {n} rows of {nq} do not fit in an output of {} numbers", out.len())),
    }
}

/// How the uniform sampler draws its numbers ([`Settings::sampling`](super::Settings::sampling)).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Sampling {
    /// Independent pseudo-random numbers (a seeded `StdRng`).
    #[default]
    Random,
    /// A low-discrepancy [`Halton`] sequence, shifted by the seed: the samples fill the box
    /// evenly from the first ones on (no clusters, no holes), and runs of different seeds differ.
    Halton,
}

impl Named for Sampling {
    const NAMES: &'static [(&'static str, Sampling)] = &[("random", Sampling::Random), ("halton", Sampling::Halton)];
    const WHAT: &'static str = "sampling";
}

/// The first `n` primes.
fn primes(n: usize) -> Vec<u64> {
    let mut out: Vec<u64> = Vec::with_capacity(n);
    let mut k = 2u64;
    while out.len() < n {
        if out.iter().take_while(|&&p| p * p <= k).all(|&p| k % p != 0) {
            out.push(k);
        }
        k += 1;
    }
    out
}

/// The radical inverse of `i` in `base`: its base-`base` digits mirrored about the point, in
/// [0, 1).
fn radical_inverse(base: u64, mut i: u64) -> f64 {
    let inv = 1.0 / base as f64;
    let (mut f, mut r) = (inv, 0.0);
    while i > 0 {
        r += f * (i % base) as f64;
        i /= base;
        f *= inv;
    }
    r
}

/// A Halton sequence in the unit cube of `dims` dimensions (coordinate k the radical inverse of
/// the index in the k-th prime), randomised per seed by a Cranley-Patterson rotation: a shift
/// drawn uniformly in the cube added to every point modulo 1 (which keeps the sequence's low
/// discrepancy), and a seeded start index. Every coordinate is in [0, 1).
#[derive(Debug, Clone)]
pub struct Halton {
    bases: Vec<u64>,
    shift: Vec<f64>,
    index: u64,
}

impl Halton {
    /// The sequence of `dims` coordinates for `seed` (the same seed, the same points).
    pub fn new(dims: usize, seed: u64) -> Halton {
        let mut rng = StdRng::seed_from_u64(seed);
        let shift = (0..dims).map(|_| rng.random::<f64>()).collect();
        // index 0 is the origin of every base: start past it, at a seeded place
        Halton { bases: primes(dims), shift, index: 1 + rng.random_range(0..1024u64) }
    }

    /// The number of coordinates of a point.
    pub fn dims(&self) -> usize {
        self.bases.len()
    }

    /// Write the next point into `out` (its first [`dims`](Self::dims) numbers).
    pub fn next_into(&mut self, out: &mut [f64]) {
        for ((o, &b), &s) in out.iter_mut().zip(&self.bases).zip(&self.shift) {
            let x = radical_inverse(b, self.index) + s;
            *o = if x >= 1.0 { x - 1.0 } else { x };
        }
        self.index += 1;
    }
}

/// `lo + u (hi - lo)` for u in [0, 1), held within `lo..=hi` against rounding.
fn scale(u: f64, lo: f64, hi: f64) -> f64 {
    (lo + u * (hi - lo)).clamp(lo, hi)
}

/// Uniform within the joint limits (continuous joints: any angle); a free-flyer base is set to
/// a fixed placement (`base`, 7 numbers), or with [`UniformSampler::with_base_box`] keeps the
/// placement's orientation and draws its position uniformly in a box (the paper's Talos sampler:
/// the centre-of-mass support box).
#[derive(Debug, Clone)]
pub struct UniformSampler {
    model: Arc<KinematicModel>,
    base: [f64; 7],
    base_box: Option<([f64; 3], [f64; 3])>,
    rng: StdRng,
    seed: u64,
    /// With [`Sampling::Halton`]: the sequence, one coordinate per number a row draws (the base
    /// box's three, then each joint's in the model's order), and its current point.
    halton: Option<(Halton, Vec<f64>)>,
}

impl UniformSampler {
    /// A sampler for `model` (every revolute or prismatic joint needs finite limits, lower <=
    /// upper, of finite width; a model without joints, nq = 0, gives empty rows); `base`: the
    /// free-flyer placement [x, y, z, qx, qy, qz, qw] (default: the identity; its quaternion is
    /// normalised and must not be zero); `seed` seeds its random numbers.
    pub fn new(model: Arc<KinematicModel>, base: Option<[f64; 7]>, seed: u64) -> PlanResult<UniformSampler> {
        for j in model.joints.iter().filter(|j| j.q_index != usize::MAX) {
            if !matches!(j.motion, Motion::Revolute { .. } | Motion::Prismatic { .. }) {
                continue;
            }
            let (Some(&lo), Some(&hi)) = (model.lower.get(j.q_index), model.upper.get(j.q_index)) else {
                return input(format!("uniform sampler: joint '{}' has no limits in the model", j.name));
            };
            if !(lo.is_finite() && hi.is_finite()) {
                return input(format!("uniform sampler: joint '{}' has no finite limits", j.name));
            }
            if !sampleable(lo, hi) {
                return input(format!(
                    "uniform sampler: joint '{}' has limits [{lo}, {hi}] that cannot be sampled (reversed, or too wide)",
                    j.name
                ));
            }
        }
        let mut base = base.unwrap_or([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]);
        if base.iter().any(|x| !x.is_finite()) {
            return input("uniform sampler: base placement is not finite");
        }
        let Some(rot) = unit_quaternion(base[6], base[3], base[4], base[5], 1e-9) else {
            return input(format!("uniform sampler: the base placement's quaternion {:?} is zero", &base[3..7]));
        };
        let r = rot.coords; // (x, y, z, w)
        base[3..7].copy_from_slice(&[r.x, r.y, r.z, r.w]);
        Ok(UniformSampler { model, base, base_box: None, rng: StdRng::seed_from_u64(seed), seed, halton: None })
    }

    /// Draw the free-flyer base position uniformly in `lower..=upper` (orientation: the base
    /// placement's).
    pub fn with_base_box(mut self, lower: [f64; 3], upper: [f64; 3]) -> PlanResult<UniformSampler> {
        if !self.model.floating_base {
            return input("uniform sampler: a base box needs a free-flyer base");
        }
        if !valid_box(&lower, &upper) {
            return input(format!(
                "uniform sampler: bad base box {lower:?} .. {upper:?} (finite, lower <= upper, of finite width)"
            ));
        }
        self.base_box = Some((lower, upper));
        if let Some((h, _)) = &self.halton {
            let dims = self.dims();
            if h.dims() != dims {
                return Ok(self.with_sampling(Sampling::Halton));
            }
        }
        Ok(self)
    }

    /// Draw with `sampling`: random numbers (the default) or the [`Halton`] sequence of the
    /// sampler's seed, one coordinate per number a row draws.
    pub fn with_sampling(mut self, sampling: Sampling) -> UniformSampler {
        self.halton = match sampling {
            Sampling::Random => None,
            Sampling::Halton => {
                let dims = self.dims();
                Some((Halton::new(dims, self.seed), vec![0.0; dims]))
            }
        };
        self
    }

    /// How it draws.
    pub fn sampling(&self) -> Sampling {
        if self.halton.is_some() {
            Sampling::Halton
        } else {
            Sampling::Random
        }
    }

    /// The numbers one row draws: three for a base box, one per joint that moves.
    fn dims(&self) -> usize {
        let joints = self.model.joints.iter().filter(|j| j.q_index != usize::MAX && !matches!(j.motion, Motion::Fixed)).count();
        joints + if self.base_box.is_some() { 3 } else { 0 }
    }
}

impl Sampler for UniformSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let m = &self.model;
        check_out("uniform sampler", n, m.nq, out)?;
        if m.nq == 0 {
            return Ok(()); // n empty rows
        }
        use std::f64::consts::PI;
        for row in out.chunks_mut(m.nq).take(n) {
            // the row's numbers in [0, 1) from the Halton sequence, or None: drawn from the rng
            // (as they always were, so that a seed's random samples do not change)
            let units = match &mut self.halton {
                Some((h, point)) => {
                    h.next_into(point);
                    Some(&point[..])
                }
                None => None,
            };
            let mut k = 0;
            if m.floating_base {
                row[..7].copy_from_slice(&self.base);
                if let Some((lo, hi)) = self.base_box {
                    for d in 0..3 {
                        row[d] = match units {
                            Some(u) => scale(u[k], lo[d], hi[d]),
                            None => self.rng.random_range(lo[d]..=hi[d]),
                        };
                        k += 1;
                    }
                }
            }
            for j in m.joints.iter().filter(|j| j.q_index != usize::MAX) {
                let i = j.q_index;
                match j.motion {
                    Motion::Continuous { .. } => {
                        let a: f64 = match units {
                            Some(u) => -PI + 2.0 * PI * u[k],
                            None => self.rng.random_range(-PI..PI),
                        };
                        k += 1;
                        row[i] = a.cos();
                        row[i + 1] = a.sin();
                    }
                    Motion::Fixed => {}
                    _ => {
                        row[i] = match units {
                            Some(u) => scale(u[k], m.lower[i], m.upper[i]),
                            None => self.rng.random_range(m.lower[i]..=m.upper[i]),
                        };
                        k += 1;
                    }
                }
            }
        }
        Ok(())
    }
}

/// Rows of a fixed set of configurations, each drawn uniformly at random (with replacement): the
/// data set a learned sampler is trained on, used as it is. It needs no training, its rows are on
/// the manifold already (to the data's tolerance), and it covers what the data cover and nothing
/// else (docs/BENCHMARKS.md, "What coverage can buy in planning").
#[derive(Debug, Clone)]
pub struct DataSampler {
    rows: Arc<Vec<f64>>,
    nq: usize,
    rng: StdRng,
}

impl DataSampler {
    /// A sampler of the rows of `rows` (row-major, rows of `nq` >= 1 finite numbers, at least
    /// one row); `seed` seeds its random numbers.
    pub fn new(rows: Vec<f64>, nq: usize, seed: u64) -> PlanResult<DataSampler> {
        if nq == 0 {
            return input("data sampler: configurations need at least one number (nq = 0)");
        }
        if rows.is_empty() || rows.len() % nq != 0 {
            return input(format!("data sampler: expected one or more rows of {nq} numbers, got {} numbers", rows.len()));
        }
        if let Some(i) = rows.iter().position(|x| !x.is_finite()) {
            return input(format!("data sampler: row {} holds a number that is not finite ({})", i / nq, rows[i]));
        }
        Ok(DataSampler { rows: Arc::new(rows), nq, rng: StdRng::seed_from_u64(seed) })
    }

    /// The number of rows drawn from.
    pub fn len(&self) -> usize {
        self.rows.len() / self.nq
    }

    /// Never true (a data sampler has one row at least).
    pub fn is_empty(&self) -> bool {
        self.rows.is_empty()
    }
}

impl Sampler for DataSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let nq = self.nq;
        check_out("data sampler", n, nq, out)?;
        let m = self.len();
        for row in out.chunks_mut(nq).take(n) {
            let i = self.rng.random_range(0..m);
            row.copy_from_slice(&self.rows[i * nq..(i + 1) * nq]);
        }
        Ok(())
    }
}

/// Draws each configuration from `primary` with probability `p`, else from `secondary`: the
/// paper's hybrid sampler (GAN with p = 0.8, else uniform) keeps the planner probabilistically
/// complete. Both are asked for whole batches.
///
/// With a `half_life` (the GAN paper's future work, an adaptive hybrid), the probability decays
/// with the rows drawn so far: row k (counted from 0 since the sampler was made, i.e. within one
/// plan) comes from `primary` with probability `p * 0.5^(k / half_life)`. A search that the
/// learned sampler serves well ends while it still dominates; a long one turns into uniform
/// sampling, which keeps the planner probabilistically complete whatever the learned sampler misses.
pub struct MixtureSampler {
    /// Drawn from with probability `p` (the paper: the GAN).
    pub primary: Box<dyn Sampler>,
    /// Drawn from otherwise (the paper: uniform).
    pub secondary: Box<dyn Sampler>,
    /// Probability of drawing from `primary` (at first, with a `half_life`), in [0, 1].
    pub p: f64,
    /// Rows after which the probability of `primary` has halved; None: constant.
    pub half_life: Option<f64>,
    drawn: u64,
    nq: usize,
    rng: StdRng,
    buf: Vec<f64>,
}

impl MixtureSampler {
    /// The mixture of two samplers of configurations of length `nq`; `seed` seeds the choice
    /// between them.
    pub fn new(primary: Box<dyn Sampler>, secondary: Box<dyn Sampler>, p: f64, nq: usize, seed: u64) -> PlanResult<MixtureSampler> {
        if !(0.0..=1.0).contains(&p) {
            return input(format!("mixture sampler: p must be in [0, 1], got {p}"));
        }
        Ok(MixtureSampler { primary, secondary, p, half_life: None, drawn: 0, nq, rng: StdRng::seed_from_u64(seed), buf: Vec::new() })
    }

    /// The same mixture whose probability of `primary` halves every `half_life` rows drawn
    /// (a finite number > 0, else an input error).
    pub fn with_half_life(mut self, half_life: f64) -> PlanResult<MixtureSampler> {
        if !(half_life.is_finite() && half_life > 0.0) {
            return input(format!("mixture sampler: half_life must be a finite number > 0, got {half_life}"));
        }
        self.half_life = Some(half_life);
        Ok(self)
    }

    /// The probability that row `k` (counted since the sampler was made) comes from `primary`.
    pub fn p_at(&self, k: u64) -> f64 {
        match self.half_life {
            None => self.p,
            Some(h) => self.p * 0.5f64.powf(k as f64 / h),
        }
    }
}

impl Sampler for MixtureSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        let nq = self.nq;
        check_out("mixture sampler", n, nq, out)?;
        if nq == 0 {
            return Ok(()); // n empty rows
        }
        let first = self.drawn;
        let pick: Vec<bool> = (0..n as u64).map(|i| self.rng.random::<f64>() < self.p_at(first + i)).collect();
        self.drawn += n as u64;
        let n1 = pick.iter().filter(|&&b| b).count();
        let mut rows_a = Vec::new();
        let mut rows_b = Vec::new();
        if n1 > 0 {
            self.buf.resize(n1 * nq, 0.0);
            self.primary.sample(n1, &mut self.buf)?;
            rows_a = self.buf.clone();
        }
        if n1 < n {
            self.buf.resize((n - n1) * nq, 0.0);
            self.secondary.sample(n - n1, &mut self.buf)?;
            rows_b = self.buf.clone();
        }
        let (mut ia, mut ib) = (0, 0);
        for (row, &a) in out.chunks_mut(nq).zip(&pick) {
            if a {
                row.copy_from_slice(&rows_a[ia * nq..(ia + 1) * nq]);
                ia += 1;
            } else {
                row.copy_from_slice(&rows_b[ib * nq..(ib + 1) * nq]);
                ib += 1;
            }
        }
        Ok(())
    }
}
