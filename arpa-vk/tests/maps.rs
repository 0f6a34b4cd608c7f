//! The compute half of the Vulkan backend on a real driver (lavapipe in CI) under the Khronos
//! validation layer (any error or warning fails, also while destroying):
//! * `run_kernel` under the kernel contract: a tiny kernel, and the core's WGSL rng
//!   (`rng.wgsl`) against `arpa_core::base::rng::Rng` bit for bit;
//! * the keyed store, sort and compaction (`MapStore`) on a few thousand synthetic keyed
//!   footprints and photons against a CPU reference: each raw footprint's outcome is the
//!   core's `ResolvedHeuristics::store` (except within 1e-3 of a threshold, as in arpa-wgpu's
//!   `store` test); the sorted photons (the pass's and the fallbacks) are exactly the host's
//!   sort of the same items by `(map << 30 | Morton code, key, slot)`, bit for bit; the
//!   footprints are in that order of their own boxes' centres; the counters add up; and a
//!   shuffled input (another append order) gives bit-identical outputs;
//! * the maps' acceleration structure built on the device from the sorted boxes
//!   (`MapAccel`): one short ray per query through the GLSL gather hit group counts exactly
//!   the records `arpa_core::gather::estimate` finds by brute force over the device's records (except
//!   on a boundary within rounding); an empty iteration's top level traces with no hits;
//! * the running mean (`DeviceAccumulator`) of three known images, one sample non-finite.
//!
//! Without a Vulkan loader, driver or validation layer the tests skip with a loud message,
//! except in CI (env `CI` set), where they fail.

use arpa_core::base::aabb::Aabb;
use arpa_core::gather::estimate::{QueryPoint, gather_brute_force};
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::gpu::codes::kernel_code;
use arpa_core::gpu::batch::Capacities;
use arpa_core::gpu::layout::{KeyedFootprint, KeyedPhoton, RawFootprint, StoreCounts, StoreSettings};
use arpa_core::base::morton::{inverse_extent, morton_code};
use arpa_core::store::heuristics::{HeuristicContext, Heuristics};
use arpa_core::gather::kernel::Kernel;
use arpa_core::store::progressive_photon::PackedPhoton;
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::gpu::sort::SortItem;
use arpa_vk::maps::StorePipelines;
use arpa_vk::vk;
use std::sync::Arc;
use arpa_vk::{
    Buffer, DeviceAccumulator, MapAccel, MapStore, MemoryLocation, Resource,
    RtPipeline, VkContext, run_kernel,
};
use glam::{DVec3, Vec3};

const RADII: [f32; 2] = [0.02, 0.05];

mod support;
use support::{assert_clean, context, gather_test_pipeline};

/// Drops `ctx` and checks the log stayed clean through its destruction.
fn finish(ctx: VkContext) {
    let log = ctx.validation_log();
    assert_clean(&log, "during the test");
    drop(ctx);
    assert_clean(&log, "while destroying");
}

// ---------------------------------------------------------------------------------------
// run_kernel

const KERNEL_IO: &str = "
@group(0) @binding(0) var<storage, read> input: array<u32>;
@group(0) @binding(1) var<storage, read_write> output: array<u32>;
";

#[test]
fn run_kernel_follows_the_contract() {
    let Some(ctx) = context("maps") else { return };
    let source = format!(
        "{KERNEL_IO}
const N: u32 = 1000u;
@compute @workgroup_size(64)
fn triple(@builtin(global_invocation_id) gid: vec3<u32>) {{
    let i = gid.x;
    if i >= N {{ return; }}
    output[i] = input[i] * 3u + i;
}}
@compute @workgroup_size(64)
fn count_input(@builtin(global_invocation_id) gid: vec3<u32>) {{
    if gid.x >= 70u {{ return; }}
    output[gid.x] = arrayLength(&input) + 100u * gid.x;
}}"
    );
    let input: Vec<u32> = (0..1000u32).map(|i| i.wrapping_mul(2_654_435_761)).collect();
    // 1100 output words: the last 100 stay zero (zero-initialised).
    let out = run_kernel(&ctx, "triple", &source, "triple", &input, 1000, 1100).expect("run_kernel");
    for i in 0..1100usize {
        let want = if i < 1000 { input[i].wrapping_mul(3).wrapping_add(i as u32) } else { 0 };
        assert_eq!(out[i], want, "word {i}");
    }
    // An empty input binds one word; 70 invocations are two workgroups.
    let out = run_kernel(&ctx, "count", &source, "count_input", &[], 70, 80).expect("run_kernel, empty input");
    assert_eq!(out[..70], (0..70u32).map(|i| 1 + 100 * i).collect::<Vec<_>>()[..]);
    assert!(out[70..].iter().all(|&w| w == 0));
    // Errors, not panics.
    assert!(matches!(run_kernel(&ctx, "x", &source, "no_such_entry", &input, 1, 1), Err(arpa_vk::VkError::InvalidInput { .. })));
    assert!(matches!(run_kernel(&ctx, "x", &source, "triple", &input, 1, 0), Err(arpa_vk::VkError::InvalidInput { .. })));
    assert!(matches!(run_kernel(&ctx, "x", "fn broken(", "triple", &input, 1, 1), Err(arpa_vk::VkError::Shader { .. })));
    finish(ctx);
}

