//! Device helpers only the tests use: read-backs, the photon pass's outputs, ray casting
//! against the scene's acceleration structure, the sort on host items, the image gather's
//! box traversal on host records, a store → gather chain in one submission, and the
//! tracer's store → sort → build → gather → accumulate chain on host data.
#![allow(dead_code)]

use arpa_core::base::aabb::Aabb;
use arpa_core::gather::estimate::QueryPoint;
use arpa_core::store::footprint::PackedFootprint;
use arpa_core::glam::Vec3;
use arpa_core::gpu::codes::kernel_code;
use arpa_core::gather::scales::Bandwidth;
use arpa_core::{gpu::layout::{AccumPixel, GatherCounts, GatherResult, ImageBufferSizes, KeyedFootprint, KeyedPhoton, PhotonCounters, RawFootprint, StoreCounts, StoreParams, StoreSettings}, gpu::sort::SortItem};
use arpa_core::gpu::sort::sorted_len;
use arpa_core::store::heuristics::PackedHeuristics;
use arpa_core::gather::kernel::Kernel;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::render::ray_cast::RayHit;
use arpa_core::render::tracer::QueryRecord;
use arpa_wgpu::GpuContext;
use arpa_wgpu::accumulate::DeviceAccumulator;
use arpa_wgpu::maps::PhotonMaps;
use arpa_wgpu::store::BATCH_COUNTS_BYTES;
use arpa_wgpu::photon::PhotonOutputs;
use arpa_wgpu::scene::GpuGeometry;
use arpa_wgpu::sort::{RadixScratch, Sorter};
use wgpu::util::DeviceExt;

/// Runs `record` in a validation scope and panics with wgpu's message on an error.
pub fn checked<T>(ctx: &GpuContext, label: &str, record: impl FnOnce() -> T) -> T {
    let scope = ctx.device.push_error_scope(wgpu::ErrorFilter::Validation);
    let out = record();
    if let Some(e) = pollster::block_on(scope.pop()) {
        panic!("{label}: {e}");
    }
    out
}

/// The first `bytes` of each buffer (`COPY_SRC`), after the work submitted so far.
pub fn read(ctx: &GpuContext, buffers: &[(&wgpu::Buffer, u64)]) -> Vec<Vec<u8>> {
    let device = &ctx.device;
    let staging: Vec<wgpu::Buffer> = checked(ctx, "read-back", || {
        let mut encoder = device.create_command_encoder(&Default::default());
        let staging = buffers
            .iter()
            .map(|&(b, bytes)| {
                let s = device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("test read-back"),
                    size: bytes.max(4),
                    usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                    mapped_at_creation: false,
                });
                if bytes > 0 {
                    encoder.copy_buffer_to_buffer(b, 0, &s, 0, bytes);
                }
                s
            })
            .collect();
        ctx.queue.submit([encoder.finish()]);
        staging
    });
    staging
        .iter()
        .zip(buffers)
        .map(|(s, &(_, bytes))| {
            s.map_async(wgpu::MapMode::Read, .., |r| r.expect("map"));
            device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
            let out = s.get_mapped_range(..).expect("mapped").to_vec();
            s.unmap();
            out[..bytes as usize].to_vec()
        })
        .collect()
}

/// A storage buffer holding `contents` (one zero word when empty: bindings must not be).
pub fn upload(ctx: &GpuContext, contents: &[u8], usage: wgpu::BufferUsages) -> wgpu::Buffer {
    let pad = [0u8; 96];
    let contents = if contents.is_empty() { &pad[..] } else { contents };
    ctx.device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: Some("test upload"), contents, usage: wgpu::BufferUsages::STORAGE | usage })
}

/// A zeroed storage buffer of `bytes` (`COPY_SRC`).
pub fn output(ctx: &GpuContext, bytes: u64, usage: wgpu::BufferUsages) -> wgpu::Buffer {
    ctx.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("test output"),
        size: bytes.max(16),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | usage,
        mapped_at_creation: false,
    })
}

