//! Floating-point mode of the calling thread: flush denormals to zero.
//!
//! Training drives many values (Adam moments, gradients of rarely hit table entries) into the
//! denormal range, where x86 arithmetic is ~100× slower; GPUs flush them. [`flush_denormals`]
//! sets FTZ+DAZ (x86_64 MXCSR) or FZ (aarch64 FPCR) for the current thread; the trainer applies
//! it on every thread of its pool. Results stay deterministic: every thread uses the same mode.

/// Sets flush-to-zero (and denormals-are-zero on x86_64) on the calling thread; returns the
/// previous control word so [`restore`] can put it back.
pub fn flush_denormals() -> u64 {
    #[cfg(target_arch = "x86_64")]
    {
        let mut old: u32 = 0;
        // SAFETY: stmxcsr/ldmxcsr read and write only the SSE control register of this thread;
        // bits 15 (FTZ) and 6 (DAZ) change how denormals are treated, nothing else.
        unsafe {
            std::arch::asm!("stmxcsr [{0}]", in(reg) &mut old, options(nostack));
            let new = old | (1 << 15) | (1 << 6);
            std::arch::asm!("ldmxcsr [{0}]", in(reg) &new, options(nostack, readonly));
        }
        old as u64
    }
    #[cfg(target_arch = "aarch64")]
    {
        let old: u64;
        // SAFETY: reads and writes FPCR of this thread; bit 24 (FZ) flushes denormals.
        unsafe {
            std::arch::asm!("mrs {0}, fpcr", out(reg) old, options(nomem, nostack));
            std::arch::asm!("msr fpcr, {0}", in(reg) old | (1 << 24), options(nomem, nostack));
        }
        old
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    {
        0
    }
}

/// Restores a control word returned by [`flush_denormals`].
pub fn restore(old: u64) {
    #[cfg(target_arch = "x86_64")]
    {
        let v = old as u32;
        // SAFETY: writes back a control word previously read from this register.
        unsafe { std::arch::asm!("ldmxcsr [{0}]", in(reg) &v, options(nostack, readonly)) };
    }
    #[cfg(target_arch = "aarch64")]
    {
        // SAFETY: writes back a control word previously read from this register.
        unsafe { std::arch::asm!("msr fpcr, {0}", in(reg) old, options(nomem, nostack)) };
    }
    #[cfg(not(any(target_arch = "x86_64", target_arch = "aarch64")))]
    let _ = old;
}

/// Runs `f` with denormals flushed on every thread of the rayon pool and on this one, then
/// restores each thread's mode: what a training step (and the end of a run) runs under.
pub fn flushed_on_pool<R>(f: impl FnOnce() -> R) -> R {
    let modes: Vec<u64> = rayon::broadcast(|_| flush_denormals());
    let main_mode = flush_denormals();
    let result = f();
    rayon::broadcast(|ctx| restore(modes[ctx.index()]));
    restore(main_mode);
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn denormals_flush_and_mode_restores() {
        let tiny = std::hint::black_box(f32::MIN_POSITIVE);
        let half = std::hint::black_box(0.5f32);
        assert!(tiny * half > 0.0, "denormals are on by default");
        let old = flush_denormals();
        let flushed = std::hint::black_box(tiny) * std::hint::black_box(half);
        restore(old);
        assert_eq!(flushed, 0.0);
        assert!(std::hint::black_box(tiny) * std::hint::black_box(half) > 0.0);
    }
}
