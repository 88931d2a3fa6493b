//! Host tests for qfa-thermal.
