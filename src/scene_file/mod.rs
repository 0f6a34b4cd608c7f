//! Scene files: a loader for **Mitsuba 3** XML scenes as they are written in the wild
//! (versions 2.x and 3.x), with PLY, OBJ and Mitsuba `serialized` meshes and bitmap
//! textures. The loader grows by plugin kind, as Mitsuba's source tree does: one module per
//! bsdf, emitter, shape, sensor and texture family under `mitsuba/`. The README's section
//! "Mitsuba 3 scenes" lists every plugin and parameter in one table.
//!
//! **glTF 2.0** files (`.gltf` with its buffers and images, `.glb`) load to the same scene
//! model ([`load_gltf`], and [`load_scene`] by the file's extension); the mapping of nodes,
//! materials, alpha modes, punctual lights (photometric units at [`LUMENS_PER_WATT`]) and
//! cameras is the table of the `gltf_scene` module (source `src/scene_file/gltf_scene.rs`),
//! summarised in the README's section "glTF 2.0 scenes".
//!
//! ```no_run
//! let loaded = arpa::scene_file::load_scene("scene.xml".as_ref(), &[("res_x".into(), "64".into())])?;
//! for w in &loaded.warnings { eprintln!("warning: {w}"); }
//! let scene = loaded.scene; // validated
//! # Ok::<(), arpa::scene_file::SceneFileError>(())
//! ```
//!
//! ## Supported
//!
//! | element | mapping |
//! |---|---|
//! | `<default name value>`, `$name` | substituted in every attribute value; `-D name=value` ([`load_scene`]'s `defines`) overrides defaults; an undefined `$name` is an error naming the line |
//! | `<path value="dir">` | a directory relative file names (meshes, textures, spectra) are looked up in before the scene's own; the last `<path>` first (Mitsuba's order) |
//! | `<transform name="to_world">` | `matrix` (16 numbers, row-major, or 9), `lookat` (`origin`, `target`, `up`), `translate`, `rotate` (`axis`, `angle` in degrees), `scale` (one or three values); composed in document order as Mitsuba does (each operation is applied after the previous ones) |
//! | `<shape type="ply">` | `ply-rs` loader (binary little/big endian or ASCII; `x y z` with optional `nx ny nz` and texture coordinates `u v`, `texture_u texture_v` or `s t`; faces `list <int> <int> vertex_indices`, quads fan-triangulated). Without stored normals the mesh gets Mitsuba's smooth vertex normals (angle-weighted unit face normals at the vertices the faces share, [`angle_weighted_normals`](arpa_core::render::shapes::angle_weighted_normals)) unless `face_normals` is set. Stored normals shade every surface: specular ones reflect and refract about them, diffuse ones are two-sided Lambertian in the shading frame as in Mitsuba (`arpa_core::propagate::lambertian`); a diffuse mesh with more than 1 % of its area under vertex normals tilted over 60° from their faces gets a warning (likely a broken export) |
//! | `<shape type="obj">` | `tobj`, all objects merged (vertices shared per `v/vt/vn` triple, as in Mitsuba, smooth normals without `vn`), polygons triangulated, texture coordinates with `v` flipped (Mitsuba's default), `.mtl` ignored |
//! | `<shape type="serialized">` | Mitsuba's compressed format (versions 3 and 4, single or double precision, normals, texture coordinates; colours dropped), `shape_index` (default 0); the file's face-normal flag drops its normals and shades the faces flat unless the scene sets `face_normals` |
//! | `<shape type="rectangle" / "cube" / "sphere" / "cylinder" / "disk">` | Mitsuba's canonical shapes and texture coordinates (`[-1,1]²` at z = 0 facing +z; `[-1,1]³`; sphere `center` + `radius` tessellated into 5,120 triangles with exact vertices and smooth normals; cylinder `p0`, `p1`, `radius`, open, 256 sides; disk of radius 1 at z = 0 facing +z, 256 triangles) |
//! | shape `face_normals`, `flip_normals` | face normals (stored normals dropped, none computed); reverse the winding and normals |
//! | `<bsdf type="diffuse">` | [`Material::Diffuse`] with `reflectance` (a colour or a texture) |
//! | `dielectric` | [`Material::Dielectric`], `ior = int_ior / ext_ior` (numbers or Mitsuba's named IORs), `specular_transmittance` |
//! | `conductor` | [`Material::Conductor`], roughness 0. `material="none"` (Mitsuba's default) is a perfect mirror of reflectance `specular_reflectance`; a named metal uses a small table of normal-incidence reflectances (Ag, Al, Au, Cr, Cu, Ni_palik, Pt, Fe, Ti, W), any other name 0.9 gray (warning); `eta`/`k` give the cosine-weighted hemispherical average of the exact conductor Fresnel reflectance ([`conductor_albedo`](arpa_core::propagate::fresnel::conductor_albedo)), used at every angle (warning) |
//! | `roughconductor`, `roughdielectric` | as above with roughness `alpha` (or the mean of `alpha_u`, `alpha_v`; default 0.1; a texture gives its mean single value, with a warning): the renderer applies [`Scene::roughness_cutoff`] ([`ROUGHNESS_CUTOFF`] = `alpha` 0.25 here, RTPM's rule of linear roughness `sqrt(alpha)` 0.5): `alpha` at or above it is diffuse, smoother is perfectly specular (warning saying which) |
//! | `plastic`, `roughplastic` | diffuse with `diffuse_reflectance`; the specular coating is dropped (warning) |
//! | `principled` | the lobe its parameters make dominant (warning saying which): `spec_trans` ≥ ½ a dielectric of index `eta` (or from `specular` as Mitsuba relates them; default 1.5) and transmittance `base_color`; else `metallic` ≥ ½ a conductor of reflectance `base_color`; else diffuse `base_color`. Roughness `alpha = roughness²` (default roughness 0.5) meets the cut-off as for rough conductors; textured `roughness`, `metallic`, `spec_trans` by their mean; `base_color` may be a texture; sheen, clearcoat, tints and anisotropy are dropped (warning) |
//! | `mask` | its nested bsdf with an `opacity` (float, colour (its mean) or texture (its luminance); default 0.5): every ray (camera, photon, shadow) stops there with that probability and passes through otherwise ([`SceneTextures`](arpa_core::render::scene::SceneTextures)) |
//! | `<texture type="bitmap">` | nested with a parameter's name, or top level with an `id` and referenced by `<ref name="..." id="..."/>`: `filename` (PNG, JPEG 8-bit sRGB unless `raw`; 16-bit PNG, OpenEXR, Radiance HDR linear), `filter_type` bilinear/nearest, `wrap_mode` repeat/mirror/clamp, `raw`, `to_uv`; as `reflectance` (diffuse, plastic `diffuse_reflectance`), conductor `specular_reflectance`, dielectric `specular_transmittance`, mask `opacity`, an area emitter's `radiance` (looked up at every hit, photon origin and next-event sample), and roughness `alpha` (its mean) ([`arpa_core::render::texture`]) |
//! | `<texture type="checkerboard">` | `color0` (default 0.4), `color1` (0.2), `to_uv`, where a bitmap goes |
//! | `twosided` | its nested bsdf (arpa's materials are two-sided). A one-sided diffuse/conductor with non-zero reflectance gets a warning, since Mitsuba renders its back black |
//! | `<ref id>` / `id` | top-level bsdfs by id; a shape without a bsdf is diffuse 0.5 (Mitsuba's default) |
//! | `<emitter type="area">` in a shape | [`TriangleMesh::emission`] = `radiance` (or 1 and a texture, [`SceneTextures::emission`](arpa_core::render::scene::SceneTextures::emission)), one-sided on the geometric-normal side `cross(p1−p0, p2−p0)` (the shared scenes' convention); zero total area is an error; a warning if the stored normals point the other way |
//! | `point` | [`PointLight`](arpa_core::emit::emission::PointLight): `intensity` (W/sr), `position` or `to_world` |
//! | `spot` | [`SpotLight`](arpa_core::emit::emission::SpotLight): `to_world` (+z is the axis), `intensity`, `cutoff_angle` (default 20°, in (0°, 90°]) and `beam_width` (default ¾ cutoff, in [0, cutoff]) in degrees → radians, [`SpotFalloff::LinearAngle`](arpa_core::emit::emission::SpotFalloff) (Mitsuba's curve) |
//! | `directional` | [`DirectionalLight`](arpa_core::emit::emission::DirectionalLight): `direction` or `to_world` +z, `irradiance` |
//! | `<sensor type="perspective">` | [`Camera`](arpa_core::render::scene::Camera) from `to_world` in Mitsuba's convention (camera +z forward, +y up, +x *left*; a mirrored frame is an error); `fov` with `fov_axis` x (Mitsuba's default), y, diagonal, smaller, larger, converted to the vertical FOV; film `width`/`height` (default 768×576) |
//! | colours | `<rgb value="r, g, b">`, `<rgb value="v">`, `<float>`, `<spectrum value="v">`, `<spectrum value="λ1:v1, λ2:v2, …">` and `<spectrum filename="x.spd">`, converted to linear sRGB as Mitsuba's RGB variants convert them (CIE 1931 over 360–830 nm, D65-weighted for reflectances and `eta`/`k`, clamped as Mitsuba clamps with a warning; a constant emission spectrum is `v` times the equal-energy white's colour, as in Mitsuba) |
//! | `<integrator>` | ignored (arpa is the integrator); its `max_depth` is reported in [`LoadedScene::max_depth`]; a type Mitsuba does not ship (`path_sms_ss`, …) is a warning |
//! | sampler, film `pixel_format` etc. | ignored; `sample_count` in [`LoadedScene::sample_count`]; a non-box `rfilter` warns that the box filter is used |
//! | `<scene version>` | 2.x and 3.x read as they are (they share parameter names); another version is a warning |
//!
//! ## Unsupported
//!
//! Other shape, bsdf, emitter, sensor and texture types, textures on other parameters
//! (a dielectric's `int_ior`, spot lights, …), media, `include`, instancing (`shapegroup`, `instance`) and
//! `focal_length` are errors naming the element and its line; unknown
//! properties of supported elements are warnings naming the property and its line
//! ([`LoadedScene::warnings`]). Malformed XML, PLY, OBJ, serialized or image files, missing files, non-finite
//! vertices and zero-area emitters are [`SceneFileError`]s naming the file and the
//! problem. The loaded scene is checked with [`Scene::validate`] before it is returned.
//!
//! ## Numeric fields
//!
//! Every number is checked where it is read, and a bad one is an error naming the line and
//! the field: NaN and ±∞ anywhere; `fov` outside (0, 180) (or a vertical field of view
//! that rounds to 0); film `width`/`height` outside 1..=16384; a transform operation that
//! is not finite, a composed transform that overflows or is singular (determinant 0 or
//! subnormal: it flattens space, so normals and camera frames are undefined); `int_ior`,
//! `ext_ior` not positive (and their ratio not a positive single-precision number);
//! reflectances and `specular_transmittance` outside [0, 1]; negative `alpha`;
//! `intensity`, `irradiance` and `radiance` negative or beyond single precision, and zero
//! for point, spot and directional lights (they must emit); spot angles as above; a sphere
//! `radius` not positive or beyond single precision; a point light whose `position`
//! overflows under its `to_world`; and vertex positions or normals that are not finite in
//! a PLY or OBJ file or after the shape's `to_world`.
//!
//! ## Fuzzing
//!
//! The parsers of all three formats are fuzzed (`scripts/fuzz.sh`, cargo-fuzz on nightly)
//! through [`fuzzing`], which loads from memory: [`load_scene_bytes`], [`parse_ply`] and
//! [`parse_obj`] are the file-system-free entry points.