/// A compute pipeline of `entry` in `source` with the layout wgpu derives.
pub fn pipeline(ctx: &GpuContext, label: &str, source: &str, entry: &str) -> wgpu::ComputePipeline {
    checked(ctx, label, || {
        let module = ctx.device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
        ctx.device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: None,
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    })
}

/// Records one dispatch of `groups` workgroups of `pipeline` with `bindings` in group 0.
pub fn dispatch(ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, pipeline: &wgpu::ComputePipeline, bindings: &[(u32, wgpu::BindingResource)], groups: u32) {
    let entries: Vec<wgpu::BindGroupEntry> = bindings.iter().map(|(b, r)| wgpu::BindGroupEntry { binding: *b, resource: r.clone() }).collect();
    let group = ctx.device.create_bind_group(&wgpu::BindGroupDescriptor { label: None, layout: &pipeline.get_bind_group_layout(0), entries: &entries });
    let mut pass = encoder.begin_compute_pass(&Default::default());
    pass.set_pipeline(pipeline);
    pass.set_bind_group(0, &group, &[]);
    pass.dispatch_workgroups(groups, 1, 1);
}

/// What the photon pass wrote: its counters and the records, in append order.
#[derive(Clone, Debug, Default)]
pub struct PhotonReadback {
    /// The counters.
    pub counters: PhotonCounters,
    /// The footprints written, in append order (not deterministic; sort by key).
    pub footprints: Vec<KeyedFootprint>,
    /// The progressive photons written, in append order.
    pub photons: Vec<KeyedPhoton>,
}

/// Reads the photon pass's counters and written records back.
pub fn read_outputs(ctx: &GpuContext, out: &PhotonOutputs) -> PhotonReadback {
    let [c] = read(ctx, &[(out.counters(), size_of::<PhotonCounters>() as u64)]).try_into().unwrap();
    let counters: PhotonCounters = bytemuck::pod_read_unaligned(&c);
    let nf = counters.footprint_appends.min(out.footprint_capacity()) as u64;
    let np = counters.photon_appends.min(out.photon_capacity()) as u64;
    let [f, p] = read(ctx, &[(out.footprints(), nf * size_of::<KeyedFootprint>() as u64), (out.photons(), np * size_of::<KeyedPhoton>() as u64)]).try_into().unwrap();
    PhotonReadback { counters, footprints: bytemuck::pod_collect_to_vec(&f), photons: bytemuck::pod_collect_to_vec(&p) }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct CastRay {
    origin: [f32; 3],
    t_max: f32,
    direction: [f32; 3],
    pad: u32,
}

#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct CastHit {
    t: f32,
    mesh: u32,
    triangle: u32,
    b1: f32,
    b2: f32,
    pad: [u32; 3],
}

/// Closest hits of the rays `(origin, unit direction, t_max)` (metres) against `geometry`,
/// as [`arpa_core::render::ray_cast::RayCaster::intersect`] would return them.
pub fn cast_rays(ctx: &GpuContext, geometry: &GpuGeometry, rays: &[(Vec3, Vec3, f32)]) -> Vec<Option<RayHit>> {
    if rays.is_empty() {
        return Vec::new();
    }
    let input: Vec<CastRay> = rays.iter().map(|(o, d, t)| CastRay { origin: o.to_array(), t_max: *t, direction: d.to_array(), pad: 0 }).collect();
    let source = format!("enable wgpu_ray_query;\n{}", include_str!("ray_cast.wgsl"));
    let pipeline = pipeline(ctx, "ray cast", &source, "cast_rays");
    let in_buf = upload(ctx, bytemuck::cast_slice(&input), wgpu::BufferUsages::empty());
    let bytes = (rays.len() * size_of::<CastHit>()) as u64;
    let out = output(ctx, bytes, wgpu::BufferUsages::empty());
    checked(ctx, "ray cast", || {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        let bindings = [(0, in_buf.as_entire_binding()), (1, out.as_entire_binding()), (2, geometry.tlas().as_binding())];
        dispatch(ctx, &mut encoder, &pipeline, &bindings, (rays.len() as u32).div_ceil(64));
        ctx.queue.submit([encoder.finish()]);
    });
    let [hits] = read(ctx, &[(&out, bytes)]).try_into().unwrap();
    bytemuck::pod_collect_to_vec::<u8, CastHit>(&hits)
        .iter()
        .map(|h| {
            // A miss has mesh u32::MAX. The kernel reports the BLAS primitive: map it back
            // to the mesh's triangle.
            let triangle = *geometry.triangle_orders().get(h.mesh as usize)?.get(h.triangle as usize)?;
            Some(RayHit { t: h.t, mesh: h.mesh, triangle, b1: h.b1, b2: h.b2 })
        })
        .collect()
}

