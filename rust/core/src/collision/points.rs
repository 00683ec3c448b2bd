//! Signed distances from points to a world's obstacles, with their gradients: the fast path of a
//! clearance cost on spheres that cover a robot (a sphere of radius `r` at `c` clears the scene by
//! `d(c) - r`), which a differentiable objective back-propagates through the robot's kinematics.
//!
//! For a point `p` outside every obstacle, `d(p)` is the distance to the nearest obstacle and its
//! gradient the unit vector from that obstacle's nearest point to `p`; inside an obstacle, `d(p)`
//! is minus the depth (the distance to its surface) and the gradient points out through the
//! nearest surface point. Obstacles whose world box lies `cutoff` or more from `p` are skipped
//! (the bounding-volume hierarchy prunes them): a point with none nearer gets `d = cutoff` and a
//! zero gradient. Mesh obstacles are the shapes the world's other queries see (a hull, a closed
//! mesh's solid or an open mesh's surface, a decomposed mesh the union of its parts: the least
//! signed distance to one of them); a point cloud is the union of its balls (likewise).

use nalgebra::{Point3, Vector3};
use parry3d_f64::bounding_volume::Aabb;

use super::world::CollisionWorld;
use super::CloudGrid;
use crate::error::{Error, Result};

impl CollisionWorld {
    /// The signed distance of each point of `points` (rows of x, y, z) to the nearest obstacle and
    /// its gradient with respect to the point (see the module's text), written into `distances`
    /// (one per point) and `gradients` (three per point). `cutoff` > 0 bounds the search.
    pub fn point_distances(&self, points: &[f64], cutoff: f64, distances: &mut [f64], gradients: &mut [f64]) -> Result<()> {
        if points.len() % 3 != 0 {
            return Err(Error::Invalid(format!("points: expected rows of 3 coordinates, got {} values", points.len())));
        }
        let n = points.len() / 3;
        if distances.len() != n || gradients.len() != 3 * n {
            return Err(Error::Invalid(format!(
                "point_distances: {n} points need {n} distances and {} gradient values (got {} and {})",
                3 * n,
                distances.len(),
                gradients.len()
            )));
        }
        if !(cutoff.is_finite() && cutoff > 0.0) {
            return Err(Error::Invalid(format!("cutoff must be a positive finite distance, got {cutoff}")));
        }
        if let Some(i) = points.iter().position(|x| !x.is_finite()) {
            return Err(Error::NonFinite { what: format!("points row {} (column {})", i / 3, i % 3), index: i, value: points[i] });
        }
        let mut near = Vec::new();
        for k in 0..n {
            let p = Point3::new(points[3 * k], points[3 * k + 1], points[3 * k + 2]);
            let (d, g) = self.point_distance(&p, cutoff, &mut near);
            distances[k] = d;
            gradients[3 * k..3 * k + 3].copy_from_slice(g.as_slice());
        }
        Ok(())
    }

