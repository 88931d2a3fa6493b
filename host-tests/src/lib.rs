//! Host tests for qfa-thermal.

#[cfg(feature = "field")]
pub mod field;
pub mod fuzzing;
pub mod onewire_sim;
pub mod oracle;
pub mod physics;
pub mod reference;
pub mod scenarios;
pub mod soak;
