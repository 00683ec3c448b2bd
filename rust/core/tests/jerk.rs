//! Jerk-limited timing (`genplan_core::jerk`): the S-curve's closed forms against the three
//! regimes (cruise, no cruise, no constant acceleration), and on seeded random paths every
//! sample within the limits with no tolerance, each state reached exactly at rest, every
//! sample on its segment's straight line, the margin under the limits cheap; bad input refused
//! with the argument named. Durations against ruckig: tests/test_trajectory_jerk.py.

use genplan_core::jerk::{JerkPath, SCurve, MARGIN};
use genplan_core::Error;
use rand::{rngs::StdRng, Rng, SeedableRng};

fn close(a: f64, b: f64, tol: f64) -> bool {
    (a - b).abs() <= tol * (1.0 + a.abs().max(b.abs()))
}

#[test]
fn the_three_regimes_have_their_closed_form_durations() {
    // cruise: v = 1, a = 4, j = 40: accel half 1/4 + 4/40 = 0.35 s covers 0.35 < 1, T = 0.35 + 1/1
    let p = SCurve::new(1.0, 4.0, 40.0);
    assert!(close(p.duration(), 1.35, 1e-12), "{p:?}");
    assert!(close(p.peak_v, 1.0, 1e-12) && close(p.peak_a, 4.0, 1e-12));
    // no cruise, constant acceleration reached: v large; vp (vp/a + a/j) = 1
    let (a, j) = (4.0, 40.0);
    let p = SCurve::new(100.0, a, j);
    let vp = p.peak_v;
    assert!(close(vp * (vp / a + a / j), 1.0, 1e-12), "{p:?}");
    assert!(close(p.duration(), 2.0 * (vp / a + a / j), 1e-12) && p.tv < 1e-12, "{p:?}");
    // neither cruise nor constant acceleration: vp = (j / 4)^(1/3), T = 4 (1 / (2 j))^(1/3)
    let p = SCurve::new(100.0, 100.0, 2.0);
    assert!(close(p.duration(), 4.0 * (0.5f64 / 2.0).cbrt(), 1e-12), "{p:?}");
    assert!(p.ta == 0.0 && p.tv < 1e-12 && p.peak_a < 100.0, "{p:?}");
}

#[test]
fn a_profile_starts_and_ends_exactly_at_rest_and_is_monotone() {
    for (v, a, j) in [(1.0, 4.0, 40.0), (100.0, 4.0, 40.0), (100.0, 100.0, 2.0), (0.3, 50.0, 7.0)] {
        let p = SCurve::new(v, a, j);
        assert_eq!(p.at(0.0).0, 0.0);
        assert_eq!(p.at(0.0).1, 0.0);
        assert_eq!(p.at(p.duration()), (1.0, 0.0, -0.0, j));
        let mut last = 0.0;
        for k in 0..=1000 {
            let (s, sd, sdd, _) = p.at(p.duration() * k as f64 / 1000.0);
            assert!(s >= last && sd <= v && sdd.abs() <= a, "{k}: {s} {sd} {sdd}");
            last = s;
        }
        // the integral of the velocity is the position (the profile is consistent)
        let steps = 200_000;
        let dt = p.duration() / steps as f64;
        let area: f64 = (0..steps).map(|k| p.at((k as f64 + 0.5) * dt).1 * dt).sum();
        assert!(close(area, 1.0, 1e-6), "{area}");
    }
}

/// A random path of `m` states of `n` joints and its limits.
fn random_case(rng: &mut StdRng, m: usize, n: usize) -> (Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>) {
    let states: Vec<f64> = (0..m * n).map(|_| rng.random_range(-2.5..2.5)).collect();
    let v: Vec<f64> = (0..n).map(|_| rng.random_range(0.5..3.0)).collect();
    let a: Vec<f64> = (0..n).map(|_| rng.random_range(1.0..20.0)).collect();
    let j: Vec<f64> = (0..n).map(|_| rng.random_range(5.0..5000.0)).collect();
    (states, v, a, j)
}

