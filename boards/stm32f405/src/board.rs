//! The firmware proper (thumbv7em-none-eabihf only). See the crate docs for the wiring.

use core::cell::RefCell;
use core::sync::atomic::{AtomicU32, Ordering};

use critical_section::Mutex;
use defmt_rtt as _;
use panic_probe as _;
use qfa_thermal::onewire::OneWire;
use qfa_thermal::time::MsClock;
use qfa_thermal::{Config, CountingApplier, Status, Table, ThreeAxisSensorPerAxis, Updater, DEFAULT_RATE_WINDOW};
use static_cell::StaticCell;
use stm32f4xx_hal::dwt::{Delay, DwtExt};
use stm32f4xx_hal::pac::{self, interrupt, Interrupt};
use stm32f4xx_hal::prelude::*;

use crate::calibration;
use crate::cycle::PERIOD_US;
use crate::poll::{self, Event as SensorEvent};
use crate::wiring::{self, now_us, slot_lock, OneWirePin};

/// The recommended configuration: 3 axes, one DS18B20 per accelerometer case, the default
/// rate window, the table held by reference.
type Comp = ThreeAxisSensorPerAxis;
type Slow = Updater<'static, 3, DEFAULT_RATE_WINDOW, 3, &'static Table>;

/// IMU cycles per logged summary (1 s).
const CYCLES_PER_SUMMARY: u32 = 1_000_000 / PERIOD_US;

/// The compensator; `split` borrows it for `'static`.
static COMP: StaticCell<Comp> = StaticCell::new();

/// Everything the IMU interrupt owns. Built in `main`, handed over once through
/// [`FAST_HANDOFF`].
struct Fast {
    applier: CountingApplier<'static, 3>,
    /// TIM7, the pulse counters and the cycle timing's clocks.
    inputs: wiring::ImuInputs,
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
        let (counters, t) = self.inputs.read();
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
    let mut rcc = wiring::clocks(dp.RCC);
    // 1-Wire slot delays from the cycle counter: exact, and `Copy`, so each bus has one.
    let delay = cp.DWT.constrain(cp.DCB, &rcc.clocks).delay();
    let tim2 = wiring::us_clock(dp.TIM2, &mut rcc);

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

    let gpiob = dp.GPIOB.split(&mut rcc);
    let pins = wiring::onewire_pins(gpiob.pb6, gpiob.pb7, gpiob.pb8);
    // Each channel's first step sets 12 bits and reads the power supply (a parasite-powered
    // sensor is refused); a sensor that does not answer is set up again every second.
    let first_us = now_us(&tim2);
    let chans = pins.map(|pin| Channel::new(OneWire::new(pin, delay).with_slot_lock(slot_lock), first_us));

    let (gpioa, gpiod, gpioe) = (dp.GPIOA.split(&mut rcc), dp.GPIOD.split(&mut rcc), dp.GPIOE.split(&mut rcc));
    let (x, y, z) = wiring::pulse_counters((dp.TIM3, dp.TIM4, dp.TIM8), (gpiod.pd2, gpioe.pe0, gpioa.pa0), &mut rcc);

    // TIM7: the 400 Hz IMU cycle. Base the counters and the latency now, with no update
    // pending, so the first cycle gives real increments (no NO_COUNTER_BASE) over a real dt.
    let tick = match wiring::imu_tick(dp.TIM7, PERIOD_US, &mut rcc) {
        Ok(t) => t,
        Err(e) => defmt::panic!("TIM7 start: {}", e),
    };
    let inputs = wiring::ImuInputs::new(tick, (x, y, z));
    let applier = applier.counting(inputs.totals());
    let fast = Fast { applier, inputs, sum: [0.0; 3], status: Status::empty(), cycles: 0, lost: 0 };
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
