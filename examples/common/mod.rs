//! Code the QEMU examples share, each with `mod common;` (the demo needs none of it).
// Each example uses the part it needs: the size measurements the quiet HardFault exit, the
// programs that run the console and the exits that print.
#![allow(dead_code)]

#[cfg(target_os = "none")]
pub mod rt;

/// The slow path's inputs the benchmark and the traced example share.
#[cfg(target_os = "none")]
pub mod inputs {
    use qfa_thermal::{Compensator, Config, Table};

    /// Timestamp (ms) and raw reading of slow-path call `k`: 1 Hz samples, a triangle of
    /// ±1/2 °C around 20.5 °C at 1/16 °C per 4 s (0.94 °C/min), so every reading is accepted,
    /// and the branch switches.
    pub fn sample(k: u32) -> (u32, i16) {
        let p = (k >> 2) & 31;
        let tri = if p < 16 { p } else { 31 - p };
        (k.wrapping_mul(1000), 320 + tri as i16)
    }

    /// A compensator with one shared sensor (and the misalignment stage `MATRIX`), holding
    /// `table` in flash, warmed up on 64 of [`sample`]'s readings.
    pub fn shared_sensor<const MATRIX: usize>(
        config: Config,
        table: &'static Table,
    ) -> Compensator<3, 32, 1, &'static Table, MATRIX> {
        let mut c = Compensator::new(config).expect("a valid config");
        c.set_table(table).expect("fixture table validates");
        for k in 0..64 {
            let (t, raw) = sample(k);
            c.on_raw(0, t, raw).expect("warm-up readings are plausible");
        }
        c
    }
}

#[cfg(all(target_os = "none", feature = "fixtures"))]
/// The tables the benchmark compensates with: the paper's JB-KT8 #1 on three axes, each a
/// `static Table` built by `const fn`s, as the README keeps a table in flash.
pub mod tables {
    use qfa_thermal::fixtures::JB_KT8_1;
    use qfa_thermal::model::{BranchHysteresis, Creep, SensorLag};
    use qfa_thermal::table::SAMPLE_UNITS_PER_G;
    use qfa_thermal::{AxisModel, BiasGrid, Extensions, Input, Table};

    /// First grid point, °C.
    const GRID_START_C: f32 = -40.0;
    /// Grid spacing, °C.
    const GRID_STEP_C: f32 = 10.0;
    /// Grid points: −40..=80 °C.
    const GRID_POINTS: usize = 13;
    /// Heating branch above the cooling branch by this much, g.
    const BRANCH_SPLIT_G: f32 = 8e-6;
    /// A small misalignment / cross-axis matrix (row-major), within the table limits.
    const MISALIGNMENT: [f32; 9] = [1.0, 1.0e-3, -2.0e-3, 5.0e-4, 1.0, 1.5e-3, -1.0e-3, 2.0e-4, 1.0];
    /// The rate window the tables are fitted for: the compensators' default.
    const RATE_WINDOW: u16 = 32;
    /// The part the samples table is read at, LSB per g.
    pub const SAMPLE_LSB_PER_G: f32 = 320_000.0;

    /// A plausible bias grid for `axis`: ~100 µg at 22 °C, 1.5 µg/°C, slight curvature,
    /// and heating/cooling branches [`BRANCH_SPLIT_G`] apart.
    const fn bias_grid(axis: usize) -> BiasGrid {
        let offset = 1.0e-4 + 2.0e-5 * axis as f32;
        let (mut heating, mut cooling) = ([0.0f32; GRID_POINTS], [0.0f32; GRID_POINTS]);
        let mut i = 0;
        while i < GRID_POINTS {
            let d = GRID_START_C + GRID_STEP_C * i as f32 - 22.0;
            let k0 = offset + 1.5e-6 * d + 8.0e-9 * d * d;
            heating[i] = k0 + 0.5 * BRANCH_SPLIT_G;
            cooling[i] = k0 - 0.5 * BRANCH_SPLIT_G;
            i += 1;
        }
        BiasGrid::with_branches(GRID_START_C, GRID_STEP_C, BiasGrid::DEFAULT_DEADBAND_C_PER_MIN, heating, cooling)
    }

    /// Every extension slot on, with plausible constants.
    const ALL_SLOTS_ON: Extensions = Extensions {
        sensor_lag: Some(SensorLag { tau_s: 40.0 }),
        bias_branch_hysteresis: Some(BranchHysteresis { half_width_c: 0.5, weight_g: 2e-5 }),
        bias_creep: Some(Creep { gain_g_per_c: 2e-6, tau_ref_s: 600.0, t_ref_c: 22.0, activation_k: 4000.0 }),
    };

