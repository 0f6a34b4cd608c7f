//! Store, acceleration structure and gather on the device without host round trips: raw
//! footprints (one per photon hit) go through the twin's heuristics and packing into the
//! slot of their own index (deterministic; rejected ones leave a zero record and a
//! zero-size box at 1e30 m — not the NaN box Vulkan calls inactive, which made lavapipe
//! miss active boxes), the AABB bottom-level structure is built straight from the device-written box
//! buffer, and the gather ([`crate::gather::GATHER_WGSL`]) reads the device-written
//! records. The host uploads the raw footprints and reads back only what the tests inspect.

use crate::device::GpuContext;
use crate::gather::{GATHER_WGSL, GatherResult};
use crate::harness::{HarnessError, submit_and_read};
use arpa_core::estimate::QueryPoint;
use arpa_core::footprint::PackedFootprint;
use arpa_core::heuristics::PackedHeuristics;
use arpa_core::kernel::Kernel;
use wgpu::util::DeviceExt;

/// WGSL of the store kernel (entry point `store_footprints`), after the twin's
/// `kernel.wgsl`, `footprint.wgsl` and `heuristics.wgsl`.
pub const STORE_WGSL: &str = include_str!("shaders/store.wgsl");

/// A footprint as the photon pass leaves it at a diffuse hit (before smoothing-independent
/// heuristics): metres, unit normal towards the arriving photon, W.
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

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct StoreParams {
    heuristics: PackedHeuristics,
    radii: [f32; 2],
    pad: [f32; 2],
}

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
    let twin = format!("{}\n{}\n{}", arpa_core::shaders::KERNEL, arpa_core::shaders::FOOTPRINT, arpa_core::shaders::HEURISTICS);
    let store_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(format!("{twin}\n{STORE_WGSL}").into()),
    });
    let gather_module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(
            format!("enable wgpu_ray_query;\n{}\n{}\n{GATHER_WGSL}", arpa_core::shaders::KERNEL, arpa_core::shaders::FOOTPRINT).into(),
        ),
    });
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
    let params = StoreParams { heuristics, radii, pad: [0.0; 2] };
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
