//! Rigid-body dynamics of a fixed-base arm (a kinematic tree) loaded from URDF.
//!
//! * [`Dynamics::mass_matrix`]: the joint-space inertia matrix M(q) (composite rigid body
//!   algorithm, as Pinocchio's `crba`, both triangles filled);
//! * [`Dynamics::rnea`] / [`Dynamics::nonlinear_effects`] / [`Dynamics::gravity_torque`]:
//!   inverse dynamics `tau = M(q) a + C(q, v) v + g(q)` (recursive Newton-Euler, as `rnea`,
//!   `nonLinearEffects`, `computeGeneralizedGravity`);
//! * [`Dynamics::forward_dynamics`]: `qdd = M^-1 (tau - C v - g)` (CRBA + RNEA + Cholesky,
//!   same result as Pinocchio's `aba`);
//! * [`Dynamics::aba_from_kinematics`]: the same `qdd` by the articulated-body algorithm
//!   (Featherstone's ABA, as Pinocchio's `aba`): O(n) and without the n x n mass matrix,
//!   cross-checked against CRBA + Cholesky (at 6-7 joints it costs about as much); the 1 kHz
//!   loop's plant uses it, on [`Dynamics::update_kinematics_moved_unchecked`]'s kinematics;
//! * [`Dynamics::frame_jacobian`] / [`Dynamics::frame_jacobian_time_variation`]: Jacobian of a
//!   frame and its time derivative, in Pinocchio's `LOCAL_WORLD_ALIGNED` convention: rows
//!   `[v; w]` are the linear velocity of the frame origin and the angular velocity, both in world
//!   axes, so that the classical acceleration of the frame is `J qdd + dJ/dt v`.
//!
//! q follows Pinocchio's convention (a continuous joint takes `[cos, sin]`); the order of the
//! joints is the [`KinematicModel`]'s (Pinocchio's for the presets). Spatial vectors are
//! `[linear; angular]` in body coordinates (Featherstone's algorithms, Pinocchio's layout).
//! Links joined by fixed (or locked) joints are lumped into one rigid body, as Pinocchio does.
//!
//! Every public method checks its input and returns an error on bad shapes or non-finite
//! values; the `*_unchecked` variants are for the 1 kHz loop, which checks once up front.


use nalgebra::{DMatrix, Isometry3, Matrix3, Translation3, UnitQuaternion, Vector3};

use crate::error::{check_vector, unknown, Error, Result};
use crate::kinematics::{KinematicModel, ModelOptions, Motion};
use crate::lie::skew;
use crate::robot::RobotDescription;
use crate::urdf::Urdf;

/// Standard gravity used by Pinocchio's default model (m/s^2).
pub const STANDARD_GRAVITY: f64 = 9.81;

/// Inertia of a rigid body about a frame's origin, in that frame's axes: mass, first moment
/// `h = m c` (c the centre of mass) and rotational inertia `i_o` about the origin.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatialInertia {
    /// Mass.
    pub mass: f64,
    /// First moment `m c`.
    pub h: Vector3<f64>,
    /// Rotational inertia about the frame's origin.
    pub i_o: Matrix3<f64>,
}

impl SpatialInertia {
    /// No mass.
    pub fn zero() -> Self {
        SpatialInertia { mass: 0.0, h: Vector3::zeros(), i_o: Matrix3::zeros() }
    }

    /// From mass, centre of mass and rotational inertia about the centre of mass.
    pub fn from_com(mass: f64, com: Vector3<f64>, i_com: Matrix3<f64>) -> Self {
        let cx = skew(&com);
        SpatialInertia { mass, h: com * mass, i_o: i_com - cx * cx * mass }
    }

    /// Centre of mass (the origin when the mass is zero).
    pub fn com(&self) -> Vector3<f64> {
        if self.mass > 0.0 {
            self.h / self.mass
        } else {
            Vector3::zeros()
        }
    }

    /// Rotational inertia about the centre of mass.
    pub fn inertia_about_com(&self) -> Matrix3<f64> {
        let cx = skew(&self.com());
        self.i_o + cx * cx * self.mass
    }

    /// The same inertia seen from a parent frame in which this frame sits at (`r`, `p`)
    /// (`x_parent = r x_this + p`).
    #[inline(always)]
    pub fn transformed(&self, r: &Matrix3<f64>, p: &Vector3<f64>) -> Self {
        // R I R^T - [h']x[p]x - [p]x[h']x - m [p]x[p]x with h' = R h, using
        // [a]x[b]x = b a^T - (a . b) I
        let hr = r * self.h;
        let m = self.mass;
        let diag = 2.0 * hr.dot(p) + m * p.norm_squared();
        // R I R^T on one triangle (I symmetric), mirrored
        let ir = self.i_o * r.transpose();
        let mut i_o = Matrix3::zeros();
        for a in 0..3 {
            for b in a..3 {
                let x = r[(a, 0)] * ir[(0, b)] + r[(a, 1)] * ir[(1, b)] + r[(a, 2)] * ir[(2, b)]
                    - (p[a] * hr[b] + hr[a] * p[b] + m * p[a] * p[b]);
                i_o[(a, b)] = x;
                i_o[(b, a)] = x;
            }
            i_o[(a, a)] += diag;
        }
        SpatialInertia { mass: m, h: hr + p * m, i_o }
    }

    /// Spatial momentum `[f; n]` of the motion `[v; w]`.
    #[inline(always)]
    pub fn apply(&self, v: &Vector3<f64>, w: &Vector3<f64>) -> (Vector3<f64>, Vector3<f64>) {
        (v * self.mass - self.h.cross(w), self.i_o * w + self.h.cross(v))
    }

    #[inline(always)]
    fn add(&mut self, o: &SpatialInertia) {
        self.mass += o.mass;
        self.h += o.h;
        self.i_o += o.i_o;
    }
}

/// How a body moves relative to its parent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis: one value in q.
    Revolute,
    /// Revolute without limits: two values `[cos, sin]` in q.
    Continuous,
    /// Translation along the axis: one value in q.
    Prismatic,
}

/// One moving body: the child link of an active joint plus every link fixed to it.
#[derive(Debug, Clone)]
pub struct Body {
    /// Name of the joint that moves it.
    pub joint: String,
    /// Name of the link that carries the body frame (the joint's child link).
    pub link: String,
    /// Parent body (None: the world).
    pub parent: Option<usize>,
    /// Placement of the joint frame in the parent body (or the world): rotation and origin.
    pub r_parent: Matrix3<f64>,
    /// See `r_parent`.
    pub p_parent: Vector3<f64>,
    /// How the joint moves.
    pub kind: JointKind,
    /// Unit joint axis in the body frame.
    pub axis: Vector3<f64>,
    /// First index of the joint in q.
    pub q_index: usize,
    /// Index of the joint in v.
    pub v_index: usize,
    /// Inertia of the lumped links in the body frame.
    pub inertia: SpatialInertia,
    /// `Some((k, sign))` when `axis` is `sign` times the body frame's k-th unit vector (most
    /// URDF joints): its rotation then turns two columns of `r_parent` and its world axis is a
    /// column of the body's world rotation, without Rodrigues' matrix or a matrix product
    /// (Pinocchio's `JointModelRevoluteX/Y/Z`).
    principal: Option<(usize, f64)>,
}

impl Body {
    /// The placement rotation in the parent for the joint at cosine `c`, sine `s`:
    /// `r_parent R(axis, c, s)`.
    #[inline(always)]
    fn rotation(&self, c: f64, s: f64) -> Matrix3<f64> {
        match self.principal {
            // about +-e_k: columns k + 1, k + 2 (mod 3) turn in their plane, column k stays
            Some((0, sign)) => turn_columns::<1, 2>(&self.r_parent, c, sign * s),
            Some((1, sign)) => turn_columns::<2, 0>(&self.r_parent, c, sign * s),
            Some((_, sign)) => turn_columns::<0, 1>(&self.r_parent, c, sign * s),
            None => self.r_parent * axis_rotation(&self.axis, c, s),
        }
    }

    /// The joint axis in world axes, given the body's world rotation `rw`.
    #[inline(always)]
    fn world_axis(&self, rw: &Matrix3<f64>) -> Vector3<f64> {
        match self.principal {
            Some((k, sign)) => Vector3::new(rw[(0, k)], rw[(1, k)], rw[(2, k)]) * sign,
            None => rw * self.axis,
        }
    }
}

