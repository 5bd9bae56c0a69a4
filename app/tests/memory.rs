//! The allocator keeps what the app frees (its own process: no other test
//! allocates meanwhile).

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[test]
fn buffers_of_megabytes_come_from_the_heap_once_told() {
    let mapped = || {
        // SAFETY: reads malloc's statistics.
        #[allow(unsafe_code)]
        unsafe {
            libc::mallinfo2().hblks
        }
    };
    let frame = |bytes: usize| std::hint::black_box(vec![1u8; bytes]);
    // By default a 4 MiB frame is a mapping of its own.
    let before = mapped();
    let f = frame(4 << 20);
    assert_eq!(mapped(), before + 1, "a 4 MiB block is mapped by default");
    drop(f);
    assert!(rigview::memory::keep_freed_memory());
    // Now frames of up to 32 MiB come from the heap, and so does the next
    // one after it is freed.
    let before = mapped();
    for bytes in [4 << 20, 12 << 20, 31 << 20] {
        let f = frame(bytes);
        assert_eq!(mapped(), before, "{bytes} bytes");
        drop(f);
    }
    // Larger blocks are still mapped.
    let f = frame(40 << 20);
    assert_eq!(mapped(), before + 1);
    drop(f);
}
