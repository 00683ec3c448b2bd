//! Robot collision geometry from the URDF's `<collision>` elements: primitives become parry
//! shapes, meshes (STL, OBJ, Collada) a shape chosen by [`MeshShape`] (by default the convex hull
//! of their vertices, [`load_mesh_vertices`]); each piece is a [`RobotGeometry`] with the bounding
//! volumes the broad phase uses.
//!
//! A mesh kept as a mesh ([`MeshShape::Mesh`]) is a parry `TriMesh`. parry's queries on it see
//! its surface only; when the mesh is closed ([`crate::mesh::Mesh::is_closed`]) it is built
//! oriented (pseudo-normals, outward), and [`intersects`], [`inside_solid`] and
//! [`signed_point_distance`] add what makes it a solid: a shape wholly inside it (no surface
//! crossed) collides, and a point inside it has a negative distance.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use nalgebra::{Isometry3, Point3, Translation3, UnitQuaternion, Vector3};
use parry3d_f64::bounding_volume::Aabb;
use parry3d_f64::query;
use parry3d_f64::shape::{Ball, Capsule, Compound, Cuboid, Cylinder, SharedShape, Shape, TriMesh, TriMeshFlags};
use parry3d_f64::transformation::vhacd::{VHACDParameters, VHACD};

use super::Hull;
use crate::error::{unknown, Error, Result};
use crate::mesh::Mesh;
use crate::kinematics::KinematicModel;
use crate::urdf::{Geometry, Urdf};

/// One piece of robot collision geometry, rigidly attached to a link.
#[derive(Clone)]
pub struct RobotGeometry {
    /// `<link>_<i>`, the i-th `<collision>` of the link (Pinocchio's naming).
    pub name: String,
    /// Index of the link it is attached to.
    pub link: usize,
    /// Pose of the shape in the link frame (includes the cylinder axis change y -> z).
    pub offset: Isometry3<f64>,
    /// The parry shape, in its own frame.
    pub shape: SharedShape,
    /// Bounding sphere in the shape frame: centre and radius.
    pub(super) center: Point3<f64>,
    pub(super) radius: f64,
    /// Bounding box in the shape frame (moved to the world per query: a cheap, tight broadphase).
    pub(super) local_aabb: Aabb,
}

/// The bounding sphere of a shape in its own frame: centre and radius.
pub(super) fn bounding_sphere(shape: &SharedShape) -> (Point3<f64>, f64) {
    let s = shape.compute_local_bounding_sphere();
    (s.center, s.radius)
}

/// The vertices of a mesh file (STL, OBJ or Collada, read by [`crate::mesh::read_mesh`]), scaled;
/// at least 4 finite ones (a convex hull needs them).
pub fn load_mesh_vertices(path: &Path, scale: &Vector3<f64>) -> Result<Vec<Point3<f64>>> {
    let mesh = crate::mesh::read_mesh(path)?;
    let points: Vec<Point3<f64>> =
        mesh.vertices.iter().map(|v| Point3::new(v.x * scale.x, v.y * scale.y, v.z * scale.z)).collect();
    if points.len() < 4 || points.iter().any(|p| !p.coords.iter().all(|c| c.is_finite())) {
        return Err(Error::Mesh {
            path: path.to_path_buf(),
            msg: format!("{} vertices, need at least 4 finite ones", points.len()),
        });
    }
    Ok(points)
}

/// How a mesh becomes a collision shape: a scene's `[[mesh]]` `shape` key, a robot file's
/// `mesh_shape` key (docs/SCENES.md, docs/ROBOTS.md).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum MeshShape {
    /// The convex hull of its vertices ([`Hull`]): one convex piece, the fastest to query, exact
    /// only for a convex mesh (a concave one is filled in, so the answers err on the safe side).
    #[default]
    Hull,
    /// The triangles themselves (parry's `TriMesh`, a bounding-volume hierarchy over them): a
    /// closed mesh is a solid, an open one a surface of zero thickness (see the module text).
    Mesh,
    /// Convex parts by V-HACD ([`decompose`]), each a [`Hull`], in a parry `Compound`.
    Decomposed,
}

