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

    use cortex_m::peripheral::DWT;
    use defmt_rtt as _;
    use panic_probe as _;
    use qfa_thermal::model::{AxisModel, BiasGrid, Extensions, ScaleFactor};
    use qfa_thermal::onewire::OneWire;
    use qfa_thermal::time::MsClock;
    use qfa_thermal::{
        Config, Input, SensorPerAxisUpdater, Status, Table, ThreeAxisCountingApplier, ThreeAxisSensorPerAxis,
    };
    use rtic_monotonics::systick::prelude::*;
    use stm32f4xx_hal::dwt::{Delay, DwtExt};
    use stm32f4xx_hal::gpio::{alt, OpenDrain, Output, PartiallyErasedPin, PinState};
    use stm32f4xx_hal::pac::{TIM2, TIM3, TIM4, TIM7, TIM8};
    use stm32f4xx_hal::prelude::*;
    use stm32f4xx_hal::rcc::Config as RccConfig;
    use stm32f4xx_hal::timer::{CounterUs, Event, FTimerUs, Timer};

    use crate::cycle::{self, PERIOD_US};
    use crate::poll::{self, Event as SensorEvent};
    use crate::widen::Widen16;
    use crate::wiring::{cnt16_tim3, cnt16_tim4, cnt16_tim8, etr_counter, now_us, slot_lock};

    systick_monotonic!(Mono, 1_000);

    /// One axis of the table: JB-KT8 #1's scale factor (Zhang et al. 2021, Eq. 15) and a
    /// flat placeholder bias, written with `const fn`s so the table is a `static` in flash.
    /// Not a calibration: a real table comes from `qfa-lab table-rs` (or the board
    /// example's build.rs).
    const AXIS: AxisModel = AxisModel {
        scale: ScaleFactor {
            t0_c: 22.0,
            gamma: 320_320.0,
            mu: -32.76,
            beta: 0.1008,
            epsilon: 88.14,
            eta: -0.02409,
            alpha: 273.0,
        },
        bias: BiasGrid::flat(-40.0, 10.0, [1e-4; 13]),
        rate_limit_c_per_min: 2.0,
        ext: Extensions::NONE,
    };

    /// The table, in flash; the compensator validates it where it lies.
    static TABLE: Table = Table::new(Input::PulseCounts, 32, [AXIS; 3], None);

    // The DS18B20s' port: its letter is part of the pin type, so pins on another port change
    // it here as well as in `init` (the compiler otherwise points at the pins, not here).
    type OneWirePin = PartiallyErasedPin<'B', Output<OpenDrain>>;
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
        /// TIM7: the 400 Hz cycle; its counter (1 MHz) also times each read.
        tick: CounterUs<TIM7>,
        x: TIM3,
        y: TIM4,
        z: TIM8,
        widen: [Widen16; 3],
        /// TIM7 count at the previous read, and the DWT cycle counter then.
        last_lat: u32,
        last_cyc: u32,
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
        // 8 MHz crystal, 168 MHz core; APB1 42 MHz (its timers 84 MHz), APB2 84 MHz.
        let mut rcc = dp.RCC.freeze(RccConfig::hse(8.MHz()).sysclk(168.MHz()).pclk1(42.MHz()).pclk2(84.MHz()));
        Mono::start(cp.SYST, 168_000_000);
        // 1-Wire slot delays from the cycle counter (which the IMU task's timing reads too).
        let delay = cp.DWT.constrain(cp.DCB, &rcc.clocks).delay();

        // TIM2: the µs clock, free-running over all 32 bits (as MsClock expects).
        let tim2 = FTimerUs::new(dp.TIM2, &mut rcc).release();
        tim2.arr().write(|w| w.arr().set(u32::MAX));
        tim2.egr().write(|w| w.ug().set_bit());
        tim2.cr1().write(|w| w.cen().enabled());

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

        // Three DS18B20s, each alone on an open-drain pin, released (high) from the start.
        let gpiob = dp.GPIOB.split(&mut rcc);
        let pins: [OneWirePin; 3] = [
            gpiob.pb6.into_open_drain_output_in_state(PinState::High).erase_number(),
            gpiob.pb7.into_open_drain_output_in_state(PinState::High).erase_number(),
            gpiob.pb8.into_open_drain_output_in_state(PinState::High).erase_number(),
        ];
        let first_us = now_us(&tim2);
        let chans = pins.map(|pin| Channel::new(OneWire::new(pin, delay).with_slot_lock(slot_lock), first_us));

        // Pulse counters on the timers' ETR pins (typed pins check the pin/AF pairs).
        let gpioa = dp.GPIOA.split(&mut rcc);
        let gpiod = dp.GPIOD.split(&mut rcc);
        let gpioe = dp.GPIOE.split(&mut rcc);
        let _etr_x: alt::tim3::Etr = gpiod.pd2.into();
        let _etr_y: alt::tim4::Etr = gpioe.pe0.into();
        let _etr_z: alt::tim8::Etr = gpioa.pa0.into();
        let x = Timer::new(dp.TIM3, &mut rcc).release();
        let y = Timer::new(dp.TIM4, &mut rcc).release();
        let z = Timer::new(dp.TIM8, &mut rcc).release();
        etr_counter!(x);
        etr_counter!(y);
        etr_counter!(z);

        // TIM7: the 400 Hz IMU cycle; RTIC unmasks its interrupt after `init`.
        let mut tick = dp.TIM7.counter_us(&mut rcc);
        if let Err(e) = tick.start(PERIOD_US.micros()) {
            defmt::panic!("TIM7 start: {}", e);
        }
        tick.listen(Event::Update);
        // Base the counters and the latency now, so the first cycle has a real dt.
        let _ = tick.wait();
        let last_lat = tick.now().ticks();
        let last_cyc = DWT::cycle_count();
        let widen = [Widen16::new(cnt16_tim3(&x)), Widen16::new(cnt16_tim4(&y)), Widen16::new(cnt16_tim8(&z))];
        let applier = applier.counting(widen.map(|w| w.total()));

        if temperature::spawn().is_err() {
            defmt::panic!("the temperature task was already spawned");
        }
        let fast = Fast { applier, tick, x, y, z, widen, last_lat, last_cyc };
        let slow = Slow { updater, chans, tim2, clock: MsClock::new() };
        (Shared { status: Status::empty() }, Local { fast, slow })
    }

    /// The fast path, each TIM7 update: never blocks, never logs.
    #[task(binds = TIM7, priority = 3, local = [fast], shared = [status])]
    fn imu(mut cx: imu::Context) {
        let f = cx.local.fast;
        // Clear the update flag first (clearing it last can re-enter the handler).
        let _ = f.tick.wait();
        let lat = f.tick.now().ticks();
        let cyc = DWT::cycle_count();
        let counters = [
            f.widen[0].update(cnt16_tim3(&f.x)),
            f.widen[1].update(cnt16_tim4(&f.y)),
            f.widen[2].update(cnt16_tim8(&f.z)),
        ];
        // dt in µs ticks, exact however late the task runs (the board example's `cycle.rs`).
        let t = cycle::timing(lat, f.last_lat, cyc.wrapping_sub(f.last_cyc));
        (f.last_lat, f.last_cyc) = (lat, cyc);
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
