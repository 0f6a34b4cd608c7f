//! Entry points of the loaders' fuzz targets (`fuzz/`, run by `scripts/fuzz.sh` under
//! cargo-fuzz) and of their regression tests on stable (`tests/fuzz_regressions.rs`), so
//! both run exactly the same code.
//!
//! Each entry point loads through the code [`load_scene`](super::load_scene) runs (XML,
//! PLY and OBJ parsing, `to_world`, the loader's checks, [`Scene::validate`]) with mesh
//! files in memory instead of on disk, then prepares the loaded scene for rendering
//! ([`PreparedScene::new`]), as a render would. Any input must give `Ok` or an error that
//! names the file ([`error_names_file`]); a panic, hang or runaway allocation is a bug.

use super::{LoadedScene, SceneFileError, load_scene_bytes};
use arpa_core::render::prepared_scene::PreparedScene;
#[cfg(doc)]
use arpa_core::render::scene::Scene;
use std::io::{Error, ErrorKind};
use std::path::Path;

/// Name of the scene file in the fuzzing entry points' messages.
pub const SCENE_PATH: &str = "fuzz/scene.xml";

/// Name under which [`ply`] serves its input to the scene.
pub const PLY_PATH: &str = "fuzz/mesh.ply";

/// Name under which [`obj`] serves its input to the scene.
pub const OBJ_PATH: &str = "fuzz/mesh.obj";

/// Name under which [`texture`] serves its input to the scene.
pub const TEXTURE_PATH: &str = "fuzz/texture.png";

/// Name under which [`serialized`] parses its input.
pub const SERIALIZED_PATH: &str = "fuzz/mesh.serialized";

/// The mesh [`scene_xml`] serves for every `.ply` file a scene names: a unit square of two
/// triangles with normals, so the shared scenes load past their mesh references.
pub const SMALL_PLY: &str = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty float nx\nproperty float ny\nproperty float nz\nelement face 2\nproperty list uchar int vertex_indices\nend_header\n-1 -1 0 0 0 1\n1 -1 0 0 0 1\n1 1 0 0 0 1\n-1 1 0 0 0 1\n3 0 1 2\n3 0 2 3\n";

/// The mesh [`scene_xml`] serves for every `.obj` file a scene names (the square of
/// [`SMALL_PLY`], one quad).
pub const SMALL_OBJ: &str = "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvn 0 0 1\nf 1//1 2//1 3//1 4//1\n";

/// A scene that uses the mesh file `file` twice: as a plain diffuse shape with its stored
/// normals, then flipped as an area emitter (which checks its area and normal sides).
fn mesh_scene(kind: &str, file: &str) -> String {
    format!(
        r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
  </sensor>
  <shape type="{kind}"><string name="filename" value="{file}"/></shape>
  <shape type="{kind}">
    <string name="filename" value="{file}"/>
    <boolean name="flip_normals" value="true"/>
    <emitter type="area"><rgb name="radiance" value="1, 2, 3"/></emitter>
  </shape>
</scene>
"#
    )
}

/// Loads with meshes from `read` and prepares the result for rendering.
fn load_and_prepare(xml: &[u8], read: &dyn Fn(&Path) -> std::io::Result<Vec<u8>>) -> Result<LoadedScene, SceneFileError> {
    let path = Path::new(SCENE_PATH);
    let loaded = load_scene_bytes(xml, path, &[], read)?;
    PreparedScene::new(loaded.scene.clone()).map_err(|source| SceneFileError::Scene { path: path.to_path_buf(), source })?;
    Ok(loaded)
}

/// The mesh [`scene_xml`] serves for every `.serialized` file a scene names: two shapes
/// (a square and a triangle with texture coordinates), version 3.
pub const SMALL_SERIALIZED: &[u8] = include_bytes!("../../tests/data/serialized/two_shapes_v3.serialized");

/// The image [`scene_xml`] serves for every `.png`, `.jpg`, `.exr` or `.hdr` file a scene
/// names: a 2 × 2 8-bit RGB PNG.
pub const SMALL_PNG: &[u8] = include_bytes!("../../fuzz/corpus/texture/rgb8.png");

/// The spectrum [`scene_xml`] serves for every `.spd` file a scene names.
pub const SMALL_SPD: &str = "# wavelength value\n400 0.2\n550 0.6\n700 0.4\n";

/// The `scene_xml` target: `data` is a Mitsuba XML scene file; every mesh, image or
/// spectrum file it names is [`SMALL_PLY`], [`SMALL_OBJ`], [`SMALL_SERIALIZED`],
/// [`SMALL_PNG`] or [`SMALL_SPD`] by its extension, any other file does not exist.
pub fn scene_xml(data: &[u8]) -> Result<LoadedScene, SceneFileError> {
    load_and_prepare(data, &|p: &Path| match p.extension().and_then(|e| e.to_str()) {
        Some("ply") => Ok(SMALL_PLY.as_bytes().to_vec()),
        Some("obj") => Ok(SMALL_OBJ.as_bytes().to_vec()),
        Some("serialized") => Ok(SMALL_SERIALIZED.to_vec()),
        Some("png" | "jpg" | "exr" | "hdr") => Ok(SMALL_PNG.to_vec()),
        Some("spd") => Ok(SMALL_SPD.as_bytes().to_vec()),
        _ => Err(Error::new(ErrorKind::NotFound, "no such file (fuzzing serves only meshes, images and .spd spectra)")),
    })
}

