//! Thread-count-independent gradient reduction.
//!
//! A batch is cut into [`SLOTS`] contiguous parts whose boundaries depend only on the batch
//! size. Each part accumulates its parameter gradient in its own buffer in sample order, on
//! whatever thread rayon picks; the buffers are then added in slot order. The floating-point
//! operations, and so the result, are the same on 1 thread or 64.

use std::ops::Range;

/// Parts a batch is cut into (enough to keep 8 cores busy; each costs one gradient buffer).
pub const SLOTS: usize = 8;

/// The sample range of slot `s` in a batch of `n`.
pub fn slot_range(n: usize, s: usize) -> Range<usize> {
    (n * s / SLOTS)..(n * (s + 1) / SLOTS)
}

/// `out += Σ_s parts[s]`, added part by part in slot order (so the floating-point sum is the
/// same on any thread count). Overwrite by zeroing `out` first.
pub fn accumulate_in_order<'a>(parts: impl IntoIterator<Item = &'a [f32]>, out: &mut [f32]) {
    for part in parts {
        for (o, v) in out.iter_mut().zip(part) {
            *o += v;
        }
    }
}

/// Splits `buf` (`n` rows of `stride` elements) into the [`SLOTS`] row ranges of
/// [`slot_range`] (an array: no allocation per call).
pub fn split_rows<T>(buf: &mut [T], n: usize, stride: usize) -> [&mut [T]; SLOTS] {
    let mut rest = &mut buf[..n * stride];
    std::array::from_fn(|s| {
        let (head, tail) = std::mem::take(&mut rest).split_at_mut(slot_range(n, s).len() * stride);
        rest = tail;
        head
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_tile_the_batch() {
        for n in [0, 1, 7, 8, 9, 1000] {
            let mut next = 0;
            for s in 0..SLOTS {
                let r = slot_range(n, s);
                assert_eq!(r.start, next);
                next = r.end;
            }
            assert_eq!(next, n);
        }
    }
}
