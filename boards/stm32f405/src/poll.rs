//! One DS18B20's slow path: its 1 s conversion period, generic over the bus like the
//! driver, so the host tests run it on the simulated 1-Wire bus. The board calls
//! [`Channel::step`] for each sensor in its thread-mode loop and logs the [`Event`].
//!
//! # Every reading reaches the updater
//! Each period owes the updater one reading, and it hears of each one, good or bad, so a
//! failure raises `TEMP_INVALID` instead of only a log line:
//!
//! | what happened | updater call | event |
//! |---|---|---|
//! | a good reading | `on_scratchpad(completed)` | [`Event::Accepted`] (or [`Event::Rejected`]: a jump, a time error) |
//! | bytes that failed decoding (CRC after the retry, power-on value, reserved bytes) | `on_scratchpad(due, bytes)`: a typed `Decode` error | [`Event::Rejected`] |
//! | nothing usable: bus error, lost or overdue conversion, changed resolution, setup failed, parasite-powered sensor, conversion not read within its period | `on_missed_reading(due)` | [`Event::Missed`] |
//!
//! `due` is when the period's reading was due: its start plus the 12-bit conversion time.
//!
//! # Conversions are checked on the bus
//! At setup (and again after a changed resolution, which means a brown-out) the channel
//! sets 12 bits and calls `use_read_slots`: an externally powered sensor then shows on the
//! bus that each Convert T started and when it ended (see the driver's "Lost conversions"),
//! so a lost command is a missed reading, not the previous value again. A parasite-powered
//! sensor cannot show that, so it is refused: never started or read, its axis missed and
//! flagged every period. A setup that fails (no sensor yet) is retried every period.

use core::borrow::Borrow;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use qfa_thermal::ds18b20::Resolution;
use qfa_thermal::ds18b20_driver::{self as drv, Ds18b20, PowerSupply, ReadFailure};
use qfa_thermal::onewire::OneWire;
use qfa_thermal::time::MsClock;
use qfa_thermal::{SampleError, Status, Table, Updater};

/// Temperature cycle: a conversion on every sensor once a second.
pub const PERIOD_US: u32 = 1_000_000;
/// 12 bits (0.0625 °C, 750 ms); the driver re-checks it in every scratchpad.
pub const RESOLUTION: Resolution = Resolution::Bits12;

/// Why a reading did not come.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Cause {
    /// The driver failed: bus, lost or overdue conversion, changed resolution, setup.
    Driver(drv::Error),
    /// The conversion was not read within its period (the loop was held up).
    NotReadInPeriod,
    /// The sensor is parasite-powered: refused at setup.
    Parasite,
}

/// What one [`Channel::step`] did, for the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Event {
    /// Nothing: converting, or waiting for the next period.
    Idle,
    /// Set up: 12 bits, externally powered, conversions checked by read slot.
    Configured,
    /// A conversion started.
    Started,
    /// A reading the updater took.
    Accepted(Status),
    /// A scratchpad the updater refused; `cause` is the driver's error when the driver had
    /// already refused it.
    Rejected {
        /// The driver's error, if any.
        cause: Option<drv::Error>,
        /// The updater's.
        error: SampleError,
    },
    /// Nothing usable came; the updater was told (`on_missed_reading`).
    Missed {
        /// Why.
        cause: Cause,
        /// The updater's answer (`Err(SampleError::Missed)`).
        result: Result<Status, SampleError>,
    },
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    /// Resolution and power supply not (or no longer) known: set up at the next period.
    Setup,
    /// Parasite-powered: never converted or read.
    Refused,
    /// Waiting for the next period.
    Idle,
    /// Converting since `started_us`.
    Converting { started_us: u32 },
}

/// One DS18B20 alone on its bus (SKIP ROM), and its period.
#[derive(Debug)]
pub struct Channel<P, D> {
    /// The sensor's bus.
    pub bus: OneWire<P, D>,
    sensor: Ds18b20,
    state: State,
    /// Start of the next period, on the caller's µs clock.
    next_us: u32,
}

