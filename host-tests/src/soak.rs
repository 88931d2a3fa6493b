//! Soak: the simulated 1-Wire bus, the DS18B20 driver and the split compensator run
//! through hours to weeks of simulated time, across every clock wrap.
//!
//! The firmware recipe under test, exactly as the driver docs give it:
//! `t_ms = clock.ms(sample.completed_us)` with one [`MsClock`] for the system, then
//! `updater.on_scratchpad_from(sensor, t_ms, &sample.scratchpad)`; the IMU interrupt calls
//! `applier.cycle(pulses, dt_ticks)`. The µs clock the driver sees starts `us_before_wrap`
//! before its 2³² µs wrap (71.6 min) and the ms clock `ms_before_wrap` before its 2³² ms
//! wrap (49.7 days), so even a short run crosses both.
//!
//! Figures: `cargo run --release -p host-tests --bin soak -- --hours H` (README).

use std::time::Instant;

use qfa_thermal::compensator::{Compensator, Config, Status};
use qfa_thermal::ds18b20::Resolution;
use qfa_thermal::ds18b20_driver::Ds18b20;
use qfa_thermal::time::MsClock;

use crate::fuzzing::stream_table;
use crate::onewire_sim::{Device, Sim};

/// Soak settings.
#[derive(Clone, Copy, Debug)]
pub struct Settings {
    /// Simulated hours.
    pub hours: f64,
    /// IMU cycles per second (coarse: the fast path's cost is measured in bench-target).
    pub imu_hz: u32,
    /// The driver's µs clock starts this many µs before it wraps.
    pub us_before_wrap: u32,
    /// The ms time base starts this many ms before it wraps.
    pub ms_before_wrap: u32,
    /// Temperature sensors (one per accelerometer case: 3; or one for all axes: 1).
    pub sensors: usize,
}

impl Default for Settings {
    fn default() -> Self {
        Self { hours: 1.0, imu_hz: 10, us_before_wrap: 60_000_000, ms_before_wrap: 3_600_000, sensors: 3 }
    }
}

/// What a soak measured.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Figures {
    /// Simulated hours run.
    pub soak_hours: f64,
    /// Times the driver's µs clock wrapped.
    pub wraps_us: u32,
    /// Times the ms time base wrapped.
    pub wraps_ms: u32,
    /// Temperature readings the driver returned.
    pub readings: u64,
    /// IMU cycles run.
    pub cycles: u64,
    /// Fraction of IMU cycles flagged stale while every sensor was healthy.
    pub stale_fraction: f64,
    /// Good readings (driver OK, true value) the compensator refused.
    pub rejected_good_readings: u64,
    /// Worst |T̂ − truth| at a reading's completion time, °C.
    pub max_temp_error_c: f64,
    /// Driver errors (none expected: the bus is fault-free).
    pub driver_errors: u64,
    /// Wall-clock seconds.
    pub wall_s: f64,
}

impl Figures {
    /// `key=value` lines.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        vec![
            format!("soak_hours={}", self.soak_hours),
            format!("wraps_us={}", self.wraps_us),
            format!("wraps_ms={}", self.wraps_ms),
            format!("readings={}", self.readings),
            format!("imu_cycles={}", self.cycles),
            format!("stale_fraction={}", self.stale_fraction),
            format!("rejected_good_readings={}", self.rejected_good_readings),
            format!("max_temp_error_c={:.4}", self.max_temp_error_c),
            format!("driver_errors={}", self.driver_errors),
            format!("wall_s={:.1}", self.wall_s),
        ]
    }
}

/// The simulated case temperature of sensor `s`: 20 ± 25 °C over a 6-h cycle (at most
/// 0.44 °C/min), each case shifted by 1 °C.
#[must_use]
pub fn truth_c(s: usize, t_s: f64) -> f64 {
    20.0 + s as f64 + 25.0 * (2.0 * std::f64::consts::PI * t_s / 21_600.0).sin()
}

