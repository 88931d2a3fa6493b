//! The physics oracle: the unit itself, simulated in continuous time, against which the
//! compensator's status-OK outputs are judged.
//!
//! The [`oracle`](crate::oracle) restates the firmware guide (its filter applied to the true
//! temperatures, its clamps, its branch rule), so where the guide itself is physically wrong
//! it agrees with the firmware. This one does not read the guide. A [`Truth`] is the unit a
//! table describes, run on the true case temperature of the history:
//!
//! - the sensing element follows the **true** case temperature through the first-order lag,
//!   solved exactly for each piecewise-linear stretch, wherever the case goes (a lag is a
//!   property of the unit, not of the calibrated range);
//! - the bias branch switches when the **true** rate passes the table's deadband, and holds
//!   in between; before the history the unit was at rest on a branch nobody knows (drawn);
//! - the play and creep states follow the true element temperature (the play started
//!   anywhere within its half-width, drawn);
//! - K1 is Eq. 11 at the true element temperature and the true rate; K0 the branch's grid at
//!   the true element temperature, extended along its end cells outside the grid (the
//!   unit's bias does not stop changing at the calibrated range's edge), plus the play and
//!   creep terms.
//!
//! The sensor is read as it is: a 12-bit DS18B20 conversion takes up to 750 ms and reports
//! the temperature during it, taken here at its middle, 375 ms before the reading arrives
//! and is stamped; quantized to 1/16 °C with flicker near code edges.
//!
//! # The stated tolerance
//! What a correct compensator cannot know, and so may differ by with status OK, in terms of
//! the sensor and the history rather than of the firmware's rules:
//!
//! - the readings' quantization, at most 0.65 LSB each (rounding, plus flicker near a code
//!   edge): through a least-squares line over the window's reading instants this moves the
//!   temperature by at most `0.65·q·Σ|vᵢ|` and the rate by `0.65·q·Σ|wᵢ|` (worst case, not
//!   realized: the firmware is judged against the truth, not against its own filter);
//! - the history's curvature within the window: the least-squares slope of a function is a
//!   positive-weighted mean of its derivative, so the rate is off by at most how far the
//!   true rate ranged over the window, the temperature by that times the window's span;
//! - time: the coefficients are held from one reading to the next and the reading is 375
//!   ms old when it arrives, so the truth's own movement since the reading's instant is
//!   allowed (computed from the truth);
//! - states started without their history: the lag within 1/64 °C, the play and creep
//!   terms within a quarter of the grid's residual, once the firmware no longer says
//!   `MODEL_SETTLING` (its documented thresholds);
//! - the bias branch: a switch at a true rate within the sensor's resolution of the
//!   deadband may be seen late or not at all (the branch then held is allowed), and noise
//!   may carry the estimate past the deadband only within the quantization bound above. A
//!   switch with the true rate at rest is never allowed: that is a decision on noise.
//!
//! A cycle is silently wrong when its status is OK and its output is further from the
//! truth than that tolerance.

use std::collections::VecDeque;

use qfa_thermal::model::AxisModel;
use qfa_thermal::table::Table;

/// Standard gravity, m/s².
const G0: f64 = 9.806_65;
/// One DS18B20 LSB at 12 bits, °C.
const Q_C: f64 = 0.0625;
/// The largest error of one reading against the temperature it sampled, LSB: half a code
/// from rounding, 0.15 more where a reading near a code edge flickers to the other code.
const READ_ERR_LSB: f64 = 0.65;
/// A 12-bit conversion lasts up to 750 ms; the reading holds the temperature of its middle.
pub const CONVERSION_DELAY_S: f64 = 0.375;
/// Readings further apart than this start a new window (the DS18B20 stream's gap rule).
const MAX_GAP_S: f64 = 30.0;
/// Readings in a window at most.
const WINDOW: usize = 32;
/// f32 arithmetic on the line (10⁻⁴ °C, °C/min), on K1, K0 and the output (relative).
const F32_LINE: f64 = 1e-4;
const F32_REL: f64 = 2e-6;
/// The firmware's settled thresholds, from its documentation: a lag state within 1/64 °C,
/// a play or creep term within a quarter of the grid's residual.
const SETTLED_LAG_C: f64 = 1.0 / 64.0;
/// The sensor's resolution of a rate: the rate that flicker at rest exceeds with
/// probability 1 % in an hour of one-second estimates (Hoeffding's bound on the line's
/// slope, whose terms are each bounded by `|wᵢ|·q`): `(60·q/2)·√(2·ln(M/α)/S)` with
/// `S = N(N² − 1)/12` s² for N readings a second apart.
fn rate_resolution(n: usize) -> f64 {
    let nf = n as f64;
    let s = nf * (nf * nf - 1.0) / 12.0;
    60.0 * Q_C / 2.0 * (2.0 * (3_600.0f64 / 0.01).ln() / s).sqrt()
}

