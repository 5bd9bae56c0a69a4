//! How the process's allocator keeps memory it frees.
//!
//! A live rig allocates and frees buffers of megabytes at the frame rate:
//! camera frames, composed views, thumbnails, and the window's vertex and
//! texture data inside Mesa. glibc's malloc serves blocks above its mmap
//! threshold (128 KiB at first, growing to at most 32 MiB as such blocks are
//! freed) with their own mappings, and gives a heap's freed top back to the
//! kernel above its trim threshold. Either way each new buffer is faulted in
//! page by page again: the window's thread spent as much time in the
//! kernel's page faults and unmapping as in its own code.
//!
//! [`keep_freed_memory`] serves every block below 32 MiB from the heaps and
//! keeps up to 128 MiB of freed memory per heap for reuse. The process's
//! resident memory then stays near its peak instead of following each
//! frame's allocations: figures in BENCHMARKS.md ("The window").
#![allow(unsafe_code)]

/// Blocks below this come from the heaps (glibc's largest dynamic value).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: libc::c_int = 32 << 20;
/// Freed memory a heap keeps before it returns any to the kernel.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const TRIM_THRESHOLD: libc::c_int = 128 << 20;

/// Tells the allocator to keep freed memory for reuse (glibc on Linux;
/// elsewhere nothing). Returns whether both settings were taken. Call it
/// before threads start.
pub fn keep_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: `mallopt` only sets malloc's parameters; called before
        // the app starts its threads.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD) == 1
        }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}