impl MeshShape {
    /// The names [`MeshShape::from_name`] takes, in the order of the variants.
    pub const NAMES: &'static [&'static str] = &["hull", "mesh", "decomposed"];

    /// The variant of a name of [`NAMES`](Self::NAMES); an unknown name is an
    /// [`Error::UnknownName`] of kind "mesh shape" listing the known ones.
    pub fn from_name(name: &str) -> Result<MeshShape> {
        match name {
            "hull" => Ok(MeshShape::Hull),
            "mesh" => Ok(MeshShape::Mesh),
            "decomposed" => Ok(MeshShape::Decomposed),
            _ => Err(unknown("mesh shape", name, Self::NAMES)),
        }
    }

    /// The variant's name (an entry of [`NAMES`](Self::NAMES)).
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }
}

/// The V-HACD parameters of [`decompose`]: parry's defaults (voxel resolution 64, concavity
/// 0.01) with at most 32 parts per mesh, chosen by benches/nonconvex_meshes.py.
pub const DECOMPOSITION: VHACDParameters = VHACDParameters {
    concavity: 0.01,
    alpha: 0.05,
    beta: 0.05,
    resolution: 64,
    plane_downsampling: 4,
    convex_hull_downsampling: 4,
    fill_mode: parry3d_f64::transformation::voxelization::FillMode::FloodFill { detect_cavities: false },
    convex_hull_approximation: true,
    max_convex_hulls: 32,
};

/// The convex parts of `mesh` by V-HACD with `params` (the hull of the mesh's own triangles
/// within each voxel part, so each part lies within the mesh's convex hull), each part's
/// vertices. A mesh V-HACD cannot split (it panics inside parry, or gives no part with volume)
/// gives [`Error::Mesh`] naming `path`.
pub fn decompose(mesh: &Mesh, params: &VHACDParameters, path: &Path) -> Result<Vec<Vec<Point3<f64>>>> {
    let bad = |msg: String| Error::Mesh { path: path.to_path_buf(), msg };
    let (vertices, triangles) = (&mesh.vertices, &mesh.triangles);
    let parts = std::panic::catch_unwind(|| {
        let d = VHACD::decompose(params, vertices, triangles, true);
        d.compute_exact_convex_hulls(vertices, triangles).into_iter().map(|(v, _)| v).collect::<Vec<_>>()
    })
    .map_err(|_| bad("convex decomposition failed (V-HACD could not split the mesh)".into()))?;
    // a part without volume (flat: from a flat mesh or a sliver) is left out
    let solid = |p: &Vec<Point3<f64>>| {
        Hull::from_points(p).is_some_and(|h| {
            let extent = h.compute_local_aabb().extents().max();
            h.polyhedron().mass_properties(1.0).mass() > 1e-9 * extent * extent * extent
        })
    };
    let parts: Vec<Vec<Point3<f64>>> = parts.into_iter().filter(solid).collect();
    if parts.is_empty() {
        return Err(bad("convex decomposition gave no part with volume (a flat or degenerate mesh?)".into()));
    }
    Ok(parts)
}

/// Where [`mesh_shape`] keeps decompositions (None: nowhere, every one computed anew).
static DECOMPOSITION_CACHE: std::sync::RwLock<Option<PathBuf>> = std::sync::RwLock::new(None);

/// Keep V-HACD's decompositions in folder `dir` (created when first written), one file per
/// mesh and parameters, named by a hash of the mesh's vertices and triangles and of the
/// parameters; None: keep none. genplan's Python package sets it to its cache folder
/// (`genplan.cache.cache_dir()`, "decompositions").
pub fn set_decomposition_cache(dir: Option<PathBuf>) {
    *DECOMPOSITION_CACHE.write().unwrap_or_else(|e| e.into_inner()) = dir;
}

/// FNV-1a (64 bits) of bytes: a hash that is the same in every run and build.
fn fnv1a(bytes: impl IntoIterator<Item = u8>, mut h: u64) -> u64 {
    for b in bytes {
        h = (h ^ u64::from(b)).wrapping_mul(0x100_0000_01b3);
    }
    h
}

const CACHE_MAGIC: &[u8] = b"genplan convex parts 1\n";

