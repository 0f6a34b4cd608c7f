//! The device sorts of the store's items on vk: the radix sort the store runs against the
//! bitonic sort (on the power-of-two length the store padded to), both through
//! [`StorePipelines::sort_items`], on the adapter `VkContext` picks (lavapipe where there is
//! no GPU).
//!
//! ```text
//! cargo bench -p arpa-vk --bench sort
//! ```
//!
//! Keys as the store makes them, in a shuffled order ([`store_like_items`]). For 1 000 000 and 4 000 000
//! items (`ARPA_SORT_SIZES=...` picks others) each sort runs once to warm up, then
//! `ARPA_SORT_RUNS` (default 3) timed runs of one submission each, waited for (wall clock; a
//! fresh upload before each, not timed); prints `vk.sort.N.METHOD: best ms (mean ms)` lines
//! and checks both sorts against the host's. Without `--bench` (`cargo test --benches`) it
//! sorts 5 000 items once per method.

use std::time::Instant;

use arpa_core::gpu::sort::{SortItem, sorted_len, store_like_items};
use arpa_vk::maps::{RadixScratch, StorePipelines};
use arpa_vk::{AdapterChoice, ContextOptions, VkContext, vk};

fn main() {
    let full = std::env::args().any(|a| a == "--bench");
    let sizes: Vec<u32> = match std::env::var("ARPA_SORT_SIZES") {
        Ok(v) => v.split(',').filter_map(|x| x.trim().parse().ok()).collect(),
        Err(_) if full => vec![1_000_000, 4_000_000],
        Err(_) => vec![5_000],
    };
    let runs: usize = std::env::var("ARPA_SORT_RUNS").ok().and_then(|v| v.parse().ok()).unwrap_or(if full { 3 } else { 1 });
    let ctx = match VkContext::new(&AdapterChoice::Auto, &ContextOptions { validation: false }) {
        Ok(ctx) => ctx,
        Err(e) if std::env::var_os("CI").is_none() => {
            println!("vk.sort: skipped, no Vulkan: {e}");
            return;
        }
        Err(e) => panic!("CI needs Vulkan: {e}"),
    };
    println!("vk.sort.adapter: {}", ctx.info().name);
    let pipelines = StorePipelines::new(&ctx).expect("sort pipelines");
    for &n in &sizes {
        let items = store_like_items(n, 35);
        let mut want = items.clone();
        want.sort();
        let padded_len = sorted_len(n);
        let mut padded = items.clone();
        padded.resize(padded_len as usize, SortItem::INVALID);
        let scratch = RadixScratch::new(&ctx, n).expect("scratch");
        for method in ["radix", "bitonic"] {
            let mut times = Vec::new();
            let mut buffer = None;
            for run in 0..=runs {
                let b = ctx.upload("bench items", bytemuck::cast_slice(&padded), vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC).expect("upload");
                let t0 = Instant::now();
                match method {
                    "radix" => pipelines.sort_items(&ctx, &b, n, n, Some(&scratch)),
                    _ => pipelines.sort_items(&ctx, &b, padded_len, u32::MAX, None),
                }
                .expect("sort");
                if run > 0 {
                    times.push(t0.elapsed().as_secs_f64() * 1e3);
                }
                buffer = Some(b);
            }
            let got: Vec<SortItem> = ctx.read_back(buffer.as_ref().expect("a run"), 0, u64::from(n) * 12).expect("read back").chunks_exact(12).map(bytemuck::pod_read_unaligned).collect();
            assert!(got == want, "{method} sort of {n} items differs from the host's");
            let best = times.iter().copied().fold(f64::INFINITY, f64::min);
            let mean = times.iter().sum::<f64>() / times.len() as f64;
            println!("vk.sort.{n}.{method}: {best:.1} ms ({mean:.1} ms mean of {runs})");
        }
    }
}
