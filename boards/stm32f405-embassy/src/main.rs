//! qfa-thermal in an embassy app on an STM32F405, wired as the board example
//! (`boards/stm32f405`).
//!
//! | what | where |
//! |---|---|
//! | DS18B20, axis X / Y / Z | PB6 / PB7 / PB8, open drain, 4.7 kΩ pull-up to 3.3 V; a task each on the async driver (`Ds18b20::measure_async`) |
//! | accelerometer pulses X / Y / Z | TIM3 ETR PD2 (AF2) / TIM4 ETR PE0 (AF2) / TIM8 ETR PA0 (AF3), rising edges |
//! | IMU cycle | task `imu` on an `InterruptExecutor` (UART4's vector, priority 6): a 400 Hz `Ticker`, the fast path (`CountingApplier::cycle`) |
//! | slow path | `main` on the thread executor: every reading from the sensor tasks, through a channel, to the updater |
//! | time | embassy-time on TIM5, 1 MHz ticks: the µs and ms clocks, the tickers, the conversion wait |
//! | log | RTT (defmt), never from the IMU task |
//!
//! Why this shape: the fast path must preempt everything else, so it runs on an interrupt
//! executor above the thread executor; its `dt` is measured (`Instant`), so a late tick costs
//! nothing. Each sensor's 94–750 ms conversion is awaited (`measure_async`), so the three
//! convert at once and no task blocks the others. The updater is `&mut` and single: the
//! sensor tasks send readings to the one task that owns it.
//!
//! Build: `cargo build --release --target thumbv7em-none-eabihf` in this directory (its own
//! workspace, linked with the board example's `memory.x`); `cargo xtask bench-target` prints its
//! flash and RAM.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/app_table.rs"]
mod app_table;
#[cfg(target_os = "none")]
#[path = "../../stm32f405/src/widen.rs"]
mod widen;

/// On the host: say how to build it.
#[cfg(not(target_os = "none"))]
fn main() {
    println!(
        "qfa-app-embassy-stm32f405 is firmware for an STM32F405 (Cortex-M4F). Build it here with\n  \
         cargo build --release --target thumbv7em-none-eabihf"
    );
}

#[cfg(target_os = "none")]
mod app {
    use core::sync::atomic::{AtomicU32, Ordering};

    use defmt_rtt as _;
    use embassy_executor::{InterruptExecutor, Spawner};
    use embassy_stm32::gpio::{Level, OutputOpenDrain, Speed};
    use embassy_stm32::interrupt;
    use embassy_stm32::interrupt::{InterruptExt, Priority};
    use embassy_stm32::pac;
    use embassy_sync::blocking_mutex::raw::CriticalSectionRawMutex;
    use embassy_sync::channel::Channel;
    use embassy_time::{Delay, Duration, Instant, Ticker};
    use panic_probe as _;
    use qfa_thermal::ds18b20::Resolution;
    use qfa_thermal::ds18b20_driver::{self as drv, Ds18b20, PowerSupply};
    use qfa_thermal::onewire::OneWire;
    use qfa_thermal::{Config, Status, ThreeAxisCountingApplier, ThreeAxisSensorPerAxis};
    use static_cell::StaticCell;

    use crate::app_table::TABLE;
    use crate::widen::Widen16;

    /// The IMU cycle, µs (400 Hz).
    const PERIOD_US: u64 = 2_500;

    /// The compensator; `split` lends both halves for `'static`.
    static COMP: StaticCell<ThreeAxisSensorPerAxis> = StaticCell::new();

    /// A sensor task's reading (or its failure), for the task that owns the updater.
    struct Reading {
        axis: usize,
        /// When it completed (or was due), ms on embassy-time's clock, wrapping.
        t_ms: u32,
        result: Result<[u8; 9], drv::Error>,
    }

    /// Sensor tasks → the updater: a few readings of slack (three sensors at 1 Hz).
    static READINGS: Channel<CriticalSectionRawMutex, Reading, 6> = Channel::new();

    /// The last IMU cycle's status, for the log (written by the IMU task only).
    static IMU_STATUS: AtomicU32 = AtomicU32::new(0);

    /// The executor above the thread executor, on a vector nothing else uses.
    static EXECUTOR_HIGH: InterruptExecutor = InterruptExecutor::new();

    #[interrupt]
    #[allow(unsafe_code)]
    unsafe fn UART4() {
        // SAFETY: the vector belongs to this executor alone (UART4 is not used).
        unsafe { EXECUTOR_HIGH.on_interrupt() }
    }

    /// The 1-Wire slot lock: the few µs of each read and write-1 slot that must not be
    /// stretched run with interrupts masked (the board example's `slot_lock`; the IMU task
    /// is late by at most that, and measures its own dt).
    fn slot_lock(f: &mut dyn FnMut()) {
        critical_section::with(|_| f());
    }