/// Sorts `items` on the device (padded with [`SortItem::INVALID`]) and returns them sorted.
pub fn sort_items(ctx: &GpuContext, items: &[SortItem]) -> Vec<SortItem> {
    let n = sorted_len(items.len() as u32);
    let mut padded = items.to_vec();
    padded.resize(n as usize, SortItem::INVALID);
    let sorter = checked(ctx, "sort", || Sorter::new(&ctx.device));
    let buffer = upload(ctx, bytemuck::cast_slice(&padded), wgpu::BufferUsages::COPY_SRC);
    checked(ctx, "sort", || {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        sorter.encode(&ctx.device, &mut encoder, &buffer, n);
        ctx.queue.submit([encoder.finish()]);
    });
    let [out] = read(ctx, &[(&buffer, items.len() as u64 * size_of::<SortItem>() as u64)]).try_into().unwrap();
    bytemuck::pod_collect_to_vec(&out)
}

/// Radix-sorts the first `items.len() - tail` of `items` on the device (values below
/// `value_bound`) and returns the whole buffer.
pub fn radix_sort_items(ctx: &GpuContext, items: &[SortItem], tail: usize, value_bound: u32) -> Vec<SortItem> {
    let n = (items.len() - tail) as u32;
    let sorter = checked(ctx, "sort", || Sorter::new(&ctx.device));
    let scratch = RadixScratch::new(&ctx.device, n);
    let buffer = upload(ctx, bytemuck::cast_slice(items), wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST);
    checked(ctx, "radix sort", || {
        let mut encoder = ctx.device.create_command_encoder(&Default::default());
        sorter.encode_radix(&ctx.device, &mut encoder, &buffer, &scratch, n, value_bound);
        ctx.queue.submit([encoder.finish()]);
    });
    let [out] = read(ctx, &[(&buffer, items.len() as u64 * size_of::<SortItem>() as u64)]).try_into().unwrap();
    bytemuck::pod_collect_to_vec(&out)
}

/// The test entry point of the gather module: `arpa_gather_at` (the box traversal) for
/// each query, no photons, results per map and scale.
const TEST_GATHER: &str = r#"
struct TestQuery {
    position: vec3<f32>,
    kernel: u32,
    normal: vec3<f32>,
    scales: u32,
}
@group(0) @binding(8) var<storage, read> test_queries: array<TestQuery>;
@group(0) @binding(9) var<storage, read_write> test_results: array<ArpaGatherResult>;

@compute @workgroup_size(64)
fn test_gather(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&test_queries) {
        return;
    }
    let q = test_queries[i];
    test_results[i] = arpa_gather_at(q.position, q.normal, q.kernel, vec2<f32>(0.0), q.scales);
}
"#;

fn gather_queries(queries: &[QueryPoint], kernel: Kernel, scales: u32) -> Vec<[u32; 8]> {
    queries
        .iter()
        .map(|q| {
            let (p, n) = (q.position.to_array(), q.normal.to_array());
            [p[0].to_bits(), p[1].to_bits(), p[2].to_bits(), kernel_code(kernel), n[0].to_bits(), n[1].to_bits(), n[2].to_bits(), scales]
        })
        .collect()
}

