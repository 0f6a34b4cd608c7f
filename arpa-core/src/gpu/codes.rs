//! The integer codes the path-level WGSL ([`crate::gpu::shaders::PATH`]) and the twin take where
//! the Rust side has enums. Each constant names its WGSL twin. Light kinds and spot falloff
//! curves have theirs beside their types ([`crate::emit::emission::Light::kind_code`],
//! [`crate::emit::emission::SpotFalloff::code`]).

use crate::store::heuristics::ProgressiveReason;

use crate::gather::kernel::Kernel;

/// Workgroup size (invocations along x) of every path-level kernel but the sort's.
pub const WORKGROUP_SIZE: u32 = 64;

/// `ARPA_KERNEL_*` of `kernel.wgsl`: 0 constant, 1 Epanechnikov, 2 Silverman.
pub const fn kernel_code(kernel: Kernel) -> u32 {
    match kernel {
        Kernel::Constant => 0,
        Kernel::Epanechnikov => 1,
        Kernel::Silverman => 2,
    }
}

/// `ARPA_PHOTON_METHOD_ARPA` of `photon_pass.wgsl` ([`crate::render::tracer::Method::Arpa`]).
pub const METHOD_ARPA: u32 = 0;
/// `ARPA_PHOTON_METHOD_RTPM` ([`crate::render::tracer::Method::Rtpm`]).
pub const METHOD_RTPM: u32 = 1;

/// [`METHOD_ARPA`] or [`METHOD_RTPM`].
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub const fn method_code(method: crate::render::tracer::Method) -> u32 {
    match method {
        crate::render::tracer::Method::Arpa => METHOD_ARPA,
        crate::render::tracer::Method::Rtpm => METHOD_RTPM,
    }
}

/// `ARPA_SCATTER_DIFFUSE` of `scene.wgsl` ([`crate::render::scene::Scattering::Diffuse`]).
pub const SCATTER_DIFFUSE: u32 = 0;
/// `ARPA_SCATTER_MIRROR` ([`crate::render::scene::Scattering::Mirror`]).
pub const SCATTER_MIRROR: u32 = 1;
/// `ARPA_SCATTER_REFRACTIVE` ([`crate::render::scene::Scattering::Refractive`]).
pub const SCATTER_REFRACTIVE: u32 = 2;
/// `ARPA_SCATTER_THIN` ([`crate::render::scene::Scattering::Thin`]).
pub const SCATTER_THIN: u32 = 3;

/// `ARPA_TRIANGLE_SHADED` of `scene.wgsl`: the triangle's vertex normals differ from its
/// face normal ([`crate::render::prepared_scene::PreparedScene::has_shading_normals`]).
pub const TRIANGLE_SHADED: u32 = 1;
/// `ARPA_TRIANGLE_NORMALS`: the mesh has vertex normals and the triangle a non-zero area,
/// so specular bounces interpolate them.
pub const TRIANGLE_NORMALS: u32 = 2;

/// `ARPA_NORMAL_MAP_NONE` of `scene.wgsl`: the mesh's material has no normal or bump map.
pub const NORMAL_MAP_NONE: u32 = 0;
/// `ARPA_NORMAL_MAP_TANGENT`: a tangent-space normal map, `t = n × s`
/// ([`crate::render::scene::NormalPerturbation::NormalMap`] with
/// [`crate::propagate::normal_map::Handedness::RightHanded`]).
pub const NORMAL_MAP_TANGENT: u32 = 1;
/// `ARPA_NORMAL_MAP_TANGENT_UV`: a tangent-space normal map whose `t` follows `∂p/∂v`
/// ([`crate::propagate::normal_map::Handedness::FollowTextureCoordinates`]).
pub const NORMAL_MAP_TANGENT_UV: u32 = 2;
/// `ARPA_NORMAL_MAP_BUMP`: a bump map ([`crate::render::scene::NormalPerturbation::BumpMap`]).
pub const NORMAL_MAP_BUMP: u32 = 3;

/// `ARPA_STORE_OK` of `heuristics.wgsl`: the footprint is stored.
pub const STORE_OK: u32 = 0;
/// `ARPA_STORE_DEGENERATE`: replaced as degenerate.
pub const STORE_DEGENERATE: u32 = 1;
/// `ARPA_STORE_CULLED`: replaced by bounding-box culling.
pub const STORE_CULLED: u32 = 2;
/// `ARPA_STORE_UNREPRESENTABLE`: `f32` cannot resolve it.
pub const STORE_UNREPRESENTABLE: u32 = 3;

/// The `ARPA_STORE_*` code of a store decision: [`STORE_OK`] for a stored footprint
/// (`None`), else the reason's. `None` for the reasons the store itself never gives
/// ([`ProgressiveReason::DifferentialLost`], [`ProgressiveReason::ProgressiveMethod`]).
pub const fn store_code(rejection: Option<ProgressiveReason>) -> Option<u32> {
    match rejection {
        None => Some(STORE_OK),
        Some(ProgressiveReason::Degenerate) => Some(STORE_DEGENERATE),
        Some(ProgressiveReason::Culled) => Some(STORE_CULLED),
        Some(ProgressiveReason::Unrepresentable) => Some(STORE_UNREPRESENTABLE),
        Some(ProgressiveReason::DifferentialLost | ProgressiveReason::ProgressiveMethod) => None,
    }
}

/// `ARPA_INSTANCE_PHOTON_BIT` of `gather.wgsl`: bit of an acceleration-structure
/// instance's custom index set for progressive photons (clear for footprints). Custom
/// indices have 24 bits (Vulkan's `instanceCustomIndex`).
pub const INSTANCE_PHOTON_BIT: u32 = 1 << 23;
/// `ARPA_INSTANCE_INDEX_MASK`: the custom index's bits holding the instance's first record.
pub const INSTANCE_INDEX_MASK: u32 = INSTANCE_PHOTON_BIT - 1;
/// Most records of one kind the custom index can address (2²³).
pub const MAX_RECORDS_PER_KIND: u32 = INSTANCE_PHOTON_BIT;

/// `GATHER_BATCH_FIRST` of `gather.wgsl` ([`crate::gpu::layout::GatherBatch::first`]).
pub const GATHER_BATCH_FIRST: u32 = 1;
/// `GATHER_BATCH_LAST` ([`crate::gpu::layout::GatherBatch::last`]).
pub const GATHER_BATCH_LAST: u32 = 2;
