//! Simulated 1-Wire bus with DS18B20 devices answering at the bit level.
//!
//! [`Sim`] holds a simulated clock and line; [`SimPin`] (open drain: `set_low` drives,
//! `set_high` releases, `is_high` reads the wired-AND line) and [`SimDelay`] share it,
//! so the real [`OneWire`] driver runs against it unchanged. Each pin call costs
//! [`World::pin_overhead_ns`] of simulated time, delays cost what they ask.
//!
//! Devices behave as a worst-case datasheet part by default: the presence pulse starts
//! 60 µs after the reset is released and lasts 60 µs, a transmitted 0 is held for
//! only 15 µs after the falling edge, and a written bit is judged by the master's low
//! time (≤ 15 µs is 1, ≥ 60 µs is 0). Master timing outside the datasheet limits is
//! recorded in [`World::violations`].
//!
//! Faults: a flipped transmitted bit ([`Device::flip_bit`]), no presence
//! ([`Device::present`]), a stuck-low bus ([`World::stuck_low_at_ns`]), a brown-out
//! back to the power-on scratchpad ([`Device::brown_out_at_ns`], with a clone part's byte 6:
//! [`Device::power_on_byte6`]), pin errors
//! ([`World::pin_error`]), a lost Convert T ([`Device::drop_convert_t`]: the command
//! never starts a conversion, so the scratchpad keeps the previous one).
//!
//! Interrupts: [`World::interrupt`] is a periodic handler on the simulated CPU. Outside a
//! slot lock it holds the master up (a delay or a pin call ends when the handler does, as
//! a busy-wait delay would); inside [`sim_slot_lock`] (given to
//! [`OneWire::with_slot_lock`]) it waits for the lock to end. A read slot sampled later
//! than 15 µs after its falling edge is recorded in [`World::violations`].

use std::cell::{Cell, RefCell};
use std::rc::Rc;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{self, ErrorType, InputPin, OutputPin};
use qfa_thermal::ds18b20::{crc8, Resolution, POWER_ON_RAW};
use qfa_thermal::onewire::OneWire;

const US: u64 = 1_000;

/// Protocol state of one device, between resets.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    /// Ignores slots until the next reset.
    Idle,
    /// Receiving a ROM command.
    RomCmd,
    /// Receiving the 64 ROM bits of MATCH ROM.
    MatchRom,
    /// Transmitting its ROM (READ ROM).
    ReadRom,
    /// SEARCH ROM at `bit`, step 0 = send bit, 1 = send complement, 2 = receive.
    Search { bit: usize, step: u8 },
    /// Selected, receiving a function command.
    FuncCmd,
    /// Receiving TH, TL, config.
    WriteScratch,
    /// Transmitting `tx` (scratchpad).
    TxData,
    /// After Convert T: read slots give 0 while converting (external power only).
    ConvertPoll,
    /// After Read Power Supply: read slots give 0 if parasite.
    PowerPoll,
}

