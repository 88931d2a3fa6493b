//! The compensator: a per-temperature-sample path and a per-IMU-cycle path.
//!
//! * **Slow path** ([`Compensator::on_scratchpad`], [`Compensator::on_raw`], about 1 Hz per
//!   sensor): validate the reading, update that sensor's rate estimator, evaluate the
//!   models of the axes it serves and publish `g0/K1` (m/s per pulse), `K0·g0·tick` (m/s
//!   per tick) and `K0·g0` (m/s²) for the fast path.
//! * **Fast path** ([`Compensator::cycle`], 200 Hz–2 kHz): per axis
//!   `Δv = N·(g0/K1) − (K0·g0·tick)·dt_ticks`, then the optional misalignment matrix; or,
//!   for MEMS samples, [`Compensator::cycle_samples`]: `a = raw·(g0/K1) − K0·g0`, the
//!   paper's `a = E/K1 − K0` with the division done in the slow path.
//!   No division, no transcendental function, no search, loops bounded by `AXES`.
//!   Measured cost under QEMU (`cargo xtask bench-target`) is in the repository's `docs/measurements.md`.
//!
//! # Interrupt-safe split
//! [`Compensator::split`] gives an [`Updater`] (slow path, thread mode or a 1 Hz task) and
//! an [`Applier`] (fast path, the IMU interrupt). They share only one
//! coefficient set: one buffer of 32-bit atomics behind a sequence number, a seqlock. The
//! updater makes the sequence odd, writes the set and makes the sequence even again. The
//! applier keeps its own copy of the last whole set; per cycle it loads the sequence (one
//! Relaxed load and a compare), and when it has moved (once per publication) it copies the
//! set and loads the sequence again, in a `#[cold]` function. It never blocks and never
//! waits, and no half-written set is ever used, whichever context preempts which, on one
//! core or several:
//! * the updater preempts the applier in the middle of its copy: the sequence has moved at
//!   the re-check, the torn copy is dropped, the previous whole set is used for that cycle,
//!   and the copy is tried again on the next cycle;
//! * the applier preempts the updater in the middle of a publication: it sees an odd
//!   sequence and keeps its last set, for every cycle until the publication is finished.
//!
//! There is one updater: the slow path is `&mut`, so two publications never overlap.
//! `compensator::tests::reader_preempting_the_writer_at_every_store_sees_whole_sets` runs the
//! applier after every single store of a publication, and
//! `a_copy_torn_by_the_writer_is_dropped` runs a publication in the middle of the applier's
//! copy. The memory orderings are checked by loom (`compensator::seqlock::model`, run by
//! `cargo xtask loom` and `cargo xtask test`): one writer thread and one reader thread
//! through every interleaving and every store each load may read under loom's memory model
//! (three tests, 627 592 executions, 33 s under CI load; up to 3 preemptions in the one with two
//! publications), with the sequence wrapping past `u32::MAX` in one of them.
//! `cargo xtask loom` also checks that the model fails on each of six mutants that weaken
//! one ordering or drop one step of the seqlock (`mutants_caught=6 of 6`). Only 32-bit
//! atomic loads and stores are used, which every Cortex-M has (no compare-and-swap, so no
//! `portable-atomic` is needed).
//!
//! # Sensors
//! `SENSORS` is 1 (one temperature stream for every axis) or `AXES` (one DS18B20 per
//! accelerometer case, as in the paper): each stream has its own rate estimator,
//! plausibility rules and staleness, and one misalignment matrix still spans the axes.
//!
//! # Faults
//! Faults never produce a silent wrong answer:
//! * A rejected reading returns a typed [`SampleError`], raises [`Status::TEMP_INVALID`]
//!   and keeps the last good compensation. So does a reading that never arrived, reported
//!   with [`Compensator::on_missed_reading`]: report every failed read.
//! * A stream with no good reading for the stale threshold raises [`Status::TEMP_STALE`]:
//!   the fast path counts its own ticks, and the slow path keeps a saturating age per
//!   stream that no clock wrap resets (see [`crate::time`]).
//! * A reading that jumps further than `max_step_raw` plus `max_slew_raw_per_min` times the
//!   elapsed time (counted at most up to the rate window's gap) is used only once
//!   [`Config::confirm_samples`] readings agree. The DS18B20's power-on value 0550h
//!   (+85 °C) is used only as the continuation of a stream already there (within one step,
//!   no gap); after a dropout or as a jump it is refused, whether or not the scratchpad's
//!   byte 6 gives it away. Values outside −55…+125 °C are refused.
//! * A table records the [`Input`](table::Input) it converts; [`Config::input`] names the
//!   compensator's, a table of the other kind is refused, and the fast-path entry of the
//!   other kind raises [`Status::WRONG_INPUT`].
//! * With no table the raw input passes through at the nominal scale
//!   [`Config::nominal_k1`], flagged [`Status::NO_TABLE`], so an INS that ignores the
//!   status still sees gravity, not free fall.
//! * Outputs are always finite and bounded: table validation bounds `g0/K1` and `K0` (the
//!   bias grid never extrapolates), [`Config::validate`] bounds the nominal scale, and the
//!   inputs are integers.

