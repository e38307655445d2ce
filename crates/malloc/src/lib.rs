//! The allocator settings of coarsen's programs (the `coarsen` and `coarsen-bench` binaries):
//! big blocks come from malloc's heap and go back to it, so that memory freed by one step
//! of a run is reused by the next instead of being handed back to the system and faulted
//! in again, page by page.
//!
//! glibc's malloc serves each block of 32 MiB or more with a mapping of its own and unmaps
//! it when the block is freed. A run on a big mesh allocates and frees many such blocks
//! (per-face tables of a few million faces, allocated by the main thread even when rayon's
//! threads fill them), so it spent about a tenth of its CPU time in page faults: on the
//! bunny subdivided three times (4.4M faces), `uniform-cvt` touched 2.9 GB of fresh pages
//! for a peak of 1.6 GB. With these settings (no mappings; up to [`KEEP_TOP`] of free
//! space kept at the top of the heap) it touches 1.7 GB, and runs 7 % faster (`qem` 7 %,
//! `adaptive-cvt` 9 %), for a peak 2 % higher (`adaptive-cvt`: 15 %, the free space
//! between live blocks of the heap). A thread's own malloc arena still hands a heap that
//! falls empty back to the system; one arena for all threads would keep those too, but
//! its lock cost more than that saved.
//!
//! Only programs call this: how the process allocates is not a library's choice. The
//! criterion-style benches that time calls in a loop in one process (`qem` against
//! meshoptimizer, `cvt`) keep glibc's defaults: there, each call would reuse the previous
//! call's memory, which a single run does not get (meshoptimizer gained more from that
//! than our simplifiers: QEM's ratio to it went from 1.8 to 2.0). Elsewhere than on Linux
//! with glibc it does nothing.

/// Free space at the top of the heap that `free` keeps instead of handing back to the
/// system.
pub const KEEP_TOP: usize = 256 << 20;

/// Sets glibc's malloc to serve every block from its heap and to keep up to [`KEEP_TOP`]
/// of free space at its top; true when both settings took (false elsewhere than on Linux
/// with glibc, where nothing changes). Call it first thing in `main`.
pub fn reuse_freed_memory() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        glibc::reuse_freed_memory()
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        false
    }
}

#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
mod glibc {
    /// See [`super::reuse_freed_memory`].
    pub fn reuse_freed_memory() -> bool {
        let keep = libc::c_int::try_from(super::KEEP_TOP).unwrap_or(libc::c_int::MAX);
        // SAFETY: `mallopt` only changes malloc's tuning parameters, under malloc's own
        // lock; it takes no pointers, and blocks allocated before keep working (a mapped
        // block is still unmapped when freed).
        unsafe {
            libc::mallopt(libc::M_MMAP_MAX, 0) == 1
                && libc::mallopt(libc::M_TRIM_THRESHOLD, keep) == 1
        }
    }
}