/// `r` with its columns `A`, `B` turned in their plane by the angle of cosine `c`, sine `s`:
/// `r R` for the rotation `R` about the third axis. The columns are constants, so the product is
/// six multiply-adds without index arithmetic.
#[inline(always)]
fn turn_columns<const A: usize, const B: usize>(r: &Matrix3<f64>, c: f64, s: f64) -> Matrix3<f64> {
    let mut out = *r;
    for row in 0..3 {
        let (ra, rb) = (r[(row, A)], r[(row, B)]);
        out[(row, A)] = c * ra + s * rb;
        out[(row, B)] = c * rb - s * ra;
    }
    out
}

/// `Some((k, sign))` when the unit `axis` is exactly `sign` times the k-th unit vector.
fn principal_axis(axis: &Vector3<f64>) -> Option<(usize, f64)> {
    (0..3).find_map(|k| {
        let others_zero = axis[(k + 1) % 3] == 0.0 && axis[(k + 2) % 3] == 0.0;
        (others_zero && axis[k].abs() == 1.0).then(|| (k, axis[k]))
    })
}

/// A frame rigidly attached to a body (or to the world): where Jacobians are taken.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frame {
    /// The body the frame moves with; None: fixed to the world.
    pub body: Option<usize>,
    /// Rotation of the frame in the body (or the world).
    pub r: Matrix3<f64>,
    /// Origin of the frame in the body (or the world).
    pub p: Vector3<f64>,
}

/// Rigid-body dynamics model of a fixed-base arm.
#[derive(Debug, Clone)]
pub struct Dynamics {
    /// The moving bodies, parents first.
    pub bodies: Vec<Body>,
    /// Length of q.
    pub nq: usize,
    /// Length of v.
    pub nv: usize,
    /// Gravity in the world frame (default `[0, 0, -9.81]`, as Pinocchio).
    pub gravity: Vector3<f64>,
    /// Names of the active joints in v order.
    pub joint_names: Vec<String>,
    /// Lower position limit per q element.
    pub lower: Vec<f64>,
    /// Upper position limit per q element.
    pub upper: Vec<f64>,
    /// Largest effort per v element (N m or N), the URDF's `<limit effort>`; +inf where the
    /// URDF gives none (or a value that is not positive).
    pub effort_limit: Vec<f64>,
    /// Largest speed per v element (rad/s or m/s), the URDF's `<limit velocity>`; +inf where
    /// the URDF gives none (or a value that is not positive).
    pub velocity_limit: Vec<f64>,
    /// For each body, the bodies from the root to it (inclusive), root first.
    pub chains: Vec<Vec<usize>>,
    /// Link names and, for each link, the body it belongs to and its placement in that body.
    pub link_names: Vec<String>,
    link_frames: Vec<Frame>,
}

/// A 3-vector in four lanes, the last zero: the articulated-body algorithm's vectors and the
/// columns of its matrices, so that a matrix-vector product is three lane-wise multiply-adds of
/// whole columns (one 256-bit register each in the AVX2 build of the tick, two 128-bit ones in
/// the baseline build, the same arithmetic lane by lane: the same bits).
type Lanes = [f64; 4];

/// `[v; 0]`.
#[inline(always)]
fn lanes(v: &Vector3<f64>) -> Lanes {
    [v.x, v.y, v.z, 0.0]
}

/// `a + b`, lane by lane.
#[inline(always)]
fn add(a: &Lanes, b: &Lanes) -> Lanes {
    let mut out = [0.0; 4];
    for l in 0..4 {
        out[l] = a[l] + b[l];
    }
    out
}

/// `a + b x`, lane by lane.
#[inline(always)]
fn add_scaled(a: &Lanes, b: &Lanes, x: f64) -> Lanes {
    let mut out = [0.0; 4];
    for l in 0..4 {
        out[l] = a[l] + b[l] * x;
    }
    out
}

/// The dot product of the first three lanes.
#[inline(always)]
fn dot(a: &Lanes, b: &Lanes) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// `M x + N y` for the matrices of columns `m`, `n`.
#[inline(always)]
fn mat_vec2(m: &[Lanes; 3], x: &Lanes, n: &[Lanes; 3], y: &Lanes) -> Lanes {
    let mut out = [0.0; 4];
    for l in 0..4 {
        out[l] = (m[0][l] * x[0] + m[1][l] * x[1] + m[2][l] * x[2]) + (n[0][l] * y[0] + n[1][l] * y[1] + n[2][l] * y[2]);
    }
    out
}

/// The columns of `m`.
#[inline(always)]
fn columns(m: &Matrix3<f64>) -> [Lanes; 3] {
    [[m[(0, 0)], m[(1, 0)], m[(2, 0)], 0.0], [m[(0, 1)], m[(1, 1)], m[(2, 1)], 0.0], [m[(0, 2)], m[(1, 2)], m[(2, 2)], 0.0]]
}

/// Articulated-body inertia (world axes, about the world origin): the force
/// `[f; n] = [[a, b], [b^T, c]] [v; w]` needed to accelerate a body and the subtree it carries
/// (`a`, `c` symmetric), each block by its columns, `b^T` kept beside `b` (`bt`) so that
/// `b^T x` is a sum of columns too.
#[derive(Debug, Clone, Copy, PartialEq)]
struct ArticulatedInertia {
    a: [Lanes; 3],
    b: [Lanes; 3],
    bt: [Lanes; 3],
    c: [Lanes; 3],
}

impl ArticulatedInertia {
    /// The rigid body's own inertia: `a = m I`, `b = -[h]x`, `c = i_o`.
    #[inline(always)]
    fn rigid(i: &SpatialInertia) -> Self {
        let (m, h) = (i.mass, &i.h);
        ArticulatedInertia {
            a: [[m, 0.0, 0.0, 0.0], [0.0, m, 0.0, 0.0], [0.0, 0.0, m, 0.0]],
            b: [[0.0, -h.z, h.y, 0.0], [h.z, 0.0, -h.x, 0.0], [-h.y, h.x, 0.0, 0.0]],
            bt: [[0.0, h.z, -h.y, 0.0], [-h.z, 0.0, h.x, 0.0], [h.y, -h.x, 0.0, 0.0]],
            c: columns(&i.i_o),
        }
    }
}

/// Scratch space of one thread for [`Dynamics`]: preallocated, so the algorithms do not
/// allocate.
#[derive(Debug, Clone)]
pub struct DynWorkspace {
    /// Body placements relative to the parent body (rotation, origin).
    pub r: Vec<Matrix3<f64>>,
    /// See `r`.
    pub p: Vec<Vector3<f64>>,
    /// World placements of the bodies (rotation, origin).
    pub rw: Vec<Matrix3<f64>>,
    /// See `rw`.
    pub pw: Vec<Vector3<f64>>,
    /// Body spatial velocities in body coordinates: linear part.
    pub v: Vec<Vector3<f64>>,
    /// Angular part of `v`.
    pub w: Vec<Vector3<f64>>,
    /// World linear velocity of the body origins.
    pub vw: Vec<Vector3<f64>>,
    /// World angular velocities of the bodies.
    pub ww: Vec<Vector3<f64>>,
    acc_v: Vec<Vector3<f64>>,
    acc_w: Vec<Vector3<f64>>,
    f: Vec<Vector3<f64>>,
    n: Vec<Vector3<f64>>,
    ic: Vec<SpatialInertia>,
    /// Joint velocities (nv) seen by the last kinematics update.
    pub qd: Vec<f64>,
    /// Per body, the cosine and sine of its joint's angle in the last kinematics update
    /// (revolute and continuous joints; `[1, 0]` for a prismatic one).
    pub angles: Vec<[f64; 2]>,
    /// Mass matrix and its Cholesky factor (nv x nv).
    pub mass: DMatrix<f64>,
    chol: DMatrix<f64>,
    tmp: Vec<f64>,
    // the articulated-body algorithm, per body in world axes: its articulated inertia, the
    // velocity-product acceleration `c`, the joint's motion subspace `S`, the bias force `p`,
    // `U = IA S`, `D = S^T U`, `u = tau - S^T p` and the acceleration
    ia: Vec<ArticulatedInertia>,
    aba: Vec<AbaBody>,
}

