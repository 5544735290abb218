//! The process's memory allocator, set once before a command runs.
//!
//! A diagnosis allocates and frees vectors of 10⁵–10⁶ samples at every model evaluation
//! (predictions, residuals, finite-difference columns). glibc's malloc serves such blocks with
//! `mmap` and returns freed heap tops to the kernel, so each evaluation faulted its pages in
//! again, zeroed by the kernel: measured, 617 000 minor page faults and 11 % of the run time of
//! the README's run-time command (docs/diagnose.md, "Session 39"). Keeping freed memory in the
//! process (an `mmap` threshold at glibc's ceiling of 32 MiB, a trim threshold of 1 GiB) takes
//! it to 41 000 faults and changes no number: the same arithmetic on the same values.
//! `mallopt(3)`; other C libraries are left as they are.

/// Keeps freed blocks in the process (module docs). Call once, before the work starts.
pub fn keep_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets two of glibc's malloc parameters; it is called before any
    // thread of ours exists, and an unaccepted value leaves the default in place (return 0).
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 1 << 30);
    }
}
