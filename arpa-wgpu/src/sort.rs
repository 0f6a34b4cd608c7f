//! Device sort of `(hi, lo, value)` items (a bitonic sort in WGSL, shared memory for the
//! short compare distances), and the Morton code the footprint and photon keys use.
//!
//! The tracer sorts the stored footprints and progressive photons by
//! `(map << 30 | Morton code of the box centre, unique photon key, slot)`: the order is total,
//! so the sorted buffers do not depend on the order the photon pass appended them in
//! (atomics), and it is spatial, which the acceleration-structure build needs (lavapipe
//! builds its BVH without sorting the primitives: unsorted boxes traverse ~400× slower).
//!
//! A bitonic sort is written here rather than taken from a crate: the wgpu sort crates
//! found pin other wgpu versions than this workspace's `=30.0.1`.

use crate::device::GpuContext;
use crate::harness::{HarnessError, output_and_staging, submit_and_read};
use wgpu::util::DeviceExt;

/// WGSL of the sort (entry points `sort_local`, `sort_merge`, `sort_global`).
pub const SORT_WGSL: &str = include_str!("shaders/sort.wgsl");

/// WGSL of `morton_code(p, lo, inv_extent)` (30 bits, 10 per axis), for the key kernels.
pub const MORTON_WGSL: &str = include_str!("shaders/morton.wgsl");

/// Items per workgroup block of the shared-memory stages; sorted lengths are powers of two
/// of at least this.
pub const SORT_BLOCK: u32 = 512;

/// `hi` and `lo` of padding items (they sort after every valid item, whose `hi` < 2³¹).
pub const SORT_INVALID: u32 = u32::MAX;

/// Most items one sort takes (one dispatch of `n/512` workgroups per step).
pub const MAX_SORT_ITEMS: u32 = 1 << 25;

/// One item: sorted by `hi`, then `lo`, then `value` (ascending).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash, bytemuck::Pod, bytemuck::Zeroable)]
pub struct SortItem {
    /// Most significant key word.
    pub hi: u32,
    /// Least significant key word.
    pub lo: u32,
    /// Payload, last tie-breaker (a slot index).
    pub value: u32,
}

impl SortItem {
    /// A padding item (sorts last).
    pub const INVALID: Self = Self { hi: SORT_INVALID, lo: SORT_INVALID, value: SORT_INVALID };
}

/// The length a sort of `n` items runs on: the next power of two, at least [`SORT_BLOCK`].
pub fn sorted_len(n: u32) -> u32 {
    n.max(SORT_BLOCK).next_power_of_two()
}

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Step {
    k: u32,
    j: u32,
    pad: [u32; 62], // 256-byte stride (dynamic uniform offsets)
}

/// 30-bit Morton code of `p` in the box `lo + [0, 1/inv_extent]` (the host twin of
/// `morton_code` in `morton.wgsl`; the scene upload orders triangles by it, tests check the
/// device against it).
pub fn morton_code(p: [f32; 3], lo: [f32; 3], inv_extent: [f32; 3]) -> u32 {
    let spread = |v: u32| {
        let mut x = v & 0x3ff;
        x = (x | (x << 16)) & 0x0300_00ff;
        x = (x | (x << 8)) & 0x0300_f00f;
        x = (x | (x << 4)) & 0x030c_30c3;
        (x | (x << 2)) & 0x0924_9249
    };
    let cell = |i: usize| {
        let c = (p[i] - lo[i]) * inv_extent[i] * 1024.0;
        // NaN compares as neither: cell 0, as the WGSL `!(c > 0.0)`.
        match c.partial_cmp(&0.0) {
            Some(core::cmp::Ordering::Greater) if c < 1023.0 => c as u32,
            Some(core::cmp::Ordering::Greater) => 1023,
            _ => 0,
        }
    };
    spread(cell(0)) | (spread(cell(1)) << 1) | (spread(cell(2)) << 2)
}

/// The sort's pipelines (built once per device).
pub struct Sorter {
    layout: wgpu::BindGroupLayout,
    local: wgpu::ComputePipeline,
    merge: wgpu::ComputePipeline,
    global: wgpu::ComputePipeline,
}

