//! The tracking stage's integration tests, one binary: the local maxima against a
//! brute-force scan, and the streamed blur against a direct convolution. proptest keeps
//! their regression seeds in `../proptest-regressions/`.

mod blur;
mod detect;
