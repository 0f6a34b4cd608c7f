//! The WGSL twin of `Aabb::padded_f32` (`arpa_padded_box`, the core's `aabb.wgsl`) on the
//! device: for boxes with `f32` centre and half extent near and far from the origin, large
//! and tiny (down to `f32` subnormals), the padded box contains the exact box grown by
//! what the gather's `f32` tests need (`half · Aabb::RELATIVE_PAD + 8 ε₃₂ s`, with
//! `s = |centre|∞ + |half|∞`), as the core's does, and stays as tight as the core's
//! padding.

use crate::common::*;
use arpa_core::base::aabb::Aabb;
use arpa_core::base::rng::{Rng, StreamDomain};

#[test]
fn padded_box_twin_contains_what_the_tests_need() {
    let Some(ctx) = gpu() else { return };
    let mut rng = Rng::new(21, 0, 0, StreamDomain::User);
    let mut rnd = || 2.0 * rng.next_f64() - 1.0;
    let mut boxes: Vec<([f32; 3], [f32; 3])> = vec![([0.0; 3], [1e-40; 3]), ([1e30, -1e30, 0.0], [1e-3, 1e-3, 1e-3]), ([0.1, -2.0, 1e-9], [0.05, 0.05, 0.05])];
    for i in 0..20_000 {
        let scale = 10f64.powf(8.0 * rnd());
        let shrink = if i % 4 == 0 { 1e-3 } else { 1.0 };
        let c = [rnd() * scale * shrink, rnd() * scale * shrink, rnd() * scale * shrink].map(|x| x as f32);
        // Photon boxes (the same half extent on every axis) and general ones.
        let r = (rnd().abs() + 1e-12) * scale * 10f64.powf(-4.0 * rnd().abs());
        let h = if i % 2 == 0 { [r; 3] } else { [r, (rnd().abs() + 1e-12) * scale, r * 0.5] }.map(|x| x as f32);
        boxes.push((c, h));
    }
    let mut input = Vec::new();
    for (c, h) in &boxes {
        push3(&mut input, *c);
        push3(&mut input, *h);
    }
    let out = run(ctx, "padded box", "let b = arpa_padded_box(in_v3(ib), in_v3(ib + 3u)); out_v3(ob, b.lower); out_v3(ob + 3u, b.upper);", &input, 6, 6);
    let eps = f32::EPSILON as f64;
    for ((c, h), o) in boxes.iter().zip(&out) {
        let (c, h) = (c.map(|x| x as f64), h.map(|x| x as f64));
        let s = c.iter().fold(0.0f64, |m, x| m.max(x.abs())) + h.iter().fold(0.0f64, |m, x| m.max(*x));
        let core = Aabb { min: (glam::DVec3::from_array(c) - glam::DVec3::from_array(h)), max: (glam::DVec3::from_array(c) + glam::DVec3::from_array(h)) }.padded_f32();
        for k in 0..3 {
            let (lower, upper) = (f(o[k]) as f64, f(o[3 + k]) as f64);
            let need = h[k] * Aabb::RELATIVE_PAD + 8.0 * eps * s;
            assert!(lower <= c[k] - h[k] - need && upper >= c[k] + h[k] + need, "centre {c:?} half {h:?}: axis {k} [{lower}, {upper}] misses the needed box");
            // As tight as the core's padding, within the roundings of the twin.
            let slack = 2.0 * eps * s + 1e-44;
            assert!(lower >= core.0[k] as f64 - slack && upper <= core.1[k] as f64 + slack, "centre {c:?} half {h:?}: axis {k} [{lower}, {upper}] vs the core's {core:?}");
        }
    }
}