#[test]
fn run_kernel_runs_the_core_rng_twin() {
    let Some(ctx) = context("maps") else { return };
    let source = arpa_core::gpu::shaders::compose(&[&arpa_core::gpu::shaders::RNG])
        + KERNEL_IO
        + "
// Stream i: (seed, iteration, index, domain) = input[4i..4i+4]; writes 3 next_u32 and one
// next_f32 (bits).
@compute @workgroup_size(64)
fn rng_twin(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if 4u * i + 3u >= arrayLength(&input) { return; }
    var rng = arpa_rng_new(input[4u * i], input[4u * i + 1u], input[4u * i + 2u], input[4u * i + 3u]);
    output[4u * i] = arpa_rng_next_u32(&rng);
    output[4u * i + 1u] = arpa_rng_next_u32(&rng);
    output[4u * i + 2u] = arpa_rng_next_u32(&rng);
    output[4u * i + 3u] = bitcast<u32>(arpa_rng_next_f32(&rng));
}";
    let domains = [StreamDomain::Photon, StreamDomain::Camera, StreamDomain::Iteration, StreamDomain::User];
    let streams: Vec<[u32; 4]> =
        (0..300u32).map(|i| [i.wrapping_mul(0x9e37_79b9), i % 7, i * 13 + (i >> 3) * 100_000, i % 4]).collect();
    let input: Vec<u32> = streams.iter().flatten().copied().collect();
    let out = run_kernel(&ctx, "rng twin", &source, "rng_twin", &input, streams.len() as u32, 4 * streams.len()).expect("rng kernel");
    for (i, s) in streams.iter().enumerate() {
        let mut rng = Rng::new(s[0], s[1], s[2], domains[s[3] as usize]);
        let want = [rng.next_u32(), rng.next_u32(), rng.next_u32(), rng.next_f32().to_bits()];
        assert_eq!(out[4 * i..4 * i + 4], want, "stream {i} {s:?}");
    }
    finish(ctx);
}

// ---------------------------------------------------------------------------------------
// Store, sort and compaction

fn scene_bounds() -> Aabb {
    Aabb { min: DVec3::new(-1.0, -1.0, -0.2), max: DVec3::new(1.0, 1.0, 0.5) }
}

/// Raw footprints on two planes (z = 0 facing up, z = 0.3 facing down), both maps, with
/// angles down to near-parallel (degenerate) and lengths up to culled sizes (arpa-wgpu's
/// `store` test's generator).
fn raw_footprints(seed: u32, n: usize) -> Vec<RawFootprint> {
    let mut rng = Rng::new(seed, 2, 0, StreamDomain::User);
    (0..n)
        .map(|_| {
            let k = rng.next_u32() % 2;
            let (z, nz) = if k == 0 { (0.0, 1.0) } else { (0.3, -1.0) };
            let a = rng.next_f64() * std::f64::consts::TAU;
            let b = a + 0.02 + 3.0 * rng.next_f64();
            let (la, lb) = (0.005 + 0.3 * rng.next_f64(), 0.005 + 0.3 * rng.next_f64());
            let f = |v: f64| v as f32;
            RawFootprint {
                center: [f(rng.next_f64() - 0.5), f(rng.next_f64() - 0.5), z],
                map: rng.next_u32() % 2,
                normal: [0.0, 0.0, nz],
                du: [f(a.cos() * la), f(a.sin() * la), 0.0],
                dv: [f(b.cos() * lb), f(b.sin() * lb), 0.0],
                flux: [f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3)],
                ..Default::default()
            }
        })
        .collect()
}

