//! A convex hull whose support function climbs the hull's vertex graph ([`Hull`]) instead of
//! scanning every vertex as parry's `ConvexPolyhedron` does: GJK, which every narrow-phase query
//! on a hull runs, asks for a support point at each of its iterations, and meshed robot links
//! have hulls of 40 to 950 vertices (Talos), where the scan dominated the collision check.
//!
//! Hill climbing finds the global maximum of `dot(v, dir)` over a convex polytope's vertices:
//! at a vertex that is not a maximiser some edge from it increases the dot product (the simplex
//! method's argument), so a climb that stops has found a maximiser. It starts from a
//! precomputed maximiser for a nearby direction: the directions are cut into the cells of a
//! cube map (each face of the cube around the origin in `CELLS` x `CELLS` squares), and each
//! cell stores the maximiser for the direction through its centre, which leaves zero to two
//! steps for most directions. (Starting from the vertex extreme along the nearest coordinate
//! axis took several steps on the large Talos hulls, and support points were 40 % of a Talos
//! self-collision check: benches/collision.rs.) The posed box of a hull of more than a few
//! vertices comes from six climbs too (the extreme vertices along the world axes), not a scan of
//! every vertex. Every other query (point projection, ray casts, mass) is the inner
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
    /// Per cube-map cell (see the module text and [`cell`]): a vertex maximising the dot
    /// product with the direction through the cell's centre.
    starts: Vec<u32>,
}

/// Cube-map cells per face side: 6 x 8 x 8 = 384 start vertices per hull.
const CELLS: usize = 8;

/// Hulls of at most this many vertices get their posed box by a scan of every vertex; larger
/// ones by six climbs ([`Hull::compute_aabb`]).
const AABB_SCAN_MAX: usize = 24;

/// The relative growth of a posed box built from support points, which covers the rounding by
/// which a dot product may differ from the scan's transformed coordinate.
const AABB_ROUNDING: f64 = 1e-12;

/// The cube-map cell of a direction: the face of its largest component (+x, -x, +y, -y, +z,
/// -z), then the square of the other two components divided by that one's magnitude. Any
/// input gives a valid index (a zero or non-finite direction some cell).
#[inline]
fn cell(dir: &Vector<Real>) -> usize {
    let ax = dir.iamax();
    let m = dir[ax].abs();
    let face = 2 * ax + usize::from(dir[ax] < 0.0);
    let scale = 0.5 * CELLS as f64 / m;
    // (u / m + 1) / 2 * CELLS, clamped; NaN (m = 0) casts to 0
    let iu = ((dir[(ax + 1) % 3] * scale + 0.5 * CELLS as f64) as usize).min(CELLS - 1);
    let iv = ((dir[(ax + 2) % 3] * scale + 0.5 * CELLS as f64) as usize).min(CELLS - 1);
    (face * CELLS + iu) * CELLS + iv
}