impl Sorter {
    /// Compiles the sort's pipelines on `device`.
    pub fn new(device: &wgpu::Device) -> Self {
        let label = Some("arpa sort");
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label,
            entries: &[
                crate::harness::storage_entry(0, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: true, min_binding_size: wgpu::BufferSize::new(16) },
                    count: None,
                },
            ],
        });
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(SORT_WGSL.into()) });
        let pipeline = |entry: &str| crate::harness::pipeline(device, "arpa sort", &module, &[Some(&layout)], entry);
        Self { local: pipeline("sort_local"), merge: pipeline("sort_merge"), global: pipeline("sort_global"), layout }
    }

    /// Records the sort of the first `n` items of `items` (`n` = [`sorted_len`] of
    /// something: a power of two ≥ [`SORT_BLOCK`], at most [`MAX_SORT_ITEMS`]).
    pub fn encode(&self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, items: &wgpu::Buffer, n: u32) {
        debug_assert!(n.is_power_of_two() && (SORT_BLOCK..=MAX_SORT_ITEMS).contains(&n));
        // Steps after the first (block-local) dispatch: for each merge size k > SORT_BLOCK,
        // the global steps j >= SORT_BLOCK, then the shared-memory tail.
        let mut steps = vec![Step { k: 0, j: 0, pad: [0; 62] }];
        let mut k = 2 * SORT_BLOCK;
        while k <= n {
            let mut j = k / 2;
            while j >= SORT_BLOCK {
                steps.push(Step { k, j, pad: [0; 62] });
                j /= 2;
            }
            steps.push(Step { k, j: 0, pad: [0; 62] });
            k *= 2;
        }
        let step_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("arpa sort steps"),
            contents: bytemuck::cast_slice(&steps),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("arpa sort"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: items, offset: 0, size: wgpu::BufferSize::new(n as u64 * 12) }),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: &step_buf, offset: 0, size: wgpu::BufferSize::new(16) }),
                },
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa sort"), timestamp_writes: None });
        let blocks = n / SORT_BLOCK;
        for (i, s) in steps.iter().enumerate() {
            let offset = (i * std::mem::size_of::<Step>()) as u32;
            pass.set_bind_group(0, &bind, &[offset]);
            match (i, s.j) {
                (0, _) => pass.set_pipeline(&self.local),
                (_, 0) => pass.set_pipeline(&self.merge),
                _ => pass.set_pipeline(&self.global),
            }
            pass.dispatch_workgroups(blocks, 1, 1);
        }
    }
}

/// Sorts `items` on the device (padded to [`sorted_len`] with [`SortItem::INVALID`]) and
/// returns them sorted (the padding removed): the host entry point the tests use.
pub fn sort_items(ctx: &GpuContext, items: &[SortItem]) -> Result<Vec<SortItem>, HarnessError> {
    let label = "arpa sort";
    let n_items = u32::try_from(items.len()).ok().filter(|&n| sorted_len(n) <= MAX_SORT_ITEMS);
    let Some(n_items) = n_items else {
        return Err(HarnessError::Size { label: label.into(), message: format!("{} items; at most {MAX_SORT_ITEMS}", items.len()) });
    };
    let n = sorted_len(n_items);
    let mut padded = items.to_vec();
    padded.resize(n as usize, SortItem::INVALID);
    let device = &ctx.device;
    let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
    let sorter = Sorter::new(device);
    let bytes = n as u64 * 12;
    let (_, staging) = output_and_staging(device, label, bytes);
    let buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents: bytemuck::cast_slice(&padded),
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some(label) });
    sorter.encode(device, &mut encoder, &buffer, n);
    encoder.copy_buffer_to_buffer(&buffer, 0, &staging, 0, bytes);
    let [out] = submit_and_read(ctx, scope, encoder, label, [&staging])?;
    let mut sorted: Vec<SortItem> = bytemuck::pod_collect_to_vec(&out);
    sorted.truncate(items.len());
    Ok(sorted)
}
