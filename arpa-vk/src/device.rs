//! The Vulkan context: instance, optional validation, adapter choice, logical device with the
//! ray-tracing extensions, one compute queue and the memory allocator.
//!
//! [`AdapterChoice::Auto`] takes a real GPU (discrete, then integrated, then virtual) that has
//! everything the backend needs, else lavapipe (Mesa's CPU driver, device type CPU), else any
//! other adapter that has everything. [`AdapterChoice::NameContains`] forces an adapter by a
//! case-insensitive part of its name.
//!
//! What an adapter needs: Vulkan 1.2, the device extensions
//! [`REQUIRED_EXTENSIONS`] (`VK_KHR_acceleration_structure`, `VK_KHR_ray_tracing_pipeline`,
//! `VK_KHR_deferred_host_operations`), the features `accelerationStructure`,
//! `rayTracingPipeline`, `bufferDeviceAddress` (core in 1.2) and `geometryShader` (naga
//! declares the SPIR-V `Geometry` capability for `primitive_index`, even in hit shaders), and
//! a queue family with compute. Ray queries are not needed; whether the adapter has them is
//! reported in [`DeviceInfo::ray_query`].

use crate::adapter::{AdapterSummary, DeviceType};
use crate::error::{VkError, VkResultExt};
use crate::timing::Timestamps;
use ash::vk;
use gpu_allocator::vulkan::{Allocator, AllocatorCreateDesc};
use gpu_allocator::{AllocationSizes, AllocatorDebugSettings};
use std::ffi::{CStr, c_void};
use std::fmt;
use std::mem::ManuallyDrop;
use std::sync::{Arc, Mutex, MutexGuard};

/// The name part that identifies lavapipe (Mesa's software Vulkan driver).
pub const LAVAPIPE_NAME: &str = "llvmpipe";

/// The Khronos validation layer enabled by [`ContextOptions::validation`].
pub const VALIDATION_LAYER: &CStr = c"VK_LAYER_KHRONOS_validation";

/// Device extensions every adapter must have.
pub const REQUIRED_EXTENSIONS: [&CStr; 3] =
    [ash::khr::acceleration_structure::NAME, ash::khr::ray_tracing_pipeline::NAME, ash::khr::deferred_host_operations::NAME];

/// Which adapter (physical device) to use.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub enum AdapterChoice {
    /// A real GPU with ray-tracing pipelines when there is one, else lavapipe.
    #[default]
    Auto,
    /// The adapter whose name contains this text (case-insensitive); the first such adapter
    /// that has everything, else an error naming what the first one lacks.
    NameContains(String),
}

/// How to create the context.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContextOptions {
    /// Enable `VK_LAYER_KHRONOS_validation` and a `VK_EXT_debug_utils` messenger that records
    /// every error and warning (see [`VkContext::validation_messages`]). Creating the context
    /// fails when the layer is not installed.
    pub validation: bool,
}


/// A Vulkan version, `major.minor.patch`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct ApiVersion {
    /// Major version.
    pub major: u32,
    /// Minor version.
    pub minor: u32,
    /// Patch version.
    pub patch: u32,
}

impl ApiVersion {
    /// Decodes a packed `VK_MAKE_API_VERSION` value.
    pub fn from_raw(v: u32) -> Self {
        Self { major: vk::api_version_major(v), minor: vk::api_version_minor(v), patch: vk::api_version_patch(v) }
    }

    fn at_least(self, major: u32, minor: u32) -> bool {
        (self.major, self.minor) >= (major, minor)
    }
}

impl fmt::Display for ApiVersion {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}.{}.{}", self.major, self.minor, self.patch)
    }
}

/// The adapter the context runs on.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct DeviceInfo {
    /// Adapter name (`deviceName`), e.g. `llvmpipe (LLVM 19.1.7, 256 bits)`.
    pub name: String,
    /// Adapter type.
    pub device_type: DeviceType,
    /// Driver name (`VkPhysicalDeviceDriverProperties::driverName`), e.g. `llvmpipe`.
    pub driver_name: String,
    /// Driver version text (`driverInfo`), e.g. `Mesa 25.0.7 (LLVM 19.1.7)`.
    pub driver_info: String,
    /// The Vulkan version the adapter supports.
    pub api_version: ApiVersion,
    /// The Vulkan version the instance was created with (1.3 when the loader has it, else 1.2).
    pub instance_api_version: ApiVersion,
    /// Whether the adapter also has `VK_KHR_ray_query` with the `rayQuery` feature. Information
    /// only: the backend traces with ray-tracing pipelines and does not enable ray queries.
    pub ray_query: bool,
    /// Whether the adapter has the `accelerationStructureIndirectBuild` feature
    /// (`vkCmdBuildAccelerationStructuresIndirectKHR`: builds whose primitive counts the
    /// device reads). Queried, never assumed (lavapipe has it off); the backend builds with
    /// counts the host read back either way (see [`crate::tracer::VkTracer`]).
    pub acceleration_structure_indirect_build: bool,
}

