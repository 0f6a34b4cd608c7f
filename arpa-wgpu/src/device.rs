//! Adapter choice and device creation for the ray-query backend.
//!
//! [`AdapterChoice::Auto`] takes a real GPU (discrete, then integrated, then virtual) that
//! supports ray queries, else lavapipe (an adapter whose name contains `llvmpipe`), else any
//! other adapter with ray queries. [`AdapterChoice::NameContains`] forces an adapter by a
//! (case-insensitive) part of its name. The device is created with
//! [`wgpu::Features::EXPERIMENTAL_RAY_QUERY`] and the adapter's acceleration-structure limits.

use crate::timing::{DeviceTimer, TIMER_FEATURES};
use wgpu::{AdapterInfo, DeviceType, Features};

/// The name part that identifies lavapipe (Mesa's software Vulkan driver).
pub const LAVAPIPE_NAME: &str = "llvmpipe";

/// Which adapter to use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum AdapterChoice {
    /// A real GPU with ray queries when there is one, else lavapipe.
    #[default]
    Auto,
    /// The first adapter whose name contains this text (case-insensitive).
    NameContains(String),
}

/// Why no usable device could be created.
#[derive(Debug, thiserror::Error)]
pub enum DeviceError {
    /// wgpu found no adapter at all.
    #[error(
        "wgpu found no Vulkan adapter (no driver installed? On Debian 12 `bash scripts/install-lavapipe.sh` installs lavapipe)"
    )]
    NoAdapter,
    /// No adapter's name contains the requested text.
    #[error("no adapter name contains {wanted:?}; adapters found: {available}")]
    AdapterNotFound {
        /// The requested name part.
        wanted: String,
        /// Every adapter found, described.
        available: String,
    },
    /// The chosen adapter cannot do ray queries.
    #[error(
        "adapter {name:?} ({device_type:?}, {driver} {driver_info}) does not support ray queries (wgpu EXPERIMENTAL_RAY_QUERY, Vulkan VK_KHR_ray_query); lavapipe needs Mesa >= 25 (`bash scripts/install-lavapipe.sh`)"
    )]
    RayQueryUnsupported {
        /// Adapter name.
        name: String,
        /// Adapter type.
        device_type: DeviceType,
        /// Driver name.
        driver: String,
        /// Driver version text.
        driver_info: String,
    },
    /// Several adapters exist but none supports ray queries.
    #[error("no adapter supports ray queries (wgpu EXPERIMENTAL_RAY_QUERY); adapters found: {available}")]
    NoRayQueryAdapter {
        /// Every adapter found, described.
        available: String,
    },
    /// The adapter refused the device request.
    #[error("creating a device on adapter {name:?} failed: {source}")]
    RequestDevice {
        /// Adapter name.
        name: String,
        /// wgpu's error.
        source: wgpu::RequestDeviceError,
    },
}

/// One adapter as seen by the choice: its description and whether it has ray queries.
#[derive(Clone, Debug)]
pub struct Candidate {
    /// wgpu's description of the adapter.
    pub info: AdapterInfo,
    /// `true` if the adapter supports [`Features::EXPERIMENTAL_RAY_QUERY`].
    pub ray_query: bool,
}