/// One simulated DS18B20 (or another family, for search tests).
#[derive(Clone, Debug)]
pub struct Device {
    /// ROM code, family first, CRC last.
    pub rom: [u8; 8],
    /// Answers resets and slots. `false` injects the no-presence fault.
    pub present: bool,
    /// Parasite powered: answers B4h with 0 and does not answer conversion polling.
    pub parasite: bool,
    /// The temperature it measures, in 1/16 °C.
    pub temp_raw: i16,
    /// Conversion time as a fraction of the datasheet maximum for the resolution.
    pub conversion_fraction: f64,
    /// Flip this bit (0-based, in transmission order) of the next `flip_times`
    /// transmissions (scratchpad, READ ROM, or the slots of a SEARCH ROM pass).
    pub flip_bit: usize,
    /// How many transmissions still get the flip.
    pub flip_times: u32,
    /// Brown-out at this simulated time: the scratchpad returns to the power-on
    /// value and the EEPROM configuration, a conversion is lost.
    pub brown_out_at_ns: Option<u64>,
    /// Byte 6 of the power-on scratchpad: 0Ch on a genuine DS18B20 (the decoder's power-on
    /// rule), something else on some clone parts, whose brown-out then decodes as a real
    /// +85 °C reading and only the compensator can refuse it.
    pub power_on_byte6: u8,
    /// Lose this many of the next Convert T (44h) commands: the device goes idle instead
    /// of converting (a corrupted command byte, or a sensor that browned out and came
    /// back between the reset and the command). The scratchpad keeps the previous
    /// conversion with a good CRC, and read slots after the command read 1 (nothing
    /// drives the line), as from a real part that did not take the command.
    pub drop_convert_t: u32,
    /// How long a transmitted 0 is held after the falling edge (datasheet ≥ 15 µs).
    pub hold_ns: u64,
    /// Presence pulse start after reset release (15–60 µs) and length (60–240 µs).
    pub presence_ns: (u64, u64),
    /// EEPROM TH, TL, config.
    pub eeprom: [u8; 3],
    scratch: [u8; 8],
    conv_end_ns: Option<u64>,
    phase: Phase,
    rx: u64,
    rx_n: u32,
    tx: [u8; 9],
    tx_bits: usize,
    tx_idx: usize,
    flip_active: bool,
    sent_in_slot: Option<bool>,
    pull: (u64, u64),
}

impl Device {
    /// A DS18B20 with serial `serial` measuring `temp_raw`, externally powered,
    /// power-on scratchpad.
    #[must_use]
    pub fn ds18b20(serial: u64, temp_raw: i16) -> Self {
        Self::with_family(0x28, serial, temp_raw)
    }

    /// A device of family `family` (only DS18B20 function commands are simulated).
    #[must_use]
    pub fn with_family(family: u8, serial: u64, temp_raw: i16) -> Self {
        let s = serial.to_le_bytes();
        let mut rom = [family, s[0], s[1], s[2], s[3], s[4], s[5], 0];
        rom[7] = crc8(&rom[..7]);
        let eeprom = [0x4B, 0x46, 0x7F];
        let mut d = Self {
            rom,
            present: true,
            parasite: false,
            temp_raw,
            conversion_fraction: 0.8,
            flip_bit: 0,
            flip_times: 0,
            brown_out_at_ns: None,
            power_on_byte6: 0x0C,
            drop_convert_t: 0,
            hold_ns: 15 * US,
            presence_ns: (60 * US, 60 * US),
            eeprom,
            scratch: [0; 8],
            conv_end_ns: None,
            phase: Phase::Idle,
            rx: 0,
            rx_n: 0,
            tx: [0; 9],
            tx_bits: 0,
            tx_idx: 0,
            flip_active: false,
            sent_in_slot: None,
            pull: (0, 0),
        };
        d.power_on();
        d
    }

    fn power_on(&mut self) {
        let t = POWER_ON_RAW.to_le_bytes();
        self.scratch = [t[0], t[1], self.eeprom[0], self.eeprom[1], self.eeprom[2], 0xFF, self.power_on_byte6, 0x10];
        self.conv_end_ns = None;
        self.phase = Phase::Idle;
    }

    /// Current scratchpad bytes 0–7 (after pending events up to the last bus action).
    #[must_use]
    pub fn scratchpad(&self) -> [u8; 8] {
        self.scratch
    }

    fn resolution(&self) -> Resolution {
        Resolution::from_config(self.scratch[4]).unwrap_or(Resolution::Bits12)
    }

    /// Apply the time-driven events (brown-out, conversion end) up to `now`.
    fn advance(&mut self, now: u64) {
        if let Some(t) = self.brown_out_at_ns {
            if now >= t {
                self.brown_out_at_ns = None;
                self.power_on();
            }
        }
        if let Some(end) = self.conv_end_ns {
            if now >= end {
                self.conv_end_ns = None;
                let res = self.resolution();
                // Undefined low bits read as 1 at reduced resolution: the decoder must mask them.
                let raw = (self.temp_raw & res.raw_mask()) | !res.raw_mask();
                let [lo, hi] = raw.to_le_bytes();
                self.scratch[0] = lo;
                self.scratch[1] = hi;
                self.scratch[6] = 0x10 - (lo & 0x0F);
            }
        }
    }

