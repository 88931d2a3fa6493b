//! Per-axis thermal model: scale factor (paper Eq. 11), branched bias grid, extension slots.
//!
//! Conventions (shared/REFERENCE.md): K1 in pulses per g per second, K0 in g,
//! ΔT = T − T0 in °C, Ṫ in °C/min. The accelerometer output is `E = K1·(K0 + a)`,
//! so the compensated specific force is `a = E/K1 − K0` (paper Eq. 5).
//!
//! Everything here runs in the per-temperature-sample path (about 1 Hz): it may divide,
//! call `libm::expf` and index the bias grid. The per-IMU-cycle path only sees the cached
//! `g0/K1` and `K0·g0` per axis.

use core::fmt;

use serde::{Deserialize, Serialize};

mod slots;
pub use slots::{BranchHysteresis, Creep, Extensions, SensorLag};

/// Largest number of bias grid points per branch.
pub const MAX_BIAS_POINTS: usize = 16;

/// Why a model could not be built.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// A bias grid needs 2..=[`MAX_BIAS_POINTS`] values per branch.
    GridPoints {
        /// The number of values given.
        given: usize,
    },
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::GridPoints { given } => {
                write!(f, "a bias grid takes 2 to {MAX_BIAS_POINTS} values per branch, {given} given")
            }
        }
    }
}

impl core::error::Error for Error {}

/// Scale factor model, paper Eq. 11:
/// `K1 = α·Ṫ² + β·ΔT² + η·Ṫ·ΔT + ε·Ṫ + μ·ΔT + γ` (pulses/(g·s), Ṫ in °C/min).
/// The simple model (Eq. 3) is the special case α = β = η = ε = 0.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ScaleFactor {
    /// Reference temperature T0, °C (22 °C in the paper).
    pub t0_c: f32,
    /// γ: K1 at T0 and Ṫ = 0.
    pub gamma: f32,
    /// μ: per °C.
    pub mu: f32,
    /// β: per °C².
    pub beta: f32,
    /// ε: per °C/min.
    pub epsilon: f32,
    /// η: per °C·°C/min.
    pub eta: f32,
    /// α: per (°C/min)².
    pub alpha: f32,
}

impl ScaleFactor {
    /// The simple linear model of Eq. 3: `K1 = μ·ΔT + γ`.
    #[must_use]
    pub const fn simple(t0_c: f32, gamma: f32, mu: f32) -> Self {
        Self { t0_c, gamma, mu, beta: 0.0, epsilon: 0.0, eta: 0.0, alpha: 0.0 }
    }

    /// This scale factor in another unit per g, `k` of the new unit to one of the old: every
    /// coefficient times `k` (a MEMS part's K1 in its LSB per g, brought to the 2²⁰ units
    /// per g of a samples table, is `.in_units(2²⁰ / lsb_per_g)`).
    #[must_use]
    pub const fn in_units(self, k: f32) -> Self {
        Self {
            t0_c: self.t0_c,
            gamma: self.gamma * k,
            mu: self.mu * k,
            beta: self.beta * k,
            epsilon: self.epsilon * k,
            eta: self.eta * k,
            alpha: self.alpha * k,
        }
    }

    /// K1 at temperature `t_c` and rate `rate` (°C/min).
    ///
    /// Evaluation order is fixed so every platform gives the same bits:
    /// `γ + ((((α·r)·r + (β·d)·d) + (η·r)·d) + ε·r) + μ·d)`.
    #[must_use]
    pub fn k1(&self, t_c: f32, rate: f32) -> f32 {
        let d = t_c - self.t0_c;
        let r = rate;
        let dev = (((self.alpha * r) * r + (self.beta * d) * d) + (self.eta * r) * d + self.epsilon * r) + self.mu * d;
        self.gamma + dev
    }

    /// Bound on `|K1 − γ|` over `|ΔT| ≤ d_max`, `|Ṫ| ≤ r_max` (triangle inequality).
    #[must_use]
    pub fn max_deviation(&self, d_max: f32, r_max: f32) -> f32 {
        abs(self.alpha) * r_max * r_max
            + abs(self.beta) * d_max * d_max
            + abs(self.eta) * r_max * d_max
            + abs(self.epsilon) * r_max
            + abs(self.mu) * d_max
    }
}

