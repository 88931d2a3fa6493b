//! Least-squares fits of the simple model (Eq. 3–4) and the hysteresis model (Eq. 11 plus
//! heating and cooling bias grids), producing root-crate [`Table`]s.
//!
//! Inputs per paired row (see [`qfa_log::pairing`]): measured K1 and K0, and the firmware's
//! T̂, Ṫ, model temperature, branch and extension-slot bias of both runs (averaged, each
//! feature separately, so the pair's equation is exact for a model linear in them).
//! Consecutive rows are averaged in blocks of `block` rows before the solve (a linear
//! model's equations may be averaged; it cuts a 1.35 M-row log to some 10⁴ equations).
//!
//! Solver: nalgebra SVD of the column-scaled design matrix (each column divided by its
//! norm). The reported condition number is that of the **scaled** matrix (the one that
//! governs the error amplification of the solve); the unscaled one is given too.
//!
//! * Simple: `K1 = γ + μ·ΔT`, `K0 = k0 + k1·ΔT` (ΔT against T0 = 22 °C).
//! * Hysteresis: `K1 = Eq. 11` with ΔT and Ṫ (°C/min) as the firmware sees them;
//!   K0 on a uniform grid of `grid_points` nodes over the fitted temperature range, one
//!   value per node and branch (hat-function basis, the Unknown branch is the mean of both,
//!   as in `BiasGrid::k0`), minus the extension slots' bias. How the two branches are tied
//!   is chosen from the data, as the static fit chooses among the same [`BranchMode`]s:
//!   Single (one curve, `g` unknowns), Offset (one curve ± a constant half-step, `g + 1`)
//!   or Free (a curve per branch, `2g`), by blocked cross-validation over the fitted
//!   programs' paired rows with the one-standard-error rule (`crate::select`): the
//!   fewest-unknown mode whose held-out K0 error is within one SE of the best's. Without
//!   it, a unit whose bias is single-valued got two branches that differ by calibration
//!   noise, which the firmware then applies as a branch-switching error. Weak regularisers
//!   (weight 1, against ~10⁴ data equations) damp second differences and, in Free, tie
//!   each heating node to its cooling node, so nodes no data reach stay defined.

use std::fmt;

use qfa_thermal::model::{Branch, MAX_BIAS_POINTS};
use qfa_thermal::{AxisModel, BiasGrid, Extensions, Input, ScaleFactor, Table};

use qfa_log::pairing::{trace_run, PairedLog, Trace};
use qfa_log::replay::RATE_WINDOW;

pub(crate) use super::solver::{lstsq, LsResult};

mod branch;
mod table;
pub use crate::static_cal::fit::{fit_static_axis, BranchMode, CurveShape, StaticSeries, StaticStructure};
pub use crate::static_cal::fit::{fit_static_traced, StaticDesign, StaticFit, StaticTraces};
use branch::choose_branch_mode;
pub use branch::{BranchChoice, BranchCv};
pub use table::{fit_held_out, fit_table};

/// Reference temperature of every lab table, °C (the paper's start temperature).
pub const T0_C: f64 = 22.0;

/// Why a fit failed.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum FitError {
    /// A fit program lacks a +1 g or a −1 g run.
    NoPair(String),
    /// A fit program the log does not hold (a misspelt `--fit-programs`), with the
    /// programs it does hold.
    NotInLog {
        /// The program asked for.
        program: String,
        /// The log's programs.
        programs: Vec<String>,
    },
    /// Too few equations for the unknowns.
    TooFewRows {
        /// Equations.
        rows: usize,
        /// Unknowns.
        unknowns: usize,
    },
    /// More axes than a table holds (`qfa_thermal::table::MAX_AXES`).
    TooManyAxes,
    /// The root crate refused the table.
    Table(qfa_thermal::table::Error),
    /// A cross-validation figure could not be formed.
    Cv(CvFault),
    /// A heating/cooling step fitted on rows that hold (almost) one branch only: it would be
    /// set by a handful of rows, or split arbitrarily from the curve it is collinear with,
    /// and then applied to the whole other branch.
    BranchUnidentified {
        /// Heating rows fitted.
        heating: usize,
        /// Cooling rows fitted.
        cooling: usize,
        /// Rows each branch needs (one averaged equation).
        needed: usize,
    },
}

