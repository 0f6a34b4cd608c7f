// One pass of the LSD radix sort of (hi, lo, value) items (ArpaSortItem, records.wgsl) on the
// device: 8-bit digits, least significant first; the host runs the passes of
// arpa_core::gpu::sort::radix_passes (the digits of value that can be non-zero, then lo,
// then hi), each reading radix_src and writing radix_dst (the host swaps them between
// passes). A pass is three dispatches:
// * radix_count, one workgroup per tile of RADIX_TILE items: the tile's digit histogram, into
//   radix_counts[digit * tiles + tile] (digit-major, so that one exclusive scan gives each
//   tile's first output position per digit);
// * radix_scan, one workgroup: the exclusive prefix sum of radix_counts in place;
// * radix_scatter, one workgroup per tile: each item to its digit's next position, in input
//   order within the tile (stable: the tile goes in rounds of 256 items; an item's rank
//   among the round's items of its digit is the number of lower invocations whose bit is set
//   in the digit's 256-bit mask).
// Stability makes the result of all passes the (hi, lo, value) order, whatever order the
// items came in; it does not depend on scheduling (no atomics decide a position).

// One pass: the first 16 bytes of arpa_core::gpu::sort::RadixPass.
struct RadixPass {
    n: u32,      // items
    tiles: u32,  // ceil(n / RADIX_TILE)
    word: u32,   // the digit's word: 0 value, 1 lo, 2 hi
    shift: u32,  // the digit's bit offset in its word
}

const RADIX_TILE: u32 = 4096u;  // arpa_core::gpu::sort::RADIX_TILE
const RADIX_BINS: u32 = 256u;   // arpa_core::gpu::sort::RADIX_BINS (also the workgroup size)

@group(0) @binding(0) var<storage, read> radix_src: array<ArpaSortItem>;
@group(0) @binding(1) var<storage, read_write> radix_dst: array<ArpaSortItem>;
@group(0) @binding(2) var<storage, read_write> radix_counts: array<u32>;
@group(0) @binding(3) var<uniform> radix_pass: RadixPass;

var<workgroup> radix_hist: array<atomic<u32>, 256>;
var<workgroup> radix_sums: array<u32, 256>;
// radix_scatter: per digit, the next output position and the round's 256-bit mask of the
// invocations holding that digit (8 words).
var<workgroup> radix_next: array<u32, 256>;
var<workgroup> radix_masks: array<atomic<u32>, 2048>;

fn radix_digit(item: ArpaSortItem) -> u32 {
    var w = item.hi;
    if radix_pass.word == 0u {
        w = item.value;
    } else if radix_pass.word == 1u {
        w = item.lo;
    }
    return (w >> radix_pass.shift) & 0xffu;
}

@compute @workgroup_size(256)
fn radix_count(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let t = lid.x;
    atomicStore(&radix_hist[t], 0u);
    workgroupBarrier();
    let end = min((wid.x + 1u) * RADIX_TILE, radix_pass.n);
    for (var i = wid.x * RADIX_TILE + t; i < end; i = i + RADIX_BINS) {
        atomicAdd(&radix_hist[radix_digit(radix_src[i])], 1u);
    }
    workgroupBarrier();
    radix_counts[t * radix_pass.tiles + wid.x] = atomicLoad(&radix_hist[t]);
}

@compute @workgroup_size(256)
fn radix_scan(@builtin(local_invocation_id) lid: vec3<u32>) {
    let t = lid.x;
    let m = RADIX_BINS * radix_pass.tiles;
    let chunk = (m + RADIX_BINS - 1u) / RADIX_BINS;
    let begin = min(t * chunk, m);
    let end = min(begin + chunk, m);
    var sum = 0u;
    for (var i = begin; i < end; i = i + 1u) {
        sum = sum + radix_counts[i];
    }
    radix_sums[t] = sum;
    workgroupBarrier();
    // Inclusive scan of the 256 chunk sums (Hillis-Steele).
    for (var d = 1u; d < RADIX_BINS; d = d * 2u) {
        var add = 0u;
        if t >= d {
            add = radix_sums[t - d];
        }
        workgroupBarrier();
        radix_sums[t] = radix_sums[t] + add;
        workgroupBarrier();
    }
    var run = radix_sums[t] - sum;
    for (var i = begin; i < end; i = i + 1u) {
        let c = radix_counts[i];
        radix_counts[i] = run;
        run = run + c;
    }
}

@compute @workgroup_size(256)
fn radix_scatter(@builtin(local_invocation_id) lid: vec3<u32>, @builtin(workgroup_id) wid: vec3<u32>) {
    let t = lid.x;
    let n = radix_pass.n;
    radix_next[t] = radix_counts[t * radix_pass.tiles + wid.x];
    for (var w = 0u; w < 8u; w = w + 1u) {
        atomicStore(&radix_masks[t * 8u + w], 0u);
    }
    workgroupBarrier();
    let word = t / 32u;
    let bit = 1u << (t % 32u);
    let base = wid.x * RADIX_TILE;
    for (var r = 0u; r < RADIX_TILE; r = r + RADIX_BINS) {
        if base + r >= n {
            break;
        }
        let i = base + r + t;
        let valid = i < n;
        var item = ArpaSortItem(0u, 0u, 0u);
        var d = 0u;
        if valid {
            item = radix_src[i];
            d = radix_digit(item);
            atomicOr(&radix_masks[d * 8u + word], bit);
        }
        workgroupBarrier();
        var at = 0u;
        var last = false;
        var total = 0u;
        if valid {
            var below = 0u;
            for (var w = 0u; w < 8u; w = w + 1u) {
                let m = atomicLoad(&radix_masks[d * 8u + w]);
                total = total + countOneBits(m);
                if w < word {
                    below = below + countOneBits(m);
                } else if w == word {
                    below = below + countOneBits(m & (bit - 1u));
                }
            }
            at = radix_next[d] + below;
            last = below + 1u == total;
        }
        workgroupBarrier();
        if valid {
            radix_dst[at] = item;
            atomicStore(&radix_masks[d * 8u + word], 0u);
            if last {
                radix_next[d] = radix_next[d] + total;
            }
        }
        workgroupBarrier();
    }
}