/// Run a soak. `progress` is called once per simulated hour with the hours done.
///
/// # Panics
/// On a driver or table setup failure (the bus is fault-free).
#[must_use]
pub fn run(set: Settings, mut progress: impl FnMut(f64)) -> Figures {
    let wall = Instant::now();
    let sensors = set.sensors.clamp(1, 3);
    let devices: Vec<Device> =
        (0..sensors).map(|s| Device::ds18b20(0x0042_1E50 + s as u64, (truth_c(s, 0.0) * 16.0) as i16)).collect();
    let sim = Sim::new(devices);
    let mut bus = sim.bus();
    let mut found = Ds18b20::search::<_, _, 4>(&mut bus).expect("search");
    assert_eq!(found.len(), sensors, "every simulated sensor answers the search");
    // The search order is by ROM; map each driver to the device with its serial.
    found.sort_by_key(|d| d.rom().map(|r| r.bytes()[1..7].iter().rev().fold(0u64, |a, &b| (a << 8) | u64::from(b))));
    for d in found.iter_mut() {
        d.set_resolution(&mut bus, Resolution::Bits12).expect("resolution");
    }

    let table = stream_table();
    let cfg = Config::default();
    let mut c3 = Compensator::<3, 32, 3>::new(cfg).expect("valid config");
    let mut c1 = Compensator::<3, 32, 1>::new(cfg).expect("valid config");
    let per_axis = sensors == 3;
    c3.load_table(&table).expect("table");
    c1.load_table(&table).expect("table");
    let (mut up3, mut ap3) = c3.split();
    let (mut up1, mut ap1) = c1.split();

    let us_origin = 0u32.wrapping_sub(set.us_before_wrap);
    let clock_us = |sim: &Sim| sim.now_us().wrapping_add(us_origin);
    let mut clock = MsClock::starting_at(0u32.wrapping_sub(set.ms_before_wrap));
    let dt_ticks = 1_000_000 / set.imu_hz.max(1);
    let pulses = [320_000 / set.imu_hz.max(1) as i32; 3];

    let total_s = (set.hours * 3600.0).round() as u64;
    let mut f = Figures::default();
    let (mut last_us, mut last_ms): (Option<u32>, Option<u32>) = (None, None);
    let mut stale_cycles = 0u64;
    for second in 0..total_s {
        let t0_ns = sim.now_ns();
        // Conversions on every sensor, then read each one.
        let t_s = t0_ns as f64 * 1e-9;
        sim.with(|w| {
            for (s, d) in w.devices.iter_mut().enumerate() {
                d.temp_raw = (truth_c(s, t_s + 0.75) * 16.0).round() as i16;
            }
        });
        for d in found.iter_mut() {
            if d.start(&mut bus, clock_us(&sim)).is_err() {
                f.driver_errors += 1;
            }
        }
        sim.idle_us(760_000);
        for (s, d) in found.iter_mut().enumerate() {
            match d.is_ready(&mut bus, clock_us(&sim)).and_then(|ready| {
                if ready {
                    d.read(&mut bus).map(Some)
                } else {
                    Ok(None)
                }
            }) {
                Ok(Some(sample)) => {
                    f.readings += 1;
                    if last_us.is_some_and(|l| sample.completed_us < l) {
                        f.wraps_us += 1;
                    }
                    last_us = Some(sample.completed_us);
                    let t_ms = clock.ms(sample.completed_us);
                    if last_ms.is_some_and(|l| t_ms < l) {
                        f.wraps_ms += 1;
                    }
                    last_ms = Some(t_ms);
                    let (res, est) = if per_axis {
                        (up3.on_scratchpad_from(s, t_ms, &sample.scratchpad), up3.estimate_of(s))
                    } else {
                        (up1.on_scratchpad_from(0, t_ms, &sample.scratchpad), up1.estimate_of(0))
                    };
                    if res.is_err() {
                        f.rejected_good_readings += 1;
                    } else if let Some(e) = est {
                        let err = (f64::from(e.temp_c) - truth_c(s, t_s + 0.75)).abs();
                        f.max_temp_error_c = f.max_temp_error_c.max(err);
                    }
                }
                Ok(None) => f.driver_errors += 1,
                Err(_) => f.driver_errors += 1,
            }
        }
        // The rest of the second: IMU cycles (virtual), then idle to the next second.
        for _ in 0..set.imu_hz {
            let out = if per_axis { ap3.cycle(pulses, dt_ticks) } else { ap1.cycle(pulses, dt_ticks) };
            f.cycles += 1;
            // The first readings have no rate yet; staleness is what is counted.
            if second > 0 && out.status.contains(Status::TEMP_STALE) {
                stale_cycles += 1;
            }
        }
        let spent_us = (sim.now_ns() - t0_ns) / 1000;
        sim.idle_us(1_000_000 - spent_us.min(1_000_000));
        if (second + 1) % 3600 == 0 {
            progress((second + 1) as f64 / 3600.0);
        }
    }
    f.soak_hours = total_s as f64 / 3600.0;
    f.stale_fraction = if f.cycles == 0 { 1.0 } else { stale_cycles as f64 / f.cycles as f64 };
    f.wall_s = wall.elapsed().as_secs_f64();
    f
}
