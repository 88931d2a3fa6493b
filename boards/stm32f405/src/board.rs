//! The firmware proper (thumbv7em-none-eabihf only). See the crate docs for the wiring.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use cortex_m::peripheral::DWT;
use critical_section::Mutex;
use defmt_rtt as _;
use panic_probe as _;
use qfa_thermal::onewire::OneWire;
use qfa_thermal::time::MsClock;
use qfa_thermal::{Config, CountingApplier, Status, Table, ThreeAxisSensorPerAxis, Updater, DEFAULT_RATE_WINDOW};
use static_cell::StaticCell;
use stm32f4xx_hal::dwt::{Delay, DwtExt};
use stm32f4xx_hal::gpio::{alt, OpenDrain, Output, PartiallyErasedPin, PinState};
use stm32f4xx_hal::pac::{self, interrupt, Interrupt, TIM3, TIM4, TIM7, TIM8};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::Config as RccConfig;
use stm32f4xx_hal::timer::{CounterUs, Event, FTimerUs, Timer};

use crate::calibration;
use crate::cycle::{self, PERIOD_US};
use crate::poll::{self, Event as SensorEvent};
use crate::widen::Widen16;
use crate::wiring::{cnt16_tim3, cnt16_tim4, cnt16_tim8, etr_counter, now_us, slot_lock};

/// The recommended configuration: 3 axes, one DS18B20 per accelerometer case, the default
/// rate window, the table held by reference.
type Comp = ThreeAxisSensorPerAxis;
type Slow = Updater<'static, 3, DEFAULT_RATE_WINDOW, 3, &'static Table>;
/// The DS18B20s' pins: the port's letter is part of the type (pins on another port change
/// it here as well as in `main`).
type OneWirePin = PartiallyErasedPin<'B', Output<OpenDrain>>;

/// IMU cycles per logged summary (1 s).
const CYCLES_PER_SUMMARY: u32 = 1_000_000 / PERIOD_US;

/// The compensator; `split` borrows it for `'static`.
static COMP: StaticCell<Comp> = StaticCell::new();

/// Everything the IMU interrupt owns. Built in `main`, handed over once through
/// [`FAST_HANDOFF`].
struct Fast {
    applier: CountingApplier<'static, 3>,
    /// TIM7: the 400 Hz cycle; its counter (1 MHz) also times each read.
    tick: CounterUs<TIM7>,
    x: TIM3,
    y: TIM4,
    z: TIM8,
    widen: [Widen16; 3],
    /// TIM7 count (µs after the update event) at the previous read.
    last_lat: u32,
    /// DWT cycle counter at the previous read: tells how many periods passed.
    last_cyc: u32,
    sum: [f32; 3],
    status: Status,
    /// TIM7 periods in the summary being summed (runs and lost ones).
    cycles: u32,
    /// Update events lost in the summary being summed.
    lost: u32,
}

/// The one-time handoff of [`Fast`] from `main` to the interrupt. The lock is taken once:
/// the handler moves `Fast` into its own `static mut` local on its first run and owns it
/// from then on, so each later cycle runs with no lock (no critical section to add to
/// other interrupts' latency, nothing to fail); it shares only the compensator's lock-free
/// shared coefficient set and the log's [`SUMMARY`] atomics.
static FAST_HANDOFF: Mutex<RefCell<Option<Fast>>> = Mutex::new(RefCell::new(None));

/// What the interrupt publishes once a second for the main loop's log: Δv sums (f32 bits),
/// the OR of the status words, the TIM7 cycles lost (update events that found the
/// interrupt still pending, held off past a whole period), and a sequence number. Written
/// only by the interrupt; the main loop reads it inside a critical section, where the
/// interrupt cannot run, so it sees one whole second.
struct Summary {
    dv: [AtomicU32; 3],
    status: AtomicU32,
    lost: AtomicU32,
    seq: AtomicU32,
}

static SUMMARY: Summary = Summary {
    dv: [const { AtomicU32::new(0) }; 3],
    status: AtomicU32::new(0),
    lost: AtomicU32::new(0),
    seq: AtomicU32::new(0),
};

