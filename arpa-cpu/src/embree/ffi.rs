//! Hand-written mirrors of the Embree **4.4** structs whose layout differs from the Embree
//! 4.2 headers that `embree4-sys` 0.0.12 generates its bindings from, plus the few extern
//! declarations whose 4.2 signatures are unsound against a 4.4 library.
//!
//! # Why this module exists (the 4.2-headers / 4.4-library trap)
//!
//! `embree4-sys` 0.0.12 runs bindgen on the Embree 4.2.0 headers it bundles, but the
//! library we link (`scripts/install-embree4.sh`) is Embree 4.4.0, built with the default
//! `EMBREE_GEOMETRY_INSTANCE_ARRAY=ON` and `RTC_MAX_INSTANCE_LEVEL_COUNT == 1`. Since 4.3,
//! with `RTC_GEOMETRY_INSTANCE_ARRAY` defined, `RTCHit`, `RTCRayQueryContext` and
//! `RTCPointQueryContext` carry an extra `instPrimID[RTC_MAX_INSTANCE_LEVEL_COUNT]` array:
//!
//! | struct (L = 1)                 | 4.2 (bindgen) | 4.4 (library)            |
//! |--------------------------------|---------------|--------------------------|
//! | `RTCRay` (align 16)            | 48 bytes      | 48 bytes (unchanged)     |
//! | `RTCHit` (align 16)            | 32 bytes      | 48 bytes                 |
//! | `RTCRayHit`                    | 80 bytes      | 96 bytes                 |
//! | `RTCRayHit8` / `RTCRayHit16`   | 640 / 1280    | 672 / 1344 (`instPrimID[1][N]` after `instID`) |
//! | `RTCPointQueryContext` (al.16) | 144 bytes, `instStackSize` at 132 | 144 bytes, `instPrimID` at 132, `instStackSize` at 136 |
//!
//! Passing a 4.2 `RTCRayHit` (80 bytes) to the 4.4 `rtcIntersect1` makes the library write
//! `hit.instPrimID[0]` at byte offset 80 (hit offset 32), i.e. just past the end of the
//! caller's 80-byte object (the packets likewise, `4·N` bytes past). The canary tests in
//! `embree/tests.rs` check that nothing is written past [`RTCRayHit44`], [`RTCRayHit8_44`]
//! and [`RTCRayHit16_44`].
//!
//! Layout source: `include/embree4/rtcore_ray.h` and `rtcore_common.h` at the Embree
//! `v4.4.0` tag; `kernels/rtcore_config.h.in` (`RTC_GEOMETRY_INSTANCE_ARRAY` follows the
//! CMake option `EMBREE_GEOMETRY_INSTANCE_ARRAY`, default ON). The sizes and offsets are
//! checked at compile time below.
//!
//! The argument structs `RTCIntersectArguments` / `RTCOccludedArguments` are not used
//! (arpa-cpu passes `NULL`, so Embree uses its defaults), which also sidesteps their
//! `RTC_MIN_WIDTH`-dependent layout. The callback argument structs used here
//! (`RTCBoundsFunctionArguments`, `RTCPointQueryFunctionArguments`, `RTCBounds`,
//! `RTCPointQuery`) are identical in 4.2 and 4.4 and are taken from `embree4-sys`.

#![allow(non_snake_case, non_camel_case_types)]

use core::ffi::{c_char, c_void};
use core::mem::{offset_of, size_of};

/// `RTC_INVALID_GEOMETRY_ID` (`(unsigned)-1`).
pub const RTC_INVALID_GEOMETRY_ID: u32 = u32::MAX;

/// `RTC_MAX_INSTANCE_LEVEL_COUNT` of the linked library (the Embree default).
pub const MAX_INSTANCE_LEVEL_COUNT: usize = 1;

/// Embree 4.4 `struct RTC_ALIGN(16) RTCRay` (unchanged since 4.0).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCRay44 {
    pub org_x: f32,
    pub org_y: f32,
    pub org_z: f32,
    pub tnear: f32,
    pub dir_x: f32,
    pub dir_y: f32,
    pub dir_z: f32,
    pub time: f32,
    pub tfar: f32,
    pub mask: u32,
    pub id: u32,
    pub flags: u32,
}

/// Embree 4.4 `struct RTC_ALIGN(16) RTCHit` with `RTC_GEOMETRY_INSTANCE_ARRAY` defined and
/// `RTC_MAX_INSTANCE_LEVEL_COUNT == 1`; the C compiler's tail padding is spelled out as
/// `_pad` so every byte of the 48-byte object is accounted for.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug)]
pub struct RTCHit44 {
    pub Ng_x: f32,
    pub Ng_y: f32,
    pub Ng_z: f32,
    pub u: f32,
    pub v: f32,
    pub primID: u32,
    pub geomID: u32,
    pub instID: [u32; MAX_INSTANCE_LEVEL_COUNT],
    /// New in 4.3 (instance arrays): written by `rtcIntersect1` on every hit.
    pub instPrimID: [u32; MAX_INSTANCE_LEVEL_COUNT],
    pub _pad: [u32; 3],
}