/// Bias K0 (g) on a uniform temperature grid, with separate heating and cooling branches.
///
/// A uniform grid makes the lookup an index computation (no search). The branch is chosen
/// from Ṫ with a deadband: above `+deadband` heating, below `−deadband` cooling, and in
/// between the previous branch is kept, so it cannot chatter. Before the first decisive
/// rate the mean of the two branches is used. A single-valued bias has equal branches.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BiasGrid {
    /// Temperature of the first grid point, °C: the bottom of the calibrated range.
    pub t_start_c: f32,
    /// Grid spacing, °C (> 0).
    pub t_step_c: f32,
    /// Branch-switch deadband on Ṫ, °C/min (≥ 0). The compensator uses at least the
    /// flicker floor of its rate window and sample period
    /// ([`crate::rate::flicker_deadband_c_per_min`], 0.182 °C/min for 32 readings at 1 s).
    pub deadband_c_per_min: f32,
    /// K0 while heating, g, one per grid point (2..=16).
    pub heating_g: heapless::Vec<f32, MAX_BIAS_POINTS>,
    /// K0 while cooling, g, same length as `heating_g`.
    pub cooling_g: heapless::Vec<f32, MAX_BIAS_POINTS>,
    /// RMS of the bias residual of the fit this grid came from, g (1e-7..0.1): what the
    /// table is accurate to. [`Status::MODEL_SETTLING`](crate::Status::MODEL_SETTLING)
    /// clears once the history states can no longer move K0 by more than a quarter of it
    /// ([`settled_within_g`](Self::settled_within_g)), so that settling adds at most 3 % to
    /// the table's own error in quadrature. `qfa-lab` writes the fit's residual; a grid
    /// written by hand takes [`DEFAULT_RESIDUAL_RMS_G`](Self::DEFAULT_RESIDUAL_RMS_G), as
    /// does a TOML table that leaves the field out.
    #[serde(default = "BiasGrid::default_residual_rms_g")]
    pub residual_rms_g: f32,
}

impl BiasGrid {
    /// The branch deadband [`single_valued`](Self::single_valued) and [`flat`](Self::flat)
    /// give, °C/min. It only matters once the branches differ; the compensator raises it to
    /// its flicker floor anyway (0.182 °C/min for 32 readings at 1 s).
    pub const DEFAULT_DEADBAND_C_PER_MIN: f32 = 0.05;

    /// The residual a grid written by hand states, g: 4 µg, a navigation-grade QFA's bias
    /// stability, which puts the settling threshold at 1 µg.
    pub const DEFAULT_RESIDUAL_RMS_G: f32 = 4e-6;

    fn default_residual_rms_g() -> f32 {
        Self::DEFAULT_RESIDUAL_RMS_G
    }

    /// How close the history states' bias terms must come to the history's before
    /// `MODEL_SETTLING` clears, g: a quarter of [`residual_rms_g`](Self::residual_rms_g).
    #[must_use]
    pub fn settled_within_g(&self) -> f32 {
        0.25 * self.residual_rms_g
    }

    /// A grid whose branches are both `values_g`, at `M` points from `t_start_c` by
    /// `t_step_c`, with [`DEFAULT_DEADBAND_C_PER_MIN`](Self::DEFAULT_DEADBAND_C_PER_MIN):
    /// [`single_valued`](Self::single_valued) in a `const`, for a table in flash. `M` is
    /// checked when it is compiled; a grid of one point does not build:
    ///
    /// ```compile_fail,E0080
    /// const ONE: qfa_thermal::BiasGrid = qfa_thermal::BiasGrid::flat(-40.0, 10.0, [1e-4]);
    /// # let _ = &ONE;
    /// ```
    #[must_use]
    pub const fn flat<const M: usize>(t_start_c: f32, t_step_c: f32, values_g: [f32; M]) -> Self {
        Self::with_branches(t_start_c, t_step_c, Self::DEFAULT_DEADBAND_C_PER_MIN, values_g, values_g)
    }

