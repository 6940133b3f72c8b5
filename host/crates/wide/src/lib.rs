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

#![deny(missing_docs)]

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

/// For the tests that compare the two builds: true when this CPU runs AVX2. Otherwise
/// there is nothing to compare and the test returns early, which the harness would
/// report as a pass: so the skip is said on the terminal (written to the process's
/// stderr, past the harness's capture) with the number of skips so far, and with
/// `TOUCHC_REQUIRE_AVX2` set (as `scripts/check.sh` does on a CPU that has AVX2) it
/// fails instead.
pub fn avx2_or_skip(test: &str) -> bool {
    // `eprintln!` would be captured with the passing test's output and never shown.
    skip_unless(avx2(), test, &mut std::io::stderr())
}

/// How many comparisons [`avx2_or_skip`] skipped in this process.
static SKIPS: std::sync::atomic::AtomicUsize = std::sync::atomic::AtomicUsize::new(0);

fn skip_unless(available: bool, test: &str, out: &mut impl std::io::Write) -> bool {
    if available {
        return true;
    }
    assert!(
        std::env::var_os("TOUCHC_REQUIRE_AVX2").is_none(),
        "{test}: TOUCHC_REQUIRE_AVX2 is set, but this CPU does not run AVX2"
    );
    let n = SKIPS.fetch_add(1, std::sync::atomic::Ordering::Relaxed) + 1;
    let _ = writeln!(
        out,
        "SKIPPED {test}: this CPU does not run AVX2, so its AVX2 build is not compared \
         with the baseline ({n} AVX2 comparison(s) skipped in this run)"
    );
    false
}

/// `kernel! { fn name / name_baseline / name_avx2 (args) -> R { body } }` defines
/// `name`, which runs `body` in its AVX2 build (`name_avx2`) when [`avx2`] says so, else
/// in its baseline build (`name_baseline`); the tests call both.
#[macro_export]
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
                if $crate::avx2() {
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
        /// Only on a CPU that runs AVX2 ([`touchc_wide::avx2`]).
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A CPU without AVX2 skips, says so with the count, and is counted; one with
    /// AVX2 compares, silently.
    #[test]
    fn a_skip_is_said_and_counted_and_a_cpu_with_avx2_compares() {
        if std::env::var_os("TOUCHC_REQUIRE_AVX2").is_some() {
            // The skip itself would fail, by design; the message is tested without it.
            return;
        }
        let mut out = Vec::new();
        assert!(skip_unless(true, "compares", &mut out));
        assert!(out.is_empty());
        let before = SKIPS.load(std::sync::atomic::Ordering::Relaxed);
        assert!(!skip_unless(false, "some::test", &mut out));
        let said = String::from_utf8(out).unwrap();
        assert!(
            said.starts_with("SKIPPED some::test: this CPU does not run AVX2"),
            "{said}"
        );
        assert!(said.contains("skipped in this run"), "{said}");
        assert!(SKIPS.load(std::sync::atomic::Ordering::Relaxed) > before);
    }
}