/// Limits of ray-tracing pipelines and acceleration structures, queried from the adapter
/// (`VkPhysicalDeviceRayTracingPipelinePropertiesKHR`,
/// `VkPhysicalDeviceAccelerationStructurePropertiesKHR`). The shader binding table is laid out
/// from these; they differ between drivers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RayTracingProperties {
    /// Size of one shader-group handle, in bytes.
    pub shader_group_handle_size: u32,
    /// Required alignment of each shader-binding-table record, in bytes (a power of two).
    pub shader_group_handle_alignment: u32,
    /// Required alignment of the start of each shader-binding-table region, in bytes (a power
    /// of two).
    pub shader_group_base_alignment: u32,
    /// Largest `maxPipelineRayRecursionDepth` a pipeline may ask for (at least 1).
    pub max_ray_recursion_depth: u32,
    /// Largest stride between shader-binding-table records, in bytes.
    pub max_shader_group_stride: u32,
    /// Largest number of rays one `vkCmdTraceRaysKHR` may launch (width × height × depth).
    pub max_ray_dispatch_invocation_count: u32,
    /// Largest hit-attribute block an intersection shader may report, in bytes.
    pub max_ray_hit_attribute_size: u32,
    /// Required alignment of acceleration-structure build scratch memory, in bytes (a power of
    /// two).
    pub min_acceleration_structure_scratch_offset_alignment: u32,
    /// Largest number of geometries in one bottom-level acceleration structure.
    pub max_geometry_count: u64,
    /// Largest number of instances in one top-level acceleration structure.
    pub max_instance_count: u64,
    /// Largest number of triangles or AABBs in one bottom-level acceleration structure.
    pub max_primitive_count: u64,
}

/// One memory heap of the adapter.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct MemoryHeap {
    /// Its size, in bytes.
    pub size: u64,
    /// Whether it is device-local (`VK_MEMORY_HEAP_DEVICE_LOCAL_BIT`).
    pub device_local: bool,
}

/// The adapter's memory heaps and the largest buffer and allocation it allows.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MemoryLimits {
    /// Every memory heap.
    pub heaps: Vec<MemoryHeap>,
    /// `maxMemoryAllocationSize`: the largest single allocation, in bytes.
    pub max_memory_allocation_size: u64,
    /// `maxBufferSize` (Vulkan 1.3 / `VK_KHR_maintenance4`), in bytes; `None` where the adapter
    /// does not report it.
    pub max_buffer_size: Option<u64>,
}

impl MemoryLimits {
    /// The size of the largest device-local heap, in bytes (0 if none is device-local).
    pub fn largest_device_local_heap(&self) -> u64 {
        self.heaps.iter().filter(|h| h.device_local).map(|h| h.size).max().unwrap_or(0)
    }
}

/// Severity of a recorded validation message.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Severity {
    /// `VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT`.
    Warning,
    /// `VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT`.
    Error,
}

/// One error or warning reported through the debug messenger.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ValidationMessage {
    /// Error or warning.
    pub severity: Severity,
    /// The message id name (a VUID such as `VUID-vkCmdCopyBuffer-size-00115`), empty if none.
    pub id_name: String,
    /// The full message text.
    pub message: String,
}

impl fmt::Display for ValidationMessage {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "[{:?}] {}: {}", self.severity, self.id_name, self.message)
    }
}

/// The list of validation errors and warnings of one context. It outlives the context (clone
/// it with [`VkContext::validation_log`] before dropping the context to see messages emitted
/// while the device and instance are destroyed, such as leak reports).
#[derive(Clone, Debug, Default)]
pub struct ValidationLog(Arc<Mutex<Vec<ValidationMessage>>>);

impl ValidationLog {
    /// Every message recorded so far, oldest first.
    pub fn messages(&self) -> Vec<ValidationMessage> {
        lock(&self.0).clone()
    }
}

/// Locks a mutex, taking the data of a poisoned one (the guarded state stays consistent:
/// every critical section either completes or leaves handles that are still valid).
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The debug messenger's callback: records errors and warnings in the context's log (the user
/// data is the `Mutex<Vec<ValidationMessage>>` inside a [`ValidationLog`]) and prints them.
unsafe extern "system" fn on_message(
    severity: vk::DebugUtilsMessageSeverityFlagsEXT,
    _types: vk::DebugUtilsMessageTypeFlagsEXT,
    data: *const vk::DebugUtilsMessengerCallbackDataEXT<'_>,
    user: *mut c_void,
) -> vk::Bool32 {
    let severity = if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::ERROR) {
        Severity::Error
    } else if severity.contains(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING) {
        Severity::Warning
    } else {
        return vk::FALSE;
    };
    if data.is_null() || user.is_null() {
        return vk::FALSE;
    }
    // SAFETY: the messenger is created with a pointer to the log's mutex, which the instance
    // owner keeps alive until after the messenger and the instance are destroyed; `data` is
    // valid for the duration of the callback.
    let (log, data) = unsafe { (&*(user as *const Mutex<Vec<ValidationMessage>>), &*data) };
    let text = |s: Option<&CStr>| s.map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    // SAFETY: the strings are null or NUL-terminated, valid during the callback.
    let (id_name, message) = unsafe { (text(data.message_id_name_as_c_str()), text(data.message_as_c_str())) };
    let m = ValidationMessage { severity, id_name, message };
    eprintln!("arpa-vk validation: {m}");
    lock(log).push(m);
    vk::FALSE
}