/// [`decompose`], through the folder of [`set_decomposition_cache`]: a file that is there and
/// well formed (the header, the part and vertex counts, finite coordinates, nothing after) is
/// read instead; one that is not is computed and written (to a temporary name, then renamed,
/// so a reader never sees half a file). A cache that cannot be read or written is skipped.
fn cached_decompose(mesh: &Mesh, params: &VHACDParameters, path: &Path) -> Result<Vec<Vec<Point3<f64>>>> {
    let dir = DECOMPOSITION_CACHE.read().unwrap_or_else(|e| e.into_inner()).clone();
    let Some(dir) = dir else { return decompose(mesh, params, path) };
    let mut h = fnv1a(format!("{params:?}").into_bytes(), 0xcbf2_9ce4_8422_2325);
    h = fnv1a(mesh.vertices.iter().flat_map(|p| p.coords.iter().flat_map(|x| x.to_bits().to_le_bytes()).collect::<Vec<_>>()), h);
    h = fnv1a(mesh.triangles.iter().flat_map(|t| t.iter().flat_map(|i| i.to_le_bytes()).collect::<Vec<_>>()), h);
    let file = dir.join(format!("{h:016x}.parts"));
    if let Some(parts) = std::fs::read(&file).ok().and_then(|b| parse_parts(&b)) {
        return Ok(parts);
    }
    let parts = decompose(mesh, params, path)?;
    let mut bytes = CACHE_MAGIC.to_vec();
    bytes.extend((parts.len() as u64).to_le_bytes());
    for p in &parts {
        bytes.extend((p.len() as u64).to_le_bytes());
        bytes.extend(p.iter().flat_map(|v| v.coords.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<_>>()));
    }
    let tmp = dir.join(format!(".{h:016x}.parts.{}", std::process::id()));
    let written = std::fs::create_dir_all(&dir).and_then(|_| std::fs::write(&tmp, &bytes)).and_then(|_| std::fs::rename(&tmp, &file));
    if written.is_err() {
        std::fs::remove_file(&tmp).ok();
    }
    Ok(parts)
}

/// The parts of a cache file's bytes (see [`cached_decompose`]); None unless well formed.
fn parse_parts(bytes: &[u8]) -> Option<Vec<Vec<Point3<f64>>>> {
    let mut rest = bytes.strip_prefix(CACHE_MAGIC)?;
    let mut take = |n: usize| -> Option<&[u8]> {
        let (a, b) = rest.split_at_checked(n)?;
        rest = b;
        Some(a)
    };
    let count = |b: &[u8]| usize::try_from(u64::from_le_bytes(b.try_into().ok()?)).ok();
    let n = count(take(8)?)?;
    let mut parts = Vec::with_capacity(n.min(1024));
    for _ in 0..n {
        let m = count(take(8)?)?;
        let raw = take(m.checked_mul(24)?)?;
        let xs: Vec<f64> = raw.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8]))).collect();
        if !xs.iter().all(|x| x.is_finite()) {
            return None;
        }
        parts.push(xs.chunks_exact(3).map(|c| Point3::new(c[0], c[1], c[2])).collect());
    }
    (take(1).is_none() && !parts.is_empty()).then_some(parts)
}

/// The collision shape of a mesh (already scaled) as `kind` says; `path` names the file in
/// errors. A hull needs 4 vertices in general position; a mesh kept as a mesh is oriented
/// outward when closed (its triangles reversed if they face inward), a surface otherwise.
pub fn mesh_shape(mesh: &Mesh, kind: MeshShape, path: &Path) -> Result<SharedShape> {
    let bad = |msg: &str| Error::Mesh { path: path.to_path_buf(), msg: msg.to_string() };
    match kind {
        MeshShape::Hull if mesh.vertices.len() < 4 => Err(bad(&format!("{} vertices, need at least 4 for a convex hull", mesh.vertices.len()))),
        MeshShape::Hull => Hull::from_points(&mesh.vertices)
            .map(SharedShape::new)
            .ok_or_else(|| bad("convex hull failed (flat or degenerate mesh?)")),
        MeshShape::Mesh => {
            let closed = mesh.is_closed();
            let triangles = if closed && mesh.signed_volume() < 0.0 {
                mesh.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect()
            } else {
                mesh.triangles.clone()
            };
            let mut flags = TriMeshFlags::MERGE_DUPLICATE_VERTICES | TriMeshFlags::DELETE_DEGENERATE_TRIANGLES;
            if closed {
                flags |= TriMeshFlags::ORIENTED;
            }
            TriMesh::with_flags(mesh.vertices.clone(), triangles, flags)
                .map(SharedShape::new)
                .map_err(|e| bad(&format!("cannot build a triangle mesh: {e}")))
        }
        MeshShape::Decomposed => {
            let parts = cached_decompose(mesh, &DECOMPOSITION, path)?;
            let shapes = parts
                .iter()
                .filter_map(|p| Hull::from_points(p))
                .map(|h| (Isometry3::identity(), SharedShape::new(h)))
                .collect();
            Ok(SharedShape(std::sync::Arc::new(Compound::new(shapes))))
        }
    }
}