/// Records the gather at `queries` over `footprints` (sorted by map) in `tlas`, evaluating
/// `scales` scales of the bandwidth ladder.
fn encode_gather(ctx: &GpuContext, encoder: &mut wgpu::CommandEncoder, footprints: &wgpu::Buffer, tlas: &wgpu::Tlas, queries: &[QueryPoint], kernel: Kernel, scales: u32) -> wgpu::Buffer {
    let source = format!("{}\n{TEST_GATHER}", arpa_wgpu::shaders::gather());
    let pipeline = pipeline(ctx, "test gather", &source, "test_gather");
    let q = upload(ctx, bytemuck::cast_slice(&gather_queries(queries, kernel, scales)), wgpu::BufferUsages::empty());
    let results = output(ctx, (queries.len() * size_of::<GatherResult>()) as u64, wgpu::BufferUsages::empty());
    let no_photons = upload(ctx, bytemuck::bytes_of(&PackedPhoton::default()), wgpu::BufferUsages::empty());
    let bindings = [
        (0, footprints.as_entire_binding()),
        (1, no_photons.as_entire_binding()),
        (7, tlas.as_binding()),
        (8, q.as_entire_binding()),
        (9, results.as_entire_binding()),
    ];
    dispatch(ctx, encoder, &pipeline, &bindings, (queries.len() as u32).div_ceil(64));
    results
}

fn identity() -> [f32; 12] {
    [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0]
}

/// Gathers the footprints `footprints` (with their acceleration-structure boxes `boxes`,
/// one per footprint, rounded outwards to `f32`) at every query point with `kernel` at the
/// first `scales` scales of the bandwidth ladder (1: the stored footprints only): one BLAS
/// per map, instance masks `1 << map`, the device's box traversal and exact test.
/// Footprints may come in any order and either map.
pub fn gather(ctx: &GpuContext, footprints: &[PackedFootprint], boxes: &[Aabb], queries: &[QueryPoint], kernel: Kernel, scales: u32) -> Vec<GatherResult> {
    assert_eq!(footprints.len(), boxes.len(), "one box per footprint");
    if queries.is_empty() {
        return Vec::new();
    }
    let device = &ctx.device;
    // Sorted by map: caustic first, then global.
    let mut order: Vec<usize> = (0..footprints.len()).collect();
    order.sort_by_key(|&i| footprints[i].map.min(1));
    let sorted: Vec<PackedFootprint> = order.iter().map(|&i| footprints[i]).collect();
    let split = sorted.iter().position(|f| f.map != 0).unwrap_or(sorted.len());
    checked(ctx, "test gather", || {
        let blas_desc = wgpu::CreateBlasDescriptor {
            label: None,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        };
        let mut blases = Vec::new();
        for (map, (start, end)) in [(0usize, split), (split, sorted.len())].into_iter().enumerate() {
            if end == start {
                continue;
            }
            let aabbs: Vec<[f32; 6]> = order[start..end]
                .iter()
                .map(|&i| {
                    let (lo, hi) = boxes[i].to_f32_conservative();
                    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
                })
                .collect();
            let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor { label: None, contents: bytemuck::cast_slice(&aabbs), usage: wgpu::BufferUsages::BLAS_INPUT });
            let size = wgpu::BlasAABBGeometrySizeDescriptor { primitive_count: (end - start) as u32, flags: wgpu::AccelerationStructureGeometryFlags::empty() };
            let blas = device.create_blas(&blas_desc, wgpu::BlasGeometrySizeDescriptors::AABBs { descriptors: vec![size.clone()] });
            blases.push((map, start, blas, buffer, size));
        }
        let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
            label: None,
            max_instances: 2,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        });
        for (slot, (map, start, blas, _, _)) in blases.iter().enumerate() {
            tlas[slot] = Some(wgpu::TlasInstance::new(blas, identity(), *start as u32, 1u8 << *map));
        }
        let fp_buf = upload(ctx, bytemuck::cast_slice(&sorted), wgpu::BufferUsages::empty());
        let mut encoder = device.create_command_encoder(&Default::default());
        let entries: Vec<wgpu::BlasBuildEntry> = blases
            .iter()
            .map(|(_, _, blas, buffer, size)| wgpu::BlasBuildEntry {
                blas,
                geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry { size, stride: wgpu::AABB_GEOMETRY_MIN_STRIDE, aabb_buffer: buffer, primitive_offset: 0 }]),
            })
            .collect();
        encoder.build_acceleration_structures(entries.iter(), [&tlas]);
        let results = encode_gather(ctx, &mut encoder, &fp_buf, &tlas, queries, kernel, scales);
        ctx.queue.submit([encoder.finish()]);
        let [out] = read(ctx, &[(&results, (queries.len() * size_of::<GatherResult>()) as u64)]).try_into().unwrap();
        bytemuck::pod_collect_to_vec(&out)
    })
}