/// The instance, its debug messenger and the loader; destroyed in that order on drop.
struct InstanceOwner {
    instance: ash::Instance,
    debug: Option<(ash::ext::debug_utils::Instance, vk::DebugUtilsMessengerEXT)>,
    api_version: ApiVersion,
    /// Read by the messenger callback: must outlive the instance.
    log: ValidationLog,
    /// Keeps the loader library open until the instance is gone.
    _entry: ash::Entry,
}

impl Drop for InstanceOwner {
    fn drop(&mut self) {
        // SAFETY: every child object (the device) is destroyed before this owner drops.
        unsafe {
            if let Some((utils, messenger)) = self.debug.take() {
                utils.destroy_debug_utils_messenger(messenger, None);
            }
            self.instance.destroy_instance(None);
        }
    }
}

fn messenger_info<'a>(log: &ValidationLog) -> vk::DebugUtilsMessengerCreateInfoEXT<'a> {
    vk::DebugUtilsMessengerCreateInfoEXT::default()
        .message_severity(vk::DebugUtilsMessageSeverityFlagsEXT::WARNING | vk::DebugUtilsMessageSeverityFlagsEXT::ERROR)
        .message_type(
            vk::DebugUtilsMessageTypeFlagsEXT::GENERAL
                | vk::DebugUtilsMessageTypeFlagsEXT::VALIDATION
                | vk::DebugUtilsMessageTypeFlagsEXT::PERFORMANCE,
        )
        .pfn_user_callback(Some(on_message))
        .user_data(Arc::as_ptr(&log.0) as *mut c_void)
}

fn cstr_name(bytes: Result<&CStr, std::ffi::FromBytesUntilNulError>) -> String {
    bytes.map(|s| s.to_string_lossy().into_owned()).unwrap_or_default()
}

impl InstanceOwner {
    fn new(options: &ContextOptions) -> Result<Self, VkError> {
        // SAFETY: loading the system's Vulkan loader; ash checks its entry points.
        let entry = unsafe { ash::Entry::load() }.map_err(|e| VkError::NoLoader(e.to_string()))?;
        // SAFETY: plain queries on a loaded entry.
        let loader = unsafe { entry.try_enumerate_instance_version() }.vk("vkEnumerateInstanceVersion")?.unwrap_or(vk::API_VERSION_1_0);
        let loader = ApiVersion::from_raw(loader);
        let api_version = if loader.at_least(1, 3) {
            vk::API_VERSION_1_3
        } else if loader.at_least(1, 2) {
            vk::API_VERSION_1_2
        } else {
            return Err(VkError::LoaderTooOld { found: loader.to_string() });
        };

        let log = ValidationLog::default();
        let mut layers: Vec<*const std::ffi::c_char> = Vec::new();
        let mut extensions: Vec<*const std::ffi::c_char> = Vec::new();
        if options.validation {
            // SAFETY: plain queries on a loaded entry.
            let have_layer = unsafe { entry.enumerate_instance_layer_properties() }
                .vk("vkEnumerateInstanceLayerProperties")?
                .iter()
                .any(|l| l.layer_name_as_c_str() == Ok(VALIDATION_LAYER));
            if !have_layer {
                return Err(VkError::ValidationUnavailable { what: VALIDATION_LAYER.to_string_lossy().into_owned() });
            }
            let utils = ash::ext::debug_utils::NAME;
            // SAFETY: as above; the layer may provide the extension itself.
            let has_utils = |layer: Option<&CStr>| -> Result<bool, VkError> {
                Ok(unsafe { entry.enumerate_instance_extension_properties(layer) }
                    .vk("vkEnumerateInstanceExtensionProperties")?
                    .iter()
                    .any(|e| e.extension_name_as_c_str() == Ok(utils)))
            };
            if !(has_utils(None)? || has_utils(Some(VALIDATION_LAYER))?) {
                return Err(VkError::ValidationUnavailable { what: utils.to_string_lossy().into_owned() });
            }
            layers.push(VALIDATION_LAYER.as_ptr());
            extensions.push(utils.as_ptr());
        }

        let app = vk::ApplicationInfo::default().application_name(c"arpa").engine_name(c"arpa-vk").api_version(api_version);
        // Also chained into the instance create info, so that messages of vkCreateInstance and
        // vkDestroyInstance are recorded too.
        let mut creation_messenger = messenger_info(&log);
        let mut info =
            vk::InstanceCreateInfo::default().application_info(&app).enabled_layer_names(&layers).enabled_extension_names(&extensions);
        if options.validation {
            info = info.push_next(&mut creation_messenger);
        }
        // SAFETY: the create info and everything it points to live across the call.
        let instance = unsafe { entry.create_instance(&info, None) }.map_err(|r| match r {
            // The loader's answer when it finds no driver (ICD) at all.
            vk::Result::ERROR_INCOMPATIBLE_DRIVER => VkError::NoAdapter { seen: Vec::new() },
            r => VkError::from_vk("vkCreateInstance", r),
        })?;
        let mut owner = Self { instance, debug: None, api_version: ApiVersion::from_raw(api_version), log, _entry: entry };
        if options.validation {
            let utils = ash::ext::debug_utils::Instance::new(&owner._entry, &owner.instance);
            // SAFETY: the instance has VK_EXT_debug_utils; the user data outlives the messenger.
            let messenger =
                unsafe { utils.create_debug_utils_messenger(&messenger_info(&owner.log), None) }.vk("vkCreateDebugUtilsMessengerEXT")?;
            owner.debug = Some((utils, messenger));
        }
        Ok(owner)
    }
}

