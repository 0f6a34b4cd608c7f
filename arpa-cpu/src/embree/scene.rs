//! [`EmbreeScene`]: a committed scene, immutable and query-only (closest hit, any hit,
//! packets of 8 or 16 rays, point queries).

use core::ffi::c_void;
use std::any::Any;
use std::panic::{AssertUnwindSafe, catch_unwind, resume_unwind};

use embree4_sys as sys;

use super::geometry::{EmbreeBox, finite3};
use super::device::Device;
use super::error::{EmbreeError, Result};
use super::ffi::{
    RTC_INVALID_GEOMETRY_ID, RTCPointQuery44, RTCPointQueryContext44, RTCRay44, RTCRayHit44,
    RTCRayHit8_44, RTCRayHit16_44,
};

/// Fills a 4.4-layout packet from `rays`, traces it and writes `hits` (see
/// [`EmbreeScene::intersect8`]).
macro_rules! packet_query {
    ($scene:expr, $rays:expr, $hits:expr, $ty:ty, $n:literal, $f:ident) => {{
        let (rays, hits): (&[PacketRay], &mut [Option<Hit>]) = ($rays, $hits);
        assert!(rays.len() <= $n && hits.len() >= rays.len(), "packet of at most {} rays", $n);
        let mut p = <$ty>::default();
        let mut valid = [0i32; $n];
        for (i, r) in rays.iter().enumerate() {
            check_ray(r.origin, r.dir, r.tnear, r.tfar)?;
            p.org_x[i] = r.origin[0];
            p.org_y[i] = r.origin[1];
            p.org_z[i] = r.origin[2];
            p.tnear[i] = r.tnear;
            p.dir_x[i] = r.dir[0];
            p.dir_y[i] = r.dir[1];
            p.dir_z[i] = r.dir[2];
            p.tfar[i] = r.tfar;
            valid[i] = -1;
        }
        // SAFETY: `p` is an initialised 4.4-layout packet, `valid` has N lanes.
        unsafe { $scene.$f(&valid, &mut p) };
        for (i, h) in hits.iter_mut().take(rays.len()).enumerate() {
            *h = (p.geomID[i] != RTC_INVALID_GEOMETRY_ID).then(|| Hit {
                t: p.tfar[i],
                u: p.u[i],
                v: p.v[i],
                prim_id: p.primID[i],
                geom_id: p.geomID[i],
                inst_id: p.instID[0][i],
                ng: [p.Ng_x[i], p.Ng_y[i], p.Ng_z[i]],
            });
        }
        Ok(())
    }};
}

/// The closest intersection of a ray with the scene's triangles (user boxes are never hit
/// by rays; see [`super::EmbreeSceneBuilder::add_boxes`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit: the hit point is `origin + t * dir`, so `t` is measured in
    /// units of `|dir|` (a distance in world units when `dir` is normalised).
    pub t: f32,
    /// Barycentric coordinate of the hit: `p = (1 - u - v) * v0 + u * v1 + v * v2` for the
    /// triangle's vertices `v0, v1, v2` in index order.
    pub u: f32,
    /// Second barycentric coordinate (see [`Hit::u`]).
    pub v: f32,
    /// Index of the triangle within its mesh (position in the `indices` slice).
    pub prim_id: u32,
    /// Geometry id returned by [`super::EmbreeSceneBuilder::add_triangle_mesh`]: of this
    /// scene, or of the instanced scene when [`Hit::inst_id`] names an instance.
    pub geom_id: u32,
    /// Geometry id of the instance ([`super::EmbreeSceneBuilder::add_instance`]) the ray
    /// hit through, or `u32::MAX` (`RTC_INVALID_GEOMETRY_ID`) for a triangle of this scene.
    pub inst_id: u32,
    /// Unnormalised geometric normal (in the frame of the geometry hit: the instanced
    /// scene's object frame for a hit through an instance, else the world frame), `(v1 - v0) x (v2 - v0)` (length =
    /// twice the triangle's area); it faces the side from which `v0, v1, v2` appear
    /// counter-clockwise, whichever side the ray came from.
    pub ng: [f32; 3],
}

