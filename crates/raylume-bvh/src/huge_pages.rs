//! [`HugePageArray`]: a read-only array the CPU's walks read at random, in memory the kernel
//! is asked to back with 2 MiB pages.
//!
//! A large scene's walk arrays and shading records are tens of megabytes read a few bytes at a
//! random place per ray: with 4 KiB pages each of those reads needs its page's translation,
//! and a core's TLB holds a few thousand of them (12 MiB of 4 KiB pages on the dev VMs' cores),
//! so most of a large scene's reads also walk the page tables. With 2 MiB pages the living
//! room's ~46 MB are 23 translations. On Linux an array asked for huge pages is copied into
//! memory aligned to 2 MiB, its size rounded up to a multiple of it, and marked
//! `MADV_HUGEPAGE` before it is written (the kernel maps huge pages at the first touch where
//! `transparent_hugepage/enabled` is `always` or `madvise`, the defaults of Debian and most
//! distributions; where it is `never` the array is ordinary memory, the same values). Arrays
//! smaller than [`HUGE_PAGE_MIN_BYTES`], arrays not asked, and other systems keep an ordinary
//! `Vec`. The contents are the slice the array was made from, bit for bit: only where the
//! bytes live changes. Huge pages are not free: the kernel gathers (compacts) free 2 MiB
//! pages at the first touch, ~3-4 ms a MB on the dev VM, so only work that reads the array
//! often enough should ask (the CPU tracer asks for long renders: `raylume_kernels`'
//! `CpuTracer::set_huge_pages`).
//!
//! (Measured first with glibc's `GLIBC_TUNABLES=glibc.malloc.hugetlb=1`, every allocation of
//! the process in huge pages: the living room's CPU trace 3.3 % faster, six rounds out of six,
//! on the AMD EPYC dev VM; that setting also made a large scene's first touch of its big
//! buffers several times slower, which the tracer's read-only arrays, written once, do not
//! pay: `docs/RESULTS.md`, issue 15, session 47.)

use std::alloc::{Layout, alloc, dealloc, handle_alloc_error};
use std::ops::Deref;
use std::ptr::NonNull;

/// The page size the arrays are aligned and rounded to where they take huge pages.
pub const HUGE_PAGE_BYTES: usize = 2 << 20;

/// Arrays of at least this many bytes take huge pages (on Linux); smaller ones, which a core's
/// TLB covers anyway, would waste up to a page each.
pub const HUGE_PAGE_MIN_BYTES: usize = HUGE_PAGE_BYTES;

/// An immutable array of `T`, in huge pages where it was asked to be, is large enough and the
/// system gives them, else in an ordinary `Vec`; dereferences to `&[T]`.
pub struct HugePageArray<T: Copy>(Storage<T>);

enum Storage<T> {
    /// Ordinary memory: the vector the array was made from, not copied.
    Ordinary(Vec<T>),
    /// A 2 MiB-aligned allocation of `layout` marked for huge pages, holding `len` items.
    Huge {
        ptr: NonNull<T>,
        len: usize,
        layout: Layout,
    },
}

// SAFETY: the array owns its memory and hands out shared references only, as a `Box<[T]>`.
unsafe impl<T: Copy + Send> Send for HugePageArray<T> {}
// SAFETY: as `Send`; no interior mutability.
unsafe impl<T: Copy + Sync> Sync for HugePageArray<T> {}

impl<T: Copy> HugePageArray<T> {
    /// A copy of `items` in huge pages where the array takes at least
    /// [`HUGE_PAGE_MIN_BYTES`] and the system is Linux, else in an ordinary vector.
    pub fn from_slice(items: &[T]) -> Self {
        if huge_pages_for(std::mem::size_of_val(items)) {
            Self::copy_huge(items)
        } else {
            Self(Storage::Ordinary(items.to_vec()))
        }
    }

    /// `items` in huge pages (a copy, the vector freed) where `huge` asks for them and
    /// [`HugePageArray::from_slice`] would give them; else the vector itself, not copied.
    pub fn from_vec(items: Vec<T>, huge: bool) -> Self {
        if huge && huge_pages_for(std::mem::size_of_val(items.as_slice())) {
            Self::copy_huge(&items)
        } else {
            Self(Storage::Ordinary(items))
        }
    }