    /// [`point_distances`](Self::point_distances) for one point (`near`: scratch).
    fn point_distance(&self, p: &Point3<f64>, cutoff: f64, near: &mut Vec<usize>) -> (f64, Vector3<f64>) {
        let reach = Vector3::repeat(cutoff);
        let probe = Aabb::new(p - reach, p + reach);
        self.obstacles.overlapping(&probe, near);
        let mut best = (cutoff, Vector3::zeros());
        for &k in near.iter() {
            let o = &self.obstacles[k];
            let (d, g) = match (o.plane, o.cloud) {
                (Some((normal, offset)), _) => (normal.dot(&p.coords) - offset, normal),
                (None, Some(_)) => match o.shape.as_shape::<CloudGrid>().and_then(|c| c.nearest(p, best.0)) {
                    Some(dg) => dg,
                    None => continue,
                },
                (None, None) => {
                    // the nearest surface point, inside or out (a decomposed mesh through its
                    // parts, a closed mesh kept as a mesh through its pseudo-normals)
                    let (d, q) = super::geometry::signed_point_distance(&*o.shape, &o.pose, p);
                    let v = p - q;
                    let len = v.norm();
                    if len > 0.0 {
                        (d, v * (d.signum() / len))
                    } else {
                        // on the surface: the gradient is the direction away from the shape's centre
                        let out = p - o.center;
                        let l = out.norm();
                        (0.0, if l > 0.0 { out / l } else { Vector3::z() })
                    }
                }
            };
            if d < best.0 {
                best = (d, g);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use crate::robot::preset;
    use nalgebra::{Isometry3, Vector3};

    #[test]
    fn distances_and_gradients_of_each_shape() {
        let (_, mut w) = preset("panda").unwrap().load().unwrap();
        w.add_box("box", [0.1, 0.2, 0.3], Isometry3::translation(1.0, 0.0, 0.0)).unwrap();
        w.add_sphere("ball", 0.1, [0.0, 1.0, 0.0]).unwrap();
        w.add_halfspace("floor", [0.0, 0.0, 1.0], -1.0).unwrap();
        let pts = [1.3, 0.0, 0.0, /* outside the box, 0.2 from its face */ 1.0, 0.0, 0.25, /* inside, 0.05 deep */
                   0.0, 1.3, 0.0, /* 0.2 from the ball */ 0.0, 0.0, -0.7, /* 0.3 above the floor */
                   -5.0, -5.0, 5.0 /* far from all but the floor (beyond the cutoff) */];
        let (mut d, mut g) = (vec![0.0; 5], vec![0.0; 15]);
        w.point_distances(&pts, 1.0, &mut d, &mut g).unwrap();
        let expect = [0.2, -0.05, 0.2, 0.3, 1.0];
        for (a, b) in d.iter().zip(expect) {
            assert!((a - b).abs() < 1e-9, "{d:?}");
        }
        assert!((Vector3::new(g[0], g[1], g[2]) - Vector3::x()).norm() < 1e-9);
        assert!((Vector3::new(g[3], g[4], g[5]) - Vector3::z()).norm() < 1e-9, "inside: out through the nearest face");
        assert!((Vector3::new(g[6], g[7], g[8]) - Vector3::y()).norm() < 1e-9);
        assert!((Vector3::new(g[9], g[10], g[11]) - Vector3::z()).norm() < 1e-9);
        assert_eq!(&g[12..15], &[0.0, 0.0, 0.0]);
    }

    #[test]
    fn gradients_match_finite_differences_and_bad_input_is_refused() {
        let (_, mut w) = preset("panda").unwrap().load().unwrap();
        w.add_cylinder("post", 0.05, 0.3, Isometry3::new(Vector3::new(0.5, 0.5, 0.0), Vector3::new(0.3, 0.0, 0.0))).unwrap();
        w.add_capsule("rod", 0.04, 0.2, Isometry3::new(Vector3::new(-0.5, 0.2, 0.1), Vector3::new(0.0, 0.7, 0.0))).unwrap();
        let h = 1e-6;
        // outside and inside each shape, off their axes (where the nearest surface point jumps)
        for p in [[0.62, 0.51, 0.05], [0.53, 0.5, 0.0], [-0.4, 0.3, 0.0], [-0.5, 0.22, 0.1]] {
            let (mut d, mut g) = ([0.0], [0.0; 3]);
            w.point_distances(&p, 2.0, &mut d, &mut g).unwrap();
            for i in 0..3 {
                let (mut q, mut dq, mut gq) = (p, [0.0], [0.0; 3]);
                q[i] += h;
                w.point_distances(&q, 2.0, &mut dq, &mut gq).unwrap();
                assert!(((dq[0] - d[0]) / h - g[i]).abs() < 1e-4, "point {p:?} axis {i}");
            }
        }
        let (mut d, mut g) = ([0.0], [0.0; 3]);
        assert!(w.point_distances(&[0.0, f64::NAN, 0.0], 1.0, &mut d, &mut g).is_err());
        assert!(w.point_distances(&[0.0, 0.0], 1.0, &mut d, &mut g).is_err());
        assert!(w.point_distances(&[0.0, 0.0, 0.0], 0.0, &mut d, &mut g).is_err());
    }
}
