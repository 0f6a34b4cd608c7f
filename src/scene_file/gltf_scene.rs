//! glTF 2.0 scenes (`.gltf` with its buffers and images, `.glb`, data URIs) to the same
//! scene model as the Mitsuba loader, on the `gltf` crate (which parses and validates the
//! JSON; buffers and images are read here, every accessor checked against its buffer).
//!
//! | glTF | arpa |
//! |---|---|
//! | the default scene's node tree | every node's world matrix (parent × local); each mesh primitive of each node is one [`TriangleMesh`] (the shading copy); a mesh that several nodes place is recorded as instanced ([`Scene::instancing`]: one prototype per mesh and handedness of placement), positions and normals transformed in `f64`, winding reversed under a mirroring matrix (as the spec defines front faces) |
//! | primitives | triangles only (other modes are skipped with a warning); `u8`/`u16`/`u32` indices or none; `NORMAL` (else face normals, as the spec asks), `TEXCOORD_0` |
//! | `pbrMetallicRoughness` | `baseColorFactor` × `baseColorTexture` (sRGB) as the colour; `KHR_materials_transmission` ≥ ½ a dielectric of `KHR_materials_ior` (default 1.5), else `metallicFactor` ≥ ½ a conductor, else diffuse, with `alpha = roughnessFactor²` through the roughness cut-off, as the XML loader's `principled`; a `metallicRoughnessTexture` multiplies the factors by its means (blue and green channels; warning: one scattering kind per material); `normalTexture` (with `scale`) as a tangent-space normal map, its bitangent following `TEXCOORD_0`'s `v` (MikkTSpace's sign; no `TANGENT` attribute is read) |
//! | `alphaMode` | `MASK`: opacity 1 where the base colour's alpha (texture × factor) reaches `alphaCutoff` (default ½), else 0, per texel; `BLEND`: that alpha as a stochastic opacity; `OPAQUE`: none |
//! | `emissiveFactor` × `emissiveTexture` × `KHR_materials_emissive_strength` | an area light of that radiance (W/(m²·sr), taken as it is) |
//! | `KHR_lights_punctual` | point (`intensity` cd → W/sr), spot (cones: `outerConeAngle` the cut-off, `innerConeAngle` the full-intensity width, smoothstep falloff), directional (lux → W/m²), at 683 lm/W, times `color`, times [`GltfOptions::light_scale`]; lights point along their node's −z; `range` is ignored |
//! | `TEXCOORD_0` | `(u, 1 − v)` in arpa's (Mitsuba's) texture coordinates, as the shared Crytek Sponza's conversion to Mitsuba maps them |
//! | cameras | the perspective camera [`GltfOptions::camera`] names, else the scene's first camera node in node order of camera index 0 (`yfov`; it looks along −z with +y up); the film is [`DEFAULT_WIDTH`] wide at the camera's aspect ratio (16:9 without one) |
//! | samplers, `KHR_texture_transform` | `wrapS` (and `wrapT` where it differs, with a warning), `magFilter` nearest or linear; offset, rotation and scale become the texture's `to_uv` |
//!
//! Unsupported required extensions are an error naming them; unknown used ones a warning.
//! Bad data (a missing buffer, an accessor beyond its buffer, an image that does not decode,
//! NaN positions) is a [`SceneFileError::Gltf`] or [`SceneFileError::Texture`] naming the
//! file and the accessor or image.

use super::bitmap;
use super::error::{SceneFileError, Warning};
use super::loaded::{FovAxis, LoadedScene};
use super::mesh::MeshReader;
use arpa_core::emit::emission::{DirectionalLight, Light, PointLight, SpotFalloff, SpotLight};
use arpa_core::render::scene::{Camera, Handedness, Instance, Instancing, Material, MaterialMaps, NormalPerturbation, Opacity, Prototype, PrototypeMesh, Scene, SceneTextures, TriangleMesh};
use arpa_core::render::texture::{Bitmap, Texels, Texture, TextureFilter, TextureId, TextureWrap, UvTransform};
use glam::{DAffine3, DMat3, DMat4, DVec3, Vec2, Vec3};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Lumens per watt of the conversion from photometric glTF light units.
pub const LUMENS_PER_WATT: f64 = 683.0;
/// Image width of a glTF camera (pixels; the height follows its aspect ratio).
pub const DEFAULT_WIDTH: u32 = 640;
/// The roughness cut-off of loaded glTF scenes (GGX alpha; the XML loader's).
const ROUGHNESS_CUTOFF: f32 = super::mitsuba::ROUGHNESS_CUTOFF;

