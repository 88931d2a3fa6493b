//! The board's wiring that the bare-metal example and the RTIC app share: its clocks, the
//! µs clock, the DS18B20 pins, the pulse counters on the timers' ETR inputs, the IMU tick,
//! and the 1-Wire slot lock. To move a signal, change it here.

use stm32f4xx_hal::gpio::gpioa::PA0;
use stm32f4xx_hal::gpio::gpiob::{PB6, PB7, PB8};
use stm32f4xx_hal::gpio::gpiod::PD2;
use stm32f4xx_hal::gpio::gpioe::PE0;
use stm32f4xx_hal::gpio::{alt, OpenDrain, Output, PartiallyErasedPin, PinState};
use stm32f4xx_hal::pac::{self, RCC, TIM2, TIM3, TIM4, TIM7, TIM8};
use stm32f4xx_hal::prelude::*;
use stm32f4xx_hal::rcc::{Config as RccConfig, Rcc};
use stm32f4xx_hal::timer::{CounterUs, Event, FTimerUs, Timer};

/// Program TIM3/TIM4 (`tim3::RegisterBlock`) or TIM8 (`tim1::RegisterBlock`) as a free-running
/// 16-bit up-counter of rising edges on its ETR pin: external clock mode 2 (ECE = 1), no
/// ETR prescaler, a 4-sample digital filter at f_CK_INT (an edge must last 4 timer clocks:
/// 48 ns on TIM3/TIM4 at 84 MHz, 24 ns on TIM8 at 168 MHz), auto-reload 0xFFFF. The HAL
/// has no ETR counting mode, so these are plain PAC writes (safe svd2rust API); the HAL
/// has already enabled and reset the timer.
macro_rules! etr_counter_impl {
    ($tim:expr) => {{
        let t = &$tim;
        t.smcr().write(|w| w.etf().fck_int_n4().etps().div1().etp().not_inverted().ece().enabled().sms().disabled());
        t.arr().write(|w| w.arr().set(0xFFFF));
        t.egr().write(|w| w.ug().set_bit());
        t.cr1().write(|w| w.cen().enabled());
    }};
}

/// [`etr_counter_impl`] by its use: `etr_counter!(tim)`.
pub(crate) use etr_counter_impl as etr_counter;

/// The DS18B20s' pins: open drain, each sensor alone on its own. The port's letter is part
/// of the type: pins on another port change it here and in [`onewire_pins`].
pub type OneWirePin = PartiallyErasedPin<'B', Output<OpenDrain>>;

/// The clocks: 8 MHz crystal, 168 MHz core; APB1 42 MHz (its timers 84 MHz), APB2 84 MHz
/// (its timers 168 MHz).
pub fn clocks(rcc: RCC) -> Rcc {
    rcc.freeze(RccConfig::hse(8.MHz()).sysclk(168.MHz()).pclk1(42.MHz()).pclk2(84.MHz()))
}

/// TIM2 as the µs clock. The HAL enables it and sets the 1 MHz prescaler; the PAC makes it
/// free-running over all 32 bits (ARR = 2³² − 1, so it wraps at exactly 2³² µs, as
/// `MsClock` expects: the HAL's `Counter::start` would make ARR one tick short of that).
pub fn us_clock(tim2: TIM2, rcc: &mut Rcc) -> TIM2 {
    let t = FTimerUs::new(tim2, rcc).release();
    t.arr().write(|w| w.arr().set(u32::MAX));
    t.egr().write(|w| w.ug().set_bit());
    t.cr1().write(|w| w.cen().enabled());
    t
}

/// The DS18B20s X / Y / Z on PB6 / PB7 / PB8, each alone on its pin with a 4.7 kΩ pull-up
/// to 3.3 V. Released (high) from the start: a pin that came up driving low would hold its
/// bus down and make the first reset see it stuck low.
pub fn onewire_pins(x: PB6, y: PB7, z: PB8) -> [OneWirePin; 3] {
    [
        x.into_open_drain_output_in_state(PinState::High).erase_number(),
        y.into_open_drain_output_in_state(PinState::High).erase_number(),
        z.into_open_drain_output_in_state(PinState::High).erase_number(),
    ]
}

/// The pulse counters X / Y / Z: TIM3 ETR on PD2 (AF2), TIM4 ETR on PE0 (AF2), TIM8 ETR on
/// PA0 (AF3), each counting rising edges (the HAL's typed ETR pins check the pin/AF pairs
/// at compile time).
pub fn pulse_counters(tims: (TIM3, TIM4, TIM8), pins: (PD2, PE0, PA0), rcc: &mut Rcc) -> (TIM3, TIM4, TIM8) {
    let _etr_x: alt::tim3::Etr = pins.0.into();
    let _etr_y: alt::tim4::Etr = pins.1.into();
    let _etr_z: alt::tim8::Etr = pins.2.into();
    let x = Timer::new(tims.0, rcc).release();
    let y = Timer::new(tims.1, rcc).release();
    let z = Timer::new(tims.2, rcc).release();
    etr_counter!(x);
    etr_counter!(y);
    etr_counter!(z);
    (x, y, z)
}