/// Why a cross-validation figure could not be formed.
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum CvFault {
    /// A fold holds no block.
    EmptyFold {
        /// The fold, from 0.
        fold: usize,
        /// Folds.
        folds: usize,
        /// Rows per block.
        block: usize,
        /// Paired rows.
        rows: usize,
    },
    /// Fewer than two folds: no standard error.
    TooFewFolds(usize),
    /// A fold's mean squared error is not finite.
    NonFiniteMse(f64),
    /// No candidate to choose from.
    NoCandidate,
}

impl fmt::Display for CvFault {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::EmptyFold { fold, folds, block, rows } => {
                write!(f, "fold {fold} of {folds} holds no block of {block} rows ({rows} paired rows)")
            }
            Self::TooFewFolds(k) => write!(f, "{k} cross-validation fold(s): a standard error needs 2 or more"),
            Self::NonFiniteMse(x) => write!(f, "non-finite fold MSE {x}"),
            Self::NoCandidate => f.write_str("no candidate"),
        }
    }
}

impl fmt::Display for FitError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoPair(p) => write!(f, "program `{p}` has no +1 g / −1 g pair of runs"),
            Self::NotInLog { program, programs } => {
                write!(f, "program `{program}` is not in the log (its programs: {})", programs.join(", "))
            }
            Self::TooFewRows { rows, unknowns } => write!(f, "{rows} equations for {unknowns} unknowns"),
            Self::TooManyAxes => write!(f, "more axes than a table holds"),
            Self::Table(e) => write!(f, "table rejected: {e}"),
            Self::Cv(s) => write!(f, "cross-validation: {s}"),
            Self::BranchUnidentified { heating, cooling, needed } => write!(
                f,
                "heating/cooling step not identified: {heating} heating and {cooling} cooling rows fitted; a step \
                 needs at least {needed} on each branch"
            ),
        }
    }
}

impl std::error::Error for FitError {}

/// Eq. 11's regressors in the lab's one column order, `[1, ΔT, ΔT², Ṫ, Ṫ·ΔT, Ṫ²]`, whose
/// coefficients are `[γ, μ, β, ε, η, α]` ([`scale_of_eq11`]); ΔT in °C, Ṫ in °C/min.
#[must_use]
pub fn eq11_regressors(d: f64, r: f64) -> [f64; 6] {
    [1.0, d, d * d, r, r * d, r * r]
}

/// The root crate's scale factor from coefficients in [`eq11_regressors`]' order.
#[must_use]
pub fn scale_of_eq11(c: &[f64; 6]) -> ScaleFactor {
    ScaleFactor {
        t0_c: T0_C as f32,
        gamma: c[0] as f32,
        mu: c[1] as f32,
        beta: c[2] as f32,
        epsilon: c[3] as f32,
        eta: c[4] as f32,
        alpha: c[5] as f32,
    }
}

/// Fit settings.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Programs to fit on (the others are held out).
    pub fit_programs: Vec<String>,
    /// Extension slots in force (their parameters fixed; their bias is subtracted).
    pub ext: Extensions,
    /// Branch deadband, °C/min.
    pub deadband_c_per_min: f32,
    /// Rows averaged per equation.
    pub block: usize,
    /// Bias grid nodes (2..=16).
    pub grid_points: usize,
    /// `None` (the default): the branch tie is chosen by cross-validation
    /// (`choose_branch_mode`). `Some(mode)` forces it (the CV figures are still
    /// reported, the rule says it was forced): for tests that must show a wrong tie fails.
    pub branch_mode: Option<BranchMode>,
    /// `None`: the curves' shape is chosen with the tie. `Some` forces it (the table fit on
    /// every program takes the shape the held-out fit chose).
    pub curve_shape: Option<CurveShape>,
}

