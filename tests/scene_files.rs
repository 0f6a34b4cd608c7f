//! The Mitsuba 3 scene-file loader (`arpa::scene_file`): every shared scene loads and
//! validates and matches the numbers in `shared/scenes/README.md`; every kind of bad input
//! is an error naming the file (and line) and the problem, never a panic.

use arpa::core::emit::emission::{Light, SpotFalloff};
use arpa::core::render::scene::{Material, Scattering, TriangleMesh};
use arpa::scene_file::{FovAxis, LoadedScene, SceneFileError, load_scene};
use glam::{Vec3, vec3};

mod common;
use common::shared_scenes;

fn load_shared(name: &str) -> Option<LoadedScene> {
    let dir = shared_scenes()?;
    let path = dir.join(name).join("scene.xml");
    Some(load_scene(&path, &[]).unwrap_or_else(|e| panic!("{name}: {e}")))
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

fn geometric_normal(m: &TriangleMesh, t: usize) -> Vec3 {
    let p = m.indices[t].map(|i| m.positions[i as usize]);
    (p[1] - p[0]).cross(p[2] - p[0]).normalize()
}

fn mesh<'a>(s: &'a LoadedScene, file: &str) -> &'a TriangleMesh {
    s.scene.meshes.iter().find(|m| m.name.starts_with(file)).unwrap_or_else(|| panic!("no mesh {file}"))
}

/// (scene, triangles, analytic lights, emissive meshes) from the README.
const SHARED: &[(&str, usize, usize, usize)] = &[
    ("caustic-glass", 88_066, 1, 0),
    ("water-caustic", 103_485, 1, 0),
    ("veach-bidir", 11_544, 0, 2),
    ("sponza-standin", 66_454, 1, 0),
    ("cornell-caustic", 5_144, 0, 1),
    ("crytek-sponza", 262_087, 1, 0),
];

/// Shared scenes the loader cannot read yet, with what the refusal must name (the file's
/// line and the element); once one loads, its entry fails the test and goes.
const REFUSED: &[(&str, &str)] = &[];

#[test]
fn every_shared_scene_loads_and_validates() {
    let Some(dir) = shared_scenes() else { return };
    let mut found = 0;
    for entry in std::fs::read_dir(&dir).unwrap() {
        let path = entry.unwrap().path().join("scene.xml");
        if !path.is_file() {
            continue;
        }
        found += 1;
        let name = path.parent().unwrap().file_name().unwrap().to_string_lossy().into_owned();
        if let Some((_, why)) = REFUSED.iter().find(|(n, _)| *n == name) {
            match load_scene(&path, &[]) {
                Err(e) => assert!(e.to_string().contains(why), "{name}: refused, but not naming '{why}': {e}"),
                Ok(_) => panic!("{name} loads now: remove it from REFUSED and check it like the others"),
            }
            eprintln!("{name}: refused as expected ({why})");
            continue;
        }
        let s = load_scene(&path, &[]).unwrap_or_else(|e| panic!("{name}: {e}"));
        s.scene.validate().unwrap_or_else(|e| panic!("{name}: {e}"));
        let emissive = s.scene.meshes.iter().filter(|m| m.emission.is_some()).count();
        eprintln!(
            "{name}: {} triangles, {} meshes, {} analytic lights, {emissive} emissive meshes, {}x{}, {} warnings",
            s.triangle_count(),
            s.scene.meshes.len(),
            s.scene.lights.len(),
            s.scene.camera.width,
            s.scene.camera.height,
            s.warnings.len()
        );
        for w in &s.warnings {
            eprintln!("  warning: {w}");
            assert!(!w.message.contains("ignored"), "{name}: a shared scene uses something the loader ignores: {w}");
        }
        if let Some(&(_, tris, lights, emitters)) = SHARED.iter().find(|(n, ..)| *n == name) {
            assert_eq!(s.triangle_count(), tris, "{name}: triangle count differs from the README");
            assert_eq!(s.scene.lights.len(), lights, "{name}: analytic lights");
            assert_eq!(emissive, emitters, "{name}: emissive meshes");
        }
    }
    assert!(found >= SHARED.len(), "only {found} scenes found in {}", dir.display());
}

#[test]
fn caustic_glass_matches_the_readme() {
    let Some(s) = load_shared("caustic-glass") else { return };
    assert_eq!(s.scene.lights.len(), 1);
    let Light::Spot(spot) = s.scene.lights[0] else { panic!("not a spot light: {:?}", s.scene.lights[0]) };
    assert!((spot.position - glam::DVec3::new(0.0, 5.0, 9.0)).length() < 1e-9);
    assert!((spot.intensity - glam::DVec3::new(139.81, 118.63, 105.38)).length() < 1e-9);
    assert!((spot.cutoff - 33.6899f64.to_radians()).abs() < 1e-9, "{}", spot.cutoff);
    assert!((spot.beam_width - 30.8251f64.to_radians()).abs() < 1e-9);
    assert_eq!(spot.falloff, SpotFalloff::LinearAngle);
    let want = glam::DVec3::new(-0.4744, -0.2135, -0.8540);
    assert!((spot.direction - want).length() < 2e-3, "{:?}", spot.direction);
    assert_eq!(mesh(&s, "meshes/mesh_00001.ply").indices.len(), 88_064);
    assert!(mesh(&s, "meshes/mesh_00001.ply").normals.is_some(), "the glass has per-vertex normals");
    assert_eq!(mesh(&s, "meshes/mesh_00002.ply").indices.len(), 2);
    let glass = s.scene.materials[mesh(&s, "meshes/mesh_00001.ply").material as usize];
    assert!(matches!(glass, Material::Dielectric { ior, roughness, .. } if (ior - 1.25).abs() < 1e-6 && roughness == 0.0), "{glass:?}");
    let floor = s.scene.materials[mesh(&s, "meshes/mesh_00002.ply").material as usize];
    assert_eq!(floor, Material::Diffuse { albedo: Vec3::splat(0.64) });
    let c = s.scene.camera;
    assert!(close(c.position, vec3(-5.5, 7.0, -5.5), 1e-6));
    let f = (c.target - c.position).normalize();
    assert!(close(f, (vec3(-4.75, 2.25, 0.0) - c.position).normalize(), 1e-5));
    assert!((c.vertical_fov - 43.6028f32.to_radians()).abs() < 1e-6);
    assert_eq!((c.width, c.height), (320, 180));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    assert_eq!(s.max_depth, Some(16));
}

