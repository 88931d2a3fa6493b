//! Independent f64 implementation of the compensator's equations, for checking the vectors.
//!
//! Written from the equations (paper Eq. 5 and 11, the bias grid, the three extension
//! slots, least squares over the window, the plausibility rules), not from the f32 code:
//! the least-squares slope is a direct centred sum over the window, timestamps are
//! unwrapped to i64, and every quantity is f64. Only the table's wire decoding is shared
//! (`Table::decode`), since the format itself is pinned by the exact-bytes test.
//!
//! Tolerances used by `tests/vectors.rs` ([`Tolerance`]) are stated there with reasons.

use std::collections::VecDeque;

use qfa_thermal::model::AxisModel;
use qfa_thermal::table::Table;

const G0: f64 = 9.806_65;
const TICK_S: f64 = 1e-6;
const STALE_AFTER: u64 = 3_000_000;
const WINDOW: usize = 32;
const MIN_SAMPLES: usize = 8;
const MAX_GAP_MS: i64 = 30_000;
const MAX_STEP: i64 = 16;
const MAX_SLEW_PER_MIN: i64 = 160;
const CONFIRM: u32 = 3;
/// `stale_after_ticks · tick`, ms.
const STALE_MS: i64 = 3_000;
/// The DS18B20's range, −55…+125 °C, in 1/16 °C.
const RAW_MIN: i64 = -55 * 16;
const RAW_MAX: i64 = 125 * 16;
/// `Config::default().nominal_k1`: the pass-through scale with no table, pulses/(g·s).
const NOMINAL_K1: f64 = 320_000.0;
/// `Config::default().imu_period_s` (2.5 ms) in 1-µs ticks.
const IMU_PERIOD_TICKS: u64 = 2_500;

/// Status bits, spelled from the documented flag list rather than imported.
pub mod flag {
    /// No fresh temperature.
    pub const TEMP_STALE: u16 = 1 << 0;
    /// Latest reading rejected.
    pub const TEMP_INVALID: u16 = 1 << 1;
    /// Rate not ready.
    pub const RATE_NOT_READY: u16 = 1 << 2;
    /// Temperature clamped.
    pub const TEMP_OUT_OF_RANGE: u16 = 1 << 3;
    /// Rate clamped.
    pub const RATE_OUT_OF_RANGE: u16 = 1 << 4;
    /// No table.
    pub const NO_TABLE: u16 = 1 << 5;
    /// No counter base.
    pub const NO_COUNTER_BASE: u16 = 1 << 6;
    /// Fast-path entry of the other input kind than configured (pulse counts by default).
    pub const WRONG_INPUT: u16 = 1 << 7;
    /// A history state (lag, play, creep) started without the history, not yet settled.
    pub const MODEL_SETTLING: u16 = 1 << 8;
    /// The cycle's length is more than 4× off the configured IMU period.
    pub const DT_IMPLAUSIBLE: u16 = 1 << 9;
}
use flag as Status;

/// Result codes, spelled independently of `qfa_replay`'s mapping.
pub mod code {
    /// Scratchpad all FFh.
    pub const BUS_ALL_ONES: u32 = 0x11;
    /// Scratchpad all zero.
    pub const ALL_ZERO: u32 = 0x12;
    /// CRC mismatch.
    pub const CRC: u32 = 0x13;
    /// Reserved bytes.
    pub const RESERVED: u32 = 0x14;
    /// Config byte.
    pub const CONFIG: u32 = 0x15;
    /// Decoder's power-on rule.
    pub const POWER_ON: u32 = 0x16;
    /// Outside −55…+125 °C.
    pub const OUT_OF_RANGE: u32 = 0x17;
    /// Time not after previous.
    pub const TIME: u32 = 0x21;
    /// 0550h as a jump.
    pub const POWER_ON_JUMP: u32 = 0x22;
    /// Implausible jump.
    pub const IMPLAUSIBLE: u32 = 0x23;
}

