//! A global allocator for the big parameter-sized buffers: cache-line alignment and, on Linux,
//! transparent huge pages.
//!
//! Two properties of the hash table's memory matter for speed (`benches/field.rs`):
//! - **Alignment.** The tcnn hash puts the `x` and `x+1` corners (and the `x±1` taps) at indices
//!   that differ only in their low bits; they share a 64-byte cache line only when the table
//!   starts on a line boundary. glibc returns large blocks (served by `mmap`) 16 bytes past a page
//!   boundary, which costs about 20% of the hash-grid forward time.
//! - **Page size.** Parameters, gradients and optimiser moments are 56 MB each for the default
//!   network and are read at random: with 4 KB pages nearly every access misses the TLB. 2 MB
//!   pages gave about +8% on the whole training step.
//!
//! The buffers are plain `Vec<f32>`s the caller owns, so both belong to the allocator. Install
//! this one in the binary:
//!
//! ```ignore
//! #[global_allocator]
//! static ALLOC: neus_aug::field::alloc::LargeAligned = neus_aug::field::alloc::LargeAligned;
//! ```
//!
//! It forwards everything to [`std::alloc::System`]: blocks of at least [`LINE_THRESHOLD`] bytes
//! get 64-byte alignment, blocks of at least [`HUGE_THRESHOLD`] bytes 2 MB alignment and (Linux)
//! `madvise(MADV_HUGEPAGE)`, which lets the kernel back them with huge pages where the system
//! allows it (`/sys/kernel/mm/transparent_hugepage/enabled` = `madvise` or `always`). Nothing
//! else changes, and nothing is required for correctness.

use std::alloc::{GlobalAlloc, Layout, System};

/// Blocks of at least this many bytes are aligned to a cache line.
pub const LINE_THRESHOLD: usize = 1 << 20;
/// Blocks of at least this many bytes are aligned to 2 MB and advised to use huge pages.
pub const HUGE_THRESHOLD: usize = 4 << 20;
const LINE: usize = 64;
const HUGE: usize = 2 << 20;

/// See the module documentation.
#[derive(Debug, Default, Clone, Copy)]
pub struct LargeAligned;

impl LargeAligned {
    /// The layout actually requested from `System`: a pure function of the caller's layout, so
    /// `dealloc` and `realloc` recover it.
    #[inline]
    fn adjusted(l: Layout) -> Layout {
        let align = if l.size() >= HUGE_THRESHOLD {
            HUGE
        } else if l.size() >= LINE_THRESHOLD {
            LINE
        } else {
            return l;
        };
        if l.align() >= align {
            return l;
        }
        // A power of two above the old alignment; the size is unchanged.
        Layout::from_size_align(l.size(), align).unwrap_or(l)
    }

    /// Advises huge pages for a fresh block of `size` bytes (a hint; failures are ignored).
    #[inline]
    fn advise(p: *mut u8, size: usize) {
        #[cfg(target_os = "linux")]
        if !p.is_null() && size >= HUGE_THRESHOLD {
            // SAFETY: `p..p+size` is a block this allocator just obtained; madvise only changes
            // how the kernel backs it.
            unsafe {
                libc::madvise(p.cast(), size, libc::MADV_HUGEPAGE);
            }
        }
        #[cfg(not(target_os = "linux"))]
        let _ = (p, size);
    }
}

// SAFETY: every call is forwarded to `System` with a layout that is a pure function of the
// caller's layout (same size, alignment at least the requested one), so blocks are freed and
// resized with the layout they were allocated with, and each returned block satisfies the
// caller's layout. `alloc_zeroed` zeroes the whole block before returning it.
unsafe impl GlobalAlloc for LargeAligned {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let l = Self::adjusted(layout);
        // SAFETY: forwarded contract (non-zero size, as for the caller).
        let p = unsafe { System.alloc(l) };
        Self::advise(p, l.size());
        p
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let l = Self::adjusted(layout);
        if l.size() < HUGE_THRESHOLD {
            // SAFETY: as in `alloc`.
            return unsafe { System.alloc_zeroed(l) };
        }
        // Advise before the pages are first touched, then zero them.
        // SAFETY: as in `alloc`; the write stays inside the block.
        unsafe {
            let p = System.alloc(l);
            Self::advise(p, l.size());
            if !p.is_null() {
                std::ptr::write_bytes(p, 0, l.size());
            }
            p
        }
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: `ptr` came from this allocator with `adjusted(layout)`.
        unsafe { System.dealloc(ptr, Self::adjusted(layout)) }
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = Self::adjusted(layout);
        let Ok(new_layout) = Layout::from_size_align(new_size, layout.align()) else {
            return std::ptr::null_mut();
        };
        let new = Self::adjusted(new_layout);
        if new.align() == old.align() && new.size() < HUGE_THRESHOLD {
            // SAFETY: `ptr` was allocated with `old`; same alignment, new size.
            return unsafe { System.realloc(ptr, old, new_size) };
        }
        // The block changes alignment class or needs the huge-page advice: move it.
        // SAFETY: `new` has a non-zero size; the copy stays within both blocks; `ptr` is freed
        // with the layout it was allocated with.
        unsafe {
            let q = System.alloc(new);
            Self::advise(q, new.size());
            if !q.is_null() {
                std::ptr::copy_nonoverlapping(ptr, q, layout.size().min(new_size));
                System.dealloc(ptr, old);
            }
            q
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Large blocks come back aligned to a line (1 MB and up) or to 2 MB (4 MB and up), small
    /// ones as requested; zeroed blocks are zero; growing a block across both thresholds and
    /// shrinking it back keeps its contents.
    #[test]
    fn large_blocks_are_aligned_and_realloc_keeps_data() {
        let a = LargeAligned;
        unsafe {
            for (size, align) in [(LINE_THRESHOLD + 12, LINE), (HUGE_THRESHOLD + 4, HUGE)] {
                let l = Layout::from_size_align(size, 4).unwrap();
                let p = a.alloc_zeroed(l);
                assert!(!p.is_null() && (p as usize).is_multiple_of(align));
                assert!((0..size).step_by(4099).all(|i| *p.add(i) == 0));
                a.dealloc(p, l);
            }
            let mut cur = Layout::from_size_align(1000, 4).unwrap();
            let mut q = a.alloc(cur);
            for i in 0..1000 {
                *q.add(i) = (i % 251) as u8;
            }
            for size in [LINE_THRESHOLD * 2, HUGE_THRESHOLD * 2, LINE_THRESHOLD, 500] {
                q = a.realloc(q, cur, size);
                assert!(!q.is_null());
                assert!(
                    (0..500).all(|i| *q.add(i) == (i % 251) as u8),
                    "size {size}"
                );
                if size >= HUGE_THRESHOLD {
                    assert!((q as usize).is_multiple_of(HUGE));
                } else if size >= LINE_THRESHOLD {
                    assert!((q as usize).is_multiple_of(LINE));
                }
                cur = Layout::from_size_align(size, 4).unwrap();
            }
            a.dealloc(q, cur);
        }
    }
}
