//! Tests of the Embree layer against the linked library: hits and misses at analytic
//! values, invalid input, determinism, point queries over box sets, and the canaries around
//! the 4.4 struct mirrors of `ffi.rs` (nothing may be written past them).

use super::ffi::{RTC_INVALID_GEOMETRY_ID, RTCHit44, RTCRay44, RTCRayHit44};
use super::*;
use core::mem::{offset_of, size_of};

/// Deterministic test RNG (SplitMix64).
struct Rng(u64);
impl Rng {
    fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in [lo, hi).
    fn f(&mut self, lo: f32, hi: f32) -> f32 {
        let x = (self.next_u64() >> 40) as f32 / (1u64 << 24) as f32;
        lo + (hi - lo) * x
    }
    fn v3(&mut self, lo: f32, hi: f32) -> [f32; 3] {
        [self.f(lo, hi), self.f(lo, hi), self.f(lo, hi)]
    }
}

fn device() -> Device {
    Device::new().expect("rtcNewDevice")
}

/// v0 = (0,0,0), v1 = (1,0,0), v2 = (0,1,0) in the z = 0 plane.
fn unit_triangle_scene(dev: &Device) -> EmbreeScene {
    let mut b = EmbreeSceneBuilder::new(dev).unwrap();
    let id = b
        .add_triangle_mesh(
            &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            &[[0, 1, 2]],
        )
        .unwrap();
    assert_eq!(id, 0);
    b.commit().unwrap()
}

#[test]
fn types_are_send_sync() {
    fn send_sync<T: Send + Sync>() {}
    fn send<T: Send>() {}
    send_sync::<Device>();
    send_sync::<EmbreeScene>();
    send::<EmbreeSceneBuilder>();
    send_sync::<EmbreeError>();
}

#[test]
fn linked_library_is_embree_4_4() {
    let dev = device();
    assert!(
        (40400..40500).contains(&dev.version()),
        "version {}",
        dev.version()
    );
}

