//! The unit tests' seeded generator: the test kit's, so every test draws from one.

pub(crate) use touchc_testkit::rng::Xorshift;
