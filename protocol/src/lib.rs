//! Wire formats and player shared by host and firmware (filled in by the foundation issue).
#![cfg_attr(not(any(test, feature = "std")), no_std)]
