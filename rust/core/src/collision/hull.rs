//! A convex hull whose support function climbs the hull's vertex graph ([`Hull`]) instead of
//! scanning every vertex as parry's `ConvexPolyhedron` does: GJK, which every narrow-phase query
//! on a hull runs, asks for a support point at each of its iterations, and meshed robot links
//! have hulls of 40 to 950 vertices (Talos), where the scan dominated the collision check.
//!
//! Hill climbing finds the global maximum of `dot(v, dir)` over a convex polytope's vertices:
//! at a vertex that is not a maximiser some edge from it increases the dot product (the simplex
//! method's argument), so a climb that stops has found a maximiser. It starts from the vertex
//! extreme along the coordinate axis closest to `dir` (precomputed), which leaves a few steps
//! for most directions. Every other query (point projection, ray casts, mass) is the inner
//! `ConvexPolyhedron`'s, and the support points are the same vertices (up to ties), so every
//! answer matches parry's hull (tested against it in the module's tests).

use parry3d_f64::bounding_volume::{Aabb, BoundingSphere};
use parry3d_f64::mass_properties::MassProperties;
use parry3d_f64::math::{Isometry, Point, Real, Vector};
use parry3d_f64::query::{PointProjection, PointQuery, Ray, RayCast, RayIntersection};
use parry3d_f64::shape::{ConvexPolyhedron, FeatureId, Shape, ShapeType, SupportMap, TypedShape};

/// A convex hull with a hill-climbing support function (see the module text).
#[derive(Debug, Clone)]
pub struct Hull {
    inner: ConvexPolyhedron,
    /// Neighbours of each vertex along the hull's edges (CSR: `adj[start[i]..start[i + 1]]`).
    start: Vec<u32>,
    adj: Vec<u32>,
    /// The vertex extreme along +x, -x, +y, -y, +z, -z.
    axis_extreme: [u32; 6],
}

impl Hull {
    /// The convex hull of `points` (None when parry cannot build it: fewer than 4 points in
    /// general position).
    pub fn from_points(points: &[Point<Real>]) -> Option<Hull> {
        ConvexPolyhedron::from_convex_hull(points).map(Hull::new)
    }

    /// The hull of parry's `ConvexPolyhedron`, with its vertex graph.
    pub fn new(inner: ConvexPolyhedron) -> Hull {
        let n = inner.points().len();
        let mut neighbours: Vec<Vec<u32>> = vec![Vec::new(); n];
        for e in inner.edges() {
            let (a, b) = (e.vertices[0], e.vertices[1]);
            if a != b && (a as usize) < n && (b as usize) < n {
                neighbours[a as usize].push(b);
                neighbours[b as usize].push(a);
            }
        }
        let mut start = Vec::with_capacity(n + 1);
        let mut adj = Vec::new();
        for mut list in neighbours {
            start.push(adj.len() as u32);
            list.sort_unstable();
            list.dedup();
            adj.extend(list);
        }
        start.push(adj.len() as u32);
        let pts = inner.points();
        let extreme = |axis: usize, sign: f64| {
            (0..n).max_by(|&i, &j| (sign * pts[i][axis]).total_cmp(&(sign * pts[j][axis]))).unwrap_or(0) as u32
        };
        let axis_extreme = [extreme(0, 1.0), extreme(0, -1.0), extreme(1, 1.0), extreme(1, -1.0), extreme(2, 1.0), extreme(2, -1.0)];
        Hull { inner, start, adj, axis_extreme }
    }

    /// The parry hull inside.
    pub fn polyhedron(&self) -> &ConvexPolyhedron {
        &self.inner
    }

    /// The index of a vertex maximising `dot(v, dir)`.
    #[inline]
    fn support_index(&self, dir: &Vector<Real>) -> usize {
        let pts = self.inner.points();
        // the start: the extreme vertex along the axis of dir's largest component
        let ax = dir.iamax();
        let mut best = self.axis_extreme[2 * ax + usize::from(dir[ax] < 0.0)] as usize;
        let mut best_dot = pts[best].coords.dot(dir);
        loop {
            let mut moved = false;
            let (s, e) = (self.start[best] as usize, self.start[best + 1] as usize);
            for &j in &self.adj[s..e] {
                let d = pts[j as usize].coords.dot(dir);
                if d > best_dot {
                    best_dot = d;
                    best = j as usize;
                    moved = true;
                }
            }
            if !moved {
                return best;
            }
        }
    }
}

impl SupportMap for Hull {
    #[inline]
    fn local_support_point(&self, dir: &Vector<Real>) -> Point<Real> {
        self.inner.points()[self.support_index(dir)]
    }
}