/// The articulated-body algorithm's vectors of one body (see [`DynWorkspace`]), linear then
/// angular parts.
#[derive(Debug, Clone, Copy, Default)]
struct AbaBody {
    s_v: Lanes,
    s_w: Lanes,
    c_v: Lanes,
    c_w: Lanes,
    p_f: Lanes,
    p_n: Lanes,
    u_f: Lanes,
    u_n: Lanes,
    a_v: Lanes,
    a_w: Lanes,
    d: f64,
    u: f64,
}

/// What a kinematics pass writes: the body-relative placements and the body-frame velocities
/// (`Local`), plus the world placements and velocities (`Full`), or the placements and the world
/// velocities without the body-frame ones (`World`).
#[derive(Clone, Copy, PartialEq, Eq)]
enum Pass {
    Local,
    Full,
    World,
}

/// One body's world placement and velocity as a `World` kinematics pass computes them, with its
/// joint axis in world axes: handed to the articulated-body algorithm's first pass in the same
/// loop, without a round trip through the workspace.
struct WorldMotion {
    rw: Matrix3<f64>,
    pw: Vector3<f64>,
    vw: Vector3<f64>,
    ww: Vector3<f64>,
    axis: Vector3<f64>,
}

/// `(sin x, cos x)` for the small angle of one integration step: their Taylor series (to
/// `x^11`, `x^12`) for `|x| <= 1/16`, whose first omitted terms are below 1e-22 there; the
/// library's `sin_cos` beyond.
#[inline(always)]
fn small_sin_cos(x: f64) -> (f64, f64) {
    if x.abs() > 0.0625 {
        return x.sin_cos();
    }
    let x2 = x * x;
    let s = x * (1.0 - x2 / 6.0 * (1.0 - x2 / 20.0 * (1.0 - x2 / 42.0 * (1.0 - x2 / 72.0 * (1.0 - x2 / 110.0)))));
    let c = 1.0 - x2 / 2.0 * (1.0 - x2 / 12.0 * (1.0 - x2 / 30.0 * (1.0 - x2 / 56.0 * (1.0 - x2 / 90.0 * (1.0 - x2 / 132.0)))));
    (s, c)
}

/// Rotation about the unit `axis` with cosine `c` and sine `s` (Rodrigues).
#[inline(always)]
fn axis_rotation(a: &Vector3<f64>, c: f64, s: f64) -> Matrix3<f64> {
    let t = 1.0 - c;
    let (x, y, z) = (a.x, a.y, a.z);
    Matrix3::new(
        c + t * x * x,
        t * x * y - s * z,
        t * x * z + s * y,
        t * x * y + s * z,
        c + t * y * y,
        t * y * z - s * x,
        t * x * z - s * y,
        t * y * z + s * x,
        c + t * z * z,
    )
}

impl Dynamics {
    /// Build from a kinematic model and the URDF that holds the links' `<inertial>` elements.
    /// Floating-base models are refused (this is a fixed-base arm model), and models with mimic
    /// joints (their coupling is not in the recursions).
    pub fn from_model(model: &KinematicModel, urdf: &Urdf) -> Result<Dynamics> {
        if model.floating_base {
            return Err(Error::Invalid(
                "dynamics: floating-base models are not supported (fixed-base arms only)".into(),
            ));
        }
        if let Some(j) = model.joints.iter().find(|j| j.mimic.is_some()) {
            let master = &model.joints[j.mimic.map_or(0, |f| f.joint)].name;
            return Err(Error::Invalid(format!(
                "dynamics: joint '{}' mimics '{master}', and mimic joints are not supported by the dynamics: lock both",
                j.name
            )));
        }
        // poses at the neutral configuration give the constant placements between links of a body
        let mut q0 = vec![0.0; model.nq];
        for j in &model.joints {
            if let Motion::Continuous { .. } = j.motion {
                q0[j.q_index] = 1.0;
            }
        }
        let mut poses = Vec::new();
        model.forward_kinematics_unchecked(&q0, &mut poses);
        let n_links = model.n_links();
        // body index of each link that is the child of an active joint
        let mut body_of_child: Vec<Option<usize>> = vec![None; n_links];
        let mut bodies: Vec<Body> = Vec::new();
        for j in &model.joints {
            let (kind, axis) = match &j.motion {
                Motion::Fixed => continue,
                Motion::Revolute { axis } => (JointKind::Revolute, axis.into_inner()),
                Motion::Continuous { axis } => (JointKind::Continuous, axis.into_inner()),
                Motion::Prismatic { axis } => (JointKind::Prismatic, axis.into_inner()),
            };
            let parent_link_body = model.body_of_link[j.parent];
            let parent = body_of_child[parent_link_body];
            let parent_pose = if parent.is_some() { poses[parent_link_body] } else { Isometry3::identity() };
            let placement = parent_pose.inverse() * poses[j.parent] * j.origin;
            body_of_child[j.child] = Some(bodies.len());
            bodies.push(Body {
                joint: j.name.clone(),
                link: model.link_names[j.child].clone(),
                parent,
                r_parent: placement.rotation.to_rotation_matrix().into_inner(),
                p_parent: placement.translation.vector,
                kind,
                axis,
                q_index: j.q_index,
                v_index: j.v_index,
                inertia: SpatialInertia::zero(),
                principal: principal_axis(&axis),
            });
        }
        let mut link_frames = Vec::with_capacity(n_links);
        for l in 0..n_links {
            let b = model.body_of_link[l];
            let body = body_of_child[b];
            let placement = match body {
                Some(_) => poses[b].inverse() * poses[l],
                None => poses[l],
            };
            link_frames.push(Frame {
                body,
                r: placement.rotation.to_rotation_matrix().into_inner(),
                p: placement.translation.vector,
            });
        }
        // lump the links' inertias into their bodies
        for link in &urdf.links {
            let Some(inertial) = link.inertial else { continue };
            let l = model.link_index(&link.name)?;
            let fr = link_frames[l];
            if let Some(b) = fr.body {
                let si = SpatialInertia::from_com(inertial.mass, inertial.com, inertial.inertia);
                bodies[b].inertia.add(&si.transformed(&fr.r, &fr.p));
            }
        }
        let chains = (0..bodies.len())
            .map(|i| {
                let mut c = vec![i];
                let mut k = i;
                while let Some(p) = bodies[k].parent {
                    c.push(p);
                    k = p;
                }
                c.reverse();
                c
            })
            .collect();
        // the URDF's effort and speed limits of the active joints, in v order
        let (mut effort_limit, mut velocity_limit) = (vec![f64::INFINITY; model.nv], vec![f64::INFINITY; model.nv]);
        let positive = |x: f64| if x > 0.0 { x } else { f64::INFINITY };
        for b in &bodies {
            if let Some(j) = urdf.joints.iter().find(|j| j.name == b.joint) {
                effort_limit[b.v_index] = positive(j.effort);
                velocity_limit[b.v_index] = positive(j.velocity);
            }
        }
        let dynamics = Dynamics {
            effort_limit,
            velocity_limit,
            nq: model.nq,
            nv: model.nv,
            gravity: Vector3::new(0.0, 0.0, -STANDARD_GRAVITY),
            joint_names: bodies.iter().map(|b| b.joint.clone()).collect(),
            lower: model.lower.clone(),
            upper: model.upper.clone(),
            chains,
            link_names: model.link_names.clone(),
            link_frames,
            bodies,
        };
        dynamics.check_bodies()?;
        Ok(dynamics)
    }

    /// Parse a URDF and build its kinematic model and dynamics.
    pub fn from_urdf(urdf: &Urdf, options: &ModelOptions) -> Result<Dynamics> {
        let model = KinematicModel::from_urdf(urdf, options)?;
        Dynamics::from_model(&model, urdf)
    }

    /// The dynamics of a fixed-base robot description (e.g. the "ur5" or "panda" preset), with
    /// its locked joints held at their reference values.
    pub fn from_description(robot: &RobotDescription) -> Result<Dynamics> {
        if robot.floating_base {
            return Err(Error::Invalid(format!(
                "dynamics: robot '{}' has a floating base; only fixed-base arms are supported",
                robot.name
            )));
        }
        let files = robot.read()?;
        Dynamics::from_model(&files.model, &files.urdf)
    }

    fn check_bodies(&self) -> Result<()> {
        for b in &self.bodies {
            let i = &b.inertia;
            if !(i.mass.is_finite() && i.h.iter().all(|x| x.is_finite()) && i.i_o.iter().all(|x| x.is_finite())) {
                return Err(Error::Invalid(format!("dynamics: body '{}' has a non-finite inertia", b.link)));
            }
        }
        Ok(())
    }

