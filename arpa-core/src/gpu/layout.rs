//! The `#[repr(C)]` records of the device buffers the path-level WGSL
//! ([`crate::gpu::shaders::PATH`]) reads and writes, each the host side of the WGSL struct it
//! names (same size and field offsets, checked below at compile time against the WGSL
//! layout rules: `vec3<f32>` aligned to 16 bytes, so a `u32` or `f32` fills its fourth
//! word), with the host computations that fill them from the core's types.
//!
//! Records of the twin have theirs beside the Rust types they pack:
//! [`crate::store::footprint::PackedFootprint`], [`crate::store::progressive_photon::PackedPhoton`],
//! [`crate::store::heuristics::PackedHeuristics`], [`crate::emit::emission::PackedLight`],
//! [`crate::render::tracer::QueryRecord`].

use core::mem::size_of;

use crate::gather::scales::Bandwidth;
use crate::store::heuristics::PackedHeuristics;
use crate::store::progressive_photon::PackedPhoton;


/// A footprint as the photon pass leaves it at a diffuse hit, before the heuristics
/// (world space: metres, unit normal towards the arriving photon, W). 80 bytes; the first
/// five fields of `ArpaKeyedFootprint` (`records.wgsl`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct RawFootprint {
    /// Centre (m).
    pub center: [f32; 3],
    /// 0 caustic, 1 global.
    pub map: u32,
    /// Unit normal.
    pub normal: [f32; 3],
    /// Padding.
    pub pad0: u32,
    /// `D_u` (m).
    pub du: [f32; 3],
    /// Padding.
    pub pad1: u32,
    /// `D_v` (m).
    pub dv: [f32; 3],
    /// Padding.
    pub pad2: u32,
    /// Flux (W, RGB).
    pub flux: [f32; 3],
    /// Padding.
    pub pad3: u32,
}
layout!(RawFootprint, 80, { center: 0, map: 12, normal: 16, du: 32, dv: 48, flux: 64 });

/// A raw footprint with its key: the photon pass's footprint append buffer element
/// (`ArpaKeyedFootprint`, 96 bytes). The footprint has the map's smoothing applied to
/// `D_u`, `D_v` and, where the photon arrived from below the shading plane, its normal
/// flipped (which flips the packed record's `row_n` exactly as the core's
/// `orient_to_shading_side`).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct KeyedFootprint {
    /// The footprint (metres, unit normal towards the arriving photon, tangent-plane
    /// differentials with the map's smoothing applied, W).
    pub footprint: RawFootprint,
    /// `photon_index · max_depth + depth`, unique within the iteration.
    pub key: u32,
    /// Padding (zero).
    pub pad: [u32; 3],
}
layout!(KeyedFootprint, 96, { footprint: 0, key: 80 });

/// A progressive photon with its key: the photon pass's photon append buffer element
/// (`ArpaKeyedPhoton`, 64 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct KeyedPhoton {
    /// The photon (metres, unit normal towards the arrival side, W).
    pub photon: PackedPhoton,
    /// `photon_index · max_depth + depth`, unique within the iteration.
    pub key: u32,
    /// Padding (zero).
    pub pad: [u32; 3],
}
layout!(KeyedPhoton, 64, { photon: 0, key: 48 });

layout!(PackedPhoton, 48, { position: 0, map: 12, normal: 16, flux: 32 });

/// What the photon pass counted (`PhotonCounters` of `photon_pass.wgsl`, 48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PhotonCounters {
    /// Photons traced (the dispatch's photon count, the batch's; also those whose emitter
    /// could not emit, as the CPU backend counts them).
    pub emitted: u32,
    /// Ray segments cast.
    pub segments: u32,
    /// Raw footprints stored, caustic map (appends attempted, overflowed ones included).
    pub footprints_caustic: u32,
    /// Raw footprints stored, global map.
    pub footprints_global: u32,
    /// Progressive photons stored, caustic map (appends attempted).
    pub progressive_caustic: u32,
    /// Progressive photons stored, global map.
    pub progressive_global: u32,
    /// Progressive photons stored because the differential was lost (method ARPA).
    pub differential_lost: u32,
    /// Footprint appends attempted (= footprints_caustic + footprints_global); the first
    /// `min(footprint_appends, capacity)` slots of the footprint buffer are written.
    pub footprint_appends: u32,
    /// Photon appends attempted; the first `min(photon_appends, capacity)` slots are written.
    pub photon_appends: u32,
    /// Footprints dropped because the buffer was full.
    pub footprint_overflowed: u32,
    /// Progressive photons dropped because the buffer was full.
    pub photon_overflowed: u32,
    /// Padding (zero).
    pub pad: u32,
}
layout!(PhotonCounters, 48, { emitted: 0, segments: 4, differential_lost: 24, footprint_appends: 28, photon_appends: 32, footprint_overflowed: 36, photon_overflowed: 40 });