#[test]
fn samples_stay_within_the_limits_on_the_straight_line_and_reach_each_state_at_rest() {
    let mut rng = StdRng::seed_from_u64(7);
    for case in 0..200 {
        let (m, n) = (rng.random_range(2..5), rng.random_range(1..8));
        let (states, v, a, j) = random_case(&mut rng, m, n);
        let path = JerkPath::new(&states, &v, &a, &j).unwrap();
        let (t, q, qd, qdd, qddd) = path.sample(1000.0).unwrap();
        assert_eq!(*t.last().unwrap(), path.duration());
        for k in 0..t.len() {
            for i in 0..n {
                let c = k * n + i;
                assert!(qd[c].abs() <= v[i] && qdd[c].abs() <= a[i] && qddd[c].abs() <= j[i], "case {case} sample {k} joint {i}");
            }
        }
        // each state at its time, exactly, at rest
        let mut row = vec![vec![0.0; n]; 4];
        for (w, &tw) in path.times.iter().enumerate() {
            let [q1, qd1, qdd1, qddd1] = &mut row[..] else { unreachable!() };
            path.at(tw, q1, qd1, qdd1, qddd1);
            assert_eq!(&q1[..], &states[w * n..(w + 1) * n], "case {case} state {w}");
            assert!(qd1.iter().chain(qdd1.iter()).all(|x| x.abs() <= 1e-9 * 1e3), "case {case} state {w}: {qd1:?} {qdd1:?}");
        }
        assert_eq!(&q[..n], &states[..n]);
        assert_eq!(&q[q.len() - n..], &states[states.len() - n..]);
        // every sample on its segment's line: q - q0 parallel to q1 - q0, between them
        for (k, &tk) in t.iter().enumerate() {
            let s = path.times.partition_point(|&x| x <= tk).clamp(1, m - 1) - 1;
            let (q0, q1) = (&states[s * n..(s + 1) * n], &states[(s + 1) * n..(s + 2) * n]);
            let d: Vec<f64> = (0..n).map(|i| q1[i] - q0[i]).collect();
            let i = (0..n).max_by(|&x, &y| d[x].abs().total_cmp(&d[y].abs())).unwrap();
            let frac = (q[k * n + i] - q0[i]) / d[i];
            assert!((-1e-12..=1.0 + 1e-12).contains(&frac));
            for i in 0..n {
                assert!((q[k * n + i] - (q0[i] + frac * d[i])).abs() <= 1e-12, "case {case} sample {k} joint {i} off the line");
            }
        }
    }
}

#[test]
fn the_margin_costs_about_as_much_of_the_duration() {
    for (v, a, j) in [(1.0, 4.0, 40.0), (100.0, 4.0, 40.0), (100.0, 100.0, 2.0)] {
        let exact = SCurve::new(v, a, j).duration();
        let kept = SCurve::new(v * (1.0 - MARGIN), a * (1.0 - MARGIN), j * (1.0 - MARGIN)).duration();
        assert!(kept > exact && kept / exact - 1.0 < 2.0 * MARGIN, "{exact} {kept}");
    }
}

#[test]
fn bad_input_is_refused_naming_the_argument() {
    let s = [0.0, 0.0, 1.0, 1.0];
    let ok = [1.0, 1.0];
    let msg = |r: Result<JerkPath, Error>| r.unwrap_err().to_string();
    assert!(msg(JerkPath::new(&[0.0, f64::NAN, 1.0, 1.0], &ok, &ok, &ok)).contains("states"));
    assert!(msg(JerkPath::new(&s, &[1.0, 0.0], &ok, &ok)).contains("vlim"));
    assert!(msg(JerkPath::new(&s, &ok, &[1.0, -2.0], &ok)).contains("alim"));
    assert!(msg(JerkPath::new(&s, &ok, &ok, &[1.0, f64::INFINITY])).contains("jlim"));
    assert!(matches!(JerkPath::new(&s, &ok, &ok, &[1.0]), Err(Error::Shape { .. })));
    assert!(msg(JerkPath::new(&[0.0, 0.0, 1.0], &ok, &ok, &ok)).contains("states"));
    assert!(msg(JerkPath::new(&[0.0, 0.0], &ok, &ok, &ok)).contains("states"));
    assert!(msg(JerkPath::new(&[1.0, 1.0, 1.0, 1.0], &ok, &ok, &ok)).contains("equal"));
    let p = JerkPath::new(&s, &ok, &ok, &ok).unwrap();
    assert!(matches!(p.sample(0.0), Err(Error::Settings { field: "rate", .. })));
    assert!(matches!(p.sample(1e15), Err(Error::Settings { field: "rate", .. })));
}
