//! The oracle: what the compensator should output, from the **true** temperature history.
//!
//! Independent of `src/` beyond the table's data (the [`Table`] struct it reads the
//! coefficients from): every model slot is written here in f64 from its documented
//! definition (`docs/firmware.md`, the rustdoc of `qfa_thermal::model`), and every estimate
//! is formed from the true temperatures at the instants the sensors were read, not from
//! the readings. So a firmware that is self-consistent but wrong (a state dropped, a branch
//! chosen on noise, a set never copied) departs from it.
//!
//! # The ideal, and what a correct firmware may differ by
//! At each good reading of a sensor, the ideal estimate is the least-squares line through
//! the *true* temperatures at the window's reading instants (the documented filter: the
//! last 32 readings, restarted after a gap over 30 s): its value at the newest instant is
//! T̂, its slope Ṫ. The model (clamps, sensor lag, branch with deadband, Eq. 11, bias grid,
//! play, creep) runs on them; K1 and K0 hold until the sensor's next good reading.
//!
//! The firmware sees readings instead: the true temperature quantized to 1/16 °C, one LSB
//! either way near a code edge (flicker). The harness knows each reading's error eᵢ (it
//! made the reading), so the line's value and slope move by exactly `Σ vᵢ·eᵢ` and
//! `Σ wᵢ·eᵢ`, where vᵢ and wᵢ are the least-squares weights of the value at the newest
//! instant and of the slope: the realized quantization, not a worst case (which, at
//! 1.6 LSB on T̂ and 0.35 °C/min on Ṫ for 32 readings, would hide a one-reading delay).
//! Their magnitudes, plus 10⁻⁴ for the firmware's f32 line, are carried through the model
//! by [`Bound`]: the lag and creep states are weighted means of their inputs, so their
//! error is the same weighted mean of the input errors; the play operator never widens a
//! difference; Eq. 11 and the grid are bounded by their first and second derivatives.
//! The branch is a set: while the ideal rate is within its error of a deadband edge,
//! either side may be in force, and the bias may be any of the possible branches'. f32
//! arithmetic adds 2·10⁻⁶ relative on K1 and Δv. The total is the tolerance per cycle.
//!
//! A cycle is silently wrong when its status is OK and its output is further from the
//! ideal than that tolerance.

use std::collections::VecDeque;

use qfa_thermal::model::AxisModel;
use qfa_thermal::table::Table;

/// Standard gravity, m/s² (the firmware's `G0`, spelled here).
pub const G0: f64 = 9.806_65;
/// One DS18B20 LSB at 12 bits, °C.
pub const LSB_C: f64 = 0.0625;
const WINDOW: usize = 32;
const MIN_SAMPLES: usize = 8;
const MAX_GAP_MS: i64 = 30_000;
/// f32 arithmetic on K1, K0 and Δv: a few ulps of each, relative (2⁻²³ ≈ 1.2·10⁻⁷).
const F32_REL: f64 = 2e-6;

/// The possible bias branches: the ideal's, and every other one the firmware's noisier rate
/// may have chosen since.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Branches {
    /// The mean of both branches (no decisive rate yet).
    pub unknown: bool,
    /// Heating.
    pub heating: bool,
    /// Cooling.
    pub cooling: bool,
}

/// An error bound carried with a state, °C.
#[derive(Clone, Copy, Debug, Default)]
struct Bound {
    value: f64,
    err: f64,
}

#[derive(Clone, Copy, Debug, Default)]
struct AxisIdeal {
    init: bool,
    element: Bound,
    play: Bound,
    creep: Bound,
}

/// The ideal of one axis as of its sensor's last good reading.
#[derive(Clone, Copy, Debug, Default)]
pub struct Ideal {
    /// K1, pulses/(g·s).
    pub k1: f64,
    /// Largest |ΔK1| a correct firmware may show.
    pub k1_tol: f64,
    /// K0, g.
    pub k0: f64,
    /// Largest |ΔK0| a correct firmware may show, g.
    pub k0_tol: f64,
}

/// One sensor's window of good readings: (unwrapped ms, true °C, reading − truth °C).
#[derive(Clone, Debug, Default)]
struct Window {
    readings: VecDeque<(i64, f64, f64)>,
    last_good_ms: Option<i64>,
}

/// The firmware forms T̂ and Ṫ in f32 from exact integer sums: within 10⁻⁴ of its f64 line.
const F32_LINE: f64 = 1e-4;

