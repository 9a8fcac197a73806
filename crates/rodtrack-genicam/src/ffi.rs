//! The only calls into Aravis' C library that its safe bindings do not cover: the device list
//! with serial numbers, the in-process fake interface, and a borrowed view of a buffer's bytes.
//!
//! This is the crate's one module with `unsafe` code (the workspace denies it elsewhere); every
//! block says why it is sound. Aravis' global device list is not thread-safe, so every call
//! that touches it goes through [`ARAVIS_GLOBAL`].

#![allow(unsafe_code)]

use std::ffi::{CStr, CString};
use std::os::raw::c_char;
use std::sync::Mutex;

/// Serialises Aravis' process-global state: device list updates, look-ups and opening devices.
pub(crate) static ARAVIS_GLOBAL: Mutex<()> = Mutex::new(());

/// What the device list says about one camera.
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct CameraInfo {
    /// Aravis' device id (e.g. `Aravis-Fake-GV01`): what `genicam://ID` opens.
    pub id: String,
    /// Serial number (`GV01`); `genicam://SERIAL` opens it too.
    pub serial: String,
    /// Vendor name.
    pub vendor: String,
    /// Model name.
    pub model: String,
    /// Protocol (`GigEVision`, `USB3Vision`, `Fake`).
    pub protocol: String,
    /// Address (IP address for GigE Vision).
    pub address: String,
    /// Physical id (MAC address for GigE Vision).
    pub physical_id: String,
}

/// A C string owned by Aravis, copied; empty for NULL.
///
/// # Safety
/// `p` is NULL or points to a NUL-terminated string that stays valid during the call.
unsafe fn owned(p: *const c_char) -> String {
    if p.is_null() {
        String::new()
    } else {
        // SAFETY: non-NULL and NUL-terminated per this function's contract.
        unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
    }
}

/// Refreshes Aravis' device list (GigE discovery waits up to about a second) and returns it.
pub(crate) fn device_list() -> Vec<CameraInfo> {
    let _guard = ARAVIS_GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    // SAFETY: plain calls without arguments into Aravis' global device list, serialised by
    // ARAVIS_GLOBAL; the returned strings belong to that list, which does not change until the
    // next `arv_update_device_list` (also behind the lock, which we hold), and `owned` copies
    // them before we release it. Indices are below `arv_get_n_devices()`.
    unsafe {
        aravis_sys::arv_update_device_list();
        let n = aravis_sys::arv_get_n_devices();
        (0..n)
            .map(|i| CameraInfo {
                id: owned(aravis_sys::arv_get_device_id(i)),
                serial: owned(aravis_sys::arv_get_device_serial_nbr(i)),
                vendor: owned(aravis_sys::arv_get_device_vendor(i)),
                model: owned(aravis_sys::arv_get_device_model(i)),
                protocol: owned(aravis_sys::arv_get_device_protocol(i)),
                address: owned(aravis_sys::arv_get_device_address(i)),
                physical_id: owned(aravis_sys::arv_get_device_physical_id(i)),
            })
            .collect()
    }
}

/// Turns on Aravis' in-process fake interface (device id `Fake_1`), for tests without a
/// fake GigE camera process.
pub fn enable_fake_interface() {
    let _guard = ARAVIS_GLOBAL.lock().unwrap_or_else(|e| e.into_inner());
    let name = CString::from(c"Fake");
    // SAFETY: `name` is a valid NUL-terminated string that outlives the call; Aravis copies
    // what it needs; the global state is serialised by ARAVIS_GLOBAL.
    unsafe { aravis_sys::arv_enable_interface(name.as_ptr()) };
}

/// The bytes of a buffer popped from a stream, borrowed for as long as the buffer.
///
/// Zero-copy: the slice points into the buffer's own memory, which Aravis does not touch
/// while the buffer is out of the stream (popped and not yet pushed back).
pub(crate) fn buffer_bytes(buffer: &aravis::Buffer) -> &[u8] {
    let (ptr, len) = buffer.data();
    if ptr.is_null() || len == 0 {
        return &[];
    }
    // SAFETY: `ptr`/`len` describe the buffer's allocation (`arv_buffer_get_data`), which lives
    // as long as the `Buffer` object we borrow; the returned lifetime is tied to that borrow.
    // The stream thread writes into a buffer only while it is in the stream's input queue, and
    // a popped buffer goes back only by `push_buffer(buffer)`, which takes it by value, so no
    // write can happen while this shared slice exists. Bytes are plain `u8` (any value valid).
    unsafe { std::slice::from_raw_parts(ptr.cast_const(), len) }
}
