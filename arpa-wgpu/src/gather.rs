//! The gather stage on ray queries: footprint boxes in an AABB acceleration structure (one
//! bottom-level structure per photon map, told apart by instance masks), a point query per
//! query point, the exact filter-space test and kernel of the core's WGSL twin
//! (`arpa_footprint_irradiance`), irradiance summed per map; progressive photons (the
//! sphere test of the progressive radius) likewise when the structure has photon instances
//! ([`crate::accel`]).
//!
//! [`gather`] takes host slices so that it can be checked against the core's brute-force
//! gather ([`arpa_core::estimate::IrradianceEstimate`]); [`ImageGather`] is the tracer's
//! form on device buffers: camera-pass query records in, the iteration's radiance per
//! pixel out.

use crate::device::GpuContext;
use crate::harness::{HarnessError, output_and_staging, submit_and_read};
use arpa_core::aabb::Aabb;
use arpa_core::estimate::QueryPoint;
use arpa_core::footprint::PackedFootprint;
use arpa_core::kernel::Kernel;
use wgpu::util::DeviceExt;

/// WGSL of the gather kernel (entry point `gather`); concatenated after
/// `enable wgpu_ray_query;` and the twin's `kernel.wgsl` and `footprint.wgsl`.
pub const GATHER_WGSL: &str = include_str!("shaders/gather.wgsl");

