//! CPU levels and run-time dispatch.
//!
//! Every hot kernel exists once per [`CpuLevel`]: a portable `_scalar` twin that is its
//! specification, and hand-written SIMD for AVX2+FMA+F16C (x86_64) and NEON (aarch64). The
//! AVX-512 level adds 512-bit MLP layer kernels (the FMA-bound part of training, ~2× the FMA
//! throughput of AVX2 where the core has two 512-bit FMA units) and a 16-lane hash-grid
//! forward; every other kernel runs its AVX2 version there, which the level includes
//! ([`CpuLevel::includes`]).
//! The level is **detected once at run time** — never chosen only at compile time — so a
//! robot build for a generic target still runs the vector code its CPU has.
//!
//! An [`Isa`] value is proof that the host supports its level: the only ways to obtain one
//! are [`Isa::scalar`], [`Isa::detect`], [`Isa::new`] and [`Isa::all`], which check the CPU.
//! Kernels therefore take an `Isa` and may call `#[target_feature]` code without re-checking.
//!
//! The AMX level runs the MLP's layer products on AMX tiles with bf16 operands
//! and fp32 sums (mixed precision; [`CpuLevel::Amx`]); it is the one level whose results
//! differ from the others' beyond rounding order.
//!
//! The environment variable `RNERF_CPU_LEVEL` (`scalar`, `avx2`, `avx512`, `amx`, `neon`) may
//! **lower** the level (for testing and for bisecting a numeric difference); a value above
//! what the host has is ignored with a warning, never obeyed.

pub(crate) mod entry;
pub mod fpmode;
#[cfg(target_arch = "aarch64")]
pub(crate) mod neon;

pub(crate) use entry::safe_entry;

use std::fmt;
use std::sync::OnceLock;

/// Name of the environment variable that may lower the CPU level.
pub const CPU_LEVEL_ENV: &str = "RNERF_CPU_LEVEL";

/// Ordered instruction-set levels: `Scalar` < `Avx2` < `Avx512` < `Amx` on x86_64, `Scalar` <
/// `Neon` on aarch64.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub enum CpuLevel {
    /// Portable Rust, no explicit SIMD. Every kernel's reference.
    Scalar,
    /// x86_64 with AVX2, FMA and F16C (Haswell / Zen 1 and later).
    Avx2,
    /// x86_64 with AVX-512F on top of the AVX2 level (Skylake-SP, Ice Lake, Sapphire Rapids,
    /// Zen 4 and later): 512-bit MLP layer kernels and hash-grid forward, the AVX2 kernels
    /// elsewhere; the same bits as `Avx2`.
    Avx512,
    /// aarch64 Advanced SIMD (NEON; part of every ARMv8-A core).
    Neon,
    /// x86_64 with AMX-BF16 tiles and AVX512-BF16 on top of the AVX-512 level (Sapphire Rapids
    /// and later), with the kernel's permission to use the tile state. The MLP's layer
    /// products (forward, dL/dx and weight gradients) run on the tiles with **bf16 operands**
    /// (round to nearest even) and fp32 sums — mixed precision, as tiny-cuda-nn's fp16 MLP,
    /// with fp32 master weights; the hash grid, Adam and everything else stay fp32 (the
    /// AVX-512 and AVX2 kernels). Unlike the other
    /// x86 levels it does **not** give `Avx2`'s bits: `RNERF_CPU_LEVEL=avx512` reproduces
    /// those. See `mlp::amx`.
    Amx,
}