/// TIM7 as the IMU cycle of `period_us`, its update event enabled (the interrupt is
/// unmasked by the caller) and no update pending, so the first cycle has a real dt.
///
/// # Errors
/// The HAL's, when the period does not fit the timer.
pub fn imu_tick(tim7: TIM7, period_us: u32, rcc: &mut Rcc) -> Result<CounterUs<TIM7>, stm32f4xx_hal::timer::Error> {
    let mut tick = tim7.counter_us(rcc);
    tick.start(period_us.micros())?;
    tick.listen(Event::Update);
    let _ = tick.wait();
    Ok(tick)
}

/// TIM3's 16-bit count (axis X's pulses).
pub fn cnt16_tim3(t: &TIM3) -> u16 {
    t.cnt().read().cnt().bits()
}
/// TIM4's 16-bit count (axis Y's pulses).
pub fn cnt16_tim4(t: &TIM4) -> u16 {
    t.cnt().read().cnt().bits()
}
/// TIM8's 16-bit count (axis Z's pulses).
pub fn cnt16_tim8(t: &TIM8) -> u16 {
    t.cnt().read().cnt().bits()
}

/// The TIM2 count: the free-running 32-bit µs clock (wraps every 71.6 min).
pub fn now_us(tim2: &pac::TIM2) -> u32 {
    tim2.cnt().read().bits()
}

/// The 1-Wire slot lock: the timing-critical part of each read slot and write-1 slot (pull
/// low, release, sample) runs with interrupts masked. A read slot samples 10 µs after its
/// falling edge and the sensor's data is valid only until 15 µs, so a TIM7 run landing in
/// between (the handler plus its entry and exit) could push the sample out of the window
/// and read a 0 as 1; a write-1 held low past 15 µs is written as 0.
///
/// Safe for the IMU interrupt: the locked part is at most 10 µs of delay and three pin
/// calls (register writes and a read, tens of ns at 168 MHz), so a TIM7 update that comes
/// during it stays pending for at most about 11 µs and then runs. That is far inside its
/// budget: the fast path measures its own dt, so a late run costs nothing, and a cycle is
/// lost only when held off a whole 2.5 ms period (and then counted, `cycle::timing`). The
/// rest of each slot (the write-0 low time, the recovery, the reset) stays open to
/// interrupts; see `qfa_thermal::onewire` for why it tolerates them.
pub fn slot_lock(f: &mut dyn FnMut()) {
    critical_section::with(|_| f());
}

/// What the IMU interrupt reads each cycle: TIM7 (the cycle, and its count for the timing),
/// the three pulse counters widened to cumulative `u32`s, and the DWT cycle counter.
pub struct ImuInputs {
    /// TIM7: the cycle; its counter (1 MHz) also times each read.
    tick: CounterUs<TIM7>,
    x: TIM3,
    y: TIM4,
    z: TIM8,
    widen: [crate::widen::Widen16; 3],
    /// TIM7 count (µs after the update event) at the previous read.
    last_lat: u32,
    /// DWT cycle counter at the previous read: tells how many periods passed.
    last_cyc: u32,
}

impl ImuInputs {
    /// From [`imu_tick`] and [`pulse_counters`], based now (no update pending), so the first
    /// cycle gives real increments over a real dt. The DWT cycle counter must be running.
    pub fn new(tick: CounterUs<TIM7>, (x, y, z): (TIM3, TIM4, TIM8)) -> Self {
        use crate::widen::Widen16;
        let last_lat = tick.now().ticks();
        let last_cyc = cortex_m::peripheral::DWT::cycle_count();
        let widen = [Widen16::new(cnt16_tim3(&x)), Widen16::new(cnt16_tim4(&y)), Widen16::new(cnt16_tim8(&z))];
        Self { tick, x, y, z, widen, last_lat, last_cyc }
    }

    /// The cumulative counts now: the base `Applier::counting` starts from.
    pub fn totals(&self) -> [u32; 3] {
        self.widen.map(|w| w.total())
    }

    /// One cycle, in TIM7's interrupt: its update flag cleared (first: clearing it last can
    /// re-enter the handler), the cumulative counts, and the time since the previous read in
    /// µs ticks (`Config::tick_s` = 1 µs), exact however late the interrupt runs, with the
    /// update events it missed when held off past a whole period (`cycle::timing`): counted,
    /// not silent. The counts stay exact too (`widen.rs`).
    #[inline(always)]
    pub fn read(&mut self) -> ([u32; 3], crate::cycle::Cycle) {
        let _ = self.tick.wait();
        // µs since this cycle's update event, and the second clock that tells whether whole
        // periods passed unseen; the counters are read right after them.
        let lat = self.tick.now().ticks();
        let cyc = cortex_m::peripheral::DWT::cycle_count();
        let counts = [
            self.widen[0].update(cnt16_tim3(&self.x)),
            self.widen[1].update(cnt16_tim4(&self.y)),
            self.widen[2].update(cnt16_tim8(&self.z)),
        ];
        let t = crate::cycle::timing(lat, self.last_lat, cyc.wrapping_sub(self.last_cyc));
        (self.last_lat, self.last_cyc) = (lat, cyc);
        (counts, t)
    }
}