impl PointQuery for Hull {
    fn project_local_point(&self, pt: &Point<Real>, solid: bool) -> PointProjection {
        self.inner.project_local_point(pt, solid)
    }

    fn project_local_point_and_get_feature(&self, pt: &Point<Real>) -> (PointProjection, FeatureId) {
        self.inner.project_local_point_and_get_feature(pt)
    }
}

impl RayCast for Hull {
    fn cast_local_ray_and_get_normal(&self, ray: &Ray, max_time_of_impact: Real, solid: bool) -> Option<RayIntersection> {
        self.inner.cast_local_ray_and_get_normal(ray, max_time_of_impact, solid)
    }
}

impl Shape for Hull {
    fn compute_local_aabb(&self) -> Aabb {
        self.inner.compute_local_aabb()
    }

    fn compute_local_bounding_sphere(&self) -> BoundingSphere {
        self.inner.compute_local_bounding_sphere()
    }

    fn compute_aabb(&self, position: &Isometry<Real>) -> Aabb {
        self.inner.compute_aabb(position)
    }

    fn clone_dyn(&self) -> Box<dyn Shape> {
        Box::new(self.clone())
    }

    fn scale_dyn(&self, scale: &Vector<Real>, _num_subdivisions: u32) -> Option<Box<dyn Shape>> {
        Some(Box::new(Hull::new(self.inner.clone().scaled(scale)?)))
    }

    fn mass_properties(&self, density: Real) -> MassProperties {
        self.inner.mass_properties(density)
    }

    fn is_convex(&self) -> bool {
        true
    }

    fn shape_type(&self) -> ShapeType {
        ShapeType::Custom
    }

    fn as_typed_shape(&self) -> TypedShape<'_> {
        TypedShape::Custom(self)
    }

    fn ccd_thickness(&self) -> Real {
        self.inner.ccd_thickness()
    }

    fn ccd_angular_thickness(&self) -> Real {
        self.inner.ccd_angular_thickness()
    }

    fn as_support_map(&self) -> Option<&dyn SupportMap> {
        Some(self as &dyn SupportMap)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::{Isometry3, Vector3};
    use parry3d_f64::query;
    use parry3d_f64::shape::SharedShape;
    use rand::rngs::StdRng;
    use rand::{Rng, SeedableRng};

    fn random_cloud(rng: &mut StdRng, n: usize) -> Vec<Point<Real>> {
        (0..n)
            .map(|_| {
                let v = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                // an ellipsoid-ish cloud with flat patches: many hull vertices and coplanar faces
                let v = v.component_mul(&Vector3::new(0.3, 0.1, 0.5));
                Point::from(v.map(|x: f64| (x * 40.0).round() / 40.0))
            })
            .collect()
    }

    /// The climb finds the scan's maximum for every direction (the same dot product; ties may
    /// pick another vertex), and every query through GJK gives parry's hull's answer.
    #[test]
    fn the_climb_is_the_scan_and_queries_agree_with_parrys_hull() {
        let mut rng = StdRng::seed_from_u64(5);
        let mut agree = 0;
        for trial in 0..30 {
            let pts = random_cloud(&mut rng, [8, 60, 400][trial % 3]);
            let hull = Hull::from_points(&pts).unwrap();
            let poly = hull.polyhedron().clone();
            for _ in 0..200 {
                let d = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
                let (a, b) = (hull.local_support_point(&d), poly.local_support_point(&d));
                assert!((a.coords.dot(&d) - b.coords.dot(&d)).abs() <= 1e-12, "climb {a} vs scan {b} along {d}");
            }
            let (mine, theirs) = (SharedShape::new(hull.clone()), SharedShape::new(poly.clone()));
            let other = SharedShape::new(Hull::from_points(&random_cloud(&mut rng, 100)).unwrap());
            let other_poly = SharedShape::new(other.as_shape::<Hull>().unwrap().polyhedron().clone());
            for _ in 0..100 {
                let p = Isometry3::new(
                    Vector3::new(rng.random_range(-0.6..0.6), rng.random_range(-0.6..0.6), rng.random_range(-0.6..0.6)),
                    Vector3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)),
                );
                let id = Isometry3::identity();
                let hit = query::intersection_test(&id, &*mine, &p, &*other).unwrap();
                assert_eq!(hit, query::intersection_test(&id, &*theirs, &p, &*other_poly).unwrap());
                let d = query::distance(&id, &*mine, &p, &*other).unwrap();
                let e = query::distance(&id, &*theirs, &p, &*other_poly).unwrap();
                assert!((d - e).abs() < 1e-9, "distance {d} vs {e}");
                agree += usize::from(hit);
            }
        }
        assert!(agree > 100, "{agree} intersecting poses: the test must meet some");
    }
}
