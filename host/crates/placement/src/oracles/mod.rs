//! The placement's oracles: the exact subset search against an ILP solver and brute
//! force, and the placement against a transform-by-transform reimplementation, on
//! trajectories of one point a frame and on regions.

mod bnb_oracle;
mod naive;
mod oracle;
mod regions;
