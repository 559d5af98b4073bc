//! Safe entry points of `#[target_feature]` kernels.
//!
//! `safe_entry!(Level, name => name_unchecked(args…))` defines `pub(super) fn name(isa: Isa,
//! args…)`, which checks that `isa`'s level includes `Level` ([`CpuLevel::includes`]: AVX2
//! kernels also run at the AVX-512 level) and calls the unsafe kernel. An [`Isa`] of a
//! level exists only when the CPU has that level's features, which is the whole safety
//! argument — written once, here.
//!
//! [`Isa`]: crate::simd::Isa
//! [`CpuLevel::includes`]: crate::simd::CpuLevel::includes

/// See the module docs.
macro_rules! safe_entry {
    ($level:ident, $name:ident => $unchecked:ident($($arg:ident: $ty:ty),* $(,)?)) => {
        #[doc = concat!("Safe entry point of [`", stringify!($unchecked), "`] at level ", stringify!($level), ".")]
        pub(super) fn $name(isa: $crate::simd::Isa, $($arg: $ty),*) {
            assert!(
                isa.level().includes($crate::simd::CpuLevel::$level),
                concat!(stringify!($name), ": called with the wrong CPU level")
            );
            // SAFETY: an `Isa` of a level that includes this one exists only when the CPU has
            // this level's features (`Isa` is constructed only after run-time detection),
            // which is what the `#[target_feature]` kernel requires.
            unsafe { $unchecked($($arg),*) }
        }
    };
}

pub(crate) use safe_entry;
