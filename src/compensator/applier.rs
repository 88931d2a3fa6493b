//! The fast path: the applier's own copy of the coefficients, refreshed through the seqlock,
//! and the per-IMU-cycle correction.

#[cfg(doc)]
use super::Compensator;
use core::sync::atomic::Ordering;

use super::seqlock::{Published, AGE_STALE};
use super::Status;

/// [`Status::DT_IMPLAUSIBLE`]'s bit number.
const DT_IMPLAUSIBLE_SHIFT: u32 = Status::DT_IMPLAUSIBLE.bits().trailing_zeros();

/// Output of one IMU cycle from pulse counts ([`Compensator::cycle`],
/// [`Compensator::cycle_counters`], [`CountingApplier::cycle`]): velocity increments.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct PulseOutput<const AXES: usize> {
    /// Compensated velocity increment over the cycle per axis, m/s.
    pub dv_mps: [f32; AXES],
    /// Conditions in force.
    pub status: Status,
}

/// Output of one IMU cycle from MEMS samples ([`Compensator::cycle_samples`]):
/// accelerations, not increments.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SampleOutput<const AXES: usize> {
    /// Compensated specific force per axis, m/s².
    pub accel_mps2: [f32; AXES],
    /// Conditions in force.
    pub status: Status,
}

/// Fast-path state: the applier's own copy of the last whole coefficient set, its
/// staleness clock and its counter base. Never touched by the updater. In declaration
/// order (`repr(C)`): the per-cycle words first, the band's two adjacent for one `ldrd`.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C)]
pub(super) struct FastState<const AXES: usize, const MATRIX: usize> {
    /// Sequence of the set copied into `coefs`, `misalign` and `epoch`.
    pub(super) seen_seq: u32,
    /// Ticks left before the set is stale, counted down and held at 0. At each copy, the
    /// budget `stale_after_ticks + 1` less the oldest stream's age: taken when a good
    /// reading came since the last copy, otherwise only if shorter. A countdown costs two
    /// instructions per cycle less than counting up and comparing.
    pub(super) ticks_left: u32,
    /// The fewest `dt_ticks` a cycle may take without [`Status::DT_IMPLAUSIBLE`], and how
    /// many more ([`Config::imu_period_s`]'s band): one unsigned compare per cycle.
    pub(super) dt_lowest: u32,
    pub(super) dt_span: u32,
    pub(super) stale_after_ticks: u32,
    /// Ticks per age unit (`stale_after_ticks / AGE_STEPS`): turns a set's age into ticks.
    pub(super) ticks_per_age: f32,
    /// Each entry's coefficients, `[pulses, samples]`: the configured entry's from the last
    /// whole set; the other entry's are 0 from construction on, so a cycle there gives zeros
    /// (flagged [`Status::WRONG_INPUT`]) through the same arithmetic, without a branch.
    pub(super) coefs: [Coefs<AXES>; 2],
    /// The unsplit compensator's counter base ([`Compensator::cycle_counters`]), meaningful
    /// once `has_counters`: from the first counter cycle until any other kind of cycle.
    pub(super) counters: [u32; AXES],
    /// The set's status as each entry sees it, `[pulses, samples]`: the entry that does not
    /// match [`Config::input`] carries [`Status::WRONG_INPUT`] from construction on (the
    /// bit is kept at each copy, so it needs no field of its own). Formed when a set is
    /// copied, so the per-cycle path only picks a field.
    pub(super) path_status: [Status; 2],
    /// The last whole set's matrix (`None` without a misalignment stage or a matrix).
    pub(super) misalign: Option<[[f32; AXES]; MATRIX]>,
    /// The last whole set's epoch (`Set::epoch`).
    pub(super) epoch: u8,
    /// `counters` holds a base (no `Option`: its 4-byte tag cost 4 B more with the padding).
    pub(super) has_counters: bool,
}

