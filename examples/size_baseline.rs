//! The size programs' runtime and statics without the core: vector table, reset, semihosting
//! exit, a table's bytes and a table in flash. `panic_check`'s flash minus this is
//! `core_flash_bytes`, `static_table_link`'s minus this `core_flash_bytes_static_table`
//! (`cargo xtask bench-target`).
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use core::hint::black_box;

    use cortex_m_rt::{entry, exception, ExceptionFrame};

    use crate::common::{rt, sized_statics};

    #[entry]
    fn main() -> ! {
        sized_statics::keep();
        rt::exit(black_box(0))
    }

    #[exception]
    #[allow(unsafe_code)]
    unsafe fn HardFault(_: &ExceptionFrame) -> ! {
        rt::on_hard_fault_quiet()
    }

    #[allow(unsafe_code)]
    extern "C" {
        fn qfa_panic_is_reachable_from_the_core() -> !;
    }

    #[panic_handler]
    fn panic(_: &core::panic::PanicInfo<'_>) -> ! {
        // SAFETY: never runs; see panic_check.
        #[allow(unsafe_code)]
        unsafe {
            qfa_panic_is_reachable_from_the_core()
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("size_baseline is a target program: run `cargo xtask bench-target`");
    std::process::exit(2);
}