#[test]
fn cornell_caustic_matches_the_readme() {
    let Some(s) = load_shared("cornell-caustic") else { return };
    let light = mesh(&s, "meshes/Light.ply");
    assert_eq!(light.emission, Some(vec3(40.0, 34.0, 26.0)));
    for t in 0..light.indices.len() {
        assert!(close(geometric_normal(light, t), -Vec3::Y, 1e-5), "the light must face down");
    }
    assert!(light.positions.iter().all(|p| (p.y - 1.99).abs() < 1e-5));
    assert_eq!(mesh(&s, "meshes/GlassSphere.ply").indices.len(), 5_120);
    let mirror = s.scene.materials[mesh(&s, "meshes/MirrorBox.ply").material as usize];
    assert_eq!(mirror, Material::Conductor { reflectance: Vec3::splat(0.95), roughness: 0.0 });
    let red = s.scene.materials[mesh(&s, "meshes/LeftWall.ply").material as usize];
    assert_eq!(red, Material::Diffuse { albedo: vec3(0.63, 0.065, 0.05) });
    let c = s.scene.camera;
    assert!(close(c.position, vec3(0.0, 1.0, 6.8), 1e-6) && close((c.target - c.position).normalize(), -Vec3::Z, 1e-6) && close(c.up, Vec3::Y, 1e-6));
    assert_eq!((c.width, c.height), (256, 256));
    assert!((c.vertical_fov - 19.5f32.to_radians()).abs() < 1e-6);
    // Image right is world +x (Mitsuba's camera +x is *left*).
    assert!(close(c.frame().unwrap().right, Vec3::X, 1e-6));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn water_caustic_matches_the_readme() {
    let Some(s) = load_shared("water-caustic") else { return };
    let Light::Spot(spot) = s.scene.lights[0] else { panic!("not a spot light") };
    assert!((spot.position - glam::DVec3::new(0.0, 1.995, 0.0)).length() < 1e-9);
    assert!((spot.direction - glam::DVec3::NEG_Y).length() < 1e-9);
    assert!((spot.cutoff - std::f64::consts::FRAC_PI_2).abs() < 1e-9);
    assert!((spot.intensity - glam::DVec3::splat(8.0)).length() < 1e-12);
    // Mesh000 asks for face normals; Mesh001 (the heightfield) keeps its smooth normals.
    assert!(mesh(&s, "meshes/Mesh000.ply").normals.is_none());
    assert!(mesh(&s, "meshes/Mesh001.ply").normals.is_some());
    assert_eq!(mesh(&s, "meshes/Mesh001.ply").indices.len(), 102_938);
    let c = s.scene.camera;
    assert!(close(c.position, vec3(0.0, 0.990944, 6.83879), 1e-5));
    assert!(close((c.target - c.position).normalize(), -Vec3::Z, 1e-5));
    assert!((c.vertical_fov - 19.5f32.to_radians()).abs() < 1e-6);
    let water = s.scene.materials[mesh(&s, "meshes/Mesh001.ply").material as usize];
    assert!(matches!(water, Material::Dielectric { ior, .. } if (ior - 1.8).abs() < 1e-6));
}

#[test]
fn veach_bidir_matches_the_readme() {
    let Some(s) = load_shared("veach-bidir") else { return };
    let l0 = mesh(&s, "meshes/Light0.ply");
    let l1 = mesh(&s, "meshes/Light1.ply");
    assert!((0..l0.indices.len()).all(|t| close(geometric_normal(l0, t), Vec3::Y, 1e-4)), "Light0 faces up");
    let n1 = vec3(0.0708, -0.4292, 0.9004).normalize();
    assert!((0..l1.indices.len()).all(|t| close(geometric_normal(l1, t), n1, 2e-3)), "Light1 faces the egg");
    assert_eq!(l1.emission, Some(vec3(12048.179, 8605.842, 6196.206)));
    assert_eq!(mesh(&s, "meshes/Mesh002.ply").indices.len(), 7_936);
    let lamp = s.scene.materials[mesh(&s, "meshes/Mesh007.ply").material as usize];
    assert!(matches!(lamp, Material::Conductor { roughness, .. } if (roughness - 0.25).abs() < 1e-6), "{lamp:?}");
    // RTPM's rule (linear roughness sqrt(alpha) = 0.5 at the cut-off) makes the lamp
    // diffuse, as in the scene RTPM and the paper rendered (Falcor roughness 0.51); its
    // albedo is the hemispherical average of the copper-like Fresnel reflectance.
    let want = |eta: f64, k: f64| arpa::core::propagate::fresnel::conductor_albedo(eta, k) as f32;
    let albedo = vec3(want(2.865601, 3.032326), want(2.119182, 2.056108), want(1.940077, 1.616293));
    assert_eq!(lamp.scattering(s.scene.roughness_cutoff), Scattering::Diffuse(albedo), "{lamp:?}");
    // Values from an independent complex-arithmetic Fresnel integrated by the midpoint rule
    // (Python, 200k steps); the normal-incidence reflectance would be (0.525, 0.393, 0.311).
    assert!(close(albedo, vec3(0.521392, 0.412529, 0.344283), 2e-6), "{albedo:?}");
    let c = s.scene.camera;
    assert!(close(c.position, vec3(16.2155, 4.05167, 0.0114864), 1e-4));
    assert!(close((c.target - c.position).normalize(), vec3(-0.99998, -0.00467, -0.00502), 1e-4));
    assert!((c.vertical_fov - 35f32.to_radians()).abs() < 1e-6);
    // The lamp's approximations are reported, with their line.
    assert!(s.warnings.iter().any(|w| w.message.contains("roughconductor") && w.line > 0), "{:?}", s.warnings);
}

#[test]
fn sponza_standin_and_overrides() {
    let Some(dir) = shared_scenes() else { return };
    let path = dir.join("sponza-standin/scene.xml");
    let s = load_scene(&path, &[("res_x".into(), "64".into()), ("res_y".into(), "48".into())]).unwrap();
    let Light::Point(p) = s.scene.lights[0] else { panic!("not a point light") };
    assert!((p.position - glam::DVec3::new(0.0, 6.5, 0.0)).length() < 1e-12);
    assert!((p.intensity - glam::DVec3::new(150.0, 140.0, 125.0)).length() < 1e-12);
    assert_eq!((s.scene.camera.width, s.scene.camera.height), (64, 48));
    assert!((s.scene.camera.vertical_fov - 50f32.to_radians()).abs() < 1e-6);
}

// ---- small synthetic scenes -------------------------------------------------------------

const CAMERA: &str = r#"<sensor type="perspective">
        <float name="fov" value="40"/>
        <string name="fov_axis" value="y"/>
        <transform name="to_world"><lookat origin="0, 1, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
        <film type="hdrfilm"><integer name="width" value="$w"/><integer name="height" value="24"/></film>
    </sensor>"#;

/// A scene with the camera, a point light and `body`.
fn scene_xml(body: &str) -> String {
    format!(
        "<?xml version=\"1.0\"?>\n<scene version=\"3.0.0\">\n    <default name=\"w\" value=\"32\"/>\n    {CAMERA}\n    <emitter type=\"point\"><point name=\"position\" x=\"0\" y=\"3\" z=\"0\"/><rgb name=\"intensity\" value=\"5\"/></emitter>\n{body}\n</scene>\n"
    )
}

/// Writes `files` into a temporary directory, then loads `scene.xml` from it.
fn load_in_tempdir(xml: &str, files: &[(&str, Vec<u8>)]) -> Result<LoadedScene, SceneFileError> {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in files {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, xml).unwrap();
    load_scene(&path, &[])
}

/// A binary little-endian PLY (every vertex normal +y when `normals`).
fn ply(positions: &[[f32; 3]], faces: &[&[i32]], normals: bool) -> Vec<u8> {
    ply_with_normal(positions, faces, normals.then_some([0.0, 1.0, 0.0]))
}

/// A binary little-endian PLY whose vertices all carry `normal`, if given.
fn ply_with_normal(positions: &[[f32; 3]], faces: &[&[i32]], normal: Option<[f32; 3]>) -> Vec<u8> {
    let normals = normal.is_some();
    let mut h = format!("ply\nformat binary_little_endian 1.0\ncomment test\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\n", positions.len());
    if normals {
        h += "property float nx\nproperty float ny\nproperty float nz\n";
    }
    h += &format!("element face {}\nproperty list uchar int vertex_indices\nend_header\n", faces.len());
    let mut b = h.into_bytes();
    for p in positions {
        p.iter().for_each(|v| b.extend(v.to_le_bytes()));
        if let Some(n) = normal {
            n.iter().for_each(|v| b.extend(v.to_le_bytes()));
        }
    }
    for f in faces {
        b.push(f.len() as u8);
        f.iter().for_each(|i| b.extend(i.to_le_bytes()));
    }
    b
}

const QUAD: [[f32; 3]; 4] = [[-1.0, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]];

fn ply_shape(file: &str) -> String {
    format!("    <shape type=\"ply\">\n        <string name=\"filename\" value=\"{file}\"/>\n    </shape>")
}

#[test]
fn ply_quads_are_triangulated_and_normals_kept() {
    let s = load_in_tempdir(&scene_xml(&ply_shape("q.ply")), &[("q.ply", ply(&QUAD, &[&[0, 1, 2, 3]], true))]).unwrap();
    let m = &s.scene.meshes[0];
    assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
    assert_eq!(m.normals.as_ref().unwrap()[0], Vec3::Y);
    // Winding (-x,-z) -> (-x,+z) -> (+x,+z): normal +y.
    assert!(close(geometric_normal(m, 0), Vec3::Y, 1e-6));
    assert_eq!(s.scene.materials[m.material as usize], Material::Diffuse { albedo: Vec3::splat(0.5) }, "Mitsuba's default bsdf");
    assert_eq!((s.scene.camera.width, s.scene.camera.height), (32, 24));
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
}

#[test]
fn builtin_shapes_transforms_and_materials() {
    let body = r#"
    <bsdf type="twosided" id="gold"><bsdf type="conductor"><string name="material" value="Au"/></bsdf></bsdf>
    <bsdf type="roughconductor" id="rough"><float name="alpha" value="0.7"/></bsdf>
    <bsdf type="plastic" id="plastic"><rgb name="diffuse_reflectance" value="0.2, 0.3, 0.4"/></bsdf>
    <shape type="rectangle">
        <transform name="to_world"><rotate x="1" angle="-90"/><scale value="2"/><translate y="-1"/></transform>
        <ref id="gold"/>
    </shape>
    <shape type="cube"><ref id="rough"/><transform name="to_world"><scale value="0.25"/></transform></shape>
    <shape type="sphere"><point name="center" x="1" y="0" z="0"/><float name="radius" value="0.5"/><ref id="plastic"/></shape>
    <shape type="rectangle">
        <transform name="to_world"><matrix value="0.1 0 0 0  0 0.1 0 1.9  0 0 0.1 0  0 0 0 1"/><rotate x="1" angle="90"/></transform>
        <emitter type="area"><rgb name="radiance" value="10"/></emitter>
    </shape>"#;
    let s = load_in_tempdir(&scene_xml(body), &[]).unwrap();
    let [floor, cube, sphere, light] = &s.scene.meshes[..] else { panic!("{} meshes", s.scene.meshes.len()) };
    // rotate -90° about x turns +z into +y; scale 2; translate down.
    assert!(close(geometric_normal(floor, 0), Vec3::Y, 1e-6));
    assert!(floor.positions.iter().all(|p| (p.y + 1.0).abs() < 1e-6 && (p.x.abs() - 2.0).abs() < 1e-6));
    assert!(matches!(s.scene.materials[floor.material as usize], Material::Conductor { reflectance, roughness: 0.0 } if reflectance.x == 1.0 && reflectance.z < 0.5));
    assert_eq!(cube.indices.len(), 12);
    assert!(cube.positions.iter().all(|p| p.abs().max_element() <= 0.25 + 1e-6));
    assert_eq!(s.scene.materials[cube.material as usize], Material::Conductor { reflectance: Vec3::ONE, roughness: 0.7 });
    assert_eq!(sphere.indices.len(), 5120);
    assert!(sphere.positions.iter().all(|p| ((*p - vec3(1.0, 0.0, 0.0)).length() - 0.5).abs() < 1e-5));
    assert_eq!(s.scene.materials[sphere.material as usize], Material::Diffuse { albedo: vec3(0.2, 0.3, 0.4) });
    // The light: scaled 0.1, moved to y = 1.9, then turned +90° about x: +z becomes -y.
    assert!(close(geometric_normal(light, 0), -Vec3::Y, 1e-5), "{:?}", geometric_normal(light, 0));
    assert_eq!(light.emission, Some(Vec3::splat(10.0)));
    let warned = |what: &str| s.warnings.iter().any(|w| w.message.contains(what));
    assert!(warned("roughconductor") && warned("plastic") && warned("not wrapped"), "{:?}", s.warnings);
}

#[test]
fn obj_meshes_and_fov_axis_x() {
    let obj = "v -1 0 -1\nv -1 0 1\nv 1 0 1\nv 1 0 -1\nvn 0 1 0\nf 1//1 2//1 3//1 4//1\n";
    let xml = scene_xml(r#"    <shape type="obj"><string name="filename" value="m.obj"/></shape>"#).replace(r#"<string name="fov_axis" value="y"/>"#, "");
    let s = load_in_tempdir(&xml, &[("m.obj", obj.as_bytes().to_vec())]).unwrap();
    assert_eq!(s.scene.meshes[0].indices.len(), 2);
    assert!(s.scene.meshes[0].normals.is_some());
    // Mitsuba's default fov_axis is x: 40° across 32 px, 24 px high.
    assert_eq!(s.fov_axis, FovAxis::X);
    let want = 2.0 * ((20f32.to_radians()).tan() * 24.0 / 32.0).atan();
    assert!((s.scene.camera.vertical_fov - want).abs() < 1e-6);
    let mut s = s;
    s.set_resolution(64, 64);
    assert!((s.scene.camera.vertical_fov - 40f32.to_radians()).abs() < 1e-6);
}

#[test]
fn unknown_properties_warn_with_their_line() {
    let body = "    <bsdf type=\"twosided\" id=\"w\"><bsdf type=\"diffuse\">\n        <float name=\"sparkle\" value=\"3\"/>\n    </bsdf></bsdf>\n    <shape type=\"cube\"><ref id=\"w\"/></shape>";
    let s = load_in_tempdir(&scene_xml(body), &[]).unwrap();
    let w = s.warnings.iter().find(|w| w.message.contains("sparkle")).unwrap_or_else(|| panic!("{:?}", s.warnings));
    assert_eq!(w.line, 12, "{w}");
    assert!(w.to_string().contains("scene.xml:12:"), "{w}");
}

// ---- one test per error kind --------------------------------------------------------------

fn expect_err(r: Result<LoadedScene, SceneFileError>) -> (SceneFileError, String) {
    let e = r.expect_err("the scene must not load");
    let s = e.to_string();
    eprintln!("error as reported: {s}");
    (e, s)
}

#[test]
fn malformed_xml_is_an_error_with_its_line() {
    let xml = scene_xml("    <shape type=\"cube\">\n    </shap>");
    let (e, s) = expect_err(load_in_tempdir(&xml, &[]));
    assert!(matches!(e, SceneFileError::Xml { line: 12, .. }), "{s}");
    assert!(s.contains("scene.xml:12") && s.contains("malformed XML"), "{s}");
    let (e, _) = expect_err(load_in_tempdir("<scene>\n<shape type=\"cube\">\n", &[]));
    assert!(matches!(e, SceneFileError::Xml { .. }));
}

#[test]
fn unknown_shape_type_names_element_and_line() {
    let (e, s) = expect_err(load_in_tempdir(&scene_xml("    <shape type=\"bsplinecurve\"/>"), &[]));
    assert!(matches!(e, SceneFileError::Unsupported { line: 11, .. }), "{s}");
    assert!(s.contains("<shape type=\"bsplinecurve\">") && s.contains(":11:"), "{s}");
    let (_, s) = expect_err(load_in_tempdir(&scene_xml("    <bsdf type=\"hair\" id=\"p\"/>"), &[]));
    assert!(s.contains("<bsdf type=\"hair\">") && s.contains(":11:"), "{s}");
    let (_, s) = expect_err(load_in_tempdir(&scene_xml("    <emitter type=\"envmap\"/>"), &[]));
    assert!(s.contains("<emitter type=\"envmap\">"), "{s}");
    let (_, s) = expect_err(load_in_tempdir(&scene_xml("    <shape type=\"cube\"><ref id=\"nope\"/></shape>"), &[]));
    assert!(s.contains("nope") && s.contains(":11:"), "{s}");
}

#[test]
fn missing_ply_file_names_the_file() {
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(&ply_shape("meshes/absent.ply")), &[]));
    assert!(matches!(e, SceneFileError::Io { .. }), "{s}");
    assert!(s.contains("absent.ply"), "{s}");
}

