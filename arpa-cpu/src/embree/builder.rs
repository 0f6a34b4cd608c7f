//! [`EmbreeSceneBuilder`]: a scene under construction (triangle meshes and box sets), and
//! the [`EmbreeBox`] its box sets are made of.

use core::ffi::c_void;

use embree4_sys as sys;

use super::device::Device;
use super::error::{EmbreeError, Result};
use super::ffi::RTC_INVALID_GEOMETRY_ID;
use super::geometry::{EmbreeBox, finite3};
use super::scene::EmbreeScene;

/// BVH build quality (`RTCBuildQuality`): a trade-off between build time and query speed.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BuildQuality {
    /// `RTC_BUILD_QUALITY_LOW`: fastest build, slowest queries.
    Low,
    /// `RTC_BUILD_QUALITY_MEDIUM`: Embree's default.
    Medium,
    /// `RTC_BUILD_QUALITY_HIGH`: spatial splits for triangles; best for static geometry
    /// traced many times. The default of [`EmbreeSceneBuilder`].
    #[default]
    High,
}

impl BuildQuality {
    fn raw(self) -> sys::RTCBuildQuality {
        match self {
            Self::Low => sys::RTCBuildQuality::LOW,
            Self::Medium => sys::RTCBuildQuality::MEDIUM,
            Self::High => sys::RTCBuildQuality::HIGH,
        }
    }
}

/// A scene under construction (`RTCScene` before `rtcCommitScene`). Add geometry, then
/// [`commit`](Self::commit) to get a query-able [`EmbreeScene`]. Dropping it releases the
/// scene.
///
/// `Send` (may be built on another thread) but not `Sync`: Embree forbids concurrent
/// modification of a scene.
pub struct EmbreeSceneBuilder {
    device: Device,
    raw: sys::RTCScene,
    box_sets: Vec<(u32, Vec<EmbreeBox>)>,
    quality: BuildQuality,
    robust: bool,
}

// SAFETY: the scene handle is only used through `&mut self`; Embree allows a scene to be
// modified from any one thread at a time.
unsafe impl Send for EmbreeSceneBuilder {}

impl Drop for EmbreeSceneBuilder {
    fn drop(&mut self) {
        if !self.raw.is_null() {
            // SAFETY: we own one reference on the scene.
            unsafe { sys::rtcReleaseScene(self.raw) };
        }
    }
}

/// `rtcReleaseGeometry` on scope exit (the scene keeps its own reference once attached).
struct GeometryGuard(sys::RTCGeometry);

impl Drop for GeometryGuard {
    fn drop(&mut self) {
        // SAFETY: we own one reference on the geometry.
        unsafe { sys::rtcReleaseGeometry(self.0) };
    }
}


unsafe extern "C" fn boxes_bounds(args: *const sys::RTCBoundsFunctionArguments) {
    // SAFETY: Embree passes valid arguments; `geometryUserPtr` is the `Vec<EmbreeBox>` data
    // pointer registered in `add_boxes_owned`, which the builder keeps alive until the
    // build is done (Embree calls this only while building: there is no motion blur and a
    // committed scene is never modified), and its length is the user primitive count (so
    // `primID < len`).
    unsafe {
        let args = &*args;
        let boxes = args.geometryUserPtr as *const EmbreeBox;
        let b = &*boxes.add(args.primID as usize);
        *args.bounds_o = bounds_of(b);
    }
}

