//! Replays every reference vector on the target and prints `N vectors bit-exact on thumbv7em`
//! (exit 0), or the first mismatch (exit 1). Run: `cargo xtask test`, which checks the output
//! against `qemu_vectors.out`.
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::entry;

    use crate::common::rt;

    #[entry]
    fn main() -> ! {
        let result = qfa_replay::replay_all();
        let code = match rt::console() {
            Some(mut out) => super::report_replay(&mut out, "thumbv7em", result).unwrap_or(super::EXIT_MISMATCH),
            None => super::EXIT_MISMATCH,
        };
        rt::exit(code)
    }

    crate::common::printing_handlers!();
}

/// On the host: the same replay, for comparison.
#[cfg(not(target_os = "none"))]
fn main() {
    let mut out = String::new();
    let code = report_replay(&mut out, std::env::consts::ARCH, qfa_replay::replay_all()).unwrap_or(EXIT_MISMATCH);
    print!("{out}");
    std::process::exit(code as i32);
}

/// Exit code of a vector mismatch.
const EXIT_MISMATCH: u32 = 1;

/// Print the result of [`qfa_replay::replay_all`] and return the exit code.
///
/// The error is printed with `Debug` (file, line, field, got/want bits), so this keeps
/// working while the replay's error type grows variants.
///
/// # Errors
/// Only a failed write.
fn report_replay<E: core::fmt::Debug>(
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