/// What the adapter choice learnt about one physical device.
struct Candidate {
    physical_device: vk::PhysicalDevice,
    summary: AdapterSummary,
    api_version: ApiVersion,
    queue_family_index: Option<u32>,
    ray_query: bool,
    indirect_build: bool,
}

fn inspect(instance: &InstanceOwner, pd: vk::PhysicalDevice) -> Result<Candidate, VkError> {
    let inst = &instance.instance;
    // SAFETY: `pd` comes from vkEnumeratePhysicalDevices on this instance.
    let props = unsafe { inst.get_physical_device_properties(pd) };
    let api_version = ApiVersion::from_raw(props.api_version);
    let mut missing = Vec::new();
    // SAFETY: as above.
    let extensions = unsafe { inst.enumerate_device_extension_properties(pd) }.vk("vkEnumerateDeviceExtensionProperties")?;
    let has = |name: &CStr| extensions.iter().any(|e| e.extension_name_as_c_str() == Ok(name));
    for ext in REQUIRED_EXTENSIONS {
        if !has(ext) {
            missing.push(ext.to_string_lossy().into_owned());
        }
    }
    let mut ray_query = false;
    let mut indirect_build = false;
    if api_version.at_least(1, 2) {
        let mut v12 = vk::PhysicalDeviceVulkan12Features::default();
        let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default();
        let mut pipeline = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default();
        let mut query = vk::PhysicalDeviceRayQueryFeaturesKHR::default();
        let mut features = vk::PhysicalDeviceFeatures2::default().push_next(&mut v12);
        // Only structures of extensions the adapter has may be chained.
        if has(ash::khr::acceleration_structure::NAME) {
            features = features.push_next(&mut accel);
        }
        if has(ash::khr::ray_tracing_pipeline::NAME) {
            features = features.push_next(&mut pipeline);
        }
        let query_ext = has(ash::khr::ray_query::NAME);
        if query_ext {
            features = features.push_next(&mut query);
        }
        // SAFETY: the chain holds only structures the adapter knows; they live across the call.
        unsafe { inst.get_physical_device_features2(pd, &mut features) };
        let geometry_shader = features.features.geometry_shader == vk::TRUE;
        if !geometry_shader {
            missing.push("feature geometryShader".into());
        }
        if v12.buffer_device_address != vk::TRUE {
            missing.push("feature bufferDeviceAddress".into());
        }
        if has(ash::khr::acceleration_structure::NAME) && accel.acceleration_structure != vk::TRUE {
            missing.push("feature accelerationStructure".into());
        }
        if has(ash::khr::ray_tracing_pipeline::NAME) && pipeline.ray_tracing_pipeline != vk::TRUE {
            missing.push("feature rayTracingPipeline".into());
        }
        ray_query = query_ext && query.ray_query == vk::TRUE;
        indirect_build = has(ash::khr::acceleration_structure::NAME) && accel.acceleration_structure_indirect_build == vk::TRUE;
    } else {
        missing.insert(0, format!("Vulkan 1.2 (adapter has {api_version})"));
    }
    // SAFETY: as above.
    let families = unsafe { inst.get_physical_device_queue_family_properties(pd) };
    let queue_family_index =
        families.iter().position(|f| f.queue_flags.contains(vk::QueueFlags::COMPUTE) && f.queue_count > 0).map(|i| i as u32);
    if queue_family_index.is_none() {
        missing.push("a queue family with compute".into());
    }
    let summary =
        AdapterSummary { name: cstr_name(props.device_name_as_c_str()), device_type: DeviceType::from_vk(props.device_type), missing };
    Ok(Candidate { physical_device: pd, summary, api_version, queue_family_index, ray_query, indirect_build })
}

