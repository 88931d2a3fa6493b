//! Temperature and thermal-hysteresis compensation for quartz-flexure (and MEMS)
//! accelerometers: `no_std`, no heap, no `unsafe`.
//!
//! The scale factor K1 of an accelerometer follows its temperature T and the rate Ṫ at
//! which it changes (Zhang et al., Sensors 2021, 21, 294, Eq. 11:
//! `K1 = α·Ṫ² + β·ΔT² + η·Ṫ·ΔT + ε·Ṫ + μ·ΔT + γ`); the bias K0 follows a temperature grid
//! with heating and cooling branches. A [`Compensator`] takes temperature readings (about
//! 1 Hz, from DS18B20s: [`ds18b20_driver`]), estimates Ṫ ([`rate`]), evaluates the model of
//! each axis ([`model`]) from a validated coefficient [`Table`], and corrects every IMU cycle
//! with two multiplies and a subtraction per axis.
//!
//! # Quick start
//!
//! ```
//! use qfa_thermal::{AxisModel, BiasGrid, Compensator, Config, Extensions, Input, ScaleFactor, Table};
//!
//! // One axis: the paper's unit #1, a flat 50 µg bias from −40 to 80 °C.
//! let bias = BiasGrid::single_valued(-40.0, 10.0, &[5e-5; 13]).expect("2 to 16 grid values");
//! let scale = ScaleFactor { t0_c: 22.0, gamma: 320_320.0, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 }; // JB-KT8 #1, Eq. 15
//! let axis = AxisModel { scale, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
//! let table = Table { input: Input::PulseCounts, rate_window: 32, axes: [axis].into_iter().collect(), misalignment: None, part_lsb_per_g: None };
//!
//! let mut comp = Compensator::<1, 32>::new(Config::default()).unwrap();
//! comp.set_table(table).unwrap();
//! for s in 0..8 {
//!     comp.on_raw(0, s * 1_000, 352).unwrap(); // 352/16 = 22.0 °C, one reading a second
//! }
//! let out = comp.cycle([1_601], 5_000); // 1 601 pulses in 5 ms (5 000 ticks of 1 µs)
//! assert!(out.status.is_ok());
//! let g = out.dv_mps[0] / 0.005 / qfa_thermal::G0;
//! assert!((g - 0.99948).abs() < 1e-4, "{g}"); // 1 601 / (γ·5 ms) − K0, in g
//! ```
//!
//! # MEMS samples
//!
//! `qfa-lab calibrate` on a static (MEMS) log writes a table for [`Input::Samples`] in the
//! lab's own scale, [`table::SAMPLE_UNITS_PER_G`] (2²⁰ units per g, K1 ≈ 1 048 576). The
//! compensator is told the part's own sensitivity at the range it is set to
//! ([`Config::sample_lsb_per_g`]: 4 096 LSB/g for a ±8 g 16-bit part) and takes the part's
//! raw LSB as they come; it brings them to the table's scale once per reading, at no cost
//! per cycle. A samples configuration that does not state the sensitivity is refused, and a
//! table that records the range it was calibrated at (`qfa-lab calibrate --lsb-per-g`)
//! refuses a compensator that states another ([`table::Error::PartScale`]).
//!
//! ```
//! use qfa_thermal::{AxisModel, BiasGrid, Compensator, Config, ConfigError, Extensions, Input, ScaleFactor, Table};
//!
//! // What `calibrate --lsb-per-g 4096` writes for one MEMS axis (`table.bin` →
//! // `Table::decode`), here by hand: K1 at the lab's 2²⁰ per g, a 2 mg bias.
//! let bias = BiasGrid::single_valued(-20.0, 10.0, &[2e-3; 10]).expect("10 values fit a branch");
//! let axis = AxisModel { scale: ScaleFactor::simple(25.0, 1_048_576.0, 0.0), bias, rate_limit_c_per_min: 5.0, ext: Extensions::default() };
//! let table = Table::samples_of_part(32, [axis], None, 4_096.0);
//!
//! // The part's sensitivity is part of the configuration, not a multiplier in your code.
//! let unstated = Config { input: Input::Samples, ..Config::default() };
//! assert_eq!(unstated.validate(), Err(ConfigError::SampleScaleNotStated));
//! // The part set to ±16 g (2 048 LSB/g) against a table calibrated at ±8 g: refused.
//! let sixteen = Config { input: Input::Samples, sample_lsb_per_g: 2_048.0, ..Config::default() };
//! let mut wrong = Compensator::<1, 32>::new(sixteen).unwrap();
//! assert!(matches!(wrong.set_table(table.clone()), Err(qfa_thermal::table::Error::PartScale { .. })));
//!
//! let part = Config { input: Input::Samples, sample_lsb_per_g: 4_096.0, ..Config::default() };
//! let mut comp = Compensator::<1, 32>::new(part).unwrap();
//! comp.set_table(table).unwrap();
//! for s in 0..8 {
//!     comp.on_raw(0, s * 1_000, 400).unwrap(); // 25.0 °C
//! }
//! let raw_lsb = 4_096 + 8; // the part's reading: 1 g plus its 2 mg bias, at 4 096 LSB/g
//! let out = comp.cycle_samples([raw_lsb], 5_000); // raw, as the part gives it
//! let g = out.accel_mps2[0] / qfa_thermal::G0;
//! assert!((g - 1.0).abs() < 1e-4, "{g}");
//! ```
//!
//! # Wiring
//!
//! In firmware the two paths run in two contexts: [`Compensator::split`] gives an
//! [`Updater`] for the temperature loop (thread mode or a low-priority task) and an
//! [`Applier`] for the IMU interrupt. Keep the compensator in a `static` (a
//! `static_cell::StaticCell`) so that both halves are `'static`, hand the applier to the
//! interrupt once, and hold the table as `&'static Table` in flash. Time stamps go through
//! one [`time::MsClock`] (never `now_us / 1000`, which wraps every 71.6 min); every failed
//! sensor read is reported with [`Updater::on_missed_reading`]. The repository's
//! `docs/firmware.md` is the full wiring guide, with what an INS does with each [`Status`]
//! flag and an STM32F405 board example.
//!
//! # Concurrency contract
//!
//! * One [`Updater`], one [`Applier`]; the slow path is `&mut`, so two publications never
//!   overlap.
//! * The applier never blocks and never waits: the halves share one coefficient set
//!   behind a sequence number (a seqlock of 32-bit atomics, so any Cortex-M works). A set
//!   being written, or written during the applier's copy, is dropped and the previous
//!   whole set is used for that cycle, whichever context preempts which, on one core or
//!   several. The orderings are model-checked with loom (see [`compensator`]).
//! * Faults never give a silent wrong answer: a refused or missed reading keeps the last
//!   good compensation and raises a [`Status`] flag; outputs are always finite.
//!
//! # Modules
//!
//! * [`compensator`]: [`Compensator`] and its recommended configurations
//!   [`ThreeAxisSensorPerAxis`] and [`ThreeAxisSharedSensor`], [`Updater`], [`Applier`]
//!   with its [`PulseOutput`] (Δv, m/s) and [`SampleOutput`] (m/s²), [`Config`], [`Status`];
//! * [`table`]: the coefficient [`Table`], its wire format (version 2) and validation;
//! * [`model`]: Eq. 11, the bias grid, the extension slots;
//! * [`rate`]: the Ṫ estimator; [`time`]: the slow path's time base and [`time::MsClock`];
//! * [`ds18b20`]: scratchpad decoding; [`onewire`] and [`ds18b20_driver`]: the 1-Wire bus
//!   and a non-blocking DS18B20 driver on embedded-hal 1.0.
//!
//! # Features
//!
//! `defmt`: `defmt::Format` for the public types. `fixtures`: the `fixtures` module, published
//! coefficients for tests and placeholder tables (the paper's JB-KT8 #1), not a calibration.
//! Measured figures (instruction counts, RAM, flash) are in the repository's
//! `docs/measurements.md`.
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod compensator;
pub mod ds18b20;
pub mod ds18b20_driver;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
pub mod model;
pub mod onewire;
pub mod rate;
pub mod table;
pub mod time;