fn core_footprint(r: &RawFootprint) -> Footprint {
    let d = |v: [f32; 3]| Vec3::from_array(v).as_dvec3();
    Footprint { center: d(r.center), normal: d(r.normal), du: d(r.du), dv: d(r.dv), flux: d(r.flux), map: PhotonMap::from_index(r.map) }
}

/// Within 1e-3 relative of the degenerate or culling threshold (arpa-wgpu's `store` test).
fn near_threshold(h: &Heuristics, fp: &Footprint, radius: f64) -> bool {
    let ctx = HeuristicContext { radius, scene_bounds: scene_bounds() };
    let fp = h.clamp_h_max(h.dampen(*fp, &ctx), &ctx);
    let near = |x: f64, t: f64| (x / t - 1.0).abs() < 1e-3;
    let (major, minor) = fp.axis_lengths();
    let deg = h.degenerate.is_some_and(|d| near(minor, d.fraction * major));
    let cull = h.culling.is_some_and(|c| near(fp.aabb(radius).largest_extent(), c.fraction * scene_bounds().largest_extent()));
    deg || cull
}

struct Input {
    raw: Vec<KeyedFootprint>,
    photons: Vec<KeyedPhoton>,
}

/// 3000 raw footprints (keys odd) and 1500 photons (keys even) on the two planes.
fn input(seed: u32) -> Input {
    let raw = raw_footprints(seed, 3000)
        .into_iter()
        .enumerate()
        .map(|(i, footprint)| KeyedFootprint { footprint, key: 2 * i as u32 + 1, pad: [0; 3] })
        .collect();
    let mut rng = Rng::new(seed, 7, 0, StreamDomain::User);
    let photons = (0..1500u32)
        .map(|i| {
            let k = rng.next_u32() % 2;
            let (z, nz) = if k == 0 { (0.0, 1.0) } else { (0.3, -1.0) };
            let f = |v: f64| v as f32;
            let photon = PackedPhoton {
                position: [f(rng.next_f64() - 0.5), f(rng.next_f64() - 0.5), z],
                map: rng.next_u32() % 2,
                normal: [0.0, 0.0, nz],
                flux: [f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3), f(rng.next_f64() * 1e-3)],
                ..Default::default()
            };
            KeyedPhoton { photon, key: 2 * i, pad: [0; 3] }
        })
        .collect();
    Input { raw, photons }
}

fn settings(input: &Input) -> StoreSettings {
    let b = scene_bounds();
    StoreSettings {
        heuristics: Heuristics::default().resolve(&b).pack(),
        radii: RADII,
        bounds: (b.min.as_vec3().to_array(), b.max.as_vec3().to_array()),
        raw_count: input.raw.len() as u32,
        photon_count: input.photons.len() as u32,
    }
}

/// The sort key of an item: `(map << 30 | Morton code of p, key)` (keys are unique, so the
/// slot never decides).
fn sort_key(s: &StoreSettings, map: u32, p: [f32; 3], key: u32) -> (u32, u32) {
    let (lo, hi) = s.bounds;
    ((map.min(1) << 30) | morton_code(p, lo, inverse_extent(lo, hi)), key)
}

/// What one run of the store, sort and compaction produced.
#[derive(PartialEq)]
struct Sorted {
    counts: StoreCounts,
    footprints: Vec<PackedFootprint>,
    footprint_boxes: Vec<[f32; 6]>,
    photons: Vec<PackedPhoton>,
    photon_boxes: Vec<[f32; 6]>,
}

fn storage_upload(ctx: &VkContext, label: &str, bytes: &[u8]) -> Buffer {
    ctx.upload(label, bytes, vk::BufferUsageFlags::STORAGE_BUFFER).expect(label)
}

