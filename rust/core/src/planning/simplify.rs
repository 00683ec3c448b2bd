//! Path simplification in free space: shorter paths from the same validity checks.
//!
//! A free-space path is straight segments between its waypoints, each segment's states evenly
//! spaced at `edge_resolution` and checked. [`Run::simplify_free`] reduces the path, then repeats
//! partial shortcuts, smoothing and reduce (as VAMP's and OMPL's simplifiers do) until a round
//! shortens the path by less than [`MIN_GAIN`] of its length, or [`MAX_ROUNDS`] rounds:
//!
//! * **reduce** (greedy shortcutting): from each waypoint, the farthest later waypoint reached
//!   by a valid straight motion replaces every waypoint between them;
//! * **partial shortcuts**: two random states of the dense path (already checked: the new
//!   waypoints are states of the path, so the segments they split need no new check) joined by a
//!   valid straight motion, which replaces the stretch between them;
//! * **smoothing** (one B-spline step, OMPL's `smoothBSpline`): each interior waypoint moved to the
//!   midpoint of the midpoints of its two segments, when both new segments are valid: the corner
//!   is cut, the path cannot get longer.
//!
//! Every new segment is checked as the tree's edges are (the same states: the interpolations at
//! `edge_resolution`), in "rake" order: a batch of states spread along the motion first, then the
//! batches between them, so that a blocked motion is refused after a few checks instead of all of
//! its states. A state is never moved without its segments being checked, so the simplified path
//! holds the planner's guarantee (every state valid, consecutive states at most
//! `edge_resolution` apart).

use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::rrt::Run;
use super::{EdgeCheck, PlanResult, Settings};

/// The most rounds of partial shortcuts, smoothing and reduce (VAMP's default: 5).
const MAX_ROUNDS: usize = 5;
/// A round that shortens the path by less than this share of its length is the last.
const MIN_GAIN: f64 = 5e-3;
/// Partial shortcut attempts per round: this many plus two per waypoint.
const PARTIAL_ATTEMPTS: usize = 16;
/// A round's partial shortcuts stop after this many failures in a row.
const PARTIAL_MAX_EMPTY: usize = 12;
/// Smoothing moves a waypoint only by more than this (rad, the space's distance): a smaller move
/// shortens the path by less than it, not worth checking two segments.
const SMOOTH_MIN_CHANGE: f64 = 1e-2;
/// The seed of the partial shortcuts' choices (fixed: a plan is reproducible from its sampler's seed).
const SEED: u64 = 0x5eed_5a0f;

/// A path as waypoints and, per waypoint, the checked states of the segment that ends at it
/// (rows; the first waypoint's: none).
type Path = (Vec<Vec<f64>>, Vec<Vec<f64>>);