#[cfg(feature = "bench-internals")]
#[doc(hidden)]
pub use compensator::Published;
pub use compensator::{
    Applier, Compensator, Config, ConfigError, CountingApplier, PulseOutput, SampleError, SampleOutput,
    SensorPerAxisUpdater, SensorPerAxisUpdaterWithMatrix, SharedSensorUpdater, SharedSensorUpdaterWithMatrix, Status,
    ThreeAxisApplier, ThreeAxisApplierWithMatrix, ThreeAxisCountingApplier, ThreeAxisCountingApplierWithMatrix,
    ThreeAxisSensorPerAxis, ThreeAxisSensorPerAxisWithMatrix, ThreeAxisSharedSensor, ThreeAxisSharedSensorWithMatrix,
    Updater, DEFAULT_RATE_WINDOW, G0, IMU_PERIOD_TOLERANCE,
};
/// The `heapless` this crate's types are built on ([`Table::axes`], [`BiasGrid`]'s
/// branches), so a table can be built at run time without a dependency of your own.
pub use heapless;
pub use model::{AxisModel, BiasGrid, Extensions, ScaleFactor};
pub use table::{Input, Table};

/// The README's example, compiled and run as a doctest, so the code a user copies with the
/// README's dependency line is known to build.
#[cfg(doctest)]
#[doc = include_str!("../README.md")]
pub struct ReadmeExample;