    fn start_tx(&mut self, bytes: &[u8], phase: Phase) {
        self.tx[..bytes.len()].copy_from_slice(bytes);
        self.tx_bits = bytes.len() * 8;
        self.tx_idx = 0;
        self.phase = phase;
        self.begin_transmission();
    }

    fn begin_transmission(&mut self) {
        self.flip_active = self.flip_times > 0;
        if self.flip_active {
            self.flip_times -= 1;
        }
    }

    /// The bit this device puts on the line in a read slot, `None` if it is receiving.
    fn bit_to_send(&mut self, now: u64) -> Option<bool> {
        let (bit, index) = match self.phase {
            Phase::ReadRom | Phase::TxData => {
                let i = self.tx_idx;
                let bit = i >= self.tx_bits || self.tx[i / 8] & (1 << (i % 8)) != 0;
                (bit, i)
            }
            Phase::Search { bit, step: 0 } => (self.rom_bit(bit), 2 * bit),
            Phase::Search { bit, step: 1 } => (!self.rom_bit(bit), 2 * bit + 1),
            Phase::ConvertPoll => return Some(self.parasite || self.conv_end_ns.is_none_or(|e| now >= e)),
            Phase::PowerPoll => return Some(!self.parasite),
            _ => return None,
        };
        Some(bit ^ (self.flip_active && index == self.flip_bit))
    }

    fn rom_bit(&self, i: usize) -> bool {
        self.rom[i / 8] & (1 << (i % 8)) != 0
    }

    fn falling_edge(&mut self, now: u64) {
        self.advance(now);
        self.sent_in_slot = None;
        if !self.present {
            return;
        }
        if let Some(bit) = self.bit_to_send(now) {
            self.sent_in_slot = Some(bit);
            if !bit {
                self.pull = (now, now + self.hold_ns);
            }
        }
    }

    fn reset(&mut self, release: u64) {
        self.advance(release);
        if !self.present {
            return;
        }
        self.phase = Phase::RomCmd;
        self.rx = 0;
        self.rx_n = 0;
        self.pull = (release + self.presence_ns.0, release + self.presence_ns.0 + self.presence_ns.1);
    }

    fn slot_end(&mut self, written: bool, now: u64) {
        if !self.present {
            return;
        }
        if self.sent_in_slot.take().is_some() {
            match self.phase {
                Phase::ReadRom | Phase::TxData => self.tx_idx += 1,
                Phase::Search { bit, step } => self.phase = Phase::Search { bit, step: step + 1 },
                _ => {}
            }
            return;
        }
        match self.phase {
            Phase::Search { bit, step: 2 } => {
                self.phase = if written != self.rom_bit(bit) {
                    Phase::Idle
                } else if bit == 63 {
                    Phase::FuncCmd
                } else {
                    Phase::Search { bit: bit + 1, step: 0 }
                };
            }
            Phase::RomCmd | Phase::MatchRom | Phase::FuncCmd | Phase::WriteScratch => {
                self.rx |= u64::from(written) << self.rx_n;
                self.rx_n += 1;
                self.received(now);
            }
            _ => {}
        }
    }

