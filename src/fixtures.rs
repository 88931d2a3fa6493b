//! Test fixtures: published coefficients for tests, benchmarks and placeholder tables.
//!
//! Behind the `fixtures` feature (and in the crate's own tests): none of this is a
//! calibration of any unit but the one it names, so it is not part of the default API.

use crate::model::ScaleFactor;

/// Unit JB-KT8 #1 of Zhang et al. (2021), Eq. 15: pulses/(g·s), T0 = 22 °C, Ṫ in °C/min.
/// For fixtures and tests (the benchmark, the board's placeholder table, the soak).
pub const JB_KT8_1: ScaleFactor =
    ScaleFactor { t0_c: 22.0, gamma: 320_320.0, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 };

/// Unit JB-KT8 #2, Eq. 16, in the same units.
pub const JB_KT8_2: ScaleFactor =
    ScaleFactor { t0_c: 22.0, gamma: 308_000.0, mu: -49.81, beta: 0.08, epsilon: 21.01, eta: -1.4912, alpha: 102.76 };

/// Unit JB-KT8 #3, Eq. 17, in the same units.
pub const JB_KT8_3: ScaleFactor =
    ScaleFactor { t0_c: 22.0, gamma: 328_000.0, mu: -41.14, beta: 0.2385, epsilon: 48.53, eta: -0.0972, alpha: 49.12 };

/// The paper's three units, #1 to #3: the one copy of their coefficients that the reference
/// vectors, the lab's simulator and the QEMU demo all use.
pub const JB_KT8: [ScaleFactor; 3] = [JB_KT8_1, JB_KT8_2, JB_KT8_3];