impl Window {
    /// Add a good reading; the elapsed ms since the previous good one (`None` for the
    /// first). A gap over 30 s restarts the window.
    fn push(&mut self, t_ms: i64, temp_c: f64, err_c: f64) -> Option<i64> {
        let dt = self.last_good_ms.map(|p| t_ms - p);
        if dt.is_some_and(|d| d > MAX_GAP_MS) {
            self.readings.clear();
        }
        if self.readings.len() == WINDOW {
            self.readings.pop_front();
        }
        self.readings.push_back((t_ms, temp_c, err_c));
        self.last_good_ms = Some(t_ms);
        dt
    }

    /// (T̂, Ṫ °C/min, |ΔT̂|, |ΔṪ| °C/min, ready) of the least-squares line at the newest
    /// instant, the differences being what the readings' errors make of it. Before
    /// `MIN_SAMPLES` readings (the firmware flags the rate not ready) the documented
    /// estimate is the newest reading and Ṫ = 0; `None` before any reading.
    fn line(&self) -> Option<(f64, f64, f64, f64, bool)> {
        let n = self.readings.len();
        if n < MIN_SAMPLES {
            return self.readings.back().map(|r| (r.1, 0.0, r.2.abs() + F32_LINE, 0.0, false));
        }
        let nf = n as f64;
        let tbar = self.readings.iter().map(|r| r.0 as f64).sum::<f64>() / nf;
        let ybar = self.readings.iter().map(|r| r.1).sum::<f64>() / nf;
        let s: f64 = self.readings.iter().map(|r| (r.0 as f64 - tbar).powi(2)).sum();
        let sty: f64 = self.readings.iter().map(|r| (r.0 as f64 - tbar) * (r.1 - ybar)).sum();
        let slope_per_ms = sty / s;
        let lever = self.readings.back().map_or(0.0, |r| r.0 as f64) - tbar;
        let value = ybar + slope_per_ms * lever;
        // value = Σ vᵢ yᵢ with vᵢ = 1/n + lever·(tᵢ − t̄)/S; slope = Σ wᵢ yᵢ, wᵢ = (tᵢ − t̄)/S.
        let d_value: f64 = self.readings.iter().map(|r| (1.0 / nf + lever * (r.0 as f64 - tbar) / s) * r.2).sum();
        let d_slope: f64 = self.readings.iter().map(|r| (r.0 as f64 - tbar) / s * r.2).sum();
        Some((value, slope_per_ms * 60_000.0, d_value.abs() + F32_LINE, d_slope.abs() * 60_000.0 + F32_LINE, true))
    }
}

/// One table's running states for every axis, from the whole history.
#[derive(Clone, Debug)]
struct Track {
    table: Table,
    axes: Vec<AxisIdeal>,
}

/// The ideal compensator for `AXES` axes, one sensor per axis (sensor i serves axis i).
///
/// It knows every table the history will load and runs each one's states over the whole
/// history, the time before power-up included ([`Oracle::before_power_up`]): the ideal after
/// a load is the loaded table's model as if it had been in force all along, which is what
/// the unit's physics gives. The firmware cannot know that history; it must say so
/// (`MODEL_SETTLING`) until its own states are within the documented thresholds, which the
/// tolerance then includes.
#[derive(Clone, Debug)]
pub struct Oracle {
    tracks: Vec<Track>,
    current: Option<usize>,
    windows: Vec<Window>,
    /// Per axis: the branch of the true rates, and every branch the firmware may hold.
    branch: Vec<(i8, Branches)>,
    ideal: Vec<Option<Ideal>>,
    /// The compensator's smallest branch deadband, °C/min.
    deadband_floor: f64,
    tick_s: f64,
}

/// The firmware's settling thresholds (`model::SETTLED_LAG_C`, and a quarter of the grid's
/// `residual_rms_g` for bias terms), spelled from its docs: what a state it no longer flags
/// may still be off by.
const SETTLED_LAG_C: f64 = 1.0 / 64.0;
fn settled_bias_g(m: &AxisModel) -> f64 {
    0.25 * f64::from(m.bias.residual_rms_g)
}