    const fn axis(i: usize, ext: Extensions, samples: bool) -> AxisModel {
        let scale = if samples { JB_KT8_1.in_units(SAMPLE_UNITS_PER_G / SAMPLE_LSB_PER_G) } else { JB_KT8_1 };
        AxisModel { scale, bias: bias_grid(i), rate_limit_c_per_min: 2.0, ext }
    }

    const fn axes(ext: Extensions, samples: bool) -> [AxisModel; 3] {
        [axis(0, ext, samples), axis(1, ext, samples), axis(2, ext, samples)]
    }

    /// Pulse counts, every slot off.
    pub static SLOTS_OFF: Table = Table::new(Input::PulseCounts, RATE_WINDOW, axes(Extensions::NONE, false), None);
    /// Pulse counts, every slot on.
    pub static SLOTS_ON: Table = Table::new(Input::PulseCounts, RATE_WINDOW, axes(ALL_SLOTS_ON, false), None);
    /// Pulse counts, every slot off, with a misalignment matrix.
    pub static MISALIGNED: Table =
        Table::new(Input::PulseCounts, RATE_WINDOW, axes(Extensions::NONE, false), Some(MISALIGNMENT));
    /// The same model for a MEMS part read at [`SAMPLE_LSB_PER_G`].
    pub static SAMPLES: Table = Table::new(Input::Samples, RATE_WINDOW, axes(Extensions::NONE, true), None);
}

/// The statics the size programs share (`size_baseline`, `panic_check`, `static_table_link`):
/// each references both, so the differences of their flash are the core's code alone.
#[cfg(target_os = "none")]
pub mod sized_statics {
    use qfa_thermal::table::MAX_TABLE_BYTES;
    use qfa_thermal::{AxisModel, BiasGrid, Extensions, Input, ScaleFactor, Table};

    /// A table's bytes, as an application receives them to load (`Compensator::load_table`).
    pub static TABLE_BYTES: [u8; MAX_TABLE_BYTES] = [0; MAX_TABLE_BYTES];

    const AXIS: AxisModel = AxisModel {
        scale: ScaleFactor::simple(22.0, 320_320.0, -32.76),
        bias: BiasGrid::flat(-40.0, 10.0, [1e-4; 13]),
        rate_limit_c_per_min: 2.0,
        ext: Extensions::NONE,
    };
    /// A table in flash, written as the README writes it.
    pub static TABLE: Table = Table::new(Input::PulseCounts, 32, [AXIS; 3], None);

    /// Keep both statics in the image, whatever the program uses.
    pub fn keep() {
        core::hint::black_box(&TABLE_BYTES[..]);
        core::hint::black_box(&TABLE);
    }
}

/// The size programs' handlers (`size_baseline`, `panic_check`, `static_table_link`): a
/// HardFault exits quietly, and the panic handler calls a function defined nowhere, so the
/// link fails if a panic is reachable. A macro, not a module: the programs that print
/// (`bench`, `qemu_vectors`) have a panic handler of their own, and a `#[panic_handler]` in
/// a module every example compiles would be a second one.
// The printing programs share this module and call `printing_handlers!` instead.
#[cfg(target_os = "none")]
#[allow(unused_macros)]
macro_rules! panic_free_handlers {
    () => {
        #[cortex_m_rt::exception]
        #[allow(unsafe_code)]
        unsafe fn HardFault(_: &cortex_m_rt::ExceptionFrame) -> ! {
            $crate::common::rt::on_hard_fault_quiet()
        }

        #[allow(unsafe_code)]
        extern "C" {
            /// Defined nowhere: referencing it from a reachable panic breaks the link.
            fn qfa_panic_is_reachable_from_the_core() -> !;
        }

        #[panic_handler]
        fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
            // SAFETY: never runs; the link succeeds only if this handler is unreachable.
            #[allow(unsafe_code)]
            unsafe {
                qfa_panic_is_reachable_from_the_core()
            }
        }
    };
}

/// The printing programs' handlers (`bench`, `qemu_vectors`, `trace_paths`): a HardFault
/// and a panic each print what happened and exit with a failure status (`rt`).
#[cfg(target_os = "none")]
#[allow(unused_macros)]
macro_rules! printing_handlers {
    () => {
        #[cortex_m_rt::exception]
        #[allow(unsafe_code)]
        unsafe fn HardFault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
            $crate::common::rt::on_hard_fault(ef)
        }

        #[panic_handler]
        fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
            $crate::common::rt::on_panic(info)
        }
    };
}
#[cfg(target_os = "none")]
#[allow(unused_imports)]
pub(crate) use panic_free_handlers;
#[cfg(target_os = "none")]
#[allow(unused_imports)]
pub(crate) use printing_handlers;