/// What the reference predicts for one event line.
#[derive(Clone, Debug, PartialEq)]
pub enum Predicted {
    /// Table load: `Some(())` accepted, `None` refused (any error).
    Table(bool),
    /// Sample accepted.
    SampleOk {
        /// Status word.
        status: u16,
        /// T̂, °C.
        temp: f64,
        /// Ṫ, °C/min.
        rate: f64,
        /// K1 per axis.
        k1: [f64; 3],
        /// K0 per axis.
        k0: [f64; 3],
    },
    /// Sample refused.
    SampleErr {
        /// Result code.
        code: u32,
        /// Status word.
        status: u16,
    },
    /// IMU cycle.
    Cycle {
        /// Status word.
        status: u16,
        /// Δv per axis, m/s.
        dv: [f64; 3],
    },
}

#[derive(Clone, Copy, Default)]
struct AxisRef {
    init: bool,
    /// Slots to restart at the next evaluation: 1 lag, 2 play, 4 creep.
    restart: u8,
    branch: i8, // 0 unknown, 1 heating, -1 cooling
    te: f64,
    play: f64,
    creep: f64,
    /// How far each state may be from the whole history's (the documented settling rule).
    lag_unknown: f64,
    play_unknown: f64,
    creep_unknown: f64,
}

/// The documented thresholds of `MODEL_SETTLING`: a quarter LSB for the lag; for the play,
/// creep and branch terms a quarter of the grid's recorded fit residual.
const SETTLED_LAG_C: f64 = 1.0 / 64.0;

/// The documented reload rule: with the same slots and grid range every state is kept;
/// otherwise the three history states restart (and settle again); the branch is kept.
fn carried_over(s: AxisRef, old: &AxisModel, new: &AxisModel) -> AxisRef {
    if !s.init {
        return AxisRef::default();
    }
    let range = |m: &AxisModel| (m.bias.t_start_c, m.bias.t_end_c());
    let restart = if range(old) == range(new) && old.ext == new.ext { s.restart } else { 7 };
    AxisRef { restart, ..s }
}

/// The f64 reference compensator (3 axes, window 32, default config).
pub struct Reference {
    table: Option<Table>,
    window: VecDeque<(i64, i64)>,
    last_abs: u32,
    last_unwrapped: i64,
    /// Newest slow-path time seen (any reading, good or rejected), unwrapped; staleness is
    /// its distance from the last good reading.
    clock: Option<(u32, i64)>,
    axes: [AxisRef; 3],
    k1: [f64; 3],
    k0: [f64; 3],
    status: u16,
    since: u64,
    last_good: Option<(i64, i64)>,
    /// (absolute ms, raw) of the last rejected reading that may start a confirmed restart.
    pending: Option<(u32, i64)>,
    pending_n: u32,
    counters: Option<[u32; 3]>,
}

impl Default for Reference {
    fn default() -> Self {
        Self::new()
    }
}

fn crc8(bytes: &[u8]) -> u8 {
    // Bit-serial Dallas/Maxim CRC from the datasheet's shift-register description.
    let mut crc = 0u8;
    for &b in bytes {
        let mut byte = b;
        for _ in 0..8 {
            let mix = (crc ^ byte) & 1;
            crc >>= 1;
            if mix != 0 {
                crc ^= 0x8C;
            }
            byte >>= 1;
        }
    }
    crc
}

/// Decode a scratchpad independently: `Ok(raw)` or an error code.
pub fn decode(sp: &[u8; 9]) -> Result<i64, u32> {
    if sp.iter().all(|&b| b == 0xFF) {
        return Err(code::BUS_ALL_ONES);
    }
    if sp.iter().all(|&b| b == 0) {
        return Err(code::ALL_ZERO);
    }
    if crc8(&sp[..8]) != sp[8] {
        return Err(code::CRC);
    }
    if sp[5] != 0xFF || sp[7] != 0x10 {
        return Err(code::RESERVED);
    }
    let drop_bits = match sp[4] {
        0x1F => 3,
        0x3F => 2,
        0x5F => 1,
        0x7F => 0,
        _ => return Err(code::CONFIG),
    };
    let raw = i64::from(i16::from_le_bytes([sp[0], sp[1]]));
    if raw == 0x0550 && sp[6] == 0x0C {
        return Err(code::POWER_ON);
    }
    let raw = (raw >> drop_bits) << drop_bits;
    if !(RAW_MIN..=RAW_MAX).contains(&raw) {
        return Err(code::OUT_OF_RANGE);
    }
    Ok(raw)
}

fn interp(values: &[f32], start: f64, step: f64, t: f64) -> f64 {
    let x = (t - start) / step;
    let i = (x.floor().max(0.0) as usize).min(values.len() - 2);
    let (a, b) = (f64::from(values[i]), f64::from(values[i + 1]));
    a + (b - a) * (x - i as f64)
}