use core::borrow::Borrow;

use crate::model::{AxisState, Evaluation};
use crate::rate::{self, Estimate, RateWindow};
use crate::table::{self, Table};

mod applier;
mod config;
mod seqlock;
mod slow_path;
mod status;
#[cfg(all(test, not(loom)))]
mod tests;

pub use applier::{Applier, CountingApplier, PulseOutput, SampleOutput};
use applier::{Coefs, FastState};
pub use config::{Config, ConfigError, IMU_PERIOD_TOLERANCE};
// Crate-private unless the benchmark's feature asks for it (its size is a figure there).
#[cfg(all(test, not(loom)))]
use seqlock::Changes;
#[cfg(feature = "bench-internals")]
#[doc(hidden)]
pub use seqlock::Published;
#[cfg(not(feature = "bench-internals"))]
use seqlock::Published;
use seqlock::{Set, AGE_STEPS};
pub use slow_path::{SampleError, Updater};
use slow_path::{SlowState, Stream};
pub use status::Status;

/// Standard gravity, m/s² (the unit the tables' g refers to).
pub const G0: f32 = 9.806_65;

/// The rate window of the recommended configurations: Ṫ from the last 32 readings (32 s at
/// 1 Hz). A table records the window it was fitted for ([`Table::rate_window`]).
pub const DEFAULT_RATE_WINDOW: usize = 32;

/// The recommended configuration: three axes, one temperature sensor (DS18B20) per
/// accelerometer case as in the paper, the default rate window, the table in flash
/// (`&'static Table`), and no misalignment stage (a table with a matrix is refused:
/// [`ThreeAxisSensorPerAxisWithMatrix`] applies it). `ThreeAxisSensorPerAxis<Table>` owns
/// its table instead, loadable from bytes at run time ([`Compensator::load_table`]).
pub type ThreeAxisSensorPerAxis<T = &'static Table> = Compensator<3, DEFAULT_RATE_WINDOW, 3, T>;

/// [`ThreeAxisSensorPerAxis`] with a misalignment stage: the table's 3×3 matrix, when it has
/// one, is applied each IMU cycle (9 multiply-adds and 36 B more of the shared set, 36 B of
/// the applier's copy).
pub type ThreeAxisSensorPerAxisWithMatrix<T = &'static Table> = Compensator<3, DEFAULT_RATE_WINDOW, 3, T, 3>;

/// Three axes sharing one temperature sensor (temperature stream 0 serves every axis), the
/// default rate window, the table in flash and no misalignment stage;
/// `ThreeAxisSharedSensor<Table>` owns its table.
pub type ThreeAxisSharedSensor<T = &'static Table> = Compensator<3, DEFAULT_RATE_WINDOW, 1, T>;

/// [`ThreeAxisSharedSensor`] with a misalignment stage.
pub type ThreeAxisSharedSensorWithMatrix<T = &'static Table> = Compensator<3, DEFAULT_RATE_WINDOW, 1, T, 3>;

/// The slow half of a [`ThreeAxisSensorPerAxis`] (from [`Compensator::split`]): the type a
/// task that owns it names, `SensorPerAxisUpdater<'static>` for a table in flash.
pub type SensorPerAxisUpdater<'a, T = &'static Table> = Updater<'a, 3, DEFAULT_RATE_WINDOW, 3, T>;