/// Extensions the loader reads.
const SUPPORTED: &[&str] = &["KHR_lights_punctual", "KHR_materials_emissive_strength", "KHR_materials_ior", "KHR_materials_transmission", "KHR_texture_transform"];
/// Extensions the loader ignores on purpose (a warning says so).
const IGNORED: &[&str] = &["KHR_materials_volume"];

/// What a glTF scene is loaded with.
#[derive(Clone, Debug, PartialEq)]
pub struct GltfOptions {
    /// The camera to render through, by name (`None`: the first).
    pub camera: Option<String>,
    /// Factor on every punctual light, for files authored in other units than the spec's.
    pub light_scale: f64,
}

impl Default for GltfOptions {
    fn default() -> Self {
        Self { camera: None, light_scale: 1.0 }
    }
}

/// Whether `path` names a glTF file (`.gltf` or `.glb`, any case).
pub fn is_gltf(path: &Path) -> bool {
    path.extension().and_then(|e| e.to_str()).is_some_and(|e| e.eq_ignore_ascii_case("gltf") || e.eq_ignore_ascii_case("glb"))
}

type R<T> = Result<T, SceneFileError>;

/// A loaded material: its index in the scene's materials, and its emission (radiance and
/// texture) if it emits.
type LoadedMaterial = (u32, Option<(Vec3, Option<TextureId>)>);

struct Loader<'a> {
    path: &'a Path,
    doc: &'a gltf::Document,
    read: MeshReader<'a>,
    buffers: Vec<Vec<u8>>,
    warnings: Vec<Warning>,
    textures: Vec<Texture>,
    /// Image index → decoded base colour (sRGB) texture of a sampler key, cached.
    colour_cache: HashMap<(usize, usize), TextureId>,
    materials: Vec<Material>,
    maps: Vec<MaterialMaps>,
    /// Material index (None: the default material) → arpa material and emission.
    material_ids: HashMap<Option<usize>, LoadedMaterial>,
}

