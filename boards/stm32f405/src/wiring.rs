//! The board's hardware helpers that the bare-metal example and the RTIC app share: the
//! pulse counters on the timers' ETR inputs, the µs clock, and the 1-Wire slot lock.

use stm32f4xx_hal::pac::{self, TIM3, TIM4, TIM8};

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

/// [`etr_counter_impl`] by its use: `etr_counter!(tim)`.
pub(crate) use etr_counter_impl as etr_counter;

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
