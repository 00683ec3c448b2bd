//! The self-collision pairs to skip for a robot without an SRDF, computed the way MoveIt's setup
//! assistant builds its "disabled collisions" (the allowed collision matrix):
//!
//! 1. **adjacent**: links joined by a joint (through links without collision geometry);
//! 2. **default**: pairs in collision at the default configuration;
//! 3. **always**: pairs in collision in at least `always_fraction` of the random configurations;
//! 4. **never**: pairs in collision in none of the random configurations.
//!
//! Pairs on one rigid body are never checked anyway (see `broad_phase::self_pairs`). The random
//! configurations are the planner's [`UniformSampler`]'s (within the joint limits, continuous
//! joints any angle, a free-flyer base at its default placement), seeded: the result is
//! reproducible.
//!
//! [`default_contacts`] is the check of a robot's own pair selection (its SRDF's): the checked
//! pairs in contact at the default configuration, and how often each is in contact over random
//! configurations (a pair always in contact makes every configuration invalid).

use std::collections::BTreeMap;

use nalgebra::Isometry3;
use parry3d_f64::query;
use rayon::prelude::*;

use super::broad_phase::self_pairs;
use super::CollisionWorld;
use crate::error::{Error, Result};
use crate::planning::{Sampler, UniformSampler};

/// Why a link pair is skipped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Reason {
    /// The links are joined by a joint.
    Adjacent,
    /// The pair collides at the default configuration.
    Default,
    /// The pair collides (almost) always.
    Always,
    /// The pair never collided over the random configurations.
    Never,
}

impl Reason {
    /// Every reason, in order.
    pub const ALL: [Reason; 4] = [Reason::Adjacent, Reason::Default, Reason::Always, Reason::Never];

    /// The reason whose [`as_str`](Self::as_str) is `word`.
    pub fn parse(word: &str) -> Option<Reason> {
        Reason::ALL.into_iter().find(|r| r.as_str() == word)
    }

    /// MoveIt's word for the reason (written in the SRDF's `reason` attribute).
    pub fn as_str(&self) -> &'static str {
        match self {
            Reason::Adjacent => "Adjacent",
            Reason::Default => "Default",
            Reason::Always => "Always",
            Reason::Never => "Never",
        }
    }
}

/// Settings of [`disabled_pairs`].
#[derive(Debug, Clone)]
pub struct Options {
    /// Random configurations sampled (MoveIt's default: 10,000).
    pub samples: usize,
    /// A pair colliding in at least this share of the samples is "always" in collision.
    pub always_fraction: f64,
    /// Seed of the random configurations.
    pub seed: u64,
}

impl Default for Options {
    fn default() -> Self {
        Options { samples: 10_000, always_fraction: 0.95, seed: 0 }
    }
}

/// One skipped pair: the two link names (sorted) and why.
#[derive(Debug, Clone, PartialEq)]
pub struct DisabledPair {
    /// First link (the smaller name).
    pub a: String,
    /// Second link.
    pub b: String,
    /// Why it is skipped.
    pub reason: Reason,
}

