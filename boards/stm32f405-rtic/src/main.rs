//! qfa-thermal in an RTIC 2 app on an STM32F405: the wiring of the board example
//! (`boards/stm32f405`, whose modules it shares), with RTIC doing what that example does by
//! hand.
//!
//! | what | where |
//! |---|---|
//! | DS18B20, axis X / Y / Z | PB6 / PB7 / PB8, open drain, 4.7 kΩ pull-up to 3.3 V |
//! | accelerometer pulses X / Y / Z | TIM3 ETR PD2 / TIM4 ETR PE0 / TIM8 ETR PA0 |
//! | µs clock | TIM2, 32-bit, 1 MHz, free-running |
//! | IMU cycle | hardware task `imu`, bound to TIM7's update at 400 Hz, priority 3: the fast path (`CountingApplier::cycle`) |
//! | slow path | async software task `temperature`, priority 1: each sensor's 1 Hz conversion stepped every 10 ms, every reading to the updater |
//! | delays | `Mono`, RTIC's SysTick monotonic (1 kHz) for the task; the DWT cycle counter for the 1-Wire slots |
//! | log | RTT (defmt), from the software task only |
//!
//! What RTIC replaces: the board example hands the applier to its interrupt through a
//! `Mutex<RefCell<Option<_>>>` taken on the first run; here it is the hardware task's
//! `#[local]` resource, owned by that task from `init` on, with no lock at all. The last
//! cycle's status is a `#[shared]` resource: the IMU task is the highest priority that
//! uses it, so its lock costs nothing there, and the temperature task's lock raises it to
//! priority 3 for the copy (RTIC's priority ceiling), never masking anything else.
//!
//! Build: `cargo build --release --target thumbv7em-none-eabihf` in this directory (its own
//! workspace, linked with the board example's `memory.x`); `cargo xtask bench-target` prints its
//! flash and RAM.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/app_table.rs"]
mod app_table;
#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/cycle.rs"]
mod cycle;
#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/poll.rs"]
mod poll;
#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/widen.rs"]
mod widen;
#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/wiring.rs"]
mod wiring;

/// On the host: say how to build it.
#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "qfa-app-rtic-stm32f405 is firmware for an STM32F405 (Cortex-M4F). Build it here with\n  \
         cargo build --release --target thumbv7em-none-eabihf"
    );
}

#[cfg(target_os = "none")]
#[rtic::app(device = stm32f4xx_hal::pac, dispatchers = [USART1])]
mod app {
    use core::mem::MaybeUninit;

    use defmt_rtt as _;
    use panic_probe as _;
    use qfa_thermal::onewire::OneWire;
    use qfa_thermal::time::MsClock;
    use qfa_thermal::{Config, SensorPerAxisUpdater, Status, ThreeAxisCountingApplier, ThreeAxisSensorPerAxis};
    use rtic_monotonics::systick::prelude::*;
    use stm32f4xx_hal::dwt::{Delay, DwtExt};
    use stm32f4xx_hal::pac::TIM2;
    use stm32f4xx_hal::prelude::*;

    use crate::app_table::TABLE;
    use crate::cycle::PERIOD_US;
    use crate::poll::{self, Event as SensorEvent};
    use crate::wiring::{self, now_us, slot_lock, OneWirePin};

    systick_monotonic!(Mono, 1_000);

    type Channel = poll::Channel<OneWirePin, Delay>;

    /// Resources two tasks share.
    #[shared]
    struct Shared {
        /// The latest IMU cycle's status, for the log.
        status: Status,
    }

    /// Resources one task owns.
    #[local]
    struct Local {
        /// The IMU task's state.
        fast: Fast,
        /// The temperature task's state.
        slow: Slow,
    }

    /// What the IMU task owns: the fast path and the registers it reads.
    pub struct Fast {
        // With a misalignment stage: `ThreeAxisCountingApplierWithMatrix`, and the
        // `...WithMatrix` compensator and updater.
        applier: ThreeAxisCountingApplier<'static>,
        /// TIM7, the pulse counters and the cycle timing's clocks.
        inputs: wiring::ImuInputs,
    }

    /// What the temperature task owns: the slow path, the sensors and the clocks.
    pub struct Slow {
        updater: SensorPerAxisUpdater<'static>,
        chans: [Channel; 3],
        tim2: TIM2,
        clock: MsClock,
    }