/// The history's case temperature: piecewise-linear from rest.
#[derive(Clone, Debug)]
pub struct Profile {
    /// (start s, start °C, rate °C/min) per segment; at rest before the first and after
    /// the last.
    segments: Vec<(f64, f64, f64)>,
    start_c: f64,
}

impl Profile {
    /// From the start temperature and (seconds, °C/min) segments.
    #[must_use]
    pub fn new(start_c: f64, segments: &[(u32, f64)]) -> Self {
        let mut out = Vec::with_capacity(segments.len() + 1);
        let (mut t, mut temp) = (0.0, start_c);
        for &(len, rate) in segments {
            out.push((t, temp, rate));
            t += f64::from(len);
            temp += rate / 60.0 * f64::from(len);
        }
        out.push((t, temp, 0.0));
        Self { segments: out, start_c }
    }

    fn index(&self, t: f64) -> Option<usize> {
        self.segments.iter().rposition(|s| s.0 <= t)
    }

    /// °C at `t` s.
    #[must_use]
    pub fn temp(&self, t: f64) -> f64 {
        self.index(t).map_or(self.start_c, |i| {
            let s = self.segments[i];
            s.1 + s.2 / 60.0 * (t - s.0)
        })
    }

    /// °C/min at `t` s (the segment starting at `t`, if one does).
    #[must_use]
    pub fn rate(&self, t: f64) -> f64 {
        self.index(t).map_or(0.0, |i| self.segments[i].2)
    }

    /// The next segment boundary after `t`.
    fn next_boundary(&self, t: f64) -> f64 {
        self.segments.iter().map(|s| s.0).find(|&b| b > t).unwrap_or(f64::INFINITY)
    }

    /// The least and greatest true rate over `[a, b]`.
    fn rate_range(&self, a: f64, b: f64) -> (f64, f64) {
        let mut lo = self.rate(a);
        let mut hi = lo;
        for s in self.segments.iter().filter(|s| s.0 > a && s.0 <= b) {
            lo = lo.min(s.2);
            hi = hi.max(s.2);
        }
        (lo, hi)
    }
}

/// One table's model of one axis, as the unit: its states in continuous time.
#[derive(Clone, Debug)]
pub struct Truth {
    m: AxisModel,
    offset_c: f64,
    t: f64,
    element_c: f64,
    play_c: f64,
    creep_c: f64,
    /// +1 heating, −1 cooling.
    branch: i8,
}

/// The longest step the truth takes, s (the play and creep between steps move by second
/// order in it).
const MAX_STEP_S: f64 = 0.25;

impl Truth {
    /// The unit at rest for ever before `t = 0`, on `branch` (±1), its play output at
    /// `play_frac` (−1…1) of its half-width from the element temperature.
    #[must_use]
    pub fn at_rest(m: &AxisModel, p: &Profile, offset_c: f64, branch: i8, play_frac: f64) -> Self {
        let te = p.temp(0.0) + offset_c;
        let half = m.ext.bias_branch_hysteresis.map_or(0.0, |h| f64::from(h.half_width_c));
        Self { m: m.clone(), offset_c, t: 0.0, element_c: te, play_c: te + half * play_frac, creep_c: te, branch }
    }

