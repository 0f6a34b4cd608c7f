//! [`KernelRunner`]: a backend's capability to run one WGSL compute kernel over a buffer
//! of 32-bit words and read a buffer of words back. It is all the cases of the core's WGSL
//! twin (the conformance suite's `twin-*` cases) need from a backend. The trait is
//! object-safe, so the registry ([`super::BackendEntry::kernel_runner`]) offers one per
//! backend: wgpu through `arpa_wgpu::harness` (`WgpuKernelRunner`), a Vulkan backend
//! through naga → SPIR-V. A backend that runs no WGSL (cpu: it runs the Rust core itself,
//! the twin's reference) offers none, and the twin cases do not apply to it.
//!
//! ## The kernel contract
//!
//! The WGSL module ([`KernelJob::source`]) declares
//! ```wgsl
//! @group(0) @binding(0) var<storage, read> input: array<u32>;
//! @group(0) @binding(1) var<storage, read_write> output: array<u32>;
//! ```
//! and the entry point [`KernelJob::entry`] with `@workgroup_size(64)`
//! ([`WORKGROUP_SIZE`]), handling invocation `global_invocation_id.x` and returning for ids
//! `>= invocations`. The runner dispatches `⌈invocations / 64⌉` workgroups along x, binds
//! [`KernelJob::input`] (a one-word buffer when empty) and a zero-initialised output of
//! [`KernelJob::output_words`] words, and returns the output. Floats travel as their bit
//! patterns (`f32::to_bits`), so nothing is rounded on the way in or out.

use super::error::BoxError;

/// Workgroup size (x) every kernel declares and the runner dispatches for.
pub const WORKGROUP_SIZE: u32 = 64;

/// One compute dispatch (see the module's kernel contract).
#[derive(Clone, Copy, Debug)]
pub struct KernelJob<'a> {
    /// Name for error messages and debug labels.
    pub label: &'a str,
    /// The complete WGSL module.
    pub source: &'a str,
    /// Name of the compute entry point.
    pub entry: &'a str,
    /// Words of the input buffer (`@group(0) @binding(0)`).
    pub input: &'a [u32],
    /// Number of invocations (`global_invocation_id.x < invocations` do the work).
    pub invocations: u32,
    /// Words of the output buffer (`@group(0) @binding(1)`, zero-initialised); not zero.
    pub output_words: usize,
}

/// Creates a backend's kernel runner (the registry's
/// [`super::BackendEntry::kernel_runner`]); an error means it cannot run here.
pub type MakeKernelRunner = fn() -> Result<Box<dyn KernelRunner>, BoxError>;

/// Runs WGSL compute kernels on a backend's device (object-safe).
pub trait KernelRunner {
    /// The device the kernels run on, in words (adapter name and type).
    fn device(&self) -> String;
    /// Runs `job` and returns its [`KernelJob::output_words`] output words. An error names
    /// what failed (the shader rejected by the compiler, a size beyond one dispatch, the
    /// read-back).
    fn run(&self, job: &KernelJob<'_>) -> Result<Vec<u32>, BoxError>;
}

/// The wgpu backend's runner: `arpa_wgpu::harness::run_kernel` on its own device.
#[cfg(feature = "wgpu")]
pub struct WgpuKernelRunner {
    ctx: arpa_wgpu::GpuContext,
}

#[cfg(feature = "wgpu")]
const _: () = assert!(WORKGROUP_SIZE == arpa_wgpu::harness::WORKGROUP_SIZE);

#[cfg(feature = "wgpu")]
impl WgpuKernelRunner {
    /// A runner on the adapter `choice` selects (a device of its own, beside the tracer's).
    pub fn new(choice: &arpa_wgpu::AdapterChoice) -> Result<Self, arpa_wgpu::DeviceError> {
        Ok(Self {
            ctx: arpa_wgpu::GpuContext::new(choice)?,
        })
    }
}

#[cfg(feature = "wgpu")]
impl KernelRunner for WgpuKernelRunner {
    fn device(&self) -> String {
        format!("{} ({:?})", self.ctx.info.name, self.ctx.info.device_type)
    }

    fn run(&self, job: &KernelJob<'_>) -> Result<Vec<u32>, BoxError> {
        Ok(arpa_wgpu::run_kernel(
            &self.ctx,
            job.label,
            job.source,
            job.entry,
            job.input,
            job.invocations,
            job.output_words,
        )?)
    }
}

/// The wgpu backend's entry in [`super::BackendEntry::kernel_runner`]: a
/// [`WgpuKernelRunner`] on the adapter `AdapterChoice::Auto` picks (a GPU with ray queries,
/// else lavapipe).
#[cfg(feature = "wgpu")]
pub fn wgpu_kernel_runner() -> Result<Box<dyn KernelRunner>, BoxError> {
    Ok(Box::new(WgpuKernelRunner::new(&arpa_wgpu::AdapterChoice::Auto)?))
}


/// The Vulkan backend's runner: `arpa_vk::kernel::run_kernel` (naga → SPIR-V compute) on a
/// context of its own.
#[cfg(feature = "vk")]
pub struct VkKernelRunner {
    ctx: arpa_vk::VkContext,
}

#[cfg(feature = "vk")]
impl VkKernelRunner {
    /// A runner on the adapter `choice` selects (a context of its own, beside the tracer's).
    pub fn new(choice: &arpa_vk::AdapterChoice) -> Result<Self, arpa_vk::VkError> {
        Ok(Self { ctx: arpa_vk::VkContext::new(choice, &arpa_vk::ContextOptions::default())? })
    }
}

#[cfg(feature = "vk")]
impl KernelRunner for VkKernelRunner {
    fn device(&self) -> String {
        let i = self.ctx.info();
        format!("{} ({})", i.name, i.device_type)
    }

    fn run(&self, job: &KernelJob<'_>) -> Result<Vec<u32>, BoxError> {
        Ok(arpa_vk::kernel::run_kernel(&self.ctx, job.label, job.source, job.entry, job.input, job.invocations, job.output_words)?)
    }
}

/// The Vulkan backend's entry in [`super::BackendEntry::kernel_runner`]: a
/// [`VkKernelRunner`] on the adapter `AdapterChoice::Auto` picks (a GPU with ray-tracing
/// pipelines, else lavapipe).
#[cfg(feature = "vk")]
pub fn vk_kernel_runner() -> Result<Box<dyn KernelRunner>, BoxError> {
    Ok(Box::new(VkKernelRunner::new(&arpa_vk::AdapterChoice::Auto)?))
}