/// The direction through the centre of cube-map cell `c` (the inverse of [`cell`] there).
fn cell_center(c: usize) -> Vector<Real> {
    let (face, iu, iv) = (c / (CELLS * CELLS), (c / CELLS) % CELLS, c % CELLS);
    let (ax, sign) = (face / 2, if face % 2 == 1 { -1.0 } else { 1.0 });
    let coord = |i: usize| (i as f64 + 0.5) / CELLS as f64 * 2.0 - 1.0;
    let mut d = Vector::zeros();
    d[ax] = sign;
    d[(ax + 1) % 3] = coord(iu);
    d[(ax + 2) % 3] = coord(iv);
    d
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
        let mut hull = Hull { inner, start, adj, starts: vec![0; 6 * CELLS * CELLS] };
        // each cell's maximiser by a climb from the previous cell's (neighbouring cells have
        // nearby answers), the first from vertex 0: the climb is exact from any start
        let mut from = 0;
        for c in 0..hull.starts.len() {
            from = hull.climb(from, &cell_center(c));
            hull.starts[c] = from as u32;
        }
        hull
    }

    /// The parry hull inside.
    pub fn polyhedron(&self) -> &ConvexPolyhedron {
        &self.inner
    }

    /// The index of a vertex maximising `dot(v, dir)`.
    #[inline]
    fn support_index(&self, dir: &Vector<Real>) -> usize {
        self.climb(self.starts[cell(dir)] as usize, dir)
    }

    /// Climb from vertex `best` to a vertex maximising `dot(v, dir)`.
    #[inline]
    fn climb(&self, mut best: usize, dir: &Vector<Real>) -> usize {
        let pts = self.inner.points();
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

    /// The box of the hull at `position`: per world axis, the vertices extreme along it (the
    /// axis in the hull's frame, by the climb), grown by `AABB_ROUNDING`: it contains the box
    /// of every vertex transformed, and differs from it by rounding alone. parry asks for it
    /// per part and query when a decomposed mesh (a compound of hulls) meets another shape,
    /// where a scan of every vertex dominated the check.
    fn compute_aabb(&self, position: &Isometry<Real>) -> Aabb {
        let pts = self.inner.points();
        if pts.len() <= AABB_SCAN_MAX {
            return self.inner.compute_aabb(position);
        }
        let rot = position.rotation.to_rotation_matrix();
        let (mut mins, mut maxs) = (Point::origin(), Point::origin());
        for k in 0..3 {
            // world coordinate k of R v + t is row k of R times v, plus t_k
            let axis: Vector<Real> = rot.matrix().row(k).transpose();
            let hi = pts[self.support_index(&axis)].coords.dot(&axis);
            let lo = pts[self.support_index(&-axis)].coords.dot(&axis);
            let t = position.translation.vector[k];
            let pad = AABB_ROUNDING * (1.0 + hi.abs().max(lo.abs()) + t.abs());
            mins[k] = lo + t - pad;
            maxs[k] = hi + t + pad;
        }
        Aabb::new(mins, maxs)
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

    /// Every direction has a cell (zero and non-finite ones too), and a cell's centre is in it.
    #[test]
    fn cube_map_cells() {
        for c in 0..6 * CELLS * CELLS {
            assert_eq!(cell(&cell_center(c)), c);
        }
        let mut rng = StdRng::seed_from_u64(3);
        let mut seen = vec![false; 6 * CELLS * CELLS];
        for _ in 0..100_000 {
            let d = Vector3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0));
            seen[cell(&d)] = true;
        }
        assert!(seen.iter().all(|&s| s), "every cell is reached");
        for d in [Vector3::zeros(), Vector3::new(f64::NAN, 0.0, 1.0), Vector3::new(f64::INFINITY, 1.0, -f64::INFINITY), Vector3::new(1e-300, -1e-300, 0.0)] {
            assert!(cell(&d) < 6 * CELLS * CELLS, "{d:?}");
        }
    }

    /// The posed box from six climbs contains the box of every vertex transformed and is within
    /// rounding of it, for small hulls (the scan itself) and large ones.
    #[test]
    fn posed_boxes_match_the_scan_of_every_vertex() {
        let mut rng = StdRng::seed_from_u64(9);
        let mut large = 0;
        for trial in 0..30 {
            let hull = Hull::from_points(&random_cloud(&mut rng, [8, 60, 400][trial % 3])).unwrap();
            large += usize::from(hull.polyhedron().points().len() > AABB_SCAN_MAX);
            for _ in 0..100 {
                let p = Isometry3::new(
                    Vector3::new(rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0), rng.random_range(-5.0..5.0)),
                    Vector3::new(rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0), rng.random_range(-3.0..3.0)),
                );
                let (mine, scan) = (hull.compute_aabb(&p), hull.polyhedron().compute_aabb(&p));
                for k in 0..3 {
                    assert!(mine.mins[k] <= scan.mins[k] && mine.maxs[k] >= scan.maxs[k], "{mine:?} inside {scan:?}");
                    assert!(scan.mins[k] - mine.mins[k] < 1e-9 && mine.maxs[k] - scan.maxs[k] < 1e-9, "{mine:?} vs {scan:?}");
                }
            }
        }
        assert!(large > 10, "{large} hulls above the scan's size");
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