impl Run<'_> {
    /// Simplify a free-space path (see the module text); returns the new waypoints and segment
    /// states. Counts every motion taken in `shortcuts`.
    pub(super) fn simplify_free(&mut self, waypoints: Vec<Vec<f64>>, edges: Vec<Vec<f64>>) -> PlanResult<Path> {
        let mut path = (waypoints, edges);
        let mut rng = StdRng::seed_from_u64(SEED);
        self.reduce(&mut path)?;
        let mut length = self.path_length(&path.0);
        for _ in 0..MAX_ROUNDS {
            self.partial_shortcuts(&mut path, &mut rng)?;
            self.smooth(&mut path)?;
            self.reduce(&mut path)?;
            let now = self.path_length(&path.0);
            let gain = length - now;
            length = now;
            if !(gain > MIN_GAIN * now) {
                break;
            }
        }
        Ok(path)
    }

    fn path_length(&self, w: &[Vec<f64>]) -> f64 {
        let space = self.ambient();
        w.windows(2).map(|p| space.distance(&p[0], &p[1])).sum()
    }

    /// The checked states of the straight motion from `a` to `b` (both excluded; `b` checked too
    /// when `check_end`), evenly spaced as [`ConstrainedSpace::geodesic`](super::ConstrainedSpace::geodesic)
    /// spaces a free-space edge, checked in rake order; None when one is not valid or the motion
    /// would need more than [`Settings::MAX_EDGE_STATES`] states. Certified edges and edges
    /// without validation go through the geodesic itself.
    fn motion(&mut self, a: &[f64], b: &[f64], check_end: bool) -> PlanResult<Option<Vec<f64>>> {
        let settings = self.space.settings();
        let resolution = settings.edge_resolution;
        if resolution == 0.0 || settings.edge_check == EdgeCheck::Certified {
            return self.space.geodesic(a, b, check_end);
        }
        self.poll()?;
        let space = self.ambient();
        let nq = space.nq();
        let intervals = (space.distance(a, b) / resolution).ceil();
        if intervals.is_nan() || intervals > Settings::MAX_EDGE_STATES as f64 {
            return Ok(None);
        }
        let n_mid = (intervals as usize).saturating_sub(1);
        let mut states = vec![0.0; (n_mid + 1) * nq];
        for k in 0..n_mid {
            let t = (k + 1) as f64 / (n_mid + 1) as f64;
            space.interpolate(a, b, t, &mut states[k * nq..(k + 1) * nq]);
        }
        states[n_mid * nq..].copy_from_slice(b);
        let n_check = n_mid + usize::from(check_end);
        if !self.space.all_valid_raked(&states[..n_check * nq])? {
            return Ok(None);
        }
        states.truncate(n_mid * nq);
        Ok(Some(states))
    }

    /// Greedy shortcutting: from each waypoint, the farthest later one a valid motion reaches.
    fn reduce(&mut self, (w, e): &mut Path) -> PlanResult<()> {
        let mut i = 0;
        while i + 2 < w.len() {
            for j in (i + 2..w.len()).rev() {
                if let Some(states) = self.motion(&w[i], &w[j], false)? {
                    self.space.stats.shortcuts += 1;
                    w.drain(i + 1..j);
                    e.drain(i + 1..j);
                    e[i + 1] = states;
                    break;
                }
            }
            i += 1;
        }
        Ok(())
    }

    /// Partial shortcuts between random states of the dense path (see the module text).
    fn partial_shortcuts(&mut self, path: &mut Path, rng: &mut StdRng) -> PlanResult<()> {
        let nq = self.ambient().nq();
        let attempts = PARTIAL_ATTEMPTS + 2 * path.0.len();
        let mut empty = 0;
        for _ in 0..attempts {
            if empty >= PARTIAL_MAX_EMPTY {
                break;
            }
            empty += 1;
            let (w, e) = &*path;
            // the dense path's states: (segment k, row r), r == rows of e[k] for the waypoint w[k]
            let rows: Vec<usize> = e.iter().map(|s| s.len() / nq).collect();
            let total: usize = rows.iter().map(|r| r + 1).sum();
            if total < 3 {
                return Ok(());
            }
            let g1 = rng.random_range(0..total - 2);
            let g2 = rng.random_range(g1 + 2..total);
            let (k1, r1) = locate(&rows, g1);
            let (k2, r2) = locate(&rows, g2);
            let state = |k: usize, r: usize| if r == rows[k] { &w[k][..] } else { &e[k][r * nq..(r + 1) * nq] };
            let (p1, p2) = (state(k1, r1).to_vec(), state(k2, r2).to_vec());
            // the arc between them against the chord: a shortcut must gain
            let space = self.ambient();
            let mut arc = 0.0;
            let mut prev = p1.clone();
            for g in g1 + 1..=g2 {
                let (k, r) = locate(&rows, g);
                let s = state(k, r);
                arc += space.distance(&prev, s);
                prev = s.to_vec();
            }
            if space.distance(&p1, &p2) >= arc * (1.0 - 1e-9) {
                continue;
            }
            let Some(states) = self.motion(&p1, &p2, false)? else {
                continue;
            };
            empty = 0;
            self.space.stats.shortcuts += 1;
            let (w, e) = path;
            splice(w, e, &rows, nq, (k1, r1), (k2, r2), p1, p2, states);
        }
        Ok(())
    }

    /// One smoothing step over the interior waypoints (see the module text).
    fn smooth(&mut self, (w, e): &mut Path) -> PlanResult<()> {
        let space = self.ambient();
        let nq = space.nq();
        let (mut m1, mut m2, mut t) = (vec![0.0; nq], vec![0.0; nq], vec![0.0; nq]);
        for i in 1..w.len().saturating_sub(1) {
            space.interpolate(&w[i - 1], &w[i], 0.5, &mut m1);
            space.interpolate(&w[i], &w[i + 1], 0.5, &mut m2);
            space.interpolate(&m1, &m2, 0.5, &mut t);
            if !(space.distance(&w[i], &t) > SMOOTH_MIN_CHANGE) {
                continue;
            }
            let Some(first) = self.motion(&w[i - 1], &t, true)? else {
                continue;
            };
            let Some(second) = self.motion(&t, &w[i + 1], false)? else {
                continue;
            };
            w[i].copy_from_slice(&t);
            e[i] = first;
            e[i + 1] = second;
        }
        Ok(())
    }
}

