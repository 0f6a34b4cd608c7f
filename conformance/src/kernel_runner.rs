//! [`KernelRunner`]: a backend's capability to run one WGSL compute kernel, all the cases
//! of the core's WGSL twin ([`crate::cases::twin`]) need from a backend. The trait, its
//! kernel contract and the wgpu runner live in the facade's registry
//! (`arpa::backends::kernel_runner`), which offers one per backend that runs WGSL.

pub use arpa::backends::kernel_runner::{KernelJob, KernelRunner, MakeKernelRunner, WORKGROUP_SIZE};