impl Loader<'_> {
    fn err(&self, message: impl Into<String>) -> SceneFileError {
        SceneFileError::Gltf { path: self.path.to_path_buf(), message: message.into() }
    }

    fn warn(&mut self, message: impl Into<String>) {
        self.warnings.push(Warning { path: self.path.to_path_buf(), line: 0, message: message.into() });
    }

    /// The bytes of a `uri` (a data URI, or a file relative to the glTF file).
    fn uri_bytes(&self, uri: &str, what: &str) -> R<(Vec<u8>, PathBuf)> {
        if let Some(rest) = uri.strip_prefix("data:") {
            let (_, data) = rest.split_once(";base64,").ok_or_else(|| self.err(format!("{what}: a data URI that is not base64")))?;
            use base64::Engine;
            let bytes = base64::engine::general_purpose::STANDARD.decode(data.trim()).map_err(|e| self.err(format!("{what}: bad base64 data URI: {e}")))?;
            return Ok((bytes, PathBuf::from(format!("{} ({what})", self.path.display()))));
        }
        let file = self.path.parent().unwrap_or(Path::new(".")).join(percent_decode(uri));
        let bytes = (self.read)(&file).map_err(|source| SceneFileError::Io { path: file.clone(), source })?;
        Ok((bytes, file))
    }

    /// Checks that every element of `accessor` lies inside its buffer (the `gltf` crate's
    /// reader slices without checking).
    fn check_accessor(&self, a: &gltf::Accessor<'_>, what: &str, kinds: &[(gltf::accessor::Dimensions, gltf::accessor::DataType)]) -> R<()> {
        let name = format!("{what} (accessor {})", a.index());
        if !kinds.contains(&(a.dimensions(), a.data_type())) {
            return Err(self.err(format!("{name}: {:?} of {:?} is not a type this attribute takes ({kinds:?})", a.dimensions(), a.data_type())));
        }
        if a.count() == 0 {
            return Err(self.err(format!("{name}: count 0 (the spec asks for at least 1)")));
        }
        if a.sparse().is_some() {
            return Err(self.err(format!("{name}: sparse accessors are not supported")));
        }
        let Some(view) = a.view() else { return Err(self.err(format!("{name}: no buffer view"))) };
        let buffer = self.buffers.get(view.buffer().index()).ok_or_else(|| self.err(format!("{name}: buffer {} missing", view.buffer().index())))?;
        let view_end = view.offset().checked_add(view.length());
        if view_end.is_none_or(|e| e > buffer.len()) {
            return Err(self.err(format!("{name}: buffer view {} lies beyond its buffer ({} bytes)", view.index(), buffer.len())));
        }
        let size = a.size();
        let stride = view.stride().unwrap_or(size);
        if stride < size {
            return Err(self.err(format!("{name}: byte stride {stride} is below its element size {size}")));
        }
        if a.count() > 0 {
            let need = a.offset().checked_add((a.count() - 1).saturating_mul(stride)).and_then(|x| x.checked_add(size));
            if need.is_none_or(|n| n > view.length()) {
                return Err(self.err(format!("{name}: {} elements do not fit its buffer view {} ({} bytes)", a.count(), view.index(), view.length())));
            }
        }
        Ok(())
    }

    /// An image's bytes and the path that names it in errors.
    fn image_bytes(&self, image: &gltf::Image<'_>) -> R<(Vec<u8>, PathBuf)> {
        let what = format!("image {}{}", image.index(), image.name().map(|n| format!(" '{n}'")).unwrap_or_default());
        // From the JSON: the crate's `Image::source` unwraps what validation lets through
        // (a buffer view without a MIME type, neither a uri nor a view).
        let json = self.doc.as_json().images.get(image.index()).ok_or_else(|| self.err(format!("{what} does not exist")))?;
        if let Some(v) = &json.buffer_view {
            let view = self.doc.views().nth(v.value()).ok_or_else(|| self.err(format!("{what}: buffer view {} does not exist", v.value())))?;
            let b = self.buffers.get(view.buffer().index()).ok_or_else(|| self.err(format!("{what}: buffer missing")))?;
            let end = view.offset().checked_add(view.length()).filter(|&e| e <= b.len()).ok_or_else(|| self.err(format!("{what}: its buffer view lies beyond its buffer")))?;
            return Ok((b[view.offset()..end].to_vec(), PathBuf::from(format!("{} ({what})", self.path.display()))));
        }
        match &json.uri {
            Some(uri) => self.uri_bytes(uri, &what),
            None => Err(self.err(format!("{what} has neither a uri nor a buffer view"))),
        }
    }

    /// The sampler and transform of a texture reference as arpa's filter, wrap and `to_uv`.
    fn sampling(&mut self, texture: &gltf::Texture<'_>, transform: Option<gltf::texture::TextureTransform<'_>>) -> (TextureFilter, TextureWrap, UvTransform) {
        let s = texture.sampler();
        let wrap = |w: gltf::texture::WrappingMode| match w {
            gltf::texture::WrappingMode::Repeat => TextureWrap::Repeat,
            gltf::texture::WrappingMode::MirroredRepeat => TextureWrap::Mirror,
            gltf::texture::WrappingMode::ClampToEdge => TextureWrap::Clamp,
        };
        if s.wrap_s() != s.wrap_t() {
            self.warn(format!("texture {}: wrapS and wrapT differ; wrapS is used for both", texture.index()));
        }
        let filter = match s.mag_filter() {
            Some(gltf::texture::MagFilter::Nearest) => TextureFilter::Nearest,
            _ => TextureFilter::Bilinear,
        };
        let to_uv = match transform {
            None => UvTransform::IDENTITY,
            Some(t) => {
                // KHR_texture_transform: uv' = T(offset) R(rotation) S(scale) uv in glTF's
                // coordinates; on arpa's flipped ones (see `flip_v`) that is F T F with
                // F(u, v) = (u, 1 − v).
                let ([ox, oy], r, [sx, sy]) = (t.offset(), t.rotation(), t.scale());
                let (c, sn) = (r.cos(), r.sin());
                let [[a, b, e], [d, g, f]] = [[c * sx, sn * sy, ox], [-sn * sx, c * sy, oy]];
                UvTransform { rows: [[a, -b, b + e], [-d, g, 1.0 - g - f]] }
            }
        };
        (filter, wrap(s.wrap_s()), to_uv)
    }

    /// A colour texture (sRGB PNG/JPEG, or a float image) for `info`.
    fn colour_texture(&mut self, texture: gltf::Texture<'_>, transform: Option<gltf::texture::TextureTransform<'_>>) -> R<TextureId> {
        let key = (texture.source().index(), texture.index());
        if let Some(&id) = self.colour_cache.get(&key).filter(|_| transform.is_none()) {
            return Ok(id);
        }
        let (bytes, path) = self.image_bytes(&texture.source())?;
        let d = bitmap::decode(&bytes, &path, false)?;
        let (filter, wrap, to_uv) = self.sampling(&texture, transform);
        self.textures.push(Texture::Bitmap(Bitmap { width: d.width, height: d.height, texels: d.texels, filter, wrap, to_uv }));
        let id = (self.textures.len() - 1) as TextureId;
        self.colour_cache.insert(key, id);
        Ok(id)
    }

    /// A texture read as stored (`raw`: 8-bit values as `c/255`), e.g. a normal map.
    fn raw_texture(&mut self, texture: gltf::Texture<'_>, transform: Option<gltf::texture::TextureTransform<'_>>) -> R<TextureId> {
        let (bytes, path) = self.image_bytes(&texture.source())?;
        let d = bitmap::decode(&bytes, &path, true)?;
        let (filter, wrap, to_uv) = self.sampling(&texture, transform);
        self.textures.push(Texture::Bitmap(Bitmap { width: d.width, height: d.height, texels: d.texels, filter, wrap, to_uv }));
        Ok((self.textures.len() - 1) as TextureId)
    }

    /// The opacity of a material's alpha: per texel, `map(alpha · factor)`.
    fn alpha_texture(&mut self, texture: gltf::Texture<'_>, transform: Option<gltf::texture::TextureTransform<'_>>, factor: f32, map: impl Fn(f32) -> f32) -> R<TextureId> {
        let (bytes, path) = self.image_bytes(&texture.source())?;
        let (width, height, alpha) = bitmap::decode_alpha(&bytes, &path)?;
        let texels = alpha.iter().map(|&a| [(map(a as f32 / 255.0 * factor).clamp(0.0, 1.0) * 255.0).round() as u8; 3]).collect();
        let (filter, wrap, to_uv) = self.sampling(&texture, transform);
        self.textures.push(Texture::Bitmap(Bitmap { width, height, texels: Texels::Linear8(texels), filter, wrap, to_uv }));
        Ok((self.textures.len() - 1) as TextureId)
    }

    /// The arpa material (and emission) of glTF material `m`.
    fn material(&mut self, m: gltf::Material<'_>) -> R<LoadedMaterial> {
        if let Some(&v) = self.material_ids.get(&m.index()) {
            return Ok(v);
        }
        let name = match m.index() {
            Some(i) => format!("material {i}{}", m.name().map(|n| format!(" '{n}'")).unwrap_or_default()),
            None => "the default material".to_string(),
        };
        let pbr = m.pbr_metallic_roughness();
        let [r, g, b, a] = pbr.base_color_factor();
        let base = Vec3::new(r, g, b);
        if !(base.is_finite() && base.min_element() >= 0.0 && base.max_element() <= 1.0 && (0.0..=1.0).contains(&a)) {
            return Err(self.err(format!("{name}: baseColorFactor {:?} is outside [0, 1]", pbr.base_color_factor())));
        }
        let mut maps = MaterialMaps::default();
        if let Some(info) = pbr.base_color_texture() {
            if info.tex_coord() != 0 {
                self.warn(format!("{name}: baseColorTexture reads TEXCOORD_{}; TEXCOORD_0 is used", info.tex_coord()));
            }
            maps.color = Some(self.colour_texture(info.texture(), info.texture_transform())?);
        }
        match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => {}
            mode => {
                let cutoff = m.alpha_cutoff().unwrap_or(0.5);
                let mask = mode == gltf::material::AlphaMode::Mask;
                let map = move |x: f32| if mask { if x >= cutoff { 1.0 } else { 0.0 } } else { x };
                maps.opacity = Some(match pbr.base_color_texture() {
                    Some(info) => Opacity::Texture(self.alpha_texture(info.texture(), info.texture_transform(), a, map)?),
                    None => Opacity::Constant(map(a)),
                });
            }
        }
        if let Some(info) = m.normal_texture() {
            if info.tex_coord() != 0 {
                self.warn(format!("{name}: normalTexture reads TEXCOORD_{}; TEXCOORD_0 is used", info.tex_coord()));
            }
            let scale = info.scale();
            if !scale.is_finite() {
                return Err(self.err(format!("{name}: normalTexture scale {scale} is not finite")));
            }
            let texture = self.raw_texture(info.texture(), None)?;
            maps.normal = Some(NormalPerturbation::NormalMap { texture, scale, handedness: Handedness::FollowTextureCoordinates });
        }
        let (mut metallic, mut roughness) = (pbr.metallic_factor().clamp(0.0, 1.0), pbr.roughness_factor().clamp(0.0, 1.0));
        if let Some(info) = pbr.metallic_roughness_texture() {
            // One scattering kind per material: the texture's means pick it.
            let (bytes, path) = self.image_bytes(&info.texture().source())?;
            let d = bitmap::decode(&bytes, &path, true)?;
            let n = d.texels.len().max(1) as f64;
            let (g, b) = (0..d.texels.len()).map(|i| d.texels.linear(i)).fold((0.0, 0.0), |(g, b), t| (g + t.y as f64, b + t.z as f64));
            roughness = (roughness as f64 * g / n).clamp(0.0, 1.0) as f32;
            metallic = (metallic as f64 * b / n).clamp(0.0, 1.0) as f32;
            self.warn(format!("{name}: metallicRoughnessTexture is read by its means (metallic {metallic:.3}, roughness {roughness:.3}): one scattering kind per material"));
        }
        let alpha = roughness * roughness;
        let transmission = m.transmission().map_or(0.0, |t| t.transmission_factor());
        let material = if transmission >= 0.5 {
            let ior = m.ior().unwrap_or(1.5);
            if !(ior.is_finite() && ior > 0.0) {
                return Err(self.err(format!("{name}: KHR_materials_ior {ior} is not a positive index")));
            }
            Material::Dielectric { ior, transmittance: base, roughness: alpha }
        } else if metallic >= 0.5 {
            Material::Conductor { reflectance: base, roughness: alpha }
        } else {
            Material::Diffuse { albedo: base }
        };
        let strength = m.emissive_strength().unwrap_or(1.0);
        let e = Vec3::from_array(m.emissive_factor()) * strength;
        let emission = if e.max_element() > 0.0 && e.is_finite() {
            let t = match m.emissive_texture() {
                Some(info) => Some(self.colour_texture(info.texture(), info.texture_transform())?),
                None => None,
            };
            Some((e, t))
        } else {
            None
        };
        self.materials.push(material);
        self.maps.push(maps);
        let id = (self.materials.len() - 1) as u32;
        self.material_ids.insert(m.index(), (id, emission));
        Ok((id, emission))
    }
}