/// `b` as Embree's `RTCBounds`, written with two 16-byte stores on x86-64: the builder
/// reads each corner (with its padding float) as one 16-byte load right after the
/// callback returns, which cannot take its data from narrower stores still in the store
/// buffer (as the ray of `EmbreeScene::intersect`).
#[inline(always)]
fn bounds_of(b: &EmbreeBox) -> sys::RTCBounds {
    #[cfg(target_arch = "x86_64")]
    {
        use core::arch::x86_64::{__m128, _mm_setr_ps};
        // SAFETY: SSE2 is part of x86-64; `RTCBounds` is 32 bytes of `f32` fields in the
        // order written here (lower, align0; upper, align1; checked in ffi.rs), so it is
        // two `__m128` with any bit pattern valid.
        unsafe {
            let lower = _mm_setr_ps(b.lower[0], b.lower[1], b.lower[2], 0.0);
            let upper = _mm_setr_ps(b.upper[0], b.upper[1], b.upper[2], 0.0);
            core::mem::transmute::<[__m128; 2], sys::RTCBounds>([lower, upper])
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    sys::RTCBounds {
        lower_x: b.lower[0],
        lower_y: b.lower[1],
        lower_z: b.lower[2],
        align0: 0.0,
        upper_x: b.upper[0],
        upper_y: b.upper[1],
        upper_z: b.upper[2],
        align1: 0.0,
    }
}

/// Rays pass through user boxes: they exist for point queries only.
unsafe extern "C" fn boxes_intersect(_args: *const sys::RTCIntersectFunctionNArguments) {}
unsafe extern "C" fn boxes_occluded(_args: *const sys::RTCOccludedFunctionNArguments) {}

impl EmbreeSceneBuilder {
    /// Starts an empty scene on `device` (`rtcNewScene`), with [`BuildQuality::High`].
    pub fn new(device: &Device) -> Result<Self> {
        // SAFETY: valid device handle.
        let raw = unsafe { sys::rtcNewScene(device.raw()) };
        if raw.is_null() {
            return Err(device
                .check()
                .err()
                .unwrap_or(EmbreeError::Unknown("rtcNewScene returned NULL".into())));
        }
        Ok(Self {
            device: device.clone(),
            raw,
            box_sets: Vec::new(),
            quality: BuildQuality::High,
            robust: false,
        })
    }

    /// Sets the BVH build quality used by [`commit`](Self::commit).
    pub fn build_quality(mut self, quality: BuildQuality) -> Self {
        self.quality = quality;
        self
    }

    /// Enables `RTC_SCENE_FLAG_ROBUST` (slower traversal that avoids optimisations which
    /// can miss hits on edges/vertices of adjacent triangles).
    pub fn robust(mut self, robust: bool) -> Self {
        self.robust = robust;
        self
    }

    /// Adds a triangle mesh; returns its geometry id (0, 1, 2, ... in call order).
    ///
    /// `vertices` are positions in the world frame (any consistent unit); each
    /// `indices[i]` names the vertices `v0, v1, v2` of triangle `i` (its `prim_id`). The
    /// data is copied into Embree-owned buffers, so the slices need not outlive the call.
    ///
    /// Fails with [`EmbreeError::InvalidInput`] if a vertex is not finite, an index is out
    /// of range, the mesh is empty, or a count exceeds `u32::MAX`.
    pub fn add_triangle_mesh(
        &mut self,
        vertices: &[[f32; 3]],
        indices: &[[u32; 3]],
    ) -> Result<u32> {
        if indices.is_empty() || vertices.is_empty() {
            return Err(EmbreeError::InvalidInput(
                "triangle mesh without vertices or triangles".into(),
            ));
        }
        if vertices.len() > u32::MAX as usize || indices.len() > u32::MAX as usize {
            return Err(EmbreeError::InvalidInput(
                "triangle mesh larger than 2^32-1 items".into(),
            ));
        }
        if let Some(i) = vertices.iter().position(|v| !finite3(*v)) {
            return Err(EmbreeError::InvalidInput(format!(
                "vertex {i} is not finite: {:?}",
                vertices[i]
            )));
        }
        let nv = vertices.len() as u64;
        if let Some(i) = indices
            .iter()
            .position(|t| t.iter().any(|&k| u64::from(k) >= nv))
        {
            return Err(EmbreeError::InvalidInput(format!(
                "triangle {i} has an index out of range (indices {:?}, {} vertices)",
                indices[i], nv
            )));
        }

        // SAFETY: valid device; the returned handle (checked) is released by the guard.
        let geom =
            unsafe { sys::rtcNewGeometry(self.device.raw(), sys::RTCGeometryType::TRIANGLE) };
        if geom.is_null() {
            return Err(self
                .device
                .check()
                .err()
                .unwrap_or(EmbreeError::Unknown("rtcNewGeometry returned NULL".into())));
        }
        let geom = GeometryGuard(geom);
        // Copies `items` (12-byte triples, FLOAT3 / UINT3) into a new buffer of the geometry.
        let fill = |kind: sys::RTCBufferType, format: sys::RTCFormat, bytes: &[u8], items: usize, what: &str| -> Result<()> {
            // SAFETY: the buffer Embree returns holds `items * 12` bytes (vertex buffers padded
            // for SSE loads); we write exactly `bytes.len() == items * 12` bytes into it after
            // checking for NULL.
            unsafe {
                let buf = sys::rtcSetNewGeometryBuffer(geom.0, kind, 0, format, 12, items);
                self.device.check()?;
                if buf.is_null() {
                    return Err(EmbreeError::OutOfMemory(what.into()));
                }
                core::ptr::copy_nonoverlapping(bytes.as_ptr(), buf.cast::<u8>(), bytes.len());
            }
            Ok(())
        };
        fill(sys::RTCBufferType::VERTEX, sys::RTCFormat::FLOAT3, bytemuck::cast_slice(vertices), vertices.len(), "vertex buffer")?;
        fill(sys::RTCBufferType::INDEX, sys::RTCFormat::UINT3, bytemuck::cast_slice(indices), indices.len(), "index buffer")?;
        self.attach(geom)
    }

    /// Adds an instance of the committed scene `scene` (`RTC_GEOMETRY_TYPE_INSTANCE`, one
    /// level), placed by the affine map `to_world` (object frame to this scene's frame,
    /// rows of a 3×4 matrix: `w = M·p + t` with `to_world[r] = [M[r][0], M[r][1],
    /// M[r][2], t[r]]`); returns its geometry id. A ray that hits through it reports this
    /// id as [`super::Hit::inst_id`] and the instanced scene's geometry and primitive.
    /// Embree keeps its own reference on `scene`.
    ///
    /// Fails with [`EmbreeError::InvalidInput`] if the map is not finite, or if `scene`
    /// lives on another device.
    pub fn add_instance(&mut self, scene: &EmbreeScene, to_world: [[f32; 4]; 3]) -> Result<u32> {
        if !to_world.iter().flatten().all(|x| x.is_finite()) {
            return Err(EmbreeError::InvalidInput(format!("instance transform is not finite: {to_world:?}")));
        }
        if scene.device().raw() != self.device.raw() {
            return Err(EmbreeError::InvalidInput("instanced scene lives on another device".into()));
        }
        // SAFETY: valid device; the returned handle (checked) is released by the guard.
        let geom = unsafe { sys::rtcNewGeometry(self.device.raw(), sys::RTCGeometryType::INSTANCE) };
        if geom.is_null() {
            return Err(self
                .device
                .check()
                .err()
                .unwrap_or(EmbreeError::Unknown("rtcNewGeometry returned NULL".into())));
        }
        let geom = GeometryGuard(geom);
        // SAFETY: valid handles; Embree copies the 12 floats (3×4 row-major) during the call
        // and takes a reference on the committed scene.
        unsafe {
            sys::rtcSetGeometryInstancedScene(geom.0, scene.raw);
            sys::rtcSetGeometryTransform(geom.0, 0, sys::RTCFormat::FLOAT3X4_ROW_MAJOR, to_world.as_ptr().cast::<c_void>());
        }
        self.device.check()?;
        self.attach(geom)
    }

    /// Adds a set of axis-aligned boxes as one Embree user geometry
    /// (`RTC_GEOMETRY_TYPE_USER`); returns its geometry id. Box `i` is primitive `i`.
    ///
    /// The boxes are found by [`EmbreeScene::point_query`] /
    /// [`EmbreeScene::boxes_containing`] (e.g. photon footprints: the box bounds the
    /// footprint, the caller does the exact test). Rays never hit them: the
    /// intersect/occluded callbacks report no hit.
    ///
    /// Fails with [`EmbreeError::InvalidInput`] if a box is not finite, has `lower > upper`
    /// on some axis, the slice is empty, or has more than `u32::MAX` boxes.
    pub fn add_boxes(&mut self, boxes: &[EmbreeBox]) -> Result<u32> {
        Self::check_boxes(boxes)?;
        self.add_checked_boxes(boxes.to_vec())
    }

    /// [`add_boxes`](Self::add_boxes) without copying: the builder (then the
    /// [`EmbreeScene`]) takes `boxes` as they are. [`EmbreeScene::release_boxes`] hands
    /// them back once the BVH is built, so that only the BVH stays.
    pub fn add_boxes_owned(&mut self, boxes: Vec<EmbreeBox>) -> Result<u32> {
        Self::check_boxes(&boxes)?;
        self.add_checked_boxes(boxes)
    }

    fn check_boxes(boxes: &[EmbreeBox]) -> Result<()> {
        if boxes.is_empty() || boxes.len() > u32::MAX as usize {
            return Err(EmbreeError::InvalidInput(
                "box set must hold 1..=2^32-1 boxes".into(),
            ));
        }
        if let Some(i) = boxes.iter().position(|b| !b.is_valid()) {
            return Err(EmbreeError::InvalidInput(format!(
                "box {i} is not finite or inverted: {:?}",
                boxes[i]
            )));
        }
        Ok(())
    }

    fn add_checked_boxes(&mut self, data: Vec<EmbreeBox>) -> Result<u32> {
        // SAFETY: valid device; handle checked and released by the guard.
        let geom = unsafe { sys::rtcNewGeometry(self.device.raw(), sys::RTCGeometryType::USER) };
        if geom.is_null() {
            return Err(self
                .device
                .check()
                .err()
                .unwrap_or(EmbreeError::Unknown("rtcNewGeometry returned NULL".into())));
        }
        let geom = GeometryGuard(geom);
        // SAFETY: `data`'s heap allocation does not move when the Vec is moved into
        // `self.box_sets` below (it is never pushed to again), and lives until the BVH is
        // built (the scene keeps it until `release_boxes`), so the user pointer stays
        // valid for every bounds callback. The callbacks have the C ABI signatures Embree
        // expects.
        unsafe {
            sys::rtcSetGeometryUserPrimitiveCount(geom.0, data.len() as u32);
            sys::rtcSetGeometryUserData(geom.0, data.as_ptr() as *mut c_void);
            sys::rtcSetGeometryBoundsFunction(geom.0, Some(boxes_bounds), core::ptr::null_mut());
            sys::rtcSetGeometryIntersectFunction(geom.0, Some(boxes_intersect));
            sys::rtcSetGeometryOccludedFunction(geom.0, Some(boxes_occluded));
        }
        self.device.check()?;
        let id = self.attach(geom)?;
        self.box_sets.push((id, data));
        Ok(id)
    }

    fn attach(&mut self, geom: GeometryGuard) -> Result<u32> {
        // SAFETY: valid geometry and scene handles.
        let id = unsafe {
            sys::rtcCommitGeometry(geom.0);
            sys::rtcAttachGeometry(self.raw, geom.0)
        };
        self.device.check()?;
        if id == RTC_INVALID_GEOMETRY_ID {
            return Err(EmbreeError::Unknown(
                "rtcAttachGeometry returned RTC_INVALID_GEOMETRY_ID".into(),
            ));
        }
        Ok(id)
    }

    /// Builds the BVH (`rtcCommitScene`, using the device's worker threads) and returns the
    /// immutable [`EmbreeScene`].
    pub fn commit(mut self) -> Result<EmbreeScene> {
        let flags = if self.robust {
            sys::RTCSceneFlags::ROBUST
        } else {
            sys::RTCSceneFlags::NONE
        };
        // SAFETY: valid scene handle, not shared with any other thread.
        unsafe {
            sys::rtcSetSceneBuildQuality(self.raw, self.quality.raw());
            sys::rtcSetSceneFlags(self.raw, flags);
            sys::rtcCommitScene(self.raw);
        }
        self.device.check()?;
        let raw = core::mem::replace(&mut self.raw, core::ptr::null_mut());
        Ok(EmbreeScene {
            device: self.device.clone(),
            raw,
            box_sets: core::mem::take(&mut self.box_sets),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The bounds assembled from two vector registers put every corner coordinate where
    /// the field-by-field layout does.
    #[test]
    fn bounds_of_puts_every_field_in_place() {
        let b = bounds_of(&EmbreeBox { lower: [-1.0, 2.5, -3.25], upper: [4.0, 5.5, 6.75] });
        assert_eq!([b.lower_x, b.lower_y, b.lower_z, b.align0], [-1.0, 2.5, -3.25, 0.0]);
        assert_eq!([b.upper_x, b.upper_y, b.upper_z, b.align1], [4.0, 5.5, 6.75, 0.0]);
    }
}
