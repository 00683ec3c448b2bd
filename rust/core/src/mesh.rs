//! Triangle meshes from the files URDF `<mesh filename=...>` elements name: STL (binary and
//! ASCII), Wavefront OBJ and COLLADA (`.dae`, versions 1.4 and 1.5).
//!
//! [`read_mesh`] returns the vertices (metres) and triangles of a file, in the file's frame after
//! its own transforms, chosen by the extension (case-insensitive). The result is meant to be the
//! geometry Pinocchio builds for the same file, since its collision library (coal) reads meshes
//! through assimp:
//!
//! * only vertices used by a triangle are kept (lines, points and unused positions are dropped);
//! * polygons are triangulated, polygons of fewer than 3 corners skipped;
//! * triangles with two corners at the same position are dropped (assimp's `FindDegenerates`
//!   and primitive sorting remove them);
//! * COLLADA node transforms are applied, but **not** the document's `<unit meter>` scale nor its
//!   `<up_axis>` rotation: assimp puts both into the scene's root node, and coal composes every
//!   node transform except the root's. [`ReadOptions`] turns either on, as the COLLADA
//!   specification asks (`ReadOptions::COLLADA_SPEC`).
//!
//! Polygons are fan-triangulated (assimp ear-clips concave ones: same vertices, so the same
//! convex hull, but other triangles).
//!
//! STL goes through `stl_io` and gives exactly its indexed mesh, as `collision/geometry.rs`
//! read it before this module: vertices merged by `stl_io`, degenerate triangles kept (coal
//! drops them; the bounding box and convex hull are the same).
//!
//! Malformed files give [`Error::Mesh`] naming the file and the problem (never a panic);
//! unreadable files give [`Error::Io`].

use std::collections::HashMap;
use std::fs::File;
use std::io::BufReader;
use std::path::Path;

use nalgebra::{Matrix4, Point3, Rotation3, Unit, Vector3};
use roxmltree::Node;

use crate::error::{Error, Result};

/// The file extensions [`read_mesh`] understands (compared case-insensitively).
pub const SUPPORTED_EXTENSIONS: &[&str] = &["stl", "obj", "dae"];

/// A triangle mesh: positions and the triangles indexing them.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Mesh {
    /// Vertex positions, in metres, in the file's frame.
    pub vertices: Vec<Point3<f64>>,
    /// Triangles, as indices into `vertices`.
    pub triangles: Vec<[u32; 3]>,
}

impl Mesh {
    /// Whether the triangles bound a solid: with corners merged by position and triangles with
    /// two corners at one position left out, every edge is shared by exactly two triangles that
    /// run through it in opposite directions (a closed, consistently oriented surface). An open
    /// mesh (a hole, a free edge), a non-manifold edge (three or more triangles) or a flipped
    /// triangle makes it false.
    pub fn is_closed(&self) -> bool {
        let ids = self.position_ids();
        let mut edges: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * self.triangles.len());
        let mut any = false;
        for t in &self.triangles {
            let [a, b, c] = t.map(|i| ids[i as usize]);
            if a == b || b == c || a == c {
                continue;
            }
            any = true;
            for e in [(a, b), (b, c), (c, a)] {
                *edges.entry(e).or_insert(0) += 1;
            }
        }
        any && edges.iter().all(|(&(u, v), &n)| n == 1 && edges.get(&(v, u)) == Some(&1))
    }

    /// The volume the triangles enclose by the divergence theorem: positive when they face
    /// outward (counter-clockwise seen from outside), negative when they all face inward;
    /// meaningful for a closed mesh ([`is_closed`](Self::is_closed)).
    pub fn signed_volume(&self) -> f64 {
        let v = &self.vertices;
        self.triangles
            .iter()
            .map(|t| {
                let (a, b, c) = (v[t[0] as usize].coords, v[t[1] as usize].coords, v[t[2] as usize].coords);
                a.dot(&b.cross(&c))
            })
            .sum::<f64>()
            / 6.0
    }

    /// The mesh with every vertex scaled per axis by `scale`; a scale with an odd number of
    /// negative components would mirror the mesh, so the triangles are then reversed to keep
    /// their orientation.
    pub fn scaled(&self, scale: &Vector3<f64>) -> Mesh {
        let vertices = self.vertices.iter().map(|p| Point3::from(p.coords.component_mul(scale))).collect();
        let mirrored = scale.iter().filter(|&&s| s < 0.0).count() % 2 == 1;
        let triangles = if mirrored { self.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect() } else { self.triangles.clone() };
        Mesh { vertices, triangles }
    }

    /// For each vertex, the index of the first vertex at the same position (bit for bit, with
    /// -0.0 and 0.0 one position).
    fn position_ids(&self) -> Vec<u32> {
        let mut first: HashMap<[u64; 3], u32> = HashMap::with_capacity(self.vertices.len());
        self.vertices
            .iter()
            .enumerate()
            .map(|(i, p)| *first.entry(p.coords.map(|x| (x + 0.0).to_bits()).into()).or_insert(i as u32))
            .collect()
    }

    /// Axis-aligned bounding box of the vertices, as (min, max); `None` for an empty mesh.
    pub fn aabb(&self) -> Option<(Point3<f64>, Point3<f64>)> {
        let first = *self.vertices.first()?;
        Some(
            self.vertices
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.inf(p), hi.sup(p))),
        )
    }
}