    /// A grid with a heating and a cooling branch of `M` points each (2..=16, checked when
    /// it is compiled), in a `const`.
    #[must_use]
    pub const fn with_branches<const M: usize>(
        t_start_c: f32,
        t_step_c: f32,
        deadband_c_per_min: f32,
        heating_g: [f32; M],
        cooling_g: [f32; M],
    ) -> Self {
        const { assert!(M >= 2 && M <= MAX_BIAS_POINTS, "a bias grid has 2 to 16 points") }
        Self {
            t_start_c,
            t_step_c,
            deadband_c_per_min,
            heating_g: heapless::Vec::from_array(heating_g),
            cooling_g: heapless::Vec::from_array(cooling_g),
            residual_rms_g: Self::DEFAULT_RESIDUAL_RMS_G,
        }
    }

    /// A grid whose branches are both `f(T)`, given at `values_g.len()` points from
    /// `t_start_c` by `t_step_c`, with
    /// [`DEFAULT_DEADBAND_C_PER_MIN`](Self::DEFAULT_DEADBAND_C_PER_MIN).
    ///
    /// # Errors
    /// [`Error::GridPoints`] unless 2..=[`MAX_BIAS_POINTS`] values are given: a longer list
    /// is refused, never cut short (that would end the calibrated range early).
    pub fn single_valued(t_start_c: f32, t_step_c: f32, values_g: &[f32]) -> Result<Self, Error> {
        let v = heapless::Vec::from_slice(values_g)
            .ok()
            .filter(|v: &heapless::Vec<f32, MAX_BIAS_POINTS>| v.len() >= 2)
            .ok_or(Error::GridPoints { given: values_g.len() })?;
        Ok(Self {
            t_start_c,
            t_step_c,
            deadband_c_per_min: Self::DEFAULT_DEADBAND_C_PER_MIN,
            heating_g: v.clone(),
            cooling_g: v,
            residual_rms_g: Self::DEFAULT_RESIDUAL_RMS_G,
        })
    }

    /// Top of the grid, °C: the top of the calibrated range.
    #[must_use]
    pub fn t_end_c(&self) -> f32 {
        let last = self.heating_g.len().saturating_sub(1) as f32;
        self.t_start_c + self.t_step_c * last
    }

    /// Linear interpolation of `branch` at `t_c`, which the caller has clamped to the grid.
    fn interpolate(&self, branch: &[f32], t_c: f32) -> f32 {
        let n = branch.len();
        if n < 2 {
            return branch.first().copied().unwrap_or(0.0);
        }
        let x = (t_c - self.t_start_c) / self.t_step_c;
        let max_i = n - 2;
        // x ≥ 0 after clamping; `as usize` truncates toward zero and saturates.
        let i = (x as usize).min(max_i);
        // Clamped so that K0 never leaves the two nodes it lies between, whatever rounding
        // does to x: a validated grid bounds K0 by its own values.
        let frac = (x - i as f32).clamp(0.0, 1.0);
        let (a, b) = (branch[i], branch[i + 1]);
        // Rounding of `a + (b − a)·1` can land one ulp past b; held to the two nodes, so a
        // validated grid bounds K0 by its own values exactly.
        let (lo, hi) = if a <= b { (a, b) } else { (b, a) };
        let k0 = a + (b - a) * frac;
        if k0 > hi {
            hi
        } else if k0 < lo {
            lo
        } else {
            k0
        }
    }

    /// K0 (g) at `t_c` on `branch`.
    #[must_use]
    pub fn k0(&self, t_c: f32, branch: Branch) -> f32 {
        self.k0_and_doubt(t_c, branch).0
    }

    /// K0 (g) at `t_c` on `branch`, and how far it may be from the branch in force, g: half
    /// the branches' difference while the branch is unknown (the mean is used), else 0.
    fn k0_and_doubt(&self, t_c: f32, branch: Branch) -> (f32, f32) {
        match branch {
            Branch::Heating => (self.interpolate(&self.heating_g, t_c), 0.0),
            Branch::Cooling => (self.interpolate(&self.cooling_g, t_c), 0.0),
            Branch::Unknown => {
                let h = self.interpolate(&self.heating_g, t_c);
                let c = self.interpolate(&self.cooling_g, t_c);
                ((h + c) * 0.5, abs(h - c) * 0.5)
            }
        }
    }
}

/// Which bias branch is in force.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Branch {
    /// No decisive rate seen yet: mean of both branches.
    #[default]
    Unknown,
    /// Temperature rising.
    Heating,
    /// Temperature falling.
    Cooling,
}

