//! The link to a computer: the server that answers requests, and the bank writer.
pub mod bank;