mod bitmap;
mod error;
pub mod fuzzing;
mod gltf_scene;
mod loaded;
mod mesh;
mod mitsuba;
mod obj;
mod ply;
mod serialized;
mod shapes;
mod spectrum;
pub mod transform;
mod xml;

pub use error::{SceneFileError, Warning};
pub use gltf_scene::{is_gltf, GltfOptions, DEFAULT_WIDTH as GLTF_DEFAULT_WIDTH, LUMENS_PER_WATT};
pub use loaded::{vertical_fov, FovAxis, LoadedScene};
pub use mesh::{MeshReader, RawMesh};
pub use mitsuba::ROUGHNESS_CUTOFF;

#[cfg(doc)]
use arpa_core::render::scene::{Material, Scene, TriangleMesh};
use std::path::Path;

/// Parses a PLY mesh (ASCII or binary, either byte order) from memory; `path` names the
/// file in errors. The scene loader reads mesh files through this, so it is also the entry
/// point of the `ply` fuzz target and its regression tests.
pub fn parse_ply(bytes: &[u8], path: &Path) -> Result<RawMesh, SceneFileError> {
    ply::parse(bytes, path)
}

/// Parses a Wavefront OBJ mesh from memory (`.mtl` libraries ignored); `path` names the
/// file in errors. The scene loader reads mesh files through this, so it is also the entry
/// point of the `obj` fuzz target and its regression tests.
pub fn parse_obj(bytes: &[u8], path: &Path) -> Result<RawMesh, SceneFileError> {
    obj::parse(bytes, path)
}

