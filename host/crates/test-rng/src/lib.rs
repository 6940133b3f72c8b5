//! The tests' seeded generator: reproducible inputs without an RNG crate. A crate of
//! its own, without dependencies, so that the layers' unit tests use it too; the test
//! kit (`touchc-testkit`) re-exports it for the integration tests, benches and examples.

#![deny(missing_docs)]

/// Xorshift64 (13, 7, 17): the same numbers for the same seed on every machine.
#[derive(Debug, Clone)]
pub struct Xorshift(u64);

impl Xorshift {
    /// A generator from `seed` (made odd: xorshift never leaves 0).
    pub fn new(seed: u64) -> Self {
        Xorshift(seed | 1)
    }

    /// A generator from `seed` spread over all 64 bits first (times the golden
    /// ratio's 2^64 fraction), so that small neighbouring seeds start far apart.
    pub fn mixed(seed: u64) -> Self {
        Xorshift::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15))
    }

    /// The next state, all 64 bits.
    pub fn next_u64(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }

    /// The next number, uniform in `[0, 1)` on a 2^-53 grid.
    pub fn uniform(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }

    /// The next number, uniform in `[-1, 1)` on a 2^-52 grid.
    pub fn signed(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

#[cfg(test)]
mod tests {
    use super::Xorshift;

    #[test]
    fn the_sequence_is_marsaglias_xorshift64() {
        // Marsaglia's (13, 7, 17) generator from state 1, worked by hand:
        // 1 ^ 1 << 13 = 8193; ^ >> 7 = 8257; ^ << 17 = 8257 + 8257 * 2^17.
        let mut r = Xorshift::new(1);
        assert_eq!(r.next_u64(), 8257 + 8257 * (1 << 17));
        // An even seed is made odd, not left to the all-zero state.
        assert_eq!(Xorshift::new(0).next_u64(), 8257 + 8257 * (1 << 17));
    }

    #[test]
    fn the_numbers_stay_in_their_ranges() {
        let mut r = Xorshift::mixed(7);
        for _ in 0..10_000 {
            let (u, s) = (r.uniform(), r.signed());
            assert!(
                (0.0..1.0).contains(&u) && (-1.0..1.0).contains(&s),
                "{u} {s}"
            );
        }
    }
}
