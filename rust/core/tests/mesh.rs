//! `genplan_core::mesh`: STL / OBJ / COLLADA readers. Hand-written files cover each feature and
//! error; the `#[ignore]`d tests read example-robot-data's meshes and compare with coal (the
//! collision library Pinocchio uses, which reads meshes through assimp).
//!
//! The expected numbers of the hand-written COLLADA / OBJ files were checked against coal too:
//! the same text saved to a file and loaded with
//! `.venv/bin/python -c "import coal, numpy as np; v = np.array(coal.MeshLoader().load(F).vertices()); print(v.min(0), v.max(0))"`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use genplan_core::mesh::{read_mesh, read_mesh_with, Mesh, ReadOptions};
use genplan_core::robot::find_robots_dir;
use genplan_core::Error;
use nalgebra::Point3;

/// A file in a per-process temporary folder, removed when dropped.
struct TempFile(PathBuf);

impl Drop for TempFile {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

impl std::ops::Deref for TempFile {
    type Target = Path;
    fn deref(&self) -> &Path {
        &self.0
    }
}

/// Write `contents` to a fresh file whose name ends with `name` (tests run in parallel).
fn write(name: &str, contents: &[u8]) -> TempFile {
    static COUNTER: AtomicUsize = AtomicUsize::new(0);
    let dir = std::env::temp_dir().join(format!("genplan-mesh-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(format!("{}-{name}", COUNTER.fetch_add(1, Ordering::Relaxed)));
    std::fs::write(&path, contents).unwrap();
    TempFile(path)
}

fn read_str(name: &str, contents: &str) -> Mesh {
    let path = write(name, contents.as_bytes());
    read_mesh(&path).unwrap_or_else(|e| panic!("{name}: {e}"))
}

/// The error message of reading `contents` as `name`; it must be a mesh error naming the file.
fn error_of(name: &str, contents: &str) -> String {
    let path = write(name, contents.as_bytes());
    let e = read_mesh(&path).expect_err(name);
    assert!(matches!(e, Error::Mesh { .. }), "{name}: {e:?}");
    let msg = e.to_string();
    assert!(msg.contains(&path.display().to_string()), "{msg}");
    msg
}

fn p(x: f64, y: f64, z: f64) -> Point3<f64> {
    Point3::new(x, y, z)
}

fn assert_close(a: &Point3<f64>, b: &Point3<f64>, tol: f64, what: &str) {
    assert!((a - b).amax() <= tol, "{what}: {a} vs {b}");
}

fn assert_aabb(mesh: &Mesh, lo: [f64; 3], hi: [f64; 3], tol: f64, what: &str) {
    let (l, h) = mesh.aabb().unwrap();
    assert_close(&l, &Point3::from(lo), tol, what);
    assert_close(&h, &Point3::from(hi), tol, what);
}

/// The corners of each triangle, as positions (independent of vertex numbering).
fn corners(mesh: &Mesh) -> Vec<[Point3<f64>; 3]> {
    mesh.triangles
        .iter()
        .map(|t| t.map(|i| mesh.vertices[i as usize]))
        .collect()
}

// ---------------------------------------------------------------------------------------------
// OBJ

#[test]
fn obj_face_forms_fan_triangulation_and_ignored_statements() {
    let mesh = read_str(
        "forms.obj",
        "# a comment\n\
         mtllib x.mtl\n\
         o thing\n\
         v 0 0 0\n\
         v 1 0 0   # trailing comment\n\
         v 1 1 0\n\
         v 0 1 0\n\
         v 9 9 9\n\
         vt 0.5 0.5\n\
         vn 0 0 1\n\
         g group\r\n\
         usemtl m\n\
         s off\n\
         f 1/1/1 2/1/1 3/1/1 4/1/1\n\
         f 1//1 2//1 \\\n  5//1\n\
         f 1/1 3/1 5/1\n\
         l 1 2\n\
         p 3\n",
    );
    // the quad gives 2 triangles (fan from its first corner), then 2 more; vertex 5 is used
    assert_eq!(mesh.triangles.len(), 4);
    let c = corners(&mesh);
    assert_eq!(c[0], [p(0., 0., 0.), p(1., 0., 0.), p(1., 1., 0.)]);
    assert_eq!(c[1], [p(0., 0., 0.), p(1., 1., 0.), p(0., 1., 0.)]);
    assert_eq!(c[2], [p(0., 0., 0.), p(1., 0., 0.), p(9., 9., 9.)]);
    assert_eq!(c[3], [p(0., 0., 0.), p(1., 1., 0.), p(9., 9., 9.)]);
    assert_eq!(mesh.vertices.len(), 5);
}

#[test]
fn obj_negative_indices_are_relative_to_the_vertices_so_far() {
    let mesh = read_str(
        "relative.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 0 0 1\nf -4/1/1 -3//2 -1\nf 1 -2 -1\n",
    );
    let c = corners(&mesh);
    assert_eq!(c.len(), 3);
    assert_eq!(c[0], [p(0., 0., 0.), p(1., 0., 0.), p(0., 1., 0.)]);
    assert_eq!(c[1], [p(0., 0., 0.), p(1., 0., 0.), p(0., 0., 1.)]);
    assert_eq!(c[2], [p(0., 0., 0.), p(0., 1., 0.), p(0., 0., 1.)]);
}

#[test]
fn obj_homogeneous_w_colours_and_forward_references() {
    // coal: w divides (AABB [0 0 0] [1 2 3]); 6 numbers are x y z r g b
    let mesh = read_str(
        "w.obj",
        "f 1 2 3\nv 0 0 0 2\nv 2 0 0 2\nv 0 4 0 2\nv 0 0 6 2\nf -4 -3 -1\n",
    );
    assert_aabb(&mesh, [0., 0., 0.], [1., 2., 3.], 0.0, "w");
    assert_eq!(mesh.triangles.len(), 2);
    let mesh = read_str("rgb.obj", "v 0 0 0 1 0 0\nv 1 0 0 1 0 0\nv 0 1 0 1 0 0\nv 9 9 9 1 0 0\nf 1 2 3\n");
    assert_aabb(&mesh, [0., 0., 0.], [1., 1., 0.], 0.0, "rgb");
}

#[test]
fn obj_degenerate_faces_and_unused_vertices_are_dropped_like_coal() {
    // coal reads this as 3 vertices, 1 triangle, AABB [0 0 0] [1 1 0]
    let mesh = read_str(
        "degenerate.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nv 7 7 7\nv -3 -3 -3\nv 0 0 0\n\
         f 1 2 3\nf 4 4 4\nf 1 1 5\nf 1 7 5\nf 1 2\nl 1 6\n",
    );
    assert_eq!(mesh.triangles.len(), 1);
    assert_eq!(mesh.vertices.len(), 3);
    assert_aabb(&mesh, [0., 0., 0.], [1., 1., 0.], 0.0, "degenerate");
}

#[test]
fn obj_errors_name_the_file_and_the_problem() {
    let cases = [
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n", "vertex index 0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n", "refers to vertex 4 but the file has 3 vertices"),
        ("v 0 0 0\nv 1 0 0\nf -1 -2 -3\n", "line 3: relative vertex index -3 reaches before the first vertex"),
        ("v 0 0 0\nv 1 0 x\nv 0 1 0\nf 1 2 3\n", "line 2: bad number 'x'"),
        ("v 0 0\n", "line 1: 'v' needs 3 (x y z), 4 (x y z w) or 6 (x y z r g b) numbers, got 2"),
        ("v 0 0 0 0\n", "line 1: vertex weight w is 0"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 a/1\n", "line 4: bad vertex reference 'a/1'"),
        ("v 0 0 0\nv 1 0 0\nv 0 1 0\n", "no triangles"),
        ("v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n", "vertex 1 is not finite"),
        ("v 0 0 0\nv 1 0 1e999\nv 0 1 0\nf 1 2 3\n", "not finite"),
        ("", "no triangles"),
    ];
    for (text, expected) in cases {
        let msg = error_of("bad.obj", text);
        assert!(msg.contains(expected), "{text:?}: {msg}");
    }
}

// ---------------------------------------------------------------------------------------------
// COLLADA

/// One tetrahedron geometry with the given asset settings and node contents.
fn simple_dae(asset: &str, node: &str) -> String {
    format!(
        r##"<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
  <asset>{asset}</asset>
  <library_geometries>
    <geometry id="g" name="g"><mesh>
      <source id="p"><float_array id="pa" count="12">1 2 3  4 2 3  1 5 3  1 2 7</float_array>
        <technique_common><accessor source="#pa" count="4" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
      <vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
      <triangles count="4"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 0 1 3 0 2 3 1 2 3</p></triangles>
    </mesh></geometry>
  </library_geometries>
  <library_visual_scenes><visual_scene id="S">
    <node id="n">{node}<instance_geometry url="#g"/></node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#S"/></scene>
</COLLADA>"##
    )
}

/// Geometry of a file exercising node nesting, every transform element, `<instance_node>`,
/// `<polylist>` (a 2-corner polygon included), `<polygons>`, a VERTEX input at offset 1 and an
/// accessor with offset, stride 4 and an unnamed parameter; COLLADA 1.5 namespace.
const COMPLEX_DAE: &str = r##"<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2008/03/COLLADASchema" version="1.5.0">
  <asset><unit meter="0.01"/><up_axis>Y_UP</up_axis></asset>
  <library_geometries>
    <geometry id="quad"><mesh>
      <source id="qp"><float_array id="qpa" count="16">99 0 0 0  1 0 0 0  1 1 0 0  0 1 0 0  0 0 0 0</float_array>
        <technique_common><accessor source="#qpa" count="3" offset="4" stride="4"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/><param type="float"/></accessor></technique_common></source>
      <source id="qn"><float_array id="qna" count="3">0 0 1</float_array>
        <technique_common><accessor source="#qna" count="1" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
      <vertices id="qv"><input semantic="POSITION" source="#qp"/></vertices>
      <polylist count="2"><input semantic="NORMAL" source="#qn" offset="0"/><input semantic="VERTEX" source="#qv" offset="1"/>
        <vcount>3 2</vcount><p>0 0 0 1 0 2  0 0 0 1</p></polylist>
    </mesh></geometry>
    <geometry id="tet"><mesh>
      <source id="tp"><float_array id="tpa" count="12">0 0 0 2 0 0 0 3 0 0 0 4</float_array>
        <technique_common><accessor source="#tpa" count="4" stride="3"><param name="X" type="float"/><param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
      <vertices id="tv"><input semantic="POSITION" source="#tp"/></vertices>
      <polygons count="2"><input semantic="VERTEX" source="#tv" offset="0"/><p>0 1 2 3</p><p>1 2 3</p></polygons>
      <lines count="1"><input semantic="VERTEX" source="#tv" offset="0"/><p>0 1</p></lines>
    </mesh></geometry>
  </library_geometries>
  <library_nodes>
    <node id="lib"><translate>0 0 100</translate><instance_geometry url="#tet"/></node>
  </library_nodes>
  <library_visual_scenes><visual_scene id="S">
    <node id="a"><translate>10 0 0</translate><rotate>0 0 1 90</rotate><scale>2 2 2</scale>
      <instance_geometry url="#quad"/>
      <node id="b"><matrix>1 0 0 5  0 1 0 6  0 0 1 7  0 0 0 1</matrix><instance_node url="#lib"/></node>
    </node>
  </visual_scene></library_visual_scenes>
  <scene><instance_visual_scene url="#S"/></scene>
</COLLADA>"##;

#[test]
fn dae_node_transforms_instance_node_polylist_polygons_like_coal() {
    let mesh = read_str("complex.dae", COMPLEX_DAE);
    // coal: 7 vertices, 4 triangles, exactly these positions (to float precision)
    let expected = [
        p(10., 2., 0.),
        p(8., 2., 0.),
        p(8., 0., 0.),
        p(-2., 10., 214.),
        p(-2., 14., 214.),
        p(-8., 10., 214.),
        p(-2., 10., 222.),
    ];
    assert_eq!(mesh.vertices.len(), 7);
    assert_eq!(mesh.triangles.len(), 4);
    for (v, e) in mesh.vertices.iter().zip(&expected) {
        assert_close(v, e, 1e-12, "complex.dae vertex");
    }
    // polygon fan: (0 1 2 3) -> (0 1 2), (0 2 3); then (1 2 3)
    assert_eq!(mesh.triangles, vec![[0, 1, 2], [3, 4, 5], [3, 5, 6], [4, 5, 6]]);

    // the same file with the COLLADA settings applied: x 0.01, then Y-up (x, y, z) -> (x, -z, y)
    let path = write("complex.dae", COMPLEX_DAE.as_bytes());
    let spec = read_mesh_with(&path, &ReadOptions::COLLADA_SPEC).unwrap();
    for (v, e) in spec.vertices.iter().zip(&expected) {
        assert_close(v, &(p(e.x, -e.z, e.y) * 0.01), 1e-12, "complex.dae, spec");
    }
}

#[test]
fn dae_tristrips_trifans_and_polygons_with_holes() {
    let tet = simple_dae("", "");
    let with = |prim: &str| {
        tet.replace(
            "<triangles count=\"4\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><p>0 1 2 0 1 3 0 2 3 1 2 3</p></triangles>",
            prim,
        )
    };
    // coal: triangles (0 1 2), (2 1 3) for the strip; (0 1 2), (0 2 3) for the fan
    let strip = read_str("strip.dae", &with(r##"<tristrips count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 3</p></tristrips>"##));
    assert_eq!(strip.triangles, vec![[0, 1, 2], [2, 1, 3]]);
    let fan = read_str("fan.dae", &with(r##"<trifans count="1"><input semantic="VERTEX" source="#v" offset="0"/><p>0 1 2 3</p></trifans>"##));
    assert_eq!(fan.triangles, vec![[0, 1, 2], [0, 2, 3]]);
    // <ph>: the outer boundary <p> is read, holes (inside it) are ignored; assimp refuses <ph>
    let holes = read_str(
        "holes.dae",
        &with(r##"<polygons count="2"><input semantic="VERTEX" source="#v" offset="0"/><ph><p>0 1 2</p><h>3 1 2</h></ph><p>0 1 3</p></polygons>"##),
    );
    assert_eq!(holes.triangles, vec![[0, 1, 2], [0, 1, 3]]);
}

#[test]
fn dae_unit_and_up_axis_are_ignored_by_default_like_coal() {
    // coal reads all of these as AABB [1 2 3] [4 5 7]
    for asset in [
        "",
        "<up_axis>Z_UP</up_axis>",
        "<up_axis>Y_UP</up_axis>",
        "<up_axis>X_UP</up_axis>",
        r#"<unit meter="0.001" name="mm"/><up_axis>Z_UP</up_axis>"#,
        r#"<unit meter="0.001" name="mm"/><up_axis>Y_UP</up_axis>"#,
    ] {
        let mesh = read_str("tet.dae", &simple_dae(asset, ""));
        assert_aabb(&mesh, [1., 2., 3.], [4., 5., 7.], 0.0, asset);
        assert_eq!((mesh.vertices.len(), mesh.triangles.len()), (4, 4));
    }
    // node transforms are applied (coal: [11 22 33] [14 25 37], and [-5 11 3] [-2 14 7])
    let mesh = read_str("tet.dae", &simple_dae("<up_axis>Y_UP</up_axis>", "<translate>10 20 30</translate>"));
    assert_aabb(&mesh, [11., 22., 33.], [14., 25., 37.], 0.0, "translate");
    let mesh = read_str("tet.dae", &simple_dae("", "<rotate>0 0 1 90</rotate><translate>10 0 0</translate>"));
    assert_aabb(&mesh, [-5., 11., 3.], [-2., 14., 7.], 1e-12, "rotate then translate");
}

#[test]
fn dae_unit_scale_and_up_axis_with_spec_options() {
    let read = |asset: &str, options: ReadOptions| {
        let path = write("tet.DAE", simple_dae(asset, "").as_bytes());
        read_mesh_with(&path, &options).unwrap()
    };
    let unit_only = ReadOptions {
        collada_unit: true,
        collada_up_axis: false,
    };
    let up_only = ReadOptions {
        collada_unit: false,
        collada_up_axis: true,
    };
    let mm = r#"<unit meter="0.001" name="mm"/><up_axis>Z_UP</up_axis>"#;
    assert_aabb(&read(mm, unit_only), [1e-3, 2e-3, 3e-3], [4e-3, 5e-3, 7e-3], 1e-15, "mm");
    assert_aabb(&read(mm, ReadOptions::COLLADA_SPEC), [1e-3, 2e-3, 3e-3], [4e-3, 5e-3, 7e-3], 1e-15, "mm, Z_UP");
    // Z_UP: unchanged; Y_UP (and no <up_axis>, the default): (x, y, z) -> (x, -z, y);
    // X_UP: (x, y, z) -> (-y, -z, x)
    assert_aabb(&read("<up_axis>Z_UP</up_axis>", up_only), [1., 2., 3.], [4., 5., 7.], 0.0, "Z_UP");
    assert_aabb(&read("<up_axis>Y_UP</up_axis>", up_only), [1., -7., 2.], [4., -3., 5.], 0.0, "Y_UP");
    assert_aabb(&read("", up_only), [1., -7., 2.], [4., -3., 5.], 0.0, "default Y_UP");
    assert_aabb(&read("<up_axis>X_UP</up_axis>", up_only), [-5., -7., 1.], [-2., -3., 4.], 0.0, "X_UP");
    assert_aabb(
        &read(r#"<unit meter="2"/><up_axis>X_UP</up_axis>"#, ReadOptions::COLLADA_SPEC),
        [-10., -14., 2.],
        [-4., -6., 8.],
        0.0,
        "X_UP, x2",
    );
    // the settings are only checked when used
    let odd = r#"<unit meter="-1"/><up_axis>W_UP</up_axis>"#;
    read(odd, ReadOptions::default());
    for options in [unit_only, up_only] {
        let path = write("odd.dae", simple_dae(odd, "").as_bytes());
        let e = read_mesh_with(&path, &options).unwrap_err().to_string();
        assert!(e.contains("meter=\"-1\"") || e.contains("W_UP"), "{e}");
    }
}

#[test]
fn dae_errors_name_the_file_and_the_problem() {
    let ok = simple_dae("", "");
    let cases: Vec<(String, &str)> = vec![
        (ok.replace("<p>0 1 2 0 1 3", "<p>0 1 4 0 1 3"), "index 4 out of range (4 positions)"),
        (ok.replace("1 2 3  4 2 3", "1 2 3  4 two 3"), "<float_array id=\"pa\">: bad number 'two'"),
        (ok.replace("1 2 3  4 2 3", "1 2 3  4 NaN 3"), "is not finite"),
        (ok.replace("1 2 3  4 2 3", "1 2 3  4 2"), "accessor needs 12 numbers, <float_array id=\"pa\"> has 11"),
        (ok.replace("<p>0 1 2 0 1 3 0 2 3 1 2 3</p>", "<p>0 1 2 0 1</p>"), "not a multiple of 3"),
        (ok.replace("<p>0 1 2 0 1 3 0 2 3 1 2 3</p>", "<p>0 1 -2</p>"), "bad number '-2'"),
        (ok.replace("<instance_geometry url=\"#g\"/>", ""), "no triangles"),
        (ok.replace("url=\"#g\"", "url=\"#nope\""), "url=\"#nope\": no element has that id"),
        (ok.replace("url=\"#g\"", "url=\"other.dae#g\""), "only references inside the file"),
        (ok.replace("url=\"#g\"", "url=\"#v\""), "names a <vertices>, expected <geometry>"),
        (ok.replace("semantic=\"VERTEX\"", "semantic=\"POSITION\""), "has no VERTEX input"),
        (ok.replace("offset=\"0\"", "offset=\"99999999999999999999\""), "not an index below 65536"),
        (ok.replace("stride=\"3\"", "stride=\"2\""), "accessor stride 2 cannot hold x, y and z"),
        (ok.replace("<node id=\"n\">", "<node id=\"n\"><matrix>1 0 0</matrix>"), "<matrix>: expected 16 numbers, got 3"),
        (ok.replace("<node id=\"n\">", "<node id=\"n\"><rotate>0 0 0 30</rotate>"), "rotation axis 0 0 0 has no direction"),
        (ok.replace("<node id=\"n\">", "<node id=\"n\"><lookat>0 0 0 1 0 0 0 0 1</lookat>"), "<lookat> transforms are not supported"),
        (ok.replace("<instance_geometry url=\"#g\"/>", "<instance_node url=\"#n\"/>"), "<instance_node> cycle"),
        (ok.replace("<mesh>", "<convex_mesh>").replace("</mesh>", "</convex_mesh>"), "has no <mesh>"),
        (ok.replace("</COLLADA>", ""), "not well-formed XML"),
        ("<scene/>".to_string(), "not <COLLADA>"),
        (
            ok.replace("<scene><instance_visual_scene url=\"#S\"/></scene>", "")
                .replace("<visual_scene id=\"S\">", "<visual_scene id=\"S\"></visual_scene><visual_scene id=\"T\">"),
            "no triangles",
        ),
    ];
    for (text, expected) in &cases {
        let msg = error_of("bad.dae", text);
        assert!(msg.contains(expected), "expected '{expected}' in: {msg}");
    }
    // polylist: <vcount> must add up to the <p> length
    let poly = ok.replace(
        "<triangles count=\"4\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><p>0 1 2 0 1 3 0 2 3 1 2 3</p></triangles>",
        "<polylist count=\"2\"><input semantic=\"VERTEX\" source=\"#v\" offset=\"0\"/><vcount>4 4</vcount><p>0 1 2 3 0 1 2</p></polylist>",
    );
    let msg = error_of("bad.dae", &poly);
    assert!(msg.contains("<vcount> adds up to 8 vertices but <p> has 7"), "{msg}");
    // no <scene>: the first visual scene is used
    let no_scene = ok.replace("<scene><instance_visual_scene url=\"#S\"/></scene>", "");
    assert_eq!(read_str("noscene.dae", &no_scene).triangles.len(), 4);
}

// ---------------------------------------------------------------------------------------------
// STL, dispatch

#[test]
fn stl_binary_and_ascii_give_stl_io_result() {
    let n = stl_io::Normal::new([0.0, 0.0, 1.0]);
    let tris = [
        stl_io::Triangle {
            normal: n,
            vertices: [
                stl_io::Vertex::new([0.0, 0.0, 0.0]),
                stl_io::Vertex::new([1.5, 0.0, 0.0]),
                stl_io::Vertex::new([0.0, 0.25, 0.0]),
            ],
        },
        stl_io::Triangle {
            normal: n,
            vertices: [
                stl_io::Vertex::new([0.0, 0.0, 0.0]),
                stl_io::Vertex::new([0.0, 0.25, 0.0]),
                stl_io::Vertex::new([0.1, 0.2, -0.3]),
            ],
        },
    ];
    let mut binary = Vec::new();
    stl_io::write_stl(&mut binary, tris.iter()).unwrap();
    let ascii = "solid t\n\
        facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 1.5 0 0\n  vertex 0 0.25 0\n endloop\nendfacet\n\
        facet normal 0 0 1\n outer loop\n  vertex 0 0 0\n  vertex 0 0.25 0\n  vertex 0.1 0.2 -0.3\n endloop\nendfacet\n\
        endsolid t\n";
    for (name, bytes) in [("b.stl", binary.clone()), ("a.STL", ascii.as_bytes().to_vec())] {
        let path = write(name, &bytes);
        let mesh = read_mesh(&path).unwrap();
        let reference = stl_io::read_stl(&mut std::io::Cursor::new(bytes)).unwrap();
        let vertices: Vec<Point3<f64>> =
            reference.vertices.iter().map(|v| p(v[0] as f64, v[1] as f64, v[2] as f64)).collect();
        let triangles: Vec<[u32; 3]> = reference.faces.iter().map(|f| f.vertices.map(|i| i as u32)).collect();
        assert_eq!(mesh, Mesh { vertices, triangles }, "{name}");
        assert_eq!(mesh.vertices.len(), 4);
    }
    let msg = error_of("bad.stl", "solid x\nfacet normal 0 0 1\n outer loop\n  vertex 0 0\n");
    assert!(msg.contains("not a valid STL file"), "{msg}");
}

#[test]
fn extension_dispatch_and_file_errors() {
    let msg = error_of("mesh.ply", "ply\n");
    assert!(msg.contains("unsupported mesh format (extension '.ply'); supported: .stl, .obj, .dae"), "{msg}");
    let msg = error_of("mesh", "v 0 0 0\n");
    assert!(msg.contains("(no extension)"), "{msg}");
    // case-insensitive extensions
    let mesh = read_str("UPPER.OBJ", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    assert_eq!(mesh.triangles.len(), 1);
    assert_eq!(read_str("UPPER.Dae", &simple_dae("", "")).triangles.len(), 4);
    // a missing file is an I/O error naming it
    let missing = std::env::temp_dir().join("genplan-mesh-test-missing/none.dae");
    let e = read_mesh(&missing).unwrap_err();
    assert!(matches!(e, Error::Io { .. }) && e.to_string().contains("none.dae"), "{e}");
}

// ---------------------------------------------------------------------------------------------
// example-robot-data, compared with coal

/// Axis-aligned boxes and triangle counts of example-robot-data meshes as coal 3.0.3 (assimp
/// 6.0.5) reads them, relative to the robots/ folder, obtained with
/// `cd <robots> && .venv/bin/python -c "import coal, numpy as np, sys; m = coal.MeshLoader().load(sys.argv[1]);
/// v = np.array(m.vertices()); print(v.min(0), v.max(0), m.num_tris)" FILE`.
/// coal works in single precision, hence the 1e-6 relative tolerance below.
const COAL_REFERENCE: &[(&str, [f64; 3], [f64; 3], usize)] = &[
    // a scaling <matrix> node (x 9.99987e-4) with a translation
    ("kinova_description/meshes/jaco_mounting_block.dae", [-0.0199997406, -0.0199997406, -4.04442403e-07], [0.0199997406, 0.0199997406, 0.045998998], 2348),
    ("kinova_description/meshes/jaco_front_hatch_support_v2.dae", [5.9603833e-10, -0.0544992909, -0.0206033532], [0.0879522786, 0.0544992909, 0.0628475696], 5378),
    ("kinova_description/meshes/hand_2finger.dae", [-0.0315002687, -0.0542660914, -0.120398], [0.0315002687, 0.0542660914, 0.0], 44578),
    ("kinova_description/meshes/arm.dae", [-0.0412499905, -0.451249987, -0.0430004001], [0.0412499905, 0.0412499905, 0.0], 8194),
    ("kinova_description/meshes/ring_small.dae", [-0.0340499207, -0.0339336284, -0.00974994805], [0.0340499207, 0.0339336284, 0.00974994805], 452),
    ("kinova_description/meshes/base.dae", [-0.0412499905, -0.0412499905, 0.0], [0.0412499905, 0.0412499905, 0.156749994], 16744),
    ("ur_description/meshes/ur5/visual/forearm.dae", [-0.0579997785, -0.0571999513, -0.0579997301], [0.0579997301, 0.0544999801, 0.43118], 21022),
    // Y_UP file: coal does not rotate it
    ("tiago_description/meshes/arm/arm_1_collision.dae", [-0.0515000001, -0.0515000001, -0.082882598], [0.176092997, 0.087458998, 0.0379999988], 92),
    ("quadruped_description/urdf/cylinder.obj", [-1.0, -1.00173926, -0.503487587], [1.0, 1.00173926, 0.503487587], 32),
    ("quadruped_description/urdf/sphere.obj", [-1.0, -1.0, -1.0], [1.0, 1.0, 1.0], 80),
    ("quadruped_description/urdf/cube.obj", [-0.5, -0.5, -0.5], [0.5, 0.5, 0.5], 12),
    ("laikago_description/meshes/trunk.obj", [-0.281099975, -0.192999989, -0.0769999996], [0.294800013, 0.192999989, 0.110800013], 22246),
    // STL: same box; coal drops degenerate triangles (1050 of them here), stl_io keeps them
    ("ur_description/meshes/ur5/collision/forearm.stl", [-0.0579122491, -0.0571760982, -0.0579855368], [0.058534015, 0.0545106791, 0.431279421], 1050),
];

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn example_robot_data_meshes_match_coal_bounding_boxes() {
    let root = find_robots_dir().unwrap();
    for &(file, lo, hi, triangles) in COAL_REFERENCE {
        let t = std::time::Instant::now();
        let mesh = read_mesh(&root.join(file)).unwrap_or_else(|e| panic!("{e}"));
        let elapsed = t.elapsed();
        let size = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        assert_aabb(&mesh, lo, hi, 1e-6 * size, file);
        if !file.ends_with(".stl") {
            assert_eq!(mesh.triangles.len(), triangles, "{file}");
        }
        println!("{file}: {} vertices, {} triangles, read in {elapsed:?}", mesh.vertices.len(), mesh.triangles.len());
    }
}

#[test]
#[ignore = "needs example-robot-data (scripts/test runs it)"]
fn every_example_robot_data_mesh_reads() {
    fn walk(dir: &Path, out: &mut Vec<PathBuf>) {
        for e in std::fs::read_dir(dir).unwrap().flatten() {
            let p = e.path();
            if p.is_dir() {
                walk(&p, out);
            } else if let Some(ext) = p.extension() {
                if ["stl", "obj", "dae"].contains(&ext.to_string_lossy().to_lowercase().as_str()) {
                    out.push(p);
                }
            }
        }
    }
    let mut files = Vec::new();
    walk(&find_robots_dir().unwrap(), &mut files);
    assert!(files.len() > 100, "{} mesh files", files.len());
    for f in &files {
        let mesh = read_mesh(f).unwrap_or_else(|e| panic!("{e}"));
        assert!(!mesh.triangles.is_empty(), "{}", f.display());
        assert!(mesh.vertices.iter().all(|v| v.iter().all(|c| c.is_finite())), "{}", f.display());
    }
}

// --- fuzz: any bytes in a mesh file give a mesh or an error, never a panic --------------------

mod fuzz {
    use super::*;
    use proptest::prelude::*;

    const OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1/1 2/2 4/4\nf -1 -2 -3\nf 1//1 3//3 4//4 2//2\n";

    /// The mesh a reader returns holds finite vertices and triangles indexing them.
    fn check(name: &str, bytes: &[u8]) -> Result<(), TestCaseError> {
        let f = write(name, bytes);
        let out = std::panic::catch_unwind(|| read_mesh(&f.0));
        let Ok(result) = out else { return Err(TestCaseError::fail(format!("read_mesh panicked on {name}"))) };
        if let Ok(mesh) = result {
            prop_assert!(mesh.vertices.iter().all(|v| v.coords.iter().all(|c| c.is_finite())));
            let n = mesh.vertices.len() as u32;
            prop_assert!(mesh.triangles.iter().all(|t| t.iter().all(|&i| i < n)));
        }
        Ok(())
    }

    /// `text` with a byte range cut out and some bytes replaced.
    fn mutated(text: &'static str) -> impl Strategy<Value = Vec<u8>> {
        let len = text.len();
        (0..=len, 0..=len, proptest::collection::vec((0..len.max(1), any::<u8>()), 0..6)).prop_map(move |(a, b, edits)| {
            let (a, b) = (a.min(b), a.max(b));
            let mut bytes = text.as_bytes().to_vec();
            for (i, byte) in edits {
                bytes[i] = byte;
            }
            bytes.drain(a..b);
            bytes
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 300, failure_persistence: None, ..ProptestConfig::default() })]

        #[test]
        fn obj_bytes_never_panic(bytes in mutated(OBJ)) {
            check("fuzz.obj", &bytes)?;
        }

        #[test]
        fn dae_bytes_never_panic(bytes in mutated(COMPLEX_DAE)) {
            check("fuzz.dae", &bytes)?;
        }

        #[test]
        fn stl_bytes_never_panic(bytes in proptest::collection::vec(any::<u8>(), 0..400)) {
            check("fuzz.stl", &bytes)?;
        }
    }
}