impl PhotonCounters {
    /// Footprints written to the buffer.
    pub fn footprints_written(&self) -> u32 {
        self.footprint_appends - self.footprint_overflowed
    }

    /// Progressive photons written to the buffer.
    pub fn photons_written(&self) -> u32 {
        self.photon_appends - self.photon_overflowed
    }

    /// Appends dropped for lack of capacity, both buffers.
    pub fn overflowed(&self) -> u64 {
        self.footprint_overflowed as u64 + self.photon_overflowed as u64
    }
}

/// Per-batch uniforms of the photon pass (`PhotonParams` of `photon_pass.wgsl`, 48 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct PhotonParams {
    /// Photons of this dispatch (the batch).
    pub photon_count: u32,
    /// 0-based iteration.
    pub iteration: u32,
    /// Seed of the random streams.
    pub seed: u32,
    /// Surface interactions per photon.
    pub max_depth: u32,
    /// [`crate::gpu::codes::METHOD_ARPA`] or [`crate::gpu::codes::METHOD_RTPM`].
    pub method: u32,
    /// 1: the first diffuse hits of direct paths are not stored.
    pub direct_lighting: u32,
    /// Emitters (elements of the light and range buffers).
    pub emitter_count: u32,
    /// Global index of the batch's first photon (0: the whole iteration).
    pub first_photon: u32,
    /// `S_c`, `S_g` (dimensionless).
    pub smoothing: [f32; 2],
    /// Padding.
    pub pad1: [f32; 2],
}
layout!(PhotonParams, 48, { photon_count: 0, iteration: 4, seed: 8, max_depth: 12, method: 16, direct_lighting: 20, emitter_count: 24, first_photon: 28, smoothing: 32 });


/// Global photon range of one emitter (`PhotonEmitterRange` of `photon_pass.wgsl`,
/// 16 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct EmitterRange {
    /// First global photon index.
    pub first_index: u32,
    /// Photons of the emitter.
    pub count: u32,
    /// 1 if the emitter can emit.
    pub valid: u32,
    /// 1 for a caustic-pass source (its photons store only caustic records and end at
    /// their first diffuse hit; [`crate::render::photon_path::PhotonPassSetup`]).
    pub caustic_only: u32,
}
layout!(EmitterRange, 16, { first_index: 0, count: 4, valid: 8, caustic_only: 12 });



/// Per-batch inputs of the keyed store (not a device record: [`StoreParams::new`] makes
/// one).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StoreSettings {
    /// The settings' heuristics resolved for the scene, packed.
    pub heuristics: PackedHeuristics,
    /// Progressive radii of the iteration, `[caustic, global]` (metres).
    pub radii: [f32; 2],
    /// Scene bounds `(min, max)` (metres): the Morton grid.
    pub bounds: ([f32; 3], [f32; 3]),
    /// Raw footprints the photon pass appended (at most the raw capacity).
    pub raw_count: u32,
    /// Progressive photons the photon pass appended (at most the photon capacity).
    pub photon_count: u32,
}

#[cfg(feature = "alloc")]
impl StoreSettings {
    /// The settings of an iteration's store: `setup`'s heuristics and radii, the Morton grid
    /// over `scene`'s bounds (rounded outwards to `f32`), and no record counts yet (the
    /// store's schedule kernel writes them from the photon pass's counters on the device).
    pub fn for_iteration(setup: &crate::render::photon_path::PhotonPassSetup, scene: &crate::render::prepared_scene::PreparedScene) -> Self {
        Self { heuristics: setup.heuristics.pack(), radii: setup.radii.map(|r| r as f32), bounds: scene.bounds().to_f32_conservative(), raw_count: 0, photon_count: 0 }
    }
}

