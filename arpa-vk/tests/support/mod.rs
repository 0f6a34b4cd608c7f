//! What the arpa-vk integration tests share: a context under the validation layer (or a loud
//! skip outside CI), the clean-log assertion, and the gather test pipeline (GLSL test ray
//! generation and miss with the production AABB hit group).
// Each test crate uses a part of this module.
#![allow(dead_code)]

use arpa_vk::shaders::{GATHER_ANY_HIT, GATHER_INTERSECTION, GATHER_TEST_MISS, GATHER_TEST_RAYGEN, GlslStage};
use arpa_vk::{AdapterChoice, BindingKind, ContextOptions, HitGroup, RtPipeline, RtPipelineDesc, ShaderEntry, ValidationLog, VkContext};

/// Whether this is CI (env `CI`), where a missing driver or layer fails instead of skipping.
pub fn in_ci() -> bool {
    std::env::var_os("CI").is_some()
}

/// Prints the loud skip message of `test`.
pub fn skip(test: &str, why: &str) {
    eprintln!("\n*** SKIPPING arpa-vk {test} test: {why}\n");
}

/// A context on `choice` with `options`, or `None` (with a loud message) where Vulkan, the
/// driver or the validation layer is missing outside CI.
pub fn context_with(test: &str, choice: &AdapterChoice, options: &ContextOptions) -> Option<VkContext> {
    match VkContext::new(choice, options) {
        Ok(ctx) => {
            assert_eq!(ctx.validation_enabled(), options.validation);
            Some(ctx)
        }
        Err(e) if in_ci() => panic!("CI needs Vulkan with lavapipe and the validation layer ({choice:?}): {e}"),
        Err(e) => {
            skip(test, &format!("{e}\n*** (run `bash scripts/install-lavapipe.sh` and `bash scripts/install-vulkan-tools.sh`)"));
            None
        }
    }
}

/// A validated context on the automatic adapter (see [`context_with`]).
pub fn context(test: &str) -> Option<VkContext> {
    context_with(test, &AdapterChoice::Auto, &ContextOptions { validation: true })
}

/// Asserts that no validation message was recorded, printing them all otherwise.
pub fn assert_clean(log: &ValidationLog, when: &str) {
    let messages = log.messages();
    let text: Vec<String> = messages.iter().map(|m| m.to_string()).collect();
    assert!(messages.is_empty(), "{} validation message(s) {when}:\n{}", messages.len(), text.join("\n"));
}

/// The gather test pipeline: GLSL test ray generation (one point query per query point,
/// results per map) and miss, the production AABB hit group. Set 0 is gather.wgsl's:
/// footprints, photons, queries (in the records' slot), results (in the image's slot),
/// parameters (`GatherImageParams`), two slots it does not read, the top level.
pub fn gather_test_pipeline(ctx: &VkContext) -> RtPipeline {
    let module = |g: &GlslStage| ctx.create_shader_module(&g.module().expect("embedded SPIR-V")).expect(g.name);
    let (rgen, rmiss, rint, rahit) =
        (module(&GATHER_TEST_RAYGEN), module(&GATHER_TEST_MISS), module(&GATHER_INTERSECTION), module(&GATHER_ANY_HIT));
    let entry = |module| ShaderEntry { module, entry: GlslStage::ENTRY };
    use BindingKind::{AccelerationStructure as As, StorageBuffer as Sb};
    RtPipeline::new(
        ctx,
        &RtPipelineDesc {
            label: "gather hit group",
            raygen: entry(&rgen),
            miss: &[entry(&rmiss)],
            hit_groups: &[HitGroup::Procedural { intersection: entry(&rint), any_hit: Some(entry(&rahit)), closest_hit: None }],
            sets: &[&[Sb, Sb, Sb, Sb, Sb, Sb, Sb, As]],
            push_constant_size: 0,
        },
    )
    .expect("gather test pipeline")
}