/// Index of the adapter to use among `adapters` (pure: testable without Vulkan). See the module
/// docs for the rules.
pub fn choose(adapters: &[AdapterSummary], choice: &AdapterChoice) -> Result<usize, VkError> {
    match choice {
        AdapterChoice::NameContains(wanted) => {
            let w = wanted.to_lowercase();
            let matching: Vec<usize> = (0..adapters.len()).filter(|&i| adapters[i].name.to_lowercase().contains(&w)).collect();
            let Some(&first) = matching.first() else {
                return Err(VkError::AdapterNotFound { wanted: wanted.clone(), seen: adapters.to_vec() });
            };
            match matching.iter().find(|&&i| adapters[i].missing.is_empty()) {
                Some(&i) => Ok(i),
                None => {
                    Err(VkError::MissingRequirements { adapter: adapters[first].name.clone(), missing: adapters[first].missing.clone() })
                }
            }
        }
        AdapterChoice::Auto => {
            let best = (0..adapters.len()).filter(|&i| adapters[i].missing.is_empty()).min_by_key(|&i| (adapters[i].device_type.rank(), i));
            match best {
                Some(i) => Ok(i),
                None if adapters.len() == 1 => {
                    Err(VkError::MissingRequirements { adapter: adapters[0].name.clone(), missing: adapters[0].missing.clone() })
                }
                None => Err(VkError::NoAdapter { seen: adapters.to_vec() }),
            }
        }
    }
}

/// The logical device; waits for it to go idle and destroys it on drop.
pub(crate) struct DeviceOwner {
    pub(crate) device: ash::Device,
}

impl Drop for DeviceOwner {
    fn drop(&mut self) {
        // SAFETY: every object created from the device is destroyed before this owner drops.
        unsafe {
            let _ = self.device.device_wait_idle();
            self.device.destroy_device(None);
        }
    }
}

/// The queue and the command pool of one-time submissions; both are externally synchronised,
/// hence kept behind one mutex.
pub(crate) struct Submitter {
    pub(crate) queue: vk::Queue,
    pub(crate) pool: vk::CommandPool,
}

/// Everything the context owns. Buffers hold an `Arc` of it, so the device and the allocator
/// outlive every buffer.
pub(crate) struct Shared {
    pub(crate) submitter: Mutex<Submitter>,
    /// Submissions not waited for yet, in submission order ([`VkContext::submit`]).
    pub(crate) in_flight: Mutex<Vec<crate::submission::InFlight>>,
    /// Command buffers of retired submissions; the next submission frees them (the pool
    /// is guarded by the submitter lock, which retiring does not take).
    pub(crate) spent: Mutex<Vec<vk::CommandBuffer>>,
    /// Submissions made so far: the next one's number ([`crate::submission::Submission`]).
    pub(crate) submissions: std::sync::atomic::AtomicU64,
    /// Every pipeline of the context is created through it, so a pipeline made again (the
    /// next render's, another tracer's on a shared context) reuses the driver's compiled
    /// shaders; on lavapipe compiling the passes costs seconds.
    pub(crate) pipeline_cache: vk::PipelineCache,
    pub(crate) allocator: ManuallyDrop<Mutex<Allocator>>,
    /// `VK_EXT_debug_utils` device functions (object names), when validation is on.
    pub(crate) debug_utils: Option<ash::ext::debug_utils::Device>,
    pub(crate) device: DeviceOwner,
    pub(crate) info: DeviceInfo,
    pub(crate) ray_tracing: RayTracingProperties,
    pub(crate) memory: MemoryLimits,
    pub(crate) physical_device: vk::PhysicalDevice,
    pub(crate) queue_family_index: u32,
    /// The queue family's timestamps (`None`: none).
    pub(crate) timestamps: Option<Timestamps>,
    /// Dropped after the device (field order).
    instance: InstanceOwner,
}

impl Drop for Shared {
    fn drop(&mut self) {
        let device = &self.device.device;
        // SAFETY: no buffer is alive (each holds an Arc of this) and every submission was
        // waited for; the pool and the allocator's memory go before the device (dropped next,
        // as a field), the device before the instance.
        unsafe {
            let _ = device.device_wait_idle();
            // Submissions nobody waited for (what they keep holds no buffer of this context,
            // or it would not be dropping): their command buffers go with the pool.
            for f in std::mem::take(self.in_flight.get_mut().unwrap_or_else(|e| e.into_inner())) {
                f.discard(device);
            }
            let submitter = self.submitter.get_mut().unwrap_or_else(|e| e.into_inner());
            device.destroy_command_pool(submitter.pool, None);
            device.destroy_pipeline_cache(self.pipeline_cache, None);
            ManuallyDrop::drop(&mut self.allocator);
        }
    }
}

/// An open Vulkan device with the ray-tracing extensions, its compute queue, a memory
/// allocator, and what the adapter reports.
///
/// Dropping the context destroys, in order: the command pool, the allocator (its memory
/// blocks), the device, the debug messenger, the instance. Buffers keep the device alive
/// (see [`crate::Buffer`]), so this happens when the context and its last buffer are gone.
///
/// Cloning gives another handle on the same device (reference-counted).
#[derive(Clone)]
pub struct VkContext {
    pub(crate) shared: Arc<Shared>,
}