/// Parameters of the store kernels (`StoreParams` of `store.wgsl`, 112 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct StoreParams {
    /// The heuristics.
    pub heuristics: PackedHeuristics,
    /// Progressive radius per map (metres).
    pub radii: [f32; 2],
    /// Padding.
    pub pad0: [f32; 2],
    /// Scene bounds' low corner (metres).
    pub scene_lo: [f32; 3],
    /// Raw footprints appended by the photon pass.
    pub raw_count: u32,
    /// `1 / scene extent` per axis ([`crate::base::morton::inverse_extent`]).
    pub scene_inv: [f32; 3],
    /// Progressive photons appended by the photon pass.
    pub photon_count: u32,
    /// Footprint sort items the sort and the compaction run over (the raw capacity): the
    /// appended ones, then padding.
    pub fp_sorted: u32,
    /// Photon sort items they run over (the sorted-photon capacity).
    pub ph_sorted: u32,
    /// Padding.
    pub pad1: [u32; 2],
}
layout!(StoreParams, 112, { heuristics: 0, radii: 48, scene_lo: 64, raw_count: 76, scene_inv: 80, photon_count: 92, fp_sorted: 96, ph_sorted: 100, pad1: 104 });
layout!(PackedHeuristics, 48, {});

impl StoreParams {
    /// The parameters of one batch's store, sort and compaction (one submission; the
    /// record counts `raw_count` and `photon_count` are the schedule kernel's to write on
    /// the device) for store buffers of `raw_capacity` raw footprints and
    /// `sorted_photons` photon sort items (the photon pass's photons and the footprints'
    /// fallbacks): the sort and the compaction run over every slot
    /// ([`StoreParams::fp_sorted`] = `raw_capacity`, [`StoreParams::ph_sorted`] =
    /// `sorted_photons`), so that no size of theirs waits for a count (`pad_items` reads the
    /// appended counts from the store's counters and pads the rest; photon items past
    /// `sorted_photons` are dropped and counted in [`StoreCounts::overflowed`]).
    pub fn new(settings: &StoreSettings, raw_capacity: u32, sorted_photons: u32) -> Self {
        let (lo, hi) = settings.bounds;
        Self {
            heuristics: settings.heuristics,
            radii: settings.radii,
            pad0: [0.0; 2],
            scene_lo: lo,
            raw_count: settings.raw_count,
            scene_inv: crate::base::morton::inverse_extent(lo, hi),
            photon_count: settings.photon_count,
            fp_sorted: raw_capacity,
            ph_sorted: sorted_photons,
            pad1: [0; 2],
        }
    }
}

/// What the keyed store counted (`store_counts` of `store.wgsl`, 48 bytes): sizes of the
/// sorted maps and why footprints fell back to progressive photons.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct StoreCounts {
    /// Footprints stored, `[caustic, global]` (sorted output: caustic first).
    pub footprints: [u32; 2],
    /// Progressive photons (the photon pass's plus the fallbacks), `[caustic, global]`.
    pub photons: [u32; 2],
    /// Fallbacks by reason: degenerate, culled, unrepresentable.
    pub degenerate: u32,
    /// See [`StoreCounts::degenerate`].
    pub culled: u32,
    /// See [`StoreCounts::degenerate`].
    pub unrepresentable: u32,
    /// Progressive photons beyond the sorted photons' capacity (their sort items or the
    /// sorted output; guarded, never written out of bounds): the batch is traced again with
    /// more room.
    pub overflowed: u32,
    /// Footprint sort items appended (= both maps' footprints).
    pub footprint_items: u32,
    /// Photon sort items appended (= both maps' photons).
    pub photon_items: u32,
    /// Padding.
    pub pad: [u32; 2],
}
layout!(StoreCounts, 48, { footprints: 0, photons: 8, degenerate: 16, culled: 20, unrepresentable: 24, overflowed: 28, footprint_items: 32, photon_items: 36 });

impl StoreCounts {
    /// Footprints of both maps.
    pub fn total_footprints(&self) -> u32 {
        self.footprints[0] + self.footprints[1]
    }

    /// Progressive photons of both maps.
    pub fn total_photons(&self) -> u32 {
        self.photons[0] + self.photons[1]
    }
}

/// One photon batch's counters as the GPU backends copy them out of the batch's submission
/// for the iteration's one wait: the photon pass's, then the store's (96 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct BatchCounts {
    /// What the photon pass counted.
    pub photon: PhotonCounters,
    /// What the store counted.
    pub store: StoreCounts,
}
layout!(BatchCounts, 96, { photon: 0, store: 48 });