/// The compensator's smallest branch deadband for a window holding `n` of its 32 readings
/// a second apart, °C/min, from its derivation (`qfa_thermal::rate::flicker_deadband_c_per_min`
/// and `RateWindow::flicker_floor`): the one-LSB flicker's largest rate σ = 60·q/(2·√S),
/// S = Σ(tᵢ − t̄)² over those n instants, times √(2·ln(M/α)) for M = 3600 readings and
/// α = 1 %.
fn flicker_floor(n: usize) -> f64 {
    let mid = (n as f64 - 1.0) / 2.0;
    let s: f64 = (0..n).map(|i| (i as f64 - mid).powi(2)).sum();
    let sigma = 60.0 * 0.0625 / (2.0 * s.sqrt());
    sigma * (2.0 * (3600.0f64 / 0.01).ln()).sqrt()
}

/// Evaluate one axis in f64: (K1, K0, temp clamped, rate clamped, settling).
fn eval_axis(m: &AxisModel, s: &mut AxisRef, t: f64, r: f64, dt: f64, n: usize) -> (f64, f64, bool, bool, bool) {
    let lo = f64::from(m.bias.t_start_c);
    let step = f64::from(m.bias.t_step_c);
    let hi = lo + step * (m.bias.heating_g.len() - 1) as f64;
    let tc = t.clamp(lo, hi);
    // The states follow the reading, held only to the range any table may describe.
    let t_in = t;
    let t = t.clamp(-60.0, 130.0);
    let lim = f64::from(m.rate_limit_c_per_min);
    let rc = r.clamp(-lim, lim);
    if !s.init {
        *s = AxisRef { init: true, restart: 7, ..AxisRef::default() };
    }
    let settled_g = 0.25 * f64::from(m.bias.residual_rms_g);
    if s.restart != 0 {
        // The documented bound: a state is an average of past temperatures of the unit,
        // held to -60..130 °C, so no further from T than that range's farther end. The
        // states follow T as read, held only to that range.
        let farther = (130.0 - t).max(t + 60.0);
        if s.restart & 1 != 0 {
            s.te = t;
            s.lag_unknown = if m.ext.sensor_lag.is_some() { farther } else { 0.0 };
        }
        let te0 = if m.ext.sensor_lag.is_some() { s.te } else { t };
        if s.restart & 2 != 0 {
            s.play = te0;
            s.play_unknown = m.ext.bias_branch_hysteresis.map_or(0.0, |h| f64::from(h.half_width_c));
        }
        if s.restart & 4 != 0 {
            s.creep = te0;
            s.creep_unknown = if m.ext.bias_creep.is_some() { farther } else { 0.0 };
        }
        s.restart = 0;
    }
    let te = match m.ext.sensor_lag {
        Some(l) => {
            if dt > 0.0 {
                let w = 1.0 - (-dt / f64::from(l.tau_s)).exp();
                s.te += w * (t - s.te);
                s.lag_unknown *= 1.0 - w;
            }
            s.te
        }
        None => t,
    };
    let db = f64::from(m.bias.deadband_c_per_min).max(flicker_floor(n));
    if rc > db {
        s.branch = 1;
    } else if rc < -db {
        s.branch = -1;
    }
    // The model is evaluated at Te held to the calibrated range; the states above are not.
    let te_eval = te.clamp(lo, hi);
    let sf = &m.scale;
    let d = te_eval - f64::from(sf.t0_c);
    let k1 = f64::from(sf.alpha) * rc * rc
        + f64::from(sf.beta) * d * d
        + f64::from(sf.eta) * rc * d
        + f64::from(sf.epsilon) * rc
        + f64::from(sf.mu) * d
        + f64::from(sf.gamma);
    let h = interp(&m.bias.heating_g, lo, step, te_eval);
    let c = interp(&m.bias.cooling_g, lo, step, te_eval);
    let mut k0 = match s.branch {
        1 => h,
        -1 => c,
        _ => 0.5 * (h + c),
    };
    if let Some(p) = m.ext.bias_branch_hysteresis {
        let r = f64::from(p.half_width_c);
        let before = s.play;
        s.play = s.play.clamp(te - r, te + r);
        // At most twice the half-width plus the element's doubt: both plays lie within
        // their half-widths of their elements.
        s.play_unknown = (s.play_unknown - (s.play - before).abs()).max(s.lag_unknown).min(2.0 * r + s.lag_unknown);
        // The term's fraction held to ±1, as the firmware holds it (Te held to the range may
        // be further than r from a play that followed the element beyond it).
        k0 += f64::from(p.weight_g) * ((te_eval - s.play) / r).clamp(-1.0, 1.0);
    }
    if let Some(cr) = m.ext.bias_creep {
        let tau = f64::from(cr.tau_ref_s)
            * (f64::from(cr.activation_k) * (1.0 / (te + 273.15) - 1.0 / (f64::from(cr.t_ref_c) + 273.15))).exp();
        if dt > 0.0 {
            let w = 1.0 - (-dt / tau).exp();
            s.creep += w * (te - s.creep);
            s.creep_unknown = (1.0 - w) * s.creep_unknown + w * s.lag_unknown;
        }
        k0 += f64::from(cr.gain_g_per_c) * (te_eval - s.creep).clamp(lo - hi, hi - lo);
    }
    let creep_outside = m.ext.bias_creep.is_some() && (te_eval - s.creep).abs() > hi - lo;
    let settling = (s.branch == 0 && (h - c).abs() * 0.5 > settled_g)
        || s.lag_unknown > SETTLED_LAG_C
        || m.ext
            .bias_branch_hysteresis
            .is_some_and(|h| f64::from(h.weight_g).abs() * s.play_unknown > settled_g * f64::from(h.half_width_c))
        || m.ext.bias_creep.is_some_and(|c| f64::from(c.gain_g_per_c).abs() * s.creep_unknown > settled_g);
    (k1, k0, tc != t_in || te_eval != te || creep_outside, rc != r, settling)
}