    /// Run the unit to `t1` s.
    pub fn advance(&mut self, p: &Profile, t1: f64) {
        while self.t < t1 {
            let boundary = p.next_boundary(self.t);
            let end = t1.min(boundary).min(self.t + MAX_STEP_S);
            let h = end - self.t;
            let rate = p.rate(self.t);
            let a = rate / 60.0;
            let tc0 = p.temp(self.t) + self.offset_c;
            let tc1 = tc0 + a * h;
            let te0 = self.element_c;
            self.element_c = match self.m.ext.sensor_lag {
                // dTe/dt = (Tc − Te)/τ with Tc = tc0 + a·s: exact.
                Some(l) => {
                    let tau = f64::from(l.tau_s);
                    tc1 - a * tau + (te0 - tc0 + a * tau) * (-h / tau).exp()
                }
                None => tc1,
            };
            let db = f64::from(self.m.bias.deadband_c_per_min);
            if rate > db {
                self.branch = 1;
            } else if rate < -db {
                self.branch = -1;
            }
            if let Some(pl) = self.m.ext.bias_branch_hysteresis {
                let half = f64::from(pl.half_width_c);
                self.play_c = self.play_c.clamp(self.element_c - half, self.element_c + half);
            }
            if let Some(c) = self.m.ext.bias_creep {
                let mid = 0.5 * (te0 + self.element_c);
                let tau = creep_tau(&c, mid);
                self.creep_c = mid + (self.creep_c - mid) * (-h / tau).exp();
            }
            self.t = end;
        }
    }

    /// The element temperature now, °C.
    #[must_use]
    pub fn element_c(&self) -> f64 {
        self.element_c
    }

    /// K1 now, at the true rate `rate` (°C/min).
    #[must_use]
    pub fn k1(&self, rate: f64) -> f64 {
        let sf = &self.m.scale;
        let d = self.element_c - f64::from(sf.t0_c);
        f64::from(sf.gamma)
            + f64::from(sf.mu) * d
            + f64::from(sf.beta) * d * d
            + f64::from(sf.epsilon) * rate
            + f64::from(sf.eta) * rate * d
            + f64::from(sf.alpha) * rate * rate
    }

    /// The bias grid of `branch` (±1; 0 the mean) at the element temperature, extended
    /// along its end cells, g.
    #[must_use]
    pub fn grid(&self, branch: i8) -> f64 {
        let g = &self.m.bias;
        let at = |v: &[f32]| extended(v, f64::from(g.t_start_c), f64::from(g.t_step_c), self.element_c);
        match branch {
            1 => at(&g.heating_g),
            -1 => at(&g.cooling_g),
            _ => 0.5 * (at(&g.heating_g) + at(&g.cooling_g)),
        }
    }

    /// The play and creep terms now, g.
    #[must_use]
    pub fn history_terms(&self) -> f64 {
        let mut k0 = 0.0;
        if let Some(pl) = self.m.ext.bias_branch_hysteresis {
            k0 += f64::from(pl.weight_g) * (self.element_c - self.play_c) / f64::from(pl.half_width_c);
        }
        if let Some(c) = self.m.ext.bias_creep {
            k0 += f64::from(c.gain_g_per_c) * (self.element_c - self.creep_c);
        }
        k0
    }

    /// K0 now, g.
    #[must_use]
    pub fn k0(&self) -> f64 {
        self.grid(self.branch) + self.history_terms()
    }
}

fn creep_tau(c: &qfa_thermal::model::Creep, te: f64) -> f64 {
    f64::from(c.tau_ref_s)
        * (f64::from(c.activation_k) * (1.0 / (te + 273.15) - 1.0 / (f64::from(c.t_ref_c) + 273.15))).exp()
}

/// A uniform grid at `t`, linear within it and along the end cells beyond it.
fn extended(v: &[f32], start: f64, step: f64, t: f64) -> f64 {
    let x = (t - start) / step;
    let i = (x.floor().max(0.0) as usize).min(v.len() - 2);
    let (a, b) = (f64::from(v[i]), f64::from(v[i + 1]));
    a + (b - a) * (x - i as f64)
}

/// Largest |slope| of a grid's cells, g/°C.
fn grid_slope(v: &[f32], step: f64) -> f64 {
    v.windows(2).map(|w| (f64::from(w[1]) - f64::from(w[0])).abs() / step).fold(0.0, f64::max)
}