impl BatchCounts {
    /// Records the batch dropped for lack of room: appends past the photon pass's buffers
    /// and sorted progressive photons past the store's output. An iteration with any is
    /// traced again.
    pub fn dropped(&self) -> u64 {
        self.photon.overflowed() + u64::from(self.store.overflowed)
    }

    /// Records the batches `batches` dropped together ([`BatchCounts::dropped`]): an
    /// iteration with any is traced again.
    pub fn dropped_in(batches: &[Self]) -> u64 {
        batches.iter().map(Self::dropped).sum()
    }
}

/// Irradiance gathered at one query point (`ArpaGatherResult` of `gather.wgsl`, 112 bytes;
/// W/m², RGB, summed in `f32` on the device): per map at the stored scale, and both maps
/// together at the smaller scales of the bandwidth ladder ([`crate::gather::scales`]).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GatherResult {
    /// Caustic-map irradiance.
    pub caustic: [f32; 3],
    /// Caustic records that contributed.
    pub caustic_count: u32,
    /// Global-map irradiance.
    pub global: [f32; 3],
    /// Global records that contributed.
    pub global_count: u32,
    /// Candidate records per map (`[caustic, global]`: boxes containing the point, each
    /// tested exactly).
    pub candidates: [u32; 2],
    /// Padding.
    pub pad: [u32; 2],
    /// Irradiance at scales `1 .. SCALES` (entry `k − 1` is scale `k`), both maps summed
    /// together in traversal order, RGB in the first three words, the fourth zero; zero at
    /// the scales the gather did not evaluate ([`GatherImageParams::scales`]).
    pub scaled: [[f32; 4]; crate::gather::scales::SCALES - 1],
}
layout!(GatherResult, 112, { caustic: 0, caustic_count: 12, global: 16, global_count: 28, candidates: 32, pad: 40, scaled: 48 });

impl GatherResult {
    /// The irradiance of both maps at scale `k` (`k < SCALES`): `caustic + global` in
    /// `f32` for the stored scale (the gather's own expression), the device's sum for the
    /// others.
    pub fn scale(&self, k: usize) -> glam::Vec3 {
        if k == 0 {
            glam::Vec3::from_array(self.caustic) + glam::Vec3::from_array(self.global)
        } else {
            glam::Vec3::from_slice(&self.scaled[k - 1][..3])
        }
    }
}

/// The gather's counters of one iteration (`gathered_total` of `gather.wgsl`, 48 bytes):
/// 64-bit totals kept as `[low, high]` words (the device adds to the low word and carries
/// into the high one).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GatherCounts {
    /// Contributions per map, `[caustic, global]`, each `[low, high]`.
    pub contributions: [[u32; 2]; 2],
    /// Candidates per map, `[caustic, global]`, each `[low, high]`.
    pub candidates: [[u32; 2]; 2],
    /// Valid query records (counted by the iteration's first batch).
    pub query_points: u32,
    /// Valid query records with at least one contribution per map, `[caustic, global]`
    /// (counted by every batch).
    pub covered: [u32; 2],
    /// Padding.
    pub pad: u32,
}
layout!(GatherCounts, 48, { contributions: 0, candidates: 16, query_points: 32, covered: 36, pad: 44 });

impl GatherCounts {
    /// The contributions per map.
    pub fn contributions(&self) -> [u64; 2] {
        self.contributions.map(|[lo, hi]| u64::from(lo) | u64::from(hi) << 32)
    }

    /// The candidates per map.
    pub fn candidates(&self) -> [u64; 2] {
        self.candidates.map(|[lo, hi]| u64::from(lo) | u64::from(hi) << 32)
    }
}

/// Where one gather stands among the photon batches of an iteration
/// ([`crate::gpu::batch`]: each batch's maps are gathered in turn).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct GatherBatch {
    /// The iteration's first batch: starts the per-pixel irradiance sum, clears the
    /// counters and counts the valid query records.
    pub first: bool,
    /// The iteration's last batch: writes the image.
    pub last: bool,
}

impl GatherBatch {
    /// The whole iteration in one batch (first and last).
    pub const WHOLE: Self = Self { first: true, last: true };

    /// Batch `k` of `batches`.
    pub const fn of(k: u32, batches: u32) -> Self {
        Self { first: k == 0, last: k + 1 >= batches }
    }