impl CpuLevel {
    /// The name used by `RNERF_CPU_LEVEL` and printed by `rnerf bench`.
    pub fn name(self) -> &'static str {
        match self {
            CpuLevel::Scalar => "scalar",
            CpuLevel::Avx2 => "avx2",
            CpuLevel::Avx512 => "avx512",
            CpuLevel::Neon => "neon",
            CpuLevel::Amx => "amx",
        }
    }

    /// Parses a level name (`scalar`, `avx2`, `avx512`, `amx`, `neon`), case-insensitively.
    pub fn parse(s: &str) -> Option<CpuLevel> {
        match s.trim().to_ascii_lowercase().as_str() {
            "scalar" => Some(CpuLevel::Scalar),
            "avx2" => Some(CpuLevel::Avx2),
            "avx512" => Some(CpuLevel::Avx512),
            "neon" => Some(CpuLevel::Neon),
            "amx" => Some(CpuLevel::Amx),
            _ => None,
        }
    }

    /// Whether this CPU can execute the level's instructions.
    pub fn host_supports(self) -> bool {
        match self {
            CpuLevel::Scalar => true,
            CpuLevel::Avx2 => host_has_avx2(),
            CpuLevel::Avx512 => host_has_avx512(),
            CpuLevel::Neon => host_has_neon(),
            CpuLevel::Amx => host_has_amx(),
        }
    }

    /// Whether code written for `other` may run at this level: the level itself, scalar, and
    /// the x86 levels below an x86 level (AVX-512 requires everything AVX2 does, AMX
    /// everything AVX-512 does).
    pub fn includes(self, other: CpuLevel) -> bool {
        use CpuLevel::*;
        self == other || other == Scalar || matches!((self, other), (Avx512, Avx2) | (Amx, Avx512 | Avx2))
    }

    /// Whether the level's MLP products have fp32 operands (every level but `Amx`, whose
    /// layer products take bf16 operands). The fp32 levels agree with the scalar spec to
    /// rounding; `Amx` agrees with its bf16 twins (`mlp::scalar::matmul_bf16`,
    /// `matmul_tn_acc_bf16`).
    pub fn mlp_is_fp32(self) -> bool {
        self != CpuLevel::Amx
    }

    /// The highest level the host supports, ignoring `RNERF_CPU_LEVEL`.
    pub fn host_max() -> CpuLevel {
        if host_has_amx() {
            CpuLevel::Amx
        } else if host_has_avx512() {
            CpuLevel::Avx512
        } else if host_has_avx2() {
            CpuLevel::Avx2
        } else if host_has_neon() {
            CpuLevel::Neon
        } else {
            CpuLevel::Scalar
        }
    }
}

impl fmt::Display for CpuLevel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

#[cfg(target_arch = "x86_64")]
fn host_has_avx2() -> bool {
    is_x86_feature_detected!("avx2") && is_x86_feature_detected!("fma") && is_x86_feature_detected!("f16c")
}
#[cfg(not(target_arch = "x86_64"))]
fn host_has_avx2() -> bool {
    false
}

#[cfg(target_arch = "x86_64")]
fn host_has_avx512() -> bool {
    host_has_avx2() && is_x86_feature_detected!("avx512f")
}
#[cfg(not(target_arch = "x86_64"))]
fn host_has_avx512() -> bool {
    false
}

/// AMX-BF16 and AMX-TILE (CPUID leaf 7), AVX512-BF16 for the conversions, and the kernel's
/// permission to use the tile data state (`arch_prctl(ARCH_REQ_XCOMP_PERM, XTILEDATA)`, Linux
/// ≥ 5.16), requested once per process.
#[cfg(target_arch = "x86_64")]
fn host_has_amx() -> bool {
    static AMX: OnceLock<bool> = OnceLock::new();
    *AMX.get_or_init(|| {
        if !(host_has_avx512() && is_x86_feature_detected!("avx512bf16") && is_x86_feature_detected!("avx512bw")) {
            return false;
        }
        // CPUID leaf 7 exists on every CPU with AVX-512 (checked above).
        let leaf7 = std::arch::x86_64::__cpuid_count(7, 0);
        let (amx_bf16, amx_tile) = (leaf7.edx & (1 << 22) != 0, leaf7.edx & (1 << 24) != 0);
        if !(amx_bf16 && amx_tile) {
            return false;
        }
        const ARCH_REQ_XCOMP_PERM: libc::c_long = 0x1023;
        const XFEATURE_XTILEDATA: libc::c_long = 18;
        // SAFETY: arch_prctl with these arguments only changes the process's permitted
        // xsave features; it reads and writes no memory of ours.
        unsafe { libc::syscall(libc::SYS_arch_prctl, ARCH_REQ_XCOMP_PERM, XFEATURE_XTILEDATA) == 0 }
    })
}
#[cfg(not(target_arch = "x86_64"))]
fn host_has_amx() -> bool {
    false
}