    /// Number of moving bodies.
    pub fn n_bodies(&self) -> usize {
        self.bodies.len()
    }

    /// A workspace sized for this model.
    pub fn workspace(&self) -> DynWorkspace {
        let n = self.bodies.len();
        let z = vec![Vector3::zeros(); n];
        DynWorkspace {
            r: vec![Matrix3::identity(); n],
            p: z.clone(),
            rw: vec![Matrix3::identity(); n],
            pw: z.clone(),
            v: z.clone(),
            w: z.clone(),
            vw: z.clone(),
            ww: z.clone(),
            acc_v: z.clone(),
            acc_w: z.clone(),
            f: z.clone(),
            n: z,
            ic: vec![SpatialInertia::zero(); n],
            qd: vec![0.0; self.nv],
            angles: vec![[1.0, 0.0]; n],
            mass: DMatrix::zeros(self.nv, self.nv),
            chol: DMatrix::zeros(self.nv, self.nv),
            tmp: vec![0.0; self.nv],
            ia: vec![ArticulatedInertia::rigid(&SpatialInertia::zero()); n],
            aba: vec![AbaBody::default(); n],
        }
    }

    /// The frame of a link, optionally offset by `placement` (in the link frame).
    pub fn frame(&self, link: &str, placement: &Isometry3<f64>) -> Result<Frame> {
        let l = self.link_names.iter().position(|n| n == link).ok_or_else(|| {
            let known: Vec<&str> = self.link_names.iter().map(String::as_str).collect();
            unknown("link", link, &known)
        })?;
        let lf = self.link_frames[l];
        let r = placement.rotation.to_rotation_matrix().into_inner();
        Ok(Frame { body: lf.body, r: lf.r * r, p: lf.p + lf.r * placement.translation.vector })
    }

    /// Add a rigid body (mass, centre of mass and inertia about it, both in the frame's axes)
    /// to the body that carries `frame`, e.g. a tool or a payload.
    pub fn add_inertia(&mut self, frame: &Frame, mass: f64, com: Vector3<f64>, inertia_com: Matrix3<f64>) -> Result<()> {
        if !(mass.is_finite() && mass >= 0.0) {
            return Err(Error::Invalid(format!("added mass must be finite and >= 0, got {mass}")));
        }
        crate::error::check_finite("added centre of mass", com.as_slice())?;
        crate::error::check_finite("added inertia", inertia_com.as_slice())?;
        if (inertia_com - inertia_com.transpose()).amax() > 1e-12 * (1.0 + inertia_com.amax()) {
            return Err(Error::Invalid("added inertia must be symmetric".into()));
        }
        let Some(b) = frame.body else {
            return Err(Error::Invalid("cannot add inertia to a frame fixed to the world".into()));
        };
        let si = SpatialInertia::from_com(mass, com, inertia_com).transformed(&frame.r, &frame.p);
        self.bodies[b].inertia.add(&si);
        Ok(())
    }

    /// Check a state: q of length nq and v of length nv, finite.
    pub fn check_state(&self, q: &[f64], v: Option<&[f64]>) -> Result<()> {
        check_vector("configuration q", q, self.nq)?;
        if let Some(v) = v {
            check_vector("velocity v", v, self.nv)?;
        }
        Ok(())
    }

    /// Placements and velocities of every body for (q, v) (v = None: at rest).
    #[inline(always)]
    pub fn update_kinematics_unchecked(&self, q: &[f64], v: Option<&[f64]>, ws: &mut DynWorkspace) {
        self.kinematics_pass(q, None, v, ws, Pass::Full, false);
    }

    /// The kinematics at `q (+) factor dq` (see [`integrate_scaled`](Self::integrate_scaled))
    /// with velocity `v`, where `angles` holds each body's `[cos, sin]` at `q` (a workspace's
    /// [`angles`](DynWorkspace::angles) after an update at `q`): each joint's rotation by angle
    /// addition with the small step's cosine and sine, without the `sin_cos` of the whole angle,
    /// and the world velocities from the parent's. Writes the placements (`r`, `p`, `rw`,
    /// `pw`), the world velocities (`vw`, `ww`), `qd` and `angles`, equal to
    /// [`update_kinematics_unchecked`](Self::update_kinematics_unchecked)'s at the integrated q
    /// up to rounding: enough for [`aba_from_kinematics`](Self::aba_from_kinematics), frames and
    /// Jacobians; the body-frame velocities (`v`, `w`) are left stale (not for RNEA). The RK
    /// stages of the 1 kHz plant take their kinematics this way from the period's start.
    pub fn update_kinematics_moved_unchecked(&self, angles: &[[f64; 2]], q: &[f64], dq: &[f64], factor: f64, v: &[f64], ws: &mut DynWorkspace) {
        self.kinematics_pass(q, Some((angles, dq, factor)), Some(v), ws, Pass::World, false);
    }

