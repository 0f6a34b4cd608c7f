//! WGSL ray-tracing stages compiled to SPIR-V at run time with naga 30
//! (`enable wgpu_ray_tracing_pipeline;`: `@ray_generation`, `@miss`, `@closest_hit`,
//! `@any_hit`, `var<ray_payload>`, `var<incoming_ray_payload>`, `traceRay`), and this crate's
//! own WGSL files, composed with the core's by [`arpa_core::gpu::shaders::compose`].
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
//!
//! So the gather's AABB hit group is GLSL (`GL_EXT_ray_tracing`), compiled by Debian's
//! `glslc` with `scripts/build-vk-shaders.sh` into checked-in SPIR-V that this module embeds
//! ([`GlslStage`]: [`GATHER_INTERSECTION`], [`GATHER_ANY_HIT`], and the test's
//! [`GATHER_TEST_RAYGEN`] and [`GATHER_TEST_MISS`]); CI runs the script's `--check` (same bytes,
//! `spirv-val`). The GLSL's copy of the footprint test, the sphere test and the kernel
//! (`arpa-vk/shaders/gather_common.glsl`) is held to the core by `tests/gather_hit_group.rs`.

use crate::error::VkError;
use arpa_core::gpu::shaders::{SCENE, WgslFile};

/// The SPIR-V version of the modules (ray-tracing pipelines need Vulkan 1.2, which takes 1.5;
/// 1.4 is what `VK_KHR_ray_tracing_pipeline` is specified against).
pub const SPIRV_VERSION: (u8, u8) = (1, 4);

/// The scene's ray casting on a ray-tracing pipeline (`arpa-vk/shaders/scene_trace.wgsl`):
/// `arpa_scene_intersect` and `arpa_scene_occluded` for the core's `scene.wgsl` (top level
/// at binding 0 of group 0), each a `traceRay` from the ray generation, and the miss and
/// triangle closest-hit shaders `vk_cast_miss`, `vk_cast_closest_hit` every pipeline that
/// traces the scene takes.
pub const SCENE_TRACE: WgslFile =
    WgslFile { name: "arpa-vk/scene_trace.wgsl", source: include_str!("../shaders/scene_trace.wgsl"), deps: &[&SCENE] };

/// Closest-hit ray casting of given rays (`arpa-vk/shaders/ray_cast.wgsl`, the ray-casting
/// test's kernel): ray generation `vk_cast_raygen` with [`SCENE_TRACE`]'s miss and
/// closest-hit shaders — compose with [`ray_cast_source`].
pub const RAY_CAST: WgslFile =
    WgslFile { name: "arpa-vk/ray_cast.wgsl", source: include_str!("../shaders/ray_cast.wgsl"), deps: &[&SCENE_TRACE] };

/// The camera pass's ray generation `vk_camera_raygen` (one invocation per pixel), over the
/// core's `camera_pass.wgsl` and [`SCENE_TRACE`].
pub const CAMERA_RAYGEN: WgslFile = WgslFile {
    name: "arpa-vk/camera_raygen.wgsl",
    source: include_str!("../shaders/camera_raygen.wgsl"),
    deps: &[&arpa_core::gpu::shaders::CAMERA_PASS, &SCENE_TRACE],
};

/// The photon pass's ray generation `vk_photon_raygen` (one invocation per photon), over the
/// core's `photon_pass.wgsl` and [`SCENE_TRACE`].
pub const PHOTON_RAYGEN: WgslFile = WgslFile {
    name: "arpa-vk/photon_raygen.wgsl",
    source: include_str!("../shaders/photon_raygen.wgsl"),
    deps: &[&arpa_core::gpu::shaders::PHOTON_PASS, &SCENE_TRACE],
};

/// The gather's ray generation `vk_gather_raygen` (one point query per query record) and
/// miss `vk_gather_miss` over the core's `gather.wgsl`; its hit group is
/// [`GATHER_INTERSECTION`] and [`GATHER_ANY_HIT`].
pub const GATHER_RAYGEN: WgslFile = WgslFile {
    name: "arpa-vk/gather_raygen.wgsl",
    source: include_str!("../shaders/gather_raygen.wgsl"),
    deps: &[&arpa_core::gpu::shaders::GATHER],
};

/// The composed WGSL of [`RAY_CAST`] and the core files it needs.
pub fn ray_cast_source() -> String {
    arpa_core::gpu::shaders::compose(&[&RAY_CAST])
}

