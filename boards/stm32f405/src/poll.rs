//! One DS18B20's slow path: its 1 s conversion period, generic over the bus like the
//! driver, so the host tests run it on the simulated 1-Wire bus. The board calls
//! [`Channel::step`] for each sensor in its thread-mode loop and logs the [`Event`].

use core::borrow::Borrow;

use embedded_hal::delay::DelayNs;
use embedded_hal::digital::{InputPin, OutputPin};
use qfa_thermal::ds18b20::Resolution;
use qfa_thermal::ds18b20_driver::{self as drv, Ds18b20};
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
    /// The driver failed.
    Driver(drv::Error),
    /// The conversion was not read within its period.
    NotReadInPeriod,
}

/// What one [`Channel::step`] did, for the log.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(target_os = "none", derive(defmt::Format))]
pub enum Event {
    /// Nothing: converting, or waiting for the next period.
    Idle,
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
    /// Nothing usable came, and the updater was not told.
    NotReported(Cause),
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Idle,
    Converting,
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
    /// The only sensor on `bus`; its first period starts at `first_us`.
    pub const fn new(bus: OneWire<P, D>, first_us: u32) -> Self {
        Self { bus, sensor: Ds18b20::single(), state: State::Idle, next_us: first_us }
    }

    /// Set the resolution.
    ///
    /// # Errors
    /// The driver's.
    pub fn setup(&mut self) -> Result<(), drv::Error> {
        self.sensor.set_resolution(&mut self.bus, RESOLUTION)
    }

    /// One step at `now_us` (µs, wrapping): at most one bus transaction and one updater
    /// call. `axis` is the updater's sensor index.
    pub fn step<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>>(
        &mut self,
        updater: &mut Updater<'_, AXES, N, SENSORS, T>,
        clock: &mut MsClock,
        axis: usize,
        now_us: u32,
    ) -> Event {
        let due = now_us.wrapping_sub(self.next_us) as i32 >= 0;
        match self.state {
            State::Converting if due => {
                self.state = State::Idle;
                Event::NotReported(Cause::NotReadInPeriod)
            }
            State::Converting => self.poll(updater, clock, axis, now_us),
            State::Idle if due => {
                self.next_us = self.next_us.wrapping_add(PERIOD_US);
                match self.sensor.start(&mut self.bus, now_us) {
                    Ok(()) => {
                        self.state = State::Converting;
                        Event::Started
                    }
                    Err(e) => Event::NotReported(Cause::Driver(e)),
                }
            }
            State::Idle => Event::Idle,
        }
    }

    fn poll<const AXES: usize, const N: usize, const SENSORS: usize, T: Borrow<Table>>(
        &mut self,
        updater: &mut Updater<'_, AXES, N, SENSORS, T>,
        clock: &mut MsClock,
        axis: usize,
        now_us: u32,
    ) -> Event {
        match self.sensor.is_ready(&mut self.bus, now_us) {
            Ok(false) => return Event::Idle,
            Ok(true) => self.state = State::Idle,
            Err(e) => {
                self.state = State::Idle;
                return Event::NotReported(Cause::Driver(e));
            }
        }
        match self.sensor.read(&mut self.bus) {
            Ok(s) => {
                // One time base for every sensor, wrap-safe (never completed_us / 1000).
                let t_ms = clock.ms(s.completed_us);
                match updater.on_scratchpad_from(axis, t_ms, &s.scratchpad) {
                    Ok(status) => Event::Accepted(status),
                    Err(error) => Event::Rejected { cause: None, error },
                }
            }
            Err(e) => Event::NotReported(Cause::Driver(e)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use host_tests::onewire_sim::{Device, Sim, SimDelay, SimPin};
    use qfa_thermal::{Compensator, Config};

    type Comp = Compensator<3, 32, 3, Table>;

    /// One sensor on the simulated bus as axis `AXIS` of the board's compensator type.
    const AXIS: usize = 1;

    fn channel(sim: &Sim) -> Channel<SimPin, SimDelay> {
        Channel::new(sim.bus(), sim.now_us())
    }

    /// Step every millisecond (the board's loop is much faster; 1 ms keeps the test short)
    /// for `ms`, collecting every event other than `Idle`.
    fn run(sim: &Sim, ch: &mut Channel<SimPin, SimDelay>, comp: &mut Comp, clock: &mut MsClock, ms: u32) -> Vec<Event> {
        let (mut updater, _) = comp.split();
        let mut events = Vec::new();
        for _ in 0..ms {
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
        ch.setup().unwrap();
        let mut comp = Comp::new(Config::default()).unwrap();
        let mut clock = MsClock::new();
        let events = run(&sim, &mut ch, &mut comp, &mut clock, 3_500);
        let accepted = events.iter().filter(|e| matches!(e, Event::Accepted(_))).count();
        let started = events.iter().filter(|e| **e == Event::Started).count();
        assert_eq!((started, accepted), (4, 3), "{events:?}");
        assert_eq!(comp.estimate_of(AXIS).map(|e| e.temp_c), Some(25.0625));
        assert!(!comp.status().contains(Status::TEMP_INVALID));
    }
}