/// One entry's coefficients: g0/K1 per axis, and the bias in that entry's form (m/s per tick
/// for pulse counts, m/s² for samples).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Coefs<const AXES: usize> {
    pub(super) scale: [f32; AXES],
    pub(super) bias: [f32; AXES],
}

impl<const AXES: usize> Coefs<AXES> {
    /// The wrong entry's coefficients. The bias is −0: `n·0 − (−0)·dt` is +0 for every
    /// input `n` (a +0 bias would leave −0 for a negative one), so the output is the same
    /// +0.0 bits the entry returned when it branched. Through a matrix too: its diagonal is
    /// within 0.05 of 1 (validation), so every row's sum holds a +0 term.
    pub(super) const ZERO: Self = Self { scale: [0.0; AXES], bias: [-0.0; AXES] };
}

/// The fast path of a split compensator: owns the IMU-cycle state and a copy of the
/// coefficients, refreshed from the shared set when its sequence changes. Put it
/// where the IMU interrupt can reach it.
///
/// Per cycle it loads one shared word (the sequence) and otherwise reads only its own
/// memory. When the sequence has moved (once per temperature reading), it copies the set
/// and checks the sequence again: a set read while the updater was writing it (an odd or
/// changed sequence) is dropped, the previous whole set stays in use for this cycle, and
/// the copy is tried again on the next. It never waits and never uses a half-written set,
/// whichever context preempts which, on one core or several.
///
/// Here the two halves run on two threads, as they would in thread mode and an interrupt
/// on a multi-core part; the applier never waits for the updater:
///
/// ```
/// use qfa_thermal::{AxisModel, BiasGrid, Config, Extensions, Input, ScaleFactor, Table, ThreeAxisSensorPerAxis};
///
/// let bias = BiasGrid::single_valued(-40.0, 10.0, &[1e-4; 13]).expect("2 to 16 grid values");
/// let scale = ScaleFactor { t0_c: 22.0, gamma: 320_320.0, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 }; // JB-KT8 #1, Eq. 15
/// let axis = AxisModel { scale, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
/// let table = Table { input: Input::PulseCounts, rate_window: 32, axes: core::iter::repeat_n(axis, 3).collect(), misalignment: None, part_lsb_per_g: None };
/// let mut comp = ThreeAxisSensorPerAxis::<Table>::new(Config::default()).unwrap(); // owns its table
/// comp.set_table(table).unwrap();
/// let (mut updater, mut applier) = comp.split();
/// let mut applier = applier.counting([0; 3]); // the counters' base
///
/// std::thread::scope(|s| {
///     s.spawn(move || {
///         for t in 0..20u32 {
///             for sensor in 0..3 {
///                 updater.on_raw(sensor, t * 1_000, 352 + (t / 4) as i16).unwrap(); // a slow ramp
///             }
///         }
///     });
///     s.spawn(move || {
///         let mut counters = [0u32; 3];
///         for _ in 0..10_000 {
///             counters[2] = counters[2].wrapping_add(1_601);
///             let out = applier.cycle(counters, 5_000);
///             assert!(out.dv_mps.iter().all(|v| v.is_finite())); // always, whatever it raced
///         }
///     });
/// });
/// ```
#[derive(Debug)]
pub struct Applier<'a, const AXES: usize, const MATRIX: usize = 0> {
    pub(super) fast: &'a mut FastState<AXES, MATRIX>,
    pub(super) shared: &'a Published<AXES, MATRIX>,
}

impl<'a, const AXES: usize, const MATRIX: usize> Applier<'a, AXES, MATRIX> {
    /// Copy the published set if it is whole (seqlock reader); the rare path.
    #[cold]
    #[inline(never)]
    pub(super) fn refresh(&mut self) {
        self.refresh_with(|| {});
    }