/// Loads a Mitsuba 3 XML scene file; `defines` are `-D name=value` overrides of its
/// `<default>`s. Mesh file names are relative to the scene file's directory.
pub fn load_scene(path: &Path, defines: &[(String, String)]) -> Result<LoadedScene, SceneFileError> {
    let bytes = std::fs::read(path).map_err(|source| SceneFileError::Io { path: path.to_path_buf(), source })?;
    load_scene_bytes(&bytes, path, defines, &|p| std::fs::read(p))
}

/// Loads a glTF 2.0 file (`.gltf` with its buffers and images, or `.glb`) with `options`
/// (the camera, a factor on its lights); see the `gltf_scene` table in the module docs.
pub fn load_gltf(path: &Path, options: &GltfOptions) -> Result<LoadedScene, SceneFileError> {
    let bytes = std::fs::read(path).map_err(|source| SceneFileError::Io { path: path.to_path_buf(), source })?;
    gltf_scene::load(&bytes, path, &|p| std::fs::read(p), options)
}

/// Loads the bytes of a glTF or GLB file; `path` names it and resolves its relative URIs,
/// which `read` reads ([`load_gltf`] without the file system).
pub fn load_gltf_bytes(bytes: &[u8], path: &Path, read: MeshReader<'_>, options: &GltfOptions) -> Result<LoadedScene, SceneFileError> {
    gltf_scene::load(bytes, path, read, options)
}