#[cfg(target_arch = "aarch64")]
fn host_has_neon() -> bool {
    std::arch::is_aarch64_feature_detected!("neon")
}
#[cfg(not(target_arch = "aarch64"))]
fn host_has_neon() -> bool {
    false
}

/// A CPU level the host is known to support. Holding one proves it (see the module docs).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Isa(CpuLevel);

impl Isa {
    /// The portable level; always available.
    pub const fn scalar() -> Isa {
        Isa(CpuLevel::Scalar)
    }

    /// `Some` when the host supports `level`.
    pub fn new(level: CpuLevel) -> Option<Isa> {
        level.host_supports().then_some(Isa(level))
    }

    /// The level kernels use by default: the host's best, lowered by `RNERF_CPU_LEVEL`.
    /// Detected once per process.
    pub fn detect() -> Isa {
        static DETECTED: OnceLock<Isa> = OnceLock::new();
        *DETECTED.get_or_init(|| {
            let host = CpuLevel::host_max();
            let Ok(value) = std::env::var(CPU_LEVEL_ENV) else {
                return Isa(host);
            };
            match CpuLevel::parse(&value) {
                Some(asked) if host.includes(asked) => Isa(asked),
                Some(asked) => {
                    eprintln!(
                        "warning: {CPU_LEVEL_ENV}={value}: this CPU does not support {asked}; using {host} \
                         (the variable may lower the level, never raise it)"
                    );
                    Isa(host)
                }
                None => {
                    eprintln!(
                        "warning: {CPU_LEVEL_ENV}={value} is not one of scalar, avx2, avx512, amx, neon; using {host}"
                    );
                    Isa(host)
                }
            }
        })
    }

    /// Every level the host supports up to the detected one, lowest first. Tests run each
    /// kernel on each of these; with `RNERF_CPU_LEVEL=scalar` this is just `[scalar]`.
    pub fn all() -> Vec<Isa> {
        let top = Isa::detect();
        [CpuLevel::Scalar, CpuLevel::Avx2, CpuLevel::Avx512, CpuLevel::Amx, CpuLevel::Neon]
            .into_iter()
            .filter(|&l| top.0.includes(l))
            .filter_map(Isa::new)
            .collect()
    }

    /// The level this value stands for.
    pub fn level(self) -> CpuLevel {
        self.0
    }
}

impl fmt::Display for Isa {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        self.0.fmt(f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_are_ordered_and_named() {
        assert!(CpuLevel::Scalar < CpuLevel::Avx2);
        assert!(CpuLevel::Avx2 < CpuLevel::Avx512);
        assert!(CpuLevel::Scalar < CpuLevel::Neon);
        assert!(CpuLevel::Avx512 < CpuLevel::Amx);
        assert!(CpuLevel::Amx.includes(CpuLevel::Avx512) && CpuLevel::Amx.includes(CpuLevel::Avx2));
        assert!(!CpuLevel::Avx512.includes(CpuLevel::Amx));
        for l in [CpuLevel::Scalar, CpuLevel::Avx2, CpuLevel::Avx512, CpuLevel::Amx, CpuLevel::Neon] {
            assert_eq!(CpuLevel::parse(l.name()), Some(l));
            assert!(l.includes(l) && l.includes(CpuLevel::Scalar));
        }
        assert!(CpuLevel::Avx512.includes(CpuLevel::Avx2));
        assert!(!CpuLevel::Avx2.includes(CpuLevel::Avx512));
        assert!(!CpuLevel::Neon.includes(CpuLevel::Avx2) && !CpuLevel::Avx512.includes(CpuLevel::Neon));
        assert_eq!(CpuLevel::parse("sse9"), None);
    }

    #[test]
    fn detected_level_is_supported_and_all_starts_with_scalar() {
        let d = Isa::detect();
        assert!(d.level().host_supports());
        let all = Isa::all();
        assert_eq!(all[0], Isa::scalar());
        assert_eq!(*all.last().unwrap(), d);
    }
}
