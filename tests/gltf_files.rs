//! The glTF 2.0 loader (`arpa::scene_file::load_gltf`) on small files authored here (JSON
//! with data URIs, external `.bin` files, GLB): node transforms, materials, alpha modes,
//! lights in photometric units, cameras, and every kind of bad input as an error naming
//! the file and the accessor or image. The real Crytek Sponza is checked when the shared
//! scenes are present.

use arpa::core::emit::emission::Light;
use arpa::core::render::scene::{Handedness, Material, NormalPerturbation, Opacity};
use arpa::core::render::texture::{Texels, Texture, TextureFilter, TextureWrap};
use arpa::scene_file::{GltfOptions, LUMENS_PER_WATT, LoadedScene, SceneFileError, load_gltf};
use base64::Engine;
use glam::{Vec3, vec3};
use serde_json::{Value, json};

mod common;
use common::shared_scenes;

fn png(width: u32, height: u32, rgba: &[[u8; 4]]) -> Vec<u8> {
    let img = image::RgbaImage::from_raw(width, height, rgba.iter().flatten().copied().collect()).unwrap();
    let mut out = Vec::new();
    image::DynamicImage::ImageRgba8(img).write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png).unwrap();
    out
}

fn data_uri(bytes: &[u8]) -> String {
    format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(bytes))
}

/// The binary data of a unit quad in the xz-plane facing +y: positions, normals, uvs,
/// u16 indices (byte offsets 0, 48, 96, 128; 140 bytes).
fn quad_bin() -> Vec<u8> {
    let mut b = Vec::new();
    for p in [[-1.0f32, 0.0, -1.0], [-1.0, 0.0, 1.0], [1.0, 0.0, 1.0], [1.0, 0.0, -1.0]] {
        p.iter().for_each(|x| b.extend(x.to_le_bytes()));
    }
    for _ in 0..4 {
        [0.0f32, 1.0, 0.0].iter().for_each(|x| b.extend(x.to_le_bytes()));
    }
    for t in [[0.0f32, 0.0], [0.0, 1.0], [1.0, 1.0], [1.0, 0.0]] {
        t.iter().for_each(|x| b.extend(x.to_le_bytes()));
    }
    for i in [0u16, 1, 2, 0, 2, 3] {
        b.extend(i.to_le_bytes());
    }
    b
}