/// The flicker floor of a window of `n` readings at 1 s, from its derivation in the
/// firmware's docs (`rate::flicker_deadband_c_per_min`, `RateWindow::flicker_floor`):
/// σ = 60·q/(2·√S), times √(2·ln(M/α)) for M = 3 600 readings and α = 1 %.
fn flicker_floor(n: usize) -> f64 {
    let mid = (n as f64 - 1.0) / 2.0;
    let s: f64 = (0..n).map(|i| (i as f64 - mid).powi(2)).sum();
    60.0 * LSB_C / (2.0 * s.sqrt()) * (2.0 * (3600.0f64 / 0.01).ln()).sqrt()
}

fn interp(values: &[f32], start: f64, step: f64, t: f64) -> f64 {
    let x = ((t - start) / step).max(0.0);
    let i = (x.floor() as usize).min(values.len() - 2);
    let (a, b) = (f64::from(values[i]), f64::from(values[i + 1]));
    a + (b - a) * (x - i as f64).min(1.0)
}

/// Largest |slope| of a branch's grid: bounds |ΔK0| per °C of Te error.
fn grid_slope(values: &[f32], step: f64) -> f64 {
    values.windows(2).map(|w| (f64::from(w[1]) - f64::from(w[0])).abs() / step).fold(0.0, f64::max)
}

fn arrhenius_tau(c: &qfa_thermal::model::Creep, te: f64) -> f64 {
    f64::from(c.tau_ref_s)
        * (f64::from(c.activation_k) * (1.0 / (te + 273.15) - 1.0 / (f64::from(c.t_ref_c) + 273.15))).exp()
}

/// The temperature line a model step takes: T̂, Ṫ and their error bounds.
#[derive(Clone, Copy, Debug)]
struct Line {
    t: f64,
    #[allow(dead_code)]
    rate: f64,
    err_t: f64,
    err_rate: f64,
}

/// Advance one axis's states under `m` by `dt_s` to the line `l`; (Te bound, play and
/// creep terms' tolerance contributions). States start at the first line.
fn step_states(m: &AxisModel, a: &mut AxisIdeal, l: Line, dt_s: f64) -> Bound {
    // The states follow the temperature as read, never clamped: the unit does not stop at
    // the calibrated range's edge (the evaluation holds Te to it).
    let t = l.t.clamp(-60.0, 130.0);
    let start = Bound { value: t, err: l.err_t };
    if !a.init {
        *a = AxisIdeal { init: true, element: start, play: start, creep: start };
    }
    let te = match m.ext.sensor_lag {
        Some(lag) => {
            if dt_s > 0.0 {
                let w = 1.0 - (-dt_s / f64::from(lag.tau_s)).exp();
                a.element.value += w * (t - a.element.value);
                a.element.err = (1.0 - w) * a.element.err + w * l.err_t;
            }
            a.element
        }
        None => start,
    };
    if let Some(p) = m.ext.bias_branch_hysteresis {
        let half = f64::from(p.half_width_c);
        a.play.value = a.play.value.clamp(te.value - half, te.value + half);
        // The play operator never widens the difference of two inputs or two states.
        a.play.err = a.play.err.max(te.err);
    }
    if let Some(cr) = m.ext.bias_creep {
        if dt_s > 0.0 {
            let tau = arrhenius_tau(&cr, te.value);
            let w = 1.0 - (-dt_s / tau).exp();
            // τ itself moves with Te's error: |∂w/∂Te| ≤ (dt/τ)·E/(Te + 273.15)².
            let dw = (dt_s / tau) * f64::from(cr.activation_k).abs() * te.err / (te.value + 273.15).powi(2);
            let gap = (te.value - a.creep.value).abs();
            a.creep.value += w * (te.value - a.creep.value);
            a.creep.err = (1.0 - w) * a.creep.err + w * te.err + dw * gap;
        }
    }
    te
}

impl Oracle {
    /// An oracle for `axes` axes and the tables `tables` (the history loads them by index),
    /// with the fast path's tick of `tick_s`. No table is in force until [`load`](Self::load).
    #[must_use]
    pub fn new(axes: usize, tables: &[Table], tick_s: f64) -> Self {
        Self {
            tracks: tables.iter().map(|t| Track { table: t.clone(), axes: vec![AxisIdeal::default(); axes] }).collect(),
            current: None,
            windows: vec![Window::default(); axes],
            branch: vec![(0, Branches { unknown: true, ..Branches::default() }); axes],
            ideal: vec![None; axes],
            deadband_floor: flicker_floor(WINDOW),
            tick_s,
        }
    }