/// Uploads the input, stores, sorts and compacts it, and reads everything back.
fn store_and_sort(ctx: &VkContext, store: &MapStore, input: &Input) -> Sorted {
    let raw = storage_upload(ctx, "raw footprints", bytemuck::cast_slice(&input.raw));
    let photons = storage_upload(ctx, "photons", bytemuck::cast_slice(&input.photons));
    let s = settings(input);
    let counts = store.store(ctx, &raw, &photons, &s).expect("store");
    let after = store.sort(ctx, &raw, &photons, &s).expect("sort");
    assert_eq!(after.overflowed, 0);
    assert_eq!(StoreCounts { overflowed: 0, ..after }, counts, "the sort half changes no counter but the overflow");
    Sorted {
        counts,
        footprints: store.read_footprints(ctx, &counts).expect("read footprints"),
        footprint_boxes: store.read_footprint_boxes(ctx, &counts).expect("read footprint boxes"),
        photons: store.read_photons(ctx, &counts).expect("read photons"),
        photon_boxes: store.read_photon_boxes(ctx, &counts).expect("read photon boxes"),
    }
}

/// A deterministic permutation of `v` (Fisher–Yates with the core's rng).
fn shuffled<T: Clone>(v: &[T], seed: u32) -> Vec<T> {
    let mut out = v.to_vec();
    let mut rng = Rng::new(seed, 9, 0, StreamDomain::User);
    for i in (1..out.len()).rev() {
        let j = (rng.next_u32() as usize) % (i + 1);
        out.swap(i, j);
    }
    out
}

/// Checks `out` against the CPU reference of `input` (see the module docs).
fn check_against_reference(input: &Input, out: &Sorted) {
    let s = settings(input);
    let c = out.counts;
    assert_eq!(c.total_footprints() as usize, out.footprints.len());
    assert_eq!(c.total_photons() as usize, out.photons.len());
    assert_eq!(c.total_footprints() + c.total_photons(), (input.raw.len() + input.photons.len()) as u32, "every record stored once");
    assert_eq!((c.footprint_items, c.photon_items), (c.total_footprints(), c.total_photons()));
    assert_eq!(c.degenerate + c.culled + c.unrepresentable, input.raw.len() as u32 - c.total_footprints(), "fallbacks by reason");
    for m in 0..2u32 {
        assert_eq!(out.footprints.iter().filter(|f| f.map == m).count(), c.footprints[m as usize] as usize);
        assert_eq!(out.photons.iter().filter(|p| p.map == m).count(), c.photons[m as usize] as usize);
    }

    // Which raw footprints the device stored (by centre: the record keeps the raw centre).
    let by_centre: std::collections::HashMap<[u32; 3], usize> =
        input.raw.iter().enumerate().map(|(i, r)| (r.footprint.center.map(f32::to_bits), i)).collect();
    assert_eq!(by_centre.len(), input.raw.len(), "distinct centres");
    let mut stored = vec![false; input.raw.len()];
    let mut fp_keys = Vec::with_capacity(out.footprints.len());
    for (f, b) in out.footprints.iter().zip(&out.footprint_boxes) {
        let i = *by_centre.get(&f.center.map(f32::to_bits)).unwrap_or_else(|| panic!("footprint {f:?} is no raw footprint"));
        assert!(!std::mem::replace(&mut stored[i], true), "raw footprint {i} stored twice");
        let r = &input.raw[i];
        assert_eq!(f.map, r.footprint.map);
        assert!((0..3).all(|a| b[a] <= f.center[a] && f.center[a] <= b[a + 3]), "box {b:?} of footprint {f:?}");
        let centre = [0.5 * (b[0] + b[3]), 0.5 * (b[1] + b[4]), 0.5 * (b[2] + b[5])];
        fp_keys.push((sort_key(&s, f.map, centre, r.key), i));
    }
    assert!(fp_keys.windows(2).all(|w| w[0] < w[1]), "footprints not in (map, Morton code of the box centre, key) order");

    // Outcomes against the core.
    let heuristics = Heuristics::default();
    let resolved = heuristics.resolve(&scene_bounds());
    let (mut checked, mut ok) = (0, 0);
    for (i, r) in input.raw.iter().enumerate() {
        let fp = core_footprint(&r.footprint);
        let radius = f64::from(RADII[r.footprint.map as usize]);
        if near_threshold(&heuristics, &fp, radius) {
            continue;
        }
        let want = resolved.store(fp, radius);
        assert_eq!(stored[i], want.is_ok(), "raw footprint {i}: device stored {}, core {want:?}", stored[i]);
        if let Ok((_, packed, _)) = want {
            assert_eq!(packed.center, r.footprint.center);
        }
        checked += 1;
        ok += want.is_ok() as usize;
    }
    assert!(checked > 2900 && ok > 500 && checked - ok > 100, "{checked} checked, {ok} stored: too few of either");

    // The photons: exactly the host's sort of the pass's photons and the fallbacks.
    let n = s.photon_count;
    let mut want: Vec<((u32, u32), u32, PackedPhoton)> = input
        .photons
        .iter()
        .enumerate()
        .map(|(j, p)| (sort_key(&s, p.photon.map, p.photon.position, p.key), j as u32, p.photon))
        .collect();
    for (i, r) in input.raw.iter().enumerate().filter(|(i, _)| !stored[*i]) {
        let f = &r.footprint;
        let p = PackedPhoton { position: f.center, map: f.map, normal: f.normal, flux: f.flux, ..Default::default() };
        want.push((sort_key(&s, f.map, f.center, r.key), n + i as u32, p));
    }
    want.sort_by_key(|w| (w.0, w.1));
    let want: Vec<PackedPhoton> = want.into_iter().map(|w| w.2).collect();
    assert!(want == out.photons, "sorted photons differ from the host's sort");
    for (p, b) in out.photons.iter().zip(&out.photon_boxes) {
        let r = RADII[p.map as usize];
        for a in 0..3 {
            let (lo, hi) = (p.position[a] - r, p.position[a] + r);
            let slack = 1e-3 * r + 1e-6;
            assert!(b[a] <= lo && b[a] >= lo - slack && b[a + 3] >= hi && b[a + 3] <= hi + slack, "box {b:?} of photon {p:?}");
        }
    }
}

