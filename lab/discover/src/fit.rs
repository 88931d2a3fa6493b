//! Fitting a model structure: nonlinear slot parameters by search, linear coefficients by
//! least squares, every trial evaluated by the root crate's `AxisModel::evaluate`.
//!
//! For a given set of nonlinear parameters (lag τ, play half-width r, creep τ_ref and E)
//! a probe `AxisModel` with those slots on is run over every row; its public states give
//! the element temperature Te, the clamped Ṫ, the play term `(Te − p)/r` and the creep
//! term `Te − x` exactly as the firmware computes them. Those are averaged into bins and
//! form the columns of two linear least-squares problems (scale factor, bias). The fitted
//! coefficients go into an `AxisModel`, which is then run again to give the predictions
//! the residuals are formed from: what is scored is what the firmware would run.
//!
//! The search over the nonlinear parameters and their profile intervals take the least
//! squares' own fitted values instead (`Setup::train_score`), one pass over the rows per
//! trial instead of two: on the real chamber log discovery took 3.3 s instead of 5.0, on
//! the lab simulator's default cycling log 62 s instead of 100 (release, `qfa-lab
//! discover`), for held-out figures that moved in the seventh digit and the same named
//! effects.

use nalgebra::{DMatrix, DVector};
use qfa_thermal::model::{AxisModel, BiasGrid, BranchHysteresis, Creep, Extensions, ScaleFactor, SensorLag};

use super::structure::{Nonlinear, Structure};
use super::Start;
use qfa_log::channels::{Channels, LogKind};

/// Reference temperature of ΔT: the lab's one [`qfa_calibrate::fit::T0_C`], as the
/// model's f32.
pub(crate) const T0_C: f32 = qfa_calibrate::fit::T0_C as f32;
/// Fixed reference temperature of the creep time constant, °C.
pub(crate) const CREEP_T_REF_C: f32 = 22.0;
/// Bias grid points.
pub(crate) const GRID_POINTS: usize = 16;

/// Fixed geometry of a data set: bias grid, rate limit, channel weights.
#[derive(Clone, Debug)]
pub(crate) struct Setup<'a> {
    /// The data.
    pub ch: &'a Channels,
    /// First grid temperature, °C.
    pub grid_start: f32,
    /// Grid step, °C.
    pub grid_step: f32,
    /// Calibrated |Ṫ| limit, °C/min.
    pub rate_limit: f32,
    /// Noise floor of the scale-factor channel, ppm (weights of the joint objective).
    pub sigma_sf: f64,
    /// Noise floor of the bias channel, µg (or value units).
    pub sigma_b: f64,
    /// Per-bin time derivative of the current model's prediction, (dK1/dt, dK0/dt) per
    /// second: the direction in which a timing offset between the temperature readings
    /// and the counts moves the prediction (K(T(t + δ)) ≈ K(T(t)) + δ·dK/dt). When set,
    /// every fit takes the offset δ as a nuisance shared by both channels
    /// ([`TimingOffset`]); `None` fits none.
    pub offset_basis: Option<Vec<(f64, f64)>>,
    /// Largest |δ| a fit may take, s.
    pub offset_limit_s: f64,
    /// δ held at this value instead of fitted (the selection holds it while it tests a
    /// round's candidates: see `select::analyze`).
    pub offset_fixed: Option<f64>,
}

/// The timing offset δ a fit took: the counts at time t follow the model at the temperature
/// stamped t + δ (δ > 0: the temperature channel is stamped δ early against the counts,
/// as a reading taken at the start of a counting interval, or a conversion that reports
/// a temperature δ old, is).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct TimingOffset {
    /// δ, s.
    pub seconds: f64,
    /// Its SE from the fit's curvature for white residuals, s (the report widens it by
    /// the residual's variance inflation).
    pub se_white_s: f64,
    /// δ sits at ±`offset_limit_s`.
    pub at_limit: bool,
}