impl FitOptions {
    /// Defaults for `fit_programs`: 30-s blocks at 1-s rows, 16 nodes, the firmware's
    /// flicker deadband ([`qfa_log::replay::branch_deadband_c_per_min`], 0.182 °C/min).
    #[must_use]
    pub fn new(fit_programs: Vec<String>) -> Self {
        Self {
            fit_programs,
            ext: Extensions::default(),
            deadband_c_per_min: qfa_log::replay::branch_deadband_c_per_min(),
            block: 30,
            grid_points: MAX_BIAS_POINTS,
            branch_mode: None,
            curve_shape: None,
        }
    }
}

/// The held-out rule: programs in order of first appearance; with three or more, fit on
/// the first and the last (for the paper's test: 0.3 and 0.9 °C/min, the extreme rates)
/// and hold out the rest (0.5 and 0.7); with two, fit on the first, hold out the second;
/// with one, fit and evaluate on it (then nothing is held out, and the report says so).
#[must_use]
pub fn split_programs(programs: &[String]) -> (Vec<String>, Vec<String>) {
    match programs.len() {
        0 => (vec![], vec![]),
        1 => (programs.to_vec(), programs.to_vec()),
        2 => (vec![programs[0].clone()], vec![programs[1].clone()]),
        n => (vec![programs[0].clone(), programs[n - 1].clone()], programs[1..n - 1].to_vec()),
    }
}

/// Everything the fits produce.
#[derive(Clone, Debug)]
pub struct Fitted {
    /// Simple-model table (Eq. 3–4).
    pub simple: Table,
    /// Hysteresis-model table (Eq. 11 + branched bias grid).
    pub hysteresis: Table,
    /// Scale factor, simple: [γ, μ].
    pub sf_simple: LsResult,
    /// Scale factor, Eq. 11: [γ, μ, β, ε, η, α].
    pub sf_hysteresis: LsResult,
    /// Bias, simple: [k0, k1].
    pub bias_simple: LsResult,
    /// Bias grid in the chosen branch mode's unknowns (`BranchMode::expand`): Single the
    /// nodes, Offset the nodes then the half-step, Free heating nodes then cooling nodes.
    pub bias_hysteresis: LsResult,
    /// How the grid's branches are tied, chosen by cross-validation (`choose_branch_mode`).
    pub branch: BranchChoice,
    /// Paired rows used.
    pub pairs: usize,
    /// The paired rows the fit solved, for a fit beside this one on the same equations
    /// (a production batch's population prior); shared, not copied, by a clone.
    pub rows: FitRows,
}

/// The paired rows of a fit and the blocks its equations average (see the module docs).
#[derive(Clone, Debug)]
pub struct FitRows {
    rows: std::sync::Arc<[Row]>,
    starts: Vec<usize>,
    block: usize,
}

impl FitRows {
    /// The scale factor's equations: per block, the mean of Eq. 11's regressors (in
    /// [`eq11_regressors`]' order, each averaged over the pair's two runs) and of K1.
    #[must_use]
    pub fn eq11_equations(&self) -> (Vec<[f64; 6]>, Vec<f64>) {
        let x: Vec<f64> = self.rows.iter().flat_map(|r| [1.0, r.d, r.d2, r.r, r.rd, r.r2]).collect();
        let y: Vec<f64> = self.rows.iter().map(|r| r.k1).collect();
        Self::rows_of(&block_average(&x, &y, 6, self.block, &self.starts))
    }

