//! qfa-thermal on an STM32F405 navigation computer (`stm32f4xx-hal`, `defmt-rtt`).
//!
//! | what | where |
//! |---|---|
//! | DS18B20, axis X / Y / Z (one per accelerometer case) | PB6 / PB7 / PB8, open drain, 4.7 kΩ pull-up to 3.3 V, sensors on V_DD (not parasite) |
//! | accelerometer pulses X / Y / Z | TIM3 ETR PD2 (AF2) / TIM4 ETR PE0 (AF2) / TIM8 ETR PA0 (AF3), rising edges |
//! | µs clock | TIM2, 32-bit, 1 MHz, free-running (wraps every 71.6 min) |
//! | IMU cycle | TIM7 update interrupt, 400 Hz: the fast path (`Applier::cycle_counters`) |
//! | slow path | thread mode: 1 Hz conversions, `Updater::on_scratchpad_from` |
//! | table | flash sector 11 (0x080E_0000), decoded and validated at boot |
//! | log | RTT (defmt) |
//!
//! Build: `cargo build -p qfa-board-stm32f405 --release --target thumbv7em-none-eabihf`.
//! On the host this binary only prints that line.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod board;
#[cfg(any(test, target_os = "none"))]
mod widen;

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
