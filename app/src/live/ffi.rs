//! The few Aravis calls that the safe `aravis` crate lacks: enabling an
//! interface, the fake cameras' GenICam file, shutting the library down,
//! and the fill callback of the
//! in-process fake camera. Every `unsafe` block of the app lives here (core keeps
//! its SIMD kernels' and one `libc` call's; ARCHITECTURE.md lists them).

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

/// Makes Aravis's in-process fake cameras describe themselves with the
/// GenICam XML at `path` instead of Aravis's own (for every fake camera
/// created after the call). A path that is not valid UTF-8 or holds a NUL
/// is left out.
pub fn set_fake_genicam(path: &std::path::Path) {
    let Some(path) = path.to_str().and_then(|p| CString::new(p).ok()) else {
        return;
    };
    // SAFETY: `path` is a valid NUL-terminated string that lives through
    // the call; Aravis copies it.
    unsafe { aravis_sys::arv_set_fake_camera_genicam_filename(path.as_ptr()) }
}

/// Frees Aravis's global state (interfaces, device lists). Call it once, at
/// the very end, when no camera, device or stream object is left.
pub fn shutdown() {
    // SAFETY: takes no arguments; the caller guarantees no Aravis object is
    // alive any more.
    unsafe { aravis_sys::arv_shutdown() }
}

/// What the fake camera tells a fill callback about the frame it fills.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FillArgs {
    /// The frame's id as the fake camera numbers it (the id its buffer
    /// arrives with: 16 bit, 0 skipped).
    pub frame_id: u64,
    /// The frame's timestamp (the one its buffer arrives with), ns.
    pub timestamp_ns: u64,
    /// The exposure time register, µs.
    pub exposure_us: u32,
    /// The `GainRaw` register.
    pub gain_raw: u32,
}

/// A fill callback: the frame to fill (tightly packed, as wide and high as
/// the camera's region, in the pixel format it was installed for) and what
/// the fake camera says about it.
pub type FillFn = dyn Fn(&mut [u8], FillArgs) + Send + Sync;

struct FillData {
    fill: Box<FillFn>,
    width: usize,
    height: usize,
    bytes_per_pixel: usize,
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
    format: aravis_sys::ArvPixelFormat,
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
    // SAFETY: as above; these read the image size, frame id and timestamp
    // the fake camera has just set from its registers, its frame counter
    // and its clock.
    let (bw, bh, frame_id, timestamp_ns) = unsafe {
        (
            aravis_sys::arv_buffer_get_image_width(buffer),
            aravis_sys::arv_buffer_get_image_height(buffer),
            aravis_sys::arv_buffer_get_frame_id(buffer),
            aravis_sys::arv_buffer_get_timestamp(buffer),
        )
    };
    // PFNC pixel formats hold their bits per pixel in bits 16–23.
    let format_bytes = ((format >> 16) & 0xff) as usize / 8;
    let image = usize::try_from(bw).unwrap_or(0) * usize::try_from(bh).unwrap_or(0);
    let need = data.width * data.height * data.bytes_per_pixel;
    if ptr.is_null()
        || image != data.width * data.height
        || format_bytes != data.bytes_per_pixel
        || need == 0
    {
        return;
    }
    // SAFETY: rigview gives the stream only buffers of the payload size the
    // camera reports for its region and pixel format (Width × Height × bytes
    // per pixel), which `open` checks is at least `need` before acquisition
    // starts, and the fake camera calls us only with a frame of that region
    // and format (checked above); nothing else touches the buffer during the
    // callback.
    let pixels = unsafe { std::slice::from_raw_parts_mut(ptr, need) };
    let args = FillArgs {
        frame_id,
        timestamp_ns,
        exposure_us: exposure_time_us,
        gain_raw: gain,
    };
    // A panic must not unwind into C; the frame then keeps what it had.
    let _ = catch_unwind(AssertUnwindSafe(|| (data.fill)(pixels, args)));
}

/// Installs `fill` as the pattern of `camera`, for frames of
/// `width × height` pixels of `bytes_per_pixel` bytes. The buffers given to
/// the camera's stream must hold at least that many bytes.
pub fn install_fill(
    camera: &FakeCamera,
    width: usize,
    height: usize,
    bytes_per_pixel: usize,
    fill: Box<FillFn>,
) -> FillGuard {
    let data = Box::into_raw(Box::new(FillData {
        fill,
        width,
        height,
        bytes_per_pixel,
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