    /// The ms and µs clocks, from embassy-time's 64-bit instant (wrapping as u32, which the
    /// updater and the driver expect).
    fn now_ms() -> u32 {
        Instant::now().as_millis() as u32
    }
    fn now_us() -> u32 {
        Instant::now().as_micros() as u32
    }

    /// Program a timer as a free-running 16-bit counter of rising edges on its ETR pin:
    /// external clock mode 2, a 4-sample filter, auto-reload 0xFFFF (TIM3/TIM4 are general
    /// purpose, TIM8 advanced; their SMCR is the same register). PAC writes: embassy-stm32
    /// has no ETR counting mode.
    macro_rules! etr_counter {
        ($tim:expr) => {{
            let t = $tim;
            t.smcr().modify(|w| {
                w.set_etf(pac::timer::vals::FilterValue::FCK_INT_N4);
                w.set_etps(pac::timer::vals::Etps::DIV1);
                w.set_etp(pac::timer::vals::Etp::NOT_INVERTED);
                w.set_ece(true);
            });
            t.arr().write(|w| w.set_arr(0xFFFF));
            t.egr().write(|w| w.set_ug(true));
            t.cr1().modify(|w| w.set_cen(true));
        }};
    }

    /// The three counters' 16-bit counts, X / Y / Z.
    fn counts() -> [u16; 3] {
        [pac::TIM3.cnt().read().cnt(), pac::TIM4.cnt().read().cnt(), pac::TIM8.cnt().read().cnt()]
    }

    /// The pulse counters: clocks on, the ETR pins in their alternate function, each timer
    /// counting.
    fn start_counters() {
        pac::RCC.apb1enr().modify(|w| {
            w.set_tim3en(true);
            w.set_tim4en(true);
        });
        pac::RCC.apb2enr().modify(|w| w.set_tim8en(true));
        pac::RCC.ahb1enr().modify(|w| {
            w.set_gpioaen(true);
            w.set_gpioden(true);
            w.set_gpioeen(true);
        });
        let alternate = pac::gpio::vals::Moder::ALTERNATE;
        // PD2: TIM3_ETR (AF2); PE0: TIM4_ETR (AF2); PA0: TIM8_ETR (AF3).
        pac::GPIOD.afr(0).modify(|w| w.set_afr(2, 2));
        pac::GPIOD.moder().modify(|w| w.set_moder(2, alternate));
        pac::GPIOE.afr(0).modify(|w| w.set_afr(0, 2));
        pac::GPIOE.moder().modify(|w| w.set_moder(0, alternate));
        pac::GPIOA.afr(0).modify(|w| w.set_afr(0, 3));
        pac::GPIOA.moder().modify(|w| w.set_moder(0, alternate));
        etr_counter!(pac::TIM3);
        etr_counter!(pac::TIM4);
        etr_counter!(pac::TIM8);
    }

    /// The fast path, 400 times a second, above everything else: never blocks, never logs.
    #[embassy_executor::task]
    async fn imu(mut applier: ThreeAxisCountingApplier<'static>, mut widen: [Widen16; 3]) {
        let mut ticker = Ticker::every(Duration::from_micros(PERIOD_US));
        let mut last = Instant::now();
        loop {
            ticker.next().await;
            let now = Instant::now();
            let c = counts();
            let counters = [widen[0].update(c[0]), widen[1].update(c[1]), widen[2].update(c[2])];
            // µs ticks (Config::tick_s = 1 µs), however late this run: exact.
            let dt_us = (now - last).as_micros() as u32;
            last = now;
            let out = applier.cycle(counters, dt_us);
            // The navigation filter takes `out.dv_mps` here, and judges it by `out.status`: in
            // this task, or through an `embassy_sync` channel on a `CriticalSectionRawMutex`
            // with `try_send` (never `.await` or a thread-mode mutex in an interrupt executor).
            IMU_STATUS.store(u32::from(out.status.bits()), Ordering::Relaxed);
        }
    }

