//! The placement's oracles: the exact subset search against an ILP solver and brute
//! force, and the placement against a transform-by-transform reimplementation.

mod bnb_oracle;
mod oracle;