/// The branches a correct compensator may hold: the unknown start (`MODEL_SETTLING` while
/// it matters), heating, cooling.
#[derive(Clone, Copy, Debug, Default)]
struct Allowed {
    unknown: bool,
    heating: bool,
    cooling: bool,
}

/// One sensor's window of accepted readings (stamp s, sample instant s), and what the
/// compensator may be off by at its last reading.
#[derive(Clone, Debug, Default)]
struct Axis {
    window: VecDeque<(f64, f64)>,
    /// The element temperature's error bound, °C (`None`: the states restart at the next
    /// reading).
    element_err: Option<f64>,
    play_err: f64,
    creep_err: f64,
    /// Per table: the truth at the last reading's instant.
    at_reading: Vec<Option<Truth>>,
    /// Bound on the rate's error at the last reading, °C/min.
    rate_err: f64,
    allowed: Allowed,
}

/// The physics oracle for one history: a [`Truth`] per table and axis, one sensor per axis.
#[derive(Clone, Debug)]
pub struct Physics {
    profile: Profile,
    truths: Vec<Vec<Truth>>,
    axes: Vec<Axis>,
    current: Option<usize>,
    tick_s: f64,
}

/// What the history states of a model depend on; a load that changes them restarts the
/// compensator's states (its documented reload rule), which then settle again.
fn history_key(m: &AxisModel) -> String {
    format!("{:?} {} {} {}", m.ext, m.bias.t_start_c, m.bias.t_step_c, m.bias.heating_g.len())
}

impl Physics {
    /// The units of `tables` on `profile`, sensor i `offsets[i]` from it; `branches` and
    /// `play_fracs` say where each axis's unit stood before the history. `tick_s` is the
    /// fast path's tick.
    #[must_use]
    pub fn new(
        profile: Profile,
        offsets: &[f64],
        tables: &[Table],
        branches: &[i8],
        play_fracs: &[f64],
        tick_s: f64,
    ) -> Self {
        let truths = tables
            .iter()
            .map(|t| {
                t.axes
                    .iter()
                    .enumerate()
                    .map(|(i, m)| Truth::at_rest(m, &profile, offsets[i], branches[i], play_fracs[i]))
                    .collect()
            })
            .collect();
        let axes = (0..offsets.len())
            .map(|_| Axis {
                at_reading: vec![None; tables.len()],
                allowed: Allowed { unknown: true, ..Allowed::default() },
                ..Axis::default()
            })
            .collect();
        Self { profile, truths, axes, current: None, tick_s }
    }

    /// Table `k` is in force from now; its states restart if its history key differs from
    /// the one before.
    pub fn load(&mut self, k: usize) {
        if let Some(old) = self.current {
            for (i, a) in self.axes.iter_mut().enumerate() {
                if history_key(&self.truths[old][i].m) != history_key(&self.truths[k][i].m) {
                    a.element_err = None;
                }
            }
        }
        self.current = Some(k);
    }

    fn advance_all(&mut self, t: f64) {
        for tr in self.truths.iter_mut().flatten() {
            tr.advance(&self.profile, t);
        }
    }