impl Reference {
    /// Fresh reference, as `Compensator::new(Config::default())`.
    #[must_use]
    pub fn new() -> Self {
        Self {
            table: None,
            window: VecDeque::new(),
            last_abs: 0,
            last_unwrapped: 0,
            clock: None,
            axes: [AxisRef::default(); 3],
            k1: [0.0; 3],
            k0: [0.0; 3],
            status: Status::NO_TABLE | Status::TEMP_STALE | Status::RATE_NOT_READY,
            since: u64::from(u32::MAX),
            last_good: None,
            pending: None,
            pending_n: 0,
            counters: None,
        }
    }

    /// (T̂, Ṫ, ready) from a direct f64 least-squares fit over the window.
    fn estimate(&self) -> (f64, f64, bool) {
        let n = self.window.len();
        if n == 0 {
            return (0.0, 0.0, false);
        }
        let newest = self.window[n - 1];
        if n < MIN_SAMPLES {
            return (newest.1 as f64 / 16.0, 0.0, false);
        }
        let nf = n as f64;
        let mt = self.window.iter().map(|s| s.0 as f64).sum::<f64>() / nf;
        let my = self.window.iter().map(|s| s.1 as f64).sum::<f64>() / nf;
        let sxy: f64 = self.window.iter().map(|s| (s.0 as f64 - mt) * (s.1 as f64 - my)).sum();
        let sxx: f64 = self.window.iter().map(|s| (s.0 as f64 - mt).powi(2)).sum();
        let slope = sxy / sxx; // raw per ms
        let fit = my + slope * (newest.0 as f64 - mt);
        (fit / 16.0, slope * 60_000.0 / 16.0, true)
    }

    fn refresh(&mut self, dt: f64) {
        let (temp, rate, ready) = self.estimate();
        let mut st = if ready { 0 } else { Status::RATE_NOT_READY };
        let Some(table) = &self.table else {
            self.k1 = [0.0; 3];
            self.k0 = [0.0; 3];
            self.status = st | Status::NO_TABLE;
            return;
        };
        let have = self.last_good.is_some();
        for (i, m) in table.axes.iter().enumerate() {
            let (k1, k0, tcl, rcl, settling) = if have {
                eval_axis(m, &mut self.axes[i], temp, rate, dt, self.window.len())
            } else {
                eval_axis(m, &mut AxisRef::default(), f64::from(m.scale.t0_c), 0.0, 0.0, self.window.len())
            };
            if tcl {
                st |= Status::TEMP_OUT_OF_RANGE;
            }
            if rcl {
                st |= Status::RATE_OUT_OF_RANGE;
            }
            if settling {
                st |= Status::MODEL_SETTLING;
            }
            self.k1[i] = k1;
            self.k0[i] = k0;
        }
        if !have || self.stale() {
            st |= Status::TEMP_STALE;
        }
        self.status = st;
    }

