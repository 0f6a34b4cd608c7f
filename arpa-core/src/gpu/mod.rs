//! The GPU layer both GPU backends share (`arpa-wgpu` on ray queries, `arpa-vk` on
//! ray-tracing pipelines) without depending on each other: what crosses the host/device
//! boundary and every rule that is a function of numbers only. The backends keep the API
//! calls (devices, buffers, pipelines, bind groups, acceleration structures) and the WGSL
//! glue that casts rays with their API.
//!
//! | module | what |
//! |---|---|
//! | [`shaders`] | the WGSL: the twin of the per-photon maths and the path-level kernels, composed in dependency order |
//! | [`layout`] | the `#[repr(C)]` records of the device buffers, each the host side of a WGSL struct of [`shaders`] (sizes and field offsets checked at compile time), filled from the per-photon stages' types |
//! | [`codes`] | the integer codes of the kernels and the path-level WGSL (kernels, methods, scattering kinds, triangle flags, store outcomes, instance custom data, batch flags); lights and spot falloff have theirs in [`crate::emit::emission`] |
//! | [`sort`] | the sort's items, lengths and step schedule |
//! | [`batch`] | the photon-batch policy: batch ranges, buffer capacities from a binding limit, growth and shrink rules |
//! | [`fill`] | the records filled from the renderer layer: settings, the photon pass's emitter and cell tables, the camera, accumulation read-back (feature `alloc`) |
//! | [`scene`] | the scene tables of [`shaders::SCENE`] and the triangle order of the bottom-level structures (feature `alloc`) |
//!
//! Morton codes, shared with the projection maps, are in [`crate::base::morton`].

/// Checks a record's size and field offsets at compile time (used by [`layout`] and
/// [`sort`]; defined before them so both see it).
macro_rules! layout {
    ($t:ty, $size:expr, { $($field:ident: $offset:expr),* $(,)? }) => {
        const _: () = assert!(::core::mem::size_of::<$t>() == $size);
        $(const _: () = assert!(::core::mem::offset_of!($t, $field) == $offset);)*
    };
}

pub mod batch;
pub mod codes;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod fill;
pub mod layout;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod scene;
pub mod shaders;
pub mod sort;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod texture;