    /// The bias's equations in a caller's basis: per block, the mean over its rows of the
    /// mean of `basis` at the pair's two runs' (model temperature, branch), and of K0 minus
    /// the extension slots' bias, g.
    #[must_use]
    pub fn bias_equations<const N: usize>(&self, basis: impl Fn(f64, Branch) -> [f64; N]) -> (Vec<[f64; N]>, Vec<f64>) {
        let x: Vec<f64> = self
            .rows
            .iter()
            .flat_map(|r| {
                let (p, m) = (basis(r.tp, r.bp), basis(r.tm, r.bm));
                std::array::from_fn::<f64, N, _>(|j| 0.5 * (p[j] + m[j]))
            })
            .collect();
        let y: Vec<f64> = self.rows.iter().map(|r| r.k0 - r.ext_k0).collect();
        Self::rows_of(&block_average(&x, &y, N, self.block, &self.starts))
    }

    /// Every run's (model temperature, branch) of every paired row, both runs of a pair.
    pub fn temps(&self) -> impl Iterator<Item = (f64, Branch)> + '_ {
        self.rows.iter().flat_map(|r| [(r.tp, r.bp), (r.tm, r.bm)])
    }

    fn rows_of<const N: usize>((x, y): &(Vec<f64>, Vec<f64>)) -> (Vec<[f64; N]>, Vec<f64>) {
        (x.chunks_exact(N).map(|c| std::array::from_fn(|j| c[j])).collect(), y.clone())
    }
}

/// Features of one paired row.
#[derive(Clone, Copy, Debug)]
struct Row {
    k1: f64,
    k0: f64,
    d: f64,
    d2: f64,
    r: f64,
    rd: f64,
    r2: f64,
    ext_k0: f64,
    // For the grid: both runs' (temperature, branch).
    tp: f64,
    bp: Branch,
    tm: f64,
    bm: Branch,
}

fn rows_of(
    paired: &PairedLog<'_>,
    program: &str,
    ext: &Extensions,
    deadband: f32,
) -> Result<(Vec<Row>, f64), FitError> {
    let log = paired.log;
    let pp = paired.program(program).ok_or_else(|| {
        let programs = log.programs();
        if programs.iter().any(|p| p == program) {
            FitError::NoPair(program.to_string())
        } else {
            FitError::NotInLog { program: program.to_string(), programs }
        }
    })?;
    let tp: Trace = trace_run(&log.runs[pp.plus], ext, deadband);
    let tm: Trace = trace_run(&log.runs[pp.minus], ext, deadband);
    let mut out = Vec::with_capacity(pp.rows.len());
    let mut max_rate: f64 = 0.0;
    for (k, &(i, j)) in pp.rows.iter().enumerate() {
        if !(tp.valid[i] && tm.valid[j]) {
            continue;
        }
        let (k1, k0) = pp.k1_k0(log, k);
        let (dp, dm) = (tp.model_temp_c[i] - T0_C, tm.model_temp_c[j] - T0_C);
        let (rp, rm) = (tp.rate_c_per_min[i], tm.rate_c_per_min[j]);
        max_rate = max_rate.max(rp.abs()).max(rm.abs());
        let avg = |a: f64, b: f64| 0.5 * (a + b);
        out.push(Row {
            k1,
            k0,
            d: avg(dp, dm),
            d2: avg(dp * dp, dm * dm),
            r: avg(rp, rm),
            rd: avg(rp * dp, rm * dm),
            r2: avg(rp * rp, rm * rm),
            ext_k0: avg(tp.ext_k0_g[i], tm.ext_k0_g[j]),
            tp: tp.model_temp_c[i],
            bp: tp.branch[i],
            tm: tm.model_temp_c[j],
            bm: tm.branch[j],
        });
    }
    Ok((out, max_rate))
}