/// The radix sort the store runs and the bitonic sort, through `StorePipelines::sort_items`,
/// against the host's sort: ties in `hi` and `lo`, full-range words, sizes around the radix
/// sort's round (256) and tile (4096); items past `n` untouched.
#[test]
fn sorts_match_the_host_sort() {
    let Some(ctx) = context("sorts") else { return };
    let pipelines = StorePipelines::new(&ctx).expect("store pipelines");
    let mut rng = Rng::new(12, 0, 0, StreamDomain::User);
    let scratch = arpa_vk::RadixScratch::new(&ctx, 70_001).expect("scratch");
    for (case, n) in [0u32, 1, 2, 257, 4096, 4097, 8192, 70_001].into_iter().enumerate() {
        let mut items: Vec<SortItem> = (0..n)
            .map(|i| match case % 2 {
                0 => SortItem { hi: rng.next_u32() % 64, lo: rng.next_u32() % 8, value: i ^ 0x5555 },
                _ => SortItem { hi: rng.next_u32(), lo: rng.next_u32() >> 30, value: i.wrapping_mul(2_654_435_761) },
            })
            .collect();
        let bound = items.iter().map(|s| u64::from(s.value) + 1).max().unwrap_or(0).min(u64::from(u32::MAX)) as u32;
        let mut want = items.clone();
        want.sort();
        let tail = [SortItem { hi: 3, lo: 0, value: 0 }, SortItem::INVALID];
        items.extend(tail);
        want.extend(tail);
        let run = |scratch: Option<&arpa_vk::RadixScratch>, len: u32, bound: u32, input: &[SortItem]| -> Vec<SortItem> {
            let buffer = ctx.upload("items", bytemuck::cast_slice(input), vk::BufferUsageFlags::STORAGE_BUFFER | vk::BufferUsageFlags::TRANSFER_SRC).expect("upload");
            pipelines.sort_items(&ctx, &buffer, len, bound, scratch).expect("sort");
            ctx.read_back(&buffer, 0, input.len() as u64 * 12).expect("read back").chunks_exact(12).map(bytemuck::pod_read_unaligned).collect()
        };
        for b in [bound, u32::MAX] {
            assert!(run(Some(&scratch), n, b, &items) == want, "radix, n = {n}, values below {b}: differs from the host's sort");
        }
        if n.is_power_of_two() && n >= arpa_core::gpu::sort::SORT_BLOCK {
            assert!(run(None, n, 0, &items) == want, "bitonic, n = {n}: differs from the host's sort");
        }
    }
    // Beyond the scratch or the buffer: errors.
    let buffer = ctx.upload("items", &[0; 24], vk::BufferUsageFlags::STORAGE_BUFFER).expect("upload");
    assert!(matches!(pipelines.sort_items(&ctx, &buffer, 3, 0, Some(&scratch)), Err(arpa_vk::VkError::InvalidInput { .. })));
    drop((scratch, pipelines));
    finish(ctx);
}

