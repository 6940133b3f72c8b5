//! The hottest loops compiled twice: for the baseline x86-64 the binary targets (SSE2)
//! and for AVX2, picked at run time by what the CPU has ([`avx2`]).
//!
//! The two builds run the same operations in the same order on the same numbers: Rust
//! never fuses a multiply and an add unless the code asks (`mul_add`), and AVX2 only
//! widens the vector registers the loops already use. So the results are the same to
//! the bit on any x86-64 CPU (the tests compare both builds of each loop); only the
//! time differs. Other architectures run the one build.
//!
//! Each kernel is a `#[inline(always)]` body with two thin entry points, one of them
//! `#[target_feature(enable = "avx2")]`, so that the compiler generates the body, and
//! whatever it inlines, for each.

/// Whether this CPU runs AVX2 (cached by the standard library after the first call).
#[inline]
pub fn avx2() -> bool {
    #[cfg(target_arch = "x86_64")]
    {
        std::arch::is_x86_feature_detected!("avx2")
    }
    #[cfg(not(target_arch = "x86_64"))]
    {
        false
    }
}

/// `kernel! { fn name / name_baseline / name_avx2 (args) -> R { body } }` defines
/// `name`, which runs `body` in its AVX2 build (`name_avx2`) when [`avx2`] says so, else
/// in its baseline build (`name_baseline`); the tests call both.
macro_rules! kernel {
    (
        $(#[$meta:meta])*
        $vis:vis fn $name:ident / $baseline:ident / $wide:ident
        ($($arg:ident : $ty:ty),* $(,)?) $(-> $ret:ty)? $body:block
    ) => {
        $(#[$meta])*
        $vis fn $name($($arg: $ty),*) $(-> $ret)? {
            #[cfg(target_arch = "x86_64")]
            {
                if $crate::wide::avx2() {
                    // SAFETY: the CPU runs AVX2 (checked just above), the one feature
                    // `$wide` is compiled for.
                    return unsafe { $wide($($arg),*) };
                }
            }
            $baseline($($arg),*)
        }

        /// The baseline (SSE2) build of the kernel above.
        #[inline(never)]
        pub(crate) fn $baseline($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body($($arg: $ty),*) $(-> $ret)? $body
            body($($arg),*)
        }

        /// The AVX2 build of the kernel above.
        ///
        /// # Safety
        /// Only on a CPU that runs AVX2 ([`crate::wide::avx2`]).
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = "avx2")]
        #[inline(never)]
        pub(crate) unsafe fn $wide($($arg: $ty),*) $(-> $ret)? {
            #[inline(always)]
            fn body($($arg: $ty),*) $(-> $ret)? $body
            body($($arg),*)
        }
    };
}

pub(crate) use kernel;