/// The test store kernel: each raw footprint through the twin's heuristics into the slot of
/// its own index, with its status; a rejected footprint leaves a zero record and a
/// zero-size box at 1e30 m, which no query reaches. Not an inactive box (min.x = NaN, as
/// Vulkan defines it): lavapipe then missed active boxes too.
const TEST_STORE: &str = r#"
struct TestRawFootprint {
    center: vec3<f32>,
    map: u32,
    normal: vec3<f32>,
    pad0: u32,
    du: vec3<f32>,
    pad1: u32,
    dv: vec3<f32>,
    pad2: u32,
    flux: vec3<f32>,
    pad3: u32,
}
struct TestStoreParams {
    heuristics: ArpaHeuristics,
    radii: vec2<f32>,
}
@group(0) @binding(0) var<storage, read> test_raw: array<TestRawFootprint>;
@group(0) @binding(1) var<storage, read> test_params: TestStoreParams;
@group(0) @binding(2) var<storage, read_write> test_records: array<ArpaPackedFootprint>;
@group(0) @binding(3) var<storage, read_write> test_boxes: array<f32>;
@group(0) @binding(4) var<storage, read_write> test_status: array<u32>;

@compute @workgroup_size(64)
fn test_store(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&test_raw) {
        return;
    }
    let f = test_raw[i];
    let map = min(f.map, 1u);
    let s = arpa_store(test_params.heuristics, f.center, f.normal, f.du, f.dv, f.flux, map, test_params.radii[map]);
    test_status[i] = s.status;
    let b = 6u * i;
    var lo = vec3<f32>(1e30);
    var hi = vec3<f32>(1e30);
    var record: ArpaPackedFootprint;
    if s.status == ARPA_STORE_OK {
        record = s.record;
        lo = s.box_min;
        hi = s.box_max;
    }
    test_records[i] = record;
    test_boxes[b] = lo.x; test_boxes[b + 1u] = lo.y; test_boxes[b + 2u] = lo.z;
    test_boxes[b + 3u] = hi.x; test_boxes[b + 4u] = hi.y; test_boxes[b + 5u] = hi.z;
}
"#;

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