impl Branch {
    /// Next branch given the rate and deadband (°C/min).
    #[must_use]
    pub fn next(self, rate: f32, deadband: f32) -> Self {
        if rate > deadband {
            Self::Heating
        } else if rate < -deadband {
            Self::Cooling
        } else {
            self
        }
    }
}

/// One axis's coefficient table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisModel {
    /// Scale factor.
    pub scale: ScaleFactor,
    /// Bias; its grid is also the calibrated temperature range.
    pub bias: BiasGrid,
    /// Largest |Ṫ| calibrated, °C/min; larger rates are clamped and flagged.
    pub rate_limit_c_per_min: f32,
    /// Extension slots.
    pub ext: Extensions,
}

/// Fixed-size state of one axis's model (branch, lag, play and creep states).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct AxisState {
    initialized: bool,
    /// The history states restart from the next temperature: at power-up, and when a
    /// reloaded table changed the slots or the range.
    restart: u8,
    /// Bias branch in force.
    pub branch: Branch,
    /// Element temperature (sensor_lag), °C.
    pub element_c: f32,
    /// Play operator output (bias_branch_hysteresis), °C.
    pub play_c: f32,
    /// Creep state x (bias_creep), °C.
    pub creep_c: f32,
    /// How far `element_c` may be from what the unit's whole history gives, °C: the grid's
    /// span when the lag starts without that history, shrinking by `e^(−dt/τ)` per step.
    lag_unknown_c: f32,
    /// How far the play term may be from the history's, g: the play output may be anywhere
    /// within its half-width at a start, and every move it makes pushes the history's
    /// along with it (the play operator never widens a difference), so the bound shrinks
    /// by each move, never below what the lag's bound makes of it.
    play_unknown_g: f32,
    /// How far the creep term may be from the history's, g: the grid's span times the gain
    /// at a start, shrinking like the lag's.
    creep_unknown_g: f32,
}

const RESTART: u8 = 1;
#[cfg(qfa_mutant = "reload_drops_state")]
const RESTART_SILENTLY: u8 = 0x80;

/// A lag state is settled when it is within this of the history's, °C (a quarter of a
/// DS18B20 LSB).
pub const SETTLED_LAG_C: f32 = 1.0 / 64.0;

/// The temperatures a table may describe, °C (`table::limits::TEMP_C`, −60…130 °C, which
/// holds a DS18B20's −55…125 °C): what the unit's states follow, and where they may lie when
/// they start without their history.
const STATE_MIN_C: f32 = crate::table::limits::TEMP_C.0;
const STATE_MAX_C: f32 = crate::table::limits::TEMP_C.1;

/// What the history states depend on, as bits: the slots, with a word saying which are on,
/// and the calibrated range. Compared as one array: field by field, with the `Option`s and
/// the float comparisons, it took 390 B of Cortex-M4 flash.
fn history_bits(m: &AxisModel) -> [u32; 11] {
    let e = &m.ext;
    let lag = e.sensor_lag.map_or(0, |l| l.tau_s.to_bits());
    let (half, weight) = e.bias_branch_hysteresis.map_or((0, 0), |h| (h.half_width_c.to_bits(), h.weight_g.to_bits()));
    let (gain, tau, t_ref, act) = e.bias_creep.map_or((0, 0, 0, 0), |c| {
        (c.gain_g_per_c.to_bits(), c.tau_ref_s.to_bits(), c.t_ref_c.to_bits(), c.activation_k.to_bits())
    });
    let on = u32::from(e.sensor_lag.is_some())
        | u32::from(e.bias_branch_hysteresis.is_some()) << 1
        | u32::from(e.bias_creep.is_some()) << 2;
    [
        on,
        lag,
        half,
        weight,
        gain,
        tau,
        t_ref,
        act,
        m.bias.t_start_c.to_bits(),
        m.bias.t_step_c.to_bits(),
        m.bias.heating_g.len() as u32,
    ]
}