    fn received(&mut self, now: u64) {
        match self.phase {
            Phase::RomCmd if self.rx_n == 8 => {
                let cmd = self.rx as u8;
                self.rx = 0;
                self.rx_n = 0;
                match cmd {
                    0x33 => {
                        let rom = self.rom;
                        self.start_tx(&rom, Phase::ReadRom);
                    }
                    0x55 => self.phase = Phase::MatchRom,
                    0xCC => self.phase = Phase::FuncCmd,
                    0xF0 => {
                        self.phase = Phase::Search { bit: 0, step: 0 };
                        self.begin_transmission();
                    }
                    _ => self.phase = Phase::Idle,
                }
            }
            Phase::MatchRom if self.rx_n == 64 => {
                self.phase = if self.rx.to_le_bytes() == self.rom { Phase::FuncCmd } else { Phase::Idle };
                self.rx = 0;
                self.rx_n = 0;
            }
            Phase::FuncCmd if self.rx_n == 8 => {
                let cmd = self.rx as u8;
                self.rx = 0;
                self.rx_n = 0;
                match cmd {
                    0x44 if self.drop_convert_t > 0 => {
                        self.drop_convert_t -= 1;
                        self.phase = Phase::Idle;
                    }
                    0x44 => {
                        let max = u64::from(self.resolution().max_conversion_us()) * US;
                        self.conv_end_ns = Some(now + (max as f64 * self.conversion_fraction) as u64);
                        self.phase = Phase::ConvertPoll;
                    }
                    0xBE => {
                        let mut sp = [0; 9];
                        sp[..8].copy_from_slice(&self.scratch);
                        sp[8] = crc8(&self.scratch);
                        self.start_tx(&sp, Phase::TxData);
                    }
                    0x4E => self.phase = Phase::WriteScratch,
                    0xB4 => self.phase = Phase::PowerPoll,
                    _ => self.phase = Phase::Idle,
                }
            }
            Phase::WriteScratch if self.rx_n == 24 => {
                let [th, tl, cfg, ..] = self.rx.to_le_bytes();
                self.scratch[2] = th;
                self.scratch[3] = tl;
                // Only R1/R0 (bits 6–5) are writable; the rest reads 0 and 1Fh.
                self.scratch[4] = (cfg & 0x60) | 0x1F;
                self.phase = Phase::Idle;
            }
            _ => {}
        }
    }
}

/// A periodic interrupt on the simulated CPU.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Interrupt {
    /// When it next fires, ns.
    pub next_ns: u64,
    /// Its period, ns.
    pub period_ns: u64,
    /// How long its handler runs, ns.
    pub duration_ns: u64,
}

thread_local! {
    /// Inside [`sim_slot_lock`] on this thread (each test runs on its own thread).
    static SLOT_LOCKED: Cell<bool> = const { Cell::new(false) };
}

/// A [`qfa_thermal::onewire::SlotLock`] for the simulation: while it runs `f`, interrupts
/// wait, as in a critical section.
pub fn sim_slot_lock(f: &mut dyn FnMut()) {
    SLOT_LOCKED.set(true);
    f();
    SLOT_LOCKED.set(false);
}

/// The shared simulated bus state.
#[derive(Debug)]
pub struct World {
    /// Simulated time, ns.
    pub now_ns: u64,
    /// Cost of each pin call, ns.
    pub pin_overhead_ns: u64,
    /// The line is held low from this time on (stuck-low fault).
    pub stuck_low_at_ns: Option<u64>,
    /// Every pin call fails.
    pub pin_error: bool,
    /// The devices on the bus.
    pub devices: Vec<Device>,
    /// Master timing outside the datasheet limits, as found.
    pub violations: Vec<String>,
    /// A periodic interrupt, if any.
    pub interrupt: Option<Interrupt>,
    /// Interrupts that held the master up (outside a slot lock).
    pub interrupts_stretching: u64,
    /// Interrupts that came during a slot lock and waited for it.
    pub interrupts_deferred: u64,
    /// Simulated time at the end of the last advance inside a slot lock.
    locked_end_ns: u64,
    master_low: bool,
    fall_ns: u64,
    prev_fall_ns: Option<u64>,
    release_ns: u64,
    reset_release_ns: Option<u64>,
}

