//! The allocator settings of coarsen's programs (the `coarsen` and `coarsen-bench` binaries):
//! big blocks come from malloc's heap, on huge pages where the kernel grants them, and go
//! back to it, so that memory freed by one step of a run is reused by the next instead of
//! being handed back to the system and faulted in again, page by page.
//!
//! glibc's malloc serves each block of 32 MiB or more with a mapping of its own and unmaps
//! it when the block is freed. A run on a big mesh allocates and frees many such blocks
//! (per-face tables of a few million faces, allocated by the main thread even when rayon's
//! threads fill them), so it spent about a tenth of its CPU time in page faults: on the
//! bunny subdivided three times (4.4M faces), `uniform-cvt` touched 2.9 GB of fresh pages
//! for a peak of 1.6 GB. With these settings (no mappings; up to [`KEEP_TOP`] of free
//! space kept at the top of the heap) it touches 1.7 GB, and runs 7 % faster (`qem` 7 %,
//! `adaptive-cvt` 9 %), for a peak 2 % higher (`adaptive-cvt`: 15 %, the free space
//! between live blocks of the heap; those figures kept 256 MiB at the top, all is kept
//! since). A thread's own malloc arena still hands a heap that
//! falls empty back to the system; one arena for all threads would keep those too, but
//! its lock cost more than that saved.
//!
//! Only programs call this: how the process allocates is not a library's choice. The
//! criterion-style benches that time calls in a loop in one process (`qem` against
//! meshoptimizer, `cvt`) keep glibc's defaults: there, each call would reuse the previous
//! call's memory, which a single run does not get (meshoptimizer gained more from that
//! than our simplifiers: QEM's ratio to it went from 1.8 to 2.0). Elsewhere than on Linux
//! with glibc it does nothing.
//!
//! The programs also allocate through [`HugeBlocks`], which asks the kernel for
//! transparent huge pages under every block of 4 MiB or more. Where the kernel grants them
//! on request only (`madvise` mode, as on the machines we measure on), a run got none
//! before. On the bunny subdivided three times, `uniform-cvt` then ran 7 % faster (the
//! median of seven alternating pairs; won six), its time in the kernel fell from 1.1–1.4 s
//! to 0.5–0.6 s, and `adaptive-cvt`'s peak fell by 100–170 MB; `qem` moved inside the
//! noise. Outputs are the same bytes. glibc's own switch (`glibc.malloc.hugetlb=1`)
//! marks the whole heap, small blocks too, and made `qem` slower.

/// Blocks of at least this many bytes are marked for huge pages by [`HugeBlocks`].
pub const HUGE_MIN: usize = 4 << 20;

/// The size of a transparent huge page on x86-64 and aarch64 with 4 KiB pages.
const HUGE_PAGE: usize = 2 << 20;

/// The system allocator, asking the kernel to back each big block (at least [`HUGE_MIN`])
/// with transparent huge pages where the system offers them on request (`madvise` mode).
///
/// A run on a big mesh reads its tables at random (a face index walked down, a heap
/// popped, fans of neighbouring faces): with 4 KiB pages most of those reads also miss the
/// address cache (TLB), and every first write to a page costs a fault. With 2 MiB pages
/// there are 512 times fewer of both. The block's whole 2 MiB-aligned interior is marked
/// (`madvise(MADV_HUGEPAGE)`), once per allocation; memory freed and reused keeps the
/// mark. Where the kernel grants no huge page, or elsewhere than on Linux, it behaves as
/// the system allocator.
#[derive(Clone, Copy, Debug, Default)]
pub struct HugeBlocks;

// SAFETY: every call goes to the system allocator with the caller's arguments; the only
// addition, `madvise(MADV_HUGEPAGE)` on whole pages inside a block just allocated, changes
// how the kernel backs those pages, never their content or the block's bounds.
#[allow(unsafe_code)]
unsafe impl std::alloc::GlobalAlloc for HugeBlocks {
    #[inline]
    unsafe fn alloc(&self, layout: std::alloc::Layout) -> *mut u8 {
        // SAFETY: the caller's contract is the system allocator's.
        let p = unsafe { std::alloc::System.alloc(layout) };
        advise(p, layout.size());
        p
    }