    /// The history before power-up of sensor `sensor`: (ms on the readings' time line,
    /// true °C, true °C/min) at each step. The states follow it exactly (no readings, no
    /// error); the firmware starts at power-up knowing none of it.
    pub fn before_power_up(&mut self, sensor: usize, steps: &[(i64, f64, f64)]) {
        for &(t_ms, temp, rate) in steps {
            let dt_s = self.windows[sensor].last_good_ms.map_or(0.0, |p| (t_ms - p) as f64 * 1e-3);
            // The window stays empty (the firmware has no reading); only its clock moves, so
            // the first reading advances the states by the time since the last step.
            self.windows[sensor].last_good_ms = Some(t_ms);
            let l = Line { t: temp, rate, err_t: 0.0, err_rate: 0.0 };
            for tr in &mut self.tracks {
                step_states(&tr.table.axes[sensor], &mut tr.axes[sensor], l, dt_s);
            }
            let lim = f64::from(self.tracks[0].table.axes[sensor].rate_limit_c_per_min);
            let db = f64::from(self.tracks[0].table.axes[sensor].bias.deadband_c_per_min).max(self.deadband_floor);
            let r = rate.clamp(-lim, lim);
            if r > db {
                self.branch[sensor].0 = 1;
            } else if r < -db {
                self.branch[sensor].0 = -1;
            }
        }
    }

    /// Table `k` was accepted.
    pub fn load(&mut self, k: usize) {
        self.current = Some(k);
        for i in 0..self.windows.len() {
            self.evaluate(i, 0.0);
        }
    }

    /// A good reading of sensor `sensor` at unwrapped `t_ms`, whose true temperature is
    /// `true_c`, read as `read_c`.
    pub fn reading(&mut self, sensor: usize, t_ms: i64, true_c: f64, read_c: f64) {
        let dt_ms = self.windows[sensor].push(t_ms, true_c, read_c - true_c);
        // Across a gap the states advance by the whole elapsed time, as in the firmware.
        let dt_s = dt_ms.map_or(0.0, |ms| ms as f64 * 1e-3);
        self.evaluate(sensor, dt_s);
    }