/// A glTF document: the quad under node "floor" (translated by `offset`, scaled by `scale`),
/// a camera node looking down from y = 3, a point light, `material` and `images`.
fn document(buffer_uri: &str, material: Value, images: Value, scale: [f32; 3]) -> Value {
    json!({
        "asset": {"version": "2.0"},
        "extensionsUsed": ["KHR_lights_punctual"],
        "extensions": {"KHR_lights_punctual": {"lights": [
            {"name": "bulb", "type": "point", "color": [1.0, 0.5, 0.25], "intensity": 683.0},
            {"name": "sun", "type": "directional", "intensity": 1366.0}
        ]}},
        "buffers": [{"uri": buffer_uri, "byteLength": 140}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 32},
            {"buffer": 0, "byteOffset": 128, "byteLength": 12}
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3", "min": [-1, 0, -1], "max": [1, 0, 1]},
            {"bufferView": 1, "componentType": 5126, "count": 4, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5123, "count": 6, "type": "SCALAR"}
        ],
        "images": images,
        "samplers": [{"magFilter": 9728, "wrapS": 33648, "wrapT": 33648}],
        "textures": [{"source": 0, "sampler": 0}],
        "materials": [material],
        "meshes": [{"name": "quad", "primitives": [{"attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2}, "indices": 3, "material": 0}]}],
        "cameras": [
            {"name": "top", "type": "perspective", "perspective": {"yfov": 1.0, "aspectRatio": 2.0, "znear": 0.01}},
            {"name": "side", "type": "perspective", "perspective": {"yfov": 0.5, "znear": 0.01}}
        ],
        "nodes": [
            {"name": "root", "translation": [0.0, 0.0, 5.0], "children": [1]},
            {"name": "floor", "mesh": 0, "scale": scale},
            {"name": "eye", "camera": 0, "translation": [0.0, 3.0, 0.0], "rotation": [-0.70710677, 0.0, 0.0, 0.70710677]},
            {"name": "side-eye", "camera": 1, "translation": [4.0, 1.0, 0.0]},
            {"name": "lamp", "translation": [0.0, 2.0, 0.0], "extensions": {"KHR_lights_punctual": {"light": 0}}},
            {"name": "sky", "rotation": [-0.70710677, 0.0, 0.0, 0.70710677], "extensions": {"KHR_lights_punctual": {"light": 1}}}
        ],
        "scenes": [{"nodes": [0, 2, 3, 4, 5]}],
        "scene": 0
    })
}

fn textured(alpha_mode: &str) -> Value {
    json!({"name": "tex", "pbrMetallicRoughness": {"baseColorFactor": [0.5, 1.0, 1.0, 1.0], "baseColorTexture": {"index": 0}, "metallicFactor": 0.0}, "alphaMode": alpha_mode, "alphaCutoff": 0.4})
}

fn images() -> Value {
    json!([{"uri": data_uri(&png(2, 1, &[[255, 0, 0, 255], [0, 128, 255, 90]]))}])
}

/// Writes `files` and the document as `scene.gltf` into a temporary directory and loads it.
fn load(doc: &Value, files: &[(&str, Vec<u8>)], options: &GltfOptions) -> Result<LoadedScene, SceneFileError> {
    let dir = tempfile::tempdir().unwrap();
    for (name, bytes) in files {
        std::fs::write(dir.path().join(name), bytes).unwrap();
    }
    let path = dir.path().join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(doc).unwrap()).unwrap();
    load_gltf(&path, options)
}

fn close(a: Vec3, b: Vec3, tol: f32) -> bool {
    (a - b).abs().max_element() <= tol
}

#[test]
fn a_textured_quad_with_lights_and_cameras() {
    let doc = document(&data_uri(&quad_bin()), textured("OPAQUE"), images(), [1.0, 1.0, 1.0]);
    let s = load(&doc, &[], &GltfOptions::default()).unwrap();
    let scene = &s.scene;
    assert_eq!(scene.meshes.len(), 1);
    let m = &scene.meshes[0];
    // The floor node's parent moves it to z = 5.
    assert!(m.positions.iter().all(|p| p.y == 0.0 && (p.z - 5.0).abs() <= 1.0 + 1e-6));
    assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
    // TEXCOORD_0 (1, 1) is (1, 0) in arpa's texture coordinates: v flipped.
    assert_eq!(m.uvs.as_ref().unwrap()[2], glam::Vec2::new(1.0, 0.0));
    assert_eq!(scene.materials[m.material as usize], Material::Diffuse { albedo: vec3(0.5, 1.0, 1.0) });
    let Texture::Bitmap(b) = &scene.textures.textures[0] else { panic!() };
    assert_eq!((b.width, b.height, b.filter, b.wrap), (2, 1, TextureFilter::Nearest, TextureWrap::Mirror));
    assert!(matches!(&b.texels, Texels::Srgb8(t) if t[1] == [0, 128, 255]));
    assert_eq!(scene.textures.maps[0].color, Some(0));
    assert_eq!(scene.textures.maps[0].opacity, None);
    // 683 cd of colour (1, 0.5, 0.25): 1 W/sr per unit colour; the sun 1366 lux: 2 W/m²,
    // shining down (its node turns -z to -y).
    let [Light::Point(bulb), Light::Directional(sun)] = scene.lights[..] else { panic!("{:?}", scene.lights) };
    assert!(close(bulb.position.as_vec3(), vec3(0.0, 2.0, 0.0), 1e-6));
    assert!(close(bulb.intensity.as_vec3(), vec3(1.0, 0.5, 0.25) * (683.0 / LUMENS_PER_WATT) as f32, 1e-6));
    assert!(close(sun.irradiance.as_vec3(), Vec3::splat(2.0), 1e-6) && close(sun.direction.as_vec3(), -Vec3::Y, 1e-6), "{sun:?}");
    // Camera 0 by default: at y = 3 looking down, yfov 1 rad, 2:1.
    let c = &scene.camera;
    assert!(close(c.position, vec3(0.0, 3.0, 0.0), 1e-6) && close(c.target - c.position, -Vec3::Y, 1e-6));
    assert_eq!((c.vertical_fov, c.width, c.height), (1.0, 640, 320));
    // By name: the side camera looks along -z.
    let s = load(&doc, &[], &GltfOptions { camera: Some("side".into()), light_scale: 2.0 }).unwrap();
    assert!(close(s.scene.camera.position, vec3(4.0, 1.0, 0.0), 1e-6) && close(s.scene.camera.target - s.scene.camera.position, -Vec3::Z, 1e-6));
    let Light::Point(bulb) = s.scene.lights[0] else { panic!() };
    assert!(close(bulb.intensity.as_vec3(), vec3(2.0, 1.0, 0.5), 1e-6), "light_scale doubles it");
    let (e, msg) = err(load(&doc, &[], &GltfOptions { camera: Some("nope".into()), light_scale: 1.0 }));
    assert!(matches!(e, SceneFileError::Gltf { .. }) && msg.contains("nope"), "{msg}");
}

#[test]
fn alpha_modes_become_opacities() {
    // MASK at 0.4: texel alphas 1 and 90/255 = 0.35 give opacities 1 and 0.
    let s = load(&document(&data_uri(&quad_bin()), textured("MASK"), images(), [1.0; 3]), &[], &GltfOptions::default()).unwrap();
    let t = &s.scene.textures;
    let Some(Opacity::Texture(id)) = t.maps[0].opacity else { panic!("{:?}", t.maps[0]) };
    assert!(matches!(&t.textures[id as usize], Texture::Bitmap(b) if b.texels == Texels::Linear8(vec![[255; 3], [0; 3]])));
    // BLEND: the alpha itself.
    let s = load(&document(&data_uri(&quad_bin()), textured("BLEND"), images(), [1.0; 3]), &[], &GltfOptions::default()).unwrap();
    let t = &s.scene.textures;
    let Some(Opacity::Texture(id)) = t.maps[0].opacity else { panic!() };
    assert!(matches!(&t.textures[id as usize], Texture::Bitmap(b) if b.texels == Texels::Linear8(vec![[255; 3], [90; 3]])));
    // Without a texture, the factor's alpha.
    let plain = json!({"pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 0.25]}, "alphaMode": "BLEND"});
    let s = load(&document(&data_uri(&quad_bin()), plain, images(), [1.0; 3]), &[], &GltfOptions::default()).unwrap();
    assert_eq!(s.scene.textures.maps[0].opacity, Some(Opacity::Constant(0.25)));
}

#[test]
fn materials_map_onto_the_photon_mappers_lobes() {
    let cases = [
        (json!({"pbrMetallicRoughness": {"metallicFactor": 1.0, "roughnessFactor": 0.2}}), "conductor"),
        (json!({"pbrMetallicRoughness": {"metallicFactor": 0.0}, "extensions": {"KHR_materials_transmission": {"transmissionFactor": 1.0}, "KHR_materials_ior": {"ior": 1.33}}}), "dielectric"),
        (json!({"pbrMetallicRoughness": {"metallicFactor": 0.0}, "emissiveFactor": [1.0, 0.5, 0.0], "extensions": {"KHR_materials_emissive_strength": {"emissiveStrength": 4.0}}}), "emitter"),
    ];
    for (material, kind) in cases {
        let mut doc = document(&data_uri(&quad_bin()), material, images(), [1.0; 3]);
        doc["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_materials_transmission", "KHR_materials_ior", "KHR_materials_emissive_strength"]);
        let s = load(&doc, &[], &GltfOptions::default()).unwrap();
        let m = &s.scene.meshes[0];
        match (kind, s.scene.materials[m.material as usize]) {
            ("conductor", Material::Conductor { reflectance, roughness }) => assert!(reflectance == Vec3::ONE && (roughness - 0.04).abs() < 1e-6),
            ("dielectric", Material::Dielectric { ior, roughness, .. }) => assert!((ior - 1.33).abs() < 1e-6 && roughness == 1.0),
            ("emitter", Material::Diffuse { .. }) => assert_eq!(m.emission, Some(vec3(4.0, 2.0, 0.0))),
            (k, got) => panic!("{k}: {got:?}"),
        }
    }
}

#[test]
fn mirroring_transforms_keep_the_front_face() {
    let s = load(&document(&data_uri(&quad_bin()), textured("OPAQUE"), images(), [-1.0, 1.0, 1.0]), &[], &GltfOptions::default()).unwrap();
    let m = &s.scene.meshes[0];
    let p = m.indices[0].map(|i| m.positions[i as usize]);
    let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
    assert!(close(n, Vec3::Y, 1e-6), "x mirrored: the winding is reversed so the face still faces +y ({n})");
    assert!(m.normals.as_ref().unwrap().iter().all(|v| close(*v, Vec3::Y, 1e-6)));
}

/// A mesh that several nodes place is recorded as instanced: one prototype per mesh and
/// handedness (a mirrored placement has the reversed winding), kept where it is placed at
/// least twice; the copies stay the scene's meshes.
#[test]
fn reused_meshes_are_recorded_as_instances() {
    let plain = load(&document(&data_uri(&quad_bin()), textured("OPAQUE"), images(), [1.0; 3]), &[], &GltfOptions::default()).unwrap();
    assert_eq!(plain.scene.instancing, None, "one placement: nothing to share");
    let mut doc = document(&data_uri(&quad_bin()), textured("OPAQUE"), images(), [1.0; 3]);
    doc["nodes"].as_array_mut().unwrap().extend([
        json!({"name": "again", "mesh": 0, "translation": [3.0, 0.5, 0.0], "rotation": [0.0, 0.38268343, 0.0, 0.92387953]}),
        json!({"name": "mirrored", "mesh": 0, "scale": [-1.0, 1.0, 1.0]}),
    ]);
    doc["scenes"][0]["nodes"].as_array_mut().unwrap().extend([json!(6), json!(7)]);
    let s = load(&doc, &[], &GltfOptions::default()).unwrap();
    assert_eq!(s.scene.meshes.len(), 3, "every placement is a mesh");
    let inst = s.scene.instancing.as_ref().expect("mesh 0 is placed twice unmirrored");
    let [proto] = &inst.prototypes[..] else { panic!("{:?}", inst.prototypes) };
    assert_eq!(proto.meshes[0].positions[0], vec3(-1.0, 0.0, -1.0), "the prototype is in the mesh's own space");
    assert_eq!(inst.instances.iter().map(|i| i.meshes.clone()).collect::<Vec<_>>(), [vec![0], vec![1]], "the mirrored placement stays a mesh of its own");
    assert_eq!(inst.instances[0].to_world.translation, glam::dvec3(0.0, 0.0, 5.0));
    assert_eq!(s.scene.validate(), Ok(()));
}

#[test]
fn external_buffers_and_glb() {
    let doc = document("quad.bin", textured("OPAQUE"), images(), [1.0; 3]);
    let s = load(&doc, &[("quad.bin", quad_bin())], &GltfOptions::default()).unwrap();
    assert_eq!(s.triangle_count(), 2);
    // GLB: the JSON chunk and the BIN chunk.
    let mut glb_doc = doc.clone();
    glb_doc["buffers"] = json!([{"byteLength": 140}]);
    let mut json_bytes = serde_json::to_vec(&glb_doc).unwrap();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let bin = quad_bin();
    let mut glb = Vec::new();
    glb.extend(b"glTF");
    glb.extend(2u32.to_le_bytes());
    glb.extend(((12 + 8 + json_bytes.len() + 8 + bin.len()) as u32).to_le_bytes());
    glb.extend((json_bytes.len() as u32).to_le_bytes());
    glb.extend(b"JSON");
    glb.extend(&json_bytes);
    glb.extend((bin.len() as u32).to_le_bytes());
    glb.extend(b"BIN\0");
    glb.extend(&bin);
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("scene.glb");
    std::fs::write(&path, glb).unwrap();
    let s = load_gltf(&path, &GltfOptions::default()).unwrap();
    assert_eq!(s.triangle_count(), 2);
}

fn err(r: Result<LoadedScene, SceneFileError>) -> (SceneFileError, String) {
    match r {
        Ok(_) => panic!("loaded, expected an error"),
        Err(e) => {
            let msg = e.to_string();
            (e, msg)
        }
    }
}

#[test]
fn bad_input_names_the_file_and_the_accessor_or_image() {
    let base = || document("quad.bin", textured("OPAQUE"), images(), [1.0; 3]);
    let opts = GltfOptions::default();
    // A missing .bin.
    let (e, msg) = err(load(&base(), &[], &opts));
    assert!(matches!(e, SceneFileError::Io { .. }) && msg.contains("quad.bin"), "{msg}");
    // An accessor beyond its buffer view.
    let mut doc = base();
    doc["accessors"][0]["count"] = json!(40);
    let (_, msg) = err(load(&doc, &[("quad.bin", quad_bin())], &opts));
    assert!(msg.contains("scene.gltf") && msg.contains("accessor 0"), "{msg}");
    // A truncated buffer.
    let (_, msg) = err(load(&base(), &[("quad.bin", quad_bin()[..100].to_vec())], &opts));
    assert!(msg.contains("buffer 0"), "{msg}");
    // An image that does not decode.
    let mut doc = base();
    doc["images"] = json!([{"uri": data_uri(b"GIF89a....")}]);
    let (e, msg) = err(load(&doc, &[("quad.bin", quad_bin())], &opts));
    assert!(matches!(e, SceneFileError::Texture { .. }) && msg.contains("image 0"), "{msg}");
    // NaN in positions.
    let mut bin = quad_bin();
    bin[4..8].copy_from_slice(&f32::NAN.to_le_bytes());
    let (_, msg) = err(load(&base(), &[("quad.bin", bin)], &opts));
    assert!(msg.contains("POSITION") && msg.contains("accessor 0") && msg.contains("not finite"), "{msg}");
    // A required extension arpa does not have.
    let mut doc = base();
    doc["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_draco_mesh_compression"]);
    doc["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let (_, msg) = err(load(&doc, &[("quad.bin", quad_bin())], &opts));
    assert!(msg.contains("KHR_draco_mesh_compression"), "{msg}");
    // Not JSON at all.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.gltf");
    std::fs::write(&path, b"{ not json").unwrap();
    let (e, msg) = err(load_gltf(&path, &opts));
    assert!(matches!(e, SceneFileError::Gltf { .. }) && msg.contains("broken.gltf"), "{msg}");
}

/// The real Crytek Sponza as glTF: the instanced triangle count of its README, the sun at
/// 6830 lux = 10 W/m² times its colour, the reference camera first, the three masked
/// materials.
#[test]
fn crytek_sponza_gltf() {
    let Some(dir) = shared_scenes() else { return };
    let s = load_gltf(&dir.join("crytek-sponza/gltf/Sponza.gltf"), &GltfOptions::default()).unwrap();
    assert_eq!(s.triangle_count(), 262_087);
    let inst = s.scene.instancing.as_ref().expect("Sponza places some meshes several times");
    assert!(inst.instances.len() >= 2 * inst.prototypes.len(), "{} instances of {} prototypes", inst.instances.len(), inst.prototypes.len());
    let [Light::Directional(sun)] = s.scene.lights[..] else { panic!("{:?}", s.scene.lights) };
    assert!(close(sun.irradiance.as_vec3(), vec3(10.0, 9.5, 9.0), 1e-4), "{sun:?}");
    let c = &s.scene.camera;
    assert!(close(c.position, vec3(15.0, 5.68, -0.75), 0.01), "{c:?}");
    assert!((c.vertical_fov - 60f32.to_radians()).abs() < 1e-5);
    let masks = s.scene.textures.maps.iter().filter(|m| m.opacity.is_some()).count();
    assert_eq!(masks, 3);
    // The 12 materials with a normalTexture get tangent-space normal maps (glTF's bitangent sign).
    let normal_maps = s.scene.textures.maps.iter().filter(|m| matches!(m.normal, Some(NormalPerturbation::NormalMap { handedness: Handedness::FollowTextureCoordinates, .. }))).count();
    assert_eq!(normal_maps, 12);
}

/// `KHR_texture_transform` (offset, scale) in arpa's flipped texture coordinates: the
/// texture reads at `F T F (uv)`, `F(u, v) = (u, 1 − v)`.
#[test]
fn texture_transforms_follow_the_flip() {
    let material = json!({"pbrMetallicRoughness": {"baseColorTexture": {"index": 0, "extensions": {"KHR_texture_transform": {"offset": [0.5, 0.0], "scale": [2.0, 2.0]}}}, "metallicFactor": 0.0}});
    let mut doc = document(&data_uri(&quad_bin()), material, images(), [1.0; 3]);
    doc["extensionsUsed"] = json!(["KHR_lights_punctual", "KHR_texture_transform"]);
    let s = load(&doc, &[], &GltfOptions::default()).unwrap();
    let Texture::Bitmap(b) = &s.scene.textures.textures[0] else { panic!() };
    // glTF: (2u + 0.5, 2v); on v' = 1 − v: (2u + 0.5, 1 − 2(1 − v')) = (2u + 0.5, 2v' − 1).
    assert_eq!(b.to_uv.rows, [[2.0, 0.0, 0.5], [0.0, 2.0, -1.0]]);
}