fn describe(candidates: &[Candidate]) -> String {
    if candidates.is_empty() {
        return "none".into();
    }
    candidates
        .iter()
        .map(|c| {
            format!(
                "{:?} ({:?}, {:?}, ray queries: {})",
                c.info.name,
                c.info.device_type,
                c.info.backend,
                if c.ray_query { "yes" } else { "no" }
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}

fn is_lavapipe(info: &AdapterInfo) -> bool {
    info.name.to_lowercase().contains(LAVAPIPE_NAME)
}

/// Preference rank of an adapter for [`AdapterChoice::Auto`] (lower is better).
fn rank(info: &AdapterInfo) -> u32 {
    match info.device_type {
        DeviceType::DiscreteGpu => 0,
        DeviceType::IntegratedGpu => 1,
        DeviceType::VirtualGpu => 2,
        _ if is_lavapipe(info) => 3,
        _ => 4,
    }
}

/// Index of the adapter to use among `candidates` (pure: no GPU needed to test it).
pub fn choose(candidates: &[Candidate], choice: &AdapterChoice) -> Result<usize, DeviceError> {
    if candidates.is_empty() {
        return Err(DeviceError::NoAdapter);
    }
    let unsupported = |c: &Candidate| DeviceError::RayQueryUnsupported {
        name: c.info.name.clone(),
        device_type: c.info.device_type,
        driver: c.info.driver.clone(),
        driver_info: c.info.driver_info.clone(),
    };
    match choice {
        AdapterChoice::NameContains(wanted) => {
            let w = wanted.to_lowercase();
            let i = candidates
                .iter()
                .position(|c| c.info.name.to_lowercase().contains(&w))
                .ok_or_else(|| DeviceError::AdapterNotFound { wanted: wanted.clone(), available: describe(candidates) })?;
            if candidates[i].ray_query { Ok(i) } else { Err(unsupported(&candidates[i])) }
        }
        AdapterChoice::Auto => {
            let best = (0..candidates.len())
                .filter(|&i| candidates[i].ray_query)
                .min_by_key(|&i| (rank(&candidates[i].info), i));
            match best {
                Some(i) => Ok(i),
                None if candidates.len() == 1 => Err(unsupported(&candidates[0])),
                None => Err(DeviceError::NoRayQueryAdapter { available: describe(candidates) }),
            }
        }
    }
}

/// An open device with ray queries, its queue and the adapter it runs on.
pub struct GpuContext {
    /// Description of the adapter (name, type, driver).
    pub info: AdapterInfo,
    /// The device, with [`Features::EXPERIMENTAL_RAY_QUERY`] enabled.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// Stage timestamps, where the adapter has [`crate::timing::TIMER_FEATURES`].
    timer: Option<DeviceTimer>,
}

impl GpuContext {
    /// Opens the adapter `choice` selects (see the module docs) and creates a device with
    /// ray queries and the adapter's acceleration-structure limits.
    pub fn new(choice: &AdapterChoice) -> Result<Self, DeviceError> {
        pollster::block_on(Self::new_async(choice))
    }

    /// Async form of [`GpuContext::new`].
    pub async fn new_async(choice: &AdapterChoice) -> Result<Self, DeviceError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends: wgpu::Backends::PRIMARY,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapters = instance.enumerate_adapters(wgpu::Backends::PRIMARY).await;
        let candidates: Vec<Candidate> = adapters
            .iter()
            .map(|a| Candidate { info: a.get_info(), ray_query: a.features().contains(Features::EXPERIMENTAL_RAY_QUERY) })
            .collect();
        let i = choose(&candidates, choice)?;
        let adapter = &adapters[i];
        let info = candidates[i].info.clone();
        // The tracer's kernels bind more storage buffers than the default 8, and its photon
        // buffers outgrow the default 128 MiB binding: take the adapter's limits for those.
        let have = adapter.limits();
        let limits = wgpu::Limits {
            max_storage_buffers_per_shader_stage: have.max_storage_buffers_per_shader_stage,
            max_storage_buffer_binding_size: have.max_storage_buffer_binding_size,
            max_buffer_size: have.max_buffer_size,
            ..wgpu::Limits::default()
        }
        .using_acceleration_structure_values(have);
        // Timestamps only where the adapter has them (wgpu offers them on Vulkan queues
        // with at least 36 valid timestamp bits); without them the stats say so.
        let timestamps = adapter.features().contains(TIMER_FEATURES);
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("arpa-wgpu"),
                required_features: if timestamps { Features::EXPERIMENTAL_RAY_QUERY | TIMER_FEATURES } else { Features::EXPERIMENTAL_RAY_QUERY },
                required_limits: limits,
                // SAFETY: ray queries are an experimental wgpu feature; arpa-wgpu uses them
                // only through validated WGSL and accepts wgpu's caveats for such features.
                experimental_features: unsafe { wgpu::ExperimentalFeatures::enabled() },
                memory_hints: wgpu::MemoryHints::Performance,
                trace: wgpu::Trace::Off,
            })
            .await
            .map_err(|source| DeviceError::RequestDevice { name: info.name.clone(), source })?;
        let timer = timestamps.then(|| DeviceTimer::new(&device, queue.get_timestamp_period()));
        Ok(Self { info, device, queue, timer })
    }

    /// The stage timer (`None`: the adapter has no timestamp queries inside encoders).
    pub fn timer(&self) -> Option<&DeviceTimer> {
        self.timer.as_ref()
    }

    /// `true` when the device runs on lavapipe (software), not a GPU.
    pub fn is_lavapipe(&self) -> bool {
        is_lavapipe(&self.info)
    }
}