/// Ranges `[s, e)` of consecutive rows averaged into one equation: `block` rows each,
/// restarting at every index in `starts` (a block never straddles a program boundary or a
/// gap), the last of a segment shorter.
pub(crate) fn block_ranges(n: usize, block: usize, starts: &[usize]) -> Vec<(usize, usize)> {
    let block = block.max(1);
    let mut bounds = starts.to_vec();
    bounds.push(n);
    let mut out = Vec::new();
    for w in bounds.windows(2) {
        let mut s = w[0];
        while s < w[1] {
            let e = (s + block).min(w[1]);
            out.push((s, e));
            s = e;
        }
    }
    out
}

/// Block-average equations: `x` row-major with `p` columns.
pub(crate) fn block_average(x: &[f64], y: &[f64], p: usize, block: usize, starts: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let mut xo = Vec::new();
    let mut yo = Vec::new();
    for (s, e) in block_ranges(y.len(), block, starts) {
        let n = (e - s) as f64;
        for j in 0..p {
            xo.push((s..e).map(|i| x[i * p + j]).sum::<f64>() / n);
        }
        yo.push(y[s..e].iter().sum::<f64>() / n);
    }
    (xo, yo)
}

/// The grid node at or below temperature `t` (clamped to the grid) and the fraction of the
/// way to the next: the hat weights are `1 − f` on node `i` and `f` on node `i + 1`.
pub(crate) fn hat_node(t: f64, start: f64, step: f64, n: usize) -> (usize, f64) {
    let x = ((t - start) / step).clamp(0.0, (n - 1) as f64);
    let i = (x.floor() as usize).min(n - 2);
    (i, x - i as f64)
}

/// Hat-function weights of temperature `t` on the grid, added into `row` at `offset`.
pub(crate) fn hat(row: &mut [f64], offset: usize, t: f64, start: f64, step: f64, n: usize, w: f64) {
    let (i, f) = hat_node(t, start, step, n);
    row[offset + i] += w * (1.0 - f);
    row[offset + i + 1] += w * f;
}

pub(crate) fn grid_row(row: &mut [f64], t: f64, b: Branch, start: f64, step: f64, n: usize, w: f64) {
    match b {
        Branch::Heating => hat(row, 0, t, start, step, n, w),
        Branch::Cooling => hat(row, n, t, start, step, n, w),
        Branch::Unknown => {
            hat(row, 0, t, start, step, n, 0.5 * w);
            hat(row, n, t, start, step, n, 0.5 * w);
        }
    }
}

/// The `residual_rms_g` a table records from its fit's block-averaged bias residual, g: never
/// below [`BiasGrid::DEFAULT_RESIDUAL_RMS_G`] (4 µg, a navigation-grade QFA's bias
/// stability: a fit that matches its rows more closely than that, as on a simulated log, does
/// not make the unit more stable) nor above the largest bias a table holds.
pub(crate) fn residual_for_table(block_rms_g: f64) -> f32 {
    let floor = f64::from(BiasGrid::DEFAULT_RESIDUAL_RMS_G);
    let rms = if block_rms_g.is_finite() { block_rms_g } else { 0.0 };
    rms.clamp(floor, f64::from(qfa_thermal::table::limits::BIAS_G)) as f32
}

pub(crate) fn f32v(v: &[f64]) -> heapless::Vec<f32, MAX_BIAS_POINTS> {
    v.iter().map(|&x| x as f32).collect()
}