impl Fast {
    /// One IMU cycle, in the TIM7 interrupt. Never logs: a log call takes defmt-rtt's
    /// critical section and copies into the RTT buffer, time the cycle does not have.
    #[inline(always)]
    fn cycle(&mut self) {
        // Clear the update flag first (clearing it last can re-enter the handler).
        let _ = self.tick.wait();
        // µs since this cycle's update event, and the second clock that tells whether whole
        // periods passed unseen; the counters are read right after them.
        let lat = self.tick.now().ticks();
        let cyc = DWT::cycle_count();
        let counters = [
            self.widen[0].update(cnt16_tim3(&self.x)),
            self.widen[1].update(cnt16_tim4(&self.y)),
            self.widen[2].update(cnt16_tim8(&self.z)),
        ];
        // The time between two reads in µs ticks (Config::tick_s = 1 µs), exact however late
        // the interrupt runs, and the update events it missed when held off past a whole
        // period (cycle::timing): counted, not silent. The counts stay exact too (widen.rs).
        let t = cycle::timing(lat, self.last_lat, cyc.wrapping_sub(self.last_cyc));
        self.last_lat = lat;
        self.last_cyc = cyc;
        self.lost = self.lost.saturating_add(t.lost);

        let out = self.applier.cycle(counters, t.dt_us);
        // The navigation filter would take `out` here. The example sums it for the log.
        for (s, v) in self.sum.iter_mut().zip(out.dv_mps) {
            *s += v;
        }
        self.status |= out.status;
        // A summary is 1 s of periods, the lost ones included.
        self.cycles = self.cycles.saturating_add(1 + t.lost);
        if self.cycles >= CYCLES_PER_SUMMARY {
            for (d, s) in SUMMARY.dv.iter().zip(self.sum) {
                d.store(s.to_bits(), Ordering::Relaxed);
            }
            SUMMARY.status.store(u32::from(self.status.bits()), Ordering::Relaxed);
            SUMMARY.lost.store(self.lost, Ordering::Relaxed);
            SUMMARY.seq.store(SUMMARY.seq.load(Ordering::Relaxed).wrapping_add(1), Ordering::Relaxed);
            self.sum = [0.0; 3];
            self.status = Status::empty();
            self.cycles = 0;
            self.lost = 0;
        }
    }
}

#[interrupt]
fn TIM7() {
    static mut FAST: Option<Fast> = None;
    if FAST.is_none() {
        // The only lock: taken on the first cycle.
        *FAST = critical_section::with(|cs| FAST_HANDOFF.borrow_ref_mut(cs).take());
    }
    match FAST.as_mut() {
        Some(fast) => fast.cycle(),
        // Unreachable (main hands over before it unmasks TIM7); without the timer the
        // flag cannot be cleared, so stop the interrupt rather than re-enter forever.
        None => cortex_m::peripheral::NVIC::mask(Interrupt::TIM7),
    }
}

/// One DS18B20 on its own open-drain pin.
type Channel = poll::Channel<OneWirePin, Delay>;

/// The slow path, in thread mode: each sensor's [`poll::Channel::step`] (1 Hz conversions,
/// checked on the bus, read when done; every reading, good or failed, reaches the updater),
/// and the log. Every call is bounded (delays alone, SKIP ROM: start 2.2 ms with its check
/// slot, poll 70 µs, read ≤ 2 × 7.1 ms with the default retry, setup ≤ 35 ms); the IMU
/// interrupt preempts all of it except each slot's few locked µs ([`slot_lock`]).
fn slow_path(mut updater: Slow, mut chans: [Channel; 3], tim2: &pac::TIM2) -> ! {
    let mut clock = MsClock::new();
    let mut seen = SUMMARY.seq.load(Ordering::Relaxed);
    loop {
        // Keep the ms clock fed even if every sensor is failing (it must see the µs clock
        // at least every 35.8 min to count its wraps).
        let _ = clock.ms(now_us(tim2));
        for (axis, ch) in chans.iter_mut().enumerate() {
            let event = ch.step(&mut updater, &mut clock, axis, now_us(tim2));
            log_event(axis, event);
        }
        // Look without a critical section; take one (a few cycles of masked interrupts) only
        // once a second, to copy a whole summary.
        if SUMMARY.seq.load(Ordering::Relaxed) != seen {
            let (seq, dv, status, lost) = critical_section::with(|_| {
                let dv = SUMMARY.dv.each_ref().map(|d| f32::from_bits(d.load(Ordering::Relaxed)));
                let status = Status::from_bits_retain(SUMMARY.status.load(Ordering::Relaxed) as u16);
                (SUMMARY.seq.load(Ordering::Relaxed), dv, status, SUMMARY.lost.load(Ordering::Relaxed))
            });
            seen = seq;
            defmt::println!("1 s: dv_mps={} status={} temp_c={} lost_cycles={}", dv, status, temps(&updater), lost);
            if lost > 0 {
                defmt::error!("IMU: {} TIM7 cycles lost (interrupt held off past 2.5 ms); dt covers them", lost);
            }
        }
    }
}

/// Log what a sensor's step did that a person should see. Thread mode only: the IMU
/// interrupt never logs.
fn log_event(axis: usize, event: SensorEvent) {
    match event {
        SensorEvent::Idle | SensorEvent::Started | SensorEvent::Accepted(_) => {}
        SensorEvent::Configured => {
            defmt::println!("axis {}: DS18B20 at 12 bits, externally powered: conversions checked on the bus", axis)
        }
        SensorEvent::Missed { cause: poll::Cause::Parasite, .. } => defmt::error!(
            "axis {}: DS18B20 is parasite-powered: a lost conversion cannot be seen, so it is refused; \
             axis flagged TEMP_INVALID and TEMP_STALE",
            axis
        ),
        SensorEvent::Rejected { cause, error } => {
            defmt::error!("axis {}: reading refused: {} (driver: {})", axis, error, cause)
        }
        SensorEvent::Missed { cause, result } => {
            defmt::error!("axis {}: reading missed: {}; updater: {}", axis, cause, result)
        }
    }
}