/// A glTF `TEXCOORD_0` in arpa's texture coordinates: `(u, 1 − v)`, the conversion of
/// `../shared/scenes/crytek-sponza/convert_gltf.py` (whose Mitsuba reference arpa's XML
/// loader matches): with it the glTF and XML forms of the shared Crytek Sponza read the same
/// texels.
fn flip_v(t: [f32; 2]) -> Vec2 {
    Vec2::new(t[0], 1.0 - t[1])
}

/// `%xx` escapes of a relative URI decoded (file names with spaces).
fn percent_decode(uri: &str) -> String {
    let b = uri.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%'
            && i + 2 < b.len()
            && let Some(v) = uri.get(i + 1..i + 3).and_then(|h| u8::from_str_radix(h, 16).ok())
        {
            out.push(v);
            i += 3;
            continue;
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}

/// What the scene's node walk collects.
#[derive(Default)]
struct Walk {
    meshes: Vec<TriangleMesh>,
    emission_textures: Vec<Option<TextureId>>,
    lights: Vec<Light>,
    /// (camera index, node name, world matrix), in node order.
    cameras: Vec<(usize, String, DMat4)>,
    /// Every placement of a mesh, as an instance of its triangle primitives.
    instancing: Instancing,
    /// The prototype of each (mesh index, placed mirrored) in `instancing`: a mirroring
    /// placement reverses the winding, so its copies have other triangles.
    prototypes: HashMap<(usize, bool), u32>,
}

/// Loads the glTF (or GLB) file `bytes`; `path` names it and resolves its relative URIs,
/// which `read` reads.
pub fn load(bytes: &[u8], path: &Path, read: MeshReader<'_>, options: &GltfOptions) -> R<LoadedScene> {
    let parse_error = |e: gltf::Error| SceneFileError::Gltf { path: path.to_path_buf(), message: e.to_string() };
    // A GLB header whose length is below the header's own 12 bytes underflows in the gltf
    // crate's reader (found by fuzzing).
    if bytes.starts_with(b"glTF") {
        let length = bytes.get(8..12).map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
        if length.is_none_or(|l| l < 12) {
            return Err(SceneFileError::Gltf { path: path.to_path_buf(), message: format!("GLB header: length {length:?} is shorter than the 12-byte header") });
        }
    }
    // The gltf crate's validation indexes a primitive's POSITION accessor before checking
    // it exists (gltf-json 1.4.1, found by fuzzing): check the indices it uses first.
    {
        let unchecked = gltf::Gltf::from_slice_without_validation(bytes).map_err(parse_error)?;
        let root = unchecked.document.as_json();
        for (mi, m) in root.meshes.iter().enumerate() {
            for (pi, p) in m.primitives.iter().enumerate() {
                if let Some((_, a)) = p.attributes.iter().find(|(_, a)| a.value() >= root.accessors.len()) {
                    return Err(SceneFileError::Gltf { path: path.to_path_buf(), message: format!("mesh {mi} primitive {pi}: accessor {} does not exist ({} accessors)", a.value(), root.accessors.len()) });
                }
            }
        }
    }
    let gltf = gltf::Gltf::from_slice(bytes).map_err(parse_error)?;
    let doc = &gltf.document;
    let mut l = Loader {
        path,
        doc,
        read,
        buffers: Vec::new(),
        warnings: Vec::new(),
        textures: Vec::new(),
        colour_cache: HashMap::new(),
        materials: Vec::new(),
        maps: Vec::new(),
        material_ids: HashMap::new(),
    };
    let required: Vec<&str> = doc.extensions_required().filter(|e| !SUPPORTED.contains(e)).collect();
    if !required.is_empty() {
        return Err(l.err(format!("requires extensions arpa does not support: {}", required.join(", "))));
    }
    for e in doc.extensions_used().filter(|e| !SUPPORTED.contains(e)) {
        let why = if IGNORED.contains(&e) { "ignored (thickness and attenuation are not modelled)" } else { "not supported; ignored" };
        l.warn(format!("extension {e}: {why}"));
    }
    for b in doc.buffers() {
        let data = match b.source() {
            gltf::buffer::Source::Bin => gltf.blob.clone().ok_or_else(|| l.err(format!("buffer {} is the GLB binary chunk, which the file lacks", b.index())))?,
            gltf::buffer::Source::Uri(uri) => l.uri_bytes(uri, &format!("buffer {}", b.index()))?.0,
        };
        if data.len() < b.length() {
            return Err(l.err(format!("buffer {}: {} bytes, its length says {}", b.index(), data.len(), b.length())));
        }
        l.buffers.push(data);
    }
    let scene = doc.default_scene().or_else(|| doc.scenes().next()).ok_or_else(|| l.err("the file has no scene"))?;
    let mut walk = Walk::default();
    let mut stack: Vec<(gltf::Node<'_>, DMat4, usize)> = scene.nodes().map(|n| (n, DMat4::IDENTITY, 0)).collect();
    stack.reverse();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > 256 {
            return Err(l.err(format!("node {}: the node tree is deeper than 256 (a cycle?)", node.index())));
        }
        let local = DMat4::from_cols_array_2d(&node.transform().matrix().map(|c| c.map(|x| x as f64)));
        let world = parent * local;
        if !world.is_finite() {
            return Err(l.err(format!("node {}: its world matrix is not finite", node.index())));
        }
        if let Some(mesh) = node.mesh() {
            place_mesh(&mut l, &mut walk, &node, &mesh, world)?;
        }
        if let Some(c) = node.camera() {
            walk.cameras.push((c.index(), node.name().unwrap_or("").to_string(), world));
        }
        if let Some(light) = node.light() {
            walk.lights.push(punctual(&l, &light, world, options.light_scale)?);
        }
        let children: Vec<_> = node.children().collect();
        for c in children.into_iter().rev() {
            stack.push((c, world, depth + 1));
        }
    }
    // The camera: by name (camera or node), else the first of camera index 0, else the first.
    let pick = match &options.camera {
        Some(name) => walk
            .cameras
            .iter()
            .find(|(i, node, _)| node == name || doc.cameras().nth(*i).and_then(|c| c.name().map(|n| n == name)).unwrap_or(false))
            .ok_or_else(|| l.err(format!("no camera named '{name}'")))?,
        None => walk.cameras.iter().find(|(i, ..)| *i == 0).or(walk.cameras.first()).ok_or_else(|| l.err("the scene places no camera"))?,
    };
    let (ci, _, m) = *pick;
    let cam = doc.cameras().nth(ci).ok_or_else(|| l.err(format!("camera {ci} missing")))?;
    let gltf::camera::Projection::Perspective(p) = cam.projection() else {
        return Err(l.err(format!("camera {ci}: only perspective cameras are supported")));
    };
    let aspect = p.aspect_ratio().filter(|a| a.is_finite() && *a > 0.0).unwrap_or(16.0 / 9.0);
    let (width, height) = (DEFAULT_WIDTH, ((DEFAULT_WIDTH as f32 / aspect).round() as u32).max(1));
    let position = m.transform_point3(DVec3::ZERO);
    let forward = m.transform_vector3(-DVec3::Z).normalize_or(-DVec3::Z);
    let up = m.transform_vector3(DVec3::Y).normalize_or(DVec3::Y);
    let yfov = p.yfov() as f64;
    if !(yfov > 0.0 && yfov < std::f64::consts::PI) {
        return Err(l.err(format!("camera {ci}: yfov {yfov} is not in (0, π)")));
    }
    let camera = Camera { position: position.as_vec3(), target: (position + forward).as_vec3(), up: up.as_vec3(), vertical_fov: yfov as f32, width, height };
    let scene = Scene {
        meshes: walk.meshes,
        materials: l.materials,
        lights: walk.lights,
        camera,
        roughness_cutoff: ROUGHNESS_CUTOFF,
        instancing: walk.instancing.shared_only(),
        textures: SceneTextures { textures: l.textures, maps: l.maps, emission: walk.emission_textures, environment: None },
    };
    scene.validate().map_err(|source| SceneFileError::Scene { path: path.to_path_buf(), source })?;
    Ok(LoadedScene { scene, warnings: l.warnings, path: path.to_path_buf(), max_depth: None, sample_count: None, fov_degrees: yfov.to_degrees(), fov_axis: FovAxis::Y })
}

/// The meshes of `mesh`'s triangle primitives placed by `world`.
fn place_mesh(l: &mut Loader<'_>, walk: &mut Walk, node: &gltf::Node<'_>, mesh: &gltf::Mesh<'_>, world: DMat4) -> R<()> {
    let normal_matrix = DMat3::from_mat4(world).inverse().transpose();
    let mirrored = DMat3::from_mat4(world).determinant() < 0.0;
    let first = walk.meshes.len() as u32;
    let mut prototype = Vec::new();
    for prim in mesh.primitives() {
        let what = format!("mesh {}{} primitive {}", mesh.index(), mesh.name().map(|n| format!(" '{n}'")).unwrap_or_default(), prim.index());
        if prim.mode() != gltf::mesh::Mode::Triangles {
            l.warn(format!("{what}: mode {:?} is not triangles; skipped", prim.mode()));
            continue;
        }
        use gltf::accessor::{DataType as T, Dimensions as D};
        let Some(pos) = prim.get(&gltf::Semantic::Positions) else { return Err(l.err(format!("{what}: no POSITION"))) };
        l.check_accessor(&pos, &format!("{what} POSITION"), &[(D::Vec3, T::F32)])?;
        let normals_acc = prim.get(&gltf::Semantic::Normals);
        if let Some(a) = &normals_acc {
            l.check_accessor(a, &format!("{what} NORMAL"), &[(D::Vec3, T::F32)])?;
        }
        let uv_acc = prim.get(&gltf::Semantic::TexCoords(0));
        if let Some(a) = &uv_acc {
            l.check_accessor(a, &format!("{what} TEXCOORD_0"), &[(D::Vec2, T::F32), (D::Vec2, T::U8), (D::Vec2, T::U16)])?;
        }
        if let Some(a) = prim.indices() {
            l.check_accessor(&a, &format!("{what} indices"), &[(D::Scalar, T::U8), (D::Scalar, T::U16), (D::Scalar, T::U32)])?;
        }
        let buffers = &l.buffers;
        let reader = prim.reader(|b| buffers.get(b.index()).map(|v| &v[..]));
        let positions: Vec<[f32; 3]> = reader.read_positions().ok_or_else(|| l.err(format!("{what}: POSITION unreadable")))?.collect();
        if let Some(v) = positions.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
            return Err(l.err(format!("{what}: POSITION (accessor {}) vertex {v} is not finite", pos.index())));
        }
        let n = positions.len();
        let indices: Vec<u32> = match reader.read_indices() {
            Some(i) => i.into_u32().collect(),
            None => (0..n as u32).collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= n) {
            return Err(l.err(format!("{what}: index {bad} beyond its {n} vertices")));
        }
        let normals: Option<Vec<[f32; 3]>> = reader.read_normals().map(|r| r.collect());
        let uvs: Option<Vec<[f32; 2]>> = reader.read_tex_coords(0).map(|r| r.into_f32().collect());
        if normals.as_ref().is_some_and(|v| v.len() != n) || uvs.as_ref().is_some_and(|v| v.len() != n) {
            return Err(l.err(format!("{what}: NORMAL or TEXCOORD_0 count differs from POSITION's {n}")));
        }
        let mut tris: Vec<[u32; 3]> = indices.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect();
        if mirrored {
            tris.iter_mut().for_each(|t| t.swap(1, 2));
        }
        let world_p: Vec<Vec3> = positions.iter().map(|p| world.transform_point3(Vec3::from_array(*p).as_dvec3()).as_vec3()).collect();
        if let Some(v) = world_p.iter().position(|p| !p.is_finite()) {
            return Err(l.err(format!("{what}: vertex {v} is not finite after node {}'s transform", node.index())));
        }
        let normals = match normals {
            Some(ns) if ns.iter().all(|v| v.iter().all(|x| x.is_finite())) => {
                Some(ns.iter().map(|v| (normal_matrix * Vec3::from_array(*v).as_dvec3()).normalize_or(DVec3::Y).as_vec3()).collect())
            }
            Some(_) => {
                l.warn(format!("{what}: NORMAL has non-finite values; shaded with face normals"));
                None
            }
            None => None,
        };
        let uvs = uvs.map(|v| v.iter().map(|t| flip_v(*t)).collect::<Vec<_>>()).filter(|v: &Vec<Vec2>| v.iter().all(|t| t.is_finite()));
        let (material, emission) = l.material(prim.material())?;
        prototype.push(PrototypeMesh { positions: positions.iter().map(|p| Vec3::from_array(*p)).collect(), indices: tris.clone() });
        walk.meshes.push(TriangleMesh {
            name: format!("{} {what}", node.name().unwrap_or("node")),
            positions: world_p,
            normals,
            uvs,
            indices: tris,
            material,
            emission: emission.map(|e| e.0),
        });
        walk.emission_textures.push(emission.and_then(|e| e.1));
    }
    if !prototype.is_empty() {
        let name = format!("mesh {}{}", mesh.index(), mesh.name().map(|n| format!(" '{n}'")).unwrap_or_default());
        let instancing = &mut walk.instancing;
        let prototype = *walk.prototypes.entry((mesh.index(), mirrored)).or_insert_with(|| {
            instancing.prototypes.push(Prototype { name, meshes: prototype });
            (instancing.prototypes.len() - 1) as u32
        });
        let meshes = (first..walk.meshes.len() as u32).collect();
        walk.instancing.instances.push(Instance { prototype, to_world: DAffine3::from_mat4(world), meshes });
    }
    Ok(())
}