/// The slow half of a [`ThreeAxisSensorPerAxisWithMatrix`].
pub type SensorPerAxisUpdaterWithMatrix<'a, T = &'static Table> = Updater<'a, 3, DEFAULT_RATE_WINDOW, 3, T, 3>;

/// The slow half of a [`ThreeAxisSharedSensor`].
pub type SharedSensorUpdater<'a, T = &'static Table> = Updater<'a, 3, DEFAULT_RATE_WINDOW, 1, T>;

/// The slow half of a [`ThreeAxisSharedSensorWithMatrix`].
pub type SharedSensorUpdaterWithMatrix<'a, T = &'static Table> = Updater<'a, 3, DEFAULT_RATE_WINDOW, 1, T, 3>;

/// The fast half of either three-axis configuration without a matrix, for the IMU
/// interrupt: `ThreeAxisApplier<'static>`.
pub type ThreeAxisApplier<'a> = Applier<'a, 3>;

/// The fast half of either three-axis configuration with a matrix.
pub type ThreeAxisApplierWithMatrix<'a> = Applier<'a, 3, 3>;

/// [`ThreeAxisApplier`] counting wrapping cumulative counters ([`Applier::counting`]): the
/// type an IMU interrupt that reads pulse counters owns, `ThreeAxisCountingApplier<'static>`.
pub type ThreeAxisCountingApplier<'a> = CountingApplier<'a, 3>;

/// [`ThreeAxisApplierWithMatrix`] counting wrapping cumulative counters.
pub type ThreeAxisCountingApplierWithMatrix<'a> = CountingApplier<'a, 3, 3>;

/// Temperature compensation for `AXES` accelerometers with a `RATE_WINDOW`-reading rate
/// window and `SENSORS` temperature streams (1, or one per axis). The table is held as `T`:
/// an owned [`Table`] (708 B, loadable from bytes at run time) or a `&'static Table` in
/// flash. `MATRIX` is the misalignment stage's rows: 0, none (the fast path has no code for
/// it, and [`set_table`](Self::set_table) refuses a table with a matrix with
/// [`table::Error::NoMisalignmentStage`]), or 3 (three axes only: the table's 3×3 matrix,
/// when it has one). [`ThreeAxisSensorPerAxis`] and [`ThreeAxisSharedSensor`] name the
/// recommended configurations, each with a `WithMatrix` twin.
///
/// Unsplit, it is one value with both paths (`&mut self` each); [`split`](Self::split)
/// hands the two paths to two execution contexts. Here one axis, unsplit, whose temperature
/// steps from 22 to 40 °C, with every reading and every refusal visible in the status:
///
/// ```
/// use qfa_thermal::{AxisModel, BiasGrid, Compensator, Config, Extensions, Input, SampleError, ScaleFactor, Status, Table};
///
/// let bias = BiasGrid::single_valued(-40.0, 10.0, &[0.0; 13]).expect("2 to 16 grid values");
/// let scale = ScaleFactor { t0_c: 22.0, gamma: 320_320.0, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 }; // JB-KT8 #1, Eq. 15
/// let axis = AxisModel { scale, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
/// let table = Table { input: Input::PulseCounts, rate_window: 32, axes: [axis].into_iter().collect(), misalignment: None, part_lsb_per_g: None };
///
/// let mut comp = Compensator::<1, 32>::new(Config::default()).unwrap();
/// // Before a table: raw pass-through at the nominal scale, flagged.
/// assert!(comp.cycle([1_600], 5_000).status.contains(Status::NO_TABLE));
/// comp.set_table(table).unwrap();
/// for s in 0..8 {
///     comp.on_raw(0, s * 1_000, 352).unwrap(); // 22.0 °C at 1 Hz
/// }
/// assert!(comp.cycle([1_600], 5_000).status.is_ok());
/// // A jump of 18 °C in one second is refused (a glitch, until confirmed by more readings);
/// // the last good compensation stays in force and the status says so.
/// assert!(matches!(comp.on_raw(0, 8_000, 640), Err(SampleError::Implausible { .. })));
/// assert!(comp.cycle([1_600], 5_000).status.contains(Status::TEMP_INVALID));
/// ```
#[derive(Debug)]
pub struct Compensator<
    const AXES: usize = 3,
    const RATE_WINDOW: usize = DEFAULT_RATE_WINDOW,
    const SENSORS: usize = 1,
    T = Table,
    const MATRIX: usize = 0,