/// How COLLADA `<asset>` settings are applied. The default (both off) matches Pinocchio / coal;
/// see the module documentation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Scale COLLADA geometry by `<asset><unit meter="...">` (default 1 when absent).
    pub collada_unit: bool,
    /// Rotate COLLADA geometry from the document's `<up_axis>` (default `Y_UP` when absent, as
    /// in the specification) to Z-up: `Y_UP` maps (x, y, z) to (x, -z, y), `X_UP` to
    /// (-y, -z, x), i.e. assimp's conversion to Y-up followed by Y-up to Z-up.
    pub collada_up_axis: bool,
}

impl ReadOptions {
    /// Both COLLADA settings applied, as the COLLADA specification reads them.
    pub const COLLADA_SPEC: ReadOptions = ReadOptions {
        collada_unit: true,
        collada_up_axis: true,
    };
}

/// Read a mesh file (`.stl`, `.obj` or `.dae`, any case) the way Pinocchio / coal read it.
pub fn read_mesh(path: &Path) -> Result<Mesh> {
    read_mesh_with(path, &ReadOptions::default())
}

/// Read a mesh file, with the given treatment of COLLADA `<asset>` settings.
pub fn read_mesh_with(path: &Path, options: &ReadOptions) -> Result<Mesh> {
    let bad = |msg: String| Error::Mesh {
        path: path.to_path_buf(),
        msg,
    };
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase())
        .unwrap_or_default();
    let io = |source| Error::Io {
        path: path.to_path_buf(),
        source,
    };
    let mesh = match ext.as_str() {
        "stl" => {
            let file = File::open(path).map_err(io)?;
            read_stl(&mut BufReader::new(file)).map_err(bad)?
        }
        "obj" => read_obj(&std::fs::read(path).map_err(io)?).map_err(bad)?,
        "dae" => {
            let bytes = std::fs::read(path).map_err(io)?;
            let text = match String::from_utf8(bytes) {
                Ok(s) => s,
                Err(e) => String::from_utf8_lossy(e.as_bytes()).into_owned(),
            };
            read_dae(&text, options).map_err(bad)?
        }
        _ => {
            let got = if ext.is_empty() {
                "no extension".to_string()
            } else {
                format!("extension '.{ext}'")
            };
            let known: Vec<String> = SUPPORTED_EXTENSIONS.iter().map(|e| format!(".{e}")).collect();
            return Err(bad(format!("unsupported mesh format ({got}); supported: {}", known.join(", "))));
        }
    };
    validate(&mesh).map_err(bad)?;
    Ok(mesh)
}