/// A primitive whose bounds overlap a point query's sphere (see
/// [`EmbreeScene::point_query`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PointQueryCandidate {
    /// Geometry id (from [`super::EmbreeSceneBuilder::add_triangle_mesh`] or
    /// [`super::EmbreeSceneBuilder::add_boxes`]).
    pub geom_id: u32,
    /// Primitive index within that geometry (triangle index, or index into the box slice).
    pub prim_id: u32,
}

/// A committed scene (`RTCScene` after `rtcCommitScene`): immutable and query-only.
///
/// `Send + Sync`: Embree guarantees that ray and point queries on a committed scene may run
/// concurrently from any number of threads. Dropping it releases the scene (the device
/// stays alive until its last user is gone).
pub struct EmbreeScene {
    pub(super) device: Device,
    pub(super) raw: sys::RTCScene,
    /// The boxes of each box set, `(geometry id, boxes)`, until [`Self::release_boxes`].
    pub(super) box_sets: Vec<(u32, Vec<EmbreeBox>)>,
}

// SAFETY: the scene is committed and never modified again; Embree allows concurrent
// queries on committed scenes. The box data is immutable.
unsafe impl Send for EmbreeScene {}
unsafe impl Sync for EmbreeScene {}

impl Drop for EmbreeScene {
    fn drop(&mut self) {
        // SAFETY: we own one reference on the scene.
        unsafe { sys::rtcReleaseScene(self.raw) };
    }
}

impl core::fmt::Debug for EmbreeScene {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("EmbreeScene")
            .field("box_sets", &self.box_sets.len())
            .finish_non_exhaustive()
    }
}

