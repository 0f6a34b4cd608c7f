//! The gather's AABB hit group (GLSL `gather.rint` + `gather.rahit`, checked-in SPIR-V) on a
//! real Vulkan driver (lavapipe in CI) under the Khronos validation layer, against the core:
//! this is the twin coverage of the GLSL's copy of `PackedFootprint::contains`/`irradiance`,
//! `PackedPhoton::contains`/`irradiance` and `Kernel::eval` (`gather_common.glsl`).
//!
//! First `scripts/build-vk-shaders.sh --check` (the checked-in SPIR-V is what the GLSL
//! compiles to, and `spirv-val` accepts it). Then random footprints (stored through
//! `arpa_core::store::decision::store_footprint`, as the photon pass does) and progressive
//! photons on three planes, both maps, some seen from the back; an AABB BLAS per
//! (kind, map) over the padded boxes (`Aabb::padded_f32`), instance custom index = kind bit |
//! first record, mask `1 << map` (gather.wgsl's convention). One short ray per query point,
//! for each of the three kernels, against `arpa_core::gather::estimate::gather_brute_force` over the
//! same records, and at every scale of the bandwidth ladder against
//! `arpa_core::gather::estimate::gather_brute_force_scales` (the any-hit shader's scale-1..4 totals of
//! both maps). (A wrong rejection by the intersection shader shows as a missing count; a
//! wrong acceptance is caught by the any-hit shader's own test, so only the any-hit's decision
//! reaches the counts in that case.)
//!
//! No inactive boxes: on lavapipe an AABB BLAS with inactive boxes (min x NaN) after the real
//! ones loses real primitives in traversal, so building over the full capacity with NaN boxes
//! is not an option there (see `accel::build_aabb_blas`).
//!
//! Bounds:
//! - **Counts** (per query and map) exact. The GLSL forms the tests' dot products in glam's
//!   order and marks them `precise` (no fused multiply-add), so it decides as the core's f32
//!   code does. A query may differ only where some record sits on a boundary within rounding
//!   (`|r² − 1|`, `||y.z| − 1|` or `|d²/r² − 1|` below 1e-5); such queries are counted and
//!   must stay below 0.1 %. A third of the queries are put on boundaries on purpose (a
//!   footprint's rim in its plane and on its slab's faces, a photon's sphere, scaled by
//!   1 − 1e-6, 1 and 1 + 1e-6).
//! - **Sums** (per query and map): the device adds the contributions in f32 in traversal
//!   order, the core in f64 in index order: the f32 summation error is at most
//!   `γ(n−1) Σ|e| ≈ (n − 1) 2⁻²⁴ Σ|e|` for `n` contributions. Each contribution is the same
//!   f32 operations as the core's, but Vulkan allows 2.5 ulp for a division (a photon's
//!   density `1/(π r²)`), up to `5 · 2⁻²⁴ Σ|e|` more. The test allows `(n + 5) 2⁻²⁴ Σ|e|`
//!   plus 1e-30. On lavapipe every single-contribution sum is bit-identical and the worst
//!   error reaches the first-order summation bound `(n − 1) 2⁻²⁴ Σ|e|` (0.99 to 1.00 of it)
//!   but no more. (Before the GLSL spelled out
//!   `3 FRAC_1_PI` as the core's f32 product, glslang's double-precision constant folding
//!   made every Silverman contribution one ulp off; see `gather_common.glsl`.)
//! - **Scaled sums** (per query and scale `k ≥ 1`, both maps): the same bound with `n` the
//!   scale's contributions (the scaled weights `2^k K(2^k r²)` and `2^k/(π r²)` are the
//!   core's f32 operations, `precise`). A query may differ only where some record sits on a
//!   scaled boundary within rounding (`|2^k r² − 1|` or `|2^k d²/r² − 1|` below 1e-5); such
//!   queries must stay below 0.1 % too. A gather of one scale leaves the totals zero.
//!
//! Without a Vulkan loader, driver or validation layer, or without `glslc`/`spirv-val`, the
//! test skips with a loud message, except in CI (env `CI` set), where it fails.

