//! Bsdf plugins: each Mitsuba bsdf mapped onto the materials the photon mapper models
//! (diffuse, perfect mirror, smooth dielectric, thin dielectric sheet; rough ones by the roughness cut-off),
//! and the adapters that wrap one: `twosided`, `mask` (opacity), `normalmap` and `bumpmap`
//! (shading normals, [`arpa_core::propagate::normal_map`]); `null` is a surface every ray
//! passes (opacity 0), whose area light still shines and is seen; `blendbsdf` scatters each
//! hit as one of its two bsdfs, the second with probability `weight`.

use super::loader::{num, Bsdf, Loader, Props, R};
use super::super::spectrum::SpectrumUse;
use super::super::transform;
use super::super::xml::Node;
use arpa_core::propagate::fresnel::conductor_albedo;
use arpa_core::render::scene::{Blend, BlendWeight, Handedness, Material, MaterialId, MaterialMaps, NormalPerturbation, Opacity};
use arpa_core::render::texture::{Texture, TextureId};
use glam::{DVec3, Vec3};

/// Roughness cut-off of loaded scenes, in GGX `alpha`: a rough conductor or dielectric
/// with `alpha >= 0.25` is rendered as diffuse, a smoother one as perfectly specular.
///
/// This is RTPM's rule: RTPM (Falcor) treats a reflection as diffuse when the material's
/// *linear* roughness `r = sqrt(alpha)` exceeds 0.5, so the cut-off on `alpha` is
/// `0.5² = 0.25`. The boundary is inclusive because the one shared scene that sits on it,
/// veach-bidir's lamp (pbrt/Mitsuba `alpha` 0.25, i.e. `r` = 0.5), is diffuse in the scene
/// RTPM and the ARPA paper rendered (its pyscene sets `r` = 0.51), and the Mitsuba `path`
/// reference agrees with the diffuse reading (ceiling and lamp region means within 1 %,
/// against +7 % and −24 % for the mirror reading; see the README's accuracy section).
pub const ROUGHNESS_CUTOFF: f32 = 0.25;

/// Normal-incidence reflectance (linear RGB) of Mitsuba's named conductor `material`s
/// (Naty Hoffman's table of metal F0 values; rounded).
const METALS: &[(&str, [f32; 3])] = &[
    ("Ag", [0.972, 0.960, 0.915]),
    ("Al", [0.913, 0.922, 0.924]),
    ("Au", [1.000, 0.766, 0.336]),
    ("Cr", [0.549, 0.556, 0.554]),
    ("Cu", [0.955, 0.638, 0.538]),
    ("Ni_palik", [0.660, 0.609, 0.526]),
    ("Pt", [0.673, 0.637, 0.585]),
    ("Fe", [0.562, 0.565, 0.578]),
    ("Ti", [0.542, 0.497, 0.449]),
    ("W", [0.504, 0.498, 0.478]),
];

/// Reflectance used for a named conductor material missing from [`METALS`].
const UNKNOWN_METAL: f32 = 0.9;

/// Mitsuba's named indices of refraction.
const IORS: &[(&str, f64)] = &[
    ("vacuum", 1.0),
    ("helium", 1.000036),
    ("hydrogen", 1.000132),
    ("air", 1.000277),
    ("carbon dioxide", 1.00045),
    ("water", 1.3330),
    ("acetone", 1.36),
    ("ethanol", 1.361),
    ("carbon tetrachloride", 1.461),
    ("glycerol", 1.4729),
    ("benzene", 1.501),
    ("silicone oil", 1.52045),
    ("bromine", 1.661),
    ("water ice", 1.31),
    ("fused quartz", 1.458),
    ("pyrex", 1.470),
    ("acrylic glass", 1.49),
    ("polypropylene", 1.49),
    ("bk7", 1.5046),
    ("sodium chloride", 1.544),
    ("amber", 1.55),
    ("pet", 1.5750),
    ("diamond", 2.419),
];