    // In `MaybeUninit`, so the compensator is zeroed RAM, not an initial value copied from
    // flash (with `Option = None` it was 860 B of `.data`).
    #[init(local = [comp: MaybeUninit<ThreeAxisSensorPerAxis> = MaybeUninit::uninit()])]
    fn init(cx: init::Context) -> (Shared, Local) {
        let dp = cx.device;
        let cp = cx.core;
        // The board's clocks, µs clock, pins and counters (`wiring.rs`, shared with it).
        let mut rcc = wiring::clocks(dp.RCC);
        Mono::start(cp.SYST, 168_000_000);
        // 1-Wire slot delays from the cycle counter (which the IMU task's timing reads too).
        let delay = cp.DWT.constrain(cp.DCB, &rcc.clocks).delay();
        let tim2 = wiring::us_clock(dp.TIM2, &mut rcc);

        // The compensator lives in `init`'s `'static` local; `split` lends both halves for
        // `'static`. TIM7's 400-Hz cycle in seconds: a dt in another unit is flagged.
        let comp = match ThreeAxisSensorPerAxis::new(Config { imu_period_s: 2.5e-3, ..Config::default() }) {
            Ok(c) => cx.local.comp.write(c),
            Err(e) => defmt::panic!("compensator config: {}", e),
        };
        if let Err(e) = comp.set_table(&TABLE) {
            defmt::error!("table refused: {}; raw pass-through at the nominal scale (NO_TABLE)", e);
        }
        let (updater, applier) = comp.split();

        let gpiob = dp.GPIOB.split(&mut rcc);
        let pins = wiring::onewire_pins(gpiob.pb6, gpiob.pb7, gpiob.pb8);
        let first_us = now_us(&tim2);
        let chans = pins.map(|pin| Channel::new(OneWire::new(pin, delay).with_slot_lock(slot_lock), first_us));

        let (gpioa, gpiod, gpioe) = (dp.GPIOA.split(&mut rcc), dp.GPIOD.split(&mut rcc), dp.GPIOE.split(&mut rcc));
        let (x, y, z) =
            wiring::pulse_counters((dp.TIM3, dp.TIM4, dp.TIM8), (gpiod.pd2, gpioe.pe0, gpioa.pa0), &mut rcc);

        // TIM7: the 400 Hz IMU cycle, no update pending; RTIC unmasks its interrupt after
        // `init`. The counters and the latency are based now, so the first cycle has a real dt.
        let tick = match wiring::imu_tick(dp.TIM7, PERIOD_US, &mut rcc) {
            Ok(t) => t,
            Err(e) => defmt::panic!("TIM7 start: {}", e),
        };
        let inputs = wiring::ImuInputs::new(tick, (x, y, z));
        let applier = applier.counting(inputs.totals());

        if temperature::spawn().is_err() {
            defmt::panic!("the temperature task was already spawned");
        }
        let fast = Fast { applier, inputs };
        let slow = Slow { updater, chans, tim2, clock: MsClock::new() };
        (Shared { status: Status::empty() }, Local { fast, slow })
    }

    /// The fast path, each TIM7 update: never blocks, never logs.
    #[task(binds = TIM7, priority = 3, local = [fast], shared = [status])]
    fn imu(mut cx: imu::Context) {
        let f = cx.local.fast;
        // The counts and the time since the last read, exact however late the task runs.
        let (counters, t) = f.inputs.read();
        let out = f.applier.cycle(counters, t.dt_us);
        // The navigation filter takes `out.dv_mps` here, and judges it by `out.status`.
        cx.shared.status.lock(|s| *s = out.status);
    }

    /// The slow path: every 10 ms, each sensor's step (a 1 Hz conversion, checked on the bus
    /// and read when done; every reading, good or failed, reaches the updater); a log line
    /// a second. Preempted by the IMU task everywhere but each 1-Wire slot's locked µs.
    #[task(priority = 1, local = [slow], shared = [status])]
    async fn temperature(mut cx: temperature::Context) {
        let s = cx.local.slow;
        let mut steps = 0u32;
        loop {
            let _ = s.clock.ms(now_us(&s.tim2));
            for (axis, ch) in s.chans.iter_mut().enumerate() {
                let event = ch.step(&mut s.updater, &mut s.clock, axis, now_us(&s.tim2));
                if let SensorEvent::Rejected { error, .. } | SensorEvent::Missed { result: Err(error), .. } = event {
                    defmt::error!("axis {}: reading not used: {}", axis, error);
                }
            }
            steps = steps.wrapping_add(1);
            if steps.is_multiple_of(100) {
                let status = cx.shared.status.lock(|s| *s);
                let temps: [Option<f32>; 3] = core::array::from_fn(|i| s.updater.estimate_of(i).map(|e| e.temp_c));
                defmt::println!("imu status={} temp_c={}", status, temps);
            }
            Mono::delay(10.millis()).await;
        }
    }
}