#[test]
fn ray_hits_unit_triangle_at_analytic_t_u_v() {
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    // Hit point (0.25, 0.5, 0) = (1-u-v) v0 + u v1 + v v2 => u = 0.25, v = 0.5.
    // dir has length 2, origin at z = 2 => t = 1.
    let hit = scene
        .intersect([0.25, 0.5, 2.0], [0.0, 0.0, -2.0], 0.0, f32::INFINITY)
        .unwrap()
        .unwrap();
    assert!((hit.t - 1.0).abs() < 1e-6, "{hit:?}");
    assert!((hit.u - 0.25).abs() < 1e-6, "{hit:?}");
    assert!((hit.v - 0.5).abs() < 1e-6, "{hit:?}");
    assert_eq!((hit.prim_id, hit.geom_id), (0, 0));
    // ng = (v1 - v0) x (v2 - v0) = (0, 0, 1), unnormalised (|ng| = 2 * area = 1).
    assert_eq!(hit.ng, [0.0, 0.0, 1.0]);

    // Same triangle from below: the normal does not flip with the ray direction.
    let below = scene
        .intersect([0.25, 0.5, -1.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY)
        .unwrap()
        .unwrap();
    assert!((below.t - 1.0).abs() < 1e-6);
    assert_eq!(below.ng, [0.0, 0.0, 1.0]);
}

#[test]
fn closest_hit_among_meshes_and_primitives() {
    let dev = device();
    let mut b = EmbreeSceneBuilder::new(&dev).unwrap();
    // geometry 0: two triangles (a unit square) at z = 0; geometry 1: a larger
    // triangle at z = 5, v0 = (0,0,5), v1 = (2,0,5), v2 = (0,2,5).
    let g0 = b
        .add_triangle_mesh(
            &[
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0],
            ],
            &[[0, 1, 2], [0, 2, 3]],
        )
        .unwrap();
    let g1 = b
        .add_triangle_mesh(
            &[[0.0, 0.0, 5.0], [2.0, 0.0, 5.0], [0.0, 2.0, 5.0]],
            &[[0, 1, 2]],
        )
        .unwrap();
    assert_eq!((g0, g1), (0, 1));
    let scene = b.commit().unwrap();

    // From z = 10 downwards at (0.5, 0.25): the z = 5 triangle is closest, t = 5,
    // point (0.5, 0.25) = u * (2,0) + v * (0,2) => u = 0.25, v = 0.125.
    let h = scene
        .intersect([0.5, 0.25, 10.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
        .unwrap()
        .unwrap();
    assert_eq!(h.geom_id, 1);
    assert!(
        (h.t - 5.0).abs() < 1e-5 && (h.u - 0.25).abs() < 1e-6 && (h.v - 0.125).abs() < 1e-6,
        "{h:?}"
    );
    assert_eq!(h.ng, [0.0, 0.0, 4.0]);
    // From z = 1 downwards at (0.25, 0.75): only the square's 2nd triangle (0,2,3).
    let h = scene
        .intersect([0.25, 0.75, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
        .unwrap()
        .unwrap();
    assert_eq!((h.geom_id, h.prim_id), (0, 1));
    assert!((h.t - 1.0).abs() < 1e-6);
    // tnear skips the closer hit.
    let h = scene
        .intersect([0.5, 0.25, 10.0], [0.0, 0.0, -1.0], 6.0, f32::INFINITY)
        .unwrap()
        .unwrap();
    assert_eq!(h.geom_id, 0);
    assert!((h.t - 10.0).abs() < 1e-5);
}

#[test]
fn misses() {
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    // Outside the triangle (u + v > 1).
    assert_eq!(
        scene
            .intersect([0.75, 0.75, 1.0], [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
            .unwrap(),
        None
    );
    // Pointing away.
    assert_eq!(
        scene
            .intersect([0.25, 0.25, 1.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY)
            .unwrap(),
        None
    );
    // Segment ends before the triangle (hit would be at t = 1).
    assert_eq!(
        scene
            .intersect([0.25, 0.25, 1.0], [0.0, 0.0, -1.0], 0.0, 0.99)
            .unwrap(),
        None
    );
    // Segment starts after it.
    assert_eq!(
        scene
            .intersect([0.25, 0.25, 1.0], [0.0, 0.0, -1.0], 1.01, 5.0)
            .unwrap(),
        None
    );
    // Parallel to the plane.
    assert_eq!(
        scene
            .intersect([0.25, 0.25, 1.0], [1.0, 0.0, 0.0], 0.0, f32::INFINITY)
            .unwrap(),
        None
    );
}

#[test]
fn occluded_matches_segment() {
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    let (o, d) = ([0.25, 0.25, 1.0], [0.0, 0.0, -1.0]);
    assert!(scene.occluded(o, d, 0.0, f32::INFINITY).unwrap());
    assert!(scene.occluded(o, d, 0.0, 1.01).unwrap());
    assert!(!scene.occluded(o, d, 0.0, 0.99).unwrap());
    assert!(
        !scene
            .occluded(o, [0.0, 0.0, 1.0], 0.0, f32::INFINITY)
            .unwrap()
    );
    assert!(
        !scene
            .occluded([0.75, 0.75, 1.0], d, 0.0, f32::INFINITY)
            .unwrap()
    );
}

#[test]
fn invalid_inputs_are_errors_not_ub() {
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    let inf = f32::INFINITY;
    let bad = [
        scene.intersect([f32::NAN, 0.0, 0.0], [0.0, 0.0, 1.0], 0.0, inf),
        scene.intersect([0.0; 3], [0.0; 3], 0.0, inf),
        scene.intersect([0.0; 3], [0.0, 0.0, 1.0], -1.0, inf),
        scene.intersect([0.0; 3], [0.0, 0.0, 1.0], 2.0, 1.0),
        scene.intersect([0.0; 3], [0.0, 0.0, 1.0], f32::NAN, inf),
        scene.intersect([0.0; 3], [0.0, 0.0, 1.0], 0.0, f32::NAN),
    ];
    for r in bad {
        assert!(matches!(r, Err(EmbreeError::InvalidInput(_))), "{r:?}");
    }
    assert!(matches!(
        scene.occluded([0.0; 3], [inf, 0.0, 0.0], 0.0, inf),
        Err(EmbreeError::InvalidInput(_))
    ));
    assert!(matches!(
        scene.point_query([0.0; 3], -1.0, |_| {}),
        Err(EmbreeError::InvalidInput(_))
    ));

    let mut b = EmbreeSceneBuilder::new(&dev).unwrap();
    let v = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    assert!(matches!(
        b.add_triangle_mesh(&v, &[[0, 1, 3]]),
        Err(EmbreeError::InvalidInput(_))
    ));
    assert!(matches!(
        b.add_triangle_mesh(&v, &[]),
        Err(EmbreeError::InvalidInput(_))
    ));
    assert!(matches!(
        b.add_triangle_mesh(
            &[[0.0, f32::NAN, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
            &[[0, 1, 2]]
        ),
        Err(EmbreeError::InvalidInput(_))
    ));
    let inverted = EmbreeBox {
        lower: [1.0, 0.0, 0.0],
        upper: [0.0, 1.0, 1.0],
    };
    assert!(matches!(
        b.add_boxes(&[inverted]),
        Err(EmbreeError::InvalidInput(_))
    ));
    // The builder is still usable after rejected input.
    assert_eq!(b.add_triangle_mesh(&v, &[[0, 1, 2]]).unwrap(), 0);
    assert!(b.commit().is_ok());

    assert!(matches!(
        Device::with_config("threads=1\0"),
        Err(EmbreeError::InvalidInput(_))
    ));
    // Embree rejects a malformed config at rtcNewDevice: reported as an error value.
    // (Embree ignores unknown options, so they are not tested here.)
    let err = Device::with_config("threads=abc").unwrap_err();
    assert!(matches!(err, EmbreeError::DeviceCreation(_)), "{err:?}");
}

// ------------------------------------------------------------------ ABI / canary

/// A 4.4-layout ray/hit followed directly by canary bytes: anything the library writes
/// past the 96-byte `RTCRayHit44` lands in `canary`.
#[repr(C, align(16))]
struct Guarded44 {
    rayhit: RTCRayHit44,
    canary: [u8; 64],
}

#[test]
fn rtcintersect1_writes_nothing_past_the_4_4_rayhit() {
    assert_eq!(offset_of!(Guarded44, canary), size_of::<RTCRayHit44>());
    assert_eq!(size_of::<RTCRayHit44>(), 96);
    assert_eq!(size_of::<RTCHit44>(), 48);
    // The trap this guards against: the 4.2 bindings are 16 bytes too small.
    assert_eq!(size_of::<embree4_sys::RTCRayHit>(), 80);
    assert_eq!(size_of::<embree4_sys::RTCHit>(), 32);

    let dev = device();
    let scene = unit_triangle_scene(&dev);
    let mut g = Guarded44 {
        rayhit: RTCRayHit44::default(),
        canary: [0xA5; 64],
    };
    g.rayhit.ray = RTCRay44 {
        org_x: 0.25,
        org_y: 0.25,
        org_z: 1.0,
        dir_z: -1.0,
        tfar: f32::INFINITY,
        mask: u32::MAX,
        ..Default::default()
    };
    // Poison the 4.4-only field and the tail padding: the library must overwrite
    // instPrimID (proving it uses the 4.4 layout) and must not touch the canary.
    g.rayhit.hit.instPrimID = [0xA5A5_A5A5];
    g.rayhit.hit._pad = [0xA5A5_A5A5; 3];
    // SAFETY: initialised 4.4 ray/hit; the pointer is derived from the whole `g`.
    unsafe { scene.intersect_raw(core::ptr::addr_of_mut!(g).cast::<RTCRayHit44>()) };

    assert_eq!(g.rayhit.hit.geomID, 0, "expected a hit");
    assert!((g.rayhit.ray.tfar - 1.0).abs() < 1e-6);
    assert_eq!(g.rayhit.hit.instID, [RTC_INVALID_GEOMETRY_ID]);
    assert_eq!(
        g.rayhit.hit.instPrimID,
        [RTC_INVALID_GEOMETRY_ID],
        "Embree 4.4 writes hit.instPrimID at byte 80 of RTCRayHit (just past a 4.2 RTCRayHit)"
    );
    assert!(
        g.canary.iter().all(|&b| b == 0xA5),
        "library wrote past RTCRayHit44: {:02x?}",
        g.canary
    );
}

#[test]
fn safe_api_leaves_no_trace_past_rayhit_across_many_rays() {
    // The safe path (`EmbreeScene::intersect`) uses the same struct; run many hits/misses
    // to exercise different traversal paths and let a stack overrun show up as a crash or
    // wrong results in the canary test above.
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    let mut rng = Rng(7);
    for _ in 0..10_000 {
        let o = [rng.f(-0.5, 1.5), rng.f(-0.5, 1.5), 1.0];
        let h = scene
            .intersect(o, [0.0, 0.0, -1.0], 0.0, f32::INFINITY)
            .unwrap();
        let inside = o[0] >= 0.0 && o[1] >= 0.0 && o[0] + o[1] <= 1.0;
        // Points within 1e-5 of an edge may go either way.
        let near_edge =
            o[0].abs() < 1e-5 || o[1].abs() < 1e-5 || (o[0] + o[1] - 1.0).abs() < 1e-5;
        if !near_edge {
            assert_eq!(h.is_some(), inside, "{o:?}");
        }
    }
}

/// A 4.4-layout packet followed directly by canary bytes.
#[repr(C, align(64))]
struct GuardedPacket<P> {
    packet: P,
    canary: [u8; 128],
}

/// `rtcIntersect8/16` must fill `instPrimID` (the 4.4 layout) and write nothing past
/// the 4.4 packet structs, on hits and misses in all lanes (invalid lanes untouched).
#[test]
fn packet_intersect_writes_nothing_past_the_4_4_packets() {
    use super::ffi::{RTCRayHit8_44, RTCRayHit16_44};
    assert_eq!(size_of::<embree4_sys::RTCRayHit8>() + 32, size_of::<RTCRayHit8_44>());
    assert_eq!(size_of::<embree4_sys::RTCRayHit16>() + 64, size_of::<RTCRayHit16_44>());
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    macro_rules! check {
        ($ty:ty, $n:literal, $f:ident) => {{
            assert_eq!(offset_of!(GuardedPacket<$ty>, canary), size_of::<$ty>());
            let mut g = GuardedPacket { packet: <$ty>::default(), canary: [0xA5; 128] };
            let mut valid = [0i32; $n];
            for i in 0..$n {
                // Even lanes hit the triangle, odd lanes miss it; the last lane is off.
                g.packet.org_x[i] = if i % 2 == 0 { 0.25 } else { 2.0 };
                g.packet.org_y[i] = 0.25;
                g.packet.org_z[i] = 1.0;
                g.packet.dir_x[i] = 0.0;
                g.packet.dir_y[i] = 0.0;
                g.packet.dir_z[i] = -1.0;
                g.packet.tfar[i] = f32::INFINITY;
                g.packet.instPrimID[0][i] = 0xA5A5_A5A5;
                valid[i] = if i + 1 < $n { -1 } else { 0 };
            }
            // SAFETY: initialised 4.4 packet; the pointer is derived from the whole `g`.
            unsafe { scene.$f(&valid, core::ptr::addr_of_mut!(g).cast::<$ty>()) };
            for i in 0..$n - 1 {
                let hit = i % 2 == 0;
                assert_eq!(g.packet.geomID[i] == 0, hit, "lane {i}");
                assert_eq!(g.packet.geomID[i] == RTC_INVALID_GEOMETRY_ID, !hit, "lane {i}");
                if hit {
                    assert!((g.packet.tfar[i] - 1.0).abs() < 1e-6);
                    assert_eq!(
                        g.packet.instPrimID[0][i],
                        RTC_INVALID_GEOMETRY_ID,
                        "Embree 4.4 writes hit.instPrimID on a hit (lane {i})"
                    );
                }
            }
            assert_eq!(g.packet.geomID[$n - 1], RTC_INVALID_GEOMETRY_ID, "inactive lane");
            assert!(g.canary.iter().all(|&b| b == 0xA5), "library wrote past the packet: {:02x?}", g.canary);
        }};
    }
    check!(RTCRayHit8_44, 8, intersect8_raw);
    check!(RTCRayHit16_44, 16, intersect16_raw);
}

/// The packet queries answer exactly (bit for bit) what `rtcIntersect1` answers, on
/// random rays through a small closed mesh, with partly filled packets.
#[test]
fn packet_intersect_matches_single_rays_bit_for_bit() {
    let dev = device();
    let mut b = EmbreeSceneBuilder::new(&dev).unwrap();
    // A tetrahedron and a ground triangle.
    b.add_triangle_mesh(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        &[[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
    )
    .unwrap();
    b.add_triangle_mesh(&[[-3.0, -1.0, -3.0], [3.0, -1.0, -3.0], [0.0, -1.0, 3.0]], &[[0, 1, 2]])
        .unwrap();
    let scene = b.commit().unwrap();
    let mut rng = Rng(11);
    let (mut hits, mut misses) = (0, 0);
    for round in 0..400 {
        let n = 1 + round % 16;
        let rays: Vec<PacketRay> = (0..n)
            .map(|_| PacketRay {
                origin: rng.v3(-2.0, 2.0),
                dir: rng.v3(-1.0, 1.0),
                tnear: 0.0,
                tfar: if rng.f(0.0, 1.0) < 0.2 { rng.f(0.0, 3.0) } else { f32::INFINITY },
            })
            .collect();
        let mut packet = [None; 16];
        if n <= 8 && round % 2 == 0 {
            scene.intersect8(&rays, &mut packet).unwrap();
        } else {
            scene.intersect16(&rays, &mut packet).unwrap();
        }
        for (r, p) in rays.iter().zip(&packet) {
            let one = scene.intersect(r.origin, r.dir, r.tnear, r.tfar).unwrap();
            match (one, p) {
                (None, None) => misses += 1,
                (Some(a), Some(b)) => {
                    hits += 1;
                    assert_eq!(
                        (a.t.to_bits(), a.u.to_bits(), a.v.to_bits(), a.prim_id, a.geom_id),
                        (b.t.to_bits(), b.u.to_bits(), b.v.to_bits(), b.prim_id, b.geom_id),
                        "{r:?}"
                    );
                }
                _ => panic!("packet and single ray disagree on {r:?}: {one:?} vs {p:?}"),
            }
        }
    }
    assert!(hits > 300 && misses > 300, "{hits} hits, {misses} misses");
}

#[test]
fn packet_intersect_rejects_an_invalid_ray() {
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    let mut hits = [None; 8];
    let ok = PacketRay { origin: [0.25, 0.25, 1.0], dir: [0.0, 0.0, -1.0], tnear: 0.0, tfar: f32::INFINITY };
    let bad = PacketRay { dir: [f32::NAN, 0.0, -1.0], ..ok };
    let err = scene.intersect8(&[ok, bad], &mut hits).unwrap_err();
    assert!(matches!(err, EmbreeError::InvalidInput(_)), "{err:?}");
}

/// Demonstration only (run with `--ignored --nocapture`): what happens with the 4.2
/// `RTCRayHit` from `embree4-sys` against the 4.4 library. On a hit the library writes
/// `hit.instPrimID[0] = 0xFFFFFFFF` at byte offset 80, so the first 4 canary bytes right
/// after the 80-byte 4.2 struct become `ff ff ff ff` (the test prints the offsets written
/// past it). Without the canary, those 4 bytes belong to whatever the caller placed after
/// the struct: silent memory corruption.
#[test]
#[ignore = "demonstrates the 4.2-struct overrun; not a pass/fail check"]
fn demo_unpadded_4_2_rayhit_is_overrun() {
    #[repr(C)]
    struct Guarded42 {
        rayhit: embree4_sys::RTCRayHit,
        canary: [u8; 64],
    }
    let dev = device();
    let scene = unit_triangle_scene(&dev);
    let mut g = Guarded42 {
        // SAFETY: all-zero is a valid value of the plain-old-data 4.2 struct.
        rayhit: unsafe { core::mem::zeroed() },
        canary: [0xA5; 64],
    };
    g.rayhit.ray.org_x = 0.25;
    g.rayhit.ray.org_y = 0.25;
    g.rayhit.ray.org_z = 1.0;
    g.rayhit.ray.dir_z = -1.0;
    g.rayhit.ray.tfar = f32::INFINITY;
    g.rayhit.ray.mask = u32::MAX;
    g.rayhit.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    g.rayhit.hit.instID = [RTC_INVALID_GEOMETRY_ID];
    // SAFETY (of this demo): the pointer covers `g` entirely, so the overrun lands in
    // our own canary, not in foreign memory.
    unsafe {
        embree4_sys::rtcIntersect1(
            scene.raw_for_tests(),
            core::ptr::addr_of_mut!(g).cast::<embree4_sys::RTCRayHit>(),
            core::ptr::null_mut(),
        )
    };
    let offset = offset_of!(Guarded42, canary);
    println!(
        "4.2 RTCRayHit size {}, canary at {offset}",
        size_of::<embree4_sys::RTCRayHit>()
    );
    println!(
        "hit geomID {} tfar {}",
        g.rayhit.hit.geomID, g.rayhit.ray.tfar
    );
    println!("canary after call: {:02x?}", &g.canary[..16]);
    let touched: Vec<usize> = (0..64)
        .filter(|&i| g.canary[i] != 0xA5)
        .map(|i| i + offset)
        .collect();
    println!("bytes written past the 4.2 struct (offsets): {touched:?}");
}

// ------------------------------------------------------------------ determinism

fn random_soup(seed: u64, n: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let mut rng = Rng(seed);
    let mut v = Vec::with_capacity(3 * n);
    let mut idx = Vec::with_capacity(n);
    for i in 0..n {
        let c = rng.v3(-10.0, 10.0);
        for _ in 0..3 {
            let d = rng.v3(-1.0, 1.0);
            v.push([c[0] + d[0], c[1] + d[1], c[2] + d[2]]);
        }
        let k = 3 * i as u32;
        idx.push([k, k + 1, k + 2]);
    }
    (v, idx)
}

fn trace_all(scene: &EmbreeScene, rays: &[([f32; 3], [f32; 3])]) -> Vec<(Option<Hit>, bool)> {
    rays.iter()
        .map(|&(o, d)| {
            (
                scene.intersect(o, d, 0.0, f32::INFINITY).unwrap(),
                scene.occluded(o, d, 0.0, f32::INFINITY).unwrap(),
            )
        })
        .collect()
}

#[test]
fn deterministic_across_builds_runs_and_threads() {
    let dev = device();
    let (v, idx) = random_soup(42, 3000);
    let build = |q| {
        let mut b = EmbreeSceneBuilder::new(&dev).unwrap().build_quality(q);
        b.add_triangle_mesh(&v, &idx).unwrap();
        b.commit().unwrap()
    };
    let mut rng = Rng(1);
    let rays: Vec<_> = (0..4000)
        .map(|_| {
            let o = rng.v3(-15.0, 15.0);
            let mut d = rng.v3(-1.0, 1.0);
            if d == [0.0; 3] {
                d = [0.0, 0.0, 1.0];
            }
            (o, d)
        })
        .collect();

    let s1 = build(BuildQuality::High);
    let s2 = build(BuildQuality::High);
    let r1 = trace_all(&s1, &rays);
    let r1b = trace_all(&s1, &rays);
    let r2 = trace_all(&s2, &rays);
    let bits = |r: &[(Option<Hit>, bool)]| -> Vec<_> {
        r.iter()
            .map(|(h, o)| {
                (
                    h.map(|h| {
                        (
                            h.t.to_bits(),
                            h.u.to_bits(),
                            h.v.to_bits(),
                            h.prim_id,
                            h.geom_id,
                            h.ng.map(f32::to_bits),
                        )
                    }),
                    *o,
                )
            })
            .collect()
    };
    assert_eq!(
        bits(&r1),
        bits(&r1b),
        "same scene, same rays, different results"
    );
    assert_eq!(bits(&r1), bits(&r2), "two identical builds disagree");
    let hits = r1.iter().filter(|(h, _)| h.is_some()).count();
    assert!(
        hits > 100 && hits < rays.len(),
        "degenerate test: {hits} hits"
    );
    // occluded == (closest hit exists) for the same unbounded ray.
    assert!(r1.iter().all(|(h, o)| h.is_some() == *o));

    // Concurrent queries on a shared committed scene give the same answers.
    let per_thread: Vec<Vec<(Option<Hit>, bool)>> = std::thread::scope(|s| {
        let hs: Vec<_> = (0..4).map(|_| s.spawn(|| trace_all(&s1, &rays))).collect();
        hs.into_iter().map(|h| h.join().unwrap()).collect()
    });
    for r in &per_thread {
        assert_eq!(bits(r), bits(&r1));
    }

    // A different build quality gives a different BVH but the same closest primitive.
    let s3 = build(BuildQuality::Medium);
    let r3 = trace_all(&s3, &rays);
    let ids = |r: &[(Option<Hit>, bool)]| -> Vec<_> {
        r.iter().map(|(h, _)| h.map(|h| h.prim_id)).collect()
    };
    assert_eq!(ids(&r1), ids(&r3));
}

// ------------------------------------------------------------------ boxes / point queries

fn random_boxes(seed: u64, n: usize) -> Vec<EmbreeBox> {
    let mut rng = Rng(seed);
    (0..n)
        .map(|_| {
            let c = rng.v3(0.0, 10.0);
            let h = rng.v3(0.05, 1.0);
            EmbreeBox {
                lower: [c[0] - h[0], c[1] - h[1], c[2] - h[2]],
                upper: [c[0] + h[0], c[1] + h[1], c[2] + h[2]],
            }
        })
        .collect()
}

#[test]
fn point_query_over_1000_boxes_matches_brute_force() {
    let dev = device();
    let boxes = random_boxes(3, 1000);
    let mut b = EmbreeSceneBuilder::new(&dev)
        .unwrap()
        .build_quality(BuildQuality::Medium);
    // A triangle mesh alongside the boxes: point queries report it too, but
    // `boxes_containing` only returns boxes, and rays ignore the boxes.
    let tri = b
        .add_triangle_mesh(
            &[[0.0, 0.0, 20.0], [30.0, 0.0, 20.0], [0.0, 30.0, 20.0]],
            &[[0, 1, 2]],
        )
        .unwrap();
    let gid = b.add_boxes(&boxes).unwrap();
    assert_eq!((tri, gid), (0, 1));
    let scene = b.commit().unwrap();
    assert_eq!(scene.boxes(gid).unwrap(), &boxes[..]);
    assert!(scene.boxes(tri).is_none());

    let mut rng = Rng(99);
    let mut total_found = 0usize;
    let mut total_candidates = 0usize;
    for _ in 0..2000 {
        let p = rng.v3(-0.5, 10.5);
        let expected: Vec<u32> = boxes
            .iter()
            .enumerate()
            .filter(|(_, b)| b.contains(p))
            .map(|(i, _)| i as u32)
            .collect();
        let got = scene.boxes_containing(p).unwrap();
        assert!(got.iter().all(|c| c.geom_id == gid));
        let got: Vec<u32> = got.iter().map(|c| c.prim_id).collect();
        assert_eq!(got, expected, "point {p:?}");
        total_found += got.len();
        scene
            .point_query(p, 0.0, |c| {
                if c.geom_id == gid {
                    total_candidates += 1
                }
            })
            .unwrap();
    }
    assert!(
        total_found > 1000,
        "degenerate test: {total_found} containments"
    );
    // The BVH prunes: far fewer candidates than 2000 points x 1000 boxes.
    assert!(
        total_candidates < 2000 * 1000 / 20,
        "{total_candidates} candidates"
    );
    assert!(total_candidates >= total_found);

    // Boxes are invisible to rays: this ray passes through many boxes and hits the
    // triangle at z = 20.
    let h = scene
        .intersect([1.0, 1.0, -5.0], [0.0, 0.0, 1.0], 0.0, f32::INFINITY)
        .unwrap()
        .unwrap();
    assert_eq!(h.geom_id, tri);
    assert!((h.t - 25.0).abs() < 1e-4);
}

#[test]
fn point_query_with_radius_reports_overlapping_boxes() {
    let dev = device();
    let boxes = [
        EmbreeBox {
            lower: [0.0, 0.0, 0.0],
            upper: [1.0, 1.0, 1.0],
        },
        EmbreeBox {
            lower: [3.0, 0.0, 0.0],
            upper: [4.0, 1.0, 1.0],
        },
    ];
    let mut b = EmbreeSceneBuilder::new(&dev).unwrap();
    let gid = b.add_boxes(&boxes).unwrap();
    let scene = b.commit().unwrap();
    let collect = |p, r| {
        let mut v = Vec::new();
        scene.point_query(p, r, |c| v.push(c)).unwrap();
        v.sort();
        v
    };
    // (2, 0.5, 0.5) is at distance 1 from both boxes.
    assert!(collect([2.0, 0.5, 0.5], 0.5).is_empty());
    let both = collect([2.0, 0.5, 0.5], 1.5);
    assert_eq!(
        both,
        vec![
            PointQueryCandidate {
                geom_id: gid,
                prim_id: 0
            },
            PointQueryCandidate {
                geom_id: gid,
                prim_id: 1
            }
        ]
    );
}

#[test]
fn panic_in_point_query_callback_propagates_after_embree_returns() {
    let dev = device();
    let mut b = EmbreeSceneBuilder::new(&dev).unwrap();
    b.add_boxes(&random_boxes(5, 100)).unwrap();
    let scene = b.commit().unwrap();
    let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
        scene
            .point_query([5.0, 5.0, 5.0], 3.0, |_| panic!("boom"))
            .unwrap();
    }));
    assert!(r.is_err());
    // The scene is still usable.
    assert!(scene.boxes_containing([5.0, 5.0, 5.0]).is_ok());
}