/// Serves `data` as the one mesh file `name` of a scene.
fn mesh_file(data: &[u8], kind: &str, name: &str) -> Result<LoadedScene, SceneFileError> {
    let file = Path::new(name).file_name().and_then(|f| f.to_str()).unwrap_or(name);
    let xml = mesh_scene(kind, file);
    load_and_prepare(xml.as_bytes(), &|p: &Path| if p == Path::new(name) { Ok(data.to_vec()) } else { Err(Error::new(ErrorKind::NotFound, "no such file")) })
}

/// The `ply` target: `data` is a PLY file (ASCII or binary) used by a small scene
/// ([`PLY_PATH`]).
pub fn ply(data: &[u8]) -> Result<LoadedScene, SceneFileError> {
    mesh_file(data, "ply", PLY_PATH)
}

/// The `obj` target: `data` is a Wavefront OBJ file used by a small scene ([`OBJ_PATH`]).
pub fn obj(data: &[u8]) -> Result<LoadedScene, SceneFileError> {
    mesh_file(data, "obj", OBJ_PATH)
}

/// The `texture` target: `data` is an image file (PNG, JPEG, OpenEXR, Radiance HDR, or
/// anything else) read as a `bitmap` texture twice, sRGB and `raw`, by a small scene
/// ([`TEXTURE_PATH`]): the reflectance of one rectangle and the opacity of a mask.
pub fn texture(data: &[u8]) -> Result<LoadedScene, SceneFileError> {
    let xml = r#"<scene version="3.0.0">
  <sensor type="perspective">
    <float name="fov" value="45"/>
    <transform name="to_world"><lookat origin="0, 0, 5" target="0, 0, 0" up="0, 1, 0"/></transform>
    <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="6"/></film>
  </sensor>
  <emitter type="point"><point name="position" x="0" y="0" z="3"/></emitter>
  <shape type="rectangle"><bsdf type="diffuse"><texture name="reflectance" type="bitmap"><string name="filename" value="texture.png"/></texture></bsdf></shape>
  <shape type="rectangle">
    <bsdf type="mask"><texture name="opacity" type="bitmap"><string name="filename" value="texture.png"/><boolean name="raw" value="true"/></texture><bsdf type="diffuse"/></bsdf>
  </shape>
</scene>
"#;
    let name = Path::new(TEXTURE_PATH);
    load_and_prepare(xml.as_bytes(), &|p: &Path| if p == name { Ok(data.to_vec()) } else { Err(Error::new(ErrorKind::NotFound, "no such file")) })
}

/// The `serialized` target: `data` is a Mitsuba serialized mesh file. Its shapes 1 to 4
/// (where the file has them) and the first index past them are parsed directly, each `Ok`
/// or an error naming the file; then shape 0 is used by a small scene
/// ([`SERIALIZED_PATH`]), as the other mesh targets use theirs.
pub fn serialized(data: &[u8]) -> Result<LoadedScene, SceneFileError> {
    let path = Path::new(SERIALIZED_PATH);
    let count = super::serialized::shape_count(data, path).unwrap_or(1).min(4);
    for shape_index in 1..=count {
        if let Err(e) = super::serialized::parse(data, path, shape_index) {
            assert!(error_names_file(&e), "the error names no file: {e}");
        }
    }
    mesh_file(data, "serialized", SERIALIZED_PATH)
}

/// Where the `gltf` target's file is (its relative URIs resolve next to it).
pub const GLTF_PATH: &str = "fuzz/scene.gltf";

/// The `gltf` target: `data` is a glTF JSON or GLB file; every `.bin` file it names is
/// [`SMALL_GLTF_BIN`], every image file [`SMALL_PNG`], any other file does not exist.
pub fn gltf(data: &[u8]) -> Result<LoadedScene, SceneFileError> {
    let path = Path::new(GLTF_PATH);
    let read = |p: &Path| match p.extension().and_then(|e| e.to_str()) {
        Some("bin") => Ok(SMALL_GLTF_BIN.to_vec()),
        Some("png" | "jpg" | "jpeg") => Ok(SMALL_PNG.to_vec()),
        _ => Err(Error::new(ErrorKind::NotFound, "no such file (fuzzing serves only .bin buffers and images)")),
    };
    let loaded = super::load_gltf_bytes(data, path, &read, &super::GltfOptions::default())?;
    PreparedScene::new(loaded.scene.clone()).map_err(|source| SceneFileError::Scene { path: path.to_path_buf(), source })?;
    Ok(loaded)
}

/// The buffer the `gltf` target serves for every `.bin` file: a quad's positions, normals,
/// texture coordinates (offsets 0, 48, 96) and six `u16` indices (offset 128), 140 bytes.
pub const SMALL_GLTF_BIN: &[u8] = include_bytes!("../../tests/data/gltf/quad.bin");

/// Whether the message of `e` names the file it concerns: the scene file, or a mesh file
/// it names (every loader error must; the fuzz targets and their regression tests assert
/// it). [`SceneFileError::BadDefine`] concerns a command-line argument, not a file, and the
/// entry points never give it.
pub fn error_names_file(e: &SceneFileError) -> bool {
    use SceneFileError as E;
    let path = match e {
        E::Io { path, .. }
        | E::Xml { path, .. }
        | E::Unsupported { path, .. }
        | E::Invalid { path, .. }
        | E::UndefinedVariable { path, .. }
        | E::Ply { path, .. }
        | E::Obj { path, .. }
        | E::Serialized { path, .. }
        | E::Texture { path, .. }
        | E::Mesh { path, .. }
        | E::Gltf { path, .. }
        | E::Scene { path, .. } => path,
        E::BadDefine(_) => return false,
    };
    let name = path.to_string_lossy();
    !name.is_empty() && e.to_string().contains(&*name)
}
