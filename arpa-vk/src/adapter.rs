//! What the adapter choice knows of a physical device: its kind and, for error messages,
//! a summary of what it lacks.

use ash::vk;
use std::fmt;

/// The kind of an adapter (`VkPhysicalDeviceType`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DeviceType {
    /// A separate GPU.
    DiscreteGpu,
    /// A GPU sharing the host's memory.
    IntegratedGpu,
    /// A GPU in a virtualised environment.
    VirtualGpu,
    /// A driver running on the host CPU (lavapipe).
    Cpu,
    /// Anything else.
    Other,
}

impl DeviceType {
    pub(crate) fn from_vk(t: vk::PhysicalDeviceType) -> Self {
        match t {
            vk::PhysicalDeviceType::DISCRETE_GPU => Self::DiscreteGpu,
            vk::PhysicalDeviceType::INTEGRATED_GPU => Self::IntegratedGpu,
            vk::PhysicalDeviceType::VIRTUAL_GPU => Self::VirtualGpu,
            vk::PhysicalDeviceType::CPU => Self::Cpu,
            _ => Self::Other,
        }
    }

    /// Preference for [`crate::device::AdapterChoice::Auto`] (lower is better).
    pub(crate) fn rank(self) -> u32 {
        match self {
            Self::DiscreteGpu => 0,
            Self::IntegratedGpu => 1,
            Self::VirtualGpu => 2,
            Self::Cpu => 3,
            Self::Other => 4,
        }
    }
}

impl fmt::Display for DeviceType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::DiscreteGpu => "discrete GPU",
            Self::IntegratedGpu => "integrated GPU",
            Self::VirtualGpu => "virtual GPU",
            Self::Cpu => "CPU",
            Self::Other => "other",
        })
    }
}

/// A physical device as the adapter choice saw it: enough to name it in an error.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct AdapterSummary {
    /// The adapter's name (`VkPhysicalDeviceProperties::deviceName`).
    pub name: String,
    /// Its type.
    pub device_type: DeviceType,
    /// What it lacks of the backend's requirements (extensions, features, API version, a
    /// compute queue); empty when it has everything.
    pub missing: Vec<String>,
}

impl fmt::Display for AdapterSummary {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{:?} ({}", self.name, self.device_type)?;
        if self.missing.is_empty() { write!(f, ", has everything)") } else { write!(f, ", missing {})", self.missing.join(", ")) }
    }
}

/// Formats a list of adapters for an error message (`none` when empty).
pub(crate) struct AdapterList<'a>(pub &'a [AdapterSummary]);

impl fmt::Display for AdapterList<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.0.is_empty() {
            return write!(f, "none");
        }
        for (i, a) in self.0.iter().enumerate() {
            if i > 0 {
                write!(f, "; ")?;
            }
            write!(f, "{a}")?;
        }
        Ok(())
    }
}