    /// One DS18B20 alone on its pin: 12 bits, externally powered (a parasite-powered one
    /// cannot show a lost conversion, so it is refused), a reading a second. The
    /// conversion is awaited; the bus slots block on the time driver's µs (see the firmware
    /// guide, "Which DelayNs").
    #[embassy_executor::task(pool_size = 3)]
    async fn sensor(axis: usize, pin: OutputOpenDrain<'static>) {
        let mut bus = OneWire::new(pin, Delay).with_slot_lock(slot_lock);
        let mut ds = Ds18b20::single();
        let mut ready = false;
        let mut ticker = Ticker::every(Duration::from_secs(1));
        loop {
            ticker.next().await;
            if !ready {
                ready = match ds.set_resolution(&mut bus, Resolution::Bits12).and_then(|()| ds.use_read_slots(&mut bus))
                {
                    Ok(PowerSupply::External) => true,
                    Ok(PowerSupply::Parasite) => {
                        defmt::error!("axis {}: DS18B20 is parasite-powered: refused", axis);
                        false
                    }
                    Err(e) => {
                        defmt::error!("axis {}: DS18B20 setup: {}", axis, e);
                        false
                    }
                };
            }
            let (t_ms, result) = if ready {
                match ds.measure_async(&mut bus, &mut Delay, now_us()).await {
                    // Stamped when the conversion completed, not after the ~6 ms read: the
                    // µs clock's distance back to it, off the ms clock now.
                    Ok(s) => (now_ms().wrapping_sub(now_us().wrapping_sub(s.completed_us) / 1_000), Ok(s.scratchpad)),
                    Err(e) => (now_ms(), Err(e)),
                }
            } else {
                (now_ms(), Err(drv::Error::NotReady))
            };
            READINGS.send(Reading { axis, t_ms, result }).await;
        }
    }

    #[embassy_executor::main]
    async fn main(spawner: Spawner) {
        let mut config = embassy_stm32::Config::default();
        {
            use embassy_stm32::rcc::*;
            use embassy_stm32::time::Hertz;
            // 8 MHz crystal, 168 MHz core; APB1 42 MHz (its timers 84 MHz), APB2 84 MHz.
            config.rcc.hse = Some(Hse { freq: Hertz(8_000_000), mode: HseMode::Oscillator });
            config.rcc.pll_src = PllSource::HSE;
            config.rcc.pll = Some(Pll {
                prediv: PllPreDiv::DIV4,
                mul: PllMul::MUL168,
                divp: Some(PllPDiv::DIV2),
                divq: Some(PllQDiv::DIV7),
                divr: None,
            });
            config.rcc.ahb_pre = AHBPrescaler::DIV1;
            config.rcc.apb1_pre = APBPrescaler::DIV4;
            config.rcc.apb2_pre = APBPrescaler::DIV2;
            config.rcc.sys = Sysclk::PLL1_P;
        }
        let p = embassy_stm32::init(config);

        // TIM7's period of the board example, here the IMU ticker's, in seconds.
        let comp = match ThreeAxisSensorPerAxis::new(Config { imu_period_s: 2.5e-3, ..Config::default() }) {
            Ok(c) => COMP.init(c),
            Err(e) => defmt::panic!("compensator config: {}", e),
        };
        if let Err(e) = comp.set_table(&TABLE) {
            defmt::error!("table refused: {}; raw pass-through at the nominal scale (NO_TABLE)", e);
        }
        let (mut updater, applier) = comp.split();

        start_counters();
        let c = counts();
        let widen = [Widen16::new(c[0]), Widen16::new(c[1]), Widen16::new(c[2])];
        let applier = applier.counting(widen.map(|w| w.total()));
        // NVIC numbering: lower is more urgent (P0 the most); the thread executor is below
        // every interrupt. (RTIC numbers the other way: higher is more urgent.)
        interrupt::UART4.set_priority(Priority::P6);
        let high = EXECUTOR_HIGH.start(interrupt::UART4);
        high.must_spawn(imu(applier, widen));

        // Released (high) from the start: a pin driving low would hold its bus down.
        let pins = [
            OutputOpenDrain::new(p.PB6, Level::High, Speed::Low),
            OutputOpenDrain::new(p.PB7, Level::High, Speed::Low),
            OutputOpenDrain::new(p.PB8, Level::High, Speed::Low),
        ];
        for (axis, pin) in pins.into_iter().enumerate() {
            spawner.must_spawn(sensor(axis, pin));
        }

        // The slow path: every reading, good or failed, to the updater; a log line a second.
        let mut last_log = now_ms();
        loop {
            let r = READINGS.receive().await;
            let result = match r.result {
                Ok(sp) => updater.on_scratchpad(r.axis, r.t_ms, &sp),
                Err(e) => {
                    defmt::error!("axis {}: reading missed: {}", r.axis, e);
                    updater.on_missed_reading(r.axis, r.t_ms)
                }
            };
            if let Err(e) = result {
                defmt::error!("axis {}: reading not used: {}", r.axis, e);
            }
            if now_ms().wrapping_sub(last_log) >= 1_000 {
                last_log = now_ms();
                let status = Status::from_bits_retain(IMU_STATUS.load(Ordering::Relaxed) as u16);
                let temps: [Option<f32>; 3] = core::array::from_fn(|i| updater.estimate_of(i).map(|e| e.temp_c));
                defmt::println!("imu status={} temp_c={}", status, temps);
            }
        }
    }
}
