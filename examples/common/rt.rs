//! Semihosting runtime on the target: console, exit with a code, panic and HardFault exits.
//! Each example defines its handlers and calls these.

use core::fmt::Write;

use cortex_m_semihosting::hio::{self, HostStream};

/// Exit code of a panic (the same as a Rust panic on the host).
pub const EXIT_PANIC: u32 = 101;
/// Exit code of a HardFault.
pub const EXIT_HARD_FAULT: u32 = 3;

/// Semihosting `SYS_EXIT_EXTENDED`: unlike `SYS_EXIT` on 32-bit Arm, it carries an exit code.
const SYS_EXIT_EXTENDED: usize = 0x20;
/// `ADP_Stopped_ApplicationExit`.
const ADP_STOPPED_APPLICATION_EXIT: usize = 0x2_0026;

/// The host's stdout, or `None` without a debugger/semihosting host.
#[must_use]
pub fn console() -> Option<HostStream> {
    hio::hstdout().ok()
}

/// End the program: QEMU (`-semihosting-config enable=on`) exits with `code`.
pub fn exit(code: u32) -> ! {
    let block = [ADP_STOPPED_APPLICATION_EXIT, code as usize];
    // SAFETY: a semihosting call with a valid two-word parameter block; under QEMU it does
    // not return. Without a host it traps (HardFault → same exit), never silently continues.
    #[allow(unsafe_code)]
    unsafe {
        cortex_m_semihosting::syscall(SYS_EXIT_EXTENDED, &block);
    }
    cortex_m::asm::udf()
}

/// Panic: print the message on the host's stderr and exit with [`EXIT_PANIC`], so a
/// panic fails the run instead of hanging it.
pub fn on_panic(info: &core::panic::PanicInfo<'_>) -> ! {
    if let Ok(mut e) = hio::hstderr() {
        let _ = writeln!(e, "panic: {info}");
    }
    exit(EXIT_PANIC)
}

/// HardFault: print the faulting PC and exit with [`EXIT_HARD_FAULT`].
pub fn on_hard_fault(ef: &cortex_m_rt::ExceptionFrame) -> ! {
    if let Ok(mut e) = hio::hstderr() {
        let _ = writeln!(e, "HardFault at pc={:#010x} lr={:#010x}", ef.pc(), ef.lr());
    }
    exit(EXIT_HARD_FAULT)
}

/// HardFault without formatting (for the panic-free link check): exit with the code only.
pub fn on_hard_fault_quiet() -> ! {
    exit(EXIT_HARD_FAULT)
}