impl<P, D> Channel<P, D>
where
    P: InputPin + OutputPin,
    D: DelayNs,
{
    /// The only sensor on `bus`; its first period (set up, then the first conversion)
    /// starts at `first_us`.
    pub const fn new(bus: OneWire<P, D>, first_us: u32) -> Self {
        Self { bus, sensor: Ds18b20::single(), state: State::Setup, next_us: first_us }
    }

    /// One step at `now_us` (µs, wrapping): at most one bus operation (setup, start, a
    /// poll and its read) and one updater call. `axis` is the updater's sensor index.
    pub fn step<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>, const M: usize>(
        &mut self,
        updater: &mut Updater<'_, AXES, N, SENSORS, T, M>,
        clock: &mut MsClock,
        axis: usize,
        now_us: u32,
    ) -> Event {
        let due = now_us.wrapping_sub(self.next_us) as i32 >= 0;
        let conversion_us = RESOLUTION.max_conversion_us();
        match self.state {
            // With read slots the driver gives up at 825 ms; this is the loop held up.
            State::Converting { started_us } if due => {
                self.state = State::Idle;
                Self::missed(updater, clock, axis, started_us.wrapping_add(conversion_us), Cause::NotReadInPeriod)
            }
            State::Converting { started_us } => self.poll(updater, clock, axis, now_us, started_us),
            _ if !due => Event::Idle,
            State::Setup => match self.setup() {
                // The period is not used up: the next step starts its conversion.
                Ok(PowerSupply::External) => {
                    self.state = State::Idle;
                    Event::Configured
                }
                Ok(PowerSupply::Parasite) => {
                    self.state = State::Refused;
                    self.next_period(now_us);
                    Self::missed(updater, clock, axis, now_us.wrapping_add(conversion_us), Cause::Parasite)
                }
                Err(e) => {
                    self.next_period(now_us);
                    Self::missed(updater, clock, axis, now_us.wrapping_add(conversion_us), Cause::Driver(e))
                }
            },
            State::Refused => {
                self.next_period(now_us);
                Self::missed(updater, clock, axis, now_us.wrapping_add(conversion_us), Cause::Parasite)
            }
            State::Idle => {
                self.next_period(now_us);
                match self.sensor.start(&mut self.bus, now_us) {
                    Ok(()) => {
                        self.state = State::Converting { started_us: now_us };
                        Event::Started
                    }
                    // ConversionNotStarted among them: the previous conversion is not read.
                    Err(e) => Self::missed(updater, clock, axis, now_us.wrapping_add(conversion_us), Cause::Driver(e)),
                }
            }
        }
    }

    /// Set 12 bits and learn the power supply (read slots if external).
    fn setup(&mut self) -> Result<PowerSupply, drv::Error> {
        self.sensor.set_resolution(&mut self.bus, RESOLUTION)?;
        self.sensor.use_read_slots(&mut self.bus)
    }

    /// The next period starts one period after this one; after a loop held up for longer,
    /// one period from now (no burst of conversions to catch up).
    fn next_period(&mut self, now_us: u32) {
        self.next_us = self.next_us.wrapping_add(PERIOD_US);
        if now_us.wrapping_sub(self.next_us) as i32 >= 0 {
            self.next_us = now_us.wrapping_add(PERIOD_US);
        }
    }

    fn missed<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>, const M: usize>(
        updater: &mut Updater<'_, AXES, N, SENSORS, T, M>,
        clock: &mut MsClock,
        axis: usize,
        due_us: u32,
        cause: Cause,
    ) -> Event {
        Event::Missed { cause, result: updater.on_missed_reading(axis, clock.ms(due_us)) }
    }

    fn poll<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>, const M: usize>(
        &mut self,
        updater: &mut Updater<'_, AXES, N, SENSORS, T, M>,
        clock: &mut MsClock,
        axis: usize,
        now_us: u32,
        started_us: u32,
    ) -> Event {
        let due_us = started_us.wrapping_add(RESOLUTION.max_conversion_us());
        match self.sensor.is_ready(&mut self.bus, now_us) {
            Ok(false) => return Event::Idle,
            Ok(true) => self.state = State::Idle,
            // A bus error, or ConversionOverdue.
            Err(e) => {
                self.state = State::Idle;
                return Self::missed(updater, clock, axis, due_us, Cause::Driver(e));
            }
        }
        match self.sensor.read_keeping_bytes(&mut self.bus) {
            Ok(s) => {
                // One time base for every sensor, wrap-safe (never completed_us / 1000).
                let t_ms = clock.ms(s.completed_us);
                match updater.on_scratchpad(axis, t_ms, &s.scratchpad) {
                    Ok(status) => Event::Accepted(status),
                    Err(error) => Event::Rejected { cause: None, error },
                }
            }
            // The bytes that failed the driver's decoding fail the updater's the same way:
            // a typed decode error there, and TEMP_INVALID.
            Err(ReadFailure { error, scratchpad: Some(sp) }) => {
                match updater.on_scratchpad(axis, clock.ms(due_us), &sp) {
                    Ok(status) => Event::Accepted(status),
                    Err(e) => Event::Rejected { cause: Some(error), error: e },
                }
            }
            Err(ReadFailure { error, scratchpad: None }) => {
                // A brown-out reloaded the EEPROM's resolution (and the sensor may have
                // changed): set up again at the next period.
                if let drv::Error::ResolutionChanged(_) = error {
                    self.state = State::Setup;
                }
                Self::missed(updater, clock, axis, due_us, Cause::Driver(error))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use host_tests::onewire_sim::{sim_slot_lock, Device, Sim, SimDelay, SimPin};
    use qfa_thermal::onewire as ow;
    use qfa_thermal::{ds18b20, Config, ThreeAxisSensorPerAxis};

    type Comp = ThreeAxisSensorPerAxis<Table>;

    /// One sensor on the simulated bus as axis `AXIS` of the board's compensator type.
    const AXIS: usize = 1;

    /// The bus as the board builds it, with the slot lock.
    fn channel(sim: &Sim) -> Channel<SimPin, SimDelay> {
        Channel::new(sim.bus().with_slot_lock(sim_slot_lock), sim.now_us())
    }

    /// Step every millisecond (the board's loop is much faster; 1 ms keeps the test short)
    /// for `ms` of simulated time (bus time included), collecting every event but `Idle`.
    fn run(sim: &Sim, ch: &mut Channel<SimPin, SimDelay>, comp: &mut Comp, clock: &mut MsClock, ms: u64) -> Vec<Event> {
        let (mut updater, _) = comp.split();
        let end_ns = sim.now_ns() + ms * 1_000_000;
        let mut events = Vec::new();
        while sim.now_ns() < end_ns {
            let e = ch.step(&mut updater, clock, AXIS, sim.now_us());
            if e != Event::Idle {
                events.push(e);
            }
            sim.idle_us(1_000);
        }
        events
    }

    #[test]
    fn good_readings_reach_the_updater_once_a_period() {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let mut ch = channel(&sim);
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        // Periods start at 0, 1, 2 and 3 s; the simulated sensor converts in 600 ms.
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 3_300);
        let accepted = events.iter().filter(|e| matches!(e, Event::Accepted(_))).count();
        let started = events.iter().filter(|e| **e == Event::Started).count();
        assert_eq!((started, accepted), (4, 3), "{events:?}");
        assert_eq!(comp.estimate_of(AXIS).map(|e| e.temp_c), Some(25.0625));
        assert!(!comp.status().contains(Status::TEMP_INVALID));
    }

    fn accepted(events: &[Event]) -> usize {
        events.iter().filter(|e| matches!(e, Event::Accepted(_))).count()
    }

    fn missed(events: &[Event], cause: Cause) -> usize {
        events
            .iter()
            .filter(|e| matches!(e, Event::Missed { cause: c, result: Err(SampleError::Missed) } if *c == cause))
            .count()
    }

    /// Scenario 7: a scratchpad whose CRC fails on the read and on its retry. The board
    /// logged the driver's error and never told the updater, so TEMP_INVALID never rose.
    /// Now the bytes read go to `on_scratchpad`, which rejects them with the typed
    /// decode error and raises the flag.
    #[test]
    fn crc_failure_reaches_the_updater_as_a_typed_decode_error() {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let mut ch = channel(&sim);
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        // One good reading; the next conversion started at 1 000 ms.
        assert_eq!(accepted(&run(&sim, &mut ch, &mut comp, &mut clock, 1_200)), 1);
        assert!(!comp.status().contains(Status::TEMP_INVALID));
        // The CRC byte's lowest bit flipped on the read and on its one retry.
        sim.with(|w| {
            w.devices[0].flip_bit = 64;
            w.devices[0].flip_times = 2;
        });
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 700);
        assert!(comp.status().contains(Status::TEMP_INVALID), "the updater never heard of it: {events:?}");
        let crc = |e: &Event| {
            matches!(
                e,
                Event::Rejected {
                    cause: Some(drv::Error::Scratchpad(ds18b20::Error::Crc { .. })),
                    error: SampleError::Decode(ds18b20::Error::Crc { .. })
                }
            )
        };
        assert_eq!(events.iter().filter(|e| crc(e)).count(), 1, "{events:?}");
        // The next good reading clears the flag.
        assert_eq!(accepted(&run(&sim, &mut ch, &mut comp, &mut clock, 1_000)), 1);
        assert!(!comp.status().contains(Status::TEMP_INVALID));
    }

    /// Scenario 7: the sensor stops answering (no presence pulse). Each reading it owes is
    /// a missed reading for the updater: the read that failed, and each start after it.
    #[test]
    fn bus_failure_reaches_the_updater_as_a_missed_reading() {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let mut ch = channel(&sim);
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        assert_eq!(accepted(&run(&sim, &mut ch, &mut comp, &mut clock, 1_200)), 1);
        sim.with(|w| w.devices[0].present = false);
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 2_000);
        assert!(comp.status().contains(Status::TEMP_INVALID), "the updater never heard of it: {events:?}");
        let no_presence = Cause::Driver(drv::Error::Bus(ow::Error::NoPresence));
        // The read of the conversion started at 1 s, the starts at 2 s and 3 s.
        assert_eq!(missed(&events, no_presence), 3, "{events:?}");
        assert_eq!(accepted(&events), 0);
    }

    /// Scenario 5 on the board: a lost Convert T. Judged by the timer, the read after it
    /// gave the previous conversion, accepted with a fresh timestamp (the sensor froze with
    /// a good status). The board now checks conversions by read slot: the lost command is
    /// a missed reading, and the next conversion gives the new temperature.
    #[test]
    fn frozen_sensor_lost_convert_t_reaches_the_updater_as_missed_not_as_the_previous_sample() {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        let mut ch = channel(&sim);
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        assert_eq!(accepted(&run(&sim, &mut ch, &mut comp, &mut clock, 1_900)), 2);
        // Between the read at ~1.6 s and the start at 2 s: 0.25 °C warmer, and the next
        // Convert T is lost.
        sim.with(|w| {
            w.devices[0].temp_raw = 0x0195;
            w.devices[0].drop_convert_t = 1;
        });
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 1_000);
        assert_eq!(accepted(&events), 0, "the previous conversion was delivered again: {events:?}");
        assert!(comp.status().contains(Status::TEMP_INVALID));
        assert_eq!(missed(&events, Cause::Driver(drv::Error::ConversionNotStarted)), 1, "{events:?}");
        assert_eq!(comp.estimate_of(AXIS).map(|e| e.temp_c), Some(25.0625));
        // The next period's conversion is taken.
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 1_000);
        assert_eq!(accepted(&events), 1, "{events:?}");
        assert!(!comp.status().contains(Status::TEMP_INVALID));
        assert!(comp.estimate_of(AXIS).unwrap().temp_c > 25.0625);
    }

    /// Scenario 5 on the board: a parasite-powered sensor cannot show a lost conversion on
    /// the bus, so it is refused at setup and its axis is flagged every period; none of
    /// its readings is used.
    #[test]
    fn parasite_sensor_is_refused_and_its_axis_flagged() {
        let sim = Sim::new(vec![Device::ds18b20(1, 0x0191)]);
        sim.with(|w| w.devices[0].parasite = true);
        let mut ch = channel(&sim);
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 3_500);
        assert_eq!(accepted(&events), 0, "{events:?}");
        assert_eq!(missed(&events, Cause::Parasite), 4, "{events:?}");
        assert!(comp.status().contains(Status::TEMP_INVALID));
        assert_eq!(comp.estimate_of(AXIS), None);
    }

    /// Scenario 7: a brown-out during a conversion. The power-on scratchpad goes to the
    /// updater (a typed `PowerOn` decode error); the next one, converted at the EEPROM's
    /// 11 bits, is a missed reading (`ResolutionChanged`), and the board sets 12 bits again.
    #[test]
    fn brown_out_reaches_the_updater_and_the_resolution_is_set_again() {
        let mut dev = Device::ds18b20(1, 0x0191);
        dev.eeprom[2] = Resolution::Bits11.config_byte();
        let sim = Sim::new(vec![dev]);
        let mut ch = channel(&sim);
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        assert_eq!(accepted(&run(&sim, &mut ch, &mut comp, &mut clock, 1_050)), 1);
        // 100 ms into the conversion started at 1 s.
        sim.with(|w| w.devices[0].brown_out_at_ns = Some(w.now_ns + 50_000_000));
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 1_000);
        assert!(comp.status().contains(Status::TEMP_INVALID), "{events:?}");
        let power_on = |e: &Event| {
            matches!(e, Event::Rejected { cause: Some(_), error: SampleError::Decode(ds18b20::Error::PowerOn) })
        };
        assert_eq!(events.iter().filter(|e| power_on(e)).count(), 1, "{events:?}");
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 1_000);
        assert!(comp.status().contains(Status::TEMP_INVALID), "{events:?}");
        let changed = Cause::Driver(drv::Error::ResolutionChanged(Resolution::Bits11));
        assert_eq!(missed(&events, changed), 1, "{events:?}");
        // Set up again at the next period, then read at 12 bits.
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 1_000);
        assert_eq!(accepted(&events), 1, "{events:?}");
        assert!(!comp.status().contains(Status::TEMP_INVALID));
        assert_eq!(sim.with(|w| w.devices[0].scratchpad()[4]), Resolution::Bits12.config_byte());
    }
}