impl World {
    /// Let `ns` pass for the master (a delay or a pin call's own time), and run the
    /// interrupts that came due: outside a slot lock, each holds the master up until its
    /// handler ends; inside one, they wait until the lock ends.
    fn advance(&mut self, ns: u64) {
        self.now_ns += ns;
        if SLOT_LOCKED.get() {
            self.locked_end_ns = self.now_ns;
            return;
        }
        let Some(mut irq) = self.interrupt else { return };
        while irq.next_ns <= self.now_ns {
            let start = irq.next_ns.max(self.locked_end_ns);
            if start > irq.next_ns {
                self.interrupts_deferred += 1;
            }
            if start + irq.duration_ns > self.now_ns {
                self.interrupts_stretching += u64::from(start == irq.next_ns);
                self.now_ns = start + irq.duration_ns;
            }
            irq.next_ns += irq.period_ns;
        }
        self.interrupt = Some(irq);
    }

    /// The line as the master reads it; a read slot sampled after the device's data
    /// window (15 µs from the falling edge, before the 60 µs slot end) is a violation.
    fn sample(&mut self) -> bool {
        let since_fall = self.now_ns - self.fall_ns;
        if !self.master_low && self.reset_release_ns.is_none() && since_fall > 15 * US && since_fall < 60 * US {
            self.violations.push(format!("read sampled {since_fall} ns after the falling edge, > 15 µs"));
        }
        self.line_low()
    }

    fn line_low(&self) -> bool {
        let t = self.now_ns;
        self.master_low
            || self.stuck_low_at_ns.is_some_and(|s| t >= s)
            || self.devices.iter().any(|d| d.present && d.pull.0 <= t && t < d.pull.1)
    }

    fn set_low(&mut self) {
        if self.master_low {
            return;
        }
        let t = self.now_ns;
        if t - self.release_ns < US {
            self.violations.push(format!("recovery {} ns < 1 µs at {t}", t - self.release_ns));
        }
        if let Some(r) = self.reset_release_ns.take() {
            if t - r < 480 * US {
                self.violations.push(format!("slot {} ns after reset, < 480 µs", t - r));
            }
        } else if let Some(p) = self.prev_fall_ns {
            if t - p < 61 * US {
                self.violations.push(format!("slot period {} ns < 61 µs at {t}", t - p));
            }
        }
        self.master_low = true;
        self.fall_ns = t;
        for d in &mut self.devices {
            d.falling_edge(t);
        }
    }

    fn set_high(&mut self) {
        if !self.master_low {
            return;
        }
        let t = self.now_ns;
        self.master_low = false;
        self.release_ns = t;
        let low = t - self.fall_ns;
        if low >= 480 * US {
            self.prev_fall_ns = None;
            self.reset_release_ns = Some(t);
            for d in &mut self.devices {
                d.reset(t);
            }
            return;
        }
        self.prev_fall_ns = Some(self.fall_ns);
        if low > 120 * US {
            self.violations.push(format!("low {low} ns: neither slot nor reset"));
        }
        let written = if low <= 15 * US {
            true
        } else {
            if low < 60 * US {
                self.violations.push(format!("write low {low} ns between 15 and 60 µs"));
            }
            false
        };
        for d in &mut self.devices {
            d.slot_end(written, t);
        }
    }
}

/// Handle to a simulated bus.
#[derive(Clone, Debug)]
pub struct Sim(Rc<RefCell<World>>);

impl Sim {
    /// A bus with `devices`, 500 ns per pin call.
    #[must_use]
    pub fn new(devices: Vec<Device>) -> Self {
        Self(Rc::new(RefCell::new(World {
            now_ns: 0,
            pin_overhead_ns: 500,
            stuck_low_at_ns: None,
            pin_error: false,
            devices,
            violations: Vec::new(),
            interrupt: None,
            interrupts_stretching: 0,
            interrupts_deferred: 0,
            locked_end_ns: 0,
            master_low: false,
            fall_ns: 0,
            prev_fall_ns: None,
            release_ns: 0,
            reset_release_ns: None,
        })))
    }

    /// A [`OneWire`] on this bus.
    #[must_use]
    pub fn bus(&self) -> OneWire<SimPin, SimDelay> {
        OneWire::new(SimPin(self.clone()), SimDelay(self.clone()))
    }