/// The link pairs to skip, sorted by (reason, a, b): see the module's documentation. `world` is
/// a world built without pair filtering (no SRDF); `q_default` the default configuration.
pub fn disabled_pairs(world: &CollisionWorld, q_default: &[f64], options: &Options) -> Result<Vec<DisabledPair>> {
    let model = &*world.model;
    model.check_configuration(q_default)?;
    if options.samples == 0 || options.samples > 10_000_000 {
        return Err(Error::Invalid(format!("disabled pairs: samples must be in 1..=10000000, got {}", options.samples)));
    }
    if !(options.always_fraction > 0.0 && options.always_fraction <= 1.0) {
        return Err(Error::Invalid(format!(
            "disabled pairs: always_fraction must be in (0, 1], got {}",
            options.always_fraction
        )));
    }
    // Link pairs with geometry on different bodies (every self-collision pair, no SRDF), and
    // the geometry pairs of each.
    let pairs = by_link_pair(world, self_pairs(model, &world.geometries, None));
    let mut reason: BTreeMap<(usize, usize), Reason> = BTreeMap::new();

    // 1. adjacent: each link with geometry and its nearest ancestor with geometry.
    let has_geometry: Vec<bool> =
        (0..model.n_links()).map(|l| world.geometries.iter().any(|g| g.link == l)).collect();
    for l in 0..model.n_links() {
        if !has_geometry[l] {
            continue;
        }
        let mut p = model.parent_link[l];
        while let Some(a) = p {
            if has_geometry[a] {
                reason.insert((a.min(l), a.max(l)), Reason::Adjacent);
                break;
            }
            p = model.parent_link[a];
        }
    }

    let keys: Vec<(usize, usize)> = pairs.keys().copied().filter(|k| !reason.contains_key(k)).collect();

    // 2. default
    let mut poses = Vec::new();
    for (k, hit) in keys.iter().zip(colliding(world, &pairs, &keys, q_default, &mut poses)) {
        if hit {
            reason.insert(*k, Reason::Default);
        }
    }

    // 3-4. over random configurations
    let counts = sample_counts(world, &pairs, &keys, q_default, options.samples, options.seed)?;
    for (k, &c) in keys.iter().zip(&counts) {
        if reason.contains_key(k) {
            continue;
        }
        if c == 0 {
            reason.insert(*k, Reason::Never);
        } else if c as f64 >= options.always_fraction * options.samples as f64 {
            reason.insert(*k, Reason::Always);
        }
    }

    let mut out: Vec<DisabledPair> = reason
        .into_iter()
        .map(|((a, b), r)| {
            let (na, nb) = (&model.link_names[a], &model.link_names[b]);
            let (a, b) = if na <= nb { (na, nb) } else { (nb, na) };
            DisabledPair { a: a.clone(), b: b.clone(), reason: r }
        })
        .collect();
    out.sort_by(|x, y| (x.reason, &x.a, &x.b).cmp(&(y.reason, &y.a, &y.b)));
    Ok(out)
}

/// Geometry pairs grouped by their (sorted) link pair.
fn by_link_pair(world: &CollisionWorld, geometry_pairs: impl IntoIterator<Item = (usize, usize)>) -> BTreeMap<(usize, usize), Vec<(usize, usize)>> {
    let mut pairs: BTreeMap<(usize, usize), Vec<(usize, usize)>> = BTreeMap::new();
    for (i, j) in geometry_pairs {
        let (a, b) = (world.geometries[i].link, world.geometries[j].link);
        pairs.entry((a.min(b), a.max(b))).or_default().push((i, j));
    }
    pairs
}

/// For each link pair of `keys`, whether any of its geometry pairs (`pairs[key]`) is in contact
/// at `q` (`poses` is scratch).
fn colliding(
    world: &CollisionWorld,
    pairs: &BTreeMap<(usize, usize), Vec<(usize, usize)>>,
    keys: &[(usize, usize)],
    q: &[f64],
    poses: &mut Vec<Isometry3<f64>>,
) -> Vec<bool> {
    world.model.forward_kinematics_unchecked(q, poses);
    keys.iter()
        .map(|k| {
            pairs[k].iter().any(|&(i, j)| {
                let (gi, gj) = (&world.geometries[i], &world.geometries[j]);
                let pi = poses[gi.link] * gi.offset;
                let pj = poses[gj.link] * gj.offset;
                query::intersection_test(&pi, gi.shape.as_ref(), &pj, gj.shape.as_ref()).unwrap_or(true)
            })
        })
        .collect()
}

/// In how many of `samples` random configurations (the planner's uniform sampler, a free-flyer
/// base held at `q_default`'s placement) each link pair of `keys` is in contact: parallel
/// chunks with per-chunk seeds, reproducible whatever the number of threads.
fn sample_counts(
    world: &CollisionWorld,
    pairs: &BTreeMap<(usize, usize), Vec<(usize, usize)>>,
    keys: &[(usize, usize)],
    q_default: &[f64],
    samples: usize,
    seed: u64,
) -> Result<Vec<u32>> {
    let model = &*world.model;
    let base = model.floating_base.then(|| {
        let mut b = [0.0; 7];
        b.copy_from_slice(&q_default[..7]);
        b
    });
    UniformSampler::new(world.model.clone(), base, 0).map_err(|e| Error::Invalid(format!("disabled pairs: {e}")))?;
    let chunk = 256usize;
    let n_chunks = samples.div_ceil(chunk);
    Ok((0..n_chunks)
        .into_par_iter()
        .map(|c| {
            let seed = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15).wrapping_add(c as u64);
            let mut sampler = UniformSampler::new(world.model.clone(), base, seed).expect("checked above");
            let n = chunk.min(samples - c * chunk);
            let mut qs = vec![0.0; n * model.nq];
            sampler.sample(n, &mut qs).expect("sized for n rows");
            let mut poses = Vec::new();
            let mut counts = vec![0u32; keys.len()];
            for q in qs.chunks(model.nq.max(1)).take(n) {
                for (c, hit) in counts.iter_mut().zip(colliding(world, pairs, keys, q, &mut poses)) {
                    *c += hit as u32;
                }
            }
            counts
        })
        .reduce(|| vec![0u32; keys.len()], |a, b| a.iter().zip(&b).map(|(x, y)| x + y).collect()))
}