use arpa_core::base::aabb::Aabb;
use arpa_core::propagate::classify::Smoothing;
use arpa_core::gather::scales::{SCALES, inv_scale2};
use arpa_core::gather::estimate::{QueryPoint, gather_brute_force, gather_brute_force_scales};
use arpa_core::store::footprint::{Footprint, PackedFootprint, PhotonMap};
use arpa_core::gpu::codes::{INSTANCE_PHOTON_BIT, kernel_code};
use arpa_core::store::heuristics::Heuristics;
use arpa_core::gather::kernel::Kernel;
use arpa_core::store::progressive_photon::{PackedPhoton, ProgressivePhoton};
use arpa_core::base::rng::{Rng, StreamDomain};
use arpa_core::store::decision::{StoredPhoton, store_footprint};
use arpa_vk::accel::IDENTITY_TRANSFORM;
use arpa_vk::vk;
use arpa_vk::{
    AccelerationStructure, MemoryLocation, Resource, TlasInstance,
};
use glam::{DVec3, Vec3};
use std::path::Path;
use std::process::Command;

mod support;
use support::{context, gather_test_pipeline, in_ci, skip};

/// Runs `scripts/build-vk-shaders.sh --check`; `false` (skip) where `glslc` or `spirv-val`
/// is missing outside CI.
fn shaders_match_their_source() -> bool {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    for tool in ["glslc", "spirv-val"] {
        if Command::new(tool).arg("--version").output().is_err() {
            assert!(!in_ci(), "CI needs {tool} (Debian: glslc, spirv-tools) for scripts/build-vk-shaders.sh --check");
            skip("gather hit-group", &format!("{tool} not found (Debian: apt-get install glslc spirv-tools)"));
            return false;
        }
    }
    let out = Command::new("bash").arg(root.join("scripts/build-vk-shaders.sh")).arg("--check").output().expect("run bash");
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    eprintln!("{}", text.trim_end());
    assert!(out.status.success(), "scripts/build-vk-shaders.sh --check failed:\n{text}");
    true
}

/// `ArpaGatherQuery` of gather_test.rgen (std430, 32 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuQuery {
    position: [f32; 3],
    pad0: u32,
    normal: [f32; 3],
    pad1: u32,
}

/// `ArpaGatherResult` of gather_test.rgen (arpa_core::gpu::layout::GatherResult, 112 bytes).
#[repr(C)]
#[derive(Clone, Copy, Debug, bytemuck::Pod, bytemuck::Zeroable)]
struct GpuResult {
    sum: [[f32; 4]; 2],
    candidates: [u32; 2],
    pad: [u32; 2],
    scaled: [[f32; 4]; SCALES - 1],
}
const RESULT_BYTES: usize = size_of::<GpuResult>();
const _: () = assert!(RESULT_BYTES == size_of::<arpa_core::gpu::layout::GatherResult>());

impl GpuResult {
    fn sum(&self, map: usize) -> DVec3 {
        Vec3::new(self.sum[map][0], self.sum[map][1], self.sum[map][2]).as_dvec3()
    }
    fn count(&self, map: usize) -> u32 {
        self.sum[map][3].to_bits()
    }
    /// Both maps' total at scale `k ≥ 1`.
    fn scaled(&self, k: usize) -> DVec3 {
        Vec3::from_slice(&self.scaled[k - 1][..3]).as_dvec3()
    }
}

/// A plane the records and queries lie on: origin, two unit tangents, unit normal.
struct Plane {
    origin: DVec3,
    t1: DVec3,
    t2: DVec3,
    n: DVec3,
}

fn planes() -> Vec<Plane> {
    let tilted_n = DVec3::new(0.3, 0.8, -0.52).normalize();
    let tilted_t1 = tilted_n.cross(DVec3::X).normalize();
    vec![
        Plane { origin: DVec3::ZERO, t1: DVec3::X, t2: DVec3::Z, n: DVec3::Y },
        Plane { origin: DVec3::new(-1.0, 1.0, 0.0), t1: DVec3::Y, t2: DVec3::Z, n: DVec3::X },
        Plane { origin: DVec3::new(0.2, 0.9, 0.4), t1: tilted_t1, t2: tilted_n.cross(tilted_t1), n: tilted_n },
    ]
}

struct Records {
    /// Sorted by map (caustic first).
    footprints: Vec<PackedFootprint>,
    footprint_boxes: Vec<[f32; 6]>,
    photons: Vec<PackedPhoton>,
    queries: Vec<QueryPoint>,
}

