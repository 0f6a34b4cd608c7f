//! Interpretation of a Mitsuba 3 scene tree (see the module docs of [`super`] for the
//! supported subset and the mappings), one module per plugin kind as in Mitsuba's own
//! source tree: [`bsdf`], [`emitter`], [`shape`], [`sensor`]; [`loader`] holds the state
//! and the property access they share.

mod bsdf;
mod emitter;
mod loader;
mod sensor;
mod shape;
mod texture;

pub use bsdf::ROUGHNESS_CUTOFF;

use super::error::SceneFileError;
use super::loaded::LoadedScene;
use super::mesh::MeshReader;
use super::xml::{self, Node};
use arpa_core::render::scene::{Scene, SceneTextures};
use loader::{Loader, R};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// Mitsuba 3's integrators (arpa renders every scene with its photon mapper; another type
/// is a warning).
const INTEGRATORS: &[&str] = &["path", "volpath", "volpathmis", "ptracer", "direct", "aov", "prb", "prb_basic", "prb_projective", "direct_projective", "prbvolpath", "depth", "moment", "stokes", "bdpt"];

/// The scene file format versions read as they are (Mitsuba 2 and 3 share parameter names).
fn version_supported(v: &str) -> bool {
    v.trim().split('.').next().and_then(|m| m.parse::<u32>().ok()).is_some_and(|major| (2..=3).contains(&major))
}

impl Loader<'_> {
    fn scene(&mut self, root: &Node) -> R<()> {
        if root.tag != "scene" {
            return Err(self.invalid(root.line, format!("the root element is <{}>, expected <scene>", root.tag)));
        }
        if let Some(v) = root.attr("version")
            && !version_supported(v)
        {
            self.warn(root.line, format!("scene version {v}: arpa reads the parameter names of versions 2.x and 3.x (Mitsuba 3 upgrades older files when it loads them, arpa does not)"));
        }
        for c in &root.children {
            match c.tag.as_str() {
                "default" | "path" => {}
                "integrator" => {
                    let ty = c.attr("type").unwrap_or("");
                    if !INTEGRATORS.contains(&ty) {
                        self.warn(c.line, format!("{}: an integrator arpa does not know; arpa renders with its own photon mapper (only max_depth is read)", c.describe()));
                    }
                    let p = self.props(c);
                    if let Some(d) = self.integer(&p, "max_depth")? {
                        self.max_depth = u32::try_from(d).ok();
                    }
                    self.consume_all(&p); // arpa uses its own photon-mapping integrator
                }
                "sensor" => self.sensor(c)?,
                "bsdf" => {
                    let b = self.bsdf(c)?;
                    match c.attr("id") {
                        Some(id) => {
                            if self.bsdfs.insert(id.to_string(), (b, None)).is_some() {
                                return Err(self.invalid(c.line, format!("duplicate id '{id}'")));
                            }
                        }
                        None => self.warn(c.line, "a top-level <bsdf> without an id is never used"),
                    }
                }
                "shape" => self.shape(c)?,
                "texture" => {
                    let Some(id) = c.attr("id") else {
                        self.warn(c.line, "a top-level <texture> without an id is never used");
                        continue;
                    };
                    let t = self.texture(c)?;
                    if self.texture_ids.insert(id.to_string(), t).is_some() || self.bsdfs.contains_key(id) {
                        return Err(self.invalid(c.line, format!("duplicate id '{id}'")));
                    }
                }
                "emitter" => self.emitter(c)?,
                "medium" | "include" | "spectrum" | "film" | "sampler" => {
                    return Err(self.unsupported(c, "not supported by the arpa scene loader"));
                }
                _ => return Err(self.unsupported(c, "unknown top-level element")),
            }
        }
        Ok(())
    }
}

/// Loads a scene from its XML text; `path` names it in messages and its directory
/// resolves mesh file names, which `read_mesh` reads.
pub(crate) fn load_str(text: &str, path: &Path, defines: &[(String, String)], read_mesh: MeshReader<'_>) -> R<LoadedScene> {
    let mut root = xml::parse(text, path)?;
    let mut params: HashMap<String, String> = HashMap::new();
    for c in root.children.iter().filter(|c| c.tag == "default") {
        let (Some(name), Some(value)) = (c.attr("name"), c.attr("value")) else {
            return Err(SceneFileError::Invalid { path: path.to_path_buf(), line: c.line, message: "<default> needs 'name' and 'value'".into() });
        };
        params.insert(name.to_string(), value.to_string());
    }
    for (k, v) in defines {
        params.insert(k.clone(), v.clone());
    }
    xml::substitute(&mut root, &params, path)?;
    let base = path.parent().map(Path::to_path_buf).unwrap_or_default();
    // <path value="dir"/> anywhere at the top level applies to every file the scene names
    // (Mitsuba instantiates objects after parsing the whole file); the last one is searched
    // first, the scene's directory last.
    let mut search: Vec<PathBuf> = Vec::new();
    for c in root.children.iter().filter(|c| c.tag == "path") {
        let Some(v) = c.attr("value") else {
            return Err(SceneFileError::Invalid { path: path.to_path_buf(), line: c.line, message: "<path> lacks the attribute 'value'".into() });
        };
        search.insert(0, base.join(v));
    }
    search.push(base.clone());
    let mut l = Loader {
        path,
        read_mesh,
        base,
        warnings: Default::default(),
        maps: Vec::new(),
        textures: Vec::new(),
        emission_textures: Vec::new(),
        texture_ids: HashMap::new(),
        search,
        bsdfs: HashMap::new(),
        default_material: None,
        materials: Vec::new(),
        meshes: Vec::new(),
        shapegroups: HashMap::new(),
        instancing: Default::default(),
        lights: Vec::new(),
        environment: None,
        camera: None,
        max_depth: None,
        sample_count: None,
    };
    l.scene(&root)?;
    let Some((camera, fov_degrees, fov_axis)) = l.camera else {
        return Err(SceneFileError::Invalid { path: path.to_path_buf(), line: root.line, message: "the scene has no <sensor type=\"perspective\">".into() });
    };
    let scene = Scene { textures: SceneTextures { textures: l.textures, maps: l.maps, emission: l.emission_textures, environment: l.environment }, meshes: l.meshes, materials: l.materials, lights: l.lights, camera, roughness_cutoff: ROUGHNESS_CUTOFF, instancing: (!l.instancing.instances.is_empty()).then_some(l.instancing) };
    scene.validate().map_err(|source| SceneFileError::Scene { path: path.to_path_buf(), source })?;
    Ok(LoadedScene { scene, warnings: l.warnings.into_inner(), path: path.to_path_buf(), max_depth: l.max_depth, sample_count: l.sample_count, fov_degrees, fov_axis })
}