#[test]
fn truncated_ply_is_an_error() {
    let mut bytes = ply(&QUAD, &[&[0, 1, 2], &[0, 2, 3]], false);
    bytes.truncate(bytes.len() - 7);
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(&ply_shape("t.ply")), &[("t.ply", bytes)]));
    assert!(matches!(e, SceneFileError::Ply { .. }), "{s}");
    assert!(s.contains("t.ply") && s.contains("ends early"), "{s}");
    // Cut inside the vertices too, and a garbage header.
    let bytes = ply(&QUAD, &[&[0, 1, 2]], false);
    let cut = bytes.windows(11).position(|w| w == b"end_header\n").unwrap() + 20;
    let (_, s) = expect_err(load_in_tempdir(&scene_xml(&ply_shape("t.ply")), &[("t.ply", bytes[..cut].to_vec())]));
    assert!(s.contains("ends early"), "{s}");
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(&ply_shape("t.ply")), &[("t.ply", b"plyx\nformat what\n".to_vec())]));
    assert!(matches!(e, SceneFileError::Ply { .. }) && s.contains("t.ply"), "{s}");
    // An index past the vertices.
    let (_, s) = expect_err(load_in_tempdir(&scene_xml(&ply_shape("t.ply")), &[("t.ply", ply(&QUAD, &[&[0, 1, 9]], false))]));
    assert!(s.contains("vertex 9"), "{s}");
}

#[test]
fn nan_vertex_is_an_error() {
    let mut q = QUAD;
    q[2][1] = f32::NAN;
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(&ply_shape("n.ply")), &[("n.ply", ply(&q, &[&[0, 1, 2, 3]], false))]));
    assert!(matches!(e, SceneFileError::Mesh { .. }), "{s}");
    assert!(s.contains("n.ply") && s.contains("vertex 2") && s.contains("non-finite"), "{s}");
    let obj = "v 0 0 0\nv 1 0 nan\nv 0 1 0\nf 1 2 3\n";
    let xml = scene_xml(r#"    <shape type="obj"><string name="filename" value="n.obj"/></shape>"#);
    let (_, s) = expect_err(load_in_tempdir(&xml, &[("n.obj", obj.as_bytes().to_vec())]));
    assert!(s.contains("n.obj") && s.contains("non-finite"), "{s}");
}

