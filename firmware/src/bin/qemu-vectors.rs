//! Replays every reference vector on the target and prints `N vectors bit-exact on thumbv7em`
//! (exit 0), or the first mismatch (exit 1). Run: `cargo xtask test`.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::{entry, exception, ExceptionFrame};
    use qfa_firmware::rt;

    #[entry]
    fn main() -> ! {
        let result = qfa_replay::replay_all();
        let code = match rt::console() {
            Some(mut out) => {
                qfa_firmware::report_replay(&mut out, "thumbv7em", result).unwrap_or(qfa_firmware::EXIT_MISMATCH)
            }
            None => qfa_firmware::EXIT_MISMATCH,
        };
        rt::exit(code)
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

/// On the host: the same replay, for comparison.
#[cfg(not(target_os = "none"))]
fn main() {
    let mut out = String::new();
    let code = qfa_firmware::report_replay(&mut out, std::env::consts::ARCH, qfa_replay::replay_all()).unwrap_or(1);
    print!("{out}");
    std::process::exit(code as i32);
}