    /// An accepted reading of sensor `i`, stamped at history time `stamp_s` (it sampled
    /// the case [`CONVERSION_DELAY_S`] earlier).
    pub fn reading(&mut self, i: usize, stamp_s: f64) {
        let sample_s = stamp_s - CONVERSION_DELAY_S;
        self.advance_all(sample_s);
        let a = &mut self.axes[i];
        let dt = a.window.back().map(|r| stamp_s - r.0);
        if dt.is_some_and(|d| d > MAX_GAP_S) {
            a.window.clear();
        }
        if a.window.len() == WINDOW {
            a.window.pop_front();
        }
        a.window.push_back((stamp_s, sample_s));
        let n = a.window.len();
        // The line's worst-case quantization on T̂ and Ṫ (°C, °C/min), by its weights at
        // the stamps.
        let (nu_t, nu_r) = if n < 2 {
            (READ_ERR_LSB * Q_C + F32_LINE, f64::INFINITY)
        } else {
            let nf = n as f64;
            let tbar = a.window.iter().map(|r| r.0).sum::<f64>() / nf;
            let s: f64 = a.window.iter().map(|r| (r.0 - tbar).powi(2)).sum();
            let lever = stamp_s - tbar;
            let sv: f64 = a.window.iter().map(|r| (1.0 / nf + lever * (r.0 - tbar) / s).abs()).sum();
            let sw: f64 = a.window.iter().map(|r| ((r.0 - tbar) / s).abs()).sum();
            (READ_ERR_LSB * Q_C * sv + F32_LINE, READ_ERR_LSB * Q_C * 60.0 * sw + F32_LINE)
        };
        let first = a.window.front().map_or(sample_s, |r| r.1);
        let (r_lo, r_hi) = self.profile.rate_range(first, sample_s);
        let r_now = self.profile.rate(sample_s);
        let curve = (r_hi - r_now).abs().max((r_lo - r_now).abs());
        let span = sample_s - first;
        let t_err = nu_t + curve * span / 60.0;
        a.rate_err = nu_r + curve;
        let Some(k) = self.current else { return };
        let m = &self.truths[k][i].m;
        // The element's error: a weighted mean of the inputs' errors (the lag), each input
        // also off by how far the truth moved over its step (the firmware holds it).
        let moved = dt.map_or(0.0, |d| {
            let (lo, hi) = self.profile.rate_range(sample_s - d, sample_s);
            lo.abs().max(hi.abs()) * d / 60.0
        });
        let e = match (a.element_err, m.ext.sensor_lag, dt) {
            (Some(prev), Some(l), Some(d)) => {
                let w = 1.0 - (-d / f64::from(l.tau_s)).exp();
                (1.0 - w) * prev + w * (t_err + moved)
            }
            (Some(_), None, _) | (None, _, _) | (Some(_), Some(_), None) => t_err,
        };
        let restarted = a.element_err.is_none();
        a.element_err = Some(e);
        a.play_err = if restarted { e } else { a.play_err.max(e + moved) };
        a.creep_err = match (restarted, m.ext.bias_creep, dt) {
            (false, Some(c), Some(d)) => {
                let te = self.truths[k][i].element_c;
                let tau = creep_tau(&c, te);
                let w = 1.0 - (-d / tau).exp();
                let dw = (d / tau) * f64::from(c.activation_k).abs() * e / (te + 273.15).powi(2);
                (1.0 - w) * a.creep_err + w * (e + moved) + dw * (te - self.truths[k][i].creep_c).abs()
            }
            _ => e,
        };
        // The branches the compensator may now hold: it decides at a reading, on a rate
        // within nu_r of the window's true rates, and may not decide below the sensor's
        // resolution of the window.
        if n >= 2 {
            let th = f64::from(m.bias.deadband_c_per_min).max(rate_resolution(n));
            let al = &mut a.allowed;
            if r_lo - a.rate_err > th {
                *al = Allowed { heating: true, ..Allowed::default() };
            } else if r_hi + a.rate_err < -th {
                *al = Allowed { cooling: true, ..Allowed::default() };
            } else {
                al.heating |= r_hi + a.rate_err > th;
                al.cooling |= r_lo - a.rate_err < -th;
            }
        }
        for (k, tr) in self.truths.iter().enumerate() {
            a.at_reading[k] = Some(tr[i].clone());
        }
    }

    /// The true Δv (m/s) of axis `i` over a cycle ending at history time `t_s`, for
    /// `pulses` over `dt_ticks`, and the tolerance; `None` where no correct compensator
    /// can say OK (no table, or no rate yet).
    pub fn dv(&mut self, i: usize, t_s: f64, pulses: i64, dt_ticks: u32) -> Option<(f64, f64)> {
        let (k1, k1_tol, k0, k0_tol) = self.coefficients(i, t_s)?;
        let n = pulses as f64;
        let dt_s = f64::from(dt_ticks) * self.tick_s;
        let dv = n * G0 / k1 - k0 * G0 * dt_s;
        let tol = n.abs() * G0 * k1_tol / (k1 * (k1 - k1_tol))
            + k0_tol * G0 * dt_s
            + F32_REL * (n.abs() * G0 / k1 + k0.abs() * G0 * dt_s);
        Some((dv, tol))
    }