impl AxisState {
    /// This state carried from the table `old` into the reloaded table `new`.
    ///
    /// The states are temperatures of the unit's own history (the element's, the play
    /// operator's, the creep's) and the branch is the direction it was last seen moving:
    /// none of them belongs to a table. A slot whose parameters and bias grid are the same
    /// in both tables keeps its state, so reloading the table in force changes nothing; when
    /// any slot or the range changed, the three states restart from the next temperature,
    /// as at power-up, and are [`settling`](Self::settling) until they have converged (play
    /// and creep follow the element temperature the lag gives, so a changed lag moves them
    /// too). The branch is kept.
    #[must_use]
    pub fn carried_over(self, old: &AxisModel, new: &AxisModel) -> Self {
        if !self.initialized {
            return Self::default();
        }
        // Any change restarts the three history states, which then say so.
        // Compared word by word: `==` on the arrays links a 116-B memcmp.
        let same = history_bits(old).iter().zip(history_bits(new)).all(|(a, b)| *a == b);
        let restart = if same { self.restart } else { RESTART };
        // The mutant restarts every state on any reload, silently (as before the fix).
        #[cfg(qfa_mutant = "reload_drops_state")]
        let restart = RESTART | RESTART_SILENTLY;
        Self { restart, ..self }
    }

    /// A history state may still be off by more than [`SETTLED_LAG_C`] (lag) or its bias
    /// term by more than `settled_g` (play, creep: the grid's
    /// [`settled_within_g`](BiasGrid::settled_within_g)).
    #[must_use]
    pub fn settling(&self, settled_g: f32) -> bool {
        self.lag_unknown_c > SETTLED_LAG_C || self.play_unknown_g > settled_g || self.creep_unknown_g > settled_g
    }
}

/// The model evaluated at one temperature sample.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Evaluation {
    /// Scale factor, pulses/(g·s).
    pub k1: f32,
    /// Bias, g.
    pub k0: f32,
    /// Temperature was outside the calibrated range and was clamped.
    pub temp_clamped: bool,
    /// |Ṫ| exceeded the calibrated limit and was clamped.
    pub rate_clamped: bool,
    /// A history state is still settling ([`AxisState::settling`]).
    pub settling: bool,
}

/// `1 − exp(−dt/τ)`: the first-order lag's step weight, exact for a held input.
fn lag_weight(dt_s: f32, tau_s: f32) -> f32 {
    1.0 - libm::expf(-dt_s / tau_s)
}

fn abs(x: f32) -> f32 {
    libm::fabsf(x)
}

/// The larger of two finite values. `f32::max` is a call to `fmaxf` on the Cortex-M4F (it
/// has no `vmaxnm`), about 17 instructions where a compare and a select take 3; for finite
/// operands the two agree bit for bit (a ±0 tie aside, which no caller compares by sign).
pub(crate) fn larger(a: f32, b: f32) -> f32 {
    if a > b {
        a
    } else {
        b
    }
}

/// `x` held to `[lo, hi]`, and whether it was moved. The flag is read off the result (one
/// compare) rather than from the two range tests again: the compiler repeated both for it,
/// about 20 instructions a call on the M4F against 13. The inputs are finite (temperatures
/// and rates from integer readings), so "moved" is "differs".
fn clamp(x: f32, lo: f32, hi: f32) -> (f32, bool) {
    let held = if x < lo {
        lo
    } else if x > hi {
        hi
    } else {
        x
    };
    (held, held != x)
}

impl AxisModel {
    /// Advance `state` by `dt_s` seconds to sensor temperature `t_c` and rate `rate`
    /// (°C/min), and evaluate K1 and K0.
    ///
    /// Order: clamp Ṫ to the calibrated limit; the element temperature Te follows T, as
    /// read, through `sensor_lag` (Te = T when off); the branch follows Ṫ; play and creep
    /// states follow Te; then Te is held to the calibrated range for the evaluation, and the
    /// creep's Te − x to the range's span (flagged `temp_clamped` when T or Te is outside
    /// the range or Te − x past its span);
    /// K1 = Eq. 11 at (Te, Ṫ); K0 = grid(Te, branch) + play term + creep term. The states
    /// are not held to the calibrated range: they are the unit's, and the unit does not stop
    /// at the range's edge (only at the −60…130 °C any table may describe, which holds every
    /// DS18B20 reading). On the first call (or after [`AxisState::default`]) every state starts at T.
    pub fn evaluate(&self, state: &mut AxisState, t_c: f32, rate: f32, dt_s: f32) -> Evaluation {
        self.evaluate_with_deadband(state, t_c, rate, dt_s, self.bias.deadband_c_per_min)
    }