impl Loader<'_> {
    pub(super) fn bsdf(&mut self, n: &Node) -> R<Bsdf> {
        let ty = n.attr("type").unwrap_or("");
        let p = self.props(n);
        let rough_note = |alpha: f64| {
            if alpha as f32 >= ROUGHNESS_CUTOFF {
                format!("alpha {alpha} >= roughness cut-off {ROUGHNESS_CUTOFF}: rendered as diffuse (RTPM's rule)")
            } else {
                format!("alpha {alpha} < roughness cut-off {ROUGHNESS_CUTOFF}: rendered as a perfect specular surface (RTPM's rule)")
            }
        };
        let one_sided = |me: &mut Self, albedo: DVec3| {
            if albedo.max_element() > 0.0 {
                me.warn(n.line, format!("{} is not wrapped in <bsdf type=\"twosided\">: Mitsuba renders its back side black, arpa renders both sides", n.describe()));
            }
        };
        let mut maps = MaterialMaps::default();
        let material = match ty {
            "mask" => {
                let inner = self.objects(&p, &["bsdf"]);
                if inner.len() != 1 {
                    return Err(self.invalid(n.line, "mask needs exactly one nested <bsdf>"));
                }
                let opacity = match self.texture_of(&p, "opacity")? {
                    Some(id) => Opacity::Texture(id),
                    None => {
                        // Mitsuba reads a constant's single value: the mean of an <rgb>.
                        let line = self.line_of(&p, "opacity");
                        let o = self.rgb(&p, "opacity", SpectrumUse::Reflectance)?.map_or(0.5, |v| (v.x + v.y + v.z) / 3.0);
                        if !(0.0..=1.0).contains(&o) {
                            return Err(self.invalid(line, format!("opacity {} is outside [0, 1]", num(o))));
                        }
                        Opacity::Constant(o as f32)
                    }
                };
                self.finish(&p);
                let mut b = self.bsdf(inner[0])?;
                if b.maps.opacity.is_some() {
                    return Err(self.unsupported(inner[0], "a mask inside a mask is not supported"));
                }
                b.maps.opacity = Some(opacity);
                return Ok(b);
            }
            "blendbsdf" => {
                let inner = self.objects(&p, &["bsdf"]);
                if inner.len() != 2 {
                    return Err(self.invalid(n.line, format!("blendbsdf needs exactly two nested <bsdf>, found {}", inner.len())));
                }
                let weight = match self.texture_of(&p, "weight")? {
                    Some(id) => BlendWeight::Texture(id),
                    None => {
                        let w = self.float(&p, "weight")?.unwrap_or(0.5);
                        if !(0.0..=1.0).contains(&w) {
                            return Err(self.invalid(self.line_of(&p, "weight"), format!("blendbsdf weight {} is outside [0, 1]", num(w))));
                        }
                        BlendWeight::Constant(w as f32)
                    }
                };
                self.finish(&p);
                let first = self.bsdf(inner[0])?;
                let second = self.bsdf(inner[1])?;
                for (b, node) in [(&first, inner[0]), (&second, inner[1])] {
                    if b.maps.opacity.is_some() || b.maps.normal.is_some() || b.maps.blend.is_some() {
                        return Err(self.unsupported(node, "a mask, normal map, bump map or blend inside a blendbsdf is not supported (wrap the blendbsdf instead)"));
                    }
                }
                let other = self.push_material(&second);
                let mut b = first;
                b.maps.blend = Some(Blend { other, weight });
                return Ok(b);
            }
            "null" => {
                // Invisible: every ray passes it (a mask of opacity 0); an area light on it
                // still emits and is seen by the camera rays passing it.
                self.finish(&p);
                maps.opacity = Some(Opacity::Constant(0.0));
                return Ok(Bsdf { material: Material::Diffuse { albedo: Vec3::ZERO }, maps });
            }
            "normalmap" | "bumpmap" => {
                let inner = self.objects(&p, &["bsdf"]);
                if inner.len() != 1 {
                    return Err(self.invalid(n.line, format!("{ty} needs exactly one nested <bsdf>")));
                }
                let map = if ty == "normalmap" {
                    let id = self.texture_of(&p, "normalmap")?.ok_or_else(|| self.invalid(n.line, "normalmap lacks <texture name=\"normalmap\"> (the tangent-space normals)"))?;
                    NormalPerturbation::NormalMap { texture: id, scale: 1.0, handedness: Handedness::RightHanded }
                } else {
                    let id = self.height_texture(&p, n)?;
                    if matches!(self.textures[id as usize], Texture::Checkerboard { .. }) {
                        return Err(self.unsupported(n, "bumpmap needs a bitmap height texture (a checkerboard has no gradient in Mitsuba 3 either)"));
                    }
                    let scale = self.float(&p, "scale")?.unwrap_or(1.0);
                    NormalPerturbation::BumpMap { texture: id, scale: scale as f32 }
                };
                self.finish(&p);
                let mut b = self.bsdf(inner[0])?;
                if b.maps.normal.is_some() {
                    return Err(self.unsupported(inner[0], "a normal or bump map inside another normal or bump map is not supported"));
                }
                b.maps.normal = Some(map);
                return Ok(b);
            }
            "twosided" => {
                let inner = self.objects(&p, &["bsdf"]);
                if inner.len() != 1 {
                    return Err(self.unsupported(n, "twosided needs exactly one nested <bsdf> (different front and back materials are not supported)"));
                }
                self.finish(&p);
                return self.bsdf_inner(inner[0]);
            }
            "diffuse" => {
                let (albedo, texture) = self.fraction_or_texture(&p, "reflectance", DVec3::splat(0.5))?;
                maps.color = texture;
                one_sided(self, albedo);
                Material::Diffuse { albedo: albedo.as_vec3() }
            }
            "dielectric" | "roughdielectric" => {
                let (ior, transmittance) = self.dielectric_interface(&p, n, "dielectric", &mut maps)?;
                let mut roughness = 0.0;
                if ty == "roughdielectric" {
                    roughness = self.alpha(&p)?;
                    let _ = self.string(&p, "distribution")?;
                    self.warn(n.line, format!("roughdielectric: {}", rough_note(roughness)));
                }
                Material::Dielectric { ior, transmittance, roughness: roughness as f32 }
            }
            "thindielectric" => {
                let (ior, transmittance) = self.dielectric_interface(&p, n, "thindielectric", &mut maps)?;
                Material::ThinDielectric { ior, transmittance }
            }
            "conductor" | "roughconductor" => {
                let (specular, texture) = self.fraction_or_texture(&p, "specular_reflectance", DVec3::ONE)?;
                maps.color = texture;
                let eta = self.rgb(&p, "eta", SpectrumUse::Unbounded)?;
                let k = self.rgb(&p, "k", SpectrumUse::Unbounded)?;
                let name = self.string(&p, "material")?;
                let base = match (eta, k, name.as_deref()) {
                    (Some(_), _, Some(_)) | (_, Some(_), Some(_)) => return Err(self.invalid(n.line, "give either 'material' or 'eta'/'k', not both")),
                    (None, None, None | Some("none")) => DVec3::ONE,
                    (None, None, Some(m)) => match METALS.iter().find(|(k, _)| *k == m) {
                        Some((_, rgb)) => Vec3::from_array(*rgb).as_dvec3(),
                        None => {
                            self.warn(n.line, format!("conductor material '{m}' is not in arpa's table of metals; using a gray reflectance of {UNKNOWN_METAL}"));
                            DVec3::splat(UNKNOWN_METAL as f64)
                        }
                    },
                    (eta, k, None) => {
                        // Mitsuba's defaults are those of its "none" material (eta 0, k 1).
                        let eta = eta.unwrap_or(DVec3::ZERO);
                        let k = k.unwrap_or(DVec3::ONE);
                        if !(eta.is_finite() && k.is_finite() && eta.min_element() >= 0.0 && k.min_element() >= 0.0) {
                            return Err(self.invalid(n.line, "conductor eta and k must be finite and non-negative"));
                        }
                        let r = DVec3::new(conductor_albedo(eta.x, k.x), conductor_albedo(eta.y, k.y), conductor_albedo(eta.z, k.z));
                        self.warn(
                            n.line,
                            format!("conductor eta/k rendered with the hemispherical average of its Fresnel reflectance ({:.3}, {:.3}, {:.3}) at every angle", r.x, r.y, r.z),
                        );
                        r
                    }
                };
                let _ = self.string(&p, "distribution")?;
                let roughness = if ty == "roughconductor" {
                    let a = self.alpha(&p)?;
                    self.warn(n.line, format!("roughconductor: {}", rough_note(a)));
                    a
                } else {
                    0.0
                };
                let reflectance = base * specular;
                one_sided(self, reflectance);
                Material::Conductor { reflectance: reflectance.as_vec3(), roughness: roughness as f32 }
            }
            "plastic" | "roughplastic" => {
                let (albedo, texture) = self.fraction_or_texture(&p, "diffuse_reflectance", DVec3::splat(0.5))?;
                maps.color = texture;
                for key in ["int_ior", "ext_ior", "specular_reflectance", "nonlinear", "alpha", "distribution"] {
                    let _ = self.find(&p, key);
                }
                self.warn(n.line, format!("{ty} is rendered as diffuse with its diffuse_reflectance; the specular coating is dropped"));
                one_sided(self, albedo);
                Material::Diffuse { albedo: albedo.as_vec3() }
            }
            "principled" => {
                // Mitsuba's principled BSDF onto the lobe its parameters make dominant:
                // spec_trans >= 0.5 a dielectric, else metallic >= 0.5 a conductor, else
                // the diffuse base; the roughness (alpha = roughness², Mitsuba's) then
                // picks smooth or diffuse by the cut-off, as for rough conductors.
                let (base, texture) = self.fraction_or_texture(&p, "base_color", DVec3::splat(0.5))?;
                maps.color = texture;
                let roughness = self.scalar_or_mean(&p, "roughness")?.unwrap_or(0.5);
                let metallic = self.scalar_or_mean(&p, "metallic")?.unwrap_or(0.0);
                let spec_trans = self.scalar_or_mean(&p, "spec_trans")?.unwrap_or(0.0);
                for (name, v) in [("roughness", roughness), ("metallic", metallic), ("spec_trans", spec_trans)] {
                    if !(0.0..=1.0).contains(&v) {
                        return Err(self.invalid(self.line_of(&p, name), format!("principled '{name}' {} is outside [0, 1]", num(v))));
                    }
                }
                let eta = match (self.float(&p, "eta")?, self.float(&p, "specular")?) {
                    (Some(e), _) => e,
                    // Mitsuba's relation between `specular` and the index of refraction.
                    (None, Some(sp)) => 2.0 / (1.0 - (0.08 * sp).max(0.0).sqrt()).max(1e-6) - 1.0,
                    (None, None) => 1.5,
                };
                if !(eta.is_finite() && eta > 0.0) {
                    return Err(self.invalid(n.line, format!("principled eta {} must be finite and positive", num(eta))));
                }
                let mut dropped = Vec::new();
                for key in ["anisotropic", "spec_tint", "sheen", "sheen_tint", "flatness", "clearcoat", "clearcoat_gloss"] {
                    if self.texture_of(&p, key)?.is_some() | self.find(&p, key).is_some() {
                        dropped.push(key);
                    }
                }
                for key in ["main_specular_sampling_rate", "clearcoat_sampling_rate", "diffuse_reflectance_sampling_rate"] {
                    let _ = self.find(&p, key);
                }
                if !dropped.is_empty() {
                    self.warn(n.line, format!("principled: {} not modelled by the photon mapper and ignored", dropped.join(", ")));
                }
                let alpha = roughness * roughness;
                let (material, what) = if spec_trans >= 0.5 {
                    (Material::Dielectric { ior: eta as f32, transmittance: base.as_vec3(), roughness: alpha as f32 }, format!("a dielectric of index {} tinted by base_color", num(eta)))
                } else if metallic >= 0.5 {
                    (Material::Conductor { reflectance: base.as_vec3(), roughness: alpha as f32 }, "a conductor of reflectance base_color".to_string())
                } else {
                    (Material::Diffuse { albedo: base.as_vec3() }, "diffuse with base_color (its specular lobe dropped)".to_string())
                };
                let rough = if matches!(material, Material::Diffuse { .. }) { String::new() } else { format!("; {}", rough_note(alpha)) };
                self.warn(n.line, format!("principled (metallic {}, spec_trans {}, roughness {}) is rendered as {what}{rough}", num(metallic), num(spec_trans), num(roughness)));
                material
            }
            _ => return Err(self.unsupported(n, "supported bsdfs: diffuse, dielectric, roughdielectric, thindielectric, conductor, roughconductor, plastic, roughplastic, principled, twosided, mask, normalmap, bumpmap, blendbsdf, null")),
        };
        self.objects(&p, &["texture"]).iter().try_for_each(|t| Err(self.unsupported(t, "a texture needs the name of the parameter it gives")))?;
        self.finish(&p);
        Ok(Bsdf { material, maps })
    }

    /// The bsdf inside `twosided` (no one-sided warning).
    pub(super) fn bsdf_inner(&mut self, n: &Node) -> R<Bsdf> {
        let before = self.warnings.borrow().len();
        let b = self.bsdf(n)?;
        let mut warnings = self.warnings.borrow_mut();
        let mut i = before;
        while i < warnings.len() {
            if warnings[i].message.contains("not wrapped in <bsdf type=\"twosided\">") {
                warnings.remove(i);
            } else {
                i += 1;
            }
        }
        drop(warnings);
        Ok(b)
    }

    /// A `bumpmap`'s height texture: its one nested `<texture>` (Mitsuba 3 takes it under
    /// any name) or a `<ref>` to a texture.
    fn height_texture(&mut self, p: &Props<'_>, n: &Node) -> R<TextureId> {
        let candidates: Vec<usize> = p
            .node
            .children
            .iter()
            .enumerate()
            .filter(|(_, c)| c.tag == "texture" || c.tag == "ref" && c.attr("id").is_some_and(|id| self.texture_ids.contains_key(id)))
            .map(|(i, _)| i)
            .collect();
        let [i] = candidates[..] else {
            return Err(self.invalid(n.line, format!("bumpmap needs exactly one nested <texture> (the height), found {}", candidates.len())));
        };
        p.used[i].set(true);
        let c = &p.node.children[i];
        if c.tag == "texture" {
            return self.texture(c);
        }
        Ok(self.texture_ids[c.attr("id").unwrap_or_default()])
    }

    /// What `dielectric` and `thindielectric` share: the relative index `int_ior / ext_ior`
    /// (Mitsuba's defaults; an error where it is not a positive `f32`) and
    /// `specular_transmittance` (its texture into `maps.color`), with a warning for a
    /// `specular_reflectance` other than 1 (`kind` names the plugin in it).
    fn dielectric_interface(&mut self, p: &Props<'_>, n: &Node, kind: &str, maps: &mut MaterialMaps) -> R<(f32, Vec3)> {
        let int = self.ior(p, "int_ior", 1.5046)?;
        let ext = self.ior(p, "ext_ior", 1.000277)?;
        let (transmittance, texture) = self.fraction_or_texture(p, "specular_transmittance", DVec3::ONE)?;
        maps.color = texture;
        if let Some(r) = self.rgb(p, "specular_reflectance", SpectrumUse::Reflectance)?
            && r != DVec3::ONE
        {
            self.warn(n.line, format!("{kind} specular_reflectance other than 1 is not supported and was ignored"));
        }
        let ior = (int / ext) as f32;
        if !(ior.is_finite() && ior > 0.0) {
            return Err(self.invalid(n.line, format!("int_ior / ext_ior = {} / {} is not a usable relative index of refraction (not a positive single-precision number)", num(int), num(ext))));
        }
        Ok((ior, transmittance.as_vec3()))
    }

    pub(super) fn ior(&self, p: &Props<'_>, name: &str, default: f64) -> R<f64> {
        let Some(n) = self.find(p, name) else { return Ok(default) };
        let s = self.value(n)?;
        let v = match n.tag.as_str() {
            "string" => IORS.iter().find(|(k, _)| k.eq_ignore_ascii_case(s.trim())).map(|(_, v)| *v).ok_or_else(|| self.invalid(n.line, format!("'{name}': unknown named IOR '{s}'")))?,
            _ => transform::number(s).map_err(|e| self.invalid(n.line, format!("'{name}': {e}")))?,
        };
        if !(v.is_finite() && v > 0.0) {
            return Err(self.invalid(n.line, format!("'{name}' is {}; an index of refraction must be finite and positive", num(v))));
        }
        Ok(v)
    }

    /// A scalar parameter that may be a texture (`None` when absent): a texture gives its
    /// mean single value ([`arpa_core::render::texture::Texture::mean_1`]), with a warning,
    /// for a parameter that picks one behaviour per material.
    pub(super) fn scalar_or_mean(&mut self, p: &Props<'_>, name: &str) -> R<Option<f64>> {
        let Some(id) = self.texture_of(p, name)? else { return self.float(p, name) };
        let v = self.textures[id as usize].mean_1() as f64;
        self.warn(self.line_of(p, name), format!("texture '{name}': the material is rendered by its mean {v:.4} (one scattering kind per material)"));
        Ok(Some(v))
    }

    /// A rough material's GGX `alpha` (`alpha`, or the mean of `alpha_u` and `alpha_v`;
    /// Mitsuba's default 0.1). A roughness texture gives its mean ([`Loader::scalar_or_mean`]):
    /// the roughness only picks the material's one scattering kind.
    pub(super) fn alpha(&mut self, p: &Props<'_>) -> R<f64> {
        let a = self.scalar_or_mean(p, "alpha")?;
        let (u, v) = (self.scalar_or_mean(p, "alpha_u")?, self.scalar_or_mean(p, "alpha_v")?);
        let a = match (a, u, v) {
            (Some(a), _, _) => a,
            (None, Some(u), Some(v)) => 0.5 * (u + v),
            (None, Some(x), None) | (None, None, Some(x)) => x,
            (None, None, None) => 0.1,
        };
        if a < 0.0 {
            return Err(self.invalid(p.node.line, format!("roughness alpha {a} is negative")));
        }
        Ok(a)
    }

    /// The material id of a top-level bsdf, created on first use.
    pub(super) fn material_of(&mut self, id: &str, line: usize) -> R<MaterialId> {
        let Some((b, mid)) = self.bsdfs.get(id).cloned() else {
            return Err(self.invalid(line, format!("<ref id=\"{id}\"> names no <bsdf> defined before it")));
        };
        if let Some(m) = mid {
            return Ok(m);
        }
        let m = self.push_material(&b);
        if let Some(e) = self.bsdfs.get_mut(id) {
            e.1 = Some(m);
        }
        Ok(m)
    }

    pub(super) fn push_material(&mut self, b: &Bsdf) -> MaterialId {
        self.materials.push(b.material);
        self.maps.push(b.maps);
        self.materials.len() as MaterialId - 1
    }
}