impl VkContext {
    /// Opens the adapter `choice` selects and creates the device (see the module docs).
    ///
    /// Errors: no loader, no validation layer (when asked for), no adapter or none with
    /// ray-tracing pipelines, the named adapter not found or lacking something, or a failing
    /// Vulkan call.
    pub fn new(choice: &AdapterChoice, options: &ContextOptions) -> Result<Self, VkError> {
        let instance = InstanceOwner::new(options)?;
        let inst = &instance.instance;
        // SAFETY: a valid instance.
        let physical_devices = unsafe { inst.enumerate_physical_devices() }.vk("vkEnumeratePhysicalDevices")?;
        let candidates = physical_devices.iter().map(|&pd| inspect(&instance, pd)).collect::<Result<Vec<_>, _>>()?;
        let summaries: Vec<AdapterSummary> = candidates.iter().map(|c| c.summary.clone()).collect();
        let chosen = &candidates[choose(&summaries, choice)?];
        let pd = chosen.physical_device;
        let queue_family_index = chosen.queue_family_index.ok_or_else(|| VkError::MissingRequirements {
            adapter: chosen.summary.name.clone(),
            missing: vec!["a queue family with compute".into()],
        })?;

        let (info, ray_tracing, memory) = query_properties(&instance, chosen);

        let priorities = [1.0f32];
        let queues = [vk::DeviceQueueCreateInfo::default().queue_family_index(queue_family_index).queue_priorities(&priorities)];
        let extensions: Vec<*const std::ffi::c_char> = REQUIRED_EXTENSIONS.iter().map(|e| e.as_ptr()).collect();
        let base_features = vk::PhysicalDeviceFeatures::default().geometry_shader(true);
        let mut v12 = vk::PhysicalDeviceVulkan12Features::default().buffer_device_address(true);
        let mut accel = vk::PhysicalDeviceAccelerationStructureFeaturesKHR::default().acceleration_structure(true);
        let mut pipeline = vk::PhysicalDeviceRayTracingPipelineFeaturesKHR::default().ray_tracing_pipeline(true);
        let create = vk::DeviceCreateInfo::default()
            .queue_create_infos(&queues)
            .enabled_extension_names(&extensions)
            .enabled_features(&base_features)
            .push_next(&mut v12)
            .push_next(&mut accel)
            .push_next(&mut pipeline);
        // SAFETY: the adapter has every extension and feature requested (checked by `inspect`);
        // the create info lives across the call.
        let device = unsafe { inst.create_device(pd, &create, None) }.vk("vkCreateDevice")?;
        let device = DeviceOwner { device };
        let dev = &device.device;
        // SAFETY: the family was created with one queue.
        let queue = unsafe { dev.get_device_queue(queue_family_index, 0) };
        let pool_info =
            vk::CommandPoolCreateInfo::default().queue_family_index(queue_family_index).flags(vk::CommandPoolCreateFlags::TRANSIENT);
        // SAFETY: a valid device.
        let pool = unsafe { dev.create_command_pool(&pool_info, None) }.vk("vkCreateCommandPool")?;
        let allocator = Allocator::new(&AllocatorCreateDesc {
            instance: inst.clone(),
            device: dev.clone(),
            physical_device: pd,
            debug_settings: AllocatorDebugSettings::default(),
            buffer_device_address: true,
            allocation_sizes: AllocationSizes::default(),
        });
        let allocator = match allocator {
            Ok(a) => a,
            Err(source) => {
                // SAFETY: the pool is unused.
                unsafe { dev.destroy_command_pool(pool, None) };
                return Err(VkError::Allocator { what: "the allocator".into(), source });
            }
        };
        // SAFETY: a valid device; an empty cache.
        let pipeline_cache = match unsafe { dev.create_pipeline_cache(&vk::PipelineCacheCreateInfo::default(), None) } {
            Ok(c) => c,
            Err(e) => {
                drop(allocator);
                // SAFETY: the pool is unused.
                unsafe { dev.destroy_command_pool(pool, None) };
                return Err(VkError::from_vk("vkCreatePipelineCache", e));
            }
        };
        let debug_utils = options.validation.then(|| ash::ext::debug_utils::Device::new(inst, dev));
        // Stage timestamps where the queue family has them (never assumed: the valid bits
        // and the period are the adapter's).
        // SAFETY: a valid physical device of this instance.
        let families = unsafe { inst.get_physical_device_queue_family_properties(pd) };
        // SAFETY: as above.
        let period = unsafe { inst.get_physical_device_properties(pd) }.limits.timestamp_period;
        let valid_bits = families.get(queue_family_index as usize).map_or(0, |f| f.timestamp_valid_bits);
        // Each submission makes its own two-query pool ([`VkContext::submit`]).
        let timestamps = Timestamps::new(valid_bits, period);
        Ok(Self {
            shared: Arc::new(Shared {
                submitter: Mutex::new(Submitter { queue, pool }),
                in_flight: Mutex::default(),
                spent: Mutex::default(),
                submissions: std::sync::atomic::AtomicU64::new(0),
                pipeline_cache,
                allocator: ManuallyDrop::new(Mutex::new(allocator)),
                debug_utils,
                device,
                info,
                ray_tracing,
                memory,
                physical_device: pd,
                queue_family_index,
                timestamps,
                instance,
            }),
        })
    }

