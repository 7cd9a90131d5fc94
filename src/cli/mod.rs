//! Command-line subcommands as library functions; `main.rs` only dispatches.

pub mod quadrature;
pub mod study;