    /// [`crate::gpu::codes::GATHER_BATCH_FIRST`] | [`crate::gpu::codes::GATHER_BATCH_LAST`]
    /// as they apply.
    pub const fn bits(self) -> u32 {
        (if self.first { crate::gpu::codes::GATHER_BATCH_FIRST } else { 0 }) | (if self.last { crate::gpu::codes::GATHER_BATCH_LAST } else { 0 })
    }
}

/// Parameters of the image gather (`GatherImageParams` of `gather.wgsl`, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GatherImageParams {
    /// Progressive radius per map (metres).
    pub radii: [f32; 2],
    /// [`crate::gpu::codes::kernel_code`] of the footprints' kernel.
    pub kernel: u32,
    /// Query records (one per pixel).
    pub pixels: u32,
    /// [`GatherBatch::bits`].
    pub batch: u32,
    /// Scales the gather evaluates ([`Bandwidth::scales`]): 1 (one image plane per pixel)
    /// or [`crate::gather::scales::SCALES`] (every plane of [`crate::gather::scales::PLANES`]).
    /// The device clamps it to `1 ..= SCALES` and writes the moment planes only for `SCALES`.
    pub scales: u32,
    /// Padding.
    pub pad: [u32; 2],
}
layout!(GatherImageParams, 32, { radii: 0, kernel: 8, pixels: 12, batch: 16, scales: 20 });

impl GatherImageParams {
    /// The parameters of gathering `pixels` query records as `batch` for an image of
    /// `bandwidth`'s planes.
    pub fn new(radii: [f32; 2], kernel: crate::gather::kernel::Kernel, pixels: u32, batch: GatherBatch, bandwidth: Bandwidth) -> Self {
        Self { radii, kernel: crate::gpu::codes::kernel_code(kernel), pixels, batch: batch.bits(), scales: bandwidth.scales() as u32, pad: [0; 2] }
    }
}

/// Bytes of the per-image device buffers of a GPU backend for `pixels` pixels and a
/// bandwidth ([`Bandwidth::planes`] planes per pixel, plane-major: plane `p` of pixel `i`
/// at `p · pixels + i`). Each must fit one storage binding.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct ImageBufferSizes {
    /// The iteration image the gather writes and the accumulation reads: one `vec4<f32>`
    /// (16 bytes) per plane and pixel.
    pub image: u64,
    /// The per-pixel irradiance summed over photon batches: one `vec4<f32>` per scale
    /// ([`Bandwidth::scales`]) and pixel, scale-major.
    pub batch_irradiance: u64,
    /// The running sums: one [`AccumPixel`] (32 bytes) per plane and pixel.
    pub accumulator: u64,
}

impl ImageBufferSizes {
    /// The sizes for `pixels` pixels under `bandwidth`.
    pub fn new(pixels: u32, bandwidth: Bandwidth) -> Self {
        let (px, planes, scales) = (u64::from(pixels), bandwidth.planes() as u64, bandwidth.scales() as u64);
        Self { image: planes * px * 16, batch_irradiance: scales * px * 16, accumulator: planes * px * size_of::<AccumPixel>() as u64 }
    }

    /// `Err(message)` when a buffer exceeds `binding_bytes` (a storage binding of the
    /// device): the message names the buffer, the image's planes and the bandwidth.
    #[cfg(feature = "alloc")]
    #[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
    pub fn check(&self, width: u32, height: u32, bandwidth: Bandwidth, binding_bytes: u64) -> Result<(), alloc::string::String> {
        let largest = [("accumulation", self.accumulator), ("iteration image", self.image), ("batch irradiance", self.batch_irradiance)].into_iter().max_by_key(|(_, b)| *b);
        match largest {
            Some((what, bytes)) if bytes > binding_bytes => Err(alloc::format!(
                "an image of {width}×{height} pixels with {} plane(s) per pixel (--bandwidth {}) needs {bytes} bytes for its {what}, above one storage binding ({binding_bytes} bytes){}",
                bandwidth.planes(),
                bandwidth.name(),
                if bandwidth.planes() > 1 { "; render it with --bandwidth global or fewer pixels" } else { "" }
            )),
            _ => Ok(()),
        }
    }
}

