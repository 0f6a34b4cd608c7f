//! Every numeric scene field with a NaN, infinite, zero, negative or absurd value is a
//! clear error naming the field (and the file), never a wrong image or a panic: one small
//! scene per field and bad value, loaded through the scene loader (meshes in memory, as in
//! `arpa::scene_file::fuzzing`). Each template also loads with a good value, so a failure
//! comes from the field under test.

use arpa::scene_file::fuzzing;
use arpa::scene_file::{LoadedScene, SceneFileError, load_scene_bytes};
use std::path::Path;

const LOOKAT: &str = r#"<lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>"#;
const LIGHT: &str = r#"<emitter type="point"><point name="position" value="0, 0, 3"/></emitter>"#;
const SHAPE: &str = r#"<shape type="rectangle"/>"#;

fn sensor(fov: &str, width: &str, height: &str, to_world: &str) -> String {
    format!(
        r#"<sensor type="perspective"><float name="fov" value="{fov}"/><transform name="to_world">{to_world}</transform>
<film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/></film></sensor>"#
    )
}

fn scene(sensor: &str, body: &str) -> String {
    format!("<scene version=\"3.0.0\">\n{sensor}\n{body}\n</scene>\n")
}

/// A scene with the default camera and `body`.
fn with(body: &str) -> String {
    scene(&sensor("45", "8", "6", LOOKAT), body)
}

fn load(xml: &str) -> Result<LoadedScene, SceneFileError> {
    load_scene_bytes(xml.as_bytes(), Path::new(fuzzing::SCENE_PATH), &[], &|_| Err(std::io::Error::other("no mesh files here")))
}

type Template = fn(&str) -> String;