#[test]
fn store_sort_and_compaction_match_the_reference_in_any_append_order() {
    let Some(ctx) = context("maps") else { return };
    let input = input(11);
    let t0 = std::time::Instant::now();
    let store = MapStore::new(&ctx, &Arc::new(StorePipelines::new(&ctx).expect("store pipelines")), Capacities { raw_footprints: 4000, photons: 2000, sorted_photons: 6000 }).expect("map store");
    eprintln!("arpa-vk StorePipelines + MapStore::new (8 compute pipelines): {:.2} s", t0.elapsed().as_secs_f64());
    let t0 = std::time::Instant::now();
    let out = store_and_sort(&ctx, &store, &input);
    eprintln!("arpa-vk store + sort + compaction: {:?} in {:.2} s", out.counts, t0.elapsed().as_secs_f64());
    let t0 = std::time::Instant::now();
    check_against_reference(&input, &out);
    eprintln!("arpa-vk store reference check: {:.2} s", t0.elapsed().as_secs_f64());

    // Another append order: bit-identical outputs.
    let other = Input { raw: shuffled(&input.raw, 1), photons: shuffled(&input.photons, 2) };
    let again = store_and_sort(&ctx, &store, &other);
    assert!(again == out, "a shuffled input gives other outputs");

    // Counts above the capacities are errors.
    let raw = storage_upload(&ctx, "raw", bytemuck::cast_slice(&input.raw));
    let photons = storage_upload(&ctx, "photons", bytemuck::cast_slice(&input.photons));
    let mut s = settings(&input);
    s.raw_count = 4001;
    assert!(matches!(store.store(&ctx, &raw, &photons, &s), Err(arpa_vk::VkError::InvalidInput { .. })));
    drop((raw, photons, store));
    finish(ctx);
}

// ---------------------------------------------------------------------------------------
// The maps' acceleration structure, traced through the gather hit group

/// `ArpaGatherQuery` of gather_test.rgen (std430, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuQuery {
    position: [f32; 3],
    pad0: u32,
    normal: [f32; 3],
    pad1: u32,
}

/// Contributions per map at `q` (what the device counts).
fn counts_at(q: &QueryPoint, footprints: &[PackedFootprint], photons: &[PackedPhoton], kernel: Kernel) -> [u32; 2] {
    let mut c = [0u32; 2];
    for fp in footprints {
        let e = fp.irradiance(q.position, q.normal, kernel);
        if e != Vec3::ZERO && e.is_finite() {
            c[fp.photon_map().index()] += 1;
        }
    }
    for ph in photons {
        let e = ph.irradiance(q.position, q.normal, RADII[ph.photon_map().index()]);
        if e != Vec3::ZERO && e.is_finite() {
            c[ph.photon_map().index()] += 1;
        }
    }
    c
}

/// Whether a record sits on its test's boundary at `q` within rounding.
fn near_boundary(q: &QueryPoint, footprints: &[PackedFootprint], photons: &[PackedPhoton]) -> bool {
    let close = |x: f32| (x - 1.0).abs() < 1e-5;
    footprints.iter().any(|fp| {
        let y = fp.filter_coords(q.position);
        close(y.x * y.x + y.y * y.y) || close(y.z.abs())
    }) || photons.iter().any(|ph| {
        let radius = RADII[ph.photon_map().index()];
        close((q.position - Vec3::from_array(ph.position)).length_squared() / (radius * radius))
    })
}