    /// Load a table (decoded by the crate's codec; everything after is independent).
    pub fn table(&mut self, bytes: &[u8]) -> Predicted {
        match Table::decode(bytes) {
            // γ within a factor of 2 of the nominal scale (the default config's 320 000).
            Ok(t)
                if t.axes.len() == 3
                    && t.rate_window == 32
                    && t.axes.iter().all(|a| (0.5..=2.0).contains(&(f64::from(a.scale.gamma) / NOMINAL_K1))) =>
            {
                match &self.table {
                    Some(old) => {
                        for i in 0..3 {
                            self.axes[i] = carried_over(self.axes[i], &old.axes[i], &t.axes[i]);
                        }
                    }
                    None => self.axes = [AxisRef::default(); 3],
                }
                self.table = Some(t);
                self.refresh(0.0);
                Predicted::Table(true)
            }
            _ => Predicted::Table(false),
        }
    }

    /// The slow-path clock moves forward only (an earlier time adds nothing).
    fn tick_clock(&mut self, t_ms: u32) {
        self.clock = Some(match self.clock {
            None => (t_ms, i64::from(t_ms)),
            Some((abs, un)) => {
                let d = t_ms.wrapping_sub(abs);
                if d < 1 << 31 {
                    (t_ms, un + i64::from(d))
                } else {
                    (abs, un)
                }
            }
        });
    }

    fn stale(&self) -> bool {
        match (self.last_good, self.clock) {
            (Some((t, _)), Some((_, now))) => now - t > STALE_MS,
            _ => true,
        }
    }

    fn reject(&mut self, code: u32) -> Predicted {
        self.status |= Status::TEMP_INVALID;
        if self.stale() {
            self.status |= Status::TEMP_STALE;
        }
        Predicted::SampleErr { code, status: self.status }
    }

    fn allowed(from_t: i64, to_t: i64) -> i64 {
        MAX_STEP + MAX_SLEW_PER_MIN * (to_t - from_t).min(MAX_GAP_MS) / 60_000
    }

    /// Count a rejected reading towards a confirmed restart: consecutive rejected readings,
    /// each later than the previous and within its step/slew allowance.
    fn confirm(&mut self, t_ms: u32, raw: i64) -> bool {
        let consistent = match self.pending {
            Some((pt, praw)) => {
                let d = t_ms.wrapping_sub(pt);
                d != 0 && d < (1 << 31) - 1 && (raw - praw).abs() <= Self::allowed(0, i64::from(d))
            }
            None => false,
        };
        self.pending_n = if consistent { self.pending_n + 1 } else { 1 };
        self.pending = Some((t_ms, raw));
        self.pending_n >= CONFIRM
    }

    /// A scratchpad read at `t_ms`.
    pub fn scratchpad(&mut self, t_ms: u32, sp: &[u8; 9]) -> Predicted {
        self.tick_clock(t_ms);
        match decode(sp) {
            Ok(raw) => self.raw(t_ms, raw),
            Err(c) => self.reject(c),
        }
    }