/// One pixel's accumulator of the running mean (`AccumPixel` of `accumulate.wgsl`,
/// 32 bytes): a compensated `f32` sum (Neumaier, as [`crate::accumulate::image::RunningMean`] in
/// `f64`) and the count of rejected non-finite samples.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct AccumPixel {
    /// Sum of the finite samples (W/(m²·sr), RGB).
    pub sum: [f32; 3],
    /// Non-finite samples rejected.
    pub rejected: u32,
    /// Neumaier compensation of `sum`.
    pub compensation: [f32; 3],
    /// Padding.
    pub pad: u32,
}
layout!(AccumPixel, 32, { sum: 0, rejected: 12, compensation: 16 });

impl AccumPixel {
    /// The mean over `iterations` iterations: `(sum + compensation) / iterations` in
    /// `f64`; 0 before any iteration and where not finite (so no NaN or Inf reaches a pixel).
    pub fn mean(&self, iterations: u32) -> glam::Vec3 {
        crate::accumulate::image::output_mean(self.to_sum().total(), u64::from(iterations))
    }

    /// The sums in `f64`, exactly (for a checkpoint).
    pub fn to_sum(&self) -> crate::accumulate::image::PixelSum {
        let f = |v: [f32; 3]| v.map(f64::from);
        crate::accumulate::image::PixelSum { sum: f(self.sum), compensation: f(self.compensation), rejected: u64::from(self.rejected), pad: 0 }
    }


    /// The device record of `sum`, when its values are exactly `f32` (as a device
    /// accumulator's are) and its rejected count fits; `None` otherwise (sums merged or
    /// accumulated in `f64`, which this accumulator cannot continue exactly).
    pub fn from_sum(sum: &crate::accumulate::image::PixelSum) -> Option<Self> {
        let f = |v: [f64; 3]| {
            let g = v.map(|x| x as f32);
            (g.map(f64::from) == v).then_some(g)
        };
        Some(Self { sum: f(sum.sum)?, rejected: u32::try_from(sum.rejected).ok()?, compensation: f(sum.compensation)?, pad: 0 })
    }
}

/// Uniforms of the camera pass (`ArpaCameraParams` of `camera_pass.wgsl`, 96 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct CameraParams {
    /// Eye position (metres).
    pub position: [f32; 3],
    /// Image width (pixels).
    pub width: u32,
    /// Unit viewing direction ([`crate::render::scene::CameraFrame`]).
    pub forward: [f32; 3],
    /// Image height (pixels).
    pub height: u32,
    /// Unit right vector.
    pub right: [f32; 3],
    /// `tan(fov/2)`.
    pub tan_half_fov: f32,
    /// Unit up vector.
    pub up: [f32; 3],
    /// Width over height.
    pub aspect: f32,
    /// Seed of the random streams.
    pub seed: u32,
    /// 0-based iteration.
    pub iteration: u32,
    /// Surface interactions per camera path.
    pub max_depth: u32,
    /// 1: next-event estimation at the query point.
    pub direct_lighting: u32,
    /// `width · height`.
    pub pixel_count: u32,
    /// Invocations per row of the dispatch grid (workgroups in x times 64).
    pub row_invocations: u32,
    /// Padding.
    pub pad: [u32; 2],
}
layout!(CameraParams, 96, { position: 0, width: 12, forward: 16, height: 28, right: 32, tan_half_fov: 44, up: 48, aspect: 60, seed: 64, iteration: 68, max_depth: 72, direct_lighting: 76, pixel_count: 80, row_invocations: 84 });

/// `ArpaSceneInfo` of `scene.wgsl` (uniform, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SceneInfo {
    /// Meshes.
    pub mesh_count: u32,
    /// Delta lights (point, spot, directional), the first emitters.
    pub delta_count: u32,
    /// Area emitters (triangles, quads), after the delta lights; 0 without positive power.
    pub area_count: u32,
    /// 1 if some material is a mask ([`crate::render::prepared_scene::PreparedScene::has_masks`]).
    pub has_masks: u32,
    /// Centre of the bounding sphere (metres).
    pub sphere_centre: [f32; 3],
    /// Its radius (metres).
    pub sphere_radius: f32,
}
layout!(SceneInfo, 32, { mesh_count: 0, delta_count: 4, area_count: 8, has_masks: 12, sphere_centre: 16, sphere_radius: 28 });