    /// Run `f` on the bus state (to inject faults or inspect).
    pub fn with<R>(&self, f: impl FnOnce(&mut World) -> R) -> R {
        f(&mut self.0.borrow_mut())
    }

    /// Simulated time, µs (wrapping u32, like a firmware timer).
    #[must_use]
    pub fn now_us(&self) -> u32 {
        (self.0.borrow().now_ns / US) as u32
    }

    /// Simulated time, ns.
    #[must_use]
    pub fn now_ns(&self) -> u64 {
        self.0.borrow().now_ns
    }

    /// Let simulated time pass with the bus idle (the application doing other work).
    pub fn idle_us(&self, us: u64) {
        self.0.borrow_mut().advance(us * US);
    }

    /// The timing violations recorded so far.
    #[must_use]
    pub fn violations(&self) -> Vec<String> {
        self.0.borrow().violations.clone()
    }
}

/// Error of a [`SimPin`] call (the pin-error fault).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SimPinError;

impl digital::Error for SimPinError {
    fn kind(&self) -> digital::ErrorKind {
        digital::ErrorKind::Other
    }
}

/// Open-drain pin on a [`Sim`] bus.
#[derive(Debug)]
pub struct SimPin(Sim);

impl SimPin {
    fn call<R>(&mut self, f: impl FnOnce(&mut World) -> R) -> Result<R, SimPinError> {
        let mut w = self.0 .0.borrow_mut();
        let overhead = w.pin_overhead_ns;
        w.advance(overhead);
        if w.pin_error {
            return Err(SimPinError);
        }
        Ok(f(&mut w))
    }
}

impl ErrorType for SimPin {
    type Error = SimPinError;
}

impl OutputPin for SimPin {
    fn set_low(&mut self) -> Result<(), SimPinError> {
        self.call(World::set_low)
    }

    fn set_high(&mut self) -> Result<(), SimPinError> {
        self.call(World::set_high)
    }
}

impl InputPin for SimPin {
    fn is_high(&mut self) -> Result<bool, SimPinError> {
        self.call(|w| !w.sample())
    }

    fn is_low(&mut self) -> Result<bool, SimPinError> {
        self.call(World::sample)
    }
}

/// Delay that advances the [`Sim`] clock.
#[derive(Debug)]
pub struct SimDelay(Sim);

impl DelayNs for SimDelay {
    fn delay_ns(&mut self, ns: u32) {
        self.0 .0.borrow_mut().advance(u64::from(ns));
    }
}

/// An async delay on the simulated clock (an executor's timer): it advances simulated
/// time and counts what was awaited, so a test can tell awaited time from blocking time.
#[derive(Debug)]
pub struct SimAsyncDelay {
    sim: Sim,
    /// Total ns awaited through this delay.
    pub awaited_ns: u64,
}

impl SimAsyncDelay {
    /// An async delay on `sim`'s clock.
    #[must_use]
    pub fn new(sim: &Sim) -> Self {
        Self { sim: sim.clone(), awaited_ns: 0 }
    }
}

impl embedded_hal_async::delay::DelayNs for SimAsyncDelay {
    async fn delay_ns(&mut self, ns: u32) {
        self.awaited_ns += u64::from(ns);
        self.sim.0.borrow_mut().now_ns += u64::from(ns);
    }
}

/// Run a future that never waits on anything external to completion (the simulated
/// delays complete at once), with a no-op waker: a minimal executor for tests.
///
/// # Panics
/// If the future returns `Pending` 1 000 times in a row.
pub fn block_on<F: core::future::Future>(f: F) -> F::Output {
    let mut f = std::pin::pin!(f);
    let mut cx = core::task::Context::from_waker(core::task::Waker::noop());
    for _ in 0..1000 {
        if let core::task::Poll::Ready(v) = f.as_mut().poll(&mut cx) {
            return v;
        }
    }
    panic!("future still pending after 1000 polls");
}
