//! `panic-check`'s runtime without the core: vector table, reset, semihosting exit. The
//! difference of their flash is `core_flash_bytes` (`cargo xtask bench-target`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use qfa_firmware::rt;

    #[entry]
    fn main() -> ! {
        rt::exit(core::hint::black_box(0))
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
        // SAFETY: never runs; see panic-check.
        #[allow(unsafe_code)]
        unsafe {
            qfa_panic_is_reachable_from_the_core()
        }
    }
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("size-baseline is a target binary: run `cargo xtask bench-target`");
    std::process::exit(2);
}