/// Each sensor's current temperature estimate, °C; `None` before its first good reading.
fn temps(updater: &Slow) -> [Option<f32>; 3] {
    core::array::from_fn(|i| updater.estimate_of(i).map(|e| e.temp_c))
}

#[cortex_m_rt::entry]
fn main() -> ! {
    let (Some(dp), Some(cp)) = (pac::Peripherals::take(), cortex_m::Peripherals::take()) else {
        defmt::panic!("peripherals taken twice");
    };
    // 8 MHz crystal, 168 MHz core; APB1 42 MHz (its timers 84 MHz), APB2 84 MHz (168 MHz).
    let mut rcc = dp.RCC.freeze(RccConfig::hse(8.MHz()).sysclk(168.MHz()).pclk1(42.MHz()).pclk2(84.MHz()));
    // 1-Wire slot delays from the cycle counter: exact, and `Copy`, so each bus has one.
    let delay = cp.DWT.constrain(cp.DCB, &rcc.clocks).delay();

    // TIM2: the µs clock. The HAL enables it and sets the 1 MHz prescaler; the PAC makes it
    // free-running over all 32 bits (ARR = 2^32 - 1, so it wraps at exactly 2^32 µs, as
    // MsClock expects: the HAL's Counter::start would make ARR one tick short of that).
    let tim2 = FTimerUs::new(dp.TIM2, &mut rcc).release();
    tim2.arr().write(|w| w.arr().set(u32::MAX));
    tim2.egr().write(|w| w.ug().set_bit());
    tim2.cr1().write(|w| w.cen().enabled());

    defmt::println!(
        "qfa-board-stm32f405: RAM compensator {=usize} B; table {=usize} B in flash",
        core::mem::size_of::<Comp>(),
        core::mem::size_of::<Table>()
    );

    // TIM7's 400-Hz cycle in seconds: a dt in another unit than TIM2's 1-µs ticks is flagged.
    let comp = match Comp::new(Config { imu_period_s: 2.5e-3, ..Config::default() }) {
        Ok(c) => COMP.init(c),
        Err(e) => defmt::panic!("compensator config: {}", e),
    };
    // Validated where it lies in flash; a refusal leaves the raw pass-through, flagged.
    match comp.set_table(&calibration::TABLE) {
        Ok(()) => defmt::println!("table: validated in flash, {} axes", calibration::TABLE.axes.len()),
        Err(e) => defmt::error!("table: refused: {}; raw pass-through at the nominal scale (NO_TABLE)", e),
    }
    let (updater, applier) = comp.split();

    // Three DS18B20s, each alone on an open-drain pin with a 4.7 kΩ pull-up to 3.3 V.
    let gpiob = dp.GPIOB.split(&mut rcc);
    // Released (high) from the start: a pin that came up driving low would hold the bus
    // down and make the first reset see it stuck low.
    let pins: [OneWirePin; 3] = [
        gpiob.pb6.into_open_drain_output_in_state(PinState::High).erase_number(),
        gpiob.pb7.into_open_drain_output_in_state(PinState::High).erase_number(),
        gpiob.pb8.into_open_drain_output_in_state(PinState::High).erase_number(),
    ];
    // Each channel's first step sets 12 bits and reads the power supply (a parasite-powered
    // sensor is refused); a sensor that does not answer is set up again every second.
    let first_us = now_us(&tim2);
    let chans = pins.map(|pin| Channel::new(OneWire::new(pin, delay).with_slot_lock(slot_lock), first_us));

    // Pulse counters: TIM3 ETR on PD2 (AF2), TIM4 ETR on PE0 (AF2), TIM8 ETR on PA0 (AF3).
    // The HAL's typed ETR pins check the pin/AF pairs at compile time.
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

    // TIM7: the 400 Hz IMU cycle.
    let mut tick = dp.TIM7.counter_us(&mut rcc);
    if let Err(e) = tick.start(PERIOD_US.micros()) {
        defmt::panic!("TIM7 start: {}", e);
    }
    tick.listen(Event::Update);
    // Base the counters and the latency now, with no update pending, so the first cycle
    // gives real increments (no NO_COUNTER_BASE) over a real dt.
    let _ = tick.wait();
    let last_lat = tick.now().ticks();
    let last_cyc = DWT::cycle_count();
    let widen = [Widen16::new(cnt16_tim3(&x)), Widen16::new(cnt16_tim4(&y)), Widen16::new(cnt16_tim8(&z))];
    let applier = applier.counting(widen.map(|w| w.total()));
    let fast = Fast {
        applier,
        tick,
        x,
        y,
        z,
        widen,
        last_lat,
        last_cyc,
        sum: [0.0; 3],
        status: Status::empty(),
        cycles: 0,
        lost: 0,
    };
    critical_section::with(|cs| *FAST_HANDOFF.borrow_ref_mut(cs) = Some(fast));
    // Unmasking is unsafe because it can break a critical section built on masking this
    // interrupt; this program's only critical sections disable all interrupts (PRIMASK),
    // and everything the handler needs was handed over on the line above.
    #[allow(unsafe_code)]
    unsafe {
        cortex_m::peripheral::NVIC::unmask(Interrupt::TIM7);
    }

    slow_path(updater, chans, &tim2)
}