    /// A raw reading at `t_ms`.
    pub fn raw(&mut self, t_ms: u32, raw: i64) -> Predicted {
        self.tick_clock(t_ms);
        if !(RAW_MIN..=RAW_MAX).contains(&raw) {
            return self.reject(code::OUT_OF_RANGE);
        }
        let mut restart = false;
        let mut clock_restart = false;
        let t;
        match self.last_good {
            None => {
                if raw == 0x0550 {
                    return self.reject(code::POWER_ON_JUMP);
                }
                t = i64::from(t_ms);
            }
            Some((lt, lraw)) => {
                let d = t_ms.wrapping_sub(self.last_abs);
                if d == 0 || d >= 1 << 31 {
                    // Backwards or too far: a restarted clock once CONFIRM readings agree.
                    if raw == 0x0550 || !self.confirm(t_ms, raw) {
                        return self.reject(code::TIME);
                    }
                    restart = true;
                    clock_restart = true;
                    // The window restarts, so only differences from here on matter.
                    t = lt + 1;
                } else {
                    t = lt + i64::from(d);
                    // 0550h only continues a stream that is there: within one step, no gap.
                    if raw == 0x0550 && ((raw - lraw).abs() > MAX_STEP || t - lt > STALE_MS) {
                        return self.reject(code::POWER_ON_JUMP);
                    }
                    if (raw - lraw).abs() > Self::allowed(lt, t) {
                        if !self.confirm(t_ms, raw) {
                            return self.reject(code::IMPLAUSIBLE);
                        }
                        restart = true;
                    }
                }
            }
        }
        let prev = self.last_good.map(|g| g.0);
        if restart || prev.is_some_and(|p| t - p > MAX_GAP_MS) {
            self.window.clear();
        }
        self.window.push_back((t, raw));
        if self.window.len() > WINDOW {
            self.window.pop_front();
        }
        self.pending = None;
        self.pending_n = 0;
        self.last_good = Some((t, raw));
        self.last_abs = t_ms;
        self.last_unwrapped = t;
        self.since = 0;
        let dt = match prev {
            Some(p) if !clock_restart => (t - p) as f64 / 1000.0,
            _ => 0.0,
        };
        self.refresh(dt);
        let (temp, rate, _) = self.estimate();
        Predicted::SampleOk { status: self.status, temp, rate, k1: self.k1, k0: self.k0 }
    }

    /// An IMU cycle.
    pub fn cycle(&mut self, pulses: [i64; 3], dt: u32) -> Predicted {
        self.apply(pulses, dt, true)
    }

    /// An IMU cycle of MEMS samples: `a = raw·g0/K1 − K0·g0`, m/s².
    pub fn samples(&mut self, raw: [i64; 3], dt: u32) -> Predicted {
        match self.apply(raw, dt, false) {
            // The reference is configured as `Config::default()`: pulse counts. The documented
            // rule: the other entry's output is 0 on every axis, flagged.
            Predicted::Cycle { status, .. } => Predicted::Cycle { status: status | Status::WRONG_INPUT, dv: [0.0; 3] },
            other => other,
        }
    }

    /// `counts·g0/K1 − K0·g0·(tick·dt if per_tick, else 1)`, then the misalignment; with no
    /// table the counts at the nominal scale.
    fn apply(&mut self, counts: [i64; 3], dt: u32, per_tick: bool) -> Predicted {
        self.since = (self.since + u64::from(dt)).min(u64::from(u32::MAX));
        let stale = if self.since > STALE_AFTER { Status::TEMP_STALE } else { 0 };
        // The documented rule: a period P with P ≤ 4·dt ≤ 16·P passes.
        let dt4 = 4 * u64::from(dt);
        let stale =
            stale | if (IMU_PERIOD_TICKS..=16 * IMU_PERIOD_TICKS).contains(&dt4) { 0 } else { Status::DT_IMPLAUSIBLE };
        let bias_factor = if per_tick { G0 * TICK_S * f64::from(dt) } else { G0 };
        let mut v = [0.0; 3];
        for i in 0..3 {
            v[i] = if self.table.is_some() {
                counts[i] as f64 * G0 / self.k1[i] - self.k0[i] * bias_factor
            } else {
                counts[i] as f64 * G0 / NOMINAL_K1
            };
        }
        if let Some(m) = self.table.as_ref().and_then(|t| t.misalignment) {
            let raw = v;
            for (r, out) in v.iter_mut().enumerate() {
                *out = (0..3).map(|c| f64::from(m[r * 3 + c]) * raw[c]).sum();
            }
        }
        Predicted::Cycle { status: self.status | stale, dv: v }
    }

    /// An IMU cycle from wrapping cumulative counters.
    pub fn counters(&mut self, c: [u32; 3], dt: u32) -> Predicted {
        match self.counters.replace(c) {
            None => match self.cycle([0; 3], dt) {
                Predicted::Cycle { status, .. } => {
                    Predicted::Cycle { status: status | Status::NO_COUNTER_BASE, dv: [0.0; 3] }
                }
                other => other,
            },
            Some(p) => {
                let d: [i64; 3] = std::array::from_fn(|i| i64::from(c[i].wrapping_sub(p[i]) as i32));
                self.cycle(d, dt)
            }
        }
    }
}
