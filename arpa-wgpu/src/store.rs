//! Store, acceleration structure and gather on the device without host round trips: raw
//! footprints (one per photon hit) go through the twin's heuristics and packing into the
//! slot of their own index (deterministic; rejected ones leave a zero record and a
//! zero-size box at 1e30 m — not the NaN box Vulkan calls inactive, which made lavapipe
//! miss active boxes), the AABB bottom-level structure is built straight from the device-written box
//! buffer, and the gather ([`crate::gather::GATHER_WGSL`]) reads the device-written
//! records. The host uploads the raw footprints and reads back only what the tests inspect.
//!
//! [`MapStore`] is the tracer's form of the stage, on the photon pass's device buffers:
//! raw footprints ([`KeyedFootprint`], smoothed by the photon pass; the twin's heuristics
//! here, rejected ones fall back to progressive photons as in [`arpa_core::store`]) and
//! progressive photons ([`KeyedPhoton`]), each with its
//! unique photon key, are keyed by `(map, Morton code of the box centre, photon key)`,
//! sorted on the device ([`crate::sort`]) and compacted into sorted record and box
//! buffers: caustic records first, then global ones. The result does not depend on the
//! order the photon pass appended in (bit-identical), and it is spatially sorted for the
//! acceleration-structure build ([`crate::accel`]).

use crate::device::GpuContext;
use crate::gather::GatherResult;
use crate::harness::{HarnessError, submit_and_read};
use arpa_core::estimate::QueryPoint;
use arpa_core::footprint::PackedFootprint;
use arpa_core::heuristics::PackedHeuristics;
use arpa_core::kernel::Kernel;
use wgpu::util::DeviceExt;

/// WGSL of the store kernel (entry point `store_footprints`), after the twin's
/// `kernel.wgsl`, `footprint.wgsl` and `heuristics.wgsl`.
pub const STORE_WGSL: &str = include_str!("shaders/store.wgsl");

/// A footprint as the photon pass leaves it at a diffuse hit, before the heuristics
/// (world space: metres, unit normal towards the arriving photon, W). 80 bytes.
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

/// The photon pass's records (defined by [`crate::photon`]): [`KeyedFootprint`] (96 bytes:
/// a [`RawFootprint`] with the map's smoothing applied and the normal flipped below the
/// shading plane, which flips the packed record's `row_n` exactly as the core's
/// `orient_to_shading_side`, plus the unique photon key) and [`KeyedPhoton`] (64 bytes).
pub use crate::photon::{KeyedFootprint, KeyedPhoton};

/// Parameters of the store kernels (`StoreParams` in store.wgsl, 112 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct StoreParams {
    heuristics: PackedHeuristics,
    radii: [f32; 2],
    pad0: [f32; 2],
    scene_lo: [f32; 3],
    raw_count: u32,
    scene_inv: [f32; 3],
    photon_count: u32,
    fp_sorted: u32,
    ph_sorted: u32,
    fp_count: u32,
    ph_count: u32,
}
const _: () = assert!(std::mem::size_of::<StoreParams>() == 112);

/// What [`store_and_gather`] read back.
#[derive(Clone, Debug, Default)]
pub struct StoreGatherOutput {
    /// Per raw footprint: 0 stored, 1 degenerate, 2 culled, 3 unrepresentable (`ARPA_STORE_*`).
    pub status: Vec<u32>,
    /// Per raw footprint: its record (zero when not stored).
    pub records: Vec<PackedFootprint>,
    /// Per query point.
    pub gathered: Vec<GatherResult>,
}

fn kernel_id(k: Kernel) -> u32 {
    match k {
        Kernel::Constant => 0,
        Kernel::Epanechnikov => 1,
        Kernel::Silverman => 2,
    }
}

