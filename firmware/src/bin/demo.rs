//! Compensates a few minutes of simulated JB-KT8 #1 data and prints it. Run: `cargo xtask demo-qemu`
//! (on the host: `cargo run -p qfa-firmware --bin demo`).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use qfa_firmware::rt;

    #[entry]
    fn main() -> ! {
        let Some(mut out) = rt::console() else { rt::exit(2) };
        match qfa_firmware::demo::run(&mut out) {
            Ok(()) => rt::exit(0),
            Err(_) => rt::exit(1),
        }
    }

    #[exception]
    #[allow(unsafe_code)]
    unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
        rt::on_hard_fault(ef)
    }

    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
        rt::on_panic(info)
    }
}

/// On the host: the same demo on stdout.
#[cfg(not(target_os = "none"))]
fn main() {
    let mut out = String::new();
    let ok = qfa_firmware::demo::run(&mut out).is_ok();
    print!("{out}");
    std::process::exit(if ok { 0 } else { 1 });
}
