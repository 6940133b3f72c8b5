//! Measurements of a compile, outside the pipeline proper: tracking against a synthetic
//! recording's truth ([`evaluate`]), the synthetic real-touch cases per preset
//! ([`cases`]), and the presets' speed/accuracy trade ([`trade`]).

#![deny(missing_docs)]

pub mod cases;
pub mod evaluate;
pub mod trade;