/// Stores `raw` with `heuristics` and the progressive `radii` `[caustic, global]`
/// (metres), builds the footprint acceleration structure on the device and gathers at
/// `queries` with `kernel`, in one submission.
pub fn store_and_gather(
    ctx: &GpuContext,
    raw: &[RawFootprint],
    heuristics: PackedHeuristics,
    radii: [f32; 2],
    queries: &[QueryPoint],
    kernel: Kernel,
) -> Result<StoreGatherOutput, HarnessError> {
    let label = "store and gather";
    let err = |message: String| HarnessError::Size { label: label.into(), message };
    if raw.is_empty() || queries.is_empty() {
        return Err(err("no footprints or no queries".into()));
    }
    let device = &ctx.device;
    let max_groups = device.limits().max_compute_workgroups_per_dimension;
    let (n, nq) = (raw.len(), queries.len());
    let (g_store, g_gather) = ((n as u32).div_ceil(64), (nq as u32).div_ceil(64));
    if n >= 1 << 24 || g_store > max_groups || g_gather > max_groups {
        return Err(err(format!("{n} footprints / {nq} queries exceed one dispatch")));
    }
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let store_module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(store_source().into()) });
    let gather_module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(crate::gather::gather_source().into()) });
    let pipeline = |module: &wgpu::ShaderModule, entry: &str| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: None,
            module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    let store_pipeline = pipeline(&store_module, "store_footprints");
    let gather_pipeline = pipeline(&gather_module, "gather");

    let storage = wgpu::BufferUsages::STORAGE;
    let init = |contents: &[u8], usage| device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents, usage });
    let raw_buf = init(bytemuck::cast_slice(raw), storage);
    let params = StoreParams { heuristics, radii, ..StoreParams::default() };
    let params_buf = init(bytemuck::bytes_of(&params), storage);
    let buffer = |size: u64, usage| device.create_buffer(&wgpu::BufferDescriptor { label: Some(label), size, usage, mapped_at_creation: false });
    let src = wgpu::BufferUsages::COPY_SRC;
    let records_buf = buffer((n * 64) as u64, storage | src);
    let boxes_buf = buffer((n * 24) as u64, storage | wgpu::BufferUsages::BLAS_INPUT);
    let status_buf = buffer((n * 4) as u64, storage | src);
    let gq: Vec<[u32; 8]> = queries
        .iter()
        .map(|q| {
            let (p, nn) = (q.position.to_array(), q.normal.to_array());
            [p[0].to_bits(), p[1].to_bits(), p[2].to_bits(), kernel_id(kernel), nn[0].to_bits(), nn[1].to_bits(), nn[2].to_bits(), 0]
        })
        .collect();
    let q_buf = init(bytemuck::cast_slice(&gq), storage);
    let out_bytes = (nq * std::mem::size_of::<GatherResult>()) as u64;
    let out_buf = buffer(out_bytes, storage | src);

    let size = wgpu::BlasAABBGeometrySizeDescriptor { primitive_count: n as u32, flags: wgpu::AccelerationStructureGeometryFlags::empty() };
    let blas = device.create_blas(
        &wgpu::CreateBlasDescriptor {
            label: Some(label),
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        },
        wgpu::BlasGeometrySizeDescriptors::AABBs { descriptors: vec![size.clone()] },
    );
    let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
        label: Some(label),
        max_instances: 1,
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    });
    tlas[0] = Some(wgpu::TlasInstance::new(&blas, [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0], 0, 0xff));

    let no_photons = crate::gather::empty_photon_buffer(device);
    let bind = |pipeline: &wgpu::ComputePipeline, entries: &[wgpu::BindGroupEntry]| {
        device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout: &pipeline.get_bind_group_layout(0), entries })
    };
    let store_bg = bind(
        &store_pipeline,
        &[
            wgpu::BindGroupEntry { binding: 0, resource: raw_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: params_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: records_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: boxes_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: status_buf.as_entire_binding() },
        ],
    );
    let gather_bg = bind(
        &gather_pipeline,
        &[
            wgpu::BindGroupEntry { binding: 0, resource: records_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: q_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: out_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: tlas.as_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: no_photons.as_entire_binding() },
        ],
    );
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(&store_pipeline);
        pass.set_bind_group(0, &store_bg, &[]);
        pass.dispatch_workgroups(g_store, 1, 1);
    }
    let entry = wgpu::BlasBuildEntry {
        blas: &blas,
        geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
            size: &size,
            stride: wgpu::AABB_GEOMETRY_MIN_STRIDE,
            aabb_buffer: &boxes_buf,
            primitive_offset: 0,
        }]),
    };
    encoder.build_acceleration_structures([&entry], [&tlas]);
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(&gather_pipeline);
        pass.set_bind_group(0, &gather_bg, &[]);
        pass.dispatch_workgroups(g_gather, 1, 1);
    }
    let staging = |src_buf: &wgpu::Buffer, bytes: u64, encoder: &mut wgpu::CommandEncoder| {
        let s = buffer(bytes, wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST);
        encoder.copy_buffer_to_buffer(src_buf, 0, &s, 0, bytes);
        s
    };
    let st_status = staging(&status_buf, (n * 4) as u64, &mut encoder);
    let st_records = staging(&records_buf, (n * 64) as u64, &mut encoder);
    let st_out = staging(&out_buf, out_bytes, &mut encoder);
    let [status, records, gathered] = submit_and_read(ctx, scope, encoder, label, [&st_status, &st_records, &st_out])?;
    Ok(StoreGatherOutput {
        status: bytemuck::pod_collect_to_vec(&status),
        records: bytemuck::pod_collect_to_vec(&records),
        gathered: bytemuck::pod_collect_to_vec(&gathered),
    })
}