    /// [`Self::refresh`] with `mid` run between the copy and the re-check (a test hook:
    /// the updater preempting the applier there).
    #[inline(always)]
    pub(super) fn refresh_with(&mut self, mid: impl FnOnce()) {
        let Some(s) = self.shared.read_with(mid) else {
            return; // being written, or written meanwhile: keep the last whole set this cycle
        };
        let f = &mut *self.fast;
        let [pulses, samples] = f.path_status.map(|st| st & Status::WRONG_INPUT);
        f.path_status = [s.set.status | pulses, s.set.status | samples];
        // The configured entry is the one without WRONG_INPUT; the other keeps its zeros.
        let entry = usize::from(!pulses.is_empty());
        if let Some(c) = f.coefs.get_mut(entry) {
            *c = Coefs { scale: s.set.scale, bias: s.set.bias };
        }
        let budget = if s.set.age >= AGE_STALE {
            0
        } else {
            // Rounded down, like the age: the countdown ends at most one age unit late (0.18 ms
            // at the 3-s default), never early.
            let age_ticks = (f32::from(s.set.age) * f.ticks_per_age) as u32;
            f.stale_after_ticks.saturating_add(1).saturating_sub(age_ticks)
        };
        // A good reading since the last copy restarts the countdown; any other publication
        // (a rejection, a missed reading: the slow path's clock moved; a table load) can only
        // shorten it, so its own tick count and the slow path's clock never make a stale set
        // fresh between them.
        f.ticks_left = if s.set.epoch != f.epoch { budget } else { f.ticks_left.min(budget) };
        f.misalign = s.set.misalign;
        f.epoch = s.set.epoch;
        f.seen_seq = s.seq;
    }

    /// Refresh the copy if a publication happened; advance the staleness clock; the
    /// status of this cycle for the pulse (`SAMPLES = false`) or sample entry.
    #[inline(always)]
    fn begin<const SAMPLES: bool>(&mut self, dt_ticks: u32) -> Status {
        if self.shared.seq.load(Ordering::Relaxed) != self.fast.seen_seq {
            self.refresh();
        }
        let f = &mut *self.fast;
        f.ticks_left = f.ticks_left.saturating_sub(dt_ticks);
        // TEMP_STALE (bit 0) exactly when ticks_left == 0: `validate` keeps it ≤ 2³¹, so
        // `ticks_left − 1` has its top bit set only at 0. Two instructions, no branch.
        let stale = (f.ticks_left.wrapping_sub(1) >> 31) as u16;
        // Outside the band, below it included (the subtraction wraps to a large number).
        let dt_bad = u16::from(dt_ticks.wrapping_sub(f.dt_lowest) > f.dt_span) << DT_IMPLAUSIBLE_SHIFT;
        Status::from_bits_retain(f.path_status[usize::from(SAMPLES)].bits() | stale | dt_bad)
    }

    /// Fast path: signed pulse counts of this cycle and its length in ticks.
    ///
    /// `Δv[i] = N[i]·(g0/K1[i]) − (K0[i]·g0·tick)·dt`, then `Δv = M·Δv` with a
    /// misalignment matrix. Always finite. Never blocks. On a compensator configured for
    /// samples every Δv is 0 with [`Status::WRONG_INPUT`]: nothing computed in another unit
    /// is left in the field.
    #[inline]
    pub fn cycle(&mut self, pulses: [i32; AXES], dt_ticks: u32) -> PulseOutput<AXES> {
        let status = self.begin::<false>(dt_ticks);
        // On a samples compensator this entry's coefficients are 0: Δv is 0 (WRONG_INPUT).
        let [c, _] = &self.fast.coefs;
        let dt = dt_ticks as f32;
        let dv: [f32; AXES] = core::array::from_fn(|i| pulses[i] as f32 * c.scale[i] - c.bias[i] * dt);
        PulseOutput { dv_mps: misalign(&self.fast.misalign, dv), status }
    }

