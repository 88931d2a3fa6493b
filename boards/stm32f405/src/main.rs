//! qfa-thermal on an STM32F405 navigation computer (`stm32f4xx-hal`, `defmt-rtt`).
//!
//! | what | where |
//! |---|---|
//! | DS18B20, axis X / Y / Z (one per accelerometer case) | PB6 / PB7 / PB8, open drain, 4.7 kΩ pull-up to 3.3 V, sensors on V_DD (a parasite-powered one is refused and its axis flagged) |
//! | accelerometer pulses X / Y / Z | TIM3 ETR PD2 (AF2) / TIM4 ETR PE0 (AF2) / TIM8 ETR PA0 (AF3), rising edges |
//! | µs clock | TIM2, 32-bit, 1 MHz, free-running (wraps every 71.6 min) |
//! | IMU cycle | TIM7 update interrupt, 400 Hz: the fast path (`CountingApplier::cycle`); cycles lost to a held-off interrupt counted (`cycle.rs`, DWT cycle counter) and logged from the main loop |
//! | slow path | thread mode, `poll.rs`: 1 Hz conversions checked on the bus (read slots), every reading to the updater: `on_scratchpad`, or `on_missed_reading` when none came |
//! | table | a `static` in flash built in by build.rs (`QFA_BOARD_TABLE=table.bin`), validated in place at boot |
//! | log | RTT (defmt) |
//!
//! Build: `cargo build -p qfa-board-stm32f405 --release --target thumbv7em-none-eabihf`.
//! On the host this binary only prints that line.
//!
//! # Pulses and samples
//! Each axis here is one pulse line counted up by its timer. An I/F converter with
//! separate + and − lines needs a second counter per axis; the signed cumulative count
//! `plus.wrapping_sub(minus)` (both widened, see `widen`) is then what `cycle_counters`
//! takes. A MEMS IMU instead gives samples over SPI: read them in its data-ready EXTI
//! interrupt and call `Applier::cycle_samples(raw, dt_ticks)`, with the same handoff.
//!
//! # RAM
//! The compensator (`core_ram_bytes` of `cargo xtask bench-target`) lives in a `StaticCell`
//! and holds a `&'static Table`: the table is a `static` in flash (see `calibration`), so
//! validating it reads flash and nothing is copied. The other RAM: the defmt-rtt buffer
//! (1 024 B), the interrupt's state and handoff, the summary, and the stack (not in these
//! figures).
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;
#[cfg(any(test, target_os = "none"))]
mod calibration;
#[cfg(any(test, target_os = "none"))]
mod cycle;
#[cfg(any(test, target_os = "none"))]
mod poll;
#[cfg(any(test, target_os = "none"))]
mod widen;
#[cfg(target_os = "none")]
mod wiring;

/// On the host: say how to build and flash it.
#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "qfa-board-stm32f405 is firmware for an STM32F405 (Cortex-M4F). Build it with\n  \
         cargo build -p qfa-board-stm32f405 --release --target thumbv7em-none-eabihf\n\
         and flash and watch its defmt log with\n  \
         probe-rs run --chip STM32F405RGTx target/thumbv7em-none-eabihf/release/qfa-board-stm32f405"
    );
}

#[cfg(test)]
mod tests {
    /// Scenario 8(a), a guard on the build: in blocking mode (what probe-rs sets, and keeps
    /// after the probe is unplugged) a full RTT buffer made the next defmt call spin for
    /// ever with interrupts masked, stopping the IMU interrupt. The board's defmt-rtt must
    /// have `disable-blocking-mode`.
    #[test]
    fn logging_never_blocks_defmt_rtt_has_disable_blocking_mode() {
        let manifest = include_str!("../Cargo.toml");
        let dep = manifest.lines().find(|l| l.starts_with("defmt-rtt")).expect("defmt-rtt is a dependency");
        assert!(dep.contains("\"disable-blocking-mode\""), "{dep}");
    }
}