/// Loads a scene from the bytes of its XML file; `path` names it in messages and its
/// directory resolves mesh file names, which `read_mesh` reads. This is [`load_scene`]
/// without the file system: the `scene_xml` fuzz target and its regression tests load
/// through it with in-memory meshes.
pub fn load_scene_bytes(bytes: &[u8], path: &Path, defines: &[(String, String)], read_mesh: MeshReader<'_>) -> Result<LoadedScene, SceneFileError> {
    if is_gltf(path) {
        return gltf_scene::load(bytes, path, read_mesh, &GltfOptions::default());
    }
    let text = std::str::from_utf8(bytes).map_err(|e| {
        let before = &bytes[..e.valid_up_to()];
        let line = before.iter().filter(|&&b| b == b'\n').count() + 1;
        SceneFileError::Xml { path: path.to_path_buf(), line, message: "the file is not UTF-8 text".into() }
    })?;
    mitsuba::load_str(text, path, defines, read_mesh)
}

/// Loads a scene from XML text; `path` names it in messages and its directory resolves
/// mesh file names (read from the file system).
pub fn load_scene_str(text: &str, path: &Path, defines: &[(String, String)]) -> Result<LoadedScene, SceneFileError> {
    mitsuba::load_str(text, path, defines, &|p| std::fs::read(p))
}

/// Parses a `-D` argument `name=value`.
pub fn parse_define(s: &str) -> Result<(String, String), SceneFileError> {
    match s.split_once('=') {
        Some((k, v)) if !k.trim().is_empty() && k.trim().chars().all(|c| c.is_ascii_alphanumeric() || c == '_') => Ok((k.trim().to_string(), v.to_string())),
        _ => Err(SceneFileError::BadDefine(s.to_string())),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fov_conversion() {
        let v = vertical_fov(40.0, FovAxis::Y, 320, 180) as f64;
        assert!((v - 40f64.to_radians()).abs() < 1e-6);
        let v = vertical_fov(90.0, FovAxis::X, 200, 100) as f64;
        assert!((v - 2.0 * 0.5f64.atan()).abs() < 1e-6);
        assert_eq!(vertical_fov(30.0, FovAxis::Smaller, 100, 200), vertical_fov(30.0, FovAxis::X, 100, 200));
        assert_eq!(vertical_fov(30.0, FovAxis::Larger, 100, 200), vertical_fov(30.0, FovAxis::Y, 100, 200));
    }

    #[test]
    fn defines() {
        assert_eq!(parse_define("res_x=64").unwrap(), ("res_x".to_string(), "64".to_string()));
        assert!(parse_define("novalue").is_err() && parse_define("=3").is_err() && parse_define("a b=1").is_err());
    }
}