/// The store module's full source: the twin files it needs, the Morton code, store.wgsl.
fn store_source() -> String {
    use arpa_core::shaders::{FOOTPRINT, HEURISTICS, KERNEL};
    format!("{KERNEL}\n{FOOTPRINT}\n{HEURISTICS}\n{}\n{STORE_WGSL}", crate::sort::MORTON_WGSL)
}

/// What the keyed store counted (read back after [`MapStore::encode_store`]): sizes of the
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
    /// Progressive photons beyond the sorted output's capacity (0 unless the device's
    /// binding limit was hit; guarded, never written out of bounds).
    pub overflowed: u32,
    /// Footprint sort items appended (= both maps' footprints).
    pub footprint_items: u32,
    /// Photon sort items appended (= both maps' photons).
    pub photon_items: u32,
    /// Padding.
    pub pad: [u32; 2],
}

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

/// Per-iteration inputs of the keyed store.
#[derive(Clone, Copy, Debug)]
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

/// Compiled pipelines of the keyed store (one per device).
pub struct StorePipelines {
    layout: wgpu::BindGroupLayout,
    keyed: wgpu::ComputePipeline,
    photon_keys: wgpu::ComputePipeline,
    compact_footprints: wgpu::ComputePipeline,
    compact_photons: wgpu::ComputePipeline,
    pad_items: wgpu::ComputePipeline,
    sorter: crate::sort::Sorter,
}

impl StorePipelines {
    /// Compiles the keyed store's pipelines.
    pub fn new(device: &wgpu::Device) -> Self {
        let label = Some("arpa keyed store");
        let entries: Vec<_> = (5..=17).map(|b| crate::harness::storage_entry(b, b <= 7)).collect();
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label, entries: &entries });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(store_source().into()) });
        let pipeline = |entry: &str| crate::harness::pipeline(device, "arpa keyed store", &module, &[Some(&layout)], entry);
        Self {
            keyed: pipeline("store_keyed"),
            photon_keys: pipeline("photon_keys"),
            compact_footprints: pipeline("compact_footprints"),
            compact_photons: pipeline("compact_photons"),
            pad_items: pipeline("pad_items"),
            sorter: crate::sort::Sorter::new(device),
            layout,
        }
    }
}

/// Dispatches `threads` invocations of a 64-wide kernel that linearises a 2D grid
/// (`gid.x + gid.y · groups.x · 64`), so that more than 65 535 workgroups fit.
pub(crate) fn dispatch_linear(pass: &mut wgpu::ComputePass, threads: u32) {
    let groups = threads.div_ceil(64).max(1);
    if groups <= 65_535 {
        pass.dispatch_workgroups(groups, 1, 1);
    } else {
        pass.dispatch_workgroups(32_768, groups.div_ceil(32_768), 1);
    }
}

/// Why the keyed store cannot take a size.
#[derive(Debug, thiserror::Error)]
#[error("keyed store: {0}")]
pub struct StoreSizeError(pub String);

