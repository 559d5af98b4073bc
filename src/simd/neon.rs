//! NEON primitives shared by the aarch64 kernels.

use std::arch::aarch64::*;
use std::arch::asm;

/// fp16×4 → f32×4 (`fcvtl`).
#[inline(always)]
pub(crate) unsafe fn cvt_f16x4_f32x4(h: uint16x4_t) -> float32x4_t {
    let r: float32x4_t;
    // SAFETY: pure register instruction of the base ARMv8 ISA; no memory access.
    unsafe { asm!("fcvtl {0:v}.4s, {1:v}.4h", out(vreg) r, in(vreg) h, options(pure, nomem, nostack)) };
    r
}

/// f32×4 → fp16×4 (`fcvtn`, round to nearest even under the default FPCR).
#[inline(always)]
pub(crate) unsafe fn cvt_f32x4_f16x4(f: float32x4_t) -> uint16x4_t {
    let r: uint16x4_t;
    // SAFETY: pure register instruction of the base ARMv8 ISA; no memory access.
    unsafe { asm!("fcvtn {0:v}.4h, {1:v}.4s", out(vreg) r, in(vreg) f, options(pure, nomem, nostack)) };
    r
}