/// Stores `raw` with `heuristics` and the progressive `radii` `[caustic, global]`
/// (metres), builds one acceleration structure over the device-written boxes (rejected
/// footprints included) and gathers at `queries` with `kernel`, in one submission.
pub fn store_and_gather(ctx: &GpuContext, raw: &[RawFootprint], heuristics: PackedHeuristics, radii: [f32; 2], queries: &[QueryPoint], kernel: Kernel) -> StoreGatherOutput {
    assert!(!raw.is_empty() && !queries.is_empty());
    let device = &ctx.device;
    let n = raw.len();
    let source = arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::HEURISTICS]) + TEST_STORE;
    let store = pipeline(ctx, "test store", &source, "test_store");
    checked(ctx, "store and gather", || {
        let raw_buf = upload(ctx, bytemuck::cast_slice(raw), wgpu::BufferUsages::empty());
        let params = StoreParams { heuristics, radii, ..StoreParams::default() };
        let params_buf = upload(ctx, bytemuck::bytes_of(&params), wgpu::BufferUsages::empty());
        let records = output(ctx, (n * 64) as u64, wgpu::BufferUsages::empty());
        let boxes = output(ctx, (n * 24) as u64, wgpu::BufferUsages::BLAS_INPUT);
        let status = output(ctx, (n * 4) as u64, wgpu::BufferUsages::empty());
        let size = wgpu::BlasAABBGeometrySizeDescriptor { primitive_count: n as u32, flags: wgpu::AccelerationStructureGeometryFlags::empty() };
        let blas = device.create_blas(
            &wgpu::CreateBlasDescriptor { label: None, flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE, update_mode: wgpu::AccelerationStructureUpdateMode::Build },
            wgpu::BlasGeometrySizeDescriptors::AABBs { descriptors: vec![size.clone()] },
        );
        let mut tlas = device.create_tlas(&wgpu::CreateTlasDescriptor {
            label: None,
            max_instances: 1,
            flags: wgpu::AccelerationStructureFlags::PREFER_FAST_TRACE,
            update_mode: wgpu::AccelerationStructureUpdateMode::Build,
        });
        tlas[0] = Some(wgpu::TlasInstance::new(&blas, identity(), 0, 0xff));
        let mut encoder = device.create_command_encoder(&Default::default());
        let bindings = [
            (0, raw_buf.as_entire_binding()),
            (1, params_buf.as_entire_binding()),
            (2, records.as_entire_binding()),
            (3, boxes.as_entire_binding()),
            (4, status.as_entire_binding()),
        ];
        dispatch(ctx, &mut encoder, &store, &bindings, (n as u32).div_ceil(64));
        let entry = wgpu::BlasBuildEntry {
            blas: &blas,
            geometry: wgpu::BlasGeometries::AabbGeometries(vec![wgpu::BlasAabbGeometry { size: &size, stride: wgpu::AABB_GEOMETRY_MIN_STRIDE, aabb_buffer: &boxes, primitive_offset: 0 }]),
        };
        encoder.build_acceleration_structures([&entry], [&tlas]);
        let results = encode_gather(ctx, &mut encoder, &records, &tlas, queries, kernel, 1);
        ctx.queue.submit([encoder.finish()]);
        let [status, records, gathered] =
            read(ctx, &[(&status, (n * 4) as u64), (&records, (n * 64) as u64), (&results, (queries.len() * size_of::<GatherResult>()) as u64)]).try_into().unwrap();
        StoreGatherOutput { status: bytemuck::pod_collect_to_vec(&status), records: bytemuck::pod_collect_to_vec(&records), gathered: bytemuck::pod_collect_to_vec(&gathered) }
    })
}

/// What [`run_from_host`] read back.
#[derive(Clone, Debug, Default)]
pub struct HostRun {
    /// Store counts.
    pub counts: StoreCounts,
    /// Sorted footprints.
    pub footprints: Vec<PackedFootprint>,
    /// Sorted progressive photons.
    pub photons: Vec<PackedPhoton>,
    /// The iteration image: every plane of the bandwidth, plane-major (plane `p` of pixel
    /// `i` at `p · pixels + i`; radiance or moments, RGB).
    pub image: Vec<[f32; 3]>,
    /// Contributions the gather found.
    pub gathered: u64,
    /// The running mean of every plane after accumulating `image` `iterations` times.
    pub mean: Vec<Vec3>,
}

