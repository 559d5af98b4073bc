//! Large parameter buffers backed by 2 MiB pages where the OS offers them.
//!
//! The hash-grid tables are read and written at random (a training step gathers 8 corners
//! × 16 levels per sample from tens of MiB); with 4 KiB pages most of those accesses miss the
//! TLB. On Linux with transparent huge pages in `madvise` mode (the common default) a fresh,
//! untouched allocation marked `MADV_HUGEPAGE` is faulted in as 2 MiB pages. Elsewhere, or
//! when `RNERF_HUGE_PAGES=0`, buffers are ordinary zeroed vectors — same values, same results.

use bytemuck::Zeroable;

/// Buffers smaller than this are left alone (a huge page would be mostly empty).
const MIN_BYTES: usize = 4 << 20;
const HUGE_PAGE: usize = 2 << 20;

/// Whether huge pages are asked for (`RNERF_HUGE_PAGES=0` turns them off, for measuring).
pub fn huge_pages_enabled() -> bool {
    static ENABLED: std::sync::OnceLock<bool> = std::sync::OnceLock::new();
    *ENABLED.get_or_init(|| std::env::var("RNERF_HUGE_PAGES").map_or(true, |v| v != "0"))
}

/// `n` zeroed values; large buffers are marked for huge pages before their first touch.
pub fn zeroed_vec<T: Zeroable + Copy>(n: usize) -> Vec<T> {
    let v: Vec<T> = bytemuck::zeroed_vec(n);
    let bytes = n * std::mem::size_of::<T>();
    if bytes >= MIN_BYTES && huge_pages_enabled() {
        advise_huge(v.as_ptr() as usize, bytes);
    }
    v
}

/// A copy of `src` in a buffer from [`zeroed_vec`].
pub fn copied_vec<T: Zeroable + Copy>(src: &[T]) -> Vec<T> {
    let mut v = zeroed_vec(src.len());
    v.copy_from_slice(src);
    v
}

#[cfg(target_os = "linux")]
fn advise_huge(addr: usize, bytes: usize) {
    // The 2 MiB-aligned middle of the buffer; the ends stay in small pages.
    let start = addr.next_multiple_of(HUGE_PAGE);
    let end = (addr + bytes) / HUGE_PAGE * HUGE_PAGE;
    if end > start {
        // SAFETY: [start, end) lies inside the live allocation `addr..addr + bytes` owned by the
        // caller's vector; MADV_HUGEPAGE only changes how the kernel backs those pages, never
        // their contents or validity. A failure (e.g. THP disabled) leaves small pages.
        unsafe {
            libc::madvise(start as *mut libc::c_void, end - start, libc::MADV_HUGEPAGE);
        }
    }
}

#[cfg(not(target_os = "linux"))]
fn advise_huge(_addr: usize, _bytes: usize) {}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn buffers_are_zeroed_and_copies_equal() {
        let v: Vec<f32> = zeroed_vec(3 << 20);
        assert!(v.iter().all(|&x| x == 0.0));
        let src: Vec<u32> = (0..(2u32 << 20)).collect();
        assert_eq!(copied_vec(&src), src);
        assert!(zeroed_vec::<f32>(0).is_empty());
    }
}