/// `ArpaSceneMesh` of `scene.wgsl` (96 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SceneMesh {
    /// Index of the mesh's first triangle record.
    pub first_triangle: u32,
    /// Triangles of the mesh.
    pub triangle_count: u32,
    /// [`crate::gpu::codes::SCATTER_DIFFUSE`], `…_MIRROR` or `…_REFRACTIVE`.
    pub kind: u32,
    /// 1 if the mesh emits `emission` on its geometric-normal side.
    pub emissive: u32,
    /// Albedo (diffuse), reflectance (mirror) or transmittance (refractive).
    pub color: [f32; 3],
    /// Interior over exterior index of refraction (refractive only).
    pub ior: f32,
    /// Emitted radiance (W/(m²·sr)).
    pub emission: [f32; 3],
    /// 1 if the mesh has vertex normals.
    pub has_normals: u32,
    /// The texture multiplying `color` ([`crate::render::scene::MaterialMaps::color`]), or
    /// [`crate::gpu::texture::NO_TEXTURE`].
    pub color_texture: u32,
    /// The texture whose single value is the opacity, or [`crate::gpu::texture::NO_TEXTURE`].
    pub opacity_texture: u32,
    /// The constant opacity where `opacity_texture` is none (1: opaque).
    pub opacity: f32,
    /// Word of the mesh's first texture coordinates in the texture words
    /// ([`crate::gpu::texture::TextureWords`]), or [`crate::gpu::texture::NO_TEXTURE`].
    pub uv_first: u32,
    /// The texture multiplying `emission` ([`crate::render::scene::SceneTextures::emission`]),
    /// or [`crate::gpu::texture::NO_TEXTURE`].
    pub emission_texture: u32,
    /// The normal or bump map ([`crate::render::scene::MaterialMaps::normal`]), or
    /// [`crate::gpu::texture::NO_TEXTURE`].
    pub normal_texture: u32,
    /// [`crate::gpu::codes::NORMAL_MAP_NONE`], `…_TANGENT`, `…_TANGENT_UV` or `…_BUMP`.
    pub normal_kind: u32,
    /// The map's scale ([`crate::render::scene::NormalPerturbation::scale`]).
    pub normal_scale: f32,
    /// Where the material is a blend ([`crate::render::scene::MaterialMaps::blend`]): the
    /// index of the record, after the scene's meshes, whose `kind`, `color`, `ior` and
    /// `color_texture` are the other material's; else [`crate::gpu::texture::NO_TEXTURE`].
    pub blend_record: u32,
    /// The blend's constant weight (where `blend_weight_texture` is none).
    pub blend_weight: f32,
    /// The texture whose single value is the blend's weight, or
    /// [`crate::gpu::texture::NO_TEXTURE`].
    pub blend_weight_texture: u32,
    /// Padding.
    pub pad: u32,
}
layout!(SceneMesh, 96, {
    first_triangle: 0, triangle_count: 4, kind: 8, emissive: 12, color: 16, ior: 28, emission: 32, has_normals: 44,
    color_texture: 48, opacity_texture: 52, opacity: 56, uv_first: 60, emission_texture: 64, normal_texture: 68,
    normal_kind: 72, normal_scale: 76, blend_record: 80, blend_weight: 84, blend_weight_texture: 88
});

/// `ArpaSceneTriangle` of `scene.wgsl` (112 bytes). The table is in the meshes' triangle
/// order; `blas_triangle` of the record at `first_triangle + i` is the mesh's triangle at
/// primitive `i` of the mesh's bottom-level structure (it rides in the record's padding,
/// so that group 0 keeps three storage buffers: the photon pass binds eight in all,
/// WebGPU's default limit).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SceneTriangle {
    /// Vertex 0 (metres).
    pub p0: [f32; 3],
    /// [`crate::gpu::codes::TRIANGLE_SHADED`] | [`crate::gpu::codes::TRIANGLE_NORMALS`].
    pub flags: u32,
    /// Vertex 1.
    pub p1: [f32; 3],
    /// See the type's docs.
    pub blas_triangle: u32,
    /// Vertex 2.
    pub p2: [f32; 3],
    /// Padding.
    pub pad2: u32,
    /// Unit geometric normal (computed in `f64`).
    pub normal: [f32; 3],
    /// Padding.
    pub pad3: u32,
    /// Vertex normal 0 as the mesh stores it; the geometric normal without vertex normals.
    pub n0: [f32; 3],
    /// Padding.
    pub pad4: u32,
    /// Vertex normal 1.
    pub n1: [f32; 3],
    /// Padding.
    pub pad5: u32,
    /// Vertex normal 2.
    pub n2: [f32; 3],
    /// Padding.
    pub pad6: u32,
}
layout!(SceneTriangle, 112, { p0: 0, flags: 12, p1: 16, blas_triangle: 28, p2: 32, normal: 48, n0: 64, n1: 80, n2: 96 });