/// The dense path's state `g` as (segment k, row r): rows `0..rows[k]` of segment k's states,
/// then `r == rows[k]`, its waypoint.
fn locate(rows: &[usize], mut g: usize) -> (usize, usize) {
    for (k, &r) in rows.iter().enumerate() {
        if g <= r {
            return (k, g);
        }
        g -= r + 1;
    }
    unreachable!("a state index past the path's end")
}

/// Replace the stretch of the path between the dense states `(k1, r1)` and `(k2, r2)` (`p1`,
/// `p2`; `k1 < k2`, or the same segment with `r1 < r2`) by the motion `states` between them: each
/// becomes a waypoint (when it is not one already), the segments they split keep their states.
#[allow(clippy::too_many_arguments)]
fn splice(w: &mut Vec<Vec<f64>>, e: &mut Vec<Vec<f64>>, rows: &[usize], nq: usize, (k1, r1): (usize, usize),
          (k2, r2): (usize, usize), p1: Vec<f64>, p2: Vec<f64>, states: Vec<f64>) {
    let mut nw: Vec<Vec<f64>> = Vec::with_capacity(w.len() + 2);
    let mut ne: Vec<Vec<f64>> = Vec::with_capacity(w.len() + 2);
    nw.extend(w[..k1].iter().cloned());
    ne.extend(e[..k1].iter().cloned());
    // p1: the waypoint w[k1], or a new one ending the first rows of segment k1
    nw.push(p1);
    ne.push(if r1 == rows[k1] { e[k1].clone() } else { e[k1][..r1 * nq].to_vec() });
    nw.push(p2);
    ne.push(states);
    if r2 < rows[k2] {
        // p2 inside segment k2: its rows after p2 lead on to w[k2]
        nw.push(w[k2].clone());
        ne.push(e[k2][(r2 + 1) * nq..].to_vec());
    }
    nw.extend(w[k2 + 1..].iter().cloned());
    ne.extend(e[k2 + 1..].iter().cloned());
    *w = nw;
    *e = ne;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn locate_walks_segments_then_their_waypoint() {
        // w0 (no rows), segment 1: 2 rows then w1, segment 2: 0 rows then w2
        let rows = [0, 2, 0];
        let got: Vec<_> = (0..5).map(|g| locate(&rows, g)).collect();
        assert_eq!(got, vec![(0, 0), (1, 0), (1, 1), (1, 2), (2, 0)]);
    }

    #[test]
    fn splice_keeps_the_split_segments_states() {
        // 1-D path 0 -> 3 -> 6 with states every 1: w = [0, 3, 6], e = [[], [1, 2], [4, 5]]
        let mut w = vec![vec![0.0], vec![3.0], vec![6.0]];
        let mut e = vec![vec![], vec![1.0, 2.0], vec![4.0, 5.0]];
        let rows = [0, 2, 2];
        // from state 1 (segment 1, row 0) to state 5 (segment 2, row 1)
        splice(&mut w, &mut e, &rows, 1, (1, 0), (2, 1), vec![1.0], vec![5.0], vec![2.0, 3.0, 4.0]);
        assert_eq!(w, vec![vec![0.0], vec![1.0], vec![5.0], vec![6.0]]);
        assert_eq!(e, vec![vec![], vec![], vec![2.0, 3.0, 4.0], vec![]]);
        // from a waypoint (w0) to a waypoint (w2 of the new path)
        let rows = [0, 0, 3, 0];
        splice(&mut w, &mut e, &rows, 1, (0, 0), (2, 3), vec![0.0], vec![5.0], vec![2.5]);
        assert_eq!(w, vec![vec![0.0], vec![5.0], vec![6.0]]);
        assert_eq!(e, vec![vec![], vec![2.5], vec![]]);
    }
}
