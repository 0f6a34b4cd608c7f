//! The device sorts of the store's items ([`arpa_core::gpu::sort`]): the LSD radix sort
//! (the core's `radix.wgsl`, [`Sorter::encode_radix`]), which the store runs, and the bitonic
//! sort (`sort.wgsl`, [`Sorter::encode`]), shared memory for the short compare distances;
//! both give the same order.
//!
//! The tracer sorts the stored footprints and progressive photons by
//! `(map << 30 | Morton code of the box centre, unique photon key, slot)`: the order is total,
//! so the sorted buffers do not depend on the order the photon pass appended them in
//! (atomics), and it is spatial, which the acceleration-structure build needs (lavapipe's
//! builder does not sort the primitives, so unsorted boxes give a BVH that is far slower to
//! traverse).
//!
//! The sort is written here rather than taken from a crate: the wgpu sort crates pin other
//! wgpu versions than this workspace's.

use arpa_core::gpu::sort::{RadixPass, SortItem, SortStep};
use arpa_core::gpu::sort::{MAX_SORT_ITEMS, SORT_BLOCK, radix_count_len, radix_passes, sort_steps};
use wgpu::util::DeviceExt;

const ITEM_BYTES: u64 = size_of::<SortItem>() as u64;

/// The sorts' pipelines (built once per device).
pub struct Sorter {
    layout: wgpu::BindGroupLayout,
    local: wgpu::ComputePipeline,
    merge: wgpu::ComputePipeline,
    global: wgpu::ComputePipeline,
    radix_layout: wgpu::BindGroupLayout,
    radix_count: wgpu::ComputePipeline,
    radix_scan: wgpu::ComputePipeline,
    radix_scatter: wgpu::ComputePipeline,
}

/// The radix sort's scratch buffers for up to `capacity` items: the second item buffer and
/// the per-tile digit counters.
pub struct RadixScratch {
    items: wgpu::Buffer,
    counts: wgpu::Buffer,
    capacity: u32,
}

impl RadixScratch {
    /// Scratch for sorts of at most `capacity` items (`capacity` × 12 bytes plus 1 KiB per
    /// [`arpa_core::gpu::sort::RADIX_TILE`] items).
    pub fn new(device: &wgpu::Device, capacity: u32) -> Self {
        let buffer = |label, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: size.max(16),
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            })
        };
        Self { items: buffer("arpa radix items", capacity as u64 * ITEM_BYTES), counts: buffer("arpa radix counts", radix_count_len(capacity) as u64 * 4), capacity }
    }

    /// Items the scratch holds.
    pub fn capacity(&self) -> u32 {
        self.capacity
    }
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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(crate::shaders::sort().into()) });
        let pipeline = |entry: &str| crate::harness::pipeline(device, "arpa sort", &module, &[Some(&layout)], entry);
        let radix_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("arpa radix sort"),
            entries: &[
                crate::harness::storage_entry(0, true),
                crate::harness::storage_entry(1, false),
                crate::harness::storage_entry(2, false),
                wgpu::BindGroupLayoutEntry {
                    binding: 3,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer { ty: wgpu::BufferBindingType::Uniform, has_dynamic_offset: true, min_binding_size: wgpu::BufferSize::new(16) },
                    count: None,
                },
            ],
        });
        let radix = device.create_shader_module(wgpu::ShaderModuleDescriptor { label: Some("arpa radix sort"), source: wgpu::ShaderSource::Wgsl(crate::shaders::radix().into()) });
        let radix_pipeline = |entry: &str| crate::harness::pipeline(device, "arpa radix sort", &radix, &[Some(&radix_layout)], entry);
        Self {
            local: pipeline("sort_local"),
            merge: pipeline("sort_merge"),
            global: pipeline("sort_global"),
            layout,
            radix_count: radix_pipeline("radix_count"),
            radix_scan: radix_pipeline("radix_scan"),
            radix_scatter: radix_pipeline("radix_scatter"),
            radix_layout,
        }
    }

    /// Records the radix sort of the first `n` items of `items` ([`SortItem`]s, `STORAGE`
    /// and `COPY_DST`; `n` ≤ `scratch`'s capacity) whose `value`s are all below
    /// `value_bound` (`u32::MAX` when unknown): the passes of [`radix_passes`], alternating
    /// between `items` and the scratch, and a copy back after an odd number of passes. Items
    /// past `n` are left as they are.
    pub fn encode_radix(&self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, items: &wgpu::Buffer, scratch: &RadixScratch, n: u32, value_bound: u32) {
        assert!(n <= scratch.capacity, "{n} items for a radix scratch of {}", scratch.capacity);
        let passes = radix_passes(n, value_bound);
        if passes.is_empty() {
            return;
        }
        let pass_buf = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("arpa radix passes"),
            contents: bytemuck::cast_slice(&passes),
            usage: wgpu::BufferUsages::UNIFORM,
        });
        let bytes = wgpu::BufferSize::new(n as u64 * ITEM_BYTES);
        let bind = |src: &wgpu::Buffer, dst: &wgpu::Buffer| {
            let storage = |binding, buffer, size| wgpu::BindGroupEntry { binding, resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer, offset: 0, size }) };
            device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("arpa radix sort"),
                layout: &self.radix_layout,
                entries: &[
                    storage(0, src, bytes),
                    storage(1, dst, bytes),
                    storage(2, &scratch.counts, wgpu::BufferSize::new(radix_count_len(n) as u64 * 4)),
                    storage(3, &pass_buf, wgpu::BufferSize::new(16)),
                ],
            })
        };
        let binds = [bind(items, &scratch.items), bind(&scratch.items, items)];
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("arpa radix sort"), timestamp_writes: None });
            for (i, p) in passes.iter().enumerate() {
                pass.set_bind_group(0, &binds[i % 2], &[(i * size_of::<RadixPass>()) as u32]);
                pass.set_pipeline(&self.radix_count);
                pass.dispatch_workgroups(p.tiles, 1, 1);
                pass.set_pipeline(&self.radix_scan);
                pass.dispatch_workgroups(1, 1, 1);
                pass.set_pipeline(&self.radix_scatter);
                pass.dispatch_workgroups(p.tiles, 1, 1);
            }
        }
        if !passes.len().is_multiple_of(2) {
            encoder.copy_buffer_to_buffer(&scratch.items, 0, items, 0, n as u64 * ITEM_BYTES);
        }
    }

    /// Records the sort of the first `n` items of `items` ([`SortItem`]s; `n` =
    /// [`arpa_core::gpu::sort::sorted_len`] of something: a power of two ≥ [`SORT_BLOCK`],
    /// at most [`MAX_SORT_ITEMS`]).
    pub fn encode(&self, device: &wgpu::Device, encoder: &mut wgpu::CommandEncoder, items: &wgpu::Buffer, n: u32) {
        debug_assert!(n.is_power_of_two() && (SORT_BLOCK..=MAX_SORT_ITEMS).contains(&n));
        let steps = sort_steps(n);
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
                    resource: wgpu::BindingResource::Buffer(wgpu::BufferBinding { buffer: items, offset: 0, size: wgpu::BufferSize::new(n as u64 * size_of::<SortItem>() as u64) }),
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
            let offset = (i * size_of::<SortStep>()) as u32;
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