    /// The adapter the context runs on.
    pub fn info(&self) -> &DeviceInfo {
        &self.shared.info
    }

    /// The adapter's ray-tracing-pipeline and acceleration-structure limits.
    pub fn ray_tracing(&self) -> &RayTracingProperties {
        &self.shared.ray_tracing
    }

    /// The adapter's memory heaps and buffer/allocation size limits.
    pub fn memory(&self) -> &MemoryLimits {
        &self.shared.memory
    }

    /// `true` when the device runs on lavapipe (software), not a GPU.
    pub fn is_lavapipe(&self) -> bool {
        self.shared.info.name.to_lowercase().contains(LAVAPIPE_NAME)
    }

    /// The logical device (for recording commands and creating pipelines).
    pub fn device(&self) -> &ash::Device {
        &self.shared.device.device
    }

    /// The instance.
    pub fn instance(&self) -> &ash::Instance {
        &self.shared.instance.instance
    }

    /// The physical device.
    pub fn physical_device(&self) -> vk::PhysicalDevice {
        self.shared.physical_device
    }

    /// The timestamps of the context's queue family (`None`: it has none, and device times
    /// are not available; [`crate::timing`]).
    pub fn timestamps(&self) -> Option<Timestamps> {
        self.shared.timestamps
    }

    /// The family of the context's one compute queue.
    pub fn queue_family_index(&self) -> u32 {
        self.shared.queue_family_index
    }

    /// Every validation error and warning recorded so far (always empty without
    /// [`ContextOptions::validation`]).
    pub fn validation_messages(&self) -> Vec<ValidationMessage> {
        self.shared.instance.log.messages()
    }

    /// A handle on the validation messages that stays valid after the context is dropped.
    pub fn validation_log(&self) -> ValidationLog {
        self.shared.instance.log.clone()
    }

    /// Whether validation is on.
    pub fn validation_enabled(&self) -> bool {
        self.shared.instance.debug.is_some()
    }
}

