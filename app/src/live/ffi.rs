//! The few Aravis calls that the safe `aravis` crate lacks: enabling an
//! interface, shutting the library down, and the fill callback of the
//! in-process fake camera. Every `unsafe` block of rigview lives here.

#![allow(unsafe_code)]

use std::ffi::{c_void, CString};
use std::panic::{catch_unwind, AssertUnwindSafe};

use aravis::glib::translate::ToGlibPtr;
use aravis::FakeCamera;

/// Enables an Aravis interface by name (`"Fake"` for the in-process fake
/// camera; the others are enabled by default).
pub fn enable_interface(name: &str) {
    let Ok(name) = CString::new(name) else {
        return;
    };
    // SAFETY: `name` is a valid NUL-terminated string that lives through the
    // call; Aravis copies what it needs.
    unsafe { aravis_sys::arv_enable_interface(name.as_ptr()) }
}

/// Frees Aravis's global state (interfaces, device lists). Call it once, at
/// the very end, when no camera, device or stream object is left.
pub fn shutdown() {
    // SAFETY: takes no arguments; the caller guarantees no Aravis object is
    // alive any more.
    unsafe { aravis_sys::arv_shutdown() }
}

/// What a fill callback receives: the frame to fill (tightly packed, as
/// wide and high as the camera's region), the exposure time in µs and the
/// raw gain of the fake camera's registers.
pub type FillFn = dyn Fn(&mut [u8], usize, usize, u32, u32) + Send + Sync;

struct FillData {
    fill: Box<FillFn>,
    width: usize,
    height: usize,
}

/// A fill callback installed on an in-process fake camera. Dropping it
/// restores the fake camera's own pattern before the callback's data is
/// freed.
pub struct FillGuard {
    camera: FakeCamera,
    data: *mut FillData,
}

// SAFETY: `data` is only dereferenced by Aravis's fill callback (under the
// fake camera's fill mutex) and freed in `drop` after the callback has been
// removed under that same mutex; `FakeCamera` is a GObject whose methods used
// here are thread-safe.
unsafe impl Send for FillGuard {}

impl std::fmt::Debug for FillGuard {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FillGuard").finish_non_exhaustive()
    }
}

unsafe extern "C" fn fill_trampoline(
    buffer: *mut aravis_sys::ArvBuffer,
    user: *mut c_void,
    exposure_time_us: u32,
    gain: u32,
    _format: aravis_sys::ArvPixelFormat,
) {
    if buffer.is_null() || user.is_null() {
        return;
    }
    // SAFETY: `user` is the `FillData` installed by `install_fill`, alive
    // until the guard removes the callback (under the same mutex that Aravis
    // holds while it calls us).
    let data = unsafe { &*(user as *const FillData) };
    let mut size: usize = 0;
    // SAFETY: `buffer` is the live buffer Aravis is filling; `size` is a
    // valid out-pointer. (The fake camera does not set the received size, so
    // `size` may be 0.)
    let ptr = unsafe { aravis_sys::arv_buffer_get_data(buffer, &mut size) };
    // SAFETY: as above; these read the image size the fake camera has just
    // set from its Width and Height registers.
    let (bw, bh) = unsafe {
        (
            aravis_sys::arv_buffer_get_image_width(buffer),
            aravis_sys::arv_buffer_get_image_height(buffer),
        )
    };
    let need = data.width * data.height;
    let image = usize::try_from(bw).unwrap_or(0) * usize::try_from(bh).unwrap_or(0);
    if ptr.is_null() || image != need {
        return;
    }
    // SAFETY: the fake camera calls us only after checking that the buffer
    // holds at least Width × Height bytes, which is `need`; nothing else
    // touches them during the callback.
    let pixels = unsafe { std::slice::from_raw_parts_mut(ptr, need) };
    // A panic must not unwind into C; the frame then keeps what it had.
    let _ = catch_unwind(AssertUnwindSafe(|| {
        (data.fill)(pixels, data.width, data.height, exposure_time_us, gain);
    }));
}

/// Installs `fill` as the pattern of `camera`, for frames of
/// `width × height` Mono8 pixels.
pub fn install_fill(
    camera: &FakeCamera,
    width: usize,
    height: usize,
    fill: Box<FillFn>,
) -> FillGuard {
    let data = Box::into_raw(Box::new(FillData {
        fill,
        width,
        height,
    }));
    let raw: *mut aravis_sys::ArvFakeCamera = camera.to_glib_none().0;
    // SAFETY: `raw` is a valid fake camera for the call; `data` stays valid
    // until `FillGuard::drop` has removed the callback.
    unsafe {
        aravis_sys::arv_fake_camera_set_fill_pattern(raw, Some(fill_trampoline), data.cast());
    }
    FillGuard {
        camera: camera.clone(),
        data,
    }
}

impl Drop for FillGuard {
    fn drop(&mut self) {
        let raw: *mut aravis_sys::ArvFakeCamera = self.camera.to_glib_none().0;
        // SAFETY: restoring the default pattern takes the fill mutex, so once
        // it returns no callback is running with our data or will run again.
        unsafe {
            aravis_sys::arv_fake_camera_set_fill_pattern(raw, None, std::ptr::null_mut());
            drop(Box::from_raw(self.data));
        }
    }
}

/// A copy of the first `len` bytes of a buffer that rigview allocated with
/// at least `allocated` bytes (for buffers whose received size Aravis does
/// not set, such as the in-process fake camera's).
pub fn buffer_bytes(buffer: &aravis::Buffer, len: usize, allocated: usize) -> Vec<u8> {
    let (ptr, _) = buffer.data();
    if ptr.is_null() || len > allocated {
        return Vec::new();
    }
    // SAFETY: the buffer was allocated with `allocated` ≥ `len` bytes at
    // `ptr`, and it is out of the stream's queues while we hold it.
    unsafe { std::slice::from_raw_parts(ptr, len) }.to_vec()
}
