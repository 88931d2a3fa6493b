//! The firmware's time base in flight: DS18B20 timestamps from a wrapping µs timer.
//!
//! [`super::run::fly`] hands every compensation the ideal time of each DS18B20 reading in
//! ms since power-on. A navigation computer has a wrapping `u32` µs timer instead (it
//! wraps every 2³² µs = 71.6 min) and must turn it into the slow path's wrapping ms
//! ([`qfa_thermal::time`]). [`Clocked`] puts that step between the flight and a
//! [`TableCompensation`]: the reading's completion time on a µs timer started at
//! `start_us`, then either the firmware's recipe, [`MsClock`] (started at `start_ms`, so
//! a test can put the ms wrap inside the flight too), or the broken one,
//! `completed_us / 1000`, which jumps back at every µs wrap.
//!
//! [`ten_hour_flight`] is the built-in flight stretched to 10 h of cruise legs and
//! temperature cycles, so it crosses eight µs wraps; [`check`] is what "stays right"
//! means for a clocked compensation beside the ideal one.

use std::cell::Cell;
use std::rc::Rc;

use qfa_thermal::time::MsClock;
use qfa_thermal::Status;

use super::accel::{AccelCompensation, TableCompensation};
use super::scenario::{Scenario, Segment};
use super::thermal::TempPoint;

/// How the slow path's ms timestamps are made from the µs timer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TimeBase {
    /// The flight's own ms since power-on (what [`super::run::fly`] hands out).
    Ideal,
    /// [`MsClock`] on the µs timer: the firmware's recipe.
    MsClock {
        /// The µs timer's value at power-on.
        start_us: u32,
        /// The ms value the clock maps power-on to.
        start_ms: u32,
    },
    /// `completed_us / 1000`: the broken recipe.
    DividedUs {
        /// The µs timer's value at power-on.
        start_us: u32,
    },
}

/// What a [`Clocked`] compensation saw, shared with the caller while it flies.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ClockLog {
    /// Readings the compensator refused.
    pub rejected: u32,
    /// IMU cycles flagged `TEMP_STALE` or `TEMP_INVALID` after the first unflagged one.
    pub flagged_cycles: u64,
    /// An unflagged cycle has been seen.
    pub settled: bool,
}

/// A [`TableCompensation`] whose DS18B20 timestamps go through a [`TimeBase`].
#[derive(Clone, Debug)]
pub struct Clocked {
    /// The compensation.
    pub inner: TableCompensation,
    base: TimeBase,
    clock: MsClock,
    log: Rc<Cell<ClockLog>>,
}

impl Clocked {
    /// `inner` behind `base`, and the log it keeps.
    #[must_use]
    pub fn new(inner: TableCompensation, base: TimeBase) -> (Self, Rc<Cell<ClockLog>>) {
        let clock = match base {
            TimeBase::MsClock { start_ms, .. } => MsClock::starting_at(start_ms),
            TimeBase::Ideal | TimeBase::DividedUs { .. } => MsClock::new(),
        };
        let log = Rc::new(Cell::new(ClockLog::default()));
        (Self { inner, base, clock, log: Rc::clone(&log) }, log)
    }

    /// The slow path's ms timestamp of a reading completed `t_ms` after power-on.
    fn stamp(&mut self, t_ms: u32) -> u32 {
        let elapsed_us = u64::from(t_ms) * 1000;
        match self.base {
            TimeBase::Ideal => t_ms,
            TimeBase::MsClock { start_us, .. } => self.clock.ms(start_us.wrapping_add(elapsed_us as u32)),
            TimeBase::DividedUs { start_us } => start_us.wrapping_add(elapsed_us as u32) / 1000,
        }
    }
}

impl AccelCompensation for Clocked {
    fn on_temperature(&mut self, t_ms: u32, raw: i16) {
        self.on_temperatures(t_ms, [raw; 3]);
    }

    fn on_temperatures(&mut self, t_ms: u32, raw: [i16; 3]) {
        let t = self.stamp(t_ms);
        self.inner.on_temperatures(t, raw);
        let mut l = self.log.get();
        l.rejected = self.inner.rejected;
        self.log.set(l);
    }