/// A checked self pair in contact at the default configuration ([`default_contacts`]).
#[derive(Debug, Clone, PartialEq)]
pub struct Contact {
    /// First link (the smaller name).
    pub a: String,
    /// Second link.
    pub b: String,
    /// In how many of the random configurations it is in contact as well.
    pub hits: usize,
}

/// The link pairs `world` checks (its own selection, e.g. all but the SRDF's disabled pairs)
/// that are in contact at `q_default`, sorted by (a, b), each with the number of `samples`
/// random configurations (as [`disabled_pairs`] draws them, seeded) in which it is in contact
/// too. Only those pairs are sampled: a robot whose default configuration is free of
/// self-collision costs one check. `samples` in 0..=10,000,000.
pub fn default_contacts(world: &CollisionWorld, q_default: &[f64], samples: usize, seed: u64) -> Result<Vec<Contact>> {
    let model = &*world.model;
    model.check_configuration(q_default)?;
    if samples > 10_000_000 {
        return Err(Error::Invalid(format!("default contacts: samples must be in 0..=10000000, got {samples}")));
    }
    let pairs = by_link_pair(world, world.self_pairs().iter().copied());
    let all: Vec<(usize, usize)> = pairs.keys().copied().collect();
    let mut poses = Vec::new();
    let keys: Vec<(usize, usize)> =
        all.iter().zip(colliding(world, &pairs, &all, q_default, &mut poses)).filter(|(_, hit)| *hit).map(|(k, _)| *k).collect();
    let counts = if keys.is_empty() || samples == 0 {
        vec![0; keys.len()]
    } else {
        sample_counts(world, &pairs, &keys, q_default, samples, seed)?
    };
    let mut out: Vec<Contact> = keys
        .iter()
        .zip(&counts)
        .map(|(&(a, b), &hits)| {
            let (na, nb) = (&model.link_names[a], &model.link_names[b]);
            let (a, b) = if na <= nb { (na, nb) } else { (nb, na) };
            Contact { a: a.clone(), b: b.clone(), hits: hits as usize }
        })
        .collect();
    out.sort_by(|x, y| (&x.a, &x.b).cmp(&(&y.a, &y.b)));
    Ok(out)
}

/// An SRDF holding `pairs` as `<disable_collisions>` (MoveIt's format) and, if given, one group
/// state "default" with the joint values.
pub fn srdf_text(robot_name: &str, pairs: &[DisabledPair], default_state: Option<&[(String, f64)]>) -> String {
    let esc = |s: &str| s.replace('&', "&amp;").replace('"', "&quot;").replace('<', "&lt;");
    let mut s = format!(
        "<?xml version=\"1.0\" ?>\n<!-- written by genplan (genplan_core::collision::allowed): the self-collision pairs to skip -->\n<robot name=\"{}\">\n",
        esc(robot_name)
    );
    if let Some(state) = default_state {
        s.push_str("  <group_state name=\"default\" group=\"all\">\n");
        for (j, v) in state {
            s.push_str(&format!("    <joint name=\"{}\" value=\"{v:?}\"/>\n", esc(j)));
        }
        s.push_str("  </group_state>\n");
    }
    for p in pairs {
        s.push_str(&format!(
            "  <disable_collisions link1=\"{}\" link2=\"{}\" reason=\"{}\"/>\n",
            esc(&p.a),
            esc(&p.b),
            p.reason.as_str()
        ));
    }
    s.push_str("</robot>\n");
    s
}