    /// The true specific force (m/s²) of axis `i` at history time `t_s` for the sample
    /// `raw` (LSB at the table's K1), and the tolerance.
    pub fn accel(&mut self, i: usize, t_s: f64, raw: i64) -> Option<(f64, f64)> {
        let (k1, k1_tol, k0, k0_tol) = self.coefficients(i, t_s)?;
        let n = raw as f64;
        let a = n * G0 / k1 - k0 * G0;
        let tol =
            n.abs() * G0 * k1_tol / (k1 * (k1 - k1_tol)) + k0_tol * G0 + F32_REL * (n.abs() * G0 / k1 + k0.abs() * G0);
        Some((a, tol))
    }

    /// (K1, its tolerance, K0, its tolerance) of axis `i` at history time `t_s`.
    fn coefficients(&mut self, i: usize, t_s: f64) -> Option<(f64, f64, f64, f64)> {
        self.advance_all(t_s);
        let k = self.current?;
        let a = &self.axes[i];
        if a.window.len() < 3 {
            return None;
        }
        let then = a.at_reading[k].as_ref()?;
        let now = &self.truths[k][i];
        let m = &now.m;
        let sample_s = a.window.back()?.1;
        let (r_then, r_now) = (self.profile.rate(sample_s), self.profile.rate(t_s));
        let lag = m.ext.sensor_lag.is_some();
        let dte = a.element_err? + if lag { SETTLED_LAG_C } else { 0.0 };
        let dr = a.rate_err;
        let sf = &m.scale;
        let (al, be, et, ep, mu) =
            (f64::from(sf.alpha), f64::from(sf.beta), f64::from(sf.eta), f64::from(sf.epsilon), f64::from(sf.mu));
        let d = then.element_c - f64::from(sf.t0_c);
        // Eq. 11 is quadratic: this bound on |ΔK1| is exact.
        let k1_then = then.k1(r_then);
        let k1_tol_then = (2.0 * be * d + et * r_then + mu).abs() * dte
            + (2.0 * al * r_then + et * d + ep).abs() * dr
            + al.abs() * dr * dr
            + be.abs() * dte * dte
            + et.abs() * dte * dr
            + F32_REL * k1_then.abs();
        let k1 = now.k1(r_now);
        let k1_tol = k1_tol_then + (k1 - k1_then).abs();
        // K0: the branches the compensator may hold, against the truth's branch now.
        let k0 = now.k0();
        let truth_grid = now.grid(now.branch);
        let mut branch_tol = 0.0f64;
        let settled_g = 0.25 * f64::from(m.bias.residual_rms_g);
        for (possible, b) in [(a.allowed.heating, 1i8), (a.allowed.cooling, -1)] {
            if possible {
                branch_tol = branch_tol.max((now.grid(b) - truth_grid).abs());
            }
        }
        if a.allowed.unknown {
            // The mean, unflagged only while within the settled threshold of either branch.
            branch_tol = branch_tol.max(settled_g.min((now.grid(0) - truth_grid).abs()));
        }
        let step = f64::from(m.bias.t_step_c);
        let slope = grid_slope(&m.bias.heating_g, step).max(grid_slope(&m.bias.cooling_g, step));
        let mut k0_tol = branch_tol + slope * dte;
        if let Some(pl) = m.ext.bias_branch_hysteresis {
            k0_tol += f64::from(pl.weight_g).abs() * (dte + a.play_err) / f64::from(pl.half_width_c) + settled_g;
        }
        if let Some(c) = m.ext.bias_creep {
            k0_tol += f64::from(c.gain_g_per_c).abs() * (dte + a.creep_err) + settled_g;
        }
        // The truth's own movement since the reading's instant (branch switches aside: the
        // allowed branches cover those).
        let k0_then_same_branch = then.grid(now.branch) + then.history_terms();
        k0_tol += (k0 - k0_then_same_branch).abs() + F32_REL * k0.abs() + 1e-9;
        Some((k1, k1_tol, k0, k0_tol))
    }
}