    /// [`evaluate`](Self::evaluate) with the branch deadband `deadband` (°C/min) in place
    /// of the table's: the compensator passes the larger of the table's and the flicker
    /// floor of its rate window and sample period
    /// ([`crate::rate::flicker_deadband_c_per_min`]).
    pub fn evaluate_with_deadband(
        &self,
        state: &mut AxisState,
        t_c: f32,
        rate: f32,
        dt_s: f32,
        deadband: f32,
    ) -> Evaluation {
        let step = self.advance(state, t_c, rate, dt_s, deadband);
        let (te, r) = (step.element_c, step.rate_c_per_min);
        let k1 = self.scale.k1(te, r);
        // Before a decisive rate the branch is unknown: the mean of the two, within half
        // their difference of either, which settling counts.
        let (mut k0, branch_unknown_g) = self.bias.k0_and_doubt(te, state.branch);
        if let Some(h) = self.ext.bias_branch_hysteresis {
            // Te ± r rounds to Te's ulp, so the fraction can reach 1.0002 with the smallest
            // half-width: held to ±1, the term never exceeds its weight.
            let fraction = (te - state.play_c) / h.half_width_c;
            k0 += h.weight_g * fraction.clamp(-1.0, 1.0);
        }
        if let Some(c) = self.ext.bias_creep {
            // Te − x, held to the grid's span (`advance`, flagged when it is).
            k0 += c.gain_g_per_c * step.creep_gap_c;
        }
        let settled_g = self.bias.settled_within_g();
        let settling = state.settling(settled_g) || branch_unknown_g > settled_g;
        #[cfg(qfa_mutant = "settling_never_flagged")]
        let settling = false;
        Evaluation { k1, k0, temp_clamped: step.temp_clamped, rate_clamped: step.rate_clamped, settling }
    }