/// Irradiance gathered at one query point (W/m², RGB, summed in `f32` on the device).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
pub struct GatherResult {
    /// Caustic-map irradiance.
    pub caustic: [f32; 3],
    /// Caustic footprints that contributed.
    pub caustic_count: u32,
    /// Global-map irradiance.
    pub global: [f32; 3],
    /// Global footprints that contributed.
    pub global_count: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuQuery {
    position: [f32; 3],
    kernel: u32,
    normal: [f32; 3],
    pad: u32,
}

fn kernel_id(k: Kernel) -> u32 {
    match k {
        Kernel::Constant => 0,
        Kernel::Epanechnikov => 1,
        Kernel::Silverman => 2,
    }
}

/// `f32` box containing the `f64` box `b` (each bound rounded outwards), as WGSL/Vulkan's
/// `AABB` record: min xyz, max xyz.
pub fn aabb_f32(b: &Aabb) -> [f32; 6] {
    let (lo, hi) = b.to_f32_conservative();
    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
}

/// Gathers the footprints `footprints` (with their acceleration-structure boxes `boxes`,
/// one per footprint) at every query point with kernel `kernel`. Footprints may come in any
/// order and either map. Errors when the device rejects the kernel or more than 2²⁴
/// footprints are given (the instance data that indexes them has 24 bits).
pub fn gather(
    ctx: &GpuContext,
    footprints: &[PackedFootprint],
    boxes: &[Aabb],
    queries: &[QueryPoint],
    kernel: Kernel,
) -> Result<Vec<GatherResult>, HarnessError> {
    let label = "footprint gather";
    let err = |message: String| HarnessError::Size { label: label.into(), message };
    if footprints.len() != boxes.len() {
        return Err(err(format!("{} footprints but {} boxes", footprints.len(), boxes.len())));
    }
    if footprints.len() >= 1 << 24 {
        return Err(err(format!("{} footprints; at most 2^24 - 1", footprints.len())));
    }
    if queries.is_empty() {
        return Ok(Vec::new());
    }
    let device = &ctx.device;
    let groups = u32::try_from(queries.len()).unwrap_or(u32::MAX).div_ceil(64);
    if groups > device.limits().max_compute_workgroups_per_dimension {
        return Err(err(format!("{} queries exceed one dispatch", queries.len())));
    }
    // Sort by map: caustic first, then global.
    let mut order: Vec<usize> = (0..footprints.len()).collect();
    order.sort_by_key(|&i| footprints[i].map.min(1));
    let sorted: Vec<PackedFootprint> = order.iter().map(|&i| footprints[i]).collect();
    let split = sorted.iter().position(|f| f.map != 0).unwrap_or(sorted.len());
    let ranges = [(0usize, split), (split, sorted.len())];

    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let blas_desc = wgpu::CreateBlasDescriptor {
        label: Some(label),
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    };
    let mut blases = Vec::new();
    for (map, &(start, end)) in ranges.iter().enumerate() {
        if end == start {
            continue;
        }
        let aabbs: Vec<[f32; 6]> = order[start..end].iter().map(|&i| aabb_f32(&boxes[i])).collect();
        let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents: bytemuck::cast_slice(&aabbs),
            usage: wgpu::BufferUsages::BLAS_INPUT,
        });
        let size = wgpu::BlasAABBGeometrySizeDescriptor {
            primitive_count: (end - start) as u32,
            flags: wgpu::AccelerationStructureGeometryFlags::empty(),
        };
        let blas = device.create_blas(&blas_desc, wgpu::BlasGeometrySizeDescriptors::AABBs { descriptors: vec![size.clone()] });
        blases.push((map, start, blas, buffer, size));
    }
    let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
        label: Some(label),
        max_instances: 2,
        flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
        update_mode: wgpu::AccelerationStructureUpdateMode::Build,
    });
    let identity = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0];
    for (slot, (map, start, blas, _, _)) in blases.iter().enumerate() {
        tlas[slot] = Some(wgpu::TlasInstance::new(blas, identity, *start as u32, 1u8 << *map));
    }

    // The `enable` directive must precede every declaration.
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(gather_source().into()) });
    let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: None,
        module: &module,
        entry_point: Some("gather"),
        compilation_options: Default::default(),
        cache: None,
    });
    // Storage bindings must not be empty.
    let dummy = [PackedFootprint::default()];
    let fp_words: &[PackedFootprint] = if sorted.is_empty() { &dummy } else { &sorted };
    let fp_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(fp_words),
        usage: wgpu::BufferUsages::STORAGE,
    });
    let gq: Vec<GpuQuery> = queries
        .iter()
        .map(|q| GpuQuery { position: q.position.to_array(), kernel: kernel_id(kernel), normal: q.normal.to_array(), pad: 0 })
        .collect();
    let q_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some(label), contents: bytemuck::cast_slice(&gq), usage: wgpu::BufferUsages::STORAGE });
    let out_bytes = (queries.len() * std::mem::size_of::<GatherResult>()) as u64;
    let (out_buf, staging) = output_and_staging(device, label, out_bytes);
    let no_photons = empty_photon_buffer(device);
    let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout: &pipeline.get_bind_group_layout(0),
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: fp_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: q_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 2, resource: out_buf.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 3, resource: tlas.as_binding() },
            wgpu::BindGroupEntry { binding: 4, resource: no_photons.as_entire_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    let entries: Vec<wgpu::BlasBuildEntry> = blases
        .iter()
        .map(|(_, _, blas, buffer, size)| wgpu::BlasBuildEntry {
            blas,
            geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry {
                size,
                stride: wgpu::AABB_GEOMETRY_MIN_STRIDE,
                aabb_buffer: buffer,
                primitive_offset: 0,
            }]),
        })
        .collect();
    encoder.build_acceleration_structures(entries.iter(), [&tlas]);
    {
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some(label), timestamp_writes: None });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        pass.dispatch_workgroups(groups, 1, 1);
    }
    encoder.copy_buffer_to_buffer(&out_buf, 0, &staging, 0, out_bytes);
    let [out] = submit_and_read(ctx, scope, encoder, label, [&staging])?;
    Ok(bytemuck::pod_collect_to_vec(&out))
}

/// The gather module's full source (`enable` directive, twin files, gather.wgsl).
pub(crate) fn gather_source() -> String {
    format!("enable wgpu_ray_query;\n{}\n{}\n{GATHER_WGSL}", arpa_core::shaders::KERNEL, arpa_core::shaders::FOOTPRINT)
}