/// A GLSL ray-tracing stage compiled ahead of time by `scripts/build-vk-shaders.sh`
/// (`arpa-vk/shaders/<name>` to `arpa-vk/shaders/spv/<name>.spv`), entry point `main`.
#[derive(Clone, Copy, Debug)]
pub struct GlslStage {
    /// The GLSL file's name under `arpa-vk/shaders`.
    pub name: &'static str,
    /// Its pipeline stage.
    pub stage: ash::vk::ShaderStageFlags,
    /// The checked-in SPIR-V (little-endian words).
    pub spirv: &'static [u8],
}

impl GlslStage {
    /// The entry point of every GLSL stage.
    pub const ENTRY: &'static str = "main";

    /// The SPIR-V as a module for [`crate::VkContext::create_shader_module`]
    /// (`entry_points` is empty: naga has no intersection stage to name; the entry is
    /// [`Self::ENTRY`]).
    ///
    /// Errors: [`VkError::Shader`] when the bytes are not SPIR-V (length not a multiple of 4,
    /// wrong magic number).
    pub fn module(&self) -> Result<SpirvModule, VkError> {
        let err = |message: String| VkError::Shader { label: self.name.into(), message };
        if self.spirv.is_empty() || !self.spirv.len().is_multiple_of(4) {
            return Err(err(format!("{} bytes of SPIR-V (a positive multiple of 4 expected)", self.spirv.len())));
        }
        let words: Vec<u32> = self.spirv.chunks_exact(4).map(|w| u32::from_le_bytes([w[0], w[1], w[2], w[3]])).collect();
        if words[0] != SPIRV_MAGIC {
            return Err(err(format!("magic number {:#010x}, not SPIR-V's {SPIRV_MAGIC:#010x}", words[0])));
        }
        Ok(SpirvModule { label: self.name.into(), words, entry_points: Vec::new() })
    }
}

/// The SPIR-V magic number (first word of every module).
pub const SPIRV_MAGIC: u32 = 0x0723_0203;

/// The gather's intersection shader (`gather.rint`): the exact test of the candidate record
/// (`PackedFootprint::contains`, `PackedPhoton::contains`), reporting hit kind 0 (footprint)
/// or 1 (progressive photon) at `t_min`. Bindings of set 0: 1 footprints, 2 photons;
/// push constants: progressive radius per map (`vec2<f32>`), kernel id, query count.
pub const GATHER_INTERSECTION: GlslStage = GlslStage {
    name: "gather.rint",
    stage: ash::vk::ShaderStageFlags::INTERSECTION_KHR,
    spirv: include_bytes!("../shaders/spv/gather.rint.spv"),
};

/// The gather's any-hit shader (`gather.rahit`): evaluates the accepted record's irradiance
/// at the scales the parameters ask for (`PackedFootprint::irradiance_scales`,
/// `PackedPhoton::irradiance_scales`), adds the stored scale and its count to its map's sum
/// and each smaller scale to that scale's total in the payload (location 0), and ignores the
/// intersection.
pub const GATHER_ANY_HIT: GlslStage = GlslStage {
    name: "gather.rahit",
    stage: ash::vk::ShaderStageFlags::ANY_HIT_KHR,
    spirv: include_bytes!("../shaders/spv/gather.rahit.spv"),
};

/// Ray generation of the gather test (`gather_test.rgen`): one point query per query point
/// (set 0: 0 the top level, 3 the queries, 4 the results).
pub const GATHER_TEST_RAYGEN: GlslStage = GlslStage {
    name: "gather_test.rgen",
    stage: ash::vk::ShaderStageFlags::RAYGEN_KHR,
    spirv: include_bytes!("../shaders/spv/gather_test.rgen.spv"),
};

/// The empty miss shader of the gather test (`gather_test.rmiss`).
pub const GATHER_TEST_MISS: GlslStage = GlslStage {
    name: "gather_test.rmiss",
    stage: ash::vk::ShaderStageFlags::MISS_KHR,
    spirv: include_bytes!("../shaders/spv/gather_test.rmiss.spv"),
};

/// Every embedded GLSL stage.
pub const GLSL_STAGES: [GlslStage; 4] = [GATHER_INTERSECTION, GATHER_ANY_HIT, GATHER_TEST_RAYGEN, GATHER_TEST_MISS];

/// A WGSL module as SPIR-V words, with the names of its entry points.
#[derive(Clone, Debug)]
pub struct SpirvModule {
    /// The label given to [`compile_wgsl`].
    pub label: String,
    /// SPIR-V words (every entry point of the source).
    pub words: Vec<u32>,
    /// `(stage, name)` of each entry point (naga's; empty for a [`GlslStage`], whose entry
    /// is `main`).
    pub entry_points: Vec<(naga::ShaderStage, String)>,
}