#[inline]
fn check_ray(origin: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> Result<()> {
    // `c * 0` is ±0 for finite `c` and NaN otherwise: one branch for all six components.
    let zero = origin
        .iter()
        .chain(&dir)
        .fold(0.0f32, |acc, &c| acc + c * 0.0);
    // `!(a <= b)` also rejects NaN.
    if zero == 0.0 && dir != [0.0; 3] && 0.0 <= tnear && tnear.is_finite() && tnear <= tfar {
        Ok(())
    } else {
        Err(bad_ray(origin, dir, tnear, tfar))
    }
}

#[cold]
fn bad_ray(origin: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> EmbreeError {
    if !finite3(origin) || !finite3(dir) {
        return EmbreeError::InvalidInput(format!(
            "ray origin/direction not finite: {origin:?} {dir:?}"
        ));
    }
    if dir == [0.0; 3] {
        return EmbreeError::InvalidInput("ray direction is zero".into());
    }
    EmbreeError::InvalidInput(format!(
        "ray interval must satisfy 0 <= tnear <= tfar, tnear finite (got [{tnear}, {tfar}])"
    ))
}

struct QueryState<F> {
    f: F,
    panic: Option<Box<dyn Any + Send>>,
}

unsafe extern "C" fn point_query_trampoline<F: FnMut(PointQueryCandidate)>(
    args: *mut sys::RTCPointQueryFunctionArguments,
) -> bool {
    // SAFETY: `userPtr` is the `QueryState<F>` of the running `point_query` call on this
    // thread (Embree calls back synchronously from rtcPointQuery).
    let (state, cand) = unsafe {
        let args = &*args;
        (
            &mut *(args.userPtr as *mut QueryState<F>),
            PointQueryCandidate {
                geom_id: args.geomID,
                prim_id: args.primID,
            },
        )
    };
    if state.panic.is_none() {
        let f = &mut state.f;
        if let Err(p) = catch_unwind(AssertUnwindSafe(|| f(cand))) {
            state.panic = Some(p);
        }
    }
    false // the query radius was not changed
}

impl EmbreeScene {

    #[cfg(test)]
    pub(crate) fn raw_for_tests(&self) -> sys::RTCScene {
        self.raw
    }

    /// The device the scene lives on.
    pub fn device(&self) -> &Device {
        &self.device
    }

    /// Hands back the boxes of every box set, `(geometry id, boxes)` in the order they were
    /// added. The BVH keeps working: Embree reads the boxes only while building (the bounds
    /// callback), and a committed scene is never rebuilt. Afterwards [`EmbreeScene::boxes`]
    /// returns `None` and [`EmbreeScene::boxes_containing`] finds nothing; point queries
    /// still report the boxes' primitives.
    pub fn release_boxes(&mut self) -> Vec<(u32, Vec<EmbreeBox>)> {
        core::mem::take(&mut self.box_sets)
    }

    /// The boxes of the box set with geometry id `geom_id`, or `None` if that id is not a
    /// box set of this scene.
    pub fn boxes(&self, geom_id: u32) -> Option<&[EmbreeBox]> {
        self.box_sets
            .iter()
            .find(|(id, _)| *id == geom_id)
            .map(|(_, b)| &b[..])
    }

    /// Closest hit of the ray `origin + t * dir`, `t` in `[tnear, tfar]`, with the scene's
    /// triangles (`rtcIntersect1`); `Ok(None)` on a miss.
    ///
    /// `origin` and `dir` are in the world frame; `dir` need not be normalised (`t` is in
    /// units of `|dir|`). `tfar` may be `f32::INFINITY`. Returns
    /// [`EmbreeError::InvalidInput`] for a non-finite origin/direction, a zero direction,
    /// or an interval violating `0 <= tnear <= tfar`.
    #[inline]
    pub fn intersect(
        &self,
        origin: [f32; 3],
        dir: [f32; 3],
        tnear: f32,
        tfar: f32,
    ) -> Result<Option<Hit>> {
        check_ray(origin, dir, tnear, tfar)?;
        let mut rh = RTCRayHit44 {
            ray: make_ray(origin, dir, tnear, tfar),
            hit: Default::default(),
        };
        // SAFETY: `rh` is a properly initialised 4.4-layout RTCRayHit.
        unsafe { self.intersect_raw(&mut rh) };
        if rh.hit.geomID == RTC_INVALID_GEOMETRY_ID {
            return Ok(None);
        }
        Ok(Some(Hit {
            t: rh.ray.tfar,
            u: rh.hit.u,
            v: rh.hit.v,
            prim_id: rh.hit.primID,
            geom_id: rh.hit.geomID,
            inst_id: rh.hit.instID[0],
            ng: [rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z],
        }))
    }

    /// Closest hits of up to 8 rays at once (`rtcIntersect8`, one packet): `hits[i]` is
    /// what [`EmbreeScene::intersect`] answers for `rays[i]`. Same frame, units and errors as
    /// [`EmbreeScene::intersect`] (the first invalid ray is reported and nothing is traced).
    ///
    /// # Panics
    /// If `rays.len() > 8` or `hits.len() < rays.len()`.
    pub fn intersect8(&self, rays: &[PacketRay], hits: &mut [Option<Hit>]) -> Result<()> {
        packet_query!(self, rays, hits, RTCRayHit8_44, 8, intersect8_raw)
    }

    /// Closest hits of up to 16 rays at once (`rtcIntersect16`, one packet); as
    /// [`EmbreeScene::intersect8`] with 16 lanes.
    ///
    /// # Panics
    /// If `rays.len() > 16` or `hits.len() < rays.len()`.
    pub fn intersect16(&self, rays: &[PacketRay], hits: &mut [Option<Hit>]) -> Result<()> {
        packet_query!(self, rays, hits, RTCRayHit16_44, 16, intersect16_raw)
    }

    /// `rtcIntersect8` on a caller-provided 4.4-layout packet with default arguments
    /// (lane `i` is traced where `valid[i] == -1`).
    ///
    /// # Safety
    /// `packet` must point to a valid, initialised [`RTCRayHit8_44`] whose valid lanes
    /// hold finite rays with `geomID == instID[0][i] == RTC_INVALID_GEOMETRY_ID`.
    pub(crate) unsafe fn intersect8_raw(&self, valid: &[i32; 8], packet: *mut RTCRayHit8_44) {
        // The 4.2 binding's `RTCRayHit8` is 32 bytes too small for the 4.4 library: pass
        // our 672-byte mirror through a pointer cast (see `ffi.rs`).
        unsafe {
            sys::rtcIntersect8(valid.as_ptr(), self.raw, packet.cast::<sys::RTCRayHit8>(), core::ptr::null_mut())
        };
    }

    /// `rtcIntersect16` on a caller-provided 4.4-layout packet; as
    /// [`EmbreeScene::intersect8_raw`] with 16 lanes.
    ///
    /// # Safety
    /// As [`EmbreeScene::intersect8_raw`], for an [`RTCRayHit16_44`].
    pub(crate) unsafe fn intersect16_raw(&self, valid: &[i32; 16], packet: *mut RTCRayHit16_44) {
        // The 4.2 binding's `RTCRayHit16` is 64 bytes too small for the 4.4 library.
        unsafe {
            sys::rtcIntersect16(valid.as_ptr(), self.raw, packet.cast::<sys::RTCRayHit16>(), core::ptr::null_mut())
        };
    }

    /// `rtcIntersect1` on a caller-provided 4.4-layout ray/hit with default arguments.
    ///
    /// # Safety
    /// `rayhit` must point to a valid, initialised [`RTCRayHit44`] (finite ray,
    /// `hit.geomID == RTC_INVALID_GEOMETRY_ID`, `hit.instID[0] == RTC_INVALID_GEOMETRY_ID`).
    pub(crate) unsafe fn intersect_raw(&self, rayhit: *mut RTCRayHit44) {
        // The 4.2 binding's `RTCRayHit` is 16 bytes too small for the 4.4 library: pass our
        // 96-byte mirror through a pointer cast (see `ffi.rs`).
        unsafe {
            sys::rtcIntersect1(
                self.raw,
                rayhit.cast::<sys::RTCRayHit>(),
                core::ptr::null_mut(),
            )
        };
    }

    /// Whether any triangle intersects the ray `origin + t * dir` for `t` in
    /// `[tnear, tfar]` (`rtcOccluded1`; any hit, not the closest). Same frame, units and
    /// errors as [`EmbreeScene::intersect`].
    pub fn occluded(&self, origin: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> Result<bool> {
        check_ray(origin, dir, tnear, tfar)?;
        let mut ray = make_ray(origin, dir, tnear, tfar);
        // SAFETY: `ray` is an initialised 48-byte RTCRay (same layout in 4.2 and 4.4).
        unsafe {
            sys::rtcOccluded1(
                self.raw,
                (&mut ray as *mut RTCRay44).cast::<sys::RTCRay>(),
                core::ptr::null_mut(),
            )
        };
        // Embree sets tfar to -inf when the ray is occluded.
        Ok(ray.tfar == f32::NEG_INFINITY)
    }

    /// Calls `f` for every primitive (triangle or box) whose bounds Embree's BVH finds
    /// overlapping the closed ball of `radius` around `point` (`rtcPointQuery`).
    ///
    /// This is a conservative broad phase: `f` must do the exact test itself (e.g. point
    /// in box, point in a footprint ellipse). `point` is in the world frame, `radius`
    /// (world units) must be finite and `>= 0`; `0` queries the point itself. Calls happen
    /// synchronously on the calling thread. A panic in `f` stops further calls to `f` and
    /// is resumed once Embree has returned.
    pub fn point_query<F: FnMut(PointQueryCandidate)>(
        &self,
        point: [f32; 3],
        radius: f32,
        f: F,
    ) -> Result<()> {
        if !(finite3(point) && radius.is_finite() && radius >= 0.0) {
            return Err(EmbreeError::InvalidInput(format!(
                "point query needs a finite point and a finite radius >= 0 (got {point:?}, {radius})"
            )));
        }
        let mut query = RTCPointQuery44 {
            x: point[0],
            y: point[1],
            z: point[2],
            time: 0.0,
            radius,
        };
        let mut context = RTCPointQueryContext44::new();
        let mut state = QueryState { f, panic: None };
        // SAFETY: query and context are 16-byte aligned 4.4-layout structs (the context is
        // cast from the 4.2 binding type, see ffi.rs); the trampoline matches F and `state`
        // outlives the synchronous call.
        unsafe {
            sys::rtcPointQuery(
                self.raw,
                (&mut query as *mut RTCPointQuery44).cast::<sys::RTCPointQuery>(),
                (&mut context as *mut RTCPointQueryContext44).cast::<sys::RTCPointQueryContext>(),
                Some(point_query_trampoline::<F>),
                (&mut state as *mut QueryState<F>).cast::<c_void>(),
            );
        }
        if let Some(p) = state.panic {
            resume_unwind(p);
        }
        self.device.check()
    }

    /// All boxes (of every box set added with [`super::EmbreeSceneBuilder::add_boxes`]) that
    /// contain `point` (closed boxes, world frame), sorted by `(geom_id, prim_id)`.
    pub fn boxes_containing(&self, point: [f32; 3]) -> Result<Vec<PointQueryCandidate>> {
        let mut out = Vec::new();
        self.point_query(point, 0.0, |c| {
            if let Some(b) = self
                .boxes(c.geom_id)
                .and_then(|bs| bs.get(c.prim_id as usize))
                && b.contains(point)
            {
                out.push(c);
            }
        })?;
        out.sort_unstable();
        out.dedup();
        Ok(out)
    }
}

/// One ray of a packet query ([`EmbreeScene::intersect8`], [`EmbreeScene::intersect16`]):
/// the ray `origin + t * dir`, `t` in `[tnear, tfar]`, world frame (as
/// [`EmbreeScene::intersect`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PacketRay {
    /// Origin (world frame).
    pub origin: [f32; 3],
    /// Direction (world frame, need not be normalised).
    pub dir: [f32; 3],
    /// Start of the interval (units of `|dir|`).
    pub tnear: f32,
    /// End of the interval (units of `|dir|`; may be infinite).
    pub tfar: f32,
}


fn make_ray(origin: [f32; 3], dir: [f32; 3], tnear: f32, tfar: f32) -> RTCRay44 {
    // Written as three 16-byte stores on x86-64: Embree reads the ray's origin and
    // direction (each with the float after it) as 16-byte loads, and a wide load of fields
    // just written by narrower stores cannot take its data from the store buffer; it waits
    // until they reach the cache, at the start of every traversal.
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{__m128, _mm_castsi128_ps, _mm_setr_epi32, _mm_setr_ps};
        // SAFETY: SSE2 is part of x86-64; `RTCRay44` is `repr(C, align(16))`, 48 bytes of
        // `f32`/`u32` fields in the order written here (org, tnear; dir, time; tfar, mask,
        // id, flags), so it is three `__m128` with any bit pattern valid.
        unsafe {
            let org = _mm_setr_ps(origin[0], origin[1], origin[2], tnear);
            let dir = _mm_setr_ps(dir[0], dir[1], dir[2], 0.0);
            let rest = _mm_castsi128_ps(_mm_setr_epi32(tfar.to_bits() as i32, -1, 0, 0));
            core::mem::transmute::<[__m128; 3], RTCRay44>([org, dir, rest])
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    RTCRay44 {
        org_x: origin[0],
        org_y: origin[1],
        org_z: origin[2],
        tnear,
        dir_x: dir[0],
        dir_y: dir[1],
        dir_z: dir[2],
        time: 0.0,
        tfar,
        mask: u32::MAX,
        id: 0,
        flags: 0,
    }
}


#[cfg(test)]
mod tests {
    use super::*;

    /// The ray assembled from three vector registers holds every field where the
    /// field-by-field layout puts it (Embree reads it by field offsets).
    #[test]
    fn make_ray_puts_every_field_in_place() {
        let r = make_ray([1.5, -2.25, 3.0], [0.0, 0.6, -0.8], f32::MIN_POSITIVE, 7.5);
        assert_eq!([r.org_x, r.org_y, r.org_z, r.tnear], [1.5, -2.25, 3.0, f32::MIN_POSITIVE]);
        assert_eq!([r.dir_x, r.dir_y, r.dir_z, r.time], [0.0, 0.6, -0.8, 0.0]);
        assert_eq!(r.tfar, 7.5);
        assert_eq!((r.mask, r.id, r.flags), (u32::MAX, 0, 0));
        let inf = make_ray([0.0; 3], [1.0, 0.0, 0.0], 0.0, f32::INFINITY);
        assert_eq!(inf.tfar, f32::INFINITY);
    }
}