    /// Fast path for MEMS samples: raw readings (LSB) of this cycle and the ticks since
    /// the previous one (for staleness only).
    ///
    /// `a[i] = raw[i]·(g0/K1[i]) − K0[i]·g0`, m/s², then `a = M·a` with a misalignment
    /// matrix: the paper's `a = E/K1 − K0`, with `1/K1` formed in the slow path. On a
    /// compensator configured for pulse counts every output is 0 with
    /// [`Status::WRONG_INPUT`].
    #[inline]
    pub fn cycle_samples(&mut self, raw: [i32; AXES], dt_ticks: u32) -> SampleOutput<AXES> {
        let status = self.begin::<true>(dt_ticks);
        // On a pulse compensator this entry's coefficients are 0: a is 0 (WRONG_INPUT).
        let [_, c] = &self.fast.coefs;
        let a: [f32; AXES] = core::array::from_fn(|i| raw[i] as f32 * c.scale[i] - c.bias[i]);
        SampleOutput { accel_mps2: misalign(&self.fast.misalign, a), status }
    }

    /// This applier for wrapping cumulative u32 counters, from `counters` as their base.
    ///
    /// It takes the applier by value, so once an interrupt counts pulses with counters it
    /// cannot also report increments through [`cycle`](Self::cycle): the two would count the
    /// same pulses twice.
    ///
    /// ```compile_fail,E0382
    /// # use qfa_thermal::{Config, Table, ThreeAxisSensorPerAxis};
    /// let mut comp = ThreeAxisSensorPerAxis::<Table>::new(Config::default()).unwrap();
    /// let (_updater, applier) = comp.split();
    /// let mut counting = applier.counting([0; 3]);
    /// counting.cycle([1_601, 0, 0], 5_000);
    /// applier.cycle([1_601, 0, 0], 5_000); // moved into `counting`: does not build
    /// ```
    #[must_use]
    pub fn counting(self, counters: [u32; AXES]) -> CountingApplier<'a, AXES, MATRIX> {
        CountingApplier { applier: self, base: counters }
    }
}

/// The fast path from wrapping cumulative u32 counters ([`Applier::counting`]): each cycle's
/// increments are the counters' advance since the previous cycle, as signed counts.
#[derive(Debug)]
pub struct CountingApplier<'a, const AXES: usize, const MATRIX: usize = 0> {
    applier: Applier<'a, AXES, MATRIX>,
    base: [u32; AXES],
}

impl<const AXES: usize, const MATRIX: usize> CountingApplier<'_, AXES, MATRIX> {
    /// Fast path: the counters now and the cycle's length in ticks; see [`Applier::cycle`].
    #[inline]
    pub fn cycle(&mut self, counters: [u32; AXES], dt_ticks: u32) -> PulseOutput<AXES> {
        let prev = core::mem::replace(&mut self.base, counters);
        let pulses: [i32; AXES] = core::array::from_fn(|i| counters[i].wrapping_sub(prev[i]) as i32);
        self.applier.cycle(pulses, dt_ticks)
    }

    /// A new base without output: the counters were reset or reloaded.
    pub fn rebase(&mut self, counters: [u32; AXES]) {
        self.base = counters;
    }
}

/// `M·v` with the set's matrix, `v` without one. Without a misalignment stage (`MATRIX`
/// 0) this is `v` at compile time: the fast path has no branch for it.
#[inline(always)]
fn misalign<const AXES: usize, const MATRIX: usize>(m: &Option<[[f32; AXES]; MATRIX]>, v: [f32; AXES]) -> [f32; AXES] {
    let Some(m) = (MATRIX > 0).then_some(m).and_then(Option::as_ref) else {
        return v;
    };
    // MATRIX is AXES here (`Compensator`'s bounds): every output row is formed.
    let mut out = v;
    for (o, row) in out.iter_mut().zip(m.iter()) {
        // From −0: `−0 + x` is x for every x, so the compiler starts the sum with a multiply
        // (from +0 it kept a move and a multiply-add per row; the two differ only in the
        // sign of an exactly zero row).
        let mut acc = -0.0f32;
        for (a, b) in row.iter().zip(v.iter()) {
            acc += a * b;
        }
        *o = acc;
    }
    out
}
