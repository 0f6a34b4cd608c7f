//! The device sorts of the store's items on wgpu: the radix sort the store runs
//! ([`Sorter::encode_radix`]) against the bitonic sort ([`Sorter::encode`], on the
//! power-of-two length the store padded to), on the adapter `GpuContext` picks (lavapipe
//! where there is no GPU).
//!
//! ```text
//! cargo bench -p arpa-wgpu --bench sort
//! ```
//!
//! Keys as the store makes them, in a shuffled order ([`store_like_items`]). For 1 000 000 and 4 000 000
//! items (`ARPA_SORT_SIZES=...` picks others) each sort runs once to warm up (pipeline
//! compilation on lavapipe), then `ARPA_SORT_RUNS` (default 3) timed runs of one submission
//! each, waited for (wall clock; a fresh upload before each, not timed); prints
//! `wgpu.sort.N.METHOD: best ms (mean ms)` lines and checks both sorts against the host's.
//! Without `--bench` (`cargo test --benches`) it sorts 5 000 items once per method.

use std::time::Instant;

use arpa_core::gpu::sort::{SortItem, sorted_len, store_like_items};
use arpa_wgpu::sort::{RadixScratch, Sorter};
use arpa_wgpu::{AdapterChoice, GpuContext};

fn read(ctx: &GpuContext, buffer: &wgpu::Buffer, n: u32) -> Vec<SortItem> {
    let bytes = (n.max(1) as u64) * 12;
    let staging = ctx.device.create_buffer(&wgpu::BufferDescriptor { label: None, size: bytes, usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST, mapped_at_creation: false });
    let mut encoder = ctx.device.create_command_encoder(&Default::default());
    encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, bytes);
    ctx.queue.submit([encoder.finish()]);
    staging.map_async(wgpu::MapMode::Read, .., |r| r.expect("map"));
    ctx.device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
    let out: Vec<SortItem> = bytemuck::pod_collect_to_vec(&staging.get_mapped_range(..).expect("mapped range"));
    out[..n as usize].to_vec()
}

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let sizes: Vec<u32> = match std::env::var("ARPA_SORT_SIZES") {
        Ok(v) => v.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
        Err(_) if full => vec![1_000_000, 4_000_000],
        Err(_) => vec![5_000],
    };
    let runs: usize = std::env::var("ARPA_SORT_RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(if full { 3 } else { 1 });
    let ctx = match GpuContext::new(&AdapterChoice::Auto) {
        Ok(ctx) => ctx,
        Err(e) if std::env::var_os("CI").is_none() => {
            println!("wgpu.sort: skipped, no adapter: {e}");
            return;
        }
        Err(e) => panic!("CI needs a wgpu adapter: {e}"),
    };
    println!("wgpu.sort.adapter: {}", ctx.info.name);
    let sorter = Sorter::new(&ctx.device);
    for &n in &sizes {
        let items = store_like_items(n, 35);
        let mut want = items.clone();
        want.sort();
        let padded_len = sorted_len(n);
        let mut padded = items.clone();
        padded.resize(padded_len as usize, SortItem::INVALID);
        let buffer = ctx.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("bench items"),
            size: padded_len as u64 * 12,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let scratch = RadixScratch::new(&ctx.device, n);
        for method in ["radix", "bitonic"] {
            let mut times = Vec::new();
            for run in 0..=runs {
                ctx.queue.write_buffer(&buffer, 0, bytemuck::cast_slice(&padded));
                ctx.device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
                let t0 = Instant::now();
                let mut encoder = ctx.device.create_command_encoder(&Default::default());
                match method {
                    "radix" => sorter.encode_radix(&ctx.device, &mut encoder, &buffer, &scratch, n, n),
                    _ => sorter.encode(&ctx.device, &mut encoder, &buffer, padded_len),
                }
                ctx.queue.submit([encoder.finish()]);
                ctx.device.poll(wgpu::PollType::wait_indefinitely()).expect("poll");
                if run > 0 {
                    times.push(t0.elapsed().as_secs_f64() * 1e3);
                }
            }
            assert!(read(&ctx, &buffer, n) == want, "{method} sort of {n} items differs from the host's");
            let best = times.iter().copied().fold(f64::INFINITY, f64::min);
            let mean = times.iter().sum::<f64>() / times.len() as f64;
            println!("wgpu.sort.{n}.{method}: {best:.1} ms ({mean:.1} ms mean of {runs})");
        }
    }
}