/// A `KHR_lights_punctual` light placed by `world`.
fn punctual(l: &Loader<'_>, light: &gltf::khr_lights_punctual::Light<'_>, world: DMat4, scale: f64) -> R<Light> {
    let what = format!("light {}{}", light.index(), light.name().map(|n| format!(" '{n}'")).unwrap_or_default());
    let colour = Vec3::from_array(light.color()).as_dvec3() * (light.intensity() as f64 * scale / LUMENS_PER_WATT);
    if !(colour.is_finite() && colour.min_element() >= 0.0) {
        return Err(l.err(format!("{what}: colour × intensity is negative or not finite")));
    }
    let position = world.transform_point3(DVec3::ZERO);
    let direction = world.transform_vector3(-DVec3::Z).normalize_or(-DVec3::Z);
    Ok(match light.kind() {
        gltf::khr_lights_punctual::Kind::Point => Light::Point(PointLight { position, intensity: colour }),
        gltf::khr_lights_punctual::Kind::Directional => Light::Directional(DirectionalLight { direction, irradiance: colour }),
        gltf::khr_lights_punctual::Kind::Spot { inner_cone_angle, outer_cone_angle } => {
            let (inner, outer) = (inner_cone_angle as f64, outer_cone_angle as f64);
            if !(outer > 0.0 && outer <= std::f64::consts::FRAC_PI_2 && inner >= 0.0 && inner <= outer) {
                return Err(l.err(format!("{what}: cone angles {inner}, {outer} are not 0 <= inner <= outer <= π/2")));
            }
            Light::Spot(SpotLight { position, direction, intensity: colour, cutoff: outer, beam_width: inner, falloff: SpotFalloff::SmoothstepAngle })
        }
    })
}
