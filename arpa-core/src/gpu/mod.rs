//! The GPU layer both GPU backends share (`arpa-wgpu` on ray queries, a Vulkan backend on
//! ray-tracing pipelines) without depending on each other: what crosses the host/device
//! boundary and every rule that is a function of numbers only. The backends keep the API
//! calls (devices, buffers, pipelines, bind groups, acceleration structures) and the WGSL
//! glue that casts rays with their API.
//!
//! | module | what |
//! |---|---|
//! | [`layout`] | the `#[repr(C)]` records of the device buffers, each the host side of a WGSL struct of [`crate::shaders`] (sizes and field offsets checked at compile time) and the host computations that fill them |
//! | [`codes`] | the integer codes of the kernels and the path-level WGSL (kernels, methods, scattering kinds, triangle flags, store outcomes, instance custom data, batch flags); lights and spot falloff have theirs in [`crate::emission`] |
//! | [`morton`] | the Morton code of the sort keys and of the triangle order |
//! | [`sort`] | the sort's lengths and step schedule |
//! | [`batch`] | the photon-batch policy: batch ranges, buffer capacities from a binding limit, growth and shrink rules |
//! | [`scene`] | the scene tables of [`crate::shaders::SCENE`] and the triangle order of the bottom-level structures (feature `alloc`) |
//!
//! The path-level WGSL itself is in [`crate::shaders`] ([`crate::shaders::PATH`]).

pub mod batch;
pub mod codes;
pub mod layout;
pub mod morton;
#[cfg(feature = "alloc")]
#[cfg_attr(docsrs, doc(cfg(feature = "alloc")))]
pub mod scene;
pub mod sort;
