//! How the `touchc` process asks its allocator to hand freed memory back: set once at
//! start by the command line and by the benchmarks that measure its memory.
//!
//! glibc serves a block of at least its mmap threshold from a mapping of its own,
//! returned to the system when freed, and the rest from its heaps, which keep what is
//! freed below live blocks. The threshold starts at 128 KB and rises to the largest
//! mapped block freed (up to 32 MB), so after the first large temporaries a compile's
//! buffers of a few MB come from the heap and stay there once freed: compiling an hour
//! of real touch, 37 MB that no stage still uses sit beside the 230 MB of the 1 kHz
//! signal when it is made (`cargo run --release -p touchc --example hour`: peak 311 MB
//! with the rising threshold, 274 MB with it fixed).

/// The size from which a block gets its own mapping: 1 MB (a frame chunk's buffers and
/// a trajectory's points stay in the heap; the per-stage arrays of a long recording do
/// not).
pub const MMAP_THRESHOLD_BYTES: usize = 1 << 20;

/// Fixes the allocator's mmap threshold at [`MMAP_THRESHOLD_BYTES`], so that freed large
/// blocks go back to the system; does nothing where the allocator is not glibc's.
/// Call it before the work starts.
pub fn return_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: `mallopt` only changes a tunable of the allocator; any value is valid, and
    // glibc takes the lock it needs.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD_BYTES as libc::c_int);
    }
}