/// Traces one query per point through `accel` over the sorted `footprints` and `photons`
/// buffers and returns the per-map counts.
fn trace_counts(
    ctx: &VkContext,
    pipeline: &RtPipeline,
    accel: &MapAccel,
    footprints: &Buffer,
    photons: &Buffer,
    queries: &[QueryPoint],
    kernel: Kernel,
) -> Vec<[u32; 2]> {
    let gpu: Vec<GpuQuery> =
        queries.iter().map(|q| GpuQuery { position: q.position.to_array(), pad0: 0, normal: q.normal.to_array(), pad1: 0 }).collect();
    let q_buf = storage_upload(ctx, "queries", bytemuck::cast_slice(&gpu));
    let n = queries.len();
    // gather_test.rgen writes one layout::GatherResult per query.
    let stride = size_of::<arpa_core::gpu::layout::GatherResult>();
    let results = ctx
        .create_buffer("results", (n * stride) as u64, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuToCpu)
        .expect("results");
    // layout::GatherImageParams: radii, kernel, query count, batch flags, scales (the stored
    // one), padding.
    let mut params = Vec::with_capacity(32);
    params.extend_from_slice(bytemuck::cast_slice(&RADII));
    params.extend_from_slice(&kernel_code(kernel).to_le_bytes());
    params.extend_from_slice(&(n as u32).to_le_bytes());
    params.extend_from_slice(&0u32.to_le_bytes());
    params.extend_from_slice(&1u32.to_le_bytes());
    params.extend_from_slice(&[0u8; 8]);
    let params = storage_upload(ctx, "gather params", &params);
    let unused = storage_upload(ctx, "unused binding", &[0u8; 16]);
    let set = [
        Resource::StorageBuffer(footprints),
        Resource::StorageBuffer(photons),
        Resource::StorageBuffer(&q_buf),
        Resource::StorageBuffer(&results),
        Resource::StorageBuffer(&params),
        Resource::StorageBuffer(&unused),
        Resource::StorageBuffer(&unused),
        Resource::AccelerationStructure(accel.tlas()),
    ];
    let bindings = pipeline.bind(&[&set]).expect("bind");
    pipeline.trace_and_wait(ctx, &bindings, &[], [64, (n as u32).div_ceil(64), 1]).expect("trace");
    let bytes = results.read(0, (n * stride) as u64).expect("read results");
    bytes.chunks_exact(stride).map(|r| [u32::from_le_bytes(r[12..16].try_into().unwrap()), u32::from_le_bytes(r[28..32].try_into().unwrap())]).collect()
}

#[test]
fn map_accel_from_device_boxes_finds_the_brute_force_records() {
    let Some(ctx) = context("maps") else { return };
    let input = input(23);
    let store = MapStore::new(&ctx, &Arc::new(StorePipelines::new(&ctx).expect("store pipelines")), Capacities { raw_footprints: 3000, photons: 1500, sorted_photons: 4500 }).expect("map store");
    let out = store_and_sort(&ctx, &store, &input);
    // Over the capacities: the slots past the records hold the compaction's inactive boxes,
    // which must hide no real box and be met by no query.
    let (fp_cap, ph_cap) = (store.capacities().raw_footprints, store.photons_out_capacity());
    assert!(out.counts.total_footprints() < fp_cap && out.counts.total_photons() < ph_cap, "no inactive slot to test: {:?}", out.counts);
    let accel = MapAccel::build(&ctx, store.footprint_boxes(), fp_cap, store.photon_boxes(), ph_cap).expect("map accel");
    assert_eq!(accel.instances().len(), 2, "both kinds: {:?}", accel.instances());
    let pipeline = gather_test_pipeline(&ctx);

    // Queries on both planes, seen from both sides, some at record centres.
    let mut rng = Rng::new(23, 11, 0, StreamDomain::User);
    let mut queries: Vec<QueryPoint> = (0..3000)
        .map(|_| {
            let k = rng.next_u32() % 2;
            let (z, nz) = if k == 0 { (0.0f32, 1.0f32) } else { (0.3, -1.0) };
            let back = rng.next_u32().is_multiple_of(4);
            QueryPoint {
                position: Vec3::new(1.2 * (rng.next_f32() - 0.5), 1.2 * (rng.next_f32() - 0.5), z),
                normal: Vec3::new(0.0, 0.0, if back { -nz } else { nz }),
            }
        })
        .collect();
    queries.extend(out.footprints.iter().step_by(7).map(|f| QueryPoint {
        position: Vec3::from_array(f.center),
        normal: Vec3::from_array(f.row_n).normalize(),
    }));
    queries.extend(out.photons.iter().step_by(7).map(|p| QueryPoint { position: Vec3::from_array(p.position), normal: Vec3::from_array(p.normal) }));

    let kernel = Kernel::Epanechnikov;
    let got = trace_counts(&ctx, &pipeline, &accel, store.footprints(), store.photons(), &queries, kernel);
    let (mut total, mut mismatched, mut empty) = (0u64, 0usize, 0usize);
    for (i, (q, g)) in queries.iter().zip(&got).enumerate() {
        let want = counts_at(q, &out.footprints, &out.photons, kernel);
        let brute = gather_brute_force(q, &out.footprints, &out.photons, RADII.map(f64::from), kernel);
        assert_eq!(want[0] + want[1], brute.footprints + brute.photons);
        if *g != want {
            assert!(near_boundary(q, &out.footprints, &out.photons), "query {i} {q:?}: device counts {g:?}, core {want:?}, no record on a boundary");
            mismatched += 1;
            continue;
        }
        total += u64::from(want[0] + want[1]);
        empty += (want == [0, 0]) as usize;
    }
    eprintln!(
        "arpa-vk map accel: {} queries, {} footprints, {} photons: {total} contributions counted exactly, {empty} queries with none, {mismatched} on a boundary differ",
        queries.len(),
        out.footprints.len(),
        out.photons.len()
    );
    assert!(mismatched * 1000 <= queries.len(), "{mismatched} queries differ");
    assert!(total > 3 * queries.len() as u64 && empty * 2 < queries.len(), "too few contributions to test anything: {total}, {empty} empty");

    // An empty iteration: a top level without instances that a trace binds; nothing is hit.
    let empty_accel = MapAccel::build(&ctx, store.footprint_boxes(), 0, store.photon_boxes(), 0).expect("empty accel");
    assert!(empty_accel.instances().is_empty() && empty_accel.blases().is_empty());
    let none = trace_counts(&ctx, &pipeline, &empty_accel, store.footprints(), store.photons(), &queries[..100], kernel);
    assert!(none.iter().all(|c| *c == [0, 0]), "hits in an empty structure");

    drop((pipeline, accel, empty_accel, store));
    finish(ctx);
}

