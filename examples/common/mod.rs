//! Code the QEMU examples share, each with `mod common;` (the demo needs none of it).
// Each example uses the part it needs: the size measurements the quiet HardFault exit, the
// programs that run the console and the exits that print.
#![allow(dead_code)]

#[cfg(target_os = "none")]
pub mod rt;

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
// The printing programs share this module and never call the macro.
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
#[cfg(target_os = "none")]
#[allow(unused_imports)]
pub(crate) use panic_free_handlers;