/// The solid of a closed mesh kept as a mesh (a `TriMesh` built oriented), if `shape` is one.
#[inline]
pub(super) fn solid_mesh(shape: &dyn Shape) -> Option<&TriMesh> {
    shape.as_shape::<TriMesh>().filter(|m| m.pseudo_normals_if_oriented().is_some())
}

/// A point of each connected convex piece of `shape` in its own frame (a support point of a
/// convex shape, one per part of a compound, a vertex of a mesh).
fn points_of(shape: &dyn Shape, out: &mut Vec<Point3<f64>>) {
    if let Some(m) = shape.as_shape::<TriMesh>() {
        out.extend(m.vertices().first().copied());
    } else if let Some(c) = shape.as_shape::<Compound>() {
        for (pose, part) in c.shapes() {
            let start = out.len();
            points_of(&**part, out);
            for p in &mut out[start..] {
                *p = pose * *p;
            }
        }
    } else if let Some(s) = shape.as_support_map() {
        out.push(s.local_support_point(&Vector3::x()));
    }
}

/// With the surfaces of `a` and `b` found apart: is either wholly inside the other, which then is
/// a solid? `a` (or a part of it) inside the solid of a closed mesh `b`, or the other way round,
/// or a mesh `b` (closed or not) inside a solid `a`. Shapes whose surfaces do not meet are either
/// nested or apart, so one point of each piece decides.
pub(super) fn inside_solid(pa: &Isometry3<f64>, a: &dyn Shape, pb: &Isometry3<f64>, b: &dyn Shape) -> bool {
    let nested = |pa: &Isometry3<f64>, a: &dyn Shape, pb: &Isometry3<f64>, b: &dyn Shape| -> bool {
        // a's pieces in b (b a solid mesh), or a mesh a in b (b any solid but a mesh surface)
        let solid_b = solid_mesh(b).is_some() || (b.as_shape::<TriMesh>().is_none() && a.as_shape::<TriMesh>().is_some());
        if !solid_b {
            return false;
        }
        let mut pts = Vec::new();
        points_of(a, &mut pts);
        pts.iter().any(|p| b.contains_point(pb, &(pa * p)))
    };
    nested(pa, a, pb, b) || nested(pb, b, pa, a)
}

/// Do `a` at `pa` and `b` at `pb` intersect, a closed mesh kept as a mesh counting as a solid?
/// parry's intersection test, then [`inside_solid`] when a mesh is involved. A pair parry does
/// not support counts as intersecting (the safe side).
#[inline]
pub(super) fn intersects(pa: &Isometry3<f64>, a: &dyn Shape, pb: &Isometry3<f64>, b: &dyn Shape) -> bool {
    query::intersection_test(pa, a, pb, b).unwrap_or(true) || (has_mesh(a, b) && inside_solid(pa, a, pb, b))
}

/// Is either shape a `TriMesh` (the only shapes with a surface that is not their solid)?
#[inline]
pub(super) fn has_mesh(a: &dyn Shape, b: &dyn Shape) -> bool {
    a.as_shape::<TriMesh>().is_some() || b.as_shape::<TriMesh>().is_some()
}

/// The signed distance from world point `p` to `shape` at `pose` (negative inside: minus the
/// depth) and the nearest point of its surface. parry's projection tells inside from outside
/// for a convex shape; a compound (a decomposed mesh) is the union of its parts, so its value is
/// the least over the parts; a closed mesh kept as a mesh is inside where its pseudo-normals say
/// so (parry's plain projection on a mesh only sees the surface).
pub(super) fn signed_point_distance(shape: &dyn Shape, pose: &Isometry3<f64>, p: &Point3<f64>) -> (f64, Point3<f64>) {
    let signed = |proj: query::PointProjection| {
        let d = (p - proj.point).norm();
        (if proj.is_inside { -d } else { d }, proj.point)
    };
    if let Some(m) = solid_mesh(shape) {
        let local = pose.inverse_transform_point(p);
        let (mut proj, _) = query::PointQueryWithLocation::project_local_point_and_get_location(m, &local, false);
        proj.point = pose * proj.point;
        return signed(proj);
    }
    if let Some(c) = shape.as_shape::<Compound>() {
        if let Some(best) = c
            .shapes()
            .iter()
            .map(|(part_pose, part)| signed(part.project_point(&(pose * part_pose), p, false)))
            .min_by(|x, y| x.0.total_cmp(&y.0))
        {
            return best;
        }
    }
    signed(shape.project_point(pose, p, false))
}