/// Parses, validates (all capabilities, ray-tracing pipelines included) and translates
/// `source` to SPIR-V [`SPIRV_VERSION`]. `traceRay` argument validation stays on (naga skips a
/// trace whose `t_min`/`t_max` are invalid, leaving the payload as the caller set it).
///
/// Errors: [`VkError::Shader`] with naga's diagnostic.
pub fn compile_wgsl(label: &str, source: &str) -> Result<SpirvModule, VkError> {
    compile_wgsl_with(label, source, true)
}

/// [`compile_wgsl`], choosing whether naga zero-initialises `var<workgroup>` memory as WGSL
/// requires (`zero_init_workgroup`: naga's polyfill, a store loop and a barrier at the start
/// of each entry point that uses workgroup memory). Pass `false` only for kernels that write
/// every workgroup element before any invocation reads it (the core's `sort.wgsl`): on
/// lavapipe the polyfill makes llvmpipe's compilation of the sort's shared-memory kernels
/// take minutes on a cold shader cache instead of about a second.
pub fn compile_wgsl_with(label: &str, source: &str, zero_init_workgroup: bool) -> Result<SpirvModule, VkError> {
    use naga::back::spv::ZeroInitializeWorkgroupMemoryMode as Zero;
    let err = |message: String| VkError::Shader { label: label.into(), message };
    let module = naga::front::wgsl::parse_str(source).map_err(|e| err(e.emit_to_string(source)))?;
    let info = naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::all())
        .validate(&module)
        .map_err(|e| err(e.emit_to_string(source)))?;
    let options = naga::back::spv::Options {
        lang_version: SPIRV_VERSION,
        flags: naga::back::spv::WriterFlags::empty(),
        zero_initialize_workgroup_memory: if zero_init_workgroup { Zero::Polyfill } else { Zero::None },
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
    fn pass_modules_compile_with_their_stages() {
        use naga::ShaderStage::{ClosestHit, Miss, RayGeneration};
        for (file, want) in [
            (&CAMERA_RAYGEN, vec![(RayGeneration, "vk_camera_raygen"), (Miss, "vk_cast_miss"), (ClosestHit, "vk_cast_closest_hit")]),
            (&PHOTON_RAYGEN, vec![(RayGeneration, "vk_photon_raygen"), (Miss, "vk_cast_miss"), (ClosestHit, "vk_cast_closest_hit")]),
            (&GATHER_RAYGEN, vec![(RayGeneration, "vk_gather_raygen"), (Miss, "vk_gather_miss")]),
        ] {
            let m = compile_wgsl(file.name, &arpa_core::gpu::shaders::compose(&[file])).unwrap_or_else(|e| panic!("{e}"));
            let names: Vec<_> = m.entry_points.iter().map(|(s, n)| (*s, n.as_str())).collect();
            assert_eq!(names.len(), want.len(), "{}: {names:?}", file.name);
            for w in want {
                assert!(names.contains(&w), "{}: {names:?}", file.name);
            }
        }
    }

    #[test]
    fn glsl_stages_are_embedded_spirv() {
        for g in GLSL_STAGES {
            let m = g.module().unwrap_or_else(|e| panic!("{}: {e}", g.name));
            // Version word: 1.5 (Vulkan 1.2).
            assert_eq!(m.words[1], 0x0001_0500, "{}", g.name);
        }
        let bad = GlslStage { spirv: &[1, 2, 3, 4], ..GATHER_TEST_MISS };
        assert!(matches!(bad.module(), Err(VkError::Shader { .. })));
        let bad = GlslStage { spirv: &[3, 2, 35], ..GATHER_TEST_MISS };
        assert!(matches!(bad.module(), Err(VkError::Shader { .. })));
    }

    #[test]
    fn workgroup_zero_initialisation_is_optional() {
        let sort = arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::SORT]);
        let with = compile_wgsl("sort", &sort).expect("sort compiles");
        let without = compile_wgsl_with("sort", &sort, false).expect("sort compiles without zero initialisation");
        assert_eq!(with.entry_points, without.entry_points);
        // The polyfill adds code (a store loop and a barrier per entry point).
        assert!(with.words.len() > without.words.len(), "{} vs {} words", with.words.len(), without.words.len());
    }

    #[test]
    fn errors_carry_naga_diagnostics() {
        let e = compile_wgsl("broken", "enable wgpu_ray_tracing_pipeline;\n@ray_generation fn f() { let x: u32 = 1.5; }").unwrap_err();
        assert!(matches!(&e, VkError::Shader { label, .. } if label == "broken"), "{e}");
    }
}