> {
    slow: SlowState<AXES, RATE_WINDOW, SENSORS, T>,
    shared: Published<AXES, MATRIX>,
    fast: FastState<AXES, MATRIX>,
}

impl<
        const AXES: usize,
        const RATE_WINDOW: usize,
        const SENSORS: usize,
        T: Clone + Borrow<Table>,
        const MATRIX: usize,
    > Clone for Compensator<AXES, RATE_WINDOW, SENSORS, T, MATRIX>
{
    /// An independent copy in the same state: its own shared set holds every word
    /// of the original's, the sequence included, so its applier sees exactly what the
    /// original's sees (a publication it has not copied yet included).
    fn clone(&self) -> Self {
        Self { slow: self.slow.clone(), shared: self.shared.snapshot(), fast: self.fast }
    }
}

/// The status before the applier's first copy of a set.
const NOT_YET: Status = Status::NO_TABLE.union(Status::TEMP_STALE);

const NO_EVAL: Evaluation = Evaluation { k1: 0.0, k0: 0.0, temp_clamped: false, rate_clamped: false, settling: false };

impl<const AXES: usize, const RATE_WINDOW: usize, const SENSORS: usize, T: Borrow<Table>, const MATRIX: usize>
    Compensator<AXES, RATE_WINDOW, SENSORS, T, MATRIX>
{
    /// Checked at compile time (evaluated in [`new`](Self::new)): a wrong count does not build.
    const BOUNDS: () = {
        assert!(AXES >= 1 && AXES <= table::MAX_AXES, "AXES must be 1..=3");
        assert!(SENSORS == 1 || SENSORS == AXES, "SENSORS must be 1 (one shared sensor) or AXES (one per axis)");
        assert!(
            MATRIX == 0 || (MATRIX == 3 && AXES == 3),
            "MATRIX must be 0 (no misalignment stage) or 3 (with 3 axes)"
        );
    };

    /// A compensator with no table: the raw input passes through at
    /// [`Config::nominal_k1`] with [`Status::NO_TABLE`] until a table is set.
    ///
    /// `AXES` (1..=3) and `SENSORS` (1 or `AXES`) are checked at compile time; two
    /// temperature sensors for three axes does not build:
    ///
    /// ```compile_fail,E0080
    /// use qfa_thermal::{Compensator, Config};
    ///
    /// let comp = Compensator::<3, 32, 2>::new(Config::default());
    /// ```
    ///
    /// # Errors
    /// [`Config::validate`]'s error or [`ConfigError::MinSamplesAboveWindow`].
    pub fn new(config: Config) -> Result<Self, ConfigError> {
        let () = Self::BOUNDS;
        config.validate()?;
        if usize::from(config.rate.min_samples) > RATE_WINDOW {
            return Err(ConfigError::MinSamplesAboveWindow);
        }
        let dt_band = config.dt_band().ok_or(ConfigError::ImuPeriodInTicks)?;
        let stream = Stream {
            rate: RateWindow::new(),
            pending_t_ms: 0,
            pending_raw: 0,
            pending_count: 0,
            invalid: false,
            age_ms: 0,
        };
        let mut c = Self {
            slow: SlowState {
                config,
                stale_ms: config.stale_after_ms(),
                clock_ms: 0,
                epoch: 0,
                deadband_floor: rate::flicker_deadband_c_per_min(RATE_WINDOW, config.sample_period_ms),
                table: None,
                streams: core::array::from_fn(|_| stream.clone()),
                states: [AxisState::default(); AXES],
                evals: [NO_EVAL; AXES],
                status: Status::empty(),
                #[cfg(qfa_mutant = "one_reading_delay")]
                delayed: None,
            },
            shared: Published::new(),
            fast: FastState {
                stale_after_ticks: config.stale_after_ticks,
                dt_lowest: dt_band.0,
                dt_span: dt_band.1,
                ticks_per_age: config.stale_after_ticks as f32 / f32::from(AGE_STEPS),
                ticks_left: 0,
                seen_seq: 0,
                coefs: [Coefs::ZERO; 2],
                misalign: None,
                epoch: Set::<AXES, MATRIX>::EMPTY.epoch,
                // Until the first set is copied, nothing is calibrated.
                path_status: match config.input {
                    table::Input::PulseCounts => [NOT_YET, NOT_YET | Status::WRONG_INPUT],
                    table::Input::Samples => [NOT_YET | Status::WRONG_INPUT, NOT_YET],
                },
                counters: [0; AXES],
                has_counters: false,
            },
        };
        c.updater().refresh_all(0.0);
        // The applier starts from that whole set, never from an empty one: a first
        // publication torn by the IMU interrupt then leaves it the pass-through set.
        c.applier().refresh();
        Ok(c)
    }

    fn updater(&mut self) -> Updater<'_, AXES, RATE_WINDOW, SENSORS, T, MATRIX> {
        Updater { slow: &mut self.slow, shared: &self.shared }
    }

    fn applier(&mut self) -> Applier<'_, AXES, MATRIX> {
        Applier { fast: &mut self.fast, shared: &self.shared }
    }

    /// The two paths, for two execution contexts: the [`Updater`] for thread mode or a
    /// task, the [`Applier`] for the IMU interrupt. With a `&'static mut Compensator`
    /// (from a `static_cell::StaticCell`, say) both halves are `'static`.
    ///
    /// The applier leaves with a copy of the set in force (the compensator is borrowed
    /// whole here, so no publication can tear it): whatever the first IMU interrupt
    /// preempts, it has a whole set to use.
    pub fn split(&mut self) -> (Updater<'_, AXES, RATE_WINDOW, SENSORS, T, MATRIX>, Applier<'_, AXES, MATRIX>) {
        self.applier().refresh();
        (Updater { slow: &mut self.slow, shared: &self.shared }, Applier { fast: &mut self.fast, shared: &self.shared })
    }

    /// Validate and activate a table. Atomic: on any error the active table and every
    /// state are unchanged; on success the fast path switches to the new coefficients in
    /// one publication.
    ///
    /// # Errors
    /// Any [`table::Error`], including an axis count other than `AXES`, a rate window
    /// other than `RATE_WINDOW`, and a K1 scale more than a factor of 2 from
    /// [`Config::nominal_k1`] ([`table::Error::Scale`]).
    pub fn set_table(&mut self, t: T) -> table::Result<()> {
        self.updater().set_table(t)
    }

    /// The active table.
    #[must_use]
    pub fn table(&self) -> Option<&Table> {
        self.slow.table.as_ref().map(Borrow::borrow)
    }

    /// Settings.
    #[must_use]
    pub const fn config(&self) -> &Config {
        &self.slow.config
    }

    /// Sensor 0's current estimate; `None` before its first good reading.
    #[must_use]
    pub fn estimate(&self) -> Option<Estimate> {
        self.slow.streams[0].rate.estimate(&self.slow.config.rate)
    }

    /// Sensor `sensor`'s current estimate; `None` before its first good reading or for an
    /// index ≥ `SENSORS`.
    #[must_use]
    pub fn estimate_of(&self, sensor: usize) -> Option<Estimate> {
        self.slow.streams.get(sensor).and_then(|s| s.rate.estimate(&self.slow.config.rate))
    }

    /// The model evaluated at each axis's last good sample (K1 in pulses/(g·s), K0 in g).
    #[must_use]
    pub const fn evaluations(&self) -> &[Evaluation; AXES] {
        &self.slow.evals
    }

    /// Status as of the last slow-path call (the fast path adds its own staleness).
    #[must_use]
    pub const fn status(&self) -> Status {
        self.slow.status
    }

    /// Slow path: the 9-byte scratchpad of temperature sensor `sensor` (0..`SENSORS`), read
    /// at `t_ms` (the time base of [`crate::time`], taken when the conversion completed).
    ///
    /// # Errors
    /// A [`SampleError`]; the last good compensation stays in force and
    /// [`Status::TEMP_INVALID`] is raised. [`SampleError::NoSuchSensor`] for
    /// `sensor ≥ SENSORS`.
    pub fn on_scratchpad(&mut self, sensor: usize, t_ms: u32, scratchpad: &[u8; 9]) -> Result<Status, SampleError> {
        self.updater().on_scratchpad(sensor, t_ms, scratchpad)
    }

    /// Slow path: a raw reading of temperature sensor `sensor` (1/16 °C, already masked),
    /// taken at `t_ms`.
    ///
    /// # Errors
    /// As [`on_scratchpad`](Self::on_scratchpad).
    pub fn on_raw(&mut self, sensor: usize, t_ms: u32, raw: i16) -> Result<Status, SampleError> {
        self.updater().on_raw(sensor, t_ms, raw)
    }

    /// Slow path: a reading of sensor `sensor` that never arrived; see
    /// [`Updater::on_missed_reading`].
    ///
    /// # Errors
    /// As [`Updater::on_missed_reading`].
    pub fn on_missed_reading(&mut self, sensor: usize, t_ms: u32) -> Result<Status, SampleError> {
        self.updater().on_missed_reading(sensor, t_ms)
    }

    /// Fast path: see [`Applier::cycle`]. Forgets the counter base of
    /// [`cycle_counters`](Self::cycle_counters), whose pulses this cycle may have reported.
    #[inline]
    pub fn cycle(&mut self, pulses: [i32; AXES], dt_ticks: u32) -> PulseOutput<AXES> {
        self.fast.has_counters = false;
        self.applier().cycle(pulses, dt_ticks)
    }

    /// Fast path for MEMS samples: see [`Applier::cycle_samples`]. Forgets the counter
    /// base, as [`cycle`](Self::cycle) does.
    #[inline]
    pub fn cycle_samples(&mut self, raw: [i32; AXES], dt_ticks: u32) -> SampleOutput<AXES> {
        self.fast.has_counters = false;
        self.applier().cycle_samples(raw, dt_ticks)
    }

    /// Fast path from wrapping cumulative u32 counters: the increments are their advance
    /// since the previous `cycle_counters`. With no base (the first call, or the first after
    /// a [`cycle`](Self::cycle) or [`cycle_samples`](Self::cycle_samples), which may have
    /// reported some of those pulses already) it returns zero increments with
    /// [`Status::NO_COUNTER_BASE`]; [`prime_counters`](Self::prime_counters) sets a base.
    /// A split compensator counts with [`Applier::counting`].
    #[inline]
    pub fn cycle_counters(&mut self, counters: [u32; AXES], dt_ticks: u32) -> PulseOutput<AXES> {
        // One call of the fast path for both outcomes (two inlined copies cost flash).
        let f = &mut self.fast;
        // The new base is taken either way; the old one only if there was one.
        let old = core::mem::replace(&mut f.counters, counters);
        let prev = core::mem::replace(&mut f.has_counters, true).then_some(old);
        let pulses: [i32; AXES] = core::array::from_fn(|i| prev.map_or(0, |p| counters[i].wrapping_sub(p[i]) as i32));
        let mut out = self.applier().cycle(pulses, dt_ticks);
        if prev.is_none() {
            out.dv_mps = [0.0; AXES];
            out.status |= Status::NO_COUNTER_BASE;
        }
        out
    }

    /// Set the cumulative counters' base without producing output.
    pub fn prime_counters(&mut self, counters: [u32; AXES]) {
        (self.fast.counters, self.fast.has_counters) = (counters, true);
    }
}

impl<const AXES: usize, const RATE_WINDOW: usize, const SENSORS: usize, const MATRIX: usize>
    Compensator<AXES, RATE_WINDOW, SENSORS, Table, MATRIX>
{
    /// Decode, validate and activate a table from its wire bytes. Atomic: on any error
    /// the active table and every state are unchanged.
    ///
    /// # Errors
    /// Any [`table::Error`], including an axis count other than `AXES` and a rate window
    /// other than `RATE_WINDOW`.
    pub fn load_table(&mut self, bytes: &[u8]) -> table::Result<()> {
        let t = Table::decode(bytes)?;
        self.set_table(t)
    }
}