    #[inline]
    unsafe fn alloc_zeroed(&self, layout: std::alloc::Layout) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { std::alloc::System.alloc_zeroed(layout) };
        advise(p, layout.size());
        p
    }

    #[inline]
    unsafe fn dealloc(&self, ptr: *mut u8, layout: std::alloc::Layout) {
        // SAFETY: as `alloc`.
        unsafe { std::alloc::System.dealloc(ptr, layout) }
    }

    #[inline]
    unsafe fn realloc(&self, ptr: *mut u8, layout: std::alloc::Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as `alloc`.
        let p = unsafe { std::alloc::System.realloc(ptr, layout, new_size) };
        advise(p, new_size);
        p
    }
}

/// Marks the huge-page interior of the block at `p` of `size` bytes for huge pages.
#[inline]
fn advise(p: *mut u8, size: usize) {
    #[cfg(target_os = "linux")]
    if let Some((start, len)) = huge_interior(p as usize, size) {
        linux::advise_huge(start, len);
    }
    #[cfg(not(target_os = "linux"))]
    let _ = (p, size);
}

/// The whole 2 MiB pages inside the block at address `p` of `size` bytes, as (start,
/// length), when the block is big enough ([`HUGE_MIN`]) and holds at least one.
fn huge_interior(p: usize, size: usize) -> Option<(usize, usize)> {
    if size < HUGE_MIN || p == 0 {
        return None;
    }
    let start = p.checked_next_multiple_of(HUGE_PAGE)?;
    let end = p.checked_add(size)? / HUGE_PAGE * HUGE_PAGE;
    (end > start).then(|| (start, end - start))
}

#[cfg(target_os = "linux")]
#[allow(unsafe_code)]
mod linux {
    /// `madvise(MADV_HUGEPAGE)` on `len` bytes at page-aligned address `start`; a refusal
    /// (no THP in this kernel) changes nothing, so its result is not looked at.
    pub fn advise_huge(start: usize, len: usize) {
        // SAFETY: the range lies inside a block the allocator just handed out; the advice
        // changes only how its pages are backed.
        unsafe {
            libc::madvise(start as *mut libc::c_void, len, libc::MADV_HUGEPAGE);
        }
    }
}

/// Free space at the top of the heap that `free` keeps instead of handing back to the
/// system: all of a run's (2 GiB, the most malloc's setting takes).
///
/// Memory handed back in the middle of a run and taken again later costs as much as
/// memory never touched on the machines we measure on, whose host takes back what the
/// guest frees within seconds: with 256 MiB, `uniform-cvt` on the bunny subdivided three
/// times gave back 480 MB after `cluster.cvt` and faulted it in again at the post-process's
/// finest level, 0.3–0.4 s of kernel time on both cores.
pub const KEEP_TOP: usize = (2 << 30) - 1;

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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_interior_is_the_whole_huge_pages_inside_a_big_block() {
        const M: usize = HUGE_PAGE;
        // Small blocks and null pointers get no advice.
        assert_eq!(huge_interior(M, HUGE_MIN - 1), None);
        assert_eq!(huge_interior(0, HUGE_MIN), None);
        // An aligned block: all of it.
        assert_eq!(huge_interior(10 * M, HUGE_MIN), Some((10 * M, HUGE_MIN)));
        // A misaligned one: from the next boundary to the last one inside.
        assert_eq!(huge_interior(10 * M + 16, 3 * M), Some((11 * M, 2 * M)));
        assert_eq!(huge_interior(10 * M + 16, 2 * M + 8), Some((11 * M, M)));
        // Blocks at the top of the address space do not overflow.
        assert_eq!(huge_interior(usize::MAX - M, HUGE_MIN), None);
    }
}
