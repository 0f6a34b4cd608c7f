//! The device sort of the store's items ([`arpa_core::gpu::sort`], the core's `sort.wgsl`):
//! a bitonic sort, shared memory for the short compare distances.
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

use arpa_core::gpu::sort::{SortItem, SortStep};
use arpa_core::gpu::sort::{MAX_SORT_ITEMS, SORT_BLOCK, sort_steps};
use wgpu::util::DeviceExt;

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
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor { label, source: wgpu::ShaderSource::Wgsl(crate::shaders::sort().into()) });
        let pipeline = |entry: &str| crate::harness::pipeline(device, "arpa sort", &module, &[Some(&layout)], entry);
        Self { local: pipeline("sort_local"), merge: pipeline("sort_merge"), global: pipeline("sort_global"), layout }
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