    /// [`update_kinematics_moved_unchecked`](Self::update_kinematics_moved_unchecked) followed
    /// by [`aba_from_kinematics`](Self::aba_from_kinematics) under `tau`, with the kinematics
    /// and the articulated-body algorithm's first pass in one loop over the bodies: the same
    /// arithmetic (the same bits in `qdd` and the workspace) without writing and re-reading each
    /// body's world placement and velocity or taking its joint axis twice. The RK stages of the
    /// 1 kHz plant after the first.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub fn aba_moved_unchecked(&self, angles: &[[f64; 2]], q: &[f64], dq: &[f64], factor: f64, v: &[f64], tau: &[f64], ws: &mut DynWorkspace, qdd: &mut [f64]) -> Result<()> {
        self.kinematics_pass(q, Some((angles, dq, factor)), Some(v), ws, Pass::World, true);
        self.aba_inward_outward(tau, ws, qdd)
    }

    /// As [`update_kinematics_unchecked`](Self::update_kinematics_unchecked) but without the
    /// world placements and velocities (`rw`, `pw`, `vw`, `ww` are left stale): enough for
    /// [`rnea_from_kinematics`](Self::rnea_from_kinematics),
    /// [`mass_matrix_from_kinematics`](Self::mass_matrix_from_kinematics) and
    /// [`forward_dynamics_from_kinematics`](Self::forward_dynamics_from_kinematics), not for
    /// frames and Jacobians.
    pub fn update_local_kinematics_unchecked(&self, q: &[f64], v: Option<&[f64]>, ws: &mut DynWorkspace) {
        self.kinematics_pass(q, None, v, ws, Pass::Local, false);
    }

    /// The kinematics at q, or with `moved` = (angles at q, dq, factor) at `q (+) factor dq`.
    /// A `World` pass with `aba_first_pass` runs the articulated-body algorithm's first pass on
    /// each body's world motion once it is written (a flag, not a closure: a closure would be
    /// compiled apart from the tick's AVX2 build instead of inlined into it).
    #[inline(always)]
    fn kinematics_pass(&self, q: &[f64], moved: Option<(&[[f64; 2]], &[f64], f64)>, v: Option<&[f64]>, ws: &mut DynWorkspace, pass: Pass, aba_first_pass: bool) {
        for (i, b) in self.bodies.iter().enumerate() {
            let qd = v.map_or(0.0, |v| v[b.v_index]);
            ws.qd[b.v_index] = qd;
            let (r, p) = match b.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    let [c, s] = match moved {
                        Some((angles, dq, factor)) => {
                            let [c0, s0] = angles[i];
                            let (sd, cd) = small_sin_cos(factor * dq[b.v_index]);
                            [c0 * cd - s0 * sd, s0 * cd + c0 * sd]
                        }
                        None if b.kind == JointKind::Revolute => {
                            let (s, c) = q[b.q_index].sin_cos();
                            [c, s]
                        }
                        None => {
                            let (c, s) = (q[b.q_index], q[b.q_index + 1]);
                            let n = c.hypot(s);
                            if n > 0.0 {
                                [c / n, s / n]
                            } else {
                                [1.0, 0.0]
                            }
                        }
                    };
                    ws.angles[i] = [c, s];
                    (b.rotation(c, s), b.p_parent)
                }
                JointKind::Prismatic => {
                    let x = q[b.q_index] + moved.map_or(0.0, |(_, dq, factor)| factor * dq[b.v_index]);
                    (b.r_parent, b.p_parent + b.r_parent * b.axis * x)
                }
            };
            ws.r[i] = r;
            ws.p[i] = p;
            if pass == Pass::World {
                // world velocities straight from the parent's: the body-frame ones are not needed
                let (rw, pw) = match b.parent {
                    Some(pi) => (ws.rw[pi] * r, ws.pw[pi] + ws.rw[pi] * p),
                    None => (r, p),
                };
                let (mut vw, mut ww) = match b.parent {
                    Some(pi) => (ws.vw[pi] + ws.ww[pi].cross(&(pw - ws.pw[pi])), ws.ww[pi]),
                    None => (Vector3::zeros(), Vector3::zeros()),
                };
                let axis = b.world_axis(&rw);
                match b.kind {
                    JointKind::Revolute | JointKind::Continuous => ww += axis * qd,
                    JointKind::Prismatic => vw += axis * qd,
                }
                ws.rw[i] = rw;
                ws.pw[i] = pw;
                ws.vw[i] = vw;
                ws.ww[i] = ww;
                if aba_first_pass {
                    self.aba_first_pass_body(i, b, &WorldMotion { rw, pw, vw, ww, axis }, ws);
                }
                continue;
            }
            let rt = r.transpose();
            let (mut vi, mut wi) = match b.parent {
                Some(pi) => (rt * (ws.v[pi] + ws.w[pi].cross(&p)), rt * ws.w[pi]),
                None => (Vector3::zeros(), Vector3::zeros()),
            };
            match b.kind {
                JointKind::Revolute | JointKind::Continuous => wi += b.axis * qd,
                JointKind::Prismatic => vi += b.axis * qd,
            }
            ws.v[i] = vi;
            ws.w[i] = wi;
            if pass == Pass::Full {
                let (rw, pw) = match b.parent {
                    Some(pi) => (ws.rw[pi] * r, ws.pw[pi] + ws.rw[pi] * p),
                    None => (r, p),
                };
                ws.rw[i] = rw;
                ws.pw[i] = pw;
                ws.vw[i] = rw * vi;
                ws.ww[i] = rw * wi;
            }
        }
    }

    /// Copy the kinematics of `from` (placements, velocities, joint speeds: what
    /// [`update_kinematics_unchecked`](Self::update_kinematics_unchecked) writes) into `to`.
    /// They depend on the joints only, not on the inertias: `from` may come from another model
    /// of the same robot with other payloads (e.g. the controller's nominal model and the
    /// plant's true one). Both workspaces must be this model's size.
    #[inline(always)]
    pub fn copy_kinematics(&self, from: &DynWorkspace, to: &mut DynWorkspace) {
        to.r.copy_from_slice(&from.r);
        to.p.copy_from_slice(&from.p);
        to.rw.copy_from_slice(&from.rw);
        to.pw.copy_from_slice(&from.pw);
        to.v.copy_from_slice(&from.v);
        to.w.copy_from_slice(&from.w);
        to.vw.copy_from_slice(&from.vw);
        to.ww.copy_from_slice(&from.ww);
        to.qd.copy_from_slice(&from.qd);
        to.angles.copy_from_slice(&from.angles);
    }

    /// Whether `other` has this model's joints and placements (the same kinematics; the
    /// inertias may differ), so that [`copy_kinematics`](Self::copy_kinematics) may pass
    /// kinematics between them.
    pub fn same_kinematics(&self, other: &Dynamics) -> bool {
        self.nq == other.nq
            && self.nv == other.nv
            && self.bodies.len() == other.bodies.len()
            && self.bodies.iter().zip(&other.bodies).all(|(a, b)| {
                a.parent == b.parent
                    && a.kind == b.kind
                    && a.axis == b.axis
                    && a.r_parent == b.r_parent
                    && a.p_parent == b.p_parent
                    && a.q_index == b.q_index
                    && a.v_index == b.v_index
            })
    }

    /// RNEA on the kinematics in `ws`: `tau = M qdd + C v + g` (qdd None: zero; with
    /// `gravity` false the gravity term is left out). Writes `tau` (nv).
    #[inline(always)]
    pub fn rnea_from_kinematics(&self, qdd: Option<&[f64]>, gravity: bool, ws: &mut DynWorkspace, tau: &mut [f64]) {
        let g0 = if gravity { -self.gravity } else { Vector3::zeros() };
        for (i, b) in self.bodies.iter().enumerate() {
            let qd = ws.qd[b.v_index];
            let qdd_i = qdd.map_or(0.0, |a| a[b.v_index]);
            let rt = ws.r[i].transpose();
            let (mut av, mut aw) = match b.parent {
                Some(pi) => (rt * (ws.acc_v[pi] + ws.acc_w[pi].cross(&ws.p[i])), rt * ws.acc_w[pi]),
                None => (rt * g0, Vector3::zeros()),
            };
            let (vi, wi) = (ws.v[i], ws.w[i]);
            match b.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    let s = b.axis * qd;
                    av += vi.cross(&s);
                    aw += b.axis * qdd_i + wi.cross(&s);
                }
                JointKind::Prismatic => {
                    let s = b.axis * qd;
                    av += b.axis * qdd_i + wi.cross(&s);
                }
            }
            ws.acc_v[i] = av;
            ws.acc_w[i] = aw;
            let (f_a, n_a) = b.inertia.apply(&av, &aw);
            let (f_v, n_v) = b.inertia.apply(&vi, &wi);
            ws.f[i] = f_a + wi.cross(&f_v);
            ws.n[i] = n_a + wi.cross(&n_v) + vi.cross(&f_v);
        }
        for i in (0..self.bodies.len()).rev() {
            let b = &self.bodies[i];
            tau[b.v_index] = match b.kind {
                JointKind::Revolute | JointKind::Continuous => b.axis.dot(&ws.n[i]),
                JointKind::Prismatic => b.axis.dot(&ws.f[i]),
            };
            if let Some(pi) = b.parent {
                let fp = ws.r[i] * ws.f[i];
                let np = ws.r[i] * ws.n[i] + ws.p[i].cross(&fp);
                ws.f[pi] += fp;
                ws.n[pi] += np;
            }
        }
    }

    /// CRBA on the placements in `ws`: fills `ws.mass` (both triangles).
    #[inline(always)]
    pub fn mass_matrix_from_kinematics(&self, ws: &mut DynWorkspace) {
        let nb = self.bodies.len();
        // entries between bodies on different branches of a tree stay zero
        ws.mass.fill(0.0);
        for i in 0..nb {
            ws.ic[i] = self.bodies[i].inertia;
        }
        for i in (0..nb).rev() {
            if let Some(pi) = self.bodies[i].parent {
                let t = ws.ic[i].transformed(&ws.r[i], &ws.p[i]);
                ws.ic[pi].add(&t);
            }
        }
        for i in 0..nb {
            let b = &self.bodies[i];
            let (mut f, mut n) = match b.kind {
                JointKind::Revolute | JointKind::Continuous => ws.ic[i].apply(&Vector3::zeros(), &b.axis),
                JointKind::Prismatic => ws.ic[i].apply(&b.axis, &Vector3::zeros()),
            };
            let s_dot = |bj: &Body, f: &Vector3<f64>, n: &Vector3<f64>| match bj.kind {
                JointKind::Revolute | JointKind::Continuous => bj.axis.dot(n),
                JointKind::Prismatic => bj.axis.dot(f),
            };
            ws.mass[(b.v_index, b.v_index)] = s_dot(b, &f, &n);
            let mut j = i;
            while let Some(pj) = self.bodies[j].parent {
                let fp = ws.r[j] * f;
                n = ws.r[j] * n + ws.p[j].cross(&fp);
                f = fp;
                j = pj;
                let bj = &self.bodies[j];
                let m = s_dot(bj, &f, &n);
                ws.mass[(b.v_index, bj.v_index)] = m;
                ws.mass[(bj.v_index, b.v_index)] = m;
            }
        }
    }

    /// Mass matrix M(q) (nv x nv) into `out`.
    pub fn mass_matrix(&self, q: &[f64], ws: &mut DynWorkspace, out: &mut DMatrix<f64>) -> Result<()> {
        self.check_state(q, None)?;
        self.update_kinematics_unchecked(q, None, ws);
        self.mass_matrix_from_kinematics(ws);
        out.clone_from(&ws.mass);
        Ok(())
    }

    /// Inverse dynamics `tau = M(q) a + C(q, v) v + g(q)`.
    pub fn rnea(&self, q: &[f64], v: &[f64], a: &[f64], ws: &mut DynWorkspace, tau: &mut [f64]) -> Result<()> {
        self.check_state(q, Some(v))?;
        check_vector("acceleration a", a, self.nv)?;
        check_len("tau (output)", tau, self.nv)?;
        self.update_kinematics_unchecked(q, Some(v), ws);
        self.rnea_from_kinematics(Some(a), true, ws, tau);
        Ok(())
    }

    /// Bias forces `C(q, v) v + g(q)` (Pinocchio's `nonLinearEffects`).
    pub fn nonlinear_effects(&self, q: &[f64], v: &[f64], ws: &mut DynWorkspace, out: &mut [f64]) -> Result<()> {
        self.check_state(q, Some(v))?;
        check_len("bias (output)", out, self.nv)?;
        self.update_kinematics_unchecked(q, Some(v), ws);
        self.rnea_from_kinematics(None, true, ws, out);
        Ok(())
    }

    /// Generalised gravity `g(q)`.
    pub fn gravity_torque(&self, q: &[f64], ws: &mut DynWorkspace, out: &mut [f64]) -> Result<()> {
        self.check_state(q, None)?;
        check_len("gravity (output)", out, self.nv)?;
        self.update_kinematics_unchecked(q, None, ws);
        self.rnea_from_kinematics(None, true, ws, out);
        Ok(())
    }

    /// Forward dynamics `qdd = M(q)^-1 (tau - C(q, v) v - g(q))`.
    pub fn forward_dynamics(&self, q: &[f64], v: &[f64], tau: &[f64], ws: &mut DynWorkspace, qdd: &mut [f64]) -> Result<()> {
        self.check_state(q, Some(v))?;
        check_vector("torque tau", tau, self.nv)?;
        check_len("qdd (output)", qdd, self.nv)?;
        self.update_kinematics_unchecked(q, Some(v), ws);
        self.forward_dynamics_from_kinematics(tau, ws, qdd)
    }

    /// Forward dynamics on the kinematics in `ws` (set by
    /// [`update_kinematics_unchecked`](Self::update_kinematics_unchecked) with the velocity).
    /// Fails only if the mass matrix is not positive definite (a body without inertia).
    pub fn forward_dynamics_from_kinematics(&self, tau: &[f64], ws: &mut DynWorkspace, qdd: &mut [f64]) -> Result<()> {
        let mut bias = std::mem::take(&mut ws.tmp);
        self.rnea_from_kinematics(None, true, ws, &mut bias);
        for i in 0..self.nv {
            qdd[i] = tau[i] - bias[i];
        }
        ws.tmp = bias;
        self.mass_matrix_from_kinematics(ws);
        cholesky_in_place(&ws.mass, &mut ws.chol).map_err(|k| {
            Error::Invalid(format!(
                "dynamics: the mass matrix is not positive definite (pivot {k}, joint '{}'): a moving body without inertia?",
                self.joint_names.get(k).map_or("?", String::as_str)
            ))
        })?;
        cholesky_solve(&ws.chol, qdd);
        Ok(())
    }

    /// Forward dynamics `qdd = M(q)^-1 (tau - C(q, v) v - g(q))` by the articulated-body
    /// algorithm on the kinematics in `ws` (set by
    /// [`update_kinematics_unchecked`](Self::update_kinematics_unchecked) with the velocity: it
    /// reads the world placements and velocities): the result of
    /// [`forward_dynamics_from_kinematics`](Self::forward_dynamics_from_kinematics) up to
    /// rounding, in O(n) and without the mass matrix. Spatial quantities are taken in world
    /// axes about the world origin, so that a body hands its articulated inertia and bias force
    /// to its parent by a sum, without a change of frame: three passes, the joint axes, the
    /// velocity-product accelerations and the bias forces (root to leaves); the articulated
    /// inertias and bias forces with each joint's own motion taken out (leaves to root); the
    /// accelerations (root to leaves, gravity as the base's acceleration). Fails only if a
    /// joint's articulated inertia `S^T IA S` is not positive (a moving body without inertia), as
    /// the mass matrix's Cholesky factor fails.
    #[inline(always)]
    pub fn aba_from_kinematics(&self, tau: &[f64], ws: &mut DynWorkspace, qdd: &mut [f64]) -> Result<()> {
        for (i, b) in self.bodies.iter().enumerate() {
            let rw = ws.rw[i];
            let m = WorldMotion { rw, pw: ws.pw[i], vw: ws.vw[i], ww: ws.ww[i], axis: b.world_axis(&rw) };
            self.aba_first_pass_body(i, b, &m, ws);
        }
        self.aba_inward_outward(tau, ws, qdd)
    }

    /// The articulated-body algorithm's first pass for body `i` moving as `m`: the joint's
    /// motion subspace, the velocity-product acceleration, the bias force and the rigid
    /// articulated inertia, in world axes about the world origin.
    #[inline(always)]
    fn aba_first_pass_body(&self, i: usize, b: &Body, m: &WorldMotion, ws: &mut DynWorkspace) {
        let (rw, pw, w, axis) = (&m.rw, &m.pw, m.ww, m.axis);
        // the spatial velocity at the world origin and the joint's motion subspace S
        let v = m.vw + pw.cross(&w);
        let (sv, sw) = match b.kind {
            JointKind::Revolute | JointKind::Continuous => (pw.cross(&axis), axis),
            JointKind::Prismatic => (axis, Vector3::zeros()),
        };
        let qd = ws.qd[b.v_index];
        let (jv, jw) = (sv * qd, sw * qd);
        let inertia = b.inertia.transformed(rw, pw);
        let (f, n) = inertia.apply(&v, &w);
        let body = &mut ws.aba[i];
        body.c_v = lanes(&(w.cross(&jv) + v.cross(&jw)));
        body.c_w = lanes(&w.cross(&jw));
        body.s_v = lanes(&sv);
        body.s_w = lanes(&sw);
        body.p_f = lanes(&w.cross(&f));
        body.p_n = lanes(&(w.cross(&n) + v.cross(&f)));
        ws.ia[i] = ArticulatedInertia::rigid(&inertia);
    }

    /// The articulated-body algorithm's last two passes on the first pass's results in `ws`
    /// (see [`aba_from_kinematics`](Self::aba_from_kinematics)). The articulated inertias are
    /// reduced in place, each handed to its parent (which precedes it) as column sums; the
    /// outer products `U U^T / D` are taken as `(U_r U_c) / D`, exactly symmetric.
    #[inline(always)]
    fn aba_inward_outward(&self, tau: &[f64], ws: &mut DynWorkspace, qdd: &mut [f64]) -> Result<()> {
        let nb = self.bodies.len();
        let (ias, abas) = (&mut ws.ia[..nb], &mut ws.aba[..nb]);
        for (i, b) in self.bodies.iter().enumerate().rev() {
            let (ia_head, ia_tail) = ias.split_at_mut(i);
            let (aba_head, aba_tail) = abas.split_at_mut(i);
            let (ia, x) = (&ia_tail[0], &mut aba_tail[0]);
            let uf = mat_vec2(&ia.a, &x.s_v, &ia.b, &x.s_w);
            let un = mat_vec2(&ia.bt, &x.s_v, &ia.c, &x.s_w);
            let d = dot(&x.s_v, &uf) + dot(&x.s_w, &un);
            let u = tau[b.v_index] - dot(&x.s_v, &x.p_f) - dot(&x.s_w, &x.p_n);
            if !(d > 0.0 && d.is_finite()) {
                return Err(Error::Invalid(format!(
                    "dynamics: the mass matrix is not positive definite (joint '{}' moves no inertia): a moving body without inertia?",
                    b.joint
                )));
            }
            (x.u_f, x.u_n, x.d, x.u) = (uf, un, d, u);
            let Some(pi) = b.parent else { continue };
            // the parent carries IA - U U^T / D and p + IA c + U (u - U^T c) / D
            let k = (u - dot(&uf, &x.c_v) - dot(&un, &x.c_w)) / d;
            let pf = add_scaled(&add(&x.p_f, &mat_vec2(&ia.a, &x.c_v, &ia.b, &x.c_w)), &uf, k);
            let pn = add_scaled(&add(&x.p_n, &mat_vec2(&ia.bt, &x.c_v, &ia.c, &x.c_w)), &un, k);
            let parent = &mut aba_head[pi];
            parent.p_f = add(&parent.p_f, &pf);
            parent.p_n = add(&parent.p_n, &pn);
            let inv = 1.0 / d;
            let pa = &mut ia_head[pi];
            for c in 0..3 {
                for l in 0..4 {
                    pa.a[c][l] += ia.a[c][l] - uf[l] * uf[c] * inv;
                    pa.b[c][l] += ia.b[c][l] - uf[l] * un[c] * inv;
                    pa.bt[c][l] += ia.bt[c][l] - un[l] * uf[c] * inv;
                    pa.c[c][l] += ia.c[c][l] - un[l] * un[c] * inv;
                }
            }
        }
        let g0 = lanes(&-self.gravity);
        for (i, b) in self.bodies.iter().enumerate() {
            let (head, tail) = abas.split_at_mut(i);
            let x = &mut tail[0];
            let (av, aw) = match b.parent {
                Some(pi) => (add(&head[pi].a_v, &x.c_v), add(&head[pi].a_w, &x.c_w)),
                None => (add(&g0, &x.c_v), x.c_w),
            };
            let a = (x.u - dot(&x.u_f, &av) - dot(&x.u_n, &aw)) / x.d;
            x.a_v = add_scaled(&av, &x.s_v, a);
            x.a_w = add_scaled(&aw, &x.s_w, a);
            qdd[b.v_index] = a;
        }
        Ok(())
    }

    /// World placement of `frame` on the kinematics in `ws`.
    #[inline(always)]
    pub fn frame_placement(&self, frame: &Frame, ws: &DynWorkspace) -> (Matrix3<f64>, Vector3<f64>) {
        match frame.body {
            Some(b) => (ws.rw[b] * frame.r, ws.pw[b] + ws.rw[b] * frame.p),
            None => (frame.r, frame.p),
        }
    }

    /// World placement of `frame` as an isometry.
    pub fn frame_isometry(&self, frame: &Frame, ws: &DynWorkspace) -> Isometry3<f64> {
        let (r, p) = self.frame_placement(frame, ws);
        Isometry3::from_parts(
            Translation3::from(p),
            UnitQuaternion::from_rotation_matrix(&nalgebra::Rotation3::from_matrix_unchecked(r)),
        )
    }

    /// Linear velocity of the frame origin and angular velocity, world axes.
    pub fn frame_velocity(&self, frame: &Frame, ws: &DynWorkspace) -> (Vector3<f64>, Vector3<f64>) {
        match frame.body {
            Some(b) => {
                let (_, p) = self.frame_placement(frame, ws);
                (ws.vw[b] + ws.ww[b].cross(&(p - ws.pw[b])), ws.ww[b])
            }
            None => (Vector3::zeros(), Vector3::zeros()),
        }
    }

    /// Jacobian (6 x nv, `LOCAL_WORLD_ALIGNED`) of `frame` and, if `djac` is given, its time
    /// derivative, from the kinematics (with velocity) in `ws`. Both outputs must be 6 x nv.
    #[inline(always)]
    pub fn frame_jacobians_from_kinematics(&self, frame: &Frame, ws: &DynWorkspace, jac: &mut DMatrix<f64>, mut djac: Option<&mut DMatrix<f64>>) {
        jac.fill(0.0);
        if let Some(d) = djac.as_deref_mut() {
            d.fill(0.0);
        }
        let Some(fb) = frame.body else { return };
        let (_, pf) = self.frame_placement(frame, ws);
        let (vf, _) = self.frame_velocity(frame, ws);
        for &j in &self.chains[fb] {
            let b = &self.bodies[j];
            let a = b.world_axis(&ws.rw[j]);
            let c = b.v_index;
            let jc = column6(jac, c);
            match b.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    let r = pf - ws.pw[j];
                    let lin = a.cross(&r);
                    for k in 0..3 {
                        jc[k] = lin[k];
                        jc[k + 3] = a[k];
                    }
                    if let Some(d) = djac.as_deref_mut() {
                        let dc = column6(d, c);
                        let ad = ws.ww[j].cross(&a);
                        let lind = ad.cross(&r) + a.cross(&(vf - ws.vw[j]));
                        for k in 0..3 {
                            dc[k] = lind[k];
                            dc[k + 3] = ad[k];
                        }
                    }
                }
                JointKind::Prismatic => {
                    for k in 0..3 {
                        jc[k] = a[k];
                    }
                    if let Some(d) = djac.as_deref_mut() {
                        let dc = column6(d, c);
                        let ad = ws.ww[j].cross(&a);
                        for k in 0..3 {
                            dc[k] = ad[k];
                        }
                    }
                }
            }
        }
    }

    /// Jacobian of `frame` at q (`LOCAL_WORLD_ALIGNED`, 6 x nv).
    pub fn frame_jacobian(&self, q: &[f64], frame: &Frame, ws: &mut DynWorkspace, out: &mut DMatrix<f64>) -> Result<()> {
        self.check_state(q, None)?;
        self.update_kinematics_unchecked(q, None, ws);
        out.resize_mut(6, self.nv, 0.0);
        self.frame_jacobians_from_kinematics(frame, ws, out, None);
        Ok(())
    }

    /// Time derivative of the `LOCAL_WORLD_ALIGNED` Jacobian of `frame` at (q, v).
    pub fn frame_jacobian_time_variation(&self, q: &[f64], v: &[f64], frame: &Frame, ws: &mut DynWorkspace, out: &mut DMatrix<f64>) -> Result<()> {
        self.check_state(q, Some(v))?;
        self.update_kinematics_unchecked(q, Some(v), ws);
        let mut jac = DMatrix::zeros(6, self.nv);
        out.resize_mut(6, self.nv, 0.0);
        self.frame_jacobians_from_kinematics(frame, ws, &mut jac, Some(out));
        Ok(())
    }

    /// Kinetic energy `v^T M v / 2` from the kinematics in `ws`.
    pub fn kinetic_energy_from_kinematics(&self, ws: &DynWorkspace) -> f64 {
        self.bodies
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let (f, n) = b.inertia.apply(&ws.v[i], &ws.w[i]);
                0.5 * (ws.v[i].dot(&f) + ws.w[i].dot(&n))
            })
            .sum()
    }

    /// Potential energy `-m g . c` (zero at the world origin) from the placements in `ws`.
    pub fn potential_energy_from_kinematics(&self, ws: &DynWorkspace) -> f64 {
        self.bodies
            .iter()
            .enumerate()
            .map(|(i, b)| {
                let c = ws.pw[i] * b.inertia.mass + ws.rw[i] * b.inertia.h;
                -self.gravity.dot(&c)
            })
            .sum()
    }

    /// Total mass of the moving bodies.
    pub fn moving_mass(&self) -> f64 {
        self.bodies.iter().map(|b| b.inertia.mass).sum()
    }
}