impl<'a> Setup<'a> {
    /// Geometry from the data's temperature and rate range.
    #[must_use]
    pub(crate) fn new(ch: &'a Channels) -> Self {
        let (mut lo, mut hi, mut rmax) = (f32::INFINITY, f32::NEG_INFINITY, 0.0f32);
        for t in &ch.traces {
            for (&x, &r) in t.est_t.iter().zip(&t.est_rate) {
                lo = lo.min(x);
                hi = hi.max(x);
                rmax = rmax.max(r.abs());
            }
        }
        let lo = (lo.floor() - 1.0).max(-60.0);
        let hi = (hi.ceil() + 1.0).min(130.0).max(lo + 2.0);
        let step = (hi - lo) / (GRID_POINTS - 1) as f32;
        Self {
            ch,
            grid_start: lo,
            grid_step: step,
            rate_limit: (rmax * 1.25).clamp(0.1, 20.0),
            sigma_sf: 1.0,
            sigma_b: 1.0,
            offset_basis: None,
            offset_limit_s: offset_limit_s(ch),
            offset_fixed: None,
        }
    }

    /// The time derivative of `model`'s per-bin prediction along each trace (central
    /// differences over the bins' times; one-sided at a trace's ends): the basis of the
    /// timing offset ([`Setup::offset_basis`]).
    #[must_use]
    pub(crate) fn offset_basis_of(&self, model: &AxisModel) -> Vec<(f64, f64)> {
        let pred = self.predict(model);
        let mut out = Vec::with_capacity(pred.len());
        let mut o = 0;
        for t in &self.ch.traces {
            let m = t.bins.len();
            for i in 0..m {
                let (a, b) = (i.saturating_sub(1), (i + 1).min(m - 1));
                let dt = t.bins[b].time_s - t.bins[a].time_s;
                out.push(if dt > 0.0 {
                    ((pred[o + b].0 - pred[o + a].0) / dt, (pred[o + b].1 - pred[o + a].1) / dt)
                } else {
                    (0.0, 0.0)
                });
            }
            o += m;
        }
        out
    }

    /// Factor from the bias channel's unit (g for cycling logs) to the reported unit.
    #[must_use]
    pub(crate) fn bias_unit(&self) -> f64 {
        match self.ch.kind {
            LogKind::Cycling => 1e6,
            LogKind::Single => 1.0,
        }
    }

    fn grid_temp(&self, j: usize) -> f32 {
        self.grid_start + self.grid_step * j as f32
    }
}

/// The two least-squares problems of one fit ([`Setup::design`]).
struct Design {
    /// The training bins, in order: the problems' rows.
    rows: Vec<usize>,
    /// The scale factor's Eq. 11 columns fitted.
    cols: Vec<usize>,
    a_sf: DMatrix<f64>,
    y_sf: DVector<f64>,
    a: DMatrix<f64>,
    y: DVector<f64>,
    /// The second-difference penalty's columns.
    pen: Option<(usize, usize)>,
    /// The bias grid's basis.
    basis: Vec<Vec<f64>>,
    /// Hours per bin (drift structures only).
    hours: Vec<f64>,
    /// The drift's column in `a`.
    drift_col: usize,
}

/// Per-bin mean features.
#[derive(Clone, Debug, Default)]
struct Features {
    /// 1, d, d², r, r², r·d.
    sf: Vec<[f64; 6]>,
    /// Hat weights on the grid.
    hat: Vec<[f64; GRID_POINTS]>,
    play: Vec<f64>,
    creep: Vec<f64>,
}

/// The largest timing offset a fit may take: 1.5 rows (a logger stamps a reading at the
/// start, the centre or the end of its counting interval, and a conversion adds up to
/// 0.75 s), at least 2 s. A longer delay is not a timestamp convention: `sensor_lag`.
fn offset_limit_s(ch: &Channels) -> f64 {
    let mut dt: Vec<f32> = ch.traces.iter().flat_map(|t| t.dt_s.iter().copied()).filter(|&d| d > 0.0).collect();
    if dt.is_empty() {
        return 2.0;
    }
    dt.sort_by(f32::total_cmp);
    (1.5 * f64::from(dt[dt.len() / 2])).max(2.0)
}

/// A fitted model and its per-bin predictions (K1, K0) over every bin.
#[derive(Clone, Debug)]
pub(crate) struct Fitted {
    /// The axis model.
    pub model: AxisModel,
    /// Per-bin predicted K1 (pulses/(g·s); 1 for single-channel) and K0.
    pub pred: Vec<(f64, f64)>,
    /// Bias drift, g/h (value units per hour for single-channel logs), when in the structure.
    pub drift_per_h: Option<f64>,
    /// The timing offset the fit took, when [`Setup::offset_basis`] is set.
    pub offset: Option<TimingOffset>,
}

