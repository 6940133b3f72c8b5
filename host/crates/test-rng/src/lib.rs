//! The unit tests' seeded generator: reproducible inputs without an RNG crate.

#![warn(missing_docs)]

/// Xorshift64 (13, 7, 17); the same numbers for the same seed on every machine.
pub struct Xorshift(u64);

impl Xorshift {
    /// A generator from `seed` (made odd: xorshift never leaves 0).
    pub fn new(seed: u64) -> Self {
        Xorshift(seed | 1)
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
}
