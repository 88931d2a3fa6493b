//! Host tests for qfa-thermal.

pub mod reference;
pub mod scenarios;