const FOOTPRINT_RADIUS: f64 = 0.05;
const RADII: [f32; 2] = [0.08, 0.12];

fn records(rng: &mut Rng, footprints: usize, photons: usize, queries: usize, rim_queries: usize) -> Records {
    let planes = planes();
    let heuristics = Heuristics::NONE.resolve(&Aabb { min: DVec3::splat(-10.0), max: DVec3::splat(10.0) });
    let f = |rng: &mut Rng| rng.next_f32() as f64;
    let mut fps: Vec<(PackedFootprint, Aabb, Footprint)> = Vec::new();
    while fps.len() < footprints {
        let p = &planes[rng.next_u32() as usize % 3];
        let (u, v) = (2.0 * f(rng) - 1.0, 2.0 * f(rng) - 1.0);
        let normal = if f(rng) < 0.2 { -p.n } else { p.n };
        let angle = std::f64::consts::TAU * f(rng);
        let dir = p.t1 * angle.cos() + p.t2 * angle.sin();
        let perp = p.n.cross(dir);
        let (len_u, len_v) = (0.1 + 0.4 * f(rng), 0.03 + 0.3 * f(rng));
        let skew = 0.6 * (f(rng) - 0.5);
        let fp = Footprint {
            center: p.origin + p.t1 * u + p.t2 * v,
            normal,
            du: dir * len_u,
            dv: (perp + dir * skew) * len_v,
            flux: DVec3::new(0.1 + f(rng), 0.1 + f(rng), 0.1 + f(rng)) * 1e-3,
            map: if rng.next_u32().is_multiple_of(3) { PhotonMap::Caustic } else { PhotonMap::Global },
        };
        if let StoredPhoton::Footprint { packed, aabb } = store_footprint(fp, &Smoothing::default(), &heuristics, FOOTPRINT_RADIUS)
        {
            fps.push((packed, aabb, fp));
        }
    }
    fps.sort_by_key(|(p, _, _)| p.map);
    let box6 = |a: &Aabb| {
        let (lo, hi) = a.padded_f32();
        [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
    };
    let mut phs: Vec<PackedPhoton> = (0..photons)
        .map(|_| {
            let p = &planes[rng.next_u32() as usize % 3];
            let (u, v) = (2.0 * f(rng) - 1.0, 2.0 * f(rng) - 1.0);
            ProgressivePhoton {
                position: p.origin + p.t1 * u + p.t2 * v,
                normal: if f(rng) < 0.2 { -p.n } else { p.n },
                flux: DVec3::new(0.1 + f(rng), 0.1 + f(rng), 0.1 + f(rng)) * 1e-3,
                map: if rng.next_u32().is_multiple_of(2) { PhotonMap::Caustic } else { PhotonMap::Global },
            }
            .pack()
        })
        .collect();
    phs.sort_by_key(|p| p.map);
    let mut qs: Vec<QueryPoint> = (0..queries)
        .map(|_| {
            let p = &planes[rng.next_u32() as usize % 3];
            let (u, v) = (2.0 * f(rng) - 1.0, 2.0 * f(rng) - 1.0);
            // Off the plane by up to 3 cm: inside and outside the footprints' slabs.
            let off = 0.06 * (f(rng) - 0.5);
            QueryPoint {
                position: (p.origin + p.t1 * u + p.t2 * v + p.n * off).as_vec3(),
                normal: (if f(rng) < 0.15 { -p.n } else { p.n }).as_vec3(),
            }
        })
        .collect();
    // Queries on the records' boundaries: a footprint's rim (ellipse with conjugate
    // semi-diameters D_u/2, D_v/2) on its plane and on its slab's faces, a photon's sphere,
    // each scaled by 1 - 1e-6, 1 or 1 + 1e-6, seen from the lit side.
    for k in 0..rim_queries {
        let s = [1.0 - 1e-6, 1.0, 1.0 + 1e-6][k % 3];
        if k % 2 == 0 {
            let angle = std::f64::consts::TAU * f(rng);
            let (_, _, fp) = &fps[rng.next_u32() as usize % fps.len()];
            let h = fp.half_thickness(FOOTPRINT_RADIUS);
            let z = [0.0, 1.0, -1.0][(k / 6) % 3];
            let d = (0.5 * fp.du * angle.cos() + 0.5 * fp.dv * angle.sin()) * s + fp.normal * (h * z * s);
            qs.push(QueryPoint { position: (fp.center + d).as_vec3(), normal: fp.normal.as_vec3() });
        } else {
            let ph = &phs[rng.next_u32() as usize % phs.len()];
            let dir = arpa_core::base::sampling::uniform_sphere(rng.next_2d());
            let r = f64::from(RADII[ph.photon_map().index()]);
            let q = Vec3::from_array(ph.position).as_dvec3() + dir * (r * s);
            qs.push(QueryPoint { position: q.as_vec3(), normal: Vec3::from_array(ph.normal) });
        }
    }
    Records {
        footprint_boxes: fps.iter().map(|(_, a, _)| box6(a)).collect(),
        footprints: fps.into_iter().map(|(p, _, _)| p).collect(),
        photons: phs,
        queries: qs,
    }
}

/// Whether any record sits on its test's boundary at `q` within rounding (see the bounds).
fn near_boundary(q: &QueryPoint, r: &Records) -> bool {
    let close = |x: f32| (x - 1.0).abs() < 1e-5;
    r.footprints.iter().any(|fp| {
        let y = fp.filter_coords(q.position);
        close(y.x * y.x + y.y * y.y) || close(y.z.abs())
    }) || r.photons.iter().any(|ph| {
        let radius = RADII[ph.photon_map().index()];
        close((q.position - Vec3::from_array(ph.position)).length_squared() / (radius * radius))
    })
}

/// Whether any record sits on a scaled boundary (scale `k ≥ 1`) at `q` within rounding.
fn near_scaled_boundary(q: &QueryPoint, r: &Records) -> bool {
    let close = |x: f32| (x - 1.0).abs() < 1e-5;
    (1..SCALES).any(|k| {
        let f = inv_scale2(k);
        r.footprints.iter().any(|fp| {
            let y = fp.filter_coords(q.position);
            close((y.x * y.x + y.y * y.y) * f)
        }) || r.photons.iter().any(|ph| {
            let radius = RADII[ph.photon_map().index()];
            close((q.position - Vec3::from_array(ph.position)).length_squared() * f / (radius * radius))
        })
    })
}

/// Contributions of both maps per scale at `q` and the sum of their magnitudes.
fn scale_counts(q: &QueryPoint, r: &Records, kernel: Kernel) -> ([u32; SCALES], [f64; SCALES]) {
    let (mut c, mut abs) = ([0u32; SCALES], [0.0f64; SCALES]);
    let mut add = |e: [Vec3; SCALES]| {
        for k in 0..SCALES {
            if e[k] != Vec3::ZERO && e[k].is_finite() {
                c[k] += 1;
                abs[k] += e[k].abs().max_element() as f64;
            }
        }
    };
    for fp in &r.footprints {
        add(fp.irradiance_scales(q.position, q.normal, kernel));
    }
    for ph in &r.photons {
        add(ph.irradiance_scales(q.position, q.normal, RADII[ph.photon_map().index()]));
    }
    (c, abs)
}

/// Boxes per map that contain `q` shrunk by `margin` (metres; negative: grown): the
/// device's candidates lie between the counts for `margin = 1e-6` and `-1e-5` (its ray
/// is 1e-6 long, and box tests may be conservative).
fn boxes_containing(q: &QueryPoint, r: &Records, margin: f32) -> [u32; 2] {
    let mut c = [0u32; 2];
    let inside = |b: &[f32; 6]| (0..3).all(|k| b[k] + margin <= q.position[k] && q.position[k] <= b[k + 3] - margin);
    for (fp, b) in r.footprints.iter().zip(&r.footprint_boxes) {
        c[fp.photon_map().index()] += inside(b) as u32;
    }
    for ph in &r.photons {
        let m = ph.photon_map().index();
        let (lo, hi) = Aabb::from_centre_half_extent(Vec3::from_array(ph.position).as_dvec3(), DVec3::splat(RADII[m].into())).padded_f32();
        c[m] += inside(&[lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]) as u32;
    }
    c
}

/// Contributions per map at `q` (what the device counts).
fn counts(q: &QueryPoint, r: &Records, kernel: Kernel) -> ([u32; 2], [DVec3; 2]) {
    let (mut c, mut abs) = ([0u32; 2], [DVec3::ZERO; 2]);
    let mut add = |map: PhotonMap, e: Vec3| {
        if e != Vec3::ZERO && e.is_finite() {
            c[map.index()] += 1;
            abs[map.index()] += e.abs().as_dvec3();
        }
    };
    for fp in &r.footprints {
        add(fp.photon_map(), fp.irradiance(q.position, q.normal, kernel));
    }
    for ph in &r.photons {
        add(ph.photon_map(), ph.irradiance(q.position, q.normal, RADII[ph.photon_map().index()]));
    }
    (c, abs)
}

/// The GLSL's ladder is the core's: `ARPA_SCALES` of `gather_common.glsl` is
/// `arpa_core::gather::scales::SCALES`, and the payload holds a total for every smaller scale.
#[test]
fn glsl_scales_are_the_cores() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let common = std::fs::read_to_string(dir.join("gather_common.glsl")).expect("gather_common.glsl");
    assert!(common.contains(&format!("const uint ARPA_SCALES = {SCALES}u;")), "gather_common.glsl's ARPA_SCALES is not {SCALES}");
    let payload = std::fs::read_to_string(dir.join("gather_payload.glsl")).expect("gather_payload.glsl");
    let raygen = std::fs::read_to_string(dir.join("gather_raygen.wgsl")).expect("gather_raygen.wgsl");
    for k in 1..SCALES {
        assert!(payload.contains(&format!("vec4 scale{k};")), "gather_payload.glsl has no scale{k}");
        assert!(raygen.contains(&format!("scale{k}: vec4<f32>,")), "gather_raygen.wgsl's VkGatherPayload has no scale{k}");
    }
    assert!(!payload.contains(&format!("scale{SCALES};")), "a payload total beyond the ladder");
}

