//! Measurements of a compile, outside the pipeline proper: how much of the touch the
//! tracked contacts explain (`coverage`), tracking against a synthetic recording's
//! truth ([`evaluate`]), and the presets' speed/accuracy trade ([`trade`]).

#![deny(missing_docs)]

pub mod evaluate;
pub mod trade;