/// Column `c` of a 6-row matrix (column-major storage): one bounds check for the column
/// instead of a shape check per element.
#[inline(always)]
fn column6(m: &mut DMatrix<f64>, c: usize) -> &mut [f64; 6] {
    (&mut m.as_mut_slice()[6 * c..6 * c + 6]).try_into().expect("a 6-row matrix")
}

fn check_len(what: &str, out: &[f64], n: usize) -> Result<()> {
    if out.len() != n {
        return Err(Error::Shape { what: what.to_string(), expected: n, got: out.len() });
    }
    Ok(())
}

/// Cholesky factor L (lower triangle of `l`) of the symmetric `a`; Err(k) when pivot k is not
/// positive. `l` must have the shape of `a` (square).
#[inline(always)]
pub fn cholesky_in_place(a: &DMatrix<f64>, l: &mut DMatrix<f64>) -> std::result::Result<(), usize> {
    let n = a.nrows();
    if a.ncols() != n || l.shape() != (n, n) {
        return Err(0);
    }
    // column-major flat storage: element (i, j) at i + j n
    let a = a.as_slice();
    let l = l.as_mut_slice();
    for j in 0..n {
        let mut d = a[j + j * n];
        for k in 0..j {
            let x = l[j + k * n];
            d -= x * x;
        }
        if !(d > 0.0 && d.is_finite()) {
            return Err(j);
        }
        let d = d.sqrt();
        l[j + j * n] = d;
        let inv = 1.0 / d;
        for i in (j + 1)..n {
            let mut s = a[i + j * n];
            for k in 0..j {
                s -= l[i + k * n] * l[j + k * n];
            }
            l[i + j * n] = s * inv;
        }
    }
    Ok(())
}

