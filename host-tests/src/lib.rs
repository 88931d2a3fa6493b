//! Host tests for qfa-thermal.

pub mod onewire_sim;
