//! The table of the apps beside this board example (RTIC, embassy): a `static` in flash
//! built by `const fn`s, the README's way. Each app includes this file by path; the board
//! example itself generates its table in build.rs.

use qfa_thermal::model::{AxisModel, BiasGrid, Extensions, ScaleFactor};
use qfa_thermal::{Input, Table};

/// One axis: JB-KT8 #1's scale factor (Zhang et al. 2021, Eq. 15) and a flat placeholder
/// bias. Not a calibration: a real table comes from `qfa-lab table-rs` (or the board
/// example's build.rs).
const AXIS: AxisModel = AxisModel {
    scale: ScaleFactor {
        t0_c: 22.0,
        gamma: 320_320.0,
        mu: -32.76,
        beta: 0.1008,
        epsilon: 88.14,
        eta: -0.02409,
        alpha: 273.0,
    },
    bias: BiasGrid::flat(-40.0, 10.0, [1e-4; 13]),
    rate_limit_c_per_min: 2.0,
    ext: Extensions::NONE,
};

/// The table, in flash; the compensator validates it where it lies.
pub static TABLE: Table = Table::new(Input::PulseCounts, 32, [AXIS; 3], None);