/// Per-bin residuals: scale factor in ppm (NaN for single-channel), bias in µg (or value).
#[derive(Clone, Debug, Default)]
pub struct Residuals {
    /// Scale-factor residual, ppm.
    pub sf: Vec<f64>,
    /// Bias residual, µg (or the value's unit).
    pub bias: Vec<f64>,
}

impl Setup<'_> {
    fn probe(&self, nl: &Nonlinear) -> AxisModel {
        let zeros = [0.0f32; GRID_POINTS];
        AxisModel {
            scale: ScaleFactor::simple(T0_C, 1.0, 0.0),
            bias: BiasGrid::single_valued(self.grid_start, self.grid_step, &zeros).expect("2 to 16 grid values"),
            rate_limit_c_per_min: self.rate_limit,
            ext: Extensions {
                sensor_lag: nl.lag_tau_s.map(|tau_s| SensorLag { tau_s }),
                bias_branch_hysteresis: nl.play_r_c.map(|r| BranchHysteresis { half_width_c: r, weight_g: 1.0 }),
                bias_creep: nl.creep.map(|(tau, e)| Creep {
                    gain_g_per_c: 1.0,
                    tau_ref_s: tau,
                    t_ref_c: CREEP_T_REF_C,
                    activation_k: e,
                }),
            },
        }
    }

    fn features(&self, nl: &Nonlinear) -> Features {
        let probe = self.probe(nl);
        let cyc = self.ch.kind == LogKind::Cycling; // else Eq. 11's sums are never read
        let n = self.ch.n_bins();
        let mut f = Features {
            sf: Vec::with_capacity(n),
            hat: Vec::with_capacity(n),
            play: Vec::with_capacity(n),
            creep: Vec::with_capacity(n),
        };
        for tr in &self.ch.traces {
            let mut bi = 0;
            let (mut s6, mut h, mut pl, mut cr) = ([0.0f64; 6], [0.0f64; GRID_POINTS], 0.0, 0.0);
            tr.advance_rows(&probe, |i, st, step| {
                let (te, r) = (step.element_c, f64::from(step.rate_c_per_min));
                if cyc {
                    let row = qfa_calibrate::fit::eq11_regressors(f64::from(te - T0_C), r);
                    (0..6).for_each(|k| s6[k] += row[k]);
                }
                let x = (te - self.grid_start) / self.grid_step;
                let j = (x as usize).min(GRID_POINTS - 2);
                let frac = f64::from(x - j as f32);
                h[j] += 1.0 - frac;
                h[j + 1] += frac;
                if let Some(rc) = nl.play_r_c {
                    pl += f64::from((te - st.play_c) / rc);
                }
                if nl.creep.is_some() {
                    cr += f64::from(te - st.creep_c);
                }
                while bi < tr.bins.len() && i + 1 == tr.bins[bi].hi {
                    let m = (tr.bins[bi].hi - tr.bins[bi].lo) as f64;
                    f.sf.push(s6.map(|v| v / m));
                    f.hat.push(h.map(|v| v / m));
                    f.play.push(pl / m);
                    f.creep.push(cr / m);
                    (s6, h, pl, cr) = ([0.0; 6], [0.0; GRID_POINTS], 0.0, 0.0);
                    bi += 1;
                }
                if bi < tr.bins.len() && i + 1 == tr.bins[bi].lo {
                    (s6, h, pl, cr) = ([0.0; 6], [0.0; GRID_POINTS], 0.0, 0.0);
                }
            });
        }
        f
    }

    /// Run `model` over every trace with the root crate's `evaluate`; per-bin (K1, K0).
    #[must_use]
    pub(crate) fn predict(&self, model: &AxisModel) -> Vec<(f64, f64)> {
        let mut out = Vec::with_capacity(self.ch.n_bins());
        for tr in &self.ch.traces {
            let mut bi = 0;
            let (mut s1, mut s10) = (0.0f64, 0.0f64);
            tr.evaluate_rows(model, |i, _, e| {
                if bi < tr.bins.len() && i >= tr.bins[bi].lo {
                    s1 += f64::from(e.k1);
                    s10 += f64::from(e.k1) * f64::from(e.k0);
                }
                while bi < tr.bins.len() && i + 1 == tr.bins[bi].hi {
                    out.push((s1 / (tr.bins[bi].hi - tr.bins[bi].lo) as f64, s10 / s1));
                    (s1, s10) = (0.0, 0.0);
                    bi += 1;
                }
            });
        }
        out
    }

    /// Residuals (measured − model) of predictions.
    #[must_use]
    pub(crate) fn residuals(&self, pred: &[(f64, f64)]) -> Residuals {
        let u = self.bias_unit();
        let mut r = Residuals::default();
        for (b, &(k1, k0)) in self.ch.traces.iter().flat_map(|t| t.bins.iter()).zip(pred) {
            r.sf.push((b.sf - k1) / k1 * 1e6);
            r.bias.push((b.bias - k0) * u);
        }
        r
    }

    /// Fit `structure` with nonlinear parameters `nl` on the bins where `train` is true.
    #[must_use]
    pub(crate) fn fit(&self, s: &Structure, nl: &Nonlinear, train: &[bool]) -> Fitted {
        self.fit_y(s, nl, train, None)
    }

    /// Hours since the start of its program, per bin (the drift column).
    #[must_use]
    pub(crate) fn bin_hours(&self) -> Vec<f64> {
        let mut v = Vec::with_capacity(self.ch.n_bins());
        for t in &self.ch.traces {
            let t0 = t.time_s.first().copied().unwrap_or(0.0);
            v.extend(t.bins.iter().map(|b| (b.time_s - t0) / 3600.0));
        }
        v
    }

    /// As [`Setup::fit`], with the measured per-bin (K1, K0) replaced by `y` when given
    /// (the block bootstrap refits resampled data through this).
    #[must_use]
    pub(crate) fn fit_y(&self, s: &Structure, nl: &Nonlinear, train: &[bool], y_over: Option<&[(f64, f64)]>) -> Fitted {
        let d = self.design(s, nl, train, y_over);
        let (c_sf, c, offset) = self.solve_with_offset(&d.rows, (&d.a_sf, &d.y_sf), (&d.a, &d.y, d.pen));
        let scale = if self.ch.kind == LogKind::Cycling {
            let mut full = [0.0f64; 6];
            for (j, &cj) in d.cols.iter().enumerate() {
                full[cj] = c_sf[j];
            }
            qfa_calibrate::fit::scale_of_eq11(&full)
        } else {
            ScaleFactor::simple(T0_C, 1.0, 0.0)
        };
        let model = self.model_of(scale, nl, &d.basis, &c);
        let mut pred = self.predict(&model);
        // The drift is not an `AxisModel` term: it is added to the predicted K0 here.
        let drift_per_h = s.bias_drift.then(|| c[d.drift_col]);
        self.add_drift_and_offset(&mut pred, drift_per_h, &d.hours, offset);
        Fitted { model, pred, drift_per_h, offset }
    }

    /// The objective of the nonlinear parameters' search: the normalized sum of squares
    /// Σ(sf/σ_sf)² + Σ(bias/σ_b)² of the training bins' residuals (ppm and µg, or the
    /// value's unit) from the least-squares fit of `s` with `nl`, its fitted values formed
    /// from the design (the features times the coefficients, plus the timing offset) rather
    /// than by running the fitted model over every row again. The two differ by the model's
    /// f32 coefficients and, on a cycling log, by the bin's K0 being the mean of K0 over its
    /// rows rather than weighted by K1 (parts per million of the bias); the search's choice
    /// is then scored, held out, by the model itself ([`Setup::fit`]).
    #[must_use]
    pub(crate) fn train_score(&self, s: &Structure, nl: &Nonlinear, train: &[bool]) -> f64 {
        let d = self.design(s, nl, train, None);
        let (c_sf, c, offset) = self.solve_with_offset(&d.rows, (&d.a_sf, &d.y_sf), (&d.a, &d.y, d.pen));
        let o = offset.map_or(0.0, |o| o.seconds);
        let basis = |b: usize| self.offset_basis.as_ref().map_or((0.0, 0.0), |v| v[b]);
        let u = self.bias_unit();
        let mut score = 0.0;
        for (i, &b) in d.rows.iter().enumerate() {
            if d.a_sf.nrows() > 0 {
                let k1 = (0..c_sf.len()).map(|j| d.a_sf[(i, j)] * c_sf[j]).sum::<f64>() + o * basis(b).0;
                let sf_ppm = (d.y_sf[i] - k1) / k1 * 1e6;
                if sf_ppm.is_finite() {
                    score += (sf_ppm / self.sigma_sf).powi(2);
                }
            }
            let k0 = (0..c.len()).map(|j| d.a[(i, j)] * c[j]).sum::<f64>() + o * basis(b).1;
            score += ((d.y[i] - k0) * u / self.sigma_b).powi(2);
        }
        score
    }

    /// The least-squares problems of `s` with `nl` on the bins where `train` is true (the
    /// measured per-bin (K1, K0), or `y_over`).
    fn design(&self, s: &Structure, nl: &Nonlinear, train: &[bool], y_over: Option<&[(f64, f64)]>) -> Design {
        let f = self.features(nl);
        let bins: Vec<_> = self.ch.traces.iter().flat_map(|t| t.bins.iter()).collect();
        let meas = |i: usize| y_over.map_or((bins[i].sf, bins[i].bias), |y| y[i]);
        let hours = if s.bias_drift { self.bin_hours() } else { Vec::new() };
        let cyc = self.ch.kind == LogKind::Cycling;
        let rows: Vec<usize> = (0..bins.len()).filter(|&i| train[i]).collect();
        let cols = Self::sf_columns(s);
        let a_sf = DMatrix::from_fn(if cyc { rows.len() } else { 0 }, cols.len(), |i, j| f.sf[rows[i]][cols[j]]);
        let y_sf = DVector::from_fn(a_sf.nrows(), |i, _| meas(rows[i]).0);
        let basis = self.bias_basis(s);
        let nb = basis[0].len();
        let np = usize::from(nl.play_r_c.is_some());
        let nc = usize::from(nl.creep.is_some());
        let nd = usize::from(s.bias_drift);
        // The paper start's basis is the identity: the sum below is then the hat weight
        // itself (its other terms are zeros), read directly. Most of a discovery's time went
        // to those sums of sixteen products.
        let identity = s.start == Start::Paper;
        let a = DMatrix::from_fn(rows.len(), nb + np + nc + nd, |i, j| {
            let b = rows[i];
            if j < nb && identity {
                f.hat[b][j]
            } else if j < nb {
                (0..GRID_POINTS).map(|g| f.hat[b][g] * basis[g][j]).sum()
            } else if j == nb && np == 1 {
                f.play[b]
            } else if j == nb + np && nc == 1 {
                f.creep[b]
            } else {
                hours[b]
            }
        });
        let y = DVector::from_fn(rows.len(), |i, _| meas(rows[i]).1);
        // Paper start: a gentle second-difference penalty keeps a sparse grid well posed.
        let pen = (s.start == Start::Paper).then_some((0usize, nb));
        Design { rows, cols, a_sf, y_sf, a, y, pen, basis, hours, drift_col: nb + np + nc }
    }

    /// The scale factor's columns of Eq. 11 (`eq11_regressors`' order) that `s` fits:
    /// 1, d, [d²], [r], [r·d], [r²].
    fn sf_columns(s: &Structure) -> Vec<usize> {
        let mut cols = vec![0usize, 1];
        for (on, c) in [(s.sf_quad, 2), (s.sf_eps, 3), (s.sf_eta, 4), (s.sf_alpha, 5)] {
            if on {
                cols.push(c);
            }
        }
        cols
    }

    /// The bias's grid basis B (`GRID_POINTS` × nb), seen through the hats in the design:
    /// 1, d, [d²] for the simple start, the identity (one value per grid point) for the
    /// paper's.
    fn bias_basis(&self, s: &Structure) -> Vec<Vec<f64>> {
        match s.start {
            Start::Simple => (0..GRID_POINTS)
                .map(|j| {
                    let d = f64::from(self.grid_temp(j) - T0_C);
                    if s.bias_quad {
                        vec![1.0, d, d * d]
                    } else {
                        vec![1.0, d]
                    }
                })
                .collect(),
            Start::Paper => {
                (0..GRID_POINTS).map(|j| (0..GRID_POINTS).map(|k| if j == k { 1.0 } else { 0.0 }).collect()).collect()
            }
        }
    }

    /// The axis model of the bias coefficients `c` (grid through `basis`, then play, creep)
    /// with `scale` and the nonlinear parameters `nl`.
    fn model_of(&self, scale: ScaleFactor, nl: &Nonlinear, basis: &[Vec<f64>], c: &[f64]) -> AxisModel {
        let nb = basis[0].len();
        let np = usize::from(nl.play_r_c.is_some());
        let grid: Vec<f32> =
            (0..GRID_POINTS).map(|g| (0..nb).map(|j| basis[g][j] * c[j]).sum::<f64>() as f32).collect();
        let mut ext = Extensions { sensor_lag: nl.lag_tau_s.map(|tau_s| SensorLag { tau_s }), ..Default::default() };
        if let Some(r) = nl.play_r_c {
            ext.bias_branch_hysteresis = Some(BranchHysteresis { half_width_c: r, weight_g: c[nb] as f32 });
        }
        if let Some((tau, e)) = nl.creep {
            ext.bias_creep = Some(Creep {
                gain_g_per_c: c[nb + np] as f32,
                tau_ref_s: tau,
                t_ref_c: CREEP_T_REF_C,
                activation_k: e,
            });
        }
        AxisModel {
            scale,
            bias: BiasGrid::single_valued(self.grid_start, self.grid_step, &grid).expect("2 to 16 grid values"),
            rate_limit_c_per_min: self.rate_limit,
            ext,
        }
    }

    /// Add to the predicted (K1, K0) the drift (`drift_per_h` × hours, on K0) and the
    /// timing offset along [`Setup::offset_basis`].
    fn add_drift_and_offset(
        &self,
        pred: &mut [(f64, f64)],
        drift_per_h: Option<f64>,
        hours: &[f64],
        offset: Option<TimingOffset>,
    ) {
        if let Some(d) = drift_per_h {
            for (p, h) in pred.iter_mut().zip(hours) {
                p.1 += d * h;
            }
        }
        if let (Some(o), Some(basis)) = (offset, &self.offset_basis) {
            for (p, d) in pred.iter_mut().zip(basis) {
                p.0 += o.seconds * d.0;
                p.1 += o.seconds * d.1;
            }
        }
    }

    /// The two channels' least squares (scale factor: `a_sf`, `y_sf`; bias: `a_b`, `y_b`
    /// with its penalty), with the timing offset δ shared by both when
    /// [`Setup::offset_basis`] is set: the data are `y = A·c + δ·p + e`, so with
    /// `r_y`, `r_p` the residuals of `y` and of the basis `p` on the scale factor's columns,
    /// δ = Σ r_y·r_p / Σ r_p² and, on each channel, `c = c_y − δ·c_p`: the exact
    /// least-squares solution on the scale factor, clamped to ±[`Setup::offset_limit_s`]
    /// (the objective is a parabola in δ, so the clamp is the constrained optimum).
    fn solve_with_offset(
        &self,
        rows: &[usize],
        (a_sf, y_sf): (&DMatrix<f64>, &DVector<f64>),
        (a_b, y_b, pen): (&DMatrix<f64>, &DVector<f64>, Option<(usize, usize)>),
    ) -> (Vec<f64>, Vec<f64>, Option<TimingOffset>) {
        let c_sf = if a_sf.nrows() > 0 { solve(a_sf, y_sf, None) } else { vec![0.0; a_sf.ncols()] };
        let c_b = solve(a_b, y_b, pen);
        let Some(basis) = self.offset_basis.as_ref().filter(|_| !rows.is_empty()) else {
            return (c_sf, c_b, None);
        };
        let p_sf = DVector::from_fn(a_sf.nrows(), |i, _| basis[rows[i]].0);
        let p_b = DVector::from_fn(a_b.nrows(), |i, _| basis[rows[i]].1);
        let cp_sf = if a_sf.nrows() > 0 { solve(a_sf, &p_sf, None) } else { vec![0.0; a_sf.ncols()] };
        let cp_b = solve(a_b, &p_b, pen);
        let resid =
            |a: &DMatrix<f64>, y: &DVector<f64>, c: &[f64]| -> DVector<f64> { y - a * DVector::from_column_slice(c) };
        let (ry_sf, rp_sf) = (resid(a_sf, y_sf, &c_sf), resid(a_sf, &p_sf, &cp_sf));
        // δ is estimated on the scale factor and applied to both channels. The bias's δ term
        // is K0'·Ṫ·δ, 0.4 µg for 9 s at 0.9 °C/min on a 3-µg/°C unit, under slow noise of
        // 1–10 µg that a white-noise weight does not see: weighted in, a 10-µg Gauss–Markov
        // bias drove δ to its limit on the lab simulator's logs. The scale factor's is μ·Ṫ·δ,
        // 16 ppm for the same 9 s on a −38 pulses/(g·s·°C) unit.
        let den = rp_sf.norm_squared();
        if den.is_nan() || den <= 0.0 {
            return (c_sf, c_b, None);
        }
        let raw = self.offset_fixed.unwrap_or_else(|| ry_sf.dot(&rp_sf) / den);
        let lim = self.offset_limit_s;
        let d = raw.clamp(-lim, lim);
        let sse = (&ry_sf - d * &rp_sf).norm_squared();
        let n = ry_sf.len().max(2) as f64;
        let se = (sse / (n - 1.0) / den).sqrt();
        let sub = |c: Vec<f64>, cp: &[f64]| c.iter().zip(cp).map(|(a, b)| a - d * b).collect::<Vec<f64>>();
        let offset =
            TimingOffset { seconds: d, se_white_s: se, at_limit: raw.abs() >= lim && self.offset_fixed.is_none() };
        (sub(c_sf, &cp_sf), sub(c_b, &cp_b), Some(offset))
    }
}

