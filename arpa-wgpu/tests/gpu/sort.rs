//! The device sort (`arpa_wgpu::sort`, run by `support::sort_items`) against the host's
//! `sort`: random `(hi, lo, value)`
//! items with many equal `hi` and `lo` words (the `value` tie-breaker decides), lengths
//! around the block size and up to several global merge steps; and the WGSL Morton code
//! against its host twin bit for bit; the radix sort (`support::radix_sort_items`) against
//! the host's `sort` at sizes around its round and tile, with full-range words and ties (points inside, outside and on the scene box, NaN).

use crate::common::*;
use arpa_core::base::rng::{Rng, StreamDomain};
use crate::support::{radix_sort_items, sort_items};
use arpa_core::gpu::sort::SortItem;
use arpa_core::base::morton::morton_code;

fn items(seed: u32, n: usize) -> Vec<SortItem> {
    let mut rng = Rng::new(seed, 0, 0, StreamDomain::User);
    (0..n)
        .map(|i| SortItem { hi: rng.next_u32() % 64, lo: rng.next_u32() % 8, value: i as u32 ^ 0x5555 })
        .collect()
}

#[test]
fn sort_matches_host_sort() {
    let Some(ctx) = gpu() else { return };
    for (seed, n) in [(1, 0usize), (2, 1), (3, 511), (4, 512), (5, 513), (6, 4097), (7, 70_000)] {
        let input = items(seed, n);
        let mut want = input.clone();
        want.sort();
        let got = sort_items(ctx, &input);
        assert!(got == want, "n = {n}: device order differs from the host's");
        // Another arrival order of the same items: the same result.
        let mut reversed = input.clone();
        reversed.reverse();
        assert!(sort_items(ctx, &reversed) == want, "n = {n}: order depends on the input order");
    }
}

#[test]
fn radix_sort_matches_host_sort() {
    let Some(ctx) = gpu() else { return };
    let mut rng = Rng::new(11, 0, 0, StreamDomain::User);
    // Sizes around the round (256) and the tile (4096), several tiles; keys with many ties
    // in hi and lo, full-range words (the top digits), and whole duplicates.
    for (case, n) in [0usize, 1, 2, 255, 257, 4096, 4097, 70_001].into_iter().enumerate() {
        let mut input = match case % 3 {
            0 => items(case as u32 + 20, n),
            1 => (0..n).map(|i| SortItem { hi: rng.next_u32(), lo: rng.next_u32() % 3, value: (i as u32).wrapping_mul(2_654_435_761) }).collect(),
            _ => (0..n).map(|i| SortItem { hi: rng.next_u32() >> 20, lo: rng.next_u32() >> 28, value: (i as u32 / 3) ^ 0x1234 }).collect(),
        };
        let bound = input.iter().map(|s| s.value as u64 + 1).max().unwrap_or(0).min(u32::MAX as u64) as u32;
        let mut want = input.clone();
        want.sort();
        // Items past n stay where they are.
        let tail = [SortItem { hi: 7, lo: 0, value: 1 }, SortItem::INVALID];
        input.extend(tail);
        want.extend(tail);
        for value_bound in [bound, u32::MAX] {
            let got = radix_sort_items(ctx, &input, tail.len(), value_bound);
            assert!(got == want, "n = {n}, values below {value_bound}: device order differs from the host's");
        }
        let mut reversed = input[..n].to_vec();
        reversed.reverse();
        reversed.extend(tail);
        assert!(radix_sort_items(ctx, &reversed, tail.len(), bound) == want, "n = {n}: order depends on the input order");
    }
}

#[test]
fn morton_matches_host_twin() {
    let Some(ctx) = gpu() else { return };
    let mut rng = Rng::new(9, 0, 0, StreamDomain::User);
    let lo = [-1.0f32, 0.5, -3.0];
    let inv = [0.5f32, 1.0 / 3.0, 0.0];
    let mut input = Vec::new();
    let mut points = Vec::new();
    for i in 0..2000 {
        let mut p = [0.0f32; 3];
        for (k, x) in p.iter_mut().enumerate() {
            *x = lo[k] + (rng.next_f64() as f32 * 1.4 - 0.2) / inv[k].max(0.25);
        }
        if i % 97 == 0 {
            p[i % 3] = f32::NAN;
        }
        if i % 89 == 0 {
            p[0] = lo[0] + 2.0; // exactly on the upper face
        }
        points.push(p);
        push3(&mut input, p);
    }
    let helpers = format!("const LO = vec3<f32>({:?}, {:?}, {:?});\nconst INV = vec3<f32>({:?}, {:?}, {:?});", lo[0], lo[1], lo[2], inv[0], inv[1], inv[2]);
    let out = run_with(ctx, "morton", &helpers, "out_u(ob, arpa_morton_code(in_v3(ib), LO, INV));", &input, 3, 1);
    let mut distinct = std::collections::HashSet::new();
    for (p, o) in points.iter().zip(&out) {
        assert_eq!(o[0], morton_code(*p, lo, inv), "{p:?}");
        distinct.insert(o[0]);
    }
    assert!(distinct.len() > 1500, "{} distinct codes", distinct.len());
}