/// Solve `L L^T x = b` in place (`l` from [`cholesky_in_place`], `b` of length n).
#[inline(always)]
pub fn cholesky_solve(l: &DMatrix<f64>, b: &mut [f64]) {
    let n = l.nrows().min(b.len());
    let l = l.as_slice();
    let stride = n.max(1);
    for i in 0..n {
        let mut s = b[i];
        for k in 0..i {
            s -= l[i + k * stride] * b[k];
        }
        b[i] = s / l[i + i * stride];
    }
    for i in (0..n).rev() {
        let mut s = b[i];
        for k in (i + 1)..n {
            s -= l[k + i * stride] * b[k];
        }
        b[i] = s / l[i + i * stride];
    }
}

/// Configuration-space arithmetic of the 1 kHz loop (`crate::control`): q holds one value per
/// revolute or prismatic joint and `[cos, sin]` per continuous joint, v one value per joint.
impl Dynamics {
    /// The neutral configuration: every joint at 0 (a continuous joint at `[1, 0]`).
    pub fn neutral(&self) -> Vec<f64> {
        let mut q = vec![0.0; self.nq];
        for b in &self.bodies {
            if b.kind == JointKind::Continuous {
                q[b.q_index] = 1.0;
            }
        }
        q
    }

    /// `out = q (+) factor v`: each joint moved by `factor v` (a continuous joint's `[cos, sin]`
    /// rotated by that angle). `out` of length nq; the inputs are not checked.
    #[inline(always)]
    pub fn integrate_scaled(&self, q: &[f64], v: &[f64], factor: f64, out: &mut [f64]) {
        for b in &self.bodies {
            let (i, k) = (b.q_index, b.v_index);
            match b.kind {
                JointKind::Revolute | JointKind::Prismatic => out[i] = q[i] + factor * v[k],
                JointKind::Continuous => {
                    let (s, c) = (factor * v[k]).sin_cos();
                    let (c0, s0) = (q[i], q[i + 1]);
                    out[i] = c0 * c - s0 * s;
                    out[i + 1] = s0 * c + c0 * s;
                }
            }
        }
    }