#[test]
fn gather_hit_group_matches_the_core() {
    let start = std::time::Instant::now();
    if !shaders_match_their_source() {
        return;
    }
    let Some(ctx) = context("gather hit-group") else { return };
    let mut rng = Rng::new(0x6a7e_0020, 0, 0, StreamDomain::User);
    let recs = records(&mut rng, 5000, 2500, 4000, 2000);

    let usage = vk::BufferUsageFlags::STORAGE_BUFFER;
    let upload = |label: &str, bytes: &[u8]| ctx.upload(label, bytes, usage).expect(label);
    let fp_buf = upload("footprints", bytemuck::cast_slice(&recs.footprints));
    let ph_buf = upload("photons", bytemuck::cast_slice(&recs.photons));
    let gpu_queries: Vec<GpuQuery> = recs
        .queries
        .iter()
        .map(|q| GpuQuery { position: q.position.to_array(), pad0: 0, normal: q.normal.to_array(), pad1: 0 })
        .collect();
    let q_buf = upload("queries", bytemuck::cast_slice(&gpu_queries));
    let n = recs.queries.len();
    let result_buf = ctx.create_buffer("results", (n * RESULT_BYTES) as u64, usage, MemoryLocation::GpuToCpu).expect("results");

    // One BLAS per non-empty (kind, map).
    let mut blases: Vec<(AccelerationStructure, u32, u8)> = Vec::new();
    for map in PhotonMap::ALL {
        let m = map as u32;
        let first = recs.footprints.iter().position(|f| f.map == m);
        let count = recs.footprints.iter().filter(|f| f.map == m).count();
        if let Some(first) = first {
            let boxes = &recs.footprint_boxes[first..first + count];
            let blas = ctx.build_aabb_blas(&format!("footprints {map:?}"), boxes).expect("footprint BLAS");
            blases.push((blas, first as u32, 1 << m));
        }
        let first = recs.photons.iter().position(|p| p.map == m);
        if let Some(first) = first {
            let boxes: Vec<[f32; 6]> = recs.photons[first..]
                .iter()
                .take_while(|p| p.map == m)
                .map(|p| {
                    let (lo, hi) = Aabb::from_centre_half_extent(Vec3::from_array(p.position).as_dvec3(), DVec3::splat(RADII[m as usize].into()))
                        .padded_f32();
                    [lo[0], lo[1], lo[2], hi[0], hi[1], hi[2]]
                })
                .collect();
            let blas = ctx.build_aabb_blas(&format!("photons {map:?}"), &boxes).expect("photon BLAS");
            blases.push((blas, INSTANCE_PHOTON_BIT | first as u32, 1 << m));
        }
    }
    assert_eq!(blases.len(), 4, "both kinds in both maps");
    let instances: Vec<TlasInstance<'_>> = blases
        .iter()
        .map(|(blas, custom_index, mask)| TlasInstance {
            blas,
            transform: IDENTITY_TRANSFORM,
            custom_index: *custom_index,
            mask: *mask,
            sbt_record_offset: 0,
            flags: vk::GeometryInstanceFlagsKHR::empty(),
        })
        .collect();
    let tlas = ctx.build_tlas("gather boxes", &instances).expect("TLAS");

    let pipeline = gather_test_pipeline(&ctx);
    let mut params_buf = ctx
        .create_buffer("gather params", 32, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::CpuToGpu)
        .expect("params buffer");
    let unused = ctx.create_buffer("unused binding", 16, vk::BufferUsageFlags::STORAGE_BUFFER, MemoryLocation::GpuOnly).expect("buffer");
    let set = [
        Resource::StorageBuffer(&fp_buf),
        Resource::StorageBuffer(&ph_buf),
        Resource::StorageBuffer(&q_buf),
        Resource::StorageBuffer(&result_buf),
        Resource::StorageBuffer(&params_buf),
        Resource::StorageBuffer(&unused),
        Resource::StorageBuffer(&unused),
        Resource::AccelerationStructure(&tlas),
    ];
    let bindings = pipeline.bind(&[&set]).expect("bind");
    let setup = start.elapsed().as_secs_f64();

    let near: Vec<bool> = recs.queries.iter().map(|q| near_boundary(q, &recs)).collect();
    let near_count = near.iter().filter(|&&b| b).count();
    let near_scaled: Vec<bool> = recs.queries.iter().map(|q| near_scaled_boundary(q, &recs)).collect();
    let width = 64u32;
    // Every scale for each kernel, then the stored scale alone (the totals stay zero).
    for (kernel, scales) in [(Kernel::Silverman, SCALES), (Kernel::Epanechnikov, SCALES), (Kernel::Constant, SCALES), (Kernel::Silverman, 1)] {
        // layout::GatherImageParams: radii, kernel, query count, batch flags, scales, padding.
        let mut params = Vec::with_capacity(32);
        params.extend_from_slice(bytemuck::cast_slice(&RADII));
        params.extend_from_slice(&kernel_code(kernel).to_le_bytes());
        params.extend_from_slice(&(n as u32).to_le_bytes());
        params.extend_from_slice(&0u32.to_le_bytes());
        params.extend_from_slice(&(scales as u32).to_le_bytes());
        params.extend_from_slice(&[0u8; 8]);
        params_buf.write(0, &params).expect("write params");
        let t0 = std::time::Instant::now();
        pipeline.trace_and_wait(&ctx, &bindings, &[], [width, (n as u32).div_ceil(width), 1]).expect("trace");
        let trace_s = t0.elapsed().as_secs_f64();
        let got: Vec<GpuResult> =
            result_buf.read(0, (n * RESULT_BYTES) as u64).expect("read results").chunks_exact(RESULT_BYTES).map(bytemuck::pod_read_unaligned).collect();

        let (mut single, mut single_exact, mut candidates) = (0u32, 0u32, 0u64);
        let (mut total, mut max_count, mut empty, mut mismatched, mut worst_rel, mut worst_vs_bound) = (0u64, 0u32, 0, 0, 0.0f64, 0.0f64);
        let (mut scaled_total, mut scaled_mismatched, mut scaled_worst) = (0u64, 0usize, 0.0f64);
        for (i, (q, g)) in recs.queries.iter().zip(&got).enumerate() {
            let want = gather_brute_force(q, &recs.footprints, &recs.photons, RADII.map(f64::from), kernel);
            let (c, abs) = counts(q, &recs, kernel);
            assert_eq!(c[0] + c[1], want.footprints + want.photons);
            let (lo, hi) = (boxes_containing(q, &recs, 1e-6), boxes_containing(q, &recs, -1e-5));
            for m in 0..2 {
                assert!(
                    (lo[m]..=hi[m]).contains(&g.candidates[m]) && g.candidates[m] >= g.count(m),
                    "{kernel:?} query {i} map {m}: {} candidates, boxes containing the point {}..={}, {} contributions",
                    g.candidates[m],
                    lo[m],
                    hi[m],
                    g.count(m)
                );
                candidates += u64::from(g.candidates[m]);
            }
            let have = [g.count(0), g.count(1)];
            if have != c {
                assert!(near[i], "{kernel:?} query {i} {q:?}: device counts {have:?}, core {c:?}, no record on a boundary");
                mismatched += 1;
                continue;
            }
            total += u64::from(c[0] + c[1]);
            max_count = max_count.max(c[0] + c[1]);
            empty += (c == [0, 0]) as u32;
            for m in 0..2 {
                let (d, w) = (g.sum(m), want.per_map[m]);
                let bound = f64::from(c[m] + 5) * f64::from(f32::EPSILON / 2.0) * abs[m].max_element() + 1e-30;
                let err = (d - w).abs().max_element();
                assert!(err <= bound, "{kernel:?} query {i} map {m}: device {d:?}, core {w:?} ({} contributions; error {err:e} > {bound:e})", c[m]);
                worst_vs_bound = worst_vs_bound.max(err / bound);
                if c[m] == 1 {
                    single += 1;
                    single_exact += (d == w) as u32;
                }
                if w.max_element() > 0.0 {
                    worst_rel = worst_rel.max(err / w.max_element());
                }
            }
            if scales == 1 {
                assert!((1..SCALES).all(|k| g.scaled(k) == DVec3::ZERO), "{kernel:?} query {i}: one scale evaluated, totals {:?}", g.scaled);
                continue;
            }
            let want_s = gather_brute_force_scales(q, &recs.footprints, &recs.photons, RADII.map(f64::from), kernel);
            let (cs, abs_s) = scale_counts(q, &recs, kernel);
            for k in 1..SCALES {
                let (d, w) = (g.scaled(k), want_s.per_scale[k]);
                let bound = f64::from(cs[k] + 5) * f64::from(f32::EPSILON / 2.0) * abs_s[k] + 1e-30;
                let err = (d - w).abs().max_element();
                if err > bound {
                    assert!(near_scaled[i] || near[i], "{kernel:?} query {i} scale {k}: device {d:?}, core {w:?} ({} contributions; error {err:e} > {bound:e}), no record on a boundary", cs[k]);
                    scaled_mismatched += 1;
                    break;
                }
                assert_eq!(g.scaled[k - 1][3], 0.0);
                scaled_worst = scaled_worst.max(err / bound);
                scaled_total += u64::from(cs[k]);
            }
        }
        eprintln!(
            "arpa-vk gather hit group, {kernel:?}: {n} queries, {} footprints, {} photons: {total} contributions agree exactly (max {max_count} per query, {empty} queries with none; {candidates} candidates within the boxes' bounds), {mismatched} differ ({near_count} queries have a record on a boundary within 1e-5); worst relative sum error {worst_rel:.3e} ({:.2} of the bound), {single_exact} of {single} single-contribution sums bit-identical; trace {trace_s:.3} s",
            recs.footprints.len(),
            recs.photons.len(),
            worst_vs_bound
        );
        assert!(mismatched * 1000 <= n, "{mismatched} queries of {n} differ on a boundary");
        assert!(total > 5 * n as u64 && empty * 20 < n as u32, "too few contributions to test anything: {total}, {empty} empty");
        if scales > 1 {
            eprintln!(
                "  scales 1..{}: {scaled_total} contributions agree within the bound (worst {scaled_worst:.2} of it), {scaled_mismatched} queries differ ({} near a scaled boundary within 1e-5)",
                SCALES - 1,
                near_scaled.iter().filter(|&&b| b).count()
            );
            assert!(scaled_mismatched * 1000 <= n, "{scaled_mismatched} queries of {n} differ at a smaller scale");
            assert!(scaled_total > 2 * n as u64, "too few scaled contributions to test anything: {scaled_total}");
        }
    }
    eprintln!("arpa-vk gather hit group: setup {setup:.2} s, total {:.2} s", start.elapsed().as_secs_f64());

    let log = ctx.validation_log();
    let messages = ctx.validation_messages();
    assert!(messages.is_empty(), "validation: {messages:#?}");
    drop((bindings, pipeline, tlas, blases, fp_buf, ph_buf, q_buf, result_buf, params_buf, unused));
    drop(ctx);
    let messages = log.messages();
    assert!(messages.is_empty(), "validation while destroying: {messages:#?}");
}