/// The keyed store's device buffers for given input buffers and capacities: slots, sort
/// items, counters and the sorted outputs (see the module docs).
pub struct MapStore {
    raw_capacity: u32,
    photon_capacity: u32,
    params: wgpu::Buffer,
    counts: wgpu::Buffer,
    fp_items: wgpu::Buffer,
    ph_items: wgpu::Buffer,
    photons_out_capacity: u32,
    /// Sorted footprint records ([`PackedFootprint`]); the first
    /// [`StoreCounts::total_footprints`] are valid, caustic first.
    pub footprints: wgpu::Buffer,
    /// Their boxes (6 `f32` each: min xyz, max xyz; metres): the AABB build input.
    pub footprint_boxes: wgpu::Buffer,
    /// Sorted progressive photons ([`arpa_core::progressive_photon::PackedPhoton`], padding zero); the first
    /// [`StoreCounts::total_photons`] are valid, caustic first.
    pub photons: wgpu::Buffer,
    /// Their boxes (position ± padded radius).
    pub photon_boxes: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
}

impl MapStore {
    /// Buffers for up to `raw_capacity` raw footprints in `raw` ([`KeyedFootprint`]) and
    /// `photon_capacity` progressive photons in `photons` ([`KeyedPhoton`]).
    pub fn new(
        device: &wgpu::Device,
        pipelines: &StorePipelines,
        raw: &wgpu::Buffer,
        photons: &wgpu::Buffer,
        raw_capacity: u32,
        photon_capacity: u32,
    ) -> Result<Self, StoreSizeError> {
        let total_photons = raw_capacity.checked_add(photon_capacity).filter(|&t| crate::sort::sorted_len(t) <= crate::sort::MAX_SORT_ITEMS);
        let Some(total_photons) = total_photons else {
            return Err(StoreSizeError(format!(
                "{raw_capacity} raw footprints + {photon_capacity} photons exceed the sort's {} items",
                crate::sort::MAX_SORT_ITEMS
            )));
        };
        let limits = device.limits();
        let max_bytes = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        if raw_capacity as u64 * 64 > max_bytes {
            return Err(StoreSizeError(format!("{raw_capacity} footprint slots of 64 bytes exceed the device's {max_bytes}-byte storage binding")));
        }
        // The sorted photons: as many as one binding holds (the compaction counts any
        // beyond in `StoreCounts::overflowed`).
        let photons_out_capacity = total_photons.min(u32::try_from(max_bytes / 48).unwrap_or(u32::MAX));
        let label = Some("arpa keyed store");
        use wgpu::BufferUsages as U;
        let buffer = |items: u32, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor { label, size: (items.max(1) as u64) * size, usage: U::STORAGE | usage, mapped_at_creation: false })
        };
        let fp_sorted = crate::sort::sorted_len(raw_capacity);
        let ph_sorted = crate::sort::sorted_len(total_photons);
        let fp_slots = buffer(raw_capacity, 64, U::empty());
        let fp_box_slots = buffer(raw_capacity, 24, U::empty());
        let ph_extra = buffer(raw_capacity, 64, U::empty());
        let fp_items = buffer(fp_sorted, 12, U::empty());
        let ph_items = buffer(ph_sorted, 12, U::empty());
        let counts = buffer(1, 48, U::COPY_SRC | U::COPY_DST);
        let params = buffer(1, std::mem::size_of::<StoreParams>() as u64, U::COPY_DST);
        let footprints = buffer(raw_capacity, 64, U::COPY_SRC);
        let footprint_boxes = buffer(raw_capacity, 24, U::COPY_SRC | U::BLAS_INPUT);
        let photons_out = buffer(photons_out_capacity, 48, U::COPY_SRC);
        let photon_boxes = buffer(photons_out_capacity, 24, U::COPY_SRC | U::BLAS_INPUT);
        let resources = [
            raw, photons, &params, &fp_slots, &fp_box_slots, &ph_extra, &fp_items, &ph_items, &counts, &footprints, &footprint_boxes, &photons_out,
            &photon_boxes,
        ];
        let entries: Vec<_> = resources.iter().enumerate().map(|(i, b)| wgpu::BindGroupEntry { binding: 5 + i as u32, resource: b.as_entire_binding() }).collect();
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor { label, layout: &pipelines.layout, entries: &entries });
        Ok(Self {
            raw_capacity,
            photon_capacity,
            params,
            counts,
            fp_items,
            ph_items,
            photons_out_capacity,
            footprints,
            footprint_boxes,
            photons: photons_out,
            photon_boxes,
            bind_group,
        })
    }

    /// Raw-footprint and photon capacities this store was made for.
    pub fn capacities(&self) -> (u32, u32) {
        (self.raw_capacity, self.photon_capacity)
    }

    /// The counters buffer ([`StoreCounts`], 48 bytes; `COPY_SRC`), valid after the
    /// commands of [`MapStore::encode_store`] ran.
    pub fn counts_buffer(&self) -> &wgpu::Buffer {
        &self.counts
    }

    fn params(&self, settings: &StoreSettings, counts: Option<&StoreCounts>) -> StoreParams {
        let (lo, hi) = settings.bounds;
        let inv = |k: usize| {
            let e = hi[k] - lo[k];
            if e > 0.0 && (1.0 / e).is_finite() { 1.0 / e } else { 0.0 }
        };
        let (fp_count, ph_count) = counts.map_or((0, 0), |c| (c.total_footprints(), c.total_photons()));
        StoreParams {
            heuristics: settings.heuristics,
            radii: settings.radii,
            pad0: [0.0; 2],
            scene_lo: lo,
            raw_count: settings.raw_count,
            scene_inv: [inv(0), inv(1), inv(2)],
            photon_count: settings.photon_count,
            fp_sorted: crate::sort::sorted_len(fp_count),
            ph_sorted: crate::sort::sorted_len(ph_count),
            fp_count,
            ph_count,
        }
    }

    /// First half: writes this iteration's parameters (through `queue`, before the next
    /// submission) and records the store and the appending of the sort items. Submit it
    /// and read the counts ([`MapStore::counts_buffer`]) before [`MapStore::encode_sort`].
    pub fn encode_store(&self, queue: &wgpu::Queue, pipelines: &StorePipelines, encoder: &mut wgpu::CommandEncoder, settings: &StoreSettings) -> Result<(), StoreSizeError> {
        if settings.raw_count > self.raw_capacity || settings.photon_count > self.photon_capacity {
            return Err(StoreSizeError(format!(
                "{} raw footprints / {} photons given for capacities {} / {}",
                settings.raw_count, settings.photon_count, self.raw_capacity, self.photon_capacity
            )));
        }
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&self.params(settings, None)));
        encoder.clear_buffer(&self.counts, 0, None);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa keyed store"), timestamp_writes: None });
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&pipelines.keyed);
        dispatch_linear(&mut pass, settings.raw_count);
        pass.set_pipeline(&pipelines.photon_keys);
        dispatch_linear(&mut pass, settings.photon_count);
        Ok(())
    }

    /// Second half, with the `counts` read back after [`MapStore::encode_store`]: pads the
    /// appended items to their sorted lengths, sorts them and compacts the records.
    pub fn encode_sort(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        pipelines: &StorePipelines,
        encoder: &mut wgpu::CommandEncoder,
        settings: &StoreSettings,
        counts: &StoreCounts,
    ) -> Result<(), StoreSizeError> {
        if counts.total_photons() > self.photons_out_capacity {
            return Err(StoreSizeError(format!(
                "{} progressive photons in one iteration; one storage binding of this device holds {}",
                counts.total_photons(),
                self.photons_out_capacity
            )));
        }
        let params = self.params(settings, Some(counts));
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa sort padding"), timestamp_writes: None });
            pass.set_bind_group(0, &self.bind_group, &[]);
            pass.set_pipeline(&pipelines.pad_items);
            dispatch_linear(&mut pass, params.fp_sorted.max(params.ph_sorted));
        }
        pipelines.sorter.encode(device, encoder, &self.fp_items, params.fp_sorted);
        pipelines.sorter.encode(device, encoder, &self.ph_items, params.ph_sorted);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa compaction"), timestamp_writes: None });
        pass.set_bind_group(0, &self.bind_group, &[]);
        pass.set_pipeline(&pipelines.compact_footprints);
        dispatch_linear(&mut pass, params.fp_sorted);
        pass.set_pipeline(&pipelines.compact_photons);
        dispatch_linear(&mut pass, params.ph_sorted);
        Ok(())
    }
}