/// Common checks on every format's result: some triangles, finite vertices, indices in range.
fn validate(mesh: &Mesh) -> std::result::Result<(), String> {
    if mesh.triangles.is_empty() {
        return Err("no triangles (no geometry to build a shape from)".into());
    }
    if let Some((i, p)) = mesh
        .vertices
        .iter()
        .enumerate()
        .find(|(_, p)| !p.coords.iter().all(|c| c.is_finite()))
    {
        return Err(format!(
            "vertex {i} is not finite ({} {} {})",
            p.x, p.y, p.z
        ));
    }
    let n = mesh.vertices.len();
    if let Some(t) = mesh
        .triangles
        .iter()
        .find(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(format!("triangle {t:?} indexes past the {n} vertices"));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Shared assembly

const UNSET: u32 = u32::MAX;

/// Triangles over a list of positions, with degenerate ones (two corners at the same position)
/// left out, as assimp does.
struct LocalMesh {
    positions: Vec<Point3<f64>>,
    triangles: Vec<[u32; 3]>,
}

impl LocalMesh {
    /// Add the triangle (a, b, c) of `positions` (indices already checked in range).
    fn push(&mut self, a: u32, b: u32, c: u32) {
        let p = &self.positions;
        let (pa, pb, pc) = (p[a as usize], p[b as usize], p[c as usize]);
        if pa != pb && pb != pc && pa != pc {
            self.triangles.push([a, b, c]);
        }
    }

    /// Fan-triangulate a polygon given by its corner indices.
    fn push_polygon(&mut self, corners: &[u32]) {
        for k in 1..corners.len().saturating_sub(1) {
            self.push(corners[0], corners[k], corners[k + 1]);
        }
    }

    /// Append the used positions (transformed by the affine part of `m`, if any) and the
    /// triangles to `out`.
    fn append_to(
        &self,
        out: &mut Mesh,
        m: Option<&Matrix4<f64>>,
        map: &mut Vec<u32>,
    ) -> std::result::Result<(), String> {
        map.clear();
        map.resize(self.positions.len(), UNSET);
        out.triangles.reserve(self.triangles.len());
        for t in &self.triangles {
            let mut tri = [0u32; 3];
            for (k, &i) in t.iter().enumerate() {
                let slot = &mut map[i as usize];
                if *slot == UNSET {
                    let idx = u32::try_from(out.vertices.len())
                        .ok()
                        .filter(|&v| v != UNSET)
                        .ok_or("more than 4 billion vertices")?;
                    let p = self.positions[i as usize];
                    out.vertices.push(match m {
                        Some(m) => affine(m, &p),
                        None => p,
                    });
                    *slot = idx;
                }
                tri[k] = *slot;
            }
            out.triangles.push(tri);
        }
        Ok(())
    }
}

/// The affine part of a 4x4 matrix applied to a point (the last row is ignored, as assimp does).
fn affine(m: &Matrix4<f64>, p: &Point3<f64>) -> Point3<f64> {
    Point3::from(m.fixed_view::<3, 3>(0, 0) * p.coords + m.fixed_view::<3, 1>(0, 3))
}

/// Parse a number token without allocating.
fn number<T: std::str::FromStr>(token: &str) -> Option<T> {
    token.parse().ok()
}

// ---------------------------------------------------------------------------------------------
// STL

fn read_stl<R: std::io::Read + std::io::Seek>(reader: &mut R) -> std::result::Result<Mesh, String> {
    let stl = stl_io::read_stl(reader).map_err(|e| format!("not a valid STL file: {e}"))?;
    let vertices = stl
        .vertices
        .iter()
        .map(|v| Point3::new(v[0] as f64, v[1] as f64, v[2] as f64))
        .collect::<Vec<_>>();
    if vertices.len() >= UNSET as usize {
        return Err("more than 4 billion vertices".into());
    }
    let triangles = stl
        .faces
        .iter()
        .map(|f| f.vertices.map(|i| i as u32))
        .collect();
    Ok(Mesh {
        vertices,
        triangles,
    })
}

// ---------------------------------------------------------------------------------------------
// Wavefront OBJ

fn read_obj(data: &[u8]) -> std::result::Result<Mesh, String> {
    let mut local = LocalMesh {
        positions: Vec::new(),
        triangles: Vec::new(),
    };
    // Faces as position indices; positive ones may point forward, so they are checked at the end.
    let mut faces: Vec<u32> = Vec::new();
    let mut face_starts: Vec<usize> = Vec::new();
    let mut joined: Vec<u8> = Vec::new();
    let mut corners: Vec<i64> = Vec::new();
    let mut values = [0.0f64; 8];

    let mut lines = data.split(|&b| b == b'\n').enumerate();
    while let Some((index, first)) = lines.next() {
        let line_no = index + 1;
        // A backslash at the end of a line continues it on the next one.
        let mut line = trim_cr(first);
        if line.last() == Some(&b'\\') {
            joined.clear();
            joined.extend_from_slice(&line[..line.len() - 1]);
            for (_, next) in lines.by_ref() {
                let next = trim_cr(next);
                joined.push(b' ');
                if next.last() == Some(&b'\\') {
                    joined.extend_from_slice(&next[..next.len() - 1]);
                } else {
                    joined.extend_from_slice(next);
                    break;
                }
            }
            line = &joined;
        }
        if let Some(hash) = line.iter().position(|&b| b == b'#') {
            line = &line[..hash];
        }
        let mut tokens = line
            .split(|b| b.is_ascii_whitespace())
            .filter(|t| !t.is_empty());
        match tokens.next() {
            Some(b"v") => {
                let mut n = 0;
                for t in tokens {
                    let v = std::str::from_utf8(t)
                        .ok()
                        .and_then(number::<f64>)
                        .ok_or_else(|| {
                            format!(
                                "line {line_no}: bad number '{}' in 'v'",
                                String::from_utf8_lossy(t)
                            )
                        })?;
                    if n < values.len() {
                        values[n] = v;
                    }
                    n += 1;
                }
                let p = match n {
                    3 | 6 => Point3::new(values[0], values[1], values[2]),
                    4 => {
                        let w = values[3];
                        if w == 0.0 {
                            return Err(format!("line {line_no}: vertex weight w is 0"));
                        }
                        Point3::new(values[0] / w, values[1] / w, values[2] / w)
                    }
                    _ => {
                        return Err(format!(
                            "line {line_no}: 'v' needs 3 (x y z), 4 (x y z w) or 6 (x y z r g b) numbers, got {n}"
                        ))
                    }
                };
                local.positions.push(p);
            }
            Some(b"f") => {
                corners.clear();
                for t in tokens {
                    let v = t.split(|&b| b == b'/').next().unwrap_or(t);
                    let i = std::str::from_utf8(v)
                        .ok()
                        .and_then(number::<i64>)
                        .ok_or_else(|| {
                            format!(
                                "line {line_no}: bad vertex reference '{}' in 'f'",
                                String::from_utf8_lossy(t)
                            )
                        })?;
                    let count = local.positions.len() as i64;
                    let resolved = match i {
                        0 => {
                            return Err(format!(
                                "line {line_no}: vertex index 0 (OBJ indices start at 1)"
                            ))
                        }
                        i if i > 0 => i - 1,
                        i => {
                            let r = count + i;
                            if r < 0 {
                                return Err(format!(
                                    "line {line_no}: relative vertex index {i} reaches before the first vertex ({count} defined so far)"
                                ));
                            }
                            r
                        }
                    };
                    corners.push(resolved);
                }
                if corners.len() >= 3 {
                    face_starts.push(faces.len());
                    for &c in &corners {
                        let c = u32::try_from(c)
                            .ok()
                            .filter(|&c| c != UNSET)
                            .ok_or_else(|| {
                                format!("line {line_no}: vertex index {} too large", c + 1)
                            })?;
                        faces.push(c);
                    }
                }
            }
            _ => {}
        }
    }
    let n = local.positions.len();
    if let Some(&bad) = faces.iter().find(|&&i| i as usize >= n) {
        return Err(format!(
            "face refers to vertex {} but the file has {n} vertices",
            bad as u64 + 1
        ));
    }
    face_starts.push(faces.len());
    for w in face_starts.windows(2) {
        local.push_polygon(&faces[w[0]..w[1]]);
    }
    let mut mesh = Mesh::default();
    local.append_to(&mut mesh, None, &mut Vec::new())?;
    Ok(mesh)
}

fn trim_cr(line: &[u8]) -> &[u8] {
    match line.last() {
        Some(b'\r') => &line[..line.len() - 1],
        _ => line,
    }
}

// ---------------------------------------------------------------------------------------------
// COLLADA

/// Deepest node nesting followed (guards against runaway `<instance_node>` chains).
const MAX_DEPTH: usize = 256;

struct Dae<'a, 'input> {
    ids: HashMap<&'a str, Node<'a, 'input>>,
    geometries: HashMap<&'a str, LocalMesh>,
    out: Mesh,
    map: Vec<u32>,
    /// Node elements on the current path, to detect `<instance_node>` cycles.
    path: Vec<roxmltree::NodeId>,
}

fn read_dae(text: &str, options: &ReadOptions) -> std::result::Result<Mesh, String> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let doc = roxmltree::Document::parse_with_options(
        text,
        roxmltree::ParsingOptions {
            allow_dtd: true,
            ..Default::default()
        },
    )
    .map_err(|e| format!("not well-formed XML: {e}"))?;
    let root = doc.root_element();
    if root.tag_name().name() != "COLLADA" {
        return Err(format!(
            "root element is <{}>, not <COLLADA>",
            root.tag_name().name()
        ));
    }
    let mut dae = Dae {
        ids: HashMap::new(),
        geometries: HashMap::new(),
        out: Mesh::default(),
        map: Vec::new(),
        path: Vec::new(),
    };
    for n in root.descendants().filter(|n| n.is_element()) {
        if let Some(id) = n.attribute("id") {
            dae.ids.entry(id).or_insert(n);
        }
    }

    let scene = match child(root, "scene").and_then(|s| child(s, "instance_visual_scene")) {
        Some(inst) => dae.lookup(inst, "url", "visual_scene")?,
        None => child(root, "library_visual_scenes")
            .and_then(|l| child(l, "visual_scene"))
            .ok_or("no <scene><instance_visual_scene> and no <visual_scene>")?,
    };

    let asset = child(root, "asset");
    let mut top = Matrix4::identity();
    if options.collada_unit {
        if let Some(unit) = asset.and_then(|a| child(a, "unit")) {
            let s = unit.attribute("meter").unwrap_or("1");
            let meter = number::<f64>(s.trim())
                .filter(|m| *m > 0.0 && m.is_finite())
                .ok_or_else(|| format!("<unit meter=\"{s}\">: not a positive number"))?;
            top = Matrix4::new_scaling(meter);
        }
    }
    if options.collada_up_axis {
        let up = asset
            .and_then(|a| child(a, "up_axis"))
            .and_then(|u| u.text())
            .map(str::trim)
            .unwrap_or("Y_UP");
        let to_z_up = match up {
            "Z_UP" => Matrix4::identity(),
            "Y_UP" => Matrix4::new(
                1.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, -1.0, 0.0, //
                0.0, 1.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ),
            "X_UP" => Matrix4::new(
                0.0, -1.0, 0.0, 0.0, //
                0.0, 0.0, -1.0, 0.0, //
                1.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ),
            other => {
                return Err(format!(
                    "<up_axis>{other}</up_axis>: expected X_UP, Y_UP or Z_UP"
                ))
            }
        };
        top = to_z_up * top;
    }

    for n in elements(scene).filter(|n| n.tag_name().name() == "node") {
        dae.node(n, &top)?;
    }
    Ok(dae.out)
}

/// The first child element named `name` (namespace ignored).
fn child<'a, 'input>(n: Node<'a, 'input>, name: &str) -> Option<Node<'a, 'input>> {
    n.children()
        .find(|c| c.is_element() && c.tag_name().name() == name)
}

/// The child elements of `n`.
fn elements<'a, 'input>(n: Node<'a, 'input>) -> impl Iterator<Item = Node<'a, 'input>> {
    n.children().filter(|c| c.is_element())
}

/// Describe an element for error messages: `<name id="...">` or `<name>`.
fn describe(n: Node) -> String {
    match n.attribute("id") {
        Some(id) => format!("<{} id=\"{id}\">", n.tag_name().name()),
        None => format!("<{}>", n.tag_name().name()),
    }
}

/// Parse the whitespace-separated numbers of an element's text into `out`.
fn numbers<T: std::str::FromStr>(n: Node, out: &mut Vec<T>) -> std::result::Result<(), String> {
    out.clear();
    for t in n.text().unwrap_or("").split_ascii_whitespace() {
        out.push(number(t).ok_or_else(|| format!("{}: bad number '{t}'", describe(n)))?);
    }
    Ok(())
}

/// Exactly `N` numbers from an element's text.
fn fixed<const N: usize>(n: Node) -> std::result::Result<[f64; N], String> {
    let mut v = Vec::with_capacity(N);
    numbers::<f64>(n, &mut v)?;
    v.try_into()
        .map_err(|v: Vec<f64>| format!("{}: expected {N} numbers, got {}", describe(n), v.len()))
}

impl<'a, 'input> Dae<'a, 'input> {
    /// The element a `#id` reference attribute of `n` points to; it must be a `<kind>`.
    fn lookup(
        &self,
        n: Node<'a, 'input>,
        attr: &str,
        kind: &str,
    ) -> std::result::Result<Node<'a, 'input>, String> {
        let url = n
            .attribute(attr)
            .ok_or_else(|| format!("{} has no {attr} attribute", describe(n)))?;
        let id = url.strip_prefix('#').ok_or_else(|| {
            format!(
                "{} {attr}=\"{url}\": only references inside the file (#id) are supported",
                describe(n)
            )
        })?;
        let target = *self
            .ids
            .get(id)
            .ok_or_else(|| format!("{} {attr}=\"{url}\": no element has that id", describe(n)))?;
        if target.tag_name().name() != kind {
            return Err(format!(
                "{} {attr}=\"{url}\" names a <{}>, expected <{kind}>",
                describe(n),
                target.tag_name().name()
            ));
        }
        Ok(target)
    }

    /// Visit a `<node>` under the parent transform `parent`.
    fn node(
        &mut self,
        node: Node<'a, 'input>,
        parent: &Matrix4<f64>,
    ) -> std::result::Result<(), String> {
        if self.path.len() >= MAX_DEPTH {
            return Err(format!(
                "nodes nested deeper than {MAX_DEPTH} at {}",
                describe(node)
            ));
        }
        if self.path.contains(&node.id()) {
            return Err(format!(
                "{} instances itself (<instance_node> cycle)",
                describe(node)
            ));
        }
        let mut m = *parent;
        for t in elements(node) {
            let local = match t.tag_name().name() {
                "matrix" => {
                    let v = fixed::<16>(t)?;
                    Matrix4::from_row_slice(&v)
                }
                "translate" => Matrix4::new_translation(&Vector3::from(fixed::<3>(t)?)),
                "scale" => Matrix4::new_nonuniform_scaling(&Vector3::from(fixed::<3>(t)?)),
                "rotate" => {
                    let [x, y, z, deg] = fixed::<4>(t)?;
                    if deg == 0.0 {
                        Matrix4::identity()
                    } else {
                        let axis = Vector3::new(x, y, z);
                        let axis = Unit::try_new(axis, 0.0)
                            .filter(|a| a.iter().all(|c| c.is_finite()))
                            .ok_or_else(|| {
                                format!(
                                    "{}: rotation axis {x} {y} {z} has no direction",
                                    describe(t)
                                )
                            })?;
                        Rotation3::from_axis_angle(&axis, deg.to_radians()).to_homogeneous()
                    }
                }
                "lookat" | "skew" => {
                    return Err(format!(
                        "{}: <{}> transforms are not supported",
                        describe(node),
                        t.tag_name().name()
                    ))
                }
                _ => continue,
            };
            m *= local;
        }
        self.path.push(node.id());
        for c in elements(node) {
            match c.tag_name().name() {
                "instance_geometry" => {
                    let g = self.lookup(c, "url", "geometry")?;
                    self.instance(g, &m)?;
                }
                "node" => self.node(c, &m)?,
                "instance_node" => {
                    let target = self.lookup(c, "url", "node")?;
                    self.node(target, &m)?;
                }
                "instance_controller" => {
                    return Err(format!(
                        "{}: <instance_controller> (skinned geometry) is not supported",
                        describe(node)
                    ))
                }
                _ => {}
            }
        }
        self.path.pop();
        Ok(())
    }

    /// Add one instance of a `<geometry>` under the transform `m`.
    fn instance(
        &mut self,
        g: Node<'a, 'input>,
        m: &Matrix4<f64>,
    ) -> std::result::Result<(), String> {
        let id = g.attribute("id").unwrap_or_default();
        if !self.geometries.contains_key(id) {
            let local = self.geometry(g)?;
            self.geometries.insert(id, local);
        }
        let local = &self.geometries[id];
        local.append_to(&mut self.out, Some(m), &mut self.map)
    }

    /// Positions and triangles of a `<geometry>`'s `<mesh>`.
    fn geometry(&self, g: Node<'a, 'input>) -> std::result::Result<LocalMesh, String> {
        let mesh = child(g, "mesh").ok_or_else(|| {
            format!(
                "{} has no <mesh> (convex_mesh, spline and brep are not supported)",
                describe(g)
            )
        })?;
        let mut local = LocalMesh {
            positions: Vec::new(),
            triangles: Vec::new(),
        };
        let mut vertices_id: Option<roxmltree::NodeId> = None;
        let mut p: Vec<u32> = Vec::new();
        let mut vcount: Vec<u32> = Vec::new();
        for prim in elements(mesh) {
            let kind = prim.tag_name().name();
            if !matches!(
                kind,
                "triangles" | "polylist" | "polygons" | "tristrips" | "trifans"
            ) {
                continue; // <source>, <vertices>, <lines>, <linestrips>, <extra>
            }
            // Inputs: each vertex of a primitive is `stride` indices, the VERTEX one at `offset`.
            let mut stride = 0usize;
            let mut vertex: Option<(usize, Node)> = None;
            for input in elements(prim).filter(|i| i.tag_name().name() == "input") {
                let offset = match input.attribute("offset") {
                    Some(s) => number::<u16>(s.trim()).ok_or_else(|| {
                        format!("<{kind}> <input offset=\"{s}\">: not an index below 65536")
                    })? as usize,
                    None => 0,
                };
                stride = stride.max(offset + 1);
                if input.attribute("semantic") == Some("VERTEX") {
                    vertex = Some((offset, self.lookup(input, "source", "vertices")?));
                }
            }
            let Some((offset, vertices)) = vertex else {
                return Err(format!("{} <{kind}> has no VERTEX input", describe(g)));
            };
            match vertices_id {
                None => {
                    local.positions = self.positions(vertices)?;
                    vertices_id = Some(vertices.id());
                }
                Some(v) if v != vertices.id() => {
                    return Err(format!(
                        "{}: primitives use different <vertices>",
                        describe(g)
                    ));
                }
                Some(_) => {}
            }
            let n = local.positions.len();
            let what = format!("{} <{kind}>", describe(g));

            // The VERTEX indices of one <p>, checked in range.
            let corners = |pn: Node, p: &mut Vec<u32>| -> std::result::Result<Vec<u32>, String> {
                numbers::<u32>(pn, p).map_err(|e| format!("{what}: {e}"))?;
                if p.len() % stride != 0 {
                    return Err(format!(
                        "{what}: <p> has {} indices, not a multiple of the {stride} inputs",
                        p.len()
                    ));
                }
                let c: Vec<u32> = p.iter().skip(offset).step_by(stride).copied().collect();
                if let Some(&bad) = c.iter().find(|&&i| i as usize >= n) {
                    return Err(format!("{what}: index {bad} out of range ({n} positions)"));
                }
                Ok(c)
            };
            match kind {
                "triangles" => {
                    for pn in elements(prim).filter(|c| c.tag_name().name() == "p") {
                        let c = corners(pn, &mut p)?;
                        if c.len() % 3 != 0 {
                            return Err(format!(
                                "{what}: {} vertices, not a multiple of 3",
                                c.len()
                            ));
                        }
                        for t in c.chunks_exact(3) {
                            local.push(t[0], t[1], t[2]);
                        }
                    }
                }
                "polylist" => {
                    let Some(pn) = child(prim, "p") else { continue };
                    let c = corners(pn, &mut p)?;
                    match child(prim, "vcount") {
                        Some(vn) => {
                            numbers::<u32>(vn, &mut vcount).map_err(|e| format!("{what}: {e}"))?
                        }
                        None => vcount.clear(),
                    }
                    let total: u64 = vcount.iter().map(|&k| k as u64).sum();
                    if total != c.len() as u64 {
                        return Err(format!(
                            "{what}: <vcount> adds up to {total} vertices but <p> has {}",
                            c.len()
                        ));
                    }
                    let mut start = 0usize;
                    for &k in &vcount {
                        let end = start + k as usize;
                        local.push_polygon(&c[start..end]);
                        start = end;
                    }
                }
                "polygons" => {
                    for pc in elements(prim) {
                        // <ph>: a polygon with holes; its outer boundary is its <p>.
                        let pn = match pc.tag_name().name() {
                            "p" => pc,
                            "ph" => match child(pc, "p") {
                                Some(pn) => pn,
                                None => continue,
                            },
                            _ => continue,
                        };
                        let c = corners(pn, &mut p)?;
                        local.push_polygon(&c);
                    }
                }
                "trifans" => {
                    for pn in elements(prim).filter(|c| c.tag_name().name() == "p") {
                        let c = corners(pn, &mut p)?;
                        local.push_polygon(&c);
                    }
                }
                _ => {
                    // tristrips: every three consecutive vertices, alternating the winding.
                    for pn in elements(prim).filter(|c| c.tag_name().name() == "p") {
                        let c = corners(pn, &mut p)?;
                        for k in 0..c.len().saturating_sub(2) {
                            if k % 2 == 0 {
                                local.push(c[k], c[k + 1], c[k + 2]);
                            } else {
                                local.push(c[k + 1], c[k], c[k + 2]);
                            }
                        }
                    }
                }
            }
        }
        Ok(local)
    }

    /// The positions of a `<vertices>` element: its POSITION input's `<source>`, read through the
    /// source's accessor.
    fn positions(
        &self,
        vertices: Node<'a, 'input>,
    ) -> std::result::Result<Vec<Point3<f64>>, String> {
        let input = elements(vertices)
            .find(|i| i.tag_name().name() == "input" && i.attribute("semantic") == Some("POSITION"))
            .ok_or_else(|| format!("{} has no POSITION input", describe(vertices)))?;
        let source = self.lookup(input, "source", "source")?;
        let what = describe(source);
        let accessor = child(source, "technique_common")
            .and_then(|t| child(t, "accessor"))
            .ok_or_else(|| format!("{what} has no <technique_common><accessor>"))?;
        let array = match accessor.attribute("source") {
            Some(_) => self.lookup(accessor, "source", "float_array")?,
            None => child(source, "float_array")
                .ok_or_else(|| format!("{what} has no <float_array>"))?,
        };
        let attr = |name: &str, default: usize| -> std::result::Result<usize, String> {
            match accessor.attribute(name) {
                Some(s) => number(s.trim())
                    .ok_or_else(|| format!("{what} <accessor {name}=\"{s}\">: not a count")),
                None => Ok(default),
            }
        };
        let count = attr("count", usize::MAX)?;
        if count == usize::MAX {
            return Err(format!("{what} <accessor> has no count"));
        }
        let stride = attr("stride", 1)?;
        let start = attr("offset", 0)?;
        // Where X, Y and Z sit within each element: from the named <param>s, else 0, 1, 2.
        let mut sub = [0usize, 1, 2];
        let params: Vec<Node> = elements(accessor)
            .filter(|p| p.tag_name().name() == "param")
            .collect();
        for (k, prm) in params.iter().enumerate() {
            let axis = match prm.attribute("name") {
                Some("X") | Some("x") => 0,
                Some("Y") | Some("y") => 1,
                Some("Z") | Some("z") => 2,
                _ => continue,
            };
            sub[axis] = k;
        }
        if sub.iter().any(|&s| s >= stride) {
            return Err(format!(
                "{what}: accessor stride {stride} cannot hold x, y and z"
            ));
        }
        let mut values: Vec<f64> = Vec::new();
        numbers::<f64>(array, &mut values)?;
        let needed = count
            .checked_mul(stride)
            .and_then(|v| v.checked_add(start))
            .ok_or_else(|| format!("{what}: accessor count {count} too large"))?;
        if count > 0 && needed > values.len() {
            return Err(format!(
                "{what}: accessor needs {needed} numbers, {} has {}",
                describe(array),
                values.len()
            ));
        }
        Ok((0..count)
            .map(|i| {
                let b = start + i * stride;
                Point3::new(values[b + sub[0]], values[b + sub[1]], values[b + sub[2]])
            })
            .collect())
    }
}