/// Fit both models on `opts.fit_programs` of `paired`'s log.
///
/// # Errors
/// A missing pair, too little data, or a table the root crate refuses.
pub fn fit(
    paired: &PairedLog<'_>,
    opts: &FitOptions,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<Fitted, FitError> {
    let (rows, starts, max_rate) = fit_rows(paired, opts, progress)?;
    let n = rows.len();
    // Scale factor.
    let y_k1: Vec<f64> = rows.iter().map(|r| r.k1).collect();
    let xs: Vec<f64> = rows.iter().flat_map(|r| [1.0, r.d]).collect();
    let (xb, yb) = block_average(&xs, &y_k1, 2, opts.block, &starts);
    let sf_simple = lstsq(&xb, 2, &yb)?;
    // Eq. 11's columns in `eq11_regressors`' order; each product is averaged over the
    // pair's two runs (not the product of the averages), so the columns are written out.
    let xh: Vec<f64> = rows.iter().flat_map(|r| [1.0, r.d, r.d2, r.r, r.rd, r.r2]).collect();
    let (xb, yb) = block_average(&xh, &y_k1, 6, opts.block, &starts);
    let sf_hysteresis = lstsq(&xb, 6, &yb)?;
    // Bias, simple.
    let y_k0: Vec<f64> = rows.iter().map(|r| r.k0).collect();
    let (xb, yb) = block_average(&xs, &y_k0, 2, opts.block, &starts);
    let bias_simple = lstsq(&xb, 2, &yb)?;
    let grid = grid_spec(&rows, opts.grid_points);
    let (branch, bias_hysteresis) = fit_bias_grid(&rows, &starts, grid, opts)?;
    let (heating, cooling) = branch.mode.expand_shaped(branch.shape, &bias_hysteresis.coef, grid.g);
    // The limit is what the fit rows covered plus a stated 25 % margin (the rate estimate
    // of the same program varies run to run), floored only at the branch deadband (below
    // it a rate is not told from the estimator's flicker), so `RATE_OUT_OF_RANGE` marks
    // every rate beyond the calibrated range; the former 0.5 °C/min floor claimed up to
    // 0.5 for the paper's staircases, which reach only ~0.4 (docs/lab.md, "Rate policy";
    // figures in docs/measurements.md, "Navigation").
    let rate_limit = (max_rate * 1.25).max(f64::from(opts.deadband_c_per_min)).min(20.0) as f32;
    let simple = simple_table(&sf_simple, &bias_simple, grid, rate_limit, opts.deadband_c_per_min)?;

    let h: [f64; 6] = sf_hysteresis.coef[..6].try_into().map_err(|_| FitError::TooFewRows { rows: n, unknowns: 6 })?;
    let scale_h = scale_of_eq11(&h);
    let grid_h = BiasGrid {
        t_start_c: grid.start as f32,
        t_step_c: grid.step as f32,
        deadband_c_per_min: opts.deadband_c_per_min,
        heating_g: f32v(&heating),
        cooling_g: f32v(&cooling),
        residual_rms_g: residual_for_table(bias_hysteresis.rms),
    };
    let hysteresis =
        table_of(AxisModel { scale: scale_h, bias: grid_h, rate_limit_c_per_min: rate_limit, ext: opts.ext })?;
    let rows = FitRows { rows: rows.into(), starts, block: opts.block };
    Ok(Fitted { simple, hysteresis, sf_simple, sf_hysteresis, bias_simple, bias_hysteresis, branch, pairs: n, rows })
}

/// A cycling table's structure in words, in static calibration's naming (`grid`,
/// `cubic-2-branches+lag463s`, …) after `Eq. 11 + `: the bias grid's tie and shape, and
/// the extension slots `ext` (a lag rounded to a second, a creep's τ at its reference).
#[must_use]
pub fn cycling_structure(mode: BranchMode, shape: CurveShape, ext: &Extensions) -> String {
    let s = StaticStructure {
        shape,
        branches: mode,
        lag_tau_s: ext.sensor_lag.map(|l| l.tau_s.round()),
        creep_tau_s: ext.bias_creep.map(|c| c.tau_ref_s.round()),
        play_half_width_c: ext.bias_branch_hysteresis.map(|p| p.half_width_c),
    };
    format!("Eq. 11 + {}", s.name())
}

/// The paired rows of `opts.fit_programs`, in order, with the row each program starts at
/// and the largest rate they reach, °C/min.
fn fit_rows(
    paired: &PairedLog<'_>,
    opts: &FitOptions,
    progress: Option<&indicatif::ProgressBar>,
) -> Result<(Vec<Row>, Vec<usize>, f64), FitError> {
    let mut rows: Vec<Row> = Vec::new();
    let mut starts = Vec::new();
    let mut max_rate: f64 = 0.0;
    for p in &opts.fit_programs {
        starts.push(rows.len());
        let (r, mr) = rows_of(paired, p, &opts.ext, opts.deadband_c_per_min)?;
        rows.extend(r);
        max_rate = max_rate.max(mr);
        if let Some(pb) = progress {
            pb.inc(1);
        }
    }
    Ok((rows, starts, max_rate))
}

/// The bias grid over the rows' temperatures (whole degrees, within −60…130 °C) with
/// `grid_points` nodes (2 to `MAX_BIAS_POINTS`).
fn grid_spec(rows: &[Row], grid_points: usize) -> GridSpec {
    let tmin = rows.iter().map(|r| r.tp.min(r.tm)).fold(f64::INFINITY, f64::min);
    let tmax = rows.iter().map(|r| r.tp.max(r.tm)).fold(f64::NEG_INFINITY, f64::max);
    let start = tmin.floor().max(-60.0);
    let end = tmax.ceil().min(130.0).max(start + 1.0);
    let g = grid_points.clamp(2, MAX_BIAS_POINTS);
    let step = (end - start) / (g - 1) as f64;
    GridSpec { start, step, g }
}

/// The hysteresis model's bias grid: the branch mode (chosen by cross-validation unless
/// `opts.branch_mode` forces it) and its least squares on all fit rows.
fn fit_bias_grid(
    rows: &[Row],
    starts: &[usize],
    grid: GridSpec,
    opts: &FitOptions,
) -> Result<(BranchChoice, LsResult), FitError> {
    let y_k0x: Vec<f64> = rows.iter().map(|r| r.k0 - r.ext_k0).collect();
    // How the branches are tied is the data's call (cross-validation, one-SE rule), then
    // the chosen mode is fitted on all fit rows with the fit's own blocks.
    let mut branch = choose_branch_mode(rows, &y_k0x, starts, grid, opts.block)?;
    if opts.branch_mode.is_some() || opts.curve_shape.is_some() {
        branch.mode = opts.branch_mode.unwrap_or(branch.mode);
        branch.shape = opts.curve_shape.unwrap_or(branch.shape);
        branch.rule = format!(
            "forced to {:?} on {:?} curves by the caller (FitOptions); the CV figures are for reference",
            branch.mode, branch.shape
        );
    }
    let (xg, p) = bias_design(rows, branch.shape, branch.mode, grid);
    let (mut xb, mut yb) = block_average(&xg, &y_k0x, p, opts.block, starts);
    drop(xg);
    branch.mode.push_shaped_regularisers(branch.shape, &mut xb, &mut yb, p, grid.g);
    let bias_hysteresis = lstsq(&xb, p, &yb)?;
    Ok((branch, bias_hysteresis))
}

/// The simple model's table: the linear scale factor, the linear bias sampled on `grid`.
fn simple_table(
    sf_simple: &LsResult,
    bias_simple: &LsResult,
    grid: GridSpec,
    rate_limit: f32,
    deadband_c_per_min: f32,
) -> Result<Table, FitError> {
    let GridSpec { start, step, g } = grid;
    let c = &sf_simple.coef;
    let scale_simple = ScaleFactor::simple(T0_C as f32, c[0] as f32, c[1] as f32);
    let b = &bias_simple.coef;
    let nodes: Vec<f64> = (0..g).map(|i| b[0] + b[1] * (start + step * i as f64 - T0_C)).collect();
    let mut grid_simple =
        BiasGrid::single_valued(start as f32, step as f32, &nodes.iter().map(|&x| x as f32).collect::<Vec<_>>())
            .expect("2 to 16 grid values");
    grid_simple.deadband_c_per_min = deadband_c_per_min;
    table_of(AxisModel {
        scale: scale_simple,
        bias: grid_simple,
        rate_limit_c_per_min: rate_limit,
        ext: Extensions::default(),
    })
}

/// The bias grid's nodes: `g` nodes from `start` °C every `step` °C.
#[derive(Clone, Copy, Debug)]
struct GridSpec {
    start: f64,
    step: f64,
    g: usize,
}

/// The K0 design of the paired rows in branch mode `mode` on curves of `shape` (row-major,
/// and its column count): each row is the mean of its two runs' hat functions (see
/// [`Row`]), through the shape's node basis (a cubic's nodes, as the static fit's);
/// Offset adds the half-step column, +1 on heating, −1 on cooling, 0 on Unknown (as
/// `BiasGrid::k0` takes the mean of both branches there).
fn bias_design(rows: &[Row], shape: CurveShape, mode: BranchMode, gs: GridSpec) -> (Vec<f64>, usize) {
    let (x, p) = node_design(rows, mode, gs);
    if shape == CurveShape::Nodes {
        return (x, p);
    }
    let q = mode.shaped_unknowns(shape, gs.g);
    (x.chunks(p).flat_map(|row| mode.shaped_row(shape, row, gs.g)).collect(), q)
}

/// [`bias_design`] on free nodes.
fn node_design(rows: &[Row], mode: BranchMode, gs: GridSpec) -> (Vec<f64>, usize) {
    let GridSpec { start, step, g } = gs;
    let p = mode.unknowns(g);
    let sign = |b: Branch| match b {
        Branch::Heating => 1.0,
        Branch::Cooling => -1.0,
        Branch::Unknown => 0.0,
    };
    let mut x = vec![0.0; rows.len() * p];
    for (i, r) in rows.iter().enumerate() {
        let row = &mut x[i * p..(i + 1) * p];
        match mode {
            BranchMode::Single => {
                hat(row, 0, r.tp, start, step, g, 0.5);
                hat(row, 0, r.tm, start, step, g, 0.5);
            }
            BranchMode::Offset => {
                hat(row, 0, r.tp, start, step, g, 0.5);
                hat(row, 0, r.tm, start, step, g, 0.5);
                row[g] = 0.5 * (sign(r.bp) + sign(r.bm));
            }
            BranchMode::Free => {
                grid_row(row, r.tp, r.bp, start, step, g, 0.5);
                grid_row(row, r.tm, r.bm, start, step, g, 0.5);
            }
        }
    }
    (x, p)
}

/// A validated single-axis lab table (see [`table_of_axes`]).
///
/// # Errors
/// The root crate's validation error.
pub fn table_of(axis: AxisModel) -> Result<Table, FitError> {
    table_of_axes(Input::PulseCounts, [axis])
}

/// The one place the lab builds a table: these axes, the lab's rate window
/// ([`RATE_WINDOW`] = 32), no misalignment matrix, validated by the root crate.
///
/// # Errors
/// More axes than a table holds, or the root crate's validation error.
pub fn table_of_axes(input: Input, axes: impl IntoIterator<Item = AxisModel>) -> Result<Table, FitError> {
    table_of_axes_with(input, axes, None)
}

/// [`table_of_axes`] with a misalignment matrix (row-major, applied after the per-axis
/// compensation).
///
/// # Errors
/// As [`table_of_axes`], and a matrix outside the table's limits.
pub fn table_of_axes_with(
    input: Input,
    axes: impl IntoIterator<Item = AxisModel>,
    misalignment: Option<[f32; 9]>,
) -> Result<Table, FitError> {
    let mut v = heapless::Vec::new();
    for a in axes {
        v.push(a).map_err(|_| FitError::TooManyAxes)?;
    }
    let t = Table { input, rate_window: RATE_WINDOW as u16, axes: v, misalignment, part_lsb_per_g: None };
    t.validate().map_err(FitError::Table)?;
    Ok(t)
}
