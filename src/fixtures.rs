//! Test fixtures: published coefficients for tests, benchmarks and placeholder tables.
//!
//! Behind the `fixtures` feature (and in the crate's own tests): none of this is a
//! calibration of any unit but the one it names, so it is not part of the default API.

use crate::model::ScaleFactor;

/// Unit JB-KT8 #1 of Zhang et al. (2021), Eq. 15: pulses/(g·s), T0 = 22 °C, Ṫ in °C/min.
/// For fixtures and tests (the benchmark, the board's placeholder table, the soak).
pub const JB_KT8_1: ScaleFactor =
    ScaleFactor { t0_c: 22.0, gamma: 320_320.0, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 };
