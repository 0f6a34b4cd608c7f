// WGSL twin of arpa_core::store::heuristics::ResolvedHeuristics::store: dampened adaptation,
// H-max limit, degenerate removal, the footprint's box and bounding-box culling, in the
// core's order, on the ellipse's principal axes (arpa_core::store::footprint::principal_axes), then
// the f32 record (footprint.wgsl's arpa_footprint_pack). The parameters come from
// arpa_core::store::heuristics::PackedHeuristics (same 48-byte layout). Needs footprint.wgsl (and
// so kernel.wgsl).
//
// Precision: f32 on vectors pre-scaled by their largest component (any normal-f32
// magnitude). The dampening ratio (l_ref/l)^(1 - gamma) is taken as exp of a logarithm
// difference: relative error ~ eps32 |ln(l/l_ref)| (below 1e-5 over the f32 range). The
// minor axis 2 sigma_2 = |D_u x D_v| / (2 sigma_1) carries a relative error
// ~ eps32 sigma_1/sigma_2; where H-max clamps the axes separately the footprint comes out
// as its principal differentials, whose directions are ill-determined for a near-circle
// (the ellipse they span is not: compare ellipses, not vectors). A footprint whose axis
// ratio sigma_2/sigma_1 is at most 16 eps32 has no ellipse f32 can resolve and is
// degenerate here (the core uses 16 eps64). The box is rounded outwards (it contains the
// core's f64 box). Decisions at a threshold (degenerate fraction, culling, the axis-ratio
// resolution) can differ from the core's within the f32 rounding of the compared quantities.

// Store outcomes (StoreRejection).
const ARPA_STORE_OK: u32 = 0u;
const ARPA_STORE_DEGENERATE: u32 = 1u;
const ARPA_STORE_CULLED: u32 = 2u;
const ARPA_STORE_UNREPRESENTABLE: u32 = 3u;

// ResolvedHeuristics (arpa_core::store::heuristics::PackedHeuristics).
struct ArpaHeuristics {
    enabled: u32,               // bit 0 dampening, 1 H-max, 2 degenerate removal, 3 culling
    dampen_reference_kind: u32, // 0 absolute, 1 progressive diameter 2 r_i
    h_max_mode: u32,            // 0 each principal axis, 1 preserve aspect
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
    // The principal axes (metres) from the Gram matrix of the vectors scaled by m0.
    let m0 = max(arpa_max_abs(du), arpa_max_abs(dv));
    if !(m0 > 0.0) || !arpa_is_finite(m0) || !arpa_is_finite3(normal) {
        return out;
    }
    let uh0 = du / m0;
    let vh0 = dv / m0;
    let la2 = dot(uh0, uh0);
    let lb2 = dot(vh0, vh0);
    let uv = dot(uh0, vh0);
    let c0 = cross(uh0, vh0);
    let area = length(c0);
    let den = dot(c0, normal);
    let mu1 = arpa_major_axis2(la2, lb2, uv);
    // No ellipse f32 resolves: sigma_2/sigma_1 <= 16 eps32.
    if !(area > 16.0 * ARPA_F32_EPSILON * mu1) {
        return out;
    }
    let l1 = sqrt(mu1);
    var major = m0 * l1;
    var minor = m0 * min(area / l1, l1);
    // 1. Dampened adaptation: the ellipse scaled by (l_ref / l)^(1 - gamma), l = 2 sigma_1.
    if (hp.enabled & 1u) != 0u {
        var reference = hp.dampen_reference;
        if hp.dampen_reference_kind == 1u {
            reference = 2.0 * radius;
        }
        if major > 0.0 && arpa_is_finite(major) && reference > 0.0 && arpa_is_finite(reference) {
            let ratio = exp((hp.dampen_exponent - 1.0) * (log(major) - log(reference)));
            if arpa_is_finite(ratio) && ratio > 0.0 {
                du *= ratio;
                dv *= ratio;
                major *= ratio;
                minor *= ratio;
            }
        }
    }
    // 2. H-max limit on the principal axes.
    if (hp.enabled & 2u) != 0u && hp.h_max > 0.0 && major > hp.h_max {
        let h = hp.h_max;
        if hp.h_max_mode == 0u {
            // Each axis clamped: the principal differentials with the clamped lengths. The
            // eigenvector of the Gram matrix for (2 sigma_1)^2 in its cancellation-free form.
            let hh = 0.5 * (la2 - lb2);
            let d = sqrt(hh * hh + uv * uv);
            var w = vec2<f32>(uv, d - hh);
            if hh >= 0.0 {
                w = vec2<f32>(d + hh, uv);
            }
            let wm = max(abs(w.x), abs(w.y));
            var e1 = uh0; // a circle spanned by orthogonal equal-length differentials
            if wm > 0.0 {
                e1 = uh0 * (w.x / wm) + vh0 * (w.y / wm);
            }
            e1 = e1 / arpa_safe_length(e1);
            var e2 = cross(normal, e1);
            if den < 0.0 {
                e2 = -e2;
            }
            minor = min(minor, h);
            major = h;
            du = e1 * h;
            dv = e2 * minor;
        } else {
            let s = h / major;
            du *= s;
            dv *= s;
            minor *= s;
            major = h;
        }
    }
    // 3. Degenerate removal: sigma_2 / sigma_1 < f.
    if (hp.enabled & 4u) != 0u {
        if !(minor >= hp.degenerate_fraction * major) {
            return out;
        }
    }
    // 4. The box of the elliptic slab, rounded outwards, and culling.
    let m = max(arpa_max_abs(du), arpa_max_abs(dv));
    if !(m > 0.0) || !arpa_is_finite(m) {
        return out;
    }
    let uh = du / m;
    let vh = dv / m;
    let axes = arpa_footprint_axes(du, dv);
    let h = arpa_half_thickness(center, axes.x, axes.y, radius);
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
