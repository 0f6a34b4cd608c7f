// WGSL twin of arpa_core::heuristics::ResolvedHeuristics::store: dampened adaptation,
// H-max limit, degenerate removal, the footprint's box and bounding-box culling, in the
// core's order, then the f32 record (footprint.wgsl's arpa_footprint_pack). The parameters
// come from arpa_core::heuristics::PackedHeuristics (same 48-byte layout). Needs
// footprint.wgsl (and so kernel.wgsl).
//
// Precision: f32 on vectors pre-scaled by their largest component (any normal-f32
// magnitude). The dampening ratio (l_ref/l)^(1 - gamma) is taken as exp of a logarithm
// difference: relative error ~ eps32 |ln(l/l_ref)| (below 1e-5 over the f32 range). The
// box is rounded outwards (it contains the core's f64 box). Decisions at a threshold
// (degenerate fraction, culling, M_p^-1's own degeneracy at 16 eps32) can differ from the
// core's within the f32 rounding of the compared quantities.

// Store outcomes (StoreRejection).
const ARPA_STORE_OK: u32 = 0u;
const ARPA_STORE_DEGENERATE: u32 = 1u;
const ARPA_STORE_CULLED: u32 = 2u;
const ARPA_STORE_UNREPRESENTABLE: u32 = 3u;

// ResolvedHeuristics (arpa_core::heuristics::PackedHeuristics).
struct ArpaHeuristics {
    enabled: u32,               // bit 0 dampening, 1 H-max, 2 degenerate removal, 3 culling
    dampen_reference_kind: u32, // 0 absolute, 1 progressive diameter 2 r_i
    h_max_mode: u32,            // 0 each differential, 1 preserve aspect
    cull_metric: u32,           // 0 largest extent, 1 diagonal, 2 surface area
    dampen_exponent: f32,
    dampen_reference: f32,      // m
    h_max: f32,                 // m
    degenerate_fraction: f32,
    cull_threshold: f32,        // m (m^2 for surface area)
    pad0: f32,
    pad1: f32,
    pad2: f32,
}

// What arpa_store produced: the final differentials, the record and the box (meaningful
// when status == ARPA_STORE_OK).
struct ArpaStored {
    du: vec3<f32>,
    dv: vec3<f32>,
    record: ArpaPackedFootprint,
    box_min: vec3<f32>,
    box_max: vec3<f32>,
    status: u32,
}

fn arpa_store_culled_metric(metric: u32, e: vec3<f32>) -> f32 {
    switch metric {
        case 0u: { return 2.0 * max(e.x, max(e.y, e.z)); }
        case 1u: { return 2.0 * arpa_safe_length(e); }
        default: { return 8.0 * (e.x * e.y + e.y * e.z + e.z * e.x); }
    }
}

// ResolvedHeuristics::store for the footprint (center, unit normal, tangent du, dv in
// metres, RGB flux in W, map) at progressive radius `radius` (m).
fn arpa_store(hp: ArpaHeuristics, center: vec3<f32>, normal: vec3<f32>, du_in: vec3<f32>, dv_in: vec3<f32>,
              flux: vec3<f32>, map: u32, radius: f32) -> ArpaStored {
    var out: ArpaStored;
    out.status = ARPA_STORE_DEGENERATE;
    var du = du_in;
    var dv = dv_in;
    // 1. Dampened adaptation: both scaled by (l_ref / l)^(1 - gamma), l = |D_major|.
    if (hp.enabled & 1u) != 0u {
        let major = max(arpa_safe_length(du), arpa_safe_length(dv));
        var reference = hp.dampen_reference;
        if hp.dampen_reference_kind == 1u {
            reference = 2.0 * radius;
        }
        if major > 0.0 && arpa_is_finite(major) && reference > 0.0 && arpa_is_finite(reference) {
            let ratio = exp((hp.dampen_exponent - 1.0) * (log(major) - log(reference)));
            if arpa_is_finite(ratio) && ratio > 0.0 {
                du *= ratio;
                dv *= ratio;
            }
        }
    }
    // 2. H-max limit.
    if (hp.enabled & 2u) != 0u && hp.h_max > 0.0 {
        let h = hp.h_max;
        let la = arpa_safe_length(du);
        let lb = arpa_safe_length(dv);
        if hp.h_max_mode == 0u {
            if la > h { du *= h / la; }
            if lb > h { dv *= h / lb; }
        } else {
            let major = max(la, lb);
            if major > h {
                let s = h / major;
                du *= s;
                dv *= s;
            }
        }
    }
    // 3. Degenerate removal: |D_u x D_v| < f |D_major|^2, on vectors scaled by a common m.
    let m = max(arpa_max_abs(du), arpa_max_abs(dv));
    if !(m > 0.0) || !arpa_is_finite(m) {
        return out;
    }
    let uh = du / m;
    let vh = dv / m;
    let major2 = max(dot(uh, uh), dot(vh, vh));
    if (hp.enabled & 4u) != 0u {
        if !(length(cross(uh, vh)) >= hp.degenerate_fraction * major2) {
            return out;
        }
    }
    // 4. The box of the elliptic slab, rounded outwards, and culling.
    let la = arpa_safe_length(du);
    let lb = arpa_safe_length(dv);
    let h = arpa_half_thickness(center, max(la, lb), min(la, lb), radius);
    let e = 0.5 * m * sqrt(uh * uh + vh * vh) + abs(normal * h);
    if (hp.enabled & 8u) != 0u {
        if !(arpa_store_culled_metric(hp.cull_metric, e) <= hp.cull_threshold) {
            out.status = ARPA_STORE_CULLED;
            return out;
        }
    }
    let packed = arpa_footprint_pack(center, normal, du, dv, flux, map, radius);
    if packed.status == ARPA_FOOTPRINT_DEGENERATE {
        return out;
    }
    if packed.status != ARPA_FOOTPRINT_OK {
        out.status = ARPA_STORE_UNREPRESENTABLE;
        return out;
    }
    let pad = e * (4.0 * ARPA_F32_EPSILON) + abs(center) * (2.0 * ARPA_F32_EPSILON);
    out.du = du;
    out.dv = dv;
    out.record = packed.fp;
    out.box_min = center - e - pad;
    out.box_max = center + e + pad;
    out.status = ARPA_STORE_OK;
    return out;
}