impl GpuContext {
    /// Submits an encoder's commands; while a stage is timed ([`GpuContext::timer`]) its
    /// device time is recorded too.
    pub fn submit(&self, encoder: wgpu::CommandEncoder) {
        match self.timer() {
            Some(t) => t.submit(&self.device, &self.queue, encoder.finish()),
            None => {
                self.queue.submit([encoder.finish()]);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cand(name: &str, device_type: DeviceType, ray_query: bool) -> Candidate {
        Candidate {
            info: AdapterInfo {
                name: name.into(),
                driver: "drv".into(),
                driver_info: "1.0".into(),
                ..AdapterInfo::new(device_type, wgpu::Backend::Vulkan)
            },
            ray_query,
        }
    }

    #[test]
    fn auto_prefers_a_gpu_with_ray_queries_then_lavapipe() {
        let lvp = cand("llvmpipe (LLVM 19.1.7, 256 bits)", DeviceType::Cpu, true);
        let gpu = cand("NVIDIA H200", DeviceType::DiscreteGpu, true);
        let old_gpu = cand("Old GPU", DeviceType::DiscreteGpu, false);
        assert_eq!(choose(&[lvp.clone(), gpu.clone()], &AdapterChoice::Auto).unwrap(), 1);
        assert_eq!(choose(&[old_gpu.clone(), lvp.clone()], &AdapterChoice::Auto).unwrap(), 1);
        assert_eq!(choose(&[lvp.clone(), gpu.clone()], &AdapterChoice::NameContains("LLVMPIPE".into())).unwrap(), 0);
    }

    #[test]
    fn errors_name_the_adapter() {
        let old = cand("Mesa llvmpipe 22.3", DeviceType::Cpu, false);
        let e = choose(std::slice::from_ref(&old), &AdapterChoice::Auto).unwrap_err().to_string();
        assert!(e.contains("Mesa llvmpipe 22.3") && e.contains("ray queries"), "{e}");
        let e = choose(std::slice::from_ref(&old), &AdapterChoice::NameContains("llvm".into())).unwrap_err().to_string();
        assert!(e.contains("Mesa llvmpipe 22.3"), "{e}");
        let e = choose(&[old.clone(), cand("GPU", DeviceType::DiscreteGpu, false)], &AdapterChoice::Auto).unwrap_err().to_string();
        assert!(e.contains("Mesa llvmpipe 22.3") && e.contains("\"GPU\""), "{e}");
        let e = choose(&[old], &AdapterChoice::NameContains("radeon".into())).unwrap_err().to_string();
        assert!(e.contains("radeon") && e.contains("Mesa llvmpipe 22.3"), "{e}");
        assert!(matches!(choose(&[], &AdapterChoice::Auto), Err(DeviceError::NoAdapter)));
    }
}