/// Uploads `raw` and `photons` as a photon pass would leave them, runs the tracer's store,
/// sort, build and gather ([`PhotonMaps`], one batch) for `records` with the planes of
/// `bandwidth`, and accumulates the iteration image `iterations` times (to exercise the
/// running mean).
#[allow(clippy::too_many_arguments)]
pub fn run_from_host(
    ctx: &GpuContext,
    raw: &[KeyedFootprint],
    photons: &[KeyedPhoton],
    settings: &StoreSettings,
    records: &[QueryRecord],
    kernel: Kernel,
    bandwidth: Bandwidth,
    iterations: u32,
) -> HostRun {
    let device = &ctx.device;
    let pixels = records.len() as u32;
    let raw_buf = upload(ctx, bytemuck::cast_slice(raw), wgpu::BufferUsages::empty());
    let ph_buf = upload(ctx, bytemuck::cast_slice(photons), wgpu::BufferUsages::empty());
    let rec_buf = upload(ctx, bytemuck::cast_slice(records), wgpu::BufferUsages::empty());
    // The photon pass's counters as it would leave them: the store takes its record counts
    // from them on the device (the schedule kernel).
    let pass = PhotonCounters { footprint_appends: settings.raw_count, photon_appends: settings.photon_count, ..PhotonCounters::default() };
    let counters_buf = upload(ctx, bytemuck::bytes_of(&pass), wgpu::BufferUsages::COPY_SRC);
    let mut maps = PhotonMaps::new(ctx).unwrap();
    let (nr, np) = (raw.len() as u32, photons.len() as u32);
    let capacities = arpa_core::gpu::batch::Capacities { raw_footprints: nr, photons: np, sorted_photons: (nr + np).max(1) };
    maps.bind_inputs(ctx, &raw_buf, &ph_buf, &counters_buf, capacities).unwrap();
    maps.begin_iteration(ctx, 1);
    let mut encoder = device.create_command_encoder(&Default::default());
    maps.encode_batch(ctx, &mut encoder, &StoreSettings { raw_count: 0, photon_count: 0, ..*settings }, &counters_buf, 0, true).unwrap();
    ctx.queue.submit([encoder.finish()]);
    let [batch] = read(ctx, &[(maps.batch_counts(), BATCH_COUNTS_BYTES)]).try_into().unwrap();
    let batch: Vec<arpa_core::gpu::layout::BatchCounts> = bytemuck::pod_collect_to_vec(&batch);
    let counts = batch[0].store;
    maps.build(ctx).unwrap();
    let sizes = ImageBufferSizes::new(pixels, bandwidth);
    let entries = bandwidth.planes() as u32 * pixels;
    let image = output(ctx, sizes.image, wgpu::BufferUsages::empty());
    let irradiance = output(ctx, sizes.batch_irradiance, wgpu::BufferUsages::empty());
    let acc = checked(ctx, "accumulator", || DeviceAccumulator::new(device, entries));
    checked(ctx, "gather", || {
        let mut encoder = device.create_command_encoder(&Default::default());
        maps.encode_gather(ctx, &mut encoder, 0, &rec_buf, &image, &irradiance, kernel, bandwidth, pixels).unwrap();
        for _ in 0..iterations {
            acc.encode(device, &mut encoder, &image, None);
        }
        ctx.queue.submit([encoder.finish()]);
    });
    let [img, total, acc_pixels] =
        read(ctx, &[(&image, sizes.image), (maps.gathered_buffer(), size_of::<GatherCounts>() as u64), (&acc.pixels, sizes.accumulator)]).try_into().unwrap();
    let img: Vec<[f32; 4]> = bytemuck::pod_collect_to_vec(&img);
    let total: GatherCounts = bytemuck::pod_read_unaligned(&total);
    let acc_pixels: Vec<AccumPixel> = bytemuck::pod_collect_to_vec(&acc_pixels);
    HostRun {
        counts,
        footprints: maps.read_footprints(ctx, &batch).unwrap(),
        photons: maps.read_photons(ctx, &batch).unwrap(),
        image: img.iter().map(|p| [p[0], p[1], p[2]]).collect(),
        gathered: total.contributions().iter().sum(),
        mean: acc_pixels.iter().map(|p| p.mean(iterations)).collect(),
    }
}