/// A one-record photon buffer for gathers without photons (bindings must not be empty).
pub(crate) fn empty_photon_buffer(device: &wgpu::Device) -> wgpu::Buffer {
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("arpa no photons"),
        contents: bytemuck::bytes_of(&arpa_core::progressive_photon::PackedPhoton::default()),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct ImageParams {
    radii: [f32; 2],
    kernel: u32,
    pixels: u32,
    batch: u32,
    pad: [u32; 3],
}

/// Where one gather stands among the photon batches of an iteration (each batch's maps
/// are gathered in turn; see [`ImageGather::encode`]).
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

    fn bits(self) -> u32 {
        self.first as u32 | (self.last as u32) << 1
    }
}

/// The tracer's gather: per query record (one per pixel, [`arpa_core::tracer::QueryRecord`]),
/// `radiance + weight · (E_caustic + E_global)` with non-finite components set to 0 (as
/// arpa-cpu's gather), written as `vec4<f32>` (RGB, 0) per pixel; the number of contributions
/// summed into a 64-bit counter and the valid records counted ([`ImageGather::total_buffer`]).
pub struct ImageGather {
    pipeline: wgpu::ComputePipeline,
    params: wgpu::Buffer,
    total: wgpu::Buffer,
}

impl ImageGather {
    /// Compiles the pipeline.
    pub fn new(device: &wgpu::Device) -> Self {
        let label = Some("arpa image gather");
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(gather_source().into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label,
            layout: None,
            module: &module,
            entry_point: Some("gather_image"),
            compilation_options: Default::default(),
            cache: None,
        });
        let buffer = |size, usage| device.create_buffer(&wgpu::BufferDescriptor { label, size, usage, mapped_at_creation: false });
        use wgpu::BufferUsages as U;
        Self { pipeline, params: buffer(32, U::STORAGE | U::COPY_DST), total: buffer(16, U::STORAGE | U::COPY_DST | U::COPY_SRC) }
    }

    /// The counters (four `u32`: contributions low and high word, valid query records,
    /// zero), valid after the commands of
    /// [`ImageGather::encode`] ran.
    pub fn total_buffer(&self) -> &wgpu::Buffer {
        &self.total
    }

    /// Records the gather of `pixels` query records `records` against the sorted
    /// `footprints` and `photons` (records of [`crate::store::MapStore`]) in `tlas`
    /// ([`crate::accel`]) with progressive `radii` (metres) and footprint `kernel`, into
    /// `image` (`pixels` × 16 bytes).
    ///
    /// Photon batches: an iteration traced in several batches gathers each batch's maps in
    /// turn, into `irradiance` (`pixels` × 16 bytes: per pixel the irradiance summed over
    /// the batches so far, W/m², RGB); `batch` says which: the first starts the sum (and
    /// clears the counters), the last writes `image` = `radiance + weight · (sum)` and not
    /// `irradiance`. [`GatherBatch::WHOLE`] is the single-pass gather, bit for bit. The
    /// contribution count then sums over the batches; the valid records are counted once.
    #[allow(clippy::too_many_arguments)]
    pub fn encode(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        encoder: &mut wgpu::CommandEncoder,
        footprints: &wgpu::Buffer,
        photons: &wgpu::Buffer,
        tlas: &wgpu::Tlas,
        records: &wgpu::Buffer,
        image: &wgpu::Buffer,
        irradiance: &wgpu::Buffer,
        radii: [f32; 2],
        kernel: Kernel,
        pixels: u32,
        batch: GatherBatch,
    ) {
        let params = ImageParams { radii, kernel: kernel_id(kernel), pixels, batch: batch.bits(), pad: [0; 3] };
        queue.write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        if batch.first {
            encoder.clear_buffer(&self.total, 0, None);
        }
        let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("arpa image gather"),
            layout: &self.pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: footprints.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 3, resource: tlas.as_binding() },
                wgpu::BindGroupEntry { binding: 4, resource: photons.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 5, resource: records.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 6, resource: image.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 7, resource: self.params.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 8, resource: self.total.as_entire_binding() },
                wgpu::BindGroupEntry { binding: 9, resource: irradiance.as_entire_binding() },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa image gather"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind_group, &[]);
        crate::store::dispatch_linear(&mut pass, pixels);
    }
}