    fn copy_huge(items: &[T]) -> Self {
        let bytes = std::mem::size_of_val(items);
        let layout = Layout::from_size_align(
            bytes.next_multiple_of(HUGE_PAGE_BYTES),
            HUGE_PAGE_BYTES.max(align_of::<T>()),
        )
        .expect("a slice's size rounded to a huge page fits a layout");
        // SAFETY: the layout's size is not zero (`bytes >= HUGE_PAGE_MIN_BYTES`).
        let raw = unsafe { alloc(layout) };
        let Some(ptr) = NonNull::new(raw.cast::<T>()) else {
            handle_alloc_error(layout)
        };
        advise_huge_pages(raw, layout.size());
        // SAFETY: `ptr` is a fresh allocation of at least `items.len()` `T`s, aligned for `T`,
        // which cannot overlap `items`.
        unsafe { std::ptr::copy_nonoverlapping(items.as_ptr(), ptr.as_ptr(), items.len()) };
        Self(Storage::Huge {
            ptr,
            len: items.len(),
            layout,
        })
    }

    /// Whether the array's memory was marked for huge pages (the kernel may still have given
    /// ordinary ones: `/proc/self/smaps` says).
    pub fn advised(&self) -> bool {
        matches!(self.0, Storage::Huge { .. })
    }
}

/// Whether an array of `bytes` takes huge pages when asked.
fn huge_pages_for(bytes: usize) -> bool {
    cfg!(target_os = "linux") && bytes >= HUGE_PAGE_MIN_BYTES
}

/// Asks the kernel to back `len` bytes at `ptr` (2 MiB aligned) with huge pages. A failure
/// (a kernel without transparent huge pages) leaves ordinary pages: nothing to report.
#[cfg(target_os = "linux")]
fn advise_huge_pages(ptr: *mut u8, len: usize) {
    // SAFETY: `[ptr, ptr + len)` is memory this process just allocated; `madvise` with
    // `MADV_HUGEPAGE` changes how it is backed, not its contents or its mapping.
    unsafe {
        libc::madvise(ptr.cast(), len, libc::MADV_HUGEPAGE);
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge_pages(_ptr: *mut u8, _len: usize) {}

impl<T: Copy> Drop for HugePageArray<T> {
    fn drop(&mut self) {
        if let Storage::Huge { ptr, layout, .. } = self.0 {
            // SAFETY: allocated in `copy_huge` with this layout; `T: Copy` has no drop.
            unsafe { dealloc(ptr.as_ptr().cast(), layout) };
        }
    }
}

impl<T: Copy> Deref for HugePageArray<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        match &self.0 {
            Storage::Ordinary(v) => v,
            // SAFETY: `ptr` holds `len` initialised `T`s for the array's life.
            Storage::Huge { ptr, len, .. } => unsafe {
                std::slice::from_raw_parts(ptr.as_ptr(), *len)
            },
        }
    }
}

impl<T: Copy> Clone for HugePageArray<T> {
    /// A copy in the same kind of memory.
    fn clone(&self) -> Self {
        Self::from_vec(self.to_vec(), self.advised())
    }
}

impl<T: Copy> Default for HugePageArray<T> {
    fn default() -> Self {
        Self(Storage::Ordinary(Vec::new()))
    }
}

impl<T: Copy + std::fmt::Debug> std::fmt::Debug for HugePageArray<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_list().entries(self.iter()).finish()
    }
}

impl<T: Copy> From<Vec<T>> for HugePageArray<T> {
    /// The vector itself, in ordinary memory ([`HugePageArray::from_vec`] with `false`).
    fn from(items: Vec<T>) -> Self {
        Self::from_vec(items, false)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_array_holds_the_slice_it_was_made_from() {
        for n in [0usize, 1, 7, 1000, (3 << 20) / 4 + 5] {
            let items: Vec<u32> = (0..n as u32)
                .map(|i| i.wrapping_mul(2_654_435_761))
                .collect();
            let big = n * 4 >= HUGE_PAGE_MIN_BYTES;
            for (a, asked) in [
                (HugePageArray::from_slice(&items), true),
                (HugePageArray::from_vec(items.clone(), true), true),
                (HugePageArray::from_vec(items.clone(), false), false),
                (HugePageArray::from(items.clone()), false),
            ] {
                assert_eq!(&a[..], &items[..]);
                assert_eq!(a.clone()[..], items[..]);
                assert_eq!(a.clone().advised(), a.advised());
                let huge = asked && big && cfg!(target_os = "linux");
                assert_eq!(a.advised(), huge, "{n} items, asked {asked}");
                if a.advised() {
                    assert_eq!(a.as_ptr() as usize % HUGE_PAGE_BYTES, 0);
                }
            }
        }
    }

    #[test]
    fn over_aligned_items_keep_their_alignment() {
        #[derive(Clone, Copy, PartialEq, Debug)]
        #[repr(C, align(64))]
        struct Line([u8; 64]);
        for n in [0usize, 3, 40_000] {
            let items = vec![Line([7; 64]); n];
            for a in [
                HugePageArray::from_slice(&items),
                HugePageArray::from_vec(items.clone(), false),
            ] {
                assert_eq!(a.as_ptr() as usize % 64, 0);
                assert_eq!(&a[..], &items[..]);
            }
        }
    }
}