impl Default for RTCHit44 {
    fn default() -> Self {
        Self {
            Ng_x: 0.0,
            Ng_y: 0.0,
            Ng_z: 0.0,
            u: 0.0,
            v: 0.0,
            primID: RTC_INVALID_GEOMETRY_ID,
            geomID: RTC_INVALID_GEOMETRY_ID,
            instID: [RTC_INVALID_GEOMETRY_ID; MAX_INSTANCE_LEVEL_COUNT],
            instPrimID: [RTC_INVALID_GEOMETRY_ID; MAX_INSTANCE_LEVEL_COUNT],
            _pad: [0; 3],
        }
    }
}

/// Embree 4.4 `struct RTCRayHit` (96 bytes, 16-byte aligned).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCRayHit44 {
    pub ray: RTCRay44,
    pub hit: RTCHit44,
}

/// Embree 4.4 `struct RTC_ALIGN(16) RTCPointQuery` (unchanged since 4.0).
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug, Default)]
pub struct RTCPointQuery44 {
    pub x: f32,
    pub y: f32,
    pub z: f32,
    pub time: f32,
    pub radius: f32,
}

/// Embree 4.4 `struct RTC_ALIGN(16) RTCPointQueryContext` with `RTC_GEOMETRY_INSTANCE_ARRAY`
/// and `RTC_MAX_INSTANCE_LEVEL_COUNT == 1`. The library reads `instStackSize` at offset 136;
/// the 4.2 binding has it at 132, where 4.4 keeps `instPrimID`.
#[repr(C, align(16))]
#[derive(Clone, Copy, Debug)]
pub struct RTCPointQueryContext44 {
    pub world2inst: [[f32; 16]; MAX_INSTANCE_LEVEL_COUNT],
    pub inst2world: [[f32; 16]; MAX_INSTANCE_LEVEL_COUNT],
    pub instID: [u32; MAX_INSTANCE_LEVEL_COUNT],
    pub instPrimID: [u32; MAX_INSTANCE_LEVEL_COUNT],
    pub instStackSize: u32,
    pub _pad: [u32; 1],
}

impl RTCPointQueryContext44 {
    /// Equivalent of the header's inline `rtcInitPointQueryContext` (4.4 version).
    pub fn new() -> Self {
        Self {
            world2inst: [[0.0; 16]; MAX_INSTANCE_LEVEL_COUNT],
            inst2world: [[0.0; 16]; MAX_INSTANCE_LEVEL_COUNT],
            instID: [RTC_INVALID_GEOMETRY_ID; MAX_INSTANCE_LEVEL_COUNT],
            instPrimID: [RTC_INVALID_GEOMETRY_ID; MAX_INSTANCE_LEVEL_COUNT],
            instStackSize: 0,
            _pad: [0],
        }
    }
}

// Compile-time layout checks against the Embree 4.4 C headers (x86_64, L = 1).
const _: () = {
    assert!(size_of::<RTCRay44>() == 48);
    assert!(offset_of!(RTCRay44, tfar) == 32);
    assert!(offset_of!(RTCRay44, flags) == 44);

    assert!(size_of::<RTCHit44>() == 48);
    assert!(offset_of!(RTCHit44, Ng_x) == 0);
    assert!(offset_of!(RTCHit44, u) == 12);
    assert!(offset_of!(RTCHit44, v) == 16);
    assert!(offset_of!(RTCHit44, primID) == 20);
    assert!(offset_of!(RTCHit44, geomID) == 24);
    assert!(offset_of!(RTCHit44, instID) == 28);
    assert!(offset_of!(RTCHit44, instPrimID) == 32);

    assert!(size_of::<RTCRayHit44>() == 96);
    assert!(align_of::<RTCRayHit44>() == 16);
    assert!(offset_of!(RTCRayHit44, hit) == 48);

    assert!(size_of::<RTCPointQuery44>() == 32);
    assert!(size_of::<RTCPointQueryContext44>() == 144);
    assert!(offset_of!(RTCPointQueryContext44, instID) == 128);
    assert!(offset_of!(RTCPointQueryContext44, instPrimID) == 132);
    assert!(offset_of!(RTCPointQueryContext44, instStackSize) == 136);

    // The pieces that are shared with the 4.2 bindings must agree with them.
    assert!(size_of::<embree4_sys::RTCRay>() == size_of::<RTCRay44>());
    assert!(size_of::<embree4_sys::RTCPointQuery>() == size_of::<RTCPointQuery44>());
    assert!(size_of::<embree4_sys::RTCBounds>() == 32);
};