/// Runs entry point `entry` of `source` (which starts with [`arpa_wgpu::shaders::scene`])
/// for `items` invocations with `scene`'s bind group as group 0 and, in group 1, `input`
/// (`@binding(0)`, read-only words) and a zeroed output of `output_words` words
/// (`@binding(1)`), which it returns.
#[allow(clippy::too_many_arguments)]
pub fn run_scene_kernel(ctx: &GpuContext, scene: &arpa_wgpu::scene::GpuScene, label: &str, source: &str, entry: &str, input: &[u32], items: u32, output_words: usize) -> Vec<u32> {
    let device = &ctx.device;
    let storage = |binding, read_only| wgpu::BindGroupLayoutEntry {
        binding,
        visibility: wgpu::ShaderStages::COMPUTE,
        ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Storage { read_only }, has_dynamic_offset: false, min_binding_size: None },
        count: None,
    };
    let (pipeline, io_layout) = checked(ctx, label, || {
        let io_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &[storage(0, true), storage(1, false)] });
        let layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some(label),
            bind_group_layouts: &[Some(scene.bind_group_layout()), Some(&io_layout)],
            immediate_size: 0,
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some(label), source: wgpu::ShaderSource::Wgsl(source.into()) });
        let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(label),
            layout: Some(&layout),
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        });
        (pipeline, io_layout)
    });
    let input_buf = upload(ctx, bytemuck::cast_slice(input), wgpu::BufferUsages::empty());
    let out = output(ctx, output_words as u64 * 4, wgpu::BufferUsages::empty());
    checked(ctx, label, || {
        let io = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some(label),
            layout: &io_layout,
            entries: &[wgpu::BindGroupEntry { binding: 0, resource: input_buf.as_entire_binding() }, wgpu::BindGroupEntry { binding: 1, resource: out.as_entire_binding() }],
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&pipeline);
            pass.set_bind_group(0, scene.bind_group(), &[]);
            pass.set_bind_group(1, &io, &[]);
            pass.dispatch_workgroups(items.div_ceil(64).max(1), 1, 1);
        }
        ctx.queue.submit([encoder.finish()]);
    });
    let [words] = read(ctx, &[(&out, output_words as u64 * 4)]).try_into().unwrap();
    bytemuck::pod_collect_to_vec(&words)
}

/// Runs one batch's store ([`PhotonMaps::encode_batch`]) on `raw` and `photons` as a photon
/// pass would leave them, with room for `sorted_photons` photon sort items, then the
/// accumulation of an image of ones guarded by the iteration's status word. Returns the
/// store's counts, the status word and the first accumulated sum (0 where the accumulation
/// was left out, 1 where it ran).
pub fn store_status(ctx: &GpuContext, raw: &[KeyedFootprint], photons: &[KeyedPhoton], settings: &StoreSettings, sorted_photons: u32) -> (StoreCounts, u32, f32) {
    let device = &ctx.device;
    let raw_buf = upload(ctx, bytemuck::cast_slice(raw), wgpu::BufferUsages::empty());
    let ph_buf = upload(ctx, bytemuck::cast_slice(photons), wgpu::BufferUsages::empty());
    let pass = PhotonCounters { footprint_appends: settings.raw_count, photon_appends: settings.photon_count, ..PhotonCounters::default() };
    let counters_buf = upload(ctx, bytemuck::bytes_of(&pass), wgpu::BufferUsages::COPY_SRC);
    let mut maps = PhotonMaps::new(ctx).unwrap();
    let capacities = arpa_core::gpu::batch::Capacities { raw_footprints: raw.len() as u32, photons: photons.len() as u32, sorted_photons };
    maps.bind_inputs(ctx, &raw_buf, &ph_buf, &counters_buf, capacities).unwrap();
    maps.begin_iteration(ctx, 1);
    let image = upload(ctx, bytemuck::cast_slice(&[[1.0f32; 4]; 4]), wgpu::BufferUsages::empty());
    let acc = checked(ctx, "accumulator", || DeviceAccumulator::new(device, 4));
    checked(ctx, "store and accumulate", || {
        let mut encoder = device.create_command_encoder(&Default::default());
        encoder.clear_buffer(maps.status(), 0, None);
        maps.encode_batch(ctx, &mut encoder, &StoreSettings { raw_count: 0, photon_count: 0, ..*settings }, &counters_buf, 0, true).unwrap();
        acc.encode(device, &mut encoder, &image, Some(maps.status()));
        ctx.queue.submit([encoder.finish()]);
    });
    let [batch, status, sums] = read(ctx, &[(maps.batch_counts(), BATCH_COUNTS_BYTES), (maps.status(), 16), (&acc.pixels, 32)]).try_into().unwrap();
    let batch: arpa_core::gpu::layout::BatchCounts = bytemuck::pod_read_unaligned(&batch);
    let status: [u32; 4] = bytemuck::pod_read_unaligned(&status);
    let sum: AccumPixel = bytemuck::pod_read_unaligned(&sums);
    (batch.store, status[0], sum.sum[0])
}