// ---------------------------------------------------------------------------------------
// Running mean

#[test]
fn accumulator_mean_of_three_images() {
    let Some(ctx) = context("maps") else { return };
    let pixels = 1000u32;
    let images: Vec<Vec<[f32; 4]>> = (0..3u32)
        .map(|k| {
            (0..pixels)
                .map(|i| {
                    let x = (i as f32 + 1.0) * 0.001 + k as f32 * 0.37;
                    if k == 1 && i % 97 == 5 { [f32::NAN, 1.0, 1.0, 0.0] } else { [x, 2.0 * x + 1e-3 * k as f32, 1e-7 * (i + k) as f32, 7.0] }
                })
                .collect()
        })
        .collect();
    let acc = DeviceAccumulator::new(&ctx, &Arc::new(arpa_vk::accumulate::accumulate_pipeline(&ctx).expect("pipeline")), pixels).expect("accumulator");
    assert_eq!(acc.read_mean(&ctx, 0).expect("mean"), vec![[0.0; 3]; pixels as usize], "before any iteration");
    for (k, img) in images.iter().enumerate() {
        let buf = storage_upload(&ctx, &format!("image {k}"), bytemuck::cast_slice(img));
        acc.accumulate_and_wait(&ctx, &buf, None).expect("accumulate");
    }
    let mean = acc.read_mean(&ctx, 3).expect("mean");
    let rejected = acc.read_pixels(&ctx).expect("pixels").iter().map(|p| p.rejected).sum::<u32>();
    assert_eq!(rejected, (0..pixels).filter(|i| i % 97 == 5).count() as u32);
    for (i, m) in mean.iter().enumerate() {
        for c in 0..3 {
            // A non-finite sample (any channel) counts as an iteration that contributed 0.
            let sum: f64 = images.iter().filter(|img| img[i][..3].iter().all(|x| x.is_finite())).map(|img| f64::from(img[i][c])).sum();
            let want = sum / 3.0;
            let err = (f64::from(m[c]) - want).abs();
            assert!(err <= 2.0 * f64::from(f32::EPSILON) * want.abs() + 1e-30, "pixel {i} channel {c}: {} vs {want}", m[c]);
        }
    }
    let small = ctx.create_buffer("small image", 16, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly).expect("small");
    assert!(matches!(acc.bind(&small, None), Err(arpa_vk::VkError::InvalidInput { .. })));
    drop((small, acc));
    finish(ctx);
}