/// `RTCErrorFunction` with the error code as a plain `u32`: the library may report codes
/// that the 4.2 `RTCError` Rust enum has no variant for (e.g. 7,
/// `RTC_ERROR_LEVEL_ZERO_RAYTRACING_SUPPORT_MISSING`), which would be UB as a Rust enum.
pub type ErrorFunction44 =
    Option<unsafe extern "C" fn(user_ptr: *mut c_void, code: u32, message: *const c_char)>;

#[allow(clashing_extern_declarations)]
unsafe extern "C" {
    /// `enum RTCError rtcGetDeviceError(RTCDevice)`, returning the raw code (see
    /// [`ErrorFunction44`]).
    pub fn rtcGetDeviceError(device: embree4_sys::RTCDevice) -> u32;

    /// `void rtcSetDeviceErrorFunction(RTCDevice, RTCErrorFunction, void*)` taking
    /// [`ErrorFunction44`].
    pub fn rtcSetDeviceErrorFunction(
        device: embree4_sys::RTCDevice,
        error: ErrorFunction44,
        user_ptr: *mut c_void,
    );
}

/// Defines the Embree 4.4 SOA packet `struct RTCRayHitN` (`RTCRayN` + `RTCHitN` with
/// `instPrimID[L][N]`, new in 4.3): `9·N` words of hit instead of the 4.2 binding's `8·N`.
macro_rules! packet {
    ($(#[$m:meta])* $name:ident, $n:literal, $align:literal) => {
        $(#[$m])*
        #[repr(C, align($align))]
        #[derive(Clone, Copy, Debug)]
        pub struct $name {
            pub org_x: [f32; $n],
            pub org_y: [f32; $n],
            pub org_z: [f32; $n],
            pub tnear: [f32; $n],
            pub dir_x: [f32; $n],
            pub dir_y: [f32; $n],
            pub dir_z: [f32; $n],
            pub time: [f32; $n],
            pub tfar: [f32; $n],
            pub mask: [u32; $n],
            pub id: [u32; $n],
            pub flags: [u32; $n],
            pub Ng_x: [f32; $n],
            pub Ng_y: [f32; $n],
            pub Ng_z: [f32; $n],
            pub u: [f32; $n],
            pub v: [f32; $n],
            pub primID: [u32; $n],
            pub geomID: [u32; $n],
            pub instID: [[u32; $n]; MAX_INSTANCE_LEVEL_COUNT],
            /// New in 4.3 (instance arrays): written on every hit.
            pub instPrimID: [[u32; $n]; MAX_INSTANCE_LEVEL_COUNT],
        }

        impl Default for $name {
            fn default() -> Self {
                Self {
                    org_x: [0.0; $n],
                    org_y: [0.0; $n],
                    org_z: [0.0; $n],
                    tnear: [0.0; $n],
                    dir_x: [0.0; $n],
                    dir_y: [0.0; $n],
                    dir_z: [1.0; $n],
                    time: [0.0; $n],
                    tfar: [0.0; $n],
                    mask: [u32::MAX; $n],
                    id: [0; $n],
                    flags: [0; $n],
                    Ng_x: [0.0; $n],
                    Ng_y: [0.0; $n],
                    Ng_z: [0.0; $n],
                    u: [0.0; $n],
                    v: [0.0; $n],
                    primID: [RTC_INVALID_GEOMETRY_ID; $n],
                    geomID: [RTC_INVALID_GEOMETRY_ID; $n],
                    instID: [[RTC_INVALID_GEOMETRY_ID; $n]; MAX_INSTANCE_LEVEL_COUNT],
                    instPrimID: [[RTC_INVALID_GEOMETRY_ID; $n]; MAX_INSTANCE_LEVEL_COUNT],
                }
            }
        }
    };
}

packet!(
    /// Embree 4.4 `struct RTCRayHit8` (672 bytes, 32-byte aligned; the 4.2 binding's is 640).
    RTCRayHit8_44, 8, 32
);
packet!(
    /// Embree 4.4 `struct RTCRayHit16` (1344 bytes, 64-byte aligned; the 4.2 binding's is 1280).
    RTCRayHit16_44, 16, 64
);

const _: () = {
    assert!(size_of::<RTCRayHit8_44>() == 672);
    assert!(offset_of!(RTCRayHit8_44, Ng_x) == 384);
    assert!(offset_of!(RTCRayHit8_44, instPrimID) == 640);
    assert!(size_of::<embree4_sys::RTCRayHit8>() == 640);
    assert!(size_of::<RTCRayHit16_44>() == 1344);
    assert!(offset_of!(RTCRayHit16_44, Ng_x) == 768);
    assert!(offset_of!(RTCRayHit16_44, instPrimID) == 1280);
    assert!(size_of::<embree4_sys::RTCRayHit16>() == 1280);
};
