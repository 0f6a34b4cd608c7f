//! WGSL ray-tracing stages compiled to SPIR-V at run time with naga 30
//! (`enable wgpu_ray_tracing_pipeline;`: `@ray_generation`, `@miss`, `@closest_hit`,
//! `@any_hit`, `var<ray_payload>`, `var<incoming_ray_payload>`, `traceRay`), and this crate's
//! own WGSL files, composed with the core's by [`arpa_core::shaders::compose`].
//!
//! What naga 30 cannot express, and what that means here:
//! - no intersection stage and no `ignoreIntersection`/`reportIntersection` (the gather's AABB
//!   hit group needs both);
//! - no hit attributes (`HitAttributeKHR`): a closest-hit shader cannot read the triangle
//!   barycentrics the traversal computed, so [`RAY_CAST`] recomputes them from the scene
//!   table's vertices;
//! - `@builtin(primitive_index)` makes naga declare the SPIR-V `Geometry` capability even in
//!   hit shaders, so the device enables `geometryShader` (lavapipe and NVIDIA have it);
//! - `traceRay` always passes SBT record offset 0, SBT stride 0 and miss index 0: one miss
//!   shader per pipeline, and the hit group comes from the instance's
//!   `instanceShaderBindingTableRecordOffset` alone.

use crate::error::VkError;
use arpa_core::shaders::{SCENE, WgslFile};

/// The SPIR-V version of the modules (ray-tracing pipelines need Vulkan 1.2, which takes 1.5;
/// 1.4 is what `VK_KHR_ray_tracing_pipeline` is specified against).
pub const SPIRV_VERSION: (u8, u8) = (1, 4);

/// Closest-hit ray casting (`arpa-vk/shaders/ray_cast.wgsl`): entry points
/// `vk_cast_raygen`, `vk_cast_miss`, `vk_cast_closest_hit`; needs the core's `scene.wgsl`
/// (its bind group 0 with the top-level structure at binding 0) — compose with
/// [`ray_cast_source`].
pub const RAY_CAST: WgslFile =
    WgslFile { name: "arpa-vk/ray_cast.wgsl", source: include_str!("../shaders/ray_cast.wgsl"), deps: &[&SCENE] };

/// The composed WGSL of [`RAY_CAST`] and the core files it needs.
pub fn ray_cast_source() -> String {
    arpa_core::shaders::compose(&[&RAY_CAST])
}

/// A WGSL module as SPIR-V words, with the names of its entry points.
#[derive(Clone, Debug)]
pub struct SpirvModule {
    /// The label given to [`compile_wgsl`].
    pub label: String,
    /// SPIR-V words (every entry point of the source).
    pub words: Vec<u32>,
    /// `(stage, name)` of each entry point.
    pub entry_points: Vec<(naga::ShaderStage, String)>,
}

/// Parses, validates (all capabilities, ray-tracing pipelines included) and translates
/// `source` to SPIR-V [`SPIRV_VERSION`]. `traceRay` argument validation stays on (naga skips a
/// trace whose `t_min`/`t_max` are invalid, leaving the payload as the caller set it).
///
/// Errors: [`VkError::Shader`] with naga's diagnostic.
pub fn compile_wgsl(label: &str, source: &str) -> Result<SpirvModule, VkError> {
    let err = |message: String| VkError::Shader { label: label.into(), message };
    let module = naga::front::wgsl::parse_str(source).map_err(|e| err(e.emit_to_string(source)))?;
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .map_err(|e| err(e.emit_to_string(source)))?;
    let options = naga::back::spv::Options {
        lang_version: SPIRV_VERSION,
        flags: naga::back::spv::WriterFlags::empty(),
        ..naga::back::spv::Options::default()
    };
    let words = naga::back::spv::write_vec(&module, &info, &options, None).map_err(|e| err(e.to_string()))?;
    let entry_points = module.entry_points.iter().map(|e| (e.stage, e.name.clone())).collect();
    Ok(SpirvModule { label: label.into(), words, entry_points })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ray_cast_compiles_with_its_three_stages() {
        let m = compile_wgsl("ray cast", &ray_cast_source()).expect("ray_cast.wgsl compiles");
        assert_eq!(m.words[0], 0x0723_0203, "SPIR-V magic");
        let names: Vec<_> = m.entry_points.iter().map(|(s, n)| (*s, n.as_str())).collect();
        for want in [
            (naga::ShaderStage::RayGeneration, "vk_cast_raygen"),
            (naga::ShaderStage::Miss, "vk_cast_miss"),
            (naga::ShaderStage::ClosestHit, "vk_cast_closest_hit"),
        ] {
            assert!(names.contains(&want), "{names:?}");
        }
    }

    #[test]
    fn errors_carry_naga_diagnostics() {
        let e = compile_wgsl("broken", "enable wgpu_ray_tracing_pipeline;\n@ray_generation fn f() { let x: u32 = 1.5; }").unwrap_err();
        assert!(matches!(&e, VkError::Shader { label, .. } if label == "broken"), "{e}");
    }
}