/// `ArpaSceneEmitter` of `scene.wgsl` (80 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SceneEmitter {
    /// [`crate::emit::emission::Light::kind_code`].
    pub kind: u32,
    /// Spot falloff ([`crate::emit::emission::SpotFalloff::code`]).
    pub falloff: u32,
    /// Spot cut-off half-angle (rad).
    pub cutoff: f32,
    /// Spot full-intensity half-angle (rad).
    pub beam_width: f32,
    /// Point/spot position, directional unit direction of travel, triangle vertex 0, quad
    /// origin.
    pub p0: [f32; 3],
    /// Area emitters: cumulative power up to and including this one over the total.
    pub cdf: f32,
    /// Spot unit axis, triangle vertex 1, quad `edge_u`.
    pub p1: [f32; 3],
    /// Area emitters: probability of being picked (power / total).
    pub probability: f32,
    /// Triangle vertex 2, quad `edge_v`.
    pub p2: [f32; 3],
    /// A textured emitter triangle's record in the texture words
    /// ([`crate::gpu::texture::emitter_records`]), or [`crate::gpu::texture::NO_TEXTURE`].
    pub emission_record: u32,
    /// Intensity (point, spot), irradiance (directional), radiance (area; a textured
    /// triangle's holds the texture's mean over it).
    pub color: [f32; 3],
    /// Padding.
    pub pad1: f32,
}
layout!(SceneEmitter, 80, { kind: 0, falloff: 4, cutoff: 8, beam_width: 12, p0: 16, cdf: 28, p1: 32, probability: 44, p2: 48, emission_record: 60, color: 64 });

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gather_batch_bits() {
        assert_eq!(GatherBatch::WHOLE.bits(), 3);
        assert_eq!(GatherBatch::of(0, 3).bits(), 1);
        assert_eq!(GatherBatch::of(1, 3).bits(), 0);
        assert_eq!(GatherBatch::of(2, 3).bits(), 2);
        assert_eq!(GatherBatch::of(0, 1), GatherBatch::WHOLE);
    }

    #[test]
    fn means_are_finite() {
        let p = AccumPixel { sum: [3.0, f32::MAX, 1.0], compensation: [1e-8, f32::MAX, 0.0], ..AccumPixel::default() };
        assert_eq!(p.mean(0), glam::Vec3::ZERO);
        assert_eq!(p.mean(1), glam::Vec3::new(3.0, 0.0, 1.0), "MAX + MAX overflows f32: 0");
        assert_eq!(p.mean(2), glam::Vec3::new(1.5, f32::MAX, 0.5), "the sum is taken in f64");
    }

    #[cfg(feature = "alloc")]
    #[test]
    fn image_buffers_hold_every_plane() {
        let g = ImageBufferSizes::new(100, Bandwidth::Global);
        assert_eq!((g.image, g.batch_irradiance, g.accumulator), (1600, 1600, 3200));
        let p = ImageBufferSizes::new(100, Bandwidth::PerPixel);
        assert_eq!((p.image, p.batch_irradiance, p.accumulator), (8 * 1600, 5 * 1600, 8 * 3200));
        assert!(p.check(10, 10, Bandwidth::PerPixel, 8 * 3200).is_ok());
        let e = p.check(10, 10, Bandwidth::PerPixel, 8 * 3200 - 1).unwrap_err();
        assert!(e.contains("accumulation") && e.contains("per-pixel") && e.contains("8 plane"), "{e}");
        assert_eq!(GatherImageParams::new([0.1; 2], crate::gather::kernel::Kernel::Constant, 100, GatherBatch::WHOLE, Bandwidth::PerPixel).scales, 5);
    }

    #[test]
    fn store_params_run_over_the_capacities() {
        let s = StoreSettings { heuristics: PackedHeuristics::default(), radii: [0.1, 0.2], bounds: ([0.0; 3], [2.0, 0.0, 4.0]), raw_count: 5, photon_count: 7 };
        let p = StoreParams::new(&s, 600, 10);
        assert_eq!((p.scene_inv, p.fp_sorted, p.ph_sorted, p.raw_count, p.photon_count), ([0.5, 0.0, 0.25], 600, 10, 5, 7));
    }
}