fn query_properties(instance: &InstanceOwner, c: &Candidate) -> (DeviceInfo, RayTracingProperties, MemoryLimits) {
    let inst = &instance.instance;
    let pd = c.physical_device;
    let mut driver = vk::PhysicalDeviceDriverProperties::default();
    let mut maint3 = vk::PhysicalDeviceMaintenance3Properties::default();
    let mut maint4 = vk::PhysicalDeviceMaintenance4Properties::default();
    let mut pipeline = vk::PhysicalDeviceRayTracingPipelinePropertiesKHR::default();
    let mut accel = vk::PhysicalDeviceAccelerationStructurePropertiesKHR::default();
    let mut props = vk::PhysicalDeviceProperties2::default()
        .push_next(&mut driver)
        .push_next(&mut maint3)
        .push_next(&mut pipeline)
        .push_next(&mut accel);
    // maxBufferSize: core in 1.3 (on both the instance and the adapter), else the extension.
    // SAFETY: a plain query.
    let has_maint4 = (c.api_version.at_least(1, 3) && instance.api_version.at_least(1, 3))
        || unsafe { inst.enumerate_device_extension_properties(pd) }
            .map(|exts| exts.iter().any(|e| e.extension_name_as_c_str() == Ok(ash::khr::maintenance4::NAME)))
            .unwrap_or(false);
    if has_maint4 {
        props = props.push_next(&mut maint4);
    }
    // SAFETY: every chained structure is known to the adapter; they live across the call.
    unsafe { inst.get_physical_device_properties2(pd, &mut props) };
    let base = props.properties;
    // SAFETY: a plain query.
    let mem = unsafe { inst.get_physical_device_memory_properties(pd) };
    let heaps = mem
        .memory_heaps_as_slice()
        .iter()
        .map(|h| MemoryHeap { size: h.size, device_local: h.flags.contains(vk::MemoryHeapFlags::DEVICE_LOCAL) })
        .collect();
    let info = DeviceInfo {
        name: c.summary.name.clone(),
        device_type: c.summary.device_type,
        driver_name: cstr_name(driver.driver_name_as_c_str()),
        driver_info: cstr_name(driver.driver_info_as_c_str()),
        api_version: ApiVersion::from_raw(base.api_version),
        instance_api_version: instance.api_version,
        ray_query: c.ray_query,
        acceleration_structure_indirect_build: c.indirect_build,
    };
    let ray_tracing = RayTracingProperties {
        shader_group_handle_size: pipeline.shader_group_handle_size,
        shader_group_handle_alignment: pipeline.shader_group_handle_alignment,
        shader_group_base_alignment: pipeline.shader_group_base_alignment,
        max_ray_recursion_depth: pipeline.max_ray_recursion_depth,
        max_shader_group_stride: pipeline.max_shader_group_stride,
        max_ray_dispatch_invocation_count: pipeline.max_ray_dispatch_invocation_count,
        max_ray_hit_attribute_size: pipeline.max_ray_hit_attribute_size,
        min_acceleration_structure_scratch_offset_alignment: accel.min_acceleration_structure_scratch_offset_alignment,
        max_geometry_count: accel.max_geometry_count,
        max_instance_count: accel.max_instance_count,
        max_primitive_count: accel.max_primitive_count,
    };
    let memory = MemoryLimits {
        heaps,
        max_memory_allocation_size: maint3.max_memory_allocation_size,
        max_buffer_size: has_maint4.then_some(maint4.max_buffer_size),
    };
    (info, ray_tracing, memory)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn adapter(name: &str, device_type: DeviceType, missing: &[&str]) -> AdapterSummary {
        AdapterSummary { name: name.into(), device_type, missing: missing.iter().map(|s| s.to_string()).collect() }
    }

    #[test]
    fn auto_prefers_a_complete_gpu_then_lavapipe() {
        let lvp = adapter("llvmpipe (LLVM 19.1.7, 256 bits)", DeviceType::Cpu, &[]);
        let gpu = adapter("NVIDIA H200", DeviceType::DiscreteGpu, &[]);
        let igpu = adapter("Intel Iris", DeviceType::IntegratedGpu, &[]);
        let old = adapter("Old GPU", DeviceType::DiscreteGpu, &["VK_KHR_ray_tracing_pipeline"]);
        assert_eq!(choose(&[lvp.clone(), gpu.clone()], &AdapterChoice::Auto).unwrap(), 1);
        assert_eq!(choose(&[lvp.clone(), igpu.clone(), gpu.clone()], &AdapterChoice::Auto).unwrap(), 2);
        assert_eq!(choose(&[lvp.clone(), igpu], &AdapterChoice::Auto).unwrap(), 1);
        assert_eq!(choose(&[old.clone(), lvp.clone()], &AdapterChoice::Auto).unwrap(), 1);
        assert_eq!(choose(&[lvp.clone(), gpu], &AdapterChoice::NameContains("LLVMPIPE".into())).unwrap(), 0);
        // Two matches: the complete one wins.
        let old_lvp = adapter("llvmpipe (LLVM 15)", DeviceType::Cpu, &["VK_KHR_acceleration_structure"]);
        assert_eq!(choose(&[old_lvp, lvp], &AdapterChoice::NameContains("llvmpipe".into())).unwrap(), 1);
    }

    #[test]
    fn errors_name_the_adapters_and_what_they_lack() {
        let old = adapter("llvmpipe (LLVM 15)", DeviceType::Cpu, &["VK_KHR_acceleration_structure", "feature rayTracingPipeline"]);
        let e = choose(std::slice::from_ref(&old), &AdapterChoice::Auto).unwrap_err().to_string();
        assert!(e.contains("llvmpipe (LLVM 15)") && e.contains("VK_KHR_acceleration_structure, feature rayTracingPipeline"), "{e}");
        let e = choose(std::slice::from_ref(&old), &AdapterChoice::NameContains("LLVM".into())).unwrap_err().to_string();
        assert!(e.contains("llvmpipe (LLVM 15)") && e.contains("VK_KHR_acceleration_structure"), "{e}");
        let gpu = adapter("GPU", DeviceType::DiscreteGpu, &["VK_KHR_deferred_host_operations"]);
        let e = choose(&[old.clone(), gpu], &AdapterChoice::Auto).unwrap_err().to_string();
        assert!(e.contains("llvmpipe (LLVM 15)") && e.contains("\"GPU\"") && e.contains("VK_KHR_deferred_host_operations"), "{e}");
        let e = choose(std::slice::from_ref(&old), &AdapterChoice::NameContains("radeon".into())).unwrap_err();
        assert!(matches!(&e, VkError::AdapterNotFound { wanted, seen } if wanted == "radeon" && seen.len() == 1), "{e}");
        assert!(matches!(choose(&[], &AdapterChoice::Auto), Err(VkError::NoAdapter { seen }) if seen.is_empty()));
        assert!(matches!(choose(&[], &AdapterChoice::NameContains("x".into())), Err(VkError::AdapterNotFound { .. })));
    }

    #[test]
    fn api_versions_decode_and_compare() {
        let v = ApiVersion::from_raw(vk::make_api_version(0, 1, 3, 281));
        assert_eq!(v.to_string(), "1.3.281");
        assert!(v.at_least(1, 2) && v.at_least(1, 3) && !v.at_least(1, 4));
    }
}