    fn compensate(&mut self, pulses: [i32; 3], dt_ticks: u32, truth: &[(f64, f64); 3]) -> nalgebra::Vector3<f64> {
        let dv = self.inner.compensate(pulses, dt_ticks, truth);
        let flagged = is_time_flag(self.inner.last_status);
        let mut l = self.log.get();
        if l.settled && flagged {
            l.flagged_cycles += 1;
        }
        l.settled |= !flagged;
        self.log.set(l);
        dv
    }
}

/// The built-in flight with its four cruise legs repeated until the flight lasts `hours`
/// (start-up, climb, descent and landing unchanged), and a drive temperature that, after
/// the built-in profile, cycles between −16 and +30 °C with a 2-h period (ramps of
/// 0.4 °C/min), so the thermal model works the whole way.
#[must_use]
pub fn ten_hour_flight(hours: f64) -> Scenario {
    let mut sc = Scenario::builtin();
    let n = sc.segments.len();
    let (head, tail) = (sc.segments[..2].to_vec(), sc.segments[n - 2..].to_vec());
    let cruise: Vec<Segment> = sc.segments[2..n - 2].to_vec();
    let fixed: f64 = head.iter().chain(&tail).map(|s| s.duration_s).sum();
    let mut segs = head;
    let mut left = hours * 3600.0 - fixed;
    'legs: loop {
        for c in &cruise {
            if left <= 0.0 {
                break 'legs;
            }
            let mut c = c.clone();
            c.duration_s = c.duration_s.min(left);
            left -= c.duration_s;
            segs.push(c);
        }
    }
    segs.extend(tail);
    sc.segments = segs;
    let last = sc.temperature.last().map_or(0.0, |p| p.t_s);
    let end = sc.duration_s();
    let mut t = last;
    let mut hot = true;
    while t < end {
        t += 3600.0;
        sc.temperature.push(TempPoint { t_s: t, temp_c: if hot { 30.0 } else { -16.0 } });
        hot = !hot;
    }
    sc.name = format!("{}, {hours} h", sc.name);
    sc
}

/// What a clocked compensation did in a flight, beside the ideal one.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ClockFigures {
    /// Readings the compensator refused.
    pub rejected: u32,
    /// IMU cycles flagged `TEMP_STALE` or `TEMP_INVALID` after the first unflagged one.
    pub flagged_cycles: u64,
    /// Thermal-only CEP rate (variant − oracle), nmile/h.
    pub thermal_nmi_per_h: f64,
    /// Largest horizontal distance from the ideal-time-base variant's track, m.
    pub max_from_ideal_m: f64,
}

/// The expectations for a clocked compensation (`got`) flown beside the same tables on
/// the ideal time base (`ideal`): no refused reading, no flagged cycle, a thermal-only
/// error within 1 % (+1e-4 nmile/h) of the ideal one and below `limit_nmi_per_h`, and a
/// track within 1 m of the ideal one. Returns every violated expectation.
#[must_use]
pub fn check(got: &ClockFigures, ideal: &ClockFigures, limit_nmi_per_h: f64) -> Vec<String> {
    let mut v = Vec::new();
    if got.rejected > 0 {
        v.push(format!("{} readings refused", got.rejected));
    }
    if got.flagged_cycles > 0 {
        v.push(format!("{} cycles flagged stale or invalid", got.flagged_cycles));
    }
    if (got.thermal_nmi_per_h - ideal.thermal_nmi_per_h).abs() > 0.01 * ideal.thermal_nmi_per_h + 1e-4 {
        v.push(format!(
            "thermal-only {:.5} nmile/h against {:.5} on the ideal time base",
            got.thermal_nmi_per_h, ideal.thermal_nmi_per_h
        ));
    }
    if got.thermal_nmi_per_h >= limit_nmi_per_h {
        v.push(format!("thermal-only {:.5} nmile/h ≥ limit {limit_nmi_per_h:.5}", got.thermal_nmi_per_h));
    }
    if got.max_from_ideal_m > 1.0 {
        v.push(format!("track {:.1} m from the ideal time base's", got.max_from_ideal_m));
    }
    v
}

/// Whether `status` is one of the flags a time-base fault raises.
#[must_use]
pub fn is_time_flag(status: Status) -> bool {
    status.intersects(Status::TEMP_STALE | Status::TEMP_INVALID)
}
