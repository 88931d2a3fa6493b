//! Coefficient tables for the demo and the benchmark: the paper's JB-KT8 #1 on three axes.

use qfa_thermal::model::{BranchHysteresis, Creep, SensorLag};
use qfa_thermal::table::{self, MAX_AXES, MAX_TABLE_BYTES};
use qfa_thermal::{AxisModel, BiasGrid, Extensions, ScaleFactor, Table};

/// Scale factor of JB-KT8 #1 (paper Eq. 15), pulses/(g·s), T0 = 22 °C, Ṫ in °C/min.
#[must_use]
pub const fn kt8_1() -> ScaleFactor {
    qfa_thermal::fixtures::JB_KT8_1
}

/// First grid point, °C.
pub const GRID_START_C: f32 = -40.0;
/// Grid spacing, °C.
pub const GRID_STEP_C: f32 = 10.0;
/// Grid points: −40..=80 °C.
pub const GRID_POINTS: usize = 13;
/// Heating branch above the cooling branch by this much, g.
pub const BRANCH_SPLIT_G: f32 = 8e-6;

/// A plausible bias grid for `axis`: ~100 µg at 22 °C, 1.5 µg/°C, slight curvature, and
/// heating/cooling branches [`BRANCH_SPLIT_G`] apart.
#[must_use]
pub fn bias_grid(axis: usize) -> BiasGrid {
    let offset = 1.0e-4 + 2.0e-5 * axis as f32;
    let k0 = |i: usize| {
        let d = GRID_START_C + GRID_STEP_C * i as f32 - 22.0;
        offset + 1.5e-6 * d + 8.0e-9 * d * d
    };
    let mut g = BiasGrid::single_valued(GRID_START_C, GRID_STEP_C, &[0.0; GRID_POINTS]).expect("2 to 16 grid values");
    for (i, (h, c)) in g.heating_g.iter_mut().zip(g.cooling_g.iter_mut()).enumerate() {
        *h = k0(i) + 0.5 * BRANCH_SPLIT_G;
        *c = k0(i) - 0.5 * BRANCH_SPLIT_G;
    }
    g
}

/// Every extension slot on, with plausible constants.
#[must_use]
pub const fn all_slots_on() -> Extensions {
    Extensions {
        sensor_lag: Some(SensorLag { tau_s: 40.0 }),
        bias_branch_hysteresis: Some(BranchHysteresis { half_width_c: 0.5, weight_g: 2e-5 }),
        bias_creep: Some(Creep { gain_g_per_c: 2e-6, tau_ref_s: 600.0, t_ref_c: 22.0, activation_k: 4000.0 }),
    }
}

/// A small misalignment / cross-axis matrix (row-major), within the table limits.
pub const MISALIGNMENT: [f32; 9] = [1.0, 1.0e-3, -2.0e-3, 5.0e-4, 1.0, 1.5e-3, -1.0e-3, 2.0e-4, 1.0];

/// A 3-axis JB-KT8 #1 table for a rate window of `rate_window` samples.
#[must_use]
pub fn table(ext: Extensions, misalignment: bool, rate_window: u16) -> Table {
    let mut axes = heapless::Vec::new();
    for i in 0..MAX_AXES {
        let axis = AxisModel { scale: kt8_1(), bias: bias_grid(i), rate_limit_c_per_min: 2.0, ext };
        // Capacity is MAX_AXES and the loop pushes MAX_AXES.
        let _ = axes.push(axis);
    }
    Table {
        input: qfa_thermal::Input::PulseCounts,
        rate_window,
        axes,
        misalignment: misalignment.then_some(MISALIGNMENT),
    }
}

/// Wire bytes of `t`.
///
/// # Errors
/// A validation error of `t`.
pub fn encode<'a>(t: &Table, buf: &'a mut [u8; MAX_TABLE_BYTES]) -> table::Result<&'a [u8]> {
    t.encode(buf)
}