#[test]
fn zero_area_emitter_is_an_error() {
    let flat = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
    let body = "    <shape type=\"ply\">\n        <string name=\"filename\" value=\"z.ply\"/>\n        <emitter type=\"area\"><rgb name=\"radiance\" value=\"1, 1, 1\"/></emitter>\n    </shape>";
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(body), &[("z.ply", ply(&flat, &[&[0, 1, 2]], false))]));
    assert!(matches!(e, SceneFileError::Mesh { line: 11, .. }), "{s}");
    assert!(s.contains("z.ply") && s.contains("zero total area"), "{s}");
}

#[test]
fn bad_variable_is_an_error() {
    let xml = scene_xml("    <shape type=\"cube\"><float name=\"x\" value=\"$undefined_thing\"/></shape>");
    let (e, s) = expect_err(load_in_tempdir(&xml, &[]));
    assert!(matches!(e, SceneFileError::UndefinedVariable { line: 11, ref name, .. } if name == "undefined_thing"), "{s}");
    // A substituted value that is not a number.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.xml");
    std::fs::write(&path, scene_xml("    <shape type=\"cube\"/>")).unwrap();
    let e = load_scene(&path, &[("w".into(), "wide".into())]).unwrap_err().to_string();
    assert!(e.contains("wide") && e.contains("scene.xml:"), "{e}");
    assert!(load_scene(&path, &[("w".into(), "48".into())]).is_ok());
}

