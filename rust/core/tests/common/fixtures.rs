//! Planning fixtures shared by the tests (`tests/planning.rs`) and the benches
//! (`benches/planning.rs`), each included as `mod fixtures` with a `#[path]`: OMPL's sphere demo
//! (a point of R^3 kept on the unit sphere, a band around the equator blocked but for a door),
//! and the GAN paper's Panda task.

use std::sync::Arc;

use genplan_core::planning::{GaussNewtonProjector, PlanResult, Projection, Projector, Sampler, ValidityChecker};
use genplan_core::projection::{self, Term, TermKind};
use genplan_core::KinematicModel;
use nalgebra::{Matrix3, Vector3};
use rand::rngs::StdRng;
use rand::Rng;

/// Uniform in a cube.
pub struct CubeSampler {
    pub dim: usize,
    pub half: f64,
    pub rng: StdRng,
}

impl Sampler for CubeSampler {
    fn sample(&mut self, n: usize, out: &mut [f64]) -> PlanResult<()> {
        for x in out.iter_mut().take(n * self.dim) {
            *x = self.rng.random_range(-self.half..self.half);
        }
        Ok(())
    }
}

/// Keeps a point of R^n on the sphere |x| = radius (OMPL's constrained-planning demo).
#[derive(Debug, Clone, Copy)]
pub struct SphereProjector {
    pub radius: f64,
}

impl Projector for SphereProjector {
    fn project(&mut self, qs: &[f64], _q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        let n = reports.len();
        let dim = if n == 0 { 0 } else { qs.len() / n };
        for ((q, o), r) in qs.chunks(dim).zip(out.chunks_mut(dim)).zip(reports.iter_mut()) {
            let norm = q.iter().map(|x| x * x).sum::<f64>().sqrt();
            let ok = norm > 1e-12;
            for (a, b) in o.iter_mut().zip(q) {
                *a = if ok { b * self.radius / norm } else { *b };
            }
            *r = Projection { success: ok, iterations: 1 };
        }
        Ok(())
    }
}

/// The sphere's band |z| < 0.2 is blocked except a gap around +y (a wall with a door, as in
/// OMPL's sphere demo).
pub struct Band;

impl Band {
    pub fn ok(q: &[f64]) -> bool {
        q[2].abs() >= 0.2 || q[1] > 0.8
    }
}

impl ValidityChecker for Band {
    fn check(&mut self, qs: &[f64], valid: &mut [bool]) -> PlanResult<()> {
        for (q, v) in qs.chunks(3).zip(valid.iter_mut()) {
            *v = Band::ok(q);
        }
        Ok(())
    }
}

/// An interrupt check that never interrupts.
pub fn no_interrupt() -> PlanResult<()> {
    Ok(())
}

/// The GAN paper's Panda constraint on a model with a `panda_hand` link: the gripper horizontal
/// (the hand frame rotated -pi/2 about y keeps no tilt: orientation rows x, y, weight 20) within
/// the joint limits (margin 1e-3, weight 20), with a posture task around the nominal
/// configuration. `tolerance` applies to the orientation, 10x it to the limits. (The Python
/// side's `genplan.projection.paper_task(panda, "projection")` is the same task.)
pub fn panda_horizontal_gripper(model: Arc<KinematicModel>, tolerance: f64) -> projection::Projector {
    let hand = model.link_index("panda_hand").unwrap();
    let offset: Matrix3<f64> = nalgebra::Rotation3::from_axis_angle(&Vector3::y_axis(), -std::f64::consts::FRAC_PI_2).into_inner();
    let primary = vec![
        Term {
            name: "hand_orientation".into(),
            kind: TermKind::FrameOrientation { link: hand, target: Matrix3::identity(), offset, mask: [1.0, 1.0, 0.0] },
            weight: 20.0,
            tolerance,
        },
        Term { name: "joint_limits".into(), kind: TermKind::JointLimits { margin: 1e-3 }, weight: 20.0, tolerance: 10.0 * tolerance },
    ];
    let secondary = vec![Term {
        name: "posture".into(),
        kind: TermKind::Posture { q_nom: None, weights: vec![1.0; model.nv], overrides: vec![] },
        weight: 1.0,
        tolerance: 1e-3,
    }];
    projection::Projector::new(model, primary, secondary, projection::Settings::default()).unwrap()
}

/// The native projector with the posture step on edge states too (the trait's default
/// `project_edge`: as before issue 17), for comparisons with [`GaussNewtonProjector`], which
/// drops it there.
pub struct WithPosture(pub GaussNewtonProjector);

impl Projector for WithPosture {
    fn project(&mut self, qs: &[f64], q_noms: &[f64], out: &mut [f64], reports: &mut [Projection]) -> PlanResult<()> {
        self.0.project(qs, q_noms, out, reports)
    }
}