/// Least squares through the lab's one solver ([`qfa_calibrate::solver::lstsq_matrix`],
/// SVD), on `A` stacked with two kinds of weak rows:
/// * a ridge of 10⁻⁶ × each column's norm, so a column the training bins leave empty (or
///   fewer bins than columns) still gives a defined, minimal answer;
/// * with `pen = Some((from, to))`, a second-difference penalty on coefficients
///   `from..to` of weight 10⁻² × the median column norm, which keeps a sparse bias grid well
///   posed (weight 10⁻⁴ in the squared objective, against bins of unit weight).
fn solve(a: &DMatrix<f64>, y: &DVector<f64>, pen: Option<(usize, usize)>) -> Vec<f64> {
    let (n, k) = a.shape();
    if n == 0 || k == 0 {
        return vec![0.0; k];
    }
    let norm: Vec<f64> = (0..k).map(|j| a.column(j).norm()).map(|v| if v > 0.0 { v } else { 1.0 }).collect();
    let pen_rows = pen.map_or(0, |(lo, hi)| hi.saturating_sub(lo + 2));
    let mut m = DMatrix::zeros(n + k + pen_rows, k);
    m.rows_mut(0, n).copy_from(a);
    for j in 0..k {
        m[(n + j, j)] = 1e-6 * norm[j];
    }
    if let Some((lo, hi)) = pen {
        // Scaled by the median column norm: a node the training bins barely touch must not
        // set the weight (an earlier 1/rms(norm⁻¹) let one near-empty end node shrink the
        // penalty to nothing, and that node then took a coefficient of 10⁶ µg).
        let mut sorted: Vec<f64> = norm[lo..hi].to_vec();
        sorted.sort_by(f64::total_cmp);
        let w = 1e-2 * sorted[sorted.len() / 2];
        for (i, row) in qfa_calibrate::solver::second_difference_rows(k, lo, hi - lo, w).enumerate() {
            m.row_mut(n + k + i).copy_from_slice(&row);
        }
    }
    let mut yy = DVector::zeros(n + k + pen_rows);
    yy.rows_mut(0, n).copy_from(y);
    // Never fails: the ridge rows make the stacked matrix at least as tall as wide.
    qfa_calibrate::solver::lstsq_matrix(m, &yy).map_or_else(|_| vec![0.0; k], |r| r.coef)
}