/// (field named by the error, good value, bad values, the scene with the value in place)
const CASES: &[(&str, &str, &[&str], Template)] = &[
    ("fov", "45", &["nan", "inf", "-inf", "0", "-10", "180", "1e9", "1e-300"], |v| scene(&sensor(v, "8", "6", LOOKAT), &format!("{SHAPE}{LIGHT}"))),
    ("width", "8", &["0", "-1", "1000000000", "nan", "1e9"], |v| scene(&sensor("45", v, "6", LOOKAT), &format!("{SHAPE}{LIGHT}"))),
    ("height", "6", &["0", "-1", "1000000000", "inf"], |v| scene(&sensor("45", "8", v, LOOKAT), &format!("{SHAPE}{LIGHT}"))),
    ("to_world", "1 0 0 0  0 1 0 0  0 0 1 5  0 0 0 1", &["nan 0 0 0  0 1 0 0  0 0 1 5  0 0 0 1", "1 0 0 0  0 1 0 0  0 0 1 inf  0 0 0 1", "0 0 0 0  0 1 0 0  0 0 1 5  0 0 0 1", "1e300 0 0 0  0 1e300 0 0  0 0 1e300 0  0 0 0 1"], |v| {
        // the camera looks along +z from (0, 0, 5): turn it round with a second operation
        scene(&sensor("45", "8", "6", &format!(r#"<matrix value="{v}"/><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/>"#)), &format!("{SHAPE}{LIGHT}"))
    }),
    ("to_world", "0, 0, 5", &["nan, 0, 5", "0, inf, 5", "0, 0, 0"], |v| scene(&sensor("45", "8", "6", &format!(r#"<lookat origin="{v}" target="0, 0, 0" up="0, 1, 0"/>"#)), &format!("{SHAPE}{LIGHT}"))),
    ("to_world", "1", &["0", "nan", "-inf", "1e-120"], |v| with(&format!(r#"<shape type="rectangle"><transform name="to_world"><scale value="{v}"/></transform></shape>{LIGHT}"#))),
    ("to_world", "90", &["nan", "inf"], |v| with(&format!(r#"<shape type="cube"><transform name="to_world"><rotate y="1" angle="{v}"/></transform></shape>{LIGHT}"#))),
    ("to_world", "1", &["1e300"], |v| with(&format!(r#"<shape type="cube"><transform name="to_world"><translate x="1e30"/><scale value="{v}"/></transform></shape>{LIGHT}"#))),
    ("int_ior", "1.5", &["nan", "inf", "0", "-1.5", "1e-200"], |v| with(&format!(r#"<shape type="cube"><bsdf type="dielectric"><float name="int_ior" value="{v}"/><float name="ext_ior" value="1e200"/></bsdf></shape>{LIGHT}"#).replace("1e200", if v == "1e-200" { "1e200" } else { "1" }))),
    ("int_ior", "bk7", &["unobtainium"], |v| with(&format!(r#"<shape type="cube"><bsdf type="dielectric"><string name="int_ior" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("ext_ior", "1", &["nan", "-inf", "0", "-1"], |v| with(&format!(r#"<shape type="cube"><bsdf type="dielectric"><float name="ext_ior" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("intensity", "1", &["nan", "inf", "-1", "0", "1e39", "1, -1, 1"], |v| with(&format!(r#"{SHAPE}<emitter type="point"><rgb name="intensity" value="{v}"/></emitter>"#))),
    ("intensity", "1", &["nan", "-1", "0", "1e39"], |v| with(&format!(r#"{SHAPE}<emitter type="spot"><rgb name="intensity" value="{v}"/></emitter>"#))),
    ("irradiance", "1", &["nan", "-inf", "-1", "0", "1e39"], |v| with(&format!(r#"{SHAPE}<emitter type="directional"><spectrum name="irradiance" value="{v}"/></emitter>"#))),
    ("radiance", "1", &["nan", "inf", "-1", "1e39", "1, 1, -0.5"], |v| with(&format!(r#"<shape type="rectangle"><emitter type="area"><rgb name="radiance" value="{v}"/></emitter></shape>"#))),
    ("cutoff_angle", "30", &["nan", "inf", "0", "-5", "90.5", "180", "1e9"], |v| with(&format!(r#"{SHAPE}<emitter type="spot"><float name="cutoff_angle" value="{v}"/><float name="beam_width" value="0"/></emitter>"#))),
    ("beam_width", "20", &["nan", "-1", "31", "inf"], |v| with(&format!(r#"{SHAPE}<emitter type="spot"><float name="cutoff_angle" value="30"/><float name="beam_width" value="{v}"/></emitter>"#))),
    ("position", "0, 0, 3", &["nan, 0, 3", "0, inf, 3"], |v| with(&format!(r#"{SHAPE}<emitter type="point"><point name="position" value="{v}"/></emitter>"#))),
    ("position", "1", &["1e300"], |v| with(&format!(r#"{SHAPE}<emitter type="point"><point name="position" value="{v}, 0, 0"/><transform name="to_world"><scale value="1e10"/></transform></emitter>"#))),
    ("direction", "0, 0, -1", &["0, 0, 0", "nan, 0, 1", "0, -inf, 0"], |v| with(&format!(r#"{SHAPE}<emitter type="directional"><vector name="direction" value="{v}"/></emitter>"#))),
    ("radius", "1", &["nan", "inf", "0", "-1", "1e300", "1e-50"], |v| with(&format!(r#"<shape type="sphere"><float name="radius" value="{v}"/></shape>{LIGHT}"#))),
    ("center", "0, 0, 0", &["nan, 0, 0", "0, 0, -inf"], |v| with(&format!(r#"<shape type="sphere"><point name="center" value="{v}"/></shape>{LIGHT}"#))),
    ("reflectance", "0.5", &["nan", "-0.1", "1.5", "0.5, 0.5, inf"], |v| with(&format!(r#"<shape type="cube"><bsdf type="diffuse"><rgb name="reflectance" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("specular_reflectance", "1", &["nan", "-1", "2"], |v| with(&format!(r#"<shape type="cube"><bsdf type="conductor"><rgb name="specular_reflectance" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("specular_transmittance", "1", &["nan", "-1", "1.01"], |v| with(&format!(r#"<shape type="cube"><bsdf type="dielectric"><rgb name="specular_transmittance" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("diffuse_reflectance", "0.5", &["inf", "-0.5", "3"], |v| with(&format!(r#"<shape type="cube"><bsdf type="plastic"><rgb name="diffuse_reflectance" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("alpha", "0.1", &["nan", "-0.1", "-inf"], |v| with(&format!(r#"<shape type="cube"><bsdf type="roughconductor"><float name="alpha" value="{v}"/></bsdf></shape>{LIGHT}"#))),
    ("eta", "0.2", &["nan", "-1"], |v| with(&format!(r#"<shape type="cube"><bsdf type="conductor"><rgb name="eta" value="{v}"/></bsdf></shape>{LIGHT}"#))),
];

#[test]
fn bad_numeric_fields_are_errors_naming_the_field() {
    let mut checked = 0;
    for &(field, good, bad, template) in CASES {
        let xml = template(good);
        if let Err(e) = load(&xml) {
            panic!("{field} = {good} (good) does not load: {e}\n{xml}");
        }
        for &v in bad {
            let xml = template(v);
            let text = match load(&xml) {
                Ok(_) => panic!("{field} = {v} loaded\n{xml}"),
                Err(e) => e.to_string(),
            };
            assert!(text.contains(field), "{field} = {v}: the error does not name '{field}': {text}");
            assert!(text.contains(fuzzing::SCENE_PATH), "{field} = {v}: the error does not name the file: {text}");
            checked += 1;
        }
    }
    assert!(checked > 100, "{checked} cases");
}

const PLY_HEADER: &str = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n";

/// A binary PLY triangle whose third vertex is `p` with normal `n`.
fn binary_ply(p: [f32; 3], n: [f32; 3]) -> Vec<u8> {
    let mut b = PLY_HEADER.replace("ascii", "binary_little_endian").into_bytes();
    for v in [[0.0, 0.0, 0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 0.0, 0.0, 0.0, 1.0], [p[0], p[1], p[2], n[0], n[1], n[2]]] {
        v.iter().for_each(|x: &f32| b.extend(x.to_le_bytes()));
    }
    b.push(3);
    [0i32, 1, 2].iter().for_each(|i| b.extend(i.to_le_bytes()));
    b
}

/// Vertex positions and normals of PLY (ASCII: no NaN literal, but 1e39 overflows a float;
/// binary: any bits) and OBJ meshes.
#[test]
fn non_finite_mesh_vertices_are_errors_naming_the_mesh_and_vertex() {
    let ply = |p: &str, n: &str| format!("{PLY_HEADER}0 0 0 0 0 1\n1 0 0 0 0 1\n{p} {n}\n3 0 1 2\n").into_bytes();
    let obj = |p: &str, n: &str| format!("v 0 0 0\nv 1 0 0\nv {p}\nvn 0 0 1\nvn {n}\nf 1//1 2//1 3//2\n").into_bytes();
    type Mesh = fn(&[u8]) -> Result<LoadedScene, SceneFileError>;
    let (nan, inf) = (f32::NAN, f32::INFINITY);
    let cases: [(&str, Mesh, Vec<u8>, &str, &str); 12] = [
        ("ply", fuzzing::ply, ply("0 1 0", "0 0 1"), fuzzing::PLY_PATH, ""),
        ("ply", fuzzing::ply, ply("0 1e39 0", "0 0 1"), fuzzing::PLY_PATH, "vertex 2 has a non-finite position"),
        ("ply", fuzzing::ply, ply("0 1 0", "0 -1e39 1"), fuzzing::PLY_PATH, "vertex 2 has a non-finite normal"),
        ("binary ply", fuzzing::ply, binary_ply([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]), fuzzing::PLY_PATH, ""),
        ("binary ply", fuzzing::ply, binary_ply([nan, 1.0, 0.0], [0.0, 0.0, 1.0]), fuzzing::PLY_PATH, "vertex 2 has a non-finite position"),
        ("binary ply", fuzzing::ply, binary_ply([0.0, 1.0, -inf], [0.0, 0.0, 1.0]), fuzzing::PLY_PATH, "vertex 2 has a non-finite position"),
        ("binary ply", fuzzing::ply, binary_ply([0.0, 1.0, 0.0], [0.0, nan, 1.0]), fuzzing::PLY_PATH, "vertex 2 has a non-finite normal"),
        ("binary ply", fuzzing::ply, binary_ply([0.0, 1.0, 0.0], [inf, 0.0, 1.0]), fuzzing::PLY_PATH, "vertex 2 has a non-finite normal"),
        ("obj", fuzzing::obj, obj("0 1 0", "0 0 1"), fuzzing::OBJ_PATH, ""),
        ("obj", fuzzing::obj, obj("0 1 nan", "0 0 1"), fuzzing::OBJ_PATH, "non-finite position"),
        ("obj", fuzzing::obj, obj("-inf 1 0", "0 0 1"), fuzzing::OBJ_PATH, "non-finite position"),
        ("obj", fuzzing::obj, obj("0 1 0", "nan 0 1"), fuzzing::OBJ_PATH, "non-finite normal"),
    ];
    for (kind, run, file, path, needle) in cases {
        match run(&file) {
            Ok(_) => assert!(needle.is_empty(), "{kind} with a non-finite value loaded"),
            Err(e) => {
                let text = e.to_string();
                assert!(!needle.is_empty(), "{kind}: the good mesh failed: {text}");
                let name = path.rsplit('/').next().unwrap();
                assert!(text.contains(needle) && text.contains(name), "{kind}: expected '{needle}' and '{name}' in: {text}");
            }
        }
    }
}