fn positive(what: &str, link: &str, v: f64) -> Result<f64> {
    if v > 0.0 && v.is_finite() {
        Ok(v)
    } else {
        Err(Error::Invalid(format!(
            "link '{link}': {what} must be positive, got {v}"
        )))
    }
}

/// Convert a URDF geometry to a parry shape and the extra local transform it needs.
fn shape_of(
    urdf: &Urdf,
    link: &str,
    geometry: &Geometry,
    package_dirs: &[PathBuf],
    mesh_kind: MeshShape,
    hull_cache: &mut HashMap<(PathBuf, [u64; 3]), SharedShape>,
) -> Result<(SharedShape, Isometry3<f64>)> {
    // URDF cylinders and capsules run along z; parry's along y. Rx(+90 deg) maps y to z.
    let y_to_z = Isometry3::from_parts(
        Translation3::identity(),
        UnitQuaternion::from_euler_angles(std::f64::consts::FRAC_PI_2, 0.0, 0.0),
    );
    Ok(match geometry {
        Geometry::Box { size } => {
            for k in 0..3 {
                positive("box size", link, size[k])?;
            }
            (
                SharedShape::new(Cuboid::new(size / 2.0)),
                Isometry3::identity(),
            )
        }
        Geometry::Sphere { radius } => (
            SharedShape::new(Ball::new(positive("sphere radius", link, *radius)?)),
            Isometry3::identity(),
        ),
        Geometry::Cylinder { radius, length } => (
            SharedShape::new(Cylinder::new(
                positive("cylinder length", link, *length)? / 2.0,
                positive("cylinder radius", link, *radius)?,
            )),
            y_to_z,
        ),
        Geometry::Capsule { radius, length } => (
            SharedShape::new(Capsule::new_y(
                positive("capsule length", link, *length)? / 2.0,
                positive("capsule radius", link, *radius)?,
            )),
            y_to_z,
        ),
        Geometry::Mesh { filename, scale } => {
            let path = urdf.resolve_mesh(filename, package_dirs)?;
            let key = (path.clone(), [scale.x.to_bits(), scale.y.to_bits(), scale.z.to_bits()]);
            if let Some(s) = hull_cache.get(&key) {
                return Ok((s.clone(), Isometry3::identity()));
            }
            let shape = match mesh_kind {
                MeshShape::Hull => {
                    let points = load_mesh_vertices(&path, scale)?;
                    Hull::from_points(&points).map(SharedShape::new).ok_or_else(|| Error::Mesh {
                        path: path.clone(),
                        msg: "convex hull failed (degenerate mesh?)".into(),
                    })?
                }
                kind => mesh_shape(&crate::mesh::read_mesh(&path)?.scaled(scale), kind, &path)?,
            };
            hull_cache.insert(key, shape.clone());
            (shape, Isometry3::identity())
        }
    })
}

/// Every `<collision>` of the URDF's links (the links must be the model's), in link order.
pub(super) fn robot_geometries(
    model: &KinematicModel,
    urdf: &Urdf,
    package_dirs: &[PathBuf],
    mesh_kind: MeshShape,
) -> Result<Vec<RobotGeometry>> {
    let mut geometries = Vec::new();
    let mut cache = HashMap::new();
    for link in &urdf.links {
        if link.collisions.is_empty() {
            continue;
        }
        let li = model.link_index(&link.name)?;
        for (i, c) in link.collisions.iter().enumerate() {
            let (shape, extra) = shape_of(urdf, &link.name, &c.geometry, package_dirs, mesh_kind, &mut cache)?;
            let (center, radius) = bounding_sphere(&shape);
            let local_aabb = shape.compute_local_aabb();
            geometries.push(RobotGeometry {
                name: format!("{}_{}", link.name, i),
                link: li,
                offset: c.origin * extra,
                shape,
                center,
                radius,
                local_aabb,
            });
        }
    }
    Ok(geometries)
}