    /// The state step of [`evaluate_with_deadband`](Self::evaluate_with_deadband) alone:
    /// clamp Ṫ, step the element temperature, the branch, the play and the creep states
    /// (and their doubts), then hold Te to the range, exactly as it does, without forming K1, K0 or the
    /// settling flag. For replays that read the states only (the lab's search over lags,
    /// play widths and creep times reads Te and the play and creep states of a model at
    /// unit gains, about half the work of a whole evaluation).
    #[inline]
    pub fn advance(&self, state: &mut AxisState, t_c: f32, rate: f32, dt_s: f32, deadband: f32) -> Advanced {
        let (lo, hi) = (self.bias.t_start_c, self.bias.t_end_c());
        let lim = self.rate_limit_c_per_min;
        let (r, rate_clamped) = clamp(rate, -lim, lim);
        if !state.initialized {
            state.initialized = true;
            state.branch = Branch::Unknown;
            state.restart = RESTART;
        }
        // The states are the unit's: the element follows the case wherever it goes, past the
        // calibrated range too, and the play and creep follow the element. Only the model's
        // evaluation is held to the range (and flagged). Clamping the temperature before the
        // lag, as this did before, left the element at the range's edge while the unit was
        // beyond it, and reported it right as soon as the case came back.
        // Held to the temperatures a table may describe, which hold every DS18B20 reading
        // (the decoder refuses others): the states stay finite, and so does the creep's τ,
        // whatever a caller passes.
        #[cfg(not(qfa_mutant = "clamp_before_state_update"))]
        let t = clamp(t_c, STATE_MIN_C, STATE_MAX_C).0;
        #[cfg(qfa_mutant = "clamp_before_state_update")]
        let t = clamp(t_c, lo, hi).0;
        if state.restart != 0 {
            // Started without the history (power-up, or a reload that changed the slots):
            // from the temperature now, with what the history could have made of them. The
            // element and creep states are averages of past temperatures of the unit, held to
            // −60…130 °C: no further from T than that range's farther end. (The table's rate limit times τ is no bound: the case may have moved faster
            // while the unit was off, and the oracle found such a history.) The play output
            // lies within its half-width of the element temperature, which bounds the play
            // term by its weight.
            let farther_end = larger(STATE_MAX_C - t, t - STATE_MIN_C);
            (state.element_c, state.play_c, state.creep_c) = (t, t, t);
            state.lag_unknown_c = if self.ext.sensor_lag.is_some() { farther_end } else { 0.0 };
            state.play_unknown_g = self.ext.bias_branch_hysteresis.map_or(0.0, |h| abs(h.weight_g));
            state.creep_unknown_g = self.ext.bias_creep.map_or(0.0, |c| abs(c.gain_g_per_c) * farther_end);
            #[cfg(qfa_mutant = "reload_drops_state")]
            if state.restart & RESTART_SILENTLY != 0 {
                (state.lag_unknown_c, state.play_unknown_g, state.creep_unknown_g) = (0.0, 0.0, 0.0);
            }
            state.restart = 0;
        }
        let te = match self.ext.sensor_lag {
            Some(lag) if dt_s > 0.0 => {
                let w = lag_weight(dt_s, lag.tau_s);
                state.element_c += w * (t - state.element_c);
                state.lag_unknown_c *= 1.0 - w;
                state.element_c
            }
            Some(_) => state.element_c,
            None => t,
        };
        state.branch = state.branch.next(r, deadband);
        if let Some(h) = self.ext.bias_branch_hysteresis {
            let lo = te - h.half_width_c;
            let hi = te + h.half_width_c;
            let before = state.play_c;
            state.play_c = clamp(state.play_c, lo, hi).0;
            let g_per_c = abs(h.weight_g) / h.half_width_c;
            let shrunk =
                larger(state.play_unknown_g - abs(state.play_c - before) * g_per_c, state.lag_unknown_c * g_per_c);
            // Two plays lie within their half-widths of their elements, so their positions
            // differ by at most twice the half-width plus the elements' difference: the
            // doubt never exceeds that, whatever the lag's doubt was when it started.
            let most = (2.0 * h.half_width_c + state.lag_unknown_c) * g_per_c;
            state.play_unknown_g = if shrunk < most { shrunk } else { most };
        }
        // The model is evaluated within its range: at the element temperature held to it,
        // flagged while the case (the reading) or the element is outside, or while the
        // creep's Te − x is past the range's span (the term is held there: `evaluate`).
        let (te_held, element_clamped) = clamp(te, lo, hi);
        let (mut creep_gap_c, mut creep_held) = (0.0, false);
        if let Some(c) = self.ext.bias_creep {
            if dt_s > 0.0 {
                let w = lag_weight(dt_s, c.tau_s(te));
                state.creep_c += w * (te - state.creep_c);
                state.creep_unknown_g =
                    (1.0 - w) * state.creep_unknown_g + w * abs(c.gain_g_per_c) * state.lag_unknown_c;
            }
            // Held to the range's span, so the term stays within its gain times that span,
            // which validation bounds; the state itself may lie outside, where the unit was.
            (creep_gap_c, creep_held) = clamp(te_held - state.creep_c, lo - hi, hi - lo);
        }
        let temp_clamped = creep_held
            | match self.ext.sensor_lag {
                // Without a lag Te is T held to −60…130 °C, which holds the grid (validation):
                // held to the grid too, it differs from T exactly when T is outside (one compare
                // where the reading's own range test took four).
                None => te_held != t_c,
                Some(_) => element_clamped | (t_c < lo) | (t_c > hi),
            };
        Advanced { element_c: te_held, rate_c_per_min: r, temp_clamped, rate_clamped, creep_gap_c }
    }
}

/// One state step of a model ([`AxisModel::advance`]): the clamped inputs it stepped on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Advanced {
    /// Element temperature Te after the step, held to the calibrated range, °C (T when
    /// `sensor_lag` is off): what the model is evaluated at.
    pub element_c: f32,
    /// Ṫ clamped to the table's rate limit, °C/min.
    pub rate_c_per_min: f32,
    /// T or Te was outside the calibrated range (the evaluation held to it), or the creep's
    /// Te − x past its span.
    pub temp_clamped: bool,
    /// |Ṫ| exceeded the calibrated limit and was clamped.
    pub rate_clamped: bool,
    /// The creep's Te − x, °C, held to the grid's span (`temp_clamped` when it was); 0
    /// without a creep slot.
    pub creep_gap_c: f32,
}

#[cfg(test)]
mod tests;