    fn evaluate(&mut self, i: usize, dt_s: f64) {
        let Some((t_hat, rate, err_t, err_rate, ready)) = self.windows[i].line() else {
            self.ideal[i] = None;
            return;
        };
        let line = Line { t: t_hat, rate, err_t, err_rate };
        let mut te_now = None;
        for (k, tr) in self.tracks.iter_mut().enumerate() {
            let te = step_states(&tr.table.axes[i], &mut tr.axes[i], line, dt_s);
            if Some(k) == self.current {
                te_now = Some(te);
            }
        }
        let (Some(k), Some(te)) = (self.current, te_now) else {
            self.ideal[i] = None;
            return;
        };
        let m: &AxisModel = &self.tracks[k].table.axes[i];
        let a = self.tracks[k].axes[i];
        let d_r = line.err_rate;
        let lim = f64::from(m.rate_limit_c_per_min);
        // Clamps never widen a difference.
        let r = rate.clamp(-lim, lim);
        // The branch: the ideal's from the ideal rate; the firmware's may be any branch its
        // rate (within d_r of the ideal) could have chosen since the last decisive rate.
        // The floor of the window as filled now (its full floor once full).
        let n = self.windows[i].readings.len();
        let db = f64::from(m.bias.deadband_c_per_min).max(flicker_floor(n).max(self.deadband_floor));
        let (ideal_branch, branches) = &mut self.branch[i];
        if r > db {
            *ideal_branch = 1;
        } else if r < -db {
            *ideal_branch = -1;
        }
        if r - d_r > db {
            *branches = Branches { heating: true, ..Branches::default() };
        } else if r + d_r < -db {
            *branches = Branches { cooling: true, ..Branches::default() };
        } else {
            branches.heating |= r + d_r > db;
            branches.cooling |= r - d_r < -db;
        }
        let (ideal_branch, branches) = (*ideal_branch, *branches);
        // Not yet settled in the firmware's terms: what an unflagged state may still be off by.
        let dte = te.err + if m.ext.sensor_lag.is_some() { SETTLED_LAG_C } else { 0.0 };
        // Evaluated at Te held to the range (which never widens a difference).
        let te = Bound { value: te.value.clamp(f64::from(m.bias.t_start_c), f64::from(m.bias.t_end_c())), err: te.err };
        let sf = &m.scale;
        let d = te.value - f64::from(sf.t0_c);
        let (al, be, et, ep, mu) =
            (f64::from(sf.alpha), f64::from(sf.beta), f64::from(sf.eta), f64::from(sf.epsilon), f64::from(sf.mu));
        let k1 = al * r * r + be * d * d + et * r * d + ep * r + mu * d + f64::from(sf.gamma);
        // |ΔK1| ≤ |∂K1/∂T|·δT + |∂K1/∂r|·δr + ½·Σ|H|·δδ (Eq. 11 is quadratic: exact bound).
        let dr = d_r.min(2.0 * lim);
        let k1_tol = (2.0 * be * d + et * r + mu).abs() * dte
            + (2.0 * al * r + et * d + ep).abs() * dr
            + al.abs() * dr * dr
            + be.abs() * dte * dte
            + et.abs() * dte * dr
            + F32_REL * k1.abs();
        let lo = f64::from(m.bias.t_start_c);
        let step = f64::from(m.bias.t_step_c);
        let h = interp(&m.bias.heating_g, lo, step, te.value);
        let c = interp(&m.bias.cooling_g, lo, step, te.value);
        let of_branch = |b: i8| match b {
            1 => h,
            -1 => c,
            _ => 0.5 * (h + c),
        };
        let mut k0 = of_branch(ideal_branch);
        let mut branch_tol = 0.0f64;
        for (possible, b) in [(branches.unknown, 0i8), (branches.heating, 1), (branches.cooling, -1)] {
            if possible {
                branch_tol = branch_tol.max((of_branch(b) - k0).abs());
            }
        }
        let slope = grid_slope(&m.bias.heating_g, step).max(grid_slope(&m.bias.cooling_g, step));
        let mut k0_tol = branch_tol + slope * dte;
        if let Some(p) = m.ext.bias_branch_hysteresis {
            let half = f64::from(p.half_width_c);
            k0 += f64::from(p.weight_g) * ((te.value - a.play.value) / half).clamp(-1.0, 1.0);
            k0_tol += f64::from(p.weight_g).abs() * (dte + a.play.err) / half + settled_bias_g(m);
        }
        if let Some(cr) = m.ext.bias_creep {
            k0 += f64::from(cr.gain_g_per_c) * (te.value - a.creep.value);
            k0_tol += f64::from(cr.gain_g_per_c).abs() * (dte + a.creep.err) + settled_bias_g(m);
        }
        k0_tol += F32_REL * k0.abs() + 1e-9;
        self.ideal[i] = ready.then_some(Ideal { k1, k1_tol, k0, k0_tol });
    }

    /// The ideal of axis `i`, or `None` where the firmware must not report OK (no table, or
    /// fewer than 8 readings in the sensor's window).
    #[must_use]
    pub fn ideal(&self, i: usize) -> Option<Ideal> {
        self.ideal[i]
    }

    /// The ideal specific force (m/s²) of axis `i` for the sample `raw` (LSB), with its
    /// tolerance: `a = raw·g0/K1 − K0·g0`.
    #[must_use]
    pub fn accel(&self, i: usize, raw: i64) -> Option<(f64, f64)> {
        let id = self.ideal[i]?;
        let n = raw as f64;
        let a = n * G0 / id.k1 - id.k0 * G0;
        let tol = n.abs() * G0 * id.k1_tol / (id.k1 * (id.k1 - id.k1_tol))
            + id.k0_tol * G0
            + F32_REL * (n.abs() * G0 / id.k1 + id.k0.abs() * G0);
        Some((a, tol))
    }

    /// The ideal Δv (m/s) of axis `i` for `pulses` over `dt_ticks`, with its tolerance.
    #[must_use]
    pub fn dv(&self, i: usize, pulses: i64, dt_ticks: u32) -> Option<(f64, f64)> {
        let id = self.ideal[i]?;
        let n = pulses as f64;
        let dt_s = f64::from(dt_ticks) * self.tick_s;
        let dv = n * G0 / id.k1 - id.k0 * G0 * dt_s;
        // |Δ(N/K1)| ≤ |N|·δK1/(K1·(K1 − δK1)).
        let tol = n.abs() * G0 * id.k1_tol / (id.k1 * (id.k1 - id.k1_tol))
            + id.k0_tol * G0 * dt_s
            + F32_REL * (n.abs() * G0 / id.k1 + id.k0.abs() * G0 * dt_s);
        Some((dv, tol))
    }
}
