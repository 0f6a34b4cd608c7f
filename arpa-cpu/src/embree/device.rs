//! [`Device`]: an owned, reference-counted `RTCDevice`.

use core::ffi::{CStr, c_char, c_void};
use std::ffi::CString;
use std::sync::{Arc, Mutex};

use embree4_sys as sys;

use super::error::{EmbreeError, Result};
use super::ffi;

/// An Embree device (`RTCDevice`): the library instance that owns scenes, geometries and
/// the worker thread pool (TBB) used to build BVHs.
///
/// Cheap to clone (an `Arc`); the device is released (`rtcReleaseDevice`) when the last
/// clone and the last [`EmbreeScene`](super::EmbreeScene) created from it are dropped. `Device` is
/// `Send + Sync`: Embree's device-level calls (creating scenes and geometries, reading
/// errors) are thread-safe, and errors are tracked per thread by Embree.
#[derive(Clone)]
pub struct Device {
    pub(crate) inner: Arc<DeviceInner>,
}

pub(crate) struct DeviceInner {
    pub(crate) raw: sys::RTCDevice,
    /// Message of the most recent error reported through the error callback. The error
    /// *code* is read per thread with `rtcGetDeviceError`; the message is best effort when
    /// several threads fail at once.
    last_message: Mutex<Option<String>>,
    version: i64,
}

// SAFETY: an RTCDevice handle may be used from any thread (Embree's device API is
// thread-safe; errors are stored per thread). `last_message` is behind a Mutex.
unsafe impl Send for DeviceInner {}
unsafe impl Sync for DeviceInner {}

impl Drop for DeviceInner {
    fn drop(&mut self) {
        // SAFETY: `raw` is a valid device we hold one reference on. Remove the callback
        // first: scenes that Embree still keeps alive must not call into freed memory.
        unsafe {
            ffi::rtcSetDeviceErrorFunction(self.raw, None, core::ptr::null_mut());
            sys::rtcReleaseDevice(self.raw);
        }
    }
}

unsafe extern "C" fn error_callback(user_ptr: *mut c_void, _code: u32, message: *const c_char) {
    if user_ptr.is_null() {
        return;
    }
    // SAFETY: `user_ptr` is the `DeviceInner` inside an `Arc` that outlives the device's
    // callback registration (unset in `Drop` before release).
    let inner = unsafe { &*(user_ptr as *const DeviceInner) };
    let text = if message.is_null() {
        String::new()
    } else {
        // SAFETY: Embree passes a NUL-terminated string valid for the call.
        unsafe { CStr::from_ptr(message) }
            .to_string_lossy()
            .into_owned()
    };
    if let Ok(mut slot) = inner.last_message.lock() {
        *slot = Some(text);
    }
}

impl Device {
    /// Creates a device with Embree's default configuration (all hardware threads).
    pub fn new() -> Result<Self> {
        Self::with_config("")
    }

    /// Creates a device from an Embree configuration string, e.g. `"threads=2"` or
    /// `"verbose=1"` (see the `rtcNewDevice` documentation).
    ///
    /// Fails with [`EmbreeError::InvalidInput`] if `config` contains a NUL byte, with
    /// [`EmbreeError::DeviceCreation`] if Embree rejects it, and with
    /// [`EmbreeError::UnsupportedVersion`] unless the library is Embree 4.
    pub fn with_config(config: &str) -> Result<Self> {
        let config = CString::new(config)
            .map_err(|_| EmbreeError::InvalidInput("device config contains a NUL byte".into()))?;
        // SAFETY: `config` is a valid C string for the duration of the call.
        let raw = unsafe { sys::rtcNewDevice(config.as_ptr()) };
        if raw.is_null() {
            // SAFETY: NULL queries the thread's device-creation error.
            let code = unsafe { ffi::rtcGetDeviceError(core::ptr::null_mut()) };
            let err = EmbreeError::from_code(code, String::new())
                .unwrap_or(EmbreeError::Unknown(String::new()));
            return Err(EmbreeError::DeviceCreation(Box::new(err)));
        }
        // SAFETY: valid device handle; VERSION is a read-only property.
        let version =
            unsafe { sys::rtcGetDeviceProperty(raw, sys::RTCDeviceProperty::VERSION) } as i64;
        let inner = Arc::new(DeviceInner {
            raw,
            last_message: Mutex::new(None),
            version,
        });
        // SAFETY: the callback and its user pointer stay valid until `DeviceInner::drop`
        // unregisters them.
        unsafe {
            ffi::rtcSetDeviceErrorFunction(
                raw,
                Some(error_callback),
                Arc::as_ptr(&inner) as *mut c_void,
            );
        }
        if !(40000..50000).contains(&version) {
            return Err(EmbreeError::UnsupportedVersion { found: version });
        }
        let device = Device { inner };
        device.check()?;
        Ok(device)
    }

    /// Version of the linked Embree library, `major*10000 + minor*100 + patch` (40400 for
    /// Embree 4.4.0).
    pub fn version(&self) -> i64 {
        self.inner.version
    }

    /// Returns (and clears) the error Embree recorded for this thread since the last check.
    pub(crate) fn check(&self) -> Result<()> {
        // SAFETY: valid device handle.
        let code = unsafe { ffi::rtcGetDeviceError(self.inner.raw) };
        if code == 0 {
            return Ok(());
        }
        let message = self
            .inner
            .last_message
            .lock()
            .ok()
            .and_then(|mut m| m.take())
            .unwrap_or_default();
        Err(EmbreeError::from_code(code, message).unwrap_or(EmbreeError::Unknown(String::new())))
    }

    pub(crate) fn raw(&self) -> sys::RTCDevice {
        self.inner.raw
    }
}

impl core::fmt::Debug for Device {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("Device")
            .field("version", &self.inner.version)
            .finish_non_exhaustive()
    }
}
