//! Host tests for qfa-thermal.

pub mod fuzzing;
pub mod onewire_sim;
pub mod reference;
pub mod scenarios;
pub mod soak;
