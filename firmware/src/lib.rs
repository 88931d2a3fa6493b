//! Firmware for qfa-thermal on a Cortex-M4F (QEMU `mps2-an386`): shared fixtures and the
//! semihosting runtime the binaries use. The demo is the root crate's example
//! `examples/qemu_demo.rs`.
//!
//! Binaries (run them with `cargo xtask …`, which builds for `thumbv7em-none-eabihf`):
//! * `qemu-vectors`: replays the reference vectors, prints `N vectors bit-exact on thumbv7em`;
//! * `bench`: instruction counts of both paths under `-icount shift=0` (`cargo xtask bench-target`);
//! * `panic-check`: links only if no panic is reachable from the core (`cargo xtask panic-check`);
//! * `size-baseline`: the same runtime without the core, the baseline of `core_flash_bytes`.
//!
//! On the host every binary builds as a plain std program, so workspace-wide host commands
//! stay clean; `qemu-vectors` even runs there. The memory map is the repository's root
//! `memory.x`, which the linker finds in its working directory, the workspace root.
#![no_std]

pub mod fixtures;

#[cfg(target_os = "none")]
pub mod rt;

/// Exit code of a vector mismatch.
pub const EXIT_MISMATCH: u32 = 1;
/// Exit code of a panic (the same as a Rust panic on the host).
pub const EXIT_PANIC: u32 = 101;
/// Exit code of a HardFault.
pub const EXIT_HARD_FAULT: u32 = 3;

/// Print the result of [`qfa_replay::replay_all`] and return the exit code.
///
/// The error is printed with `Debug` (file, line, field, got/want bits), so this keeps
/// working while the replay's error type grows variants.
///
/// # Errors
/// Only a failed write.
pub fn report_replay<E: core::fmt::Debug>(
    out: &mut dyn core::fmt::Write,
    platform: &str,
    result: Result<usize, E>,
) -> Result<u32, core::fmt::Error> {
    match result {
        Ok(n) => {
            writeln!(out, "{n} vectors bit-exact on {platform}")?;
            Ok(0)
        }
        Err(e) => {
            writeln!(out, "replay FAILED on {platform}: {e:?}")?;
            Ok(EXIT_MISMATCH)
        }
    }
}