    /// `out = q1 (-) q0`: per joint the motion from `q0` to `q1` (a continuous joint's angle
    /// from one to the other, in (-pi, pi]). `out` of length nv; the inputs are not checked.
    #[inline(always)]
    pub fn difference(&self, q0: &[f64], q1: &[f64], out: &mut [f64]) {
        for b in &self.bodies {
            let (i, k) = (b.q_index, b.v_index);
            out[k] = match b.kind {
                JointKind::Revolute | JointKind::Prismatic => q1[i] - q0[i],
                JointKind::Continuous => {
                    let (c0, s0, c1, s1) = (q0[i], q0[i + 1], q1[i], q1[i + 1]);
                    (c0 * s1 - s0 * c1).atan2(c0 * c1 + s0 * s1)
                }
            };
        }
    }

    /// Every continuous joint's `[cos, sin]` scaled to unit length (against the drift of many
    /// integration steps); a zero pair becomes `[1, 0]`.
    #[inline(always)]
    pub fn normalize_circles(&self, q: &mut [f64]) {
        for b in &self.bodies {
            if b.kind == JointKind::Continuous {
                let i = b.q_index;
                let n = q[i].hypot(q[i + 1]);
                if n > 0.0 && n.is_finite() {
                    q[i] /= n;
                    q[i + 1] /= n;
                } else {
                    q[i] = 1.0;
                    q[i + 1] = 0.0;
                }
            }
        }
    }

    /// Whether the joint at v index `k` is continuous (no position limits).
    pub fn is_continuous(&self, k: usize) -> bool {
        self.bodies.iter().any(|b| b.v_index == k && b.kind == JointKind::Continuous)
    }
}

#[cfg(test)]
mod tests {
    use super::{axis_rotation, lanes, mat_vec2, principal_axis, ArticulatedInertia, Body, JointKind, SpatialInertia};
    use nalgebra::{Matrix3, Rotation3, Vector3};

    /// A body on `axis` under the placement rotation `r_parent`.
    fn body(axis: Vector3<f64>, r_parent: Matrix3<f64>) -> Body {
        Body {
            joint: "j".into(),
            link: "l".into(),
            parent: None,
            r_parent,
            p_parent: Vector3::zeros(),
            kind: JointKind::Revolute,
            axis,
            q_index: 0,
            v_index: 0,
            inertia: SpatialInertia::zero(),
            principal: principal_axis(&axis),
        }
    }

    #[test]
    fn principal_axes_turn_and_map_as_rodrigues_and_the_matrix_product() {
        let r_parent = Rotation3::from_euler_angles(0.3, -1.1, 2.4).into_inner();
        let rw = Rotation3::from_euler_angles(-0.7, 0.4, 1.9).into_inner();
        let mut principal = 0;
        for k in 0..3 {
            for sign in [1.0, -1.0] {
                let mut axis = Vector3::zeros();
                axis[k] = sign;
                let b = body(axis, r_parent);
                assert_eq!(b.principal, Some((k, sign)));
                principal += 1;
                for angle in [0.0, 0.4, -2.9, 3.1] {
                    let (s, c) = f64::sin_cos(angle);
                    let want = r_parent * axis_rotation(&axis, c, s);
                    assert!((b.rotation(c, s) - want).amax() < 1e-15, "axis {axis:?} angle {angle}");
                }
                assert!((b.world_axis(&rw) - rw * axis).amax() < 1e-15);
            }
        }
        assert_eq!(principal, 6);
        // any other axis takes the general path, with the same results
        for axis in [Vector3::new(0.6, 0.8, 0.0), Vector3::new(0.0, 1e-9, 1.0).normalize(), Vector3::new(1.0, 1.0, 1.0).normalize()] {
            let b = body(axis, r_parent);
            assert_eq!(b.principal, None, "{axis:?}");
            let (s, c) = f64::sin_cos(0.7);
            assert_eq!(b.rotation(c, s), r_parent * axis_rotation(&axis, c, s));
            assert_eq!(b.world_axis(&rw), rw * axis);
        }
    }

    #[test]
    fn transformed_inertia_is_the_congruence_and_exactly_symmetric() {
        let r = Rotation3::from_euler_angles(0.2, 0.9, -1.3).into_inner();
        let p = Vector3::new(0.3, -0.2, 0.5);
        let i_com = Matrix3::new(0.04, 0.001, -0.002, 0.001, 0.03, 0.003, -0.002, 0.003, 0.05);
        let si = SpatialInertia::from_com(2.5, Vector3::new(0.01, 0.02, -0.1), i_com);
        let t = si.transformed(&r, &p);
        // the definition: the inertia about the new origin of the body's rotated inertia about its centre
        let com = r * si.com() + p;
        let want = SpatialInertia::from_com(2.5, com, r * si.inertia_about_com() * r.transpose());
        assert!((t.i_o - want.i_o).amax() < 1e-14 && (t.h - want.h).amax() < 1e-15);
        assert_eq!(t.i_o, t.i_o.transpose());
    }

    #[test]
    fn rigid_articulated_inertia_maps_a_motion_to_the_rigid_momentum() {
        let i_com = Matrix3::new(0.02, -0.003, 0.001, -0.003, 0.05, 0.002, 0.001, 0.002, 0.03);
        let si = SpatialInertia::from_com(1.7, Vector3::new(0.03, -0.05, 0.12), i_com);
        let ia = ArticulatedInertia::rigid(&si);
        let (v, w) = (Vector3::new(0.3, -1.1, 0.4), Vector3::new(-0.6, 0.2, 0.9));
        let (f, n) = si.apply(&v, &w);
        let (vl, wl) = (lanes(&v), lanes(&w));
        let got_f = mat_vec2(&ia.a, &vl, &ia.b, &wl);
        let got_n = mat_vec2(&ia.bt, &vl, &ia.c, &wl);
        for k in 0..3 {
            assert!((got_f[k] - f[k]).abs() < 1e-15 && (got_n[k] - n[k]).abs() < 1e-15);
        }
        assert_eq!((got_f[3], got_n[3]), (0.0, 0.0));
        // b^T kept beside b is its transpose
        for r in 0..3 {
            for c in 0..3 {
                assert_eq!(ia.b[c][r], ia.bt[r][c]);
            }
        }
    }
}