#[test]
fn malformed_obj_is_an_error() {
    let xml = scene_xml(r#"    <shape type="obj"><string name="filename" value="b.obj"/></shape>"#);
    for (obj, what) in [("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n", "vertex"), ("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 x\n", "cannot parse"), ("v 0 0 0\n", "no faces")] {
        let (e, s) = expect_err(load_in_tempdir(&xml, &[("b.obj", obj.as_bytes().to_vec())]));
        assert!(matches!(e, SceneFileError::Obj { .. }), "{obj:?}: {s}");
        assert!(s.contains("b.obj") && s.contains(what), "{obj:?}: {s}");
    }
}

#[test]
fn invalid_values_are_errors_with_their_line() {
    let spot = "    <emitter type=\"spot\">\n        <float name=\"cutoff_angle\" value=\"20\"/><float name=\"beam_width\" value=\"30\"/>\n    </emitter>";
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(spot), &[]));
    assert!(matches!(e, SceneFileError::Invalid { line: 11, .. }), "{s}");
    assert!(s.contains("beam_width") && s.contains("scene.xml:11"), "{s}");
    let metal = r#"    <shape type="cube"><bsdf type="conductor"><rgb name="eta" value="-1, 1, 1"/><rgb name="k" value="1"/></bsdf></shape>"#;
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(metal), &[]));
    assert!(matches!(e, SceneFileError::Invalid { line: 11, .. }) && s.contains("eta"), "{s}");
    let (e, s) = expect_err(load_in_tempdir(&scene_xml(r#"    <shape type="sphere"><float name="radius" value="0"/></shape>"#), &[]));
    assert!(matches!(e, SceneFileError::Invalid { line: 11, .. }) && s.contains("radius"), "{s}");
}

#[test]
fn bad_define_is_an_error() {
    let e = arpa::scene_file::parse_define("res_x").unwrap_err();
    assert!(matches!(e, SceneFileError::BadDefine(_)) && e.to_string().contains("res_x"), "{e}");
}

#[test]
fn conductor_eta_k_uses_the_fresnel_albedo() {
    // Gold-like eta/k: the albedo (hemispherical Fresnel average), not F0.
    let body = r#"    <shape type="cube"><bsdf type="conductor"><rgb name="eta" value="0.2, 0.5, 1.4"/><rgb name="k" value="3.6, 2.3, 1.8"/></bsdf></shape>"#;
    let s = load_in_tempdir(&scene_xml(body), &[]).unwrap();
    let Material::Conductor { reflectance, roughness } = s.scene.materials[s.scene.meshes[0].material as usize] else { panic!() };
    assert_eq!(roughness, 0.0);
    let a = |eta: f64, k: f64| arpa::core::propagate::fresnel::conductor_albedo(eta, k) as f32;
    assert_eq!(reflectance, vec3(a(0.2, 3.6), a(0.5, 2.3), a(1.4, 1.8)));
    assert!(s.warnings.iter().any(|w| w.message.contains("hemispherical average")), "{:?}", s.warnings);
}

#[test]
fn roughness_cutoff_is_rtpms_linear_roughness_half() {
    // alpha 0.2 (linear roughness 0.447) stays a mirror; 0.25 (0.5) and 0.3 are diffuse.
    for (alpha, diffuse) in [(0.2, false), (0.25, true), (0.3, true)] {
        let body = format!(r#"    <shape type="cube"><bsdf type="roughconductor"><float name="alpha" value="{alpha}"/></bsdf></shape>"#);
        let s = load_in_tempdir(&scene_xml(&body), &[]).unwrap();
        let m = s.scene.materials[s.scene.meshes[0].material as usize];
        let got = m.scattering(s.scene.roughness_cutoff);
        assert_eq!(matches!(got, Scattering::Diffuse(_)), diffuse, "alpha {alpha}: {got:?}");
        assert!(s.warnings.iter().any(|w| w.message.contains(if diffuse { "rendered as diffuse" } else { "perfect specular" })), "{:?}", s.warnings);
    }
}

#[test]
fn tilted_vertex_normals_on_diffuse_meshes_warn() {
    // Normals lying in the plane of the quad (arpa and Mitsuba both shade with them: a
    // likely broken export is worth a warning).
    let s = load_in_tempdir(&scene_xml(&ply_shape("t.ply")), &[("t.ply", ply_with_normal(&QUAD, &[&[0, 1, 2, 3]], Some([1.0, 0.0, 0.0])))]).unwrap();
    let w = s.warnings.iter().find(|w| w.message.contains("vertex normals")).unwrap_or_else(|| panic!("{:?}", s.warnings));
    assert!(w.message.contains("t.ply") && w.message.contains("100.0 %") && w.line == 11, "{w}");
    // 45° is fine, and so are tilted normals on a specular mesh (they are used there).
    let h = std::f32::consts::FRAC_1_SQRT_2;
    let s = load_in_tempdir(&scene_xml(&ply_shape("t.ply")), &[("t.ply", ply_with_normal(&QUAD, &[&[0, 1, 2, 3]], Some([h, h, 0.0])))]).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let glass = "    <shape type=\"ply\"><string name=\"filename\" value=\"t.ply\"/><bsdf type=\"dielectric\"/></shape>";
    let s = load_in_tempdir(&scene_xml(glass), &[("t.ply", ply_with_normal(&QUAD, &[&[0, 1, 2, 3]], Some([1.0, 0.0, 0.0])))]).unwrap();
    assert!(!s.warnings.iter().any(|w| w.message.contains("vertex normals")), "{:?}", s.warnings);
}

#[test]
fn sponza_standin_warns_about_its_tilted_normals() {
    // About 18 % of the stand-in's area carries vertex normals 80-90° off their faces
    // (the Max2Obj export); Mitsuba's reference is shaded with them.
    let Some(s) = load_shared("sponza-standin") else { return };
    assert!(s.warnings.iter().any(|w| w.message.contains("sponza_dabrovic.ply") && w.message.contains("vertex normals more than 60")), "{:?}", s.warnings);
}

#[test]
fn scene_without_light_or_camera_is_an_error() {
    let xml = "<scene version=\"3.0.0\">\n<default name=\"w\" value=\"8\"/>\n".to_string() + CAMERA + "\n<shape type=\"cube\"/>\n</scene>";
    let (e, s) = expect_err(load_in_tempdir(&xml, &[]));
    assert!(matches!(e, SceneFileError::Scene { .. }) && s.contains("no light"), "{s}");
    let (_, s) = expect_err(load_in_tempdir("<scene version=\"3.0.0\"><shape type=\"cube\"/></scene>", &[]));
    assert!(s.contains("no <sensor"), "{s}");
}

#[test]
#[cfg(all(feature = "cpu", feature = "cli"))] // the `arpa` binary needs `cli`
fn cli_renders_a_scene_file() {
    let dir = tempfile::tempdir().unwrap();
    let body = "    <shape type=\"rectangle\"><transform name=\"to_world\"><rotate x=\"1\" angle=\"-90\"/><scale value=\"3\"/></transform></shape>\n    <shape type=\"sphere\"><float name=\"radius\" value=\"0.5\"/><bsdf type=\"dielectric\"/></shape>";
    let path = dir.path().join("s.xml");
    std::fs::write(&path, scene_xml(body)).unwrap();
    let out = dir.path().join("img");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_arpa"))
        .args(["render", path.to_str().unwrap(), "-D", "w=20", "--iterations", "1", "--photons", "5000", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "{err}");
    assert!(err.contains("5122 triangles") && err.contains("20x24"), "{err}");
    let image = arpa::image_io::read_exr(&dir.path().join("img.exr")).unwrap();
    assert_eq!((image.width, image.height), (20, 24));
    assert!(image.pixels.iter().any(|p| p.max_element() > 0.0), "black image");
    // --resolution overrides the film size.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_arpa"))
        .args(["render", path.to_str().unwrap(), "--resolution", "8x6", "--iterations", "1", "--photons", "2000", "--out", out.to_str().unwrap()])
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert_eq!(arpa::image_io::read_exr(&dir.path().join("img.exr")).unwrap().width, 8);
}

/// `tests/data/serialized/` holds serialized files written by its `make_fixtures.py` and
/// the vertices Mitsuba 3.9.1 reads from them (`mitsuba_values.py` → `mitsuba_values.json`):
/// the loader reads the same numbers.
#[test]
fn serialized_meshes_read_as_mitsuba_reads_them() {
    let data = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/serialized");
    let file = |name: &str| std::fs::read(data.join(name)).unwrap();
    let shape = |index: u32| scene_xml(&format!(r#"    <shape type="serialized"><string name="filename" value="m.serialized"/><integer name="shape_index" value="{index}"/></shape>"#));
    let s = load_in_tempdir(&shape(1), &[("m.serialized", file("two_shapes_v3.serialized"))]).unwrap();
    let m = mesh(&s, "m.serialized");
    let mitsuba = [vec3(0.1, 0.2, 0.3), vec3(2.5, -1.25, 0.0), vec3(0.0, 3.0, -4.0)];
    assert_eq!(m.positions, mitsuba);
    assert_eq!(m.indices, vec![[2, 0, 1]]);
    // The file stores no normals: Mitsuba computes smooth vertex normals, which on one flat
    // triangle are its face normal.
    let face = vec3(0.49976766, 0.7311087, 0.46444827);
    assert!(close(geometric_normal(m, 0), face, 1e-6), "{}", geometric_normal(m, 0));
    assert!(m.normals.as_ref().unwrap().iter().all(|n| close(*n, face, 1e-6)), "{:?}", m.normals);
    // Version 4, double precision, normals and uvs: Mitsuba's shape 0 of normals_uvs_v4.
    let s = load_in_tempdir(&shape(0), &[("m.serialized", file("normals_uvs_v4.serialized"))]).unwrap();
    let m = mesh(&s, "m.serialized");
    assert_eq!(m.positions, [vec3(0.1, 0.2, 0.3), vec3(1.1, 0.2, 0.3), vec3(1.1, 1.2, 0.3), vec3(0.1, 1.2, 0.3)]);
    // A shape the file does not hold is an error naming the file (Mitsuba fails too).
    let (_, msg) = expect_err(load_in_tempdir(&shape(2), &[("m.serialized", file("two_shapes_v3.serialized"))]));
    assert!(msg.contains("m.serialized") && msg.contains("shape_index 2 out of range"), "{msg}");
    let (_, msg) = expect_err(load_in_tempdir(&shape(0), &[("m.serialized", b"not a mesh".to_vec())]));
    assert!(msg.contains("m.serialized"), "{msg}");
}

/// Mesh files without normals get Mitsuba's smooth vertex normals (angle-weighted face
/// normals at shared vertices), unless `face_normals` is set; analytic shapes keep theirs.
#[test]
fn meshes_without_normals_get_smooth_normals_as_in_mitsuba() {
    // A roof: two triangles meeting at a right angle along the shared edge 0-1 (each has a
    // 90 degree angle at vertex 0 and a 45 degree angle at vertex 1).
    let roof = [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]];
    let faces: [&[i32]; 2] = [&[0, 1, 2], &[0, 3, 1]];
    let files = [("r.ply", ply(&roof, &faces, false))];
    let s = load_in_tempdir(&scene_xml(&ply_shape("r.ply")), &files).unwrap();
    let m = &s.scene.meshes[0];
    let (n0, n1) = (geometric_normal(m, 0), geometric_normal(m, 1));
    assert!(close(n0, vec3(-1.0, 1.0, 0.0).normalize(), 1e-6) && close(n1, vec3(1.0, 1.0, 0.0).normalize(), 1e-6), "{n0} {n1}");
    let ns = m.normals.as_ref().expect("smooth normals");
    // Equal angles at the shared vertices: the bisector +y; the others keep their face's.
    assert!(close(ns[0], Vec3::Y, 1e-6) && close(ns[1], Vec3::Y, 1e-6) && close(ns[2], n0, 1e-6) && close(ns[3], n1, 1e-6), "{ns:?}");
    assert!(s.warnings.is_empty(), "computed normals are not stored ones: {:?}", s.warnings);
    let flat = ply_shape("r.ply").replace("</shape>", r#"<boolean name="face_normals" value="true"/></shape>"#);
    assert!(load_in_tempdir(&scene_xml(&flat), &files).unwrap().scene.meshes[0].normals.is_none());
    // OBJ without vn: the same; the built-in cube: face normals.
    let obj = "v 0 0 0\nv 0 0 1\nv 1 1 0\nv -1 1 0\nf 1 2 3\nf 1 4 2\n";
    let xml = scene_xml(r#"    <shape type="obj"><string name="filename" value="r.obj"/></shape>
    <shape type="cube"/>"#);
    let s = load_in_tempdir(&xml, &[("r.obj", obj.as_bytes().to_vec())]).unwrap();
    assert!(close(s.scene.meshes[0].normals.as_ref().unwrap()[0], Vec3::Y, 1e-6));
    assert!(s.scene.meshes[1].normals.is_none());
}

/// Mitsuba's principled BSDF maps onto the lobe its parameters make dominant, saying so.
#[test]
fn principled_maps_onto_its_dominant_lobe() {
    let body = r#"
    <shape type="rectangle"><bsdf type="principled"><rgb name="base_color" value="0.2, 0.4, 0.6"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="principled"><float name="metallic" value="0.9"/><float name="roughness" value="0.2"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="principled"><float name="spec_trans" value="1"/><float name="eta" value="1.33"/><float name="roughness" value="0.0"/><float name="clearcoat" value="0.5"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="principled"><float name="metallic" value="1"/><float name="roughness" value="0.7"/></bsdf></shape>"#;
    let s = load_in_tempdir(&scene_xml(body), &[]).unwrap();
    let m: Vec<Material> = s.scene.meshes.iter().map(|x| s.scene.materials[x.material as usize]).collect();
    assert_eq!(m[0], Material::Diffuse { albedo: vec3(0.2, 0.4, 0.6) });
    // alpha = roughness²: 0.04 (specular), 0.49 (diffuse by the cut-off).
    assert!(matches!(m[1], Material::Conductor { reflectance, roughness } if reflectance == Vec3::splat(0.5) && (roughness - 0.04).abs() < 1e-6), "{:?}", m[1]);
    assert!(matches!(m[2], Material::Dielectric { ior, roughness: 0.0, .. } if (ior - 1.33).abs() < 1e-6), "{:?}", m[2]);
    assert!(matches!(m[3], Material::Conductor { roughness, .. } if (roughness - 0.49).abs() < 1e-6));
    assert_eq!(m[3].scattering(s.scene.roughness_cutoff), arpa::core::render::scene::Scattering::Diffuse(Vec3::splat(0.5)));
    let said = |line: usize, what: &str| s.warnings.iter().any(|w| w.line == line && w.message.contains(what));
    assert!(said(12, "diffuse with base_color") && said(13, "a conductor") && said(14, "a dielectric of index 1.33") && said(14, "clearcoat"), "{:?}", s.warnings);
    let bad = scene_xml(r#"    <shape type="rectangle"><bsdf type="principled"><float name="metallic" value="2"/></bsdf></shape>"#);
    let (_, msg) = expect_err(load_in_tempdir(&bad, &[]));
    assert!(msg.contains(":11:") && msg.contains("metallic"), "{msg}");
}

/// `shapegroup`s are placed by their `instance`s (one mesh per copy, positions and normals
/// transformed, what shading reads) and recorded as the scene's instancing (the group in
/// its own space, each instance's transform and copies, for the backends' acceleration
/// structures); what cannot be instanced is an error naming the line.
#[test]
fn shapegroups_are_placed_by_their_instances() {
    let files = [("q.ply", ply(&QUAD, &[&[0, 1, 2, 3]], true))];
    let group = r#"    <shape type="shapegroup" id="g"><shape type="ply"><string name="filename" value="q.ply"/></shape></shape>"#;
    let xml = scene_xml(&format!(
        r#"{group}
    <shape type="instance"><ref id="g"/><transform name="to_world"><translate x="5"/></transform></shape>
    <shape type="instance" id="turned"><ref id="g"/><transform name="to_world"><rotate z="1" angle="90"/></transform></shape>"#
    ));
    let s = load_in_tempdir(&xml, &files).unwrap();
    let [a, b] = &s.scene.meshes[..] else { panic!("{} meshes: the group itself is not placed", s.scene.meshes.len()) };
    assert!(a.positions.iter().zip(QUAD).all(|(p, q)| close(*p, vec3(q[0] + 5.0, q[1], q[2]), 1e-6)));
    // +90° about z turns the +y normals into -x.
    assert!(b.normals.as_ref().unwrap().iter().all(|n| close(*n, -Vec3::X, 1e-6)), "{:?}", b.normals);
    assert!(close(geometric_normal(b, 0), -Vec3::X, 1e-6));
    assert!(b.name.starts_with("turned"), "{}", b.name);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let inst = s.scene.instancing.as_ref().expect("the instances are recorded");
    let [proto] = &inst.prototypes[..] else { panic!("{} prototypes", inst.prototypes.len()) };
    assert_eq!(proto.name, "g");
    assert!(proto.meshes[0].positions.iter().zip(QUAD).all(|(p, q)| *p == vec3(q[0], q[1], q[2])), "the group stays in its own space");
    assert_eq!(proto.meshes[0].indices, a.indices);
    assert_eq!(inst.instances.iter().map(|i| (i.prototype, i.meshes.clone())).collect::<Vec<_>>(), [(0, vec![0]), (0, vec![1])]);
    assert_eq!(inst.instances[0].to_world.translation, glam::dvec3(5.0, 0.0, 0.0));
    assert!((inst.instances[1].to_world.transform_vector3(glam::DVec3::X) - glam::DVec3::Y).length() < 1e-12);
    assert_eq!(inst.copies(2), [Some((0, 0)), Some((1, 0))]);
    // Without instances nothing is recorded.
    let plain = load_in_tempdir(&scene_xml(r#"    <shape type="ply"><string name="filename" value="q.ply"/></shape>"#), &files).unwrap();
    assert_eq!(plain.scene.instancing, None);
    let err = |body: &str| expect_err(load_in_tempdir(&scene_xml(body), &files)).1;
    let msg = err(r#"    <shape type="instance"><ref id="g"/></shape>"#);
    assert!(msg.contains(":11:") && msg.contains("no shapegroup defined before"), "{msg}");
    let msg = err(&format!("{group}\n    <shape type=\"instance\"/>"));
    assert!(msg.contains(":12:") && msg.contains("exactly one <ref"), "{msg}");
    let msg = err(r#"    <shape type="shapegroup" id="e"><shape type="rectangle"><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape></shape>"#);
    assert!(msg.contains(":11:") && msg.contains("cannot be instanced"), "{msg}");
    let msg = err(r#"    <shape type="shapegroup" id="n"><shape type="shapegroup" id="m"/></shape>"#);
    assert!(msg.contains(":11:") && msg.contains("shapegroup"), "{msg}");
}

/// `<path>` directories are searched before the scene's own directory, the last first.
#[test]
fn path_elements_are_searched_before_the_scene_directory() {
    let dir = tempfile::tempdir().unwrap();
    let quad = |y: f32| ply(&[[0.0, y, 0.0], [1.0, y, 0.0], [1.0, y, 1.0], [0.0, y, 1.0]], &[&[0, 1, 2, 3]], false);
    for (sub, y) in [("", 0.0), ("a", 1.0), ("b", 2.0)] {
        std::fs::create_dir_all(dir.path().join(sub)).unwrap();
        std::fs::write(dir.path().join(sub).join("q.ply"), quad(y)).unwrap();
    }
    let load = |paths: &str| {
        let xml = scene_xml(&format!("{paths}\n    <shape type=\"ply\"><string name=\"filename\" value=\"q.ply\"/></shape>"));
        let path = dir.path().join("scene.xml");
        std::fs::write(&path, xml).unwrap();
        let s = load_scene(&path, &[]).unwrap();
        mesh(&s, "q.ply").positions[0].y
    };
    assert_eq!(load(""), 0.0);
    assert_eq!(load(r#"<path value="a"/>"#), 1.0);
    assert_eq!(load(r#"<path value="a"/><path value="b"/>"#), 2.0);
    assert_eq!(load(r#"<path value="b"/><path value="a"/>"#), 1.0);
}

/// Wavelength lists become linear sRGB as Mitsuba 3.9.1's RGB variants make them
/// (reference values from Mitsuba; the module `scene_file::spectrum` has the full table).
#[test]
fn spectra_convert_as_mitsuba_converts_them() {
    let xml = scene_xml(r#"    <shape type="rectangle"><bsdf type="diffuse"><spectrum name="reflectance" value="400:0.1, 700:0.9"/></bsdf></shape>
    <emitter type="point"><point name="position" x="0" y="2" z="0"/><spectrum name="intensity" value="400:1, 500:5, 600:10, 700:3"/></emitter>"#);
    let s = load_in_tempdir(&xml, &[]).unwrap();
    let Material::Diffuse { albedo } = s.scene.materials[s.scene.meshes[0].material as usize] else { panic!("not diffuse") };
    assert!(close(albedo, vec3(0.742_852_8, 0.481_140_1, 0.208_324_55), 1e-6), "{albedo}");
    let Light::Point(p) = &s.scene.lights[1] else { panic!() };
    let want = glam::dvec3(11.1462078, 7.01080799, 2.2256465);
    assert!((p.intensity - want).abs().max_element() < 1e-5, "{}", p.intensity);
    // A spectrum file, resolved like a mesh; a bad one names the file and the line.
    let xml = scene_xml(r#"    <shape type="rectangle"><bsdf type="diffuse"><spectrum name="reflectance" filename="r.spd"/></bsdf></shape>"#);
    let s = load_in_tempdir(&xml, &[("r.spd", b"# ramp\n400 0.1\n700 0.9\n".to_vec())]).unwrap();
    let Material::Diffuse { albedo } = s.scene.materials[s.scene.meshes[0].material as usize] else { panic!() };
    assert!(close(albedo, vec3(0.742_852_8, 0.481_140_1, 0.208_324_55), 1e-6), "{albedo}");
    let (_, msg) = expect_err(load_in_tempdir(&xml, &[("r.spd", b"400 0.1\n300 0.9\n".to_vec())]));
    assert!(msg.contains(":11:") && msg.contains("r.spd") && msg.contains("wavelengths must increase"), "{msg}");
}

/// `cylinder` and `disk` are Mitsuba's: areas, orientation and placement.
#[test]
fn cylinders_and_disks() {
    let xml = scene_xml(r#"    <shape type="disk"><transform name="to_world"><scale value="2"/><translate y="1"/></transform><emitter type="area"><rgb name="radiance" value="1"/></emitter></shape>
    <shape type="cylinder"><point name="p0" x="0" y="0" z="0"/><point name="p1" x="0" y="2" z="0"/><float name="radius" value="0.5"/></shape>"#);
    let s = load_in_tempdir(&xml, &[]).unwrap();
    let area = |m: &TriangleMesh| m.indices.iter().map(|t| { let p = t.map(|i| m.positions[i as usize].as_dvec3()); 0.5 * (p[1] - p[0]).cross(p[2] - p[0]).length() }).sum::<f64>();
    let (disk, cyl) = (mesh(&s, "disk"), mesh(&s, "cylinder"));
    let pi = std::f64::consts::PI;
    // Tessellated: the chords cut off 1 − sin(2π/N)/(2π/N) of the exact area.
    assert!((area(disk) / (4.0 * pi) - 1.0).abs() < 2e-4, "{}", area(disk));
    assert!((area(cyl) / (2.0 * pi) - 1.0).abs() < 2e-4, "{}", area(cyl));
    assert!(disk.positions.iter().all(|p| p.z.abs() < 1e-6), "the disk lies in its xy plane");
    let centre = disk.positions.iter().copied().sum::<Vec3>() / disk.positions.len() as f32;
    assert!(close(centre, vec3(0.0, 1.0, 0.0), 1e-5), "scaled by 2, then moved up by 1: {centre}");
    // Mitsuba's disk faces +z in its local frame; under this to_world it still faces +z.
    assert!((0..disk.indices.len()).all(|t| geometric_normal(disk, t).z > 0.99 || geometric_normal(disk, t).z.is_nan()));
    // The cylinder's side faces outward, away from its axis (the y axis here).
    assert!((0..cyl.indices.len()).all(|t| {
        let p = cyl.indices[t].map(|i| cyl.positions[i as usize]);
        let mid = (p[0] + p[1] + p[2]) / 3.0;
        geometric_normal(cyl, t).dot(vec3(mid.x, 0.0, mid.z)) > 0.0
    }));
    assert!(cyl.positions.iter().all(|p| p.y >= -1e-6 && p.y <= 2.0 + 1e-6 && (p.x * p.x + p.z * p.z - 0.25).abs() < 1e-5));
}

/// Mitsuba 2.x files read without a warning; an integrator arpa does not know and a
/// non-box film filter are warnings that say what arpa does instead.
#[test]
fn versions_integrators_and_filters() {
    let xml = scene_xml("    <shape type=\"cube\"/>").replace("version=\"3.0.0\"", "version=\"2.1.0\"");
    let s = load_in_tempdir(&xml, &[]).unwrap();
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    let xml = scene_xml("    <shape type=\"cube\"/>\n    <integrator type=\"path_sms_ss\"><integer name=\"max_depth\" value=\"7\"/><boolean name=\"caustics_bounce\" value=\"true\"/></integrator>")
        .replace("<film type=\"hdrfilm\">", "<film type=\"hdrfilm\"><rfilter type=\"gaussian\"/>");
    let s = load_in_tempdir(&xml, &[]).unwrap();
    assert_eq!(s.max_depth, Some(7));
    let text: Vec<String> = s.warnings.iter().map(|w| w.to_string()).collect();
    assert!(text.iter().any(|w| w.contains("path_sms_ss") && w.contains("max_depth")), "{text:?}");
    assert!(text.iter().any(|w| w.contains("gaussian") && w.contains("box")), "{text:?}");
    let xml = scene_xml("    <shape type=\"cube\"/>").replace("version=\"3.0.0\"", "version=\"0.6.0\"");
    let s = load_in_tempdir(&xml, &[]).unwrap();
    assert!(s.warnings.iter().any(|w| w.to_string().contains("version 0.6.0")), "{:?}", s.warnings);
}

/// A PNG file's bytes (8-bit RGB).
fn png_rgb(width: u32, height: u32, texels: &[[u8; 3]]) -> Vec<u8> {
    let img = image::RgbImage::from_raw(width, height, texels.iter().flatten().copied().collect()).unwrap();
    let mut out = Vec::new();
    image::DynamicImage::ImageRgb8(img).write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    out
}

/// Bitmap and checkerboard textures (nested and by reference) and masks load with
/// Mitsuba's parameters; bad textures are errors naming the file.
#[test]
fn textures_and_masks_load() {
    use arpa::core::render::scene::Opacity;
    use arpa::core::render::texture::{Texels, Texture, TextureFilter, TextureWrap};
    let xml = scene_xml(
        r#"    <texture type="bitmap" id="wood"><string name="filename" value="wood.png"/><string name="filter_type" value="nearest"/><string name="wrap_mode" value="mirror"/><transform name="to_uv"><scale x="2" y="3"/><translate x="0.5"/></transform></texture>
    <shape type="rectangle"><bsdf type="diffuse"><ref name="reflectance" id="wood"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="mask"><rgb name="opacity" value="0.2, 0.4, 0.6"/><bsdf type="twosided"><bsdf type="diffuse"><texture name="reflectance" type="checkerboard"><rgb name="color0" value="0.1"/></texture></bsdf></bsdf></bsdf></shape>
    <shape type="rectangle"><bsdf type="mask"><texture name="opacity" type="bitmap"><string name="filename" value="wood.png"/><boolean name="raw" value="true"/></texture><bsdf type="conductor"/></bsdf></shape>"#,
    );
    let png = png_rgb(2, 1, &[[255, 0, 0], [0, 128, 255]]);
    let s = load_in_tempdir(&xml, &[("wood.png", png.clone())]).unwrap();
    let t = &s.scene.textures;
    assert_eq!(t.textures.len(), 3);
    let Texture::Bitmap(wood) = &t.textures[0] else { panic!() };
    assert_eq!((wood.width, wood.height, wood.filter, wood.wrap), (2, 1, TextureFilter::Nearest, TextureWrap::Mirror));
    assert_eq!(wood.texels, Texels::Srgb8(vec![[255, 0, 0], [0, 128, 255]]));
    // Mitsuba composes in document order: scale, then translate; to_uv = [2 0 0.5; 0 3 0].
    assert_eq!(wood.to_uv.rows, [[2.0, 0.0, 0.5], [0.0, 3.0, 0.0]]);
    let maps: Vec<_> = s.scene.meshes.iter().map(|m| t.maps(m.material)).collect();
    assert_eq!(maps[0].color, Some(0));
    assert_eq!(maps[0].opacity, None);
    assert!(matches!(t.textures[1], Texture::Checkerboard { color0, color1, .. } if color0 == Vec3::splat(0.1) && color1 == Vec3::splat(0.2)));
    assert_eq!(maps[1].color, Some(1));
    // A constant opacity is the mean of its channels (Mitsuba's single value).
    assert!(matches!(maps[1].opacity, Some(Opacity::Constant(o)) if (o - 0.4).abs() < 1e-7));
    assert!(matches!(maps[2].opacity, Some(Opacity::Texture(2))));
    assert!(matches!(&t.textures[2], Texture::Bitmap(b) if matches!(b.texels, Texels::Linear8(_))));
    // The rectangles carry Mitsuba's uvs.
    assert!(s.scene.meshes.iter().all(|m| m.uvs.as_ref().is_some_and(|u| u.len() == m.positions.len())));
    // Bad textures name the file and what is wrong.
    let (_, msg) = expect_err(load_in_tempdir(&xml, &[]));
    assert!(msg.contains("wood.png"), "{msg}");
    let (_, msg) = expect_err(load_in_tempdir(&xml, &[("wood.png", b"GIF89a....".to_vec())]));
    assert!(msg.contains("wood.png") && msg.contains("texture file"), "{msg}");
    let bad_ref = scene_xml(r#"    <shape type="rectangle"><bsdf type="diffuse"><ref name="reflectance" id="nope"/></bsdf></shape>"#);
    let (_, msg) = expect_err(load_in_tempdir(&bad_ref, &[]));
    assert!(msg.contains(":11:") && msg.contains("nope"), "{msg}");
    let bad_opacity = scene_xml(r#"    <shape type="rectangle"><bsdf type="mask"><float name="opacity" value="1.5"/><bsdf type="diffuse"/></bsdf></shape>"#);
    let (_, msg) = expect_err(load_in_tempdir(&bad_opacity, &[]));
    assert!(msg.contains(":11:") && msg.contains("opacity"), "{msg}");
    // A textured area emitter: the texture is the radiance (factor 1), per mesh.
    let lamp = scene_xml(
        r#"    <shape type="rectangle"><emitter type="area"><texture name="radiance" type="checkerboard"><rgb name="color0" value="4"/><rgb name="color1" value="1"/></texture></emitter></shape>
    <shape type="cube"/>"#,
    );
    let s = load_in_tempdir(&lamp, &[]).unwrap();
    assert_eq!(s.scene.meshes[0].emission, Some(Vec3::ONE));
    assert_eq!(s.scene.textures.emission, vec![Some(0), None]);
    assert!(matches!(s.scene.textures.textures[0], Texture::Checkerboard { color0, .. } if color0 == Vec3::splat(4.0)));
    // A roughness texture picks the material's scattering kind by its mean alpha (0.1 and
    // 0.5 squares: 0.3, above the cut-off 0.25: diffuse), with a warning naming it.
    let rough = scene_xml(
        r#"    <shape type="rectangle"><bsdf type="roughconductor"><texture name="alpha" type="checkerboard"><float name="color0" value="0.1"/><float name="color1" value="0.5"/></texture></bsdf></shape>"#,
    );
    let s = load_in_tempdir(&rough, &[]).unwrap();
    assert!(matches!(s.scene.materials[0], Material::Conductor { roughness, .. } if (roughness - 0.3).abs() < 1e-6), "{:?}", s.scene.materials[0]);
    assert!(s.warnings.iter().any(|w| w.line == 11 && w.message.contains("texture 'alpha': the material is rendered by its mean 0.3000")), "{:?}", s.warnings);
}

/// `constant` and `envmap` load as the scene's one environment light: the constant's
/// radiance, the map's scale, orientation and mean over the sphere (a grey map of value v
/// has mean v); bad input (two environments, a map that does not decode, a singular
/// to_world, a black map) is an error naming the file and line.
#[test]
fn environment_emitters_load() {
    let shape = r#"    <shape type="rectangle"><bsdf type="twosided"><bsdf type="diffuse"/></bsdf></shape>"#;
    let s = load_in_tempdir(&scene_xml(&format!("{shape}\n    <emitter type=\"constant\"><rgb name=\"radiance\" value=\"0.5, 1, 2\"/></emitter>")), &[]).unwrap();
    let env: Vec<_> = s.scene.lights.iter().filter_map(|l| if let Light::Environment(e) = l { Some(*e) } else { None }).collect();
    assert_eq!(env.len(), 1);
    assert_eq!(env[0].radiance, glam::DVec3::new(0.5, 1.0, 2.0));
    assert_eq!(env[0].mean, glam::DVec3::ONE);
    assert!(s.scene.textures.environment.is_none());

    let grey = png_rgb(8, 4, &[[128, 128, 128]; 32]);
    let xml = scene_xml(&format!(
        "{shape}\n    <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.png\"/><float name=\"scale\" value=\"3\"/><transform name=\"to_world\"><rotate y=\"1\" angle=\"90\"/></transform></emitter>"
    ));
    let s = load_in_tempdir(&xml, &[("sky.png", grey.clone())]).unwrap();
    let Some(Light::Environment(e)) = s.scene.lights.iter().find(|l| matches!(l, Light::Environment(_))) else { panic!("no environment") };
    let v = arpa::core::render::texture::srgb_to_linear(128) as f64;
    assert_eq!(e.radiance, glam::DVec3::splat(3.0));
    assert!((e.mean - glam::DVec3::splat(v)).abs().max_element() < 1e-6, "{}", e.mean);
    let map = s.scene.textures.environment.as_ref().expect("the map");
    assert!((map.to_world.z_axis - glam::DVec3::new(1.0, 0.0, 0.0)).length() < 1e-9, "{:?}", map.to_world);
    assert!(s.warnings.is_empty(), "{:?}", s.warnings);
    arpa::core::render::prepared_scene::PreparedScene::new(s.scene).unwrap();

    let two = scene_xml(&format!("{shape}\n    <emitter type=\"constant\"/>\n    <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.png\"/></emitter>"));
    let (_, msg) = expect_err(load_in_tempdir(&two, &[("sky.png", grey.clone())]));
    assert!(msg.contains("scene.xml:") && msg.contains("at most one environment"), "{msg}");
    let bad = scene_xml(&format!("{shape}\n    <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.png\"/></emitter>"));
    let (_, msg) = expect_err(load_in_tempdir(&bad, &[("sky.png", b"not an image".to_vec())]));
    assert!(msg.contains("sky.png"), "{msg}");
    let singular = scene_xml(&format!("{shape}\n    <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.png\"/><transform name=\"to_world\"><scale x=\"0\"/></transform></emitter>"));
    let (_, msg) = expect_err(load_in_tempdir(&singular, &[("sky.png", grey)]));
    assert!(msg.contains("singular"), "{msg}");
    let black = scene_xml(&format!("{shape}\n    <emitter type=\"envmap\"><string name=\"filename\" value=\"sky.png\"/></emitter>"));
    let (_, msg) = expect_err(load_in_tempdir(&black, &[("sky.png", png_rgb(4, 2, &[[0, 0, 0]; 8]))]));
    assert!(msg.contains("sky.png") && msg.contains("black"), "{msg}");
}

/// `thindielectric` loads as a thin sheet of relative index `int_ior / ext_ior` whose
/// reflectance is Mitsuba's `2R/(1 + R)`.
#[test]
fn thin_dielectric_loads() {
    use arpa::core::render::scene::thin_sheet_reflectance;
    let xml = scene_xml(r#"    <shape type="rectangle"><bsdf type="thindielectric"><float name="int_ior" value="1.5"/><rgb name="specular_transmittance" value="0.9"/></bsdf></shape>"#);
    let s = load_in_tempdir(&xml, &[]).unwrap();
    let m = s.scene.materials[s.scene.meshes[0].material as usize];
    assert!(matches!(m, Material::ThinDielectric { ior, transmittance } if (ior - 1.5 / 1.000277).abs() < 1e-6 && transmittance == Vec3::splat(0.9)), "{m:?}");
    // Normal incidence: R = ((n - 1)/(n + 1))² = 0.04 for n = 1.5, R' = 0.08/1.04.
    assert!((thin_sheet_reflectance(1.0, 1.5) - 0.08 / 1.04).abs() < 1e-12);
    assert_eq!(thin_sheet_reflectance(-1.0, 1.5), thin_sheet_reflectance(1.0, 1.5));
}

/// `normalmap`, `bumpmap`, `blendbsdf` and `null` become maps on their nested material, and
/// malformed ones are errors naming the file and line.
#[test]
fn adapter_bsdfs_load() {
    use arpa::core::render::scene::{Blend, BlendWeight, Handedness, NormalPerturbation, Opacity};
    let files = [("n.png", png_rgb(1, 1, &[[128, 128, 255]]))];
    let xml = scene_xml(
        r#"    <shape type="rectangle"><bsdf type="normalmap"><texture name="normalmap" type="bitmap"><string name="filename" value="n.png"/><boolean name="raw" value="true"/></texture><bsdf type="conductor"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="bumpmap"><texture name="anything" type="bitmap"><string name="filename" value="n.png"/></texture><float name="scale" value="0.25"/><bsdf type="diffuse"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="blendbsdf"><float name="weight" value="0.3"/><bsdf type="diffuse"/><bsdf type="dielectric"/></bsdf></shape>
    <shape type="rectangle"><bsdf type="null"/><emitter type="area"><rgb name="radiance" value="2"/></emitter></shape>"#,
    );
    let s = load_in_tempdir(&xml, &files).unwrap();
    let maps = |i: usize| s.scene.textures.maps(s.scene.meshes[i].material);
    assert!(matches!(s.scene.materials[s.scene.meshes[0].material as usize], Material::Conductor { .. }));
    assert!(matches!(maps(0).normal, Some(NormalPerturbation::NormalMap { scale: 1.0, handedness: Handedness::RightHanded, .. })), "{:?}", maps(0));
    assert!(matches!(maps(1).normal, Some(NormalPerturbation::BumpMap { scale: 0.25, .. })), "{:?}", maps(1));
    let Some(Blend { other, weight: BlendWeight::Constant(w) }) = maps(2).blend else { panic!("{:?}", maps(2)) };
    assert!((w - 0.3).abs() < 1e-7 && matches!(s.scene.materials[other as usize], Material::Dielectric { .. }));
    assert!(matches!(s.scene.materials[s.scene.meshes[2].material as usize], Material::Diffuse { .. }));
    assert_eq!(maps(3).opacity, Some(Opacity::Constant(0.0)));
    assert!(s.scene.meshes[3].emission.is_some());
    for (bad, what) in [
        (r#"<bsdf type="bumpmap"><texture name="h" type="checkerboard"/><bsdf type="diffuse"/></bsdf>"#, "checkerboard"),
        (r#"<bsdf type="bumpmap"><bsdf type="diffuse"/></bsdf>"#, "exactly one nested <texture>"),
        (r#"<bsdf type="normalmap"><bsdf type="diffuse"/></bsdf>"#, "normalmap lacks"),
        (r#"<bsdf type="blendbsdf"><bsdf type="diffuse"/></bsdf>"#, "exactly two nested"),
        (r#"<bsdf type="blendbsdf"><float name="weight" value="1.5"/><bsdf type="diffuse"/><bsdf type="diffuse"/></bsdf>"#, "outside [0, 1]"),
        (r#"<bsdf type="blendbsdf"><bsdf type="mask"><bsdf type="diffuse"/></bsdf><bsdf type="diffuse"/></bsdf>"#, "inside a blendbsdf"),
    ] {
        let xml = scene_xml(&format!("    <shape type=\"rectangle\">{bad}</shape>"));
        let e = load_in_tempdir(&xml, &files).unwrap_err().to_string();
        assert!(e.contains("scene.xml:") && e.contains(what), "{bad}: {e}");
    }
}
