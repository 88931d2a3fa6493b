//! Bias-only fit of one axis of a static log (a board at constant orientation): the
//! structures static calibration chooses among ([`StaticStructure`]: curve shape, branch
//! tie, lag, creep and play slots) and the one fitter that fits them.

use serde::Serialize;

use qfa_thermal::model::{Branch, MAX_BIAS_POINTS};
use qfa_thermal::{AxisModel, BiasGrid, Extensions, ScaleFactor};

use crate::fit::*;
use crate::solver::Factored;
use qfa_log::pairing::Trace;
use qfa_log::replay::{FirmwareRows, RowInstant};

/// How the two bias branches are tied in a static fit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum BranchMode {
    /// One curve: heating = cooling.
    Single,
    /// One curve plus a constant heating/cooling step: heating = f(T) + d, cooling = f(T) − d.
    Offset,
    /// Free nodes per branch, tied weakly as in [`fit`].
    Free,
}

impl BranchMode {
    /// Linear unknowns for `g` grid nodes.
    #[must_use]
    pub(crate) fn unknowns(self, g: usize) -> usize {
        match self {
            Self::Single => g,
            Self::Offset => g + 1,
            Self::Free => 2 * g,
        }
    }

    /// Heating and cooling nodes from this mode's first [`Self::unknowns`] coefficients.
    #[must_use]
    pub(crate) fn expand(self, c: &[f64], g: usize) -> (Vec<f64>, Vec<f64>) {
        match self {
            Self::Single => (c[..g].to_vec(), c[..g].to_vec()),
            Self::Offset => (c[..g].iter().map(|v| v + c[g]).collect(), c[..g].iter().map(|v| v - c[g]).collect()),
            Self::Free => (c[..g].to_vec(), c[g..2 * g].to_vec()),
        }
    }

    /// The weak rows (weight 1) that keep every node defined: second differences along each
    /// fitted curve, and for Free the heating–cooling ties, so a node that only one branch's
    /// data reach follows the other branch.
    pub(crate) fn push_regularisers(self, xb: &mut Vec<f64>, yb: &mut Vec<f64>, p: usize, g: usize) {
        if self == Self::Free {
            push_branch_ties(xb, yb, p, g);
        }
        let curves = if self == Self::Free { 2 } else { 1 };
        for off in (0..curves).map(|b| b * g) {
            for row in crate::solver::second_difference_rows(p, off, g, 1.0) {
                xb.extend(row);
                yb.push(0.0);
            }
        }
    }
}

/// The shape of a static bias curve over its grid nodes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum CurveShape {
    /// Every node free (`g` unknowns per curve): any shape the grid can hold.
    Nodes,
    /// The nodes on a cubic in temperature (4 unknowns per curve): the peers' own shape,
    /// stored in the same grid. Across a temperature range with no rows (a held-out block of
    /// a single ramp) it bridges smoothly where free nodes fall back to a straight line.
    Cubic,
}

impl CurveShape {
    /// Unknowns of one curve on `g` nodes.
    #[must_use]
    pub(crate) fn unknowns(self, g: usize) -> usize {
        match self {
            Self::Nodes => g,
            Self::Cubic => 4.min(g),
        }
    }
}

/// The structure of a static bias model: which firmware slots are on, with their fixed
/// nonlinear parameters (the linear weights — grid nodes or the cubic's coefficients,
/// creep gain, play weight — are fitted).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct StaticStructure {
    /// Shape of each bias curve.
    pub shape: CurveShape,
    /// Branch tie.
    pub branches: BranchMode,
    /// `sensor_lag` τ, s.
    pub lag_tau_s: Option<f32>,
    /// `bias_creep` τ (no activation), s.
    pub creep_tau_s: Option<f32>,
    /// `bias_branch_hysteresis` half-width, °C.
    pub play_half_width_c: Option<f32>,
}

impl StaticStructure {
    /// Grid only, one branch.
    pub const PLAIN: Self = Self {
        shape: CurveShape::Nodes,
        branches: BranchMode::Single,
        lag_tau_s: None,
        creep_tau_s: None,
        play_half_width_c: None,
    };

    /// Short name for reports, e.g. `grid+branch-step+lag120s+creep600s` (`cubic…` for the
    /// cubic shape).
    #[must_use]
    pub fn name(&self) -> String {
        let mut s = match self.shape {
            CurveShape::Nodes => "grid".to_string(),
            CurveShape::Cubic => "cubic".to_string(),
        };
        s.push_str(match self.branches {
            BranchMode::Single => "",
            BranchMode::Offset => "+branch-step",
            BranchMode::Free => "-2-branches",
        });
        if let Some(t) = self.lag_tau_s {
            s.push_str(&format!("+lag{t}s"));
        }
        if let Some(t) = self.creep_tau_s {
            s.push_str(&format!("+creep{t}s"));
        }
        if let Some(r) = self.play_half_width_c {
            s.push_str(&format!("+play{r}C"));
        }
        s
    }

    /// Linear unknowns for `g` grid nodes.
    #[must_use]
    pub fn unknowns(&self, g: usize) -> usize {
        self.branches.unknowns(self.shape.unknowns(g))
            + usize::from(self.creep_tau_s.is_some())
            + usize::from(self.play_half_width_c.is_some())
    }

    pub(crate) fn ext(&self, creep_gain: f32, play_weight: f32) -> Extensions {
        Extensions {
            sensor_lag: self.lag_tau_s.map(|tau_s| qfa_thermal::model::SensorLag { tau_s }),
            bias_branch_hysteresis: self
                .play_half_width_c
                .map(|half_width_c| qfa_thermal::model::BranchHysteresis { half_width_c, weight_g: play_weight }),
            bias_creep: self.creep_tau_s.map(|tau_ref_s| qfa_thermal::model::Creep {
                gain_g_per_c: creep_gain,
                tau_ref_s,
                t_ref_c: T0_C as f32,
                activation_k: 0.0,
            }),
        }
    }
}

/// A static fit of one axis.
#[derive(Clone, Debug)]
pub struct StaticFit {
    /// The fitted model (scale factor 1: a static log says nothing about it).
    pub axis: AxisModel,
    /// Its structure.
    pub structure: StaticStructure,
    /// The least-squares solve.
    pub ls: LsResult,
    /// The constant the bias is measured from, g: the axis's mean over the training rows
    /// (gravity's projection and the offset cannot be told apart at one orientation).
    pub reference_g: f64,
}

/// One static series: the firmware's view of its rows and one axis's output (g), row for
/// row. The rows' times and temperatures are reached only through the view, so a series
/// cannot pair one log's rows with another's view.
#[derive(Clone, Copy, Debug)]
pub struct StaticSeries<'a> {
    /// The firmware's view of the rows ([`StaticSeries::view_of`]), shared by every axis of
    /// a log and every model tried on it.
    pub view: &'a FirmwareRows,
    /// Axis output, g, one value per row of `view`.
    pub accel_g: &'a [f64],
}

impl StaticSeries<'_> {
    /// The firmware's view of static rows at `time_s` reading `temp_c`, each row one sample
    /// at its time, the branch switching past `deadband` (°C/min).
    #[must_use]
    pub fn view_of(time_s: &[f64], temp_c: &[f64], deadband: f32) -> FirmwareRows {
        FirmwareRows::new(time_s.iter().zip(temp_c).map(|(&t, &c)| (t, Some(c))), RowInstant::OwnReading, deadband)
    }

    /// Rows in the series.
    #[must_use]
    pub fn rows(&self) -> usize {
        self.view.rows().len()
    }

    /// The firmware's view of the series under `ext` (see [`qfa_log::pairing::trace_view`]).
    #[must_use]
    pub(crate) fn trace(&self, ext: &Extensions, deadband: f32) -> Trace {
        qfa_log::pairing::trace_view(self.view, ext, deadband)
    }

    /// The model's K0 (g) per row through the root crate's `AxisModel::evaluate`.
    #[must_use]
    pub fn model_trace(&self, axis: &AxisModel) -> Trace {
        self.model_trace_rows(axis, 0..self.rows())
    }

    /// [`Self::model_trace`] of the rows `rows` only (entry `k` is row `rows.start + k`): the
    /// model's states depend on earlier rows alone, so these rows' values are the whole
    /// series' (a cross-validation block needs no row outside it; see
    /// [`qfa_log::pairing::trace_axis_rows`]).
    #[must_use]
    pub fn model_trace_rows(&self, axis: &AxisModel, rows: std::ops::Range<usize>) -> Trace {
        qfa_log::pairing::trace_axis_rows(self.view, rows, axis)
    }
}

/// Weak rows `heating[i] − cooling[i] = 0` for the two `g`-node branches at 0 and `g`:
/// where only one branch has data, the other follows it.
pub(super) fn push_branch_ties(xb: &mut Vec<f64>, yb: &mut Vec<f64>, p: usize, g: usize) {
    for i in 0..g {
        let mut row = vec![0.0; p];
        row[i] = 1.0;
        row[g + i] = -1.0;
        xb.extend(row);
        yb.push(0.0);
    }
}

/// Fit the bias model `structure` to `series` on the rows where `train` is true.
///
/// Equations: `a − reference = grid(Te, branch) [+ creep gain·(Te − x)] [+ play weight·(Te − p)/r]`
/// per training row, with Te, branch, x and p from the root crate (unit gains), averaged in
/// blocks of `block` consecutive rows; the grid spans the training rows' Te, and, when every
/// row is fitted (the table written), their readings T̂ too, so a table never flags its own
/// log out of range; `grid_points` nodes. Weak second-difference rows (weight 1, as in [`fit`]) keep nodes
/// few data reach defined.
///
/// # Errors
/// Too few training rows, a heating/cooling step ([`BranchMode::Offset`]) on rows with
/// fewer than `block` rows on either branch ([`FitError::BranchUnidentified`]), or a table
/// the root crate refuses.
pub fn fit_static_axis(
    series: &StaticSeries<'_>,
    train: &[bool],
    structure: &StaticStructure,
    grid_points: usize,
    deadband: f32,
    block: usize,
) -> Result<StaticFit, FitError> {
    let traces = StaticTraces::new(series, structure, deadband);
    fit_static_traced(series, &traces, train, grid_points, block)
}

/// The firmware's view of a static series under one structure at unit gains: what
/// [`fit_static_traced`] regresses on. It depends on the rows' times and temperatures and
/// the structure only (not on the axis output, nor on which rows are fitted), so a caller
/// that fits one structure many times (cross-validation folds, several axes) computes it once.
#[derive(Clone, Debug)]
pub struct StaticTraces {
    /// The structure.
    pub structure: StaticStructure,
    /// Branch deadband, °C/min.
    pub deadband: f32,
    base: Trace,
    creep: Option<Trace>,
    play: Option<Trace>,
}

impl StaticTraces {
    /// Replay `series`' temperatures through the root crate under `structure`.
    #[must_use]
    pub fn new(series: &StaticSeries<'_>, structure: &StaticStructure, deadband: f32) -> Self {
        Self {
            structure: *structure,
            deadband,
            base: series.trace(&structure.ext(0.0, 0.0), deadband),
            creep: structure.creep_tau_s.map(|_| series.trace(&structure.ext(1.0, 0.0), deadband)),
            play: structure.play_half_width_c.map(|_| series.trace(&structure.ext(0.0, 1.0), deadband)),
        }
    }
}

/// [`fit_static_axis`] on traces computed beforehand (same series' times and temperatures).
///
/// # Errors
/// As [`fit_static_axis`].
pub fn fit_static_traced(
    series: &StaticSeries<'_>,
    traces: &StaticTraces,
    train: &[bool],
    grid_points: usize,
    block: usize,
) -> Result<StaticFit, FitError> {
    StaticDesign::new(traces, train, grid_points, block)?.fit(series.accel_g)
}

/// The half of a static fit that does not depend on the axis: one structure's block
/// equations on one set of training rows, factored once. A log's axes share their rows'
/// times and temperatures, so every axis (and [`StaticDesign::fit`] on each) shares this:
/// the same bits as [`fit_static_traced`] per axis, one design and one factorization
/// instead of one per axis.
pub struct StaticDesign<'t> {
    traces: &'t StaticTraces,
    /// The training rows with a valid trace.
    idx: Vec<usize>,
    /// Grid nodes.
    g: usize,
    /// The grid's first node and step, °C.
    start: f64,
    step: f64,
    /// Node values of the curve's unknowns.
    basis: Vec<Vec<f64>>,
    /// The block equations' row ranges in `idx`.
    blocks: Vec<(usize, usize)>,
    /// Block equations and all equations (with the regularisers).
    block_rows: usize,
    rows: usize,
    /// The equations, row-major (for the block RMS).
    xb: Vec<f64>,
    /// Largest rate seen, °C/min.
    max_rate: f64,
    solver: Factored,
}

impl<'t> StaticDesign<'t> {
    /// The block equations of `traces`' structure on the rows where `train` is true.
    ///
    /// # Errors
    /// As [`fit_static_axis`], but for a table the root crate refuses (that depends on the
    /// axis: [`StaticDesign::fit`]).
    pub fn new(traces: &'t StaticTraces, train: &[bool], grid_points: usize, block: usize) -> Result<Self, FitError> {
        let structure = &traces.structure;
        let g = grid_points.clamp(2, MAX_BIAS_POINTS);
        let idx = training_rows(traces, train, g, block)?;
        let (start, step) = grid_span(&traces.base, &idx, g);
        let c = structure.shape.unknowns(g);
        let basis = node_basis(structure.shape, g, c);
        let mut starts = vec![0];
        starts.extend((1..idx.len()).filter(|&k| idx[k] != idx[k - 1] + 1));
        let blocks = crate::fit::block_ranges(idx.len(), block, &starts);
        let (mut xb, max_rate) = design_blocks(traces, &idx, &blocks, &basis, start, step);
        let block_rows = blocks.len();
        let p = structure.unknowns(g);
        let mut zeros = Vec::new();
        match structure.shape {
            CurveShape::Nodes => structure.branches.push_regularisers(&mut xb, &mut zeros, p, g),
            // A cubic needs no smoothing rows; two branches are tied coefficient by
            // coefficient (weakly, as the nodes are), so a branch no row reaches follows the other.
            CurveShape::Cubic if structure.branches == BranchMode::Free => push_branch_ties(&mut xb, &mut zeros, p, c),
            CurveShape::Cubic => {}
        }
        let rows = block_rows + zeros.len();
        if rows < p {
            return Err(FitError::TooFewRows { rows, unknowns: p });
        }
        let solver = Factored::new(nalgebra::DMatrix::from_row_slice(rows, p, &xb))?;
        Ok(Self { traces, idx, g, start, step, basis, blocks, block_rows, rows, xb, max_rate, solver })
    }

    /// The fit of one axis's output `accel_g` (one value per row of the series).
    ///
    /// # Errors
    /// A solve that fails, or a table the root crate refuses.
    pub fn fit(&self, accel_g: &[f64]) -> Result<StaticFit, FitError> {
        let (structure, g) = (&self.traces.structure, self.g);
        let reference_g = self.idx.iter().map(|&i| accel_g[i]).sum::<f64>() / self.idx.len() as f64;
        // The output's block means, less `reference_g`, then zeros for the regularisers.
        let mut yb = Vec::with_capacity(self.rows);
        for &(s, e) in &self.blocks {
            let y_sum: f64 = self.idx[s..e].iter().fold(0.0, |acc, &i| acc + (accel_g[i] - reference_g));
            yb.push(y_sum / (e - s) as f64);
        }
        yb.resize(self.rows, 0.0);
        let ls = self.solver.solve(&nalgebra::DVector::from_vec(yb.clone()))?;
        let p = structure.unknowns(g);
        let ss: f64 = (0..self.block_rows)
            .map(|k| {
                let fit: f64 = (0..p).map(|j| self.xb[k * p + j] * ls.coef[j]).sum();
                (yb[k] - fit).powi(2)
            })
            .sum();
        let block_rms_g = (ss / self.block_rows.max(1) as f64).sqrt();
        let c = structure.shape.unknowns(g);
        let nb = structure.branches.unknowns(c);
        let (heating, cooling) = branch_nodes(structure, &self.basis, &ls.coef, c);
        let (creep_gain, play_weight) = extension_weights(structure, &ls.coef, nb);
        let axis = AxisModel {
            scale: ScaleFactor::simple(T0_C as f32, crate::compensate::STATIC_LSB_PER_G, 0.0),
            bias: BiasGrid {
                t_start_c: self.start as f32,
                t_step_c: self.step as f32,
                deadband_c_per_min: self.traces.deadband,
                heating_g: f32v(&heating),
                cooling_g: f32v(&cooling),
                residual_rms_g: residual_for_table(block_rms_g),
            },
            rate_limit_c_per_min: (self.max_rate * 1.25).clamp(0.5, 20.0) as f32,
            ext: structure.ext(creep_gain, play_weight),
        };
        table_of(axis.clone())?;
        Ok(StaticFit { axis, structure: *structure, ls, reference_g })
    }
}

/// The training rows with a valid trace, refused when they are too few for the
/// structure's unknowns on `g` nodes or, for [`BranchMode::Offset`], when a branch has
/// fewer than `block` of them.
fn training_rows(traces: &StaticTraces, train: &[bool], g: usize, block: usize) -> Result<Vec<usize>, FitError> {
    let (structure, base) = (&traces.structure, &traces.base);
    let idx: Vec<usize> = (0..train.len()).filter(|&i| train[i] && base.valid[i]).collect();
    let p = structure.unknowns(g);
    if idx.len() < 2 * p {
        return Err(FitError::TooFewRows { rows: idx.len(), unknowns: p });
    }
    if structure.branches == BranchMode::Offset {
        // The step is the contrast between branches: without `block` rows (one averaged
        // equation) on each, it is noise or a split of the curve's own constant, and the
        // table would apply it to every row of the branch the fit never saw. (Free needs no
        // such rule: its weak ties make an unseen branch follow the seen one.)
        let count = |b: Branch| idx.iter().filter(|&&i| base.branch[i] == b).count();
        let (heating, cooling) = (count(Branch::Heating), count(Branch::Cooling));
        if heating.min(cooling) < block.max(1) {
            return Err(FitError::BranchUnidentified { heating, cooling, needed: block.max(1) });
        }
    }
    Ok(idx)
}

/// The bias grid's first node and step, °C, for `g` nodes over the rows `idx`.
fn grid_span(base: &Trace, idx: &[usize], g: usize) -> (f64, f64) {
    // The grid spans the fitted rows' model temperature Te. A fit of every row of the
    // series (the table written) also spans their readings T̂: the firmware clamps T̂ to
    // the grid and flags TEMP_OUT_OF_RANGE beyond it, and with `sensor_lag` Te stays inside
    // T̂'s extremes, so without this the table would flag its own log. A fit of part of the
    // rows (a fold, a held-out split) keeps the Te span: its figures and the
    // cross-validation's choice are those of a grid fitted to what the rows determine.
    let all_rows = idx.len() == base.valid.iter().filter(|v| **v).count();
    let (tmin, tmax) = idx
        .iter()
        .flat_map(|&i| [base.model_temp_c[i], if all_rows { base.temp_c[i] } else { base.model_temp_c[i] }])
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), t| (lo.min(t), hi.max(t)));
    let start = tmin.floor().max(-60.0);
    let end = tmax.ceil().min(130.0).max(start + 1.0);
    let step = (end - start) / (g - 1) as f64;
    (start, step)
}

/// Node values of the curve's `c` unknowns at each of the `g` nodes: the identity for free
/// nodes; for the cubic, powers 0..=3 of the node temperature scaled to −1..1
/// (conditioning).
pub(super) fn node_basis(shape: CurveShape, g: usize, c: usize) -> Vec<Vec<f64>> {
    (0..g)
        .map(|j| match shape {
            CurveShape::Nodes => (0..g).map(|k| f64::from(u8::from(j == k))).collect(),
            CurveShape::Cubic => {
                let u = (2.0 * j as f64 / (g - 1) as f64) - 1.0;
                (0..c).map(|k| u.powi(k as i32)).collect()
            }
        })
        .collect()
}

/// One equation per block of consecutive training rows (`blocks`, ranges in `idx`; a block
/// never spans a gap in the training set): the block means of the rows' design (row-major,
/// the structure's unknowns per row), and the largest rate seen, °C/min. The output's
/// block means are the axis's own ([`StaticDesign::fit`]).
///
/// Each row's design has a few nonzero entries (two hat weights per curve through the
/// basis, the branch step, the extensions' columns), so only those are summed into the
/// block's equation: the same sums, in the same order, as averaging the full rows, without
/// forming an `n × p` matrix (that and its average were 40 % of a static calibration).
fn design_blocks(
    traces: &StaticTraces,
    idx: &[usize],
    blocks: &[(usize, usize)],
    basis: &[Vec<f64>],
    start: f64,
    step: f64,
) -> (Vec<f64>, f64) {
    let structure = &traces.structure;
    let (base, creep, play) = (&traces.base, &traces.creep, &traces.play);
    let g = basis.len();
    let p = structure.unknowns(g);
    let c = structure.shape.unknowns(g);
    let nb = structure.branches.unknowns(c);
    // Each node's nonzero basis entries (one for free nodes, four for the cubic).
    let nonzero: Vec<Vec<(usize, f64)>> =
        basis.iter().map(|bj| bj.iter().copied().enumerate().filter(|(_, v)| *v != 0.0).collect()).collect();
    let mut row = vec![0.0; p];
    let mut touched: Vec<usize> = Vec::with_capacity(p);
    let mut xb = Vec::with_capacity(blocks.len() * p);
    let mut max_rate: f64 = 0.0;
    let mut acc = vec![0.0; p];
    // Free nodes: each hat weight is its own column's one term in the row (the basis is the
    // identity, so `row[col] = 0 + w·1` is `w` exactly), added straight into the block's
    // sums: the same bits as through `row`, without its bookkeeping (which was most of the
    // cost of forming a fold's equations).
    let identity = structure.shape == CurveShape::Nodes;
    for &(s, e) in blocks {
        acc.iter_mut().for_each(|v| *v = 0.0);
        for &i in &idx[s..e] {
            let (t, b) = (base.model_temp_c[i], base.branch[i]);
            // The hat weights on the two nodes around T (heating curve, then cooling), onto
            // the curves' unknowns through the basis, in node order.
            let (j, f) = hat_node(t, start, step, g);
            let weights: [(usize, f64); 2] = match (structure.branches, b) {
                (BranchMode::Free, Branch::Cooling) => [(1, 1.0), (0, 0.0)],
                (BranchMode::Free, Branch::Unknown) => [(0, 0.5), (1, 0.5)],
                _ => [(0, 1.0), (0, 0.0)],
            };
            for (cv, w) in weights {
                if w == 0.0 {
                    continue;
                }
                for (node, hw) in [(j, w * (1.0 - f)), (j + 1, w * f)] {
                    if hw == 0.0 {
                        continue;
                    }
                    if identity {
                        acc[cv * c + node] += hw;
                        continue;
                    }
                    for &(kk, v) in &nonzero[node] {
                        let col = cv * c + kk;
                        if !touched.contains(&col) {
                            touched.push(col);
                        }
                        row[col] += hw * v;
                    }
                }
            }
            // The branch step and the extensions' columns: one term each in the row.
            let mut col = nb;
            let mut one = |col: usize, v: f64| {
                if identity {
                    acc[col] += v;
                } else {
                    row[col] = v;
                    touched.push(col);
                }
            };
            if structure.branches == BranchMode::Offset {
                one(
                    c,
                    match b {
                        Branch::Heating => 1.0,
                        Branch::Cooling => -1.0,
                        Branch::Unknown => 0.0,
                    },
                );
            }
            if let Some(tr) = creep {
                one(col, tr.ext_k0_g[i]);
                col += 1;
            }
            if let Some(tr) = play {
                one(col, tr.ext_k0_g[i]);
            }
            for &j in &touched {
                acc[j] += row[j];
                row[j] = 0.0;
            }
            touched.clear();
            max_rate = max_rate.max(base.rate_c_per_min[i].abs());
        }
        let n = (e - s) as f64;
        xb.extend(acc.iter().map(|v| v / n));
    }
    (xb, max_rate)
}

/// The heating and cooling node values from the solved coefficients.
fn branch_nodes(structure: &StaticStructure, basis: &[Vec<f64>], coef: &[f64], c: usize) -> (Vec<f64>, Vec<f64>) {
    let nodes = |u: &[f64]| -> Vec<f64> { basis.iter().map(|bj| bj.iter().zip(u).map(|(a, b)| a * b).sum()).collect() };
    // The branch step `d` is a constant on the curve's values, so it is added to the nodes,
    // never to the curve's unknowns: on a cubic those are coefficients, and `d` on each of
    // them would be `d·(1 + u + u² + u³)`, a step that vanishes at the bottom node.
    match structure.branches {
        BranchMode::Offset => {
            let mid = nodes(&coef[..c]);
            (mid.iter().map(|v| v + coef[c]).collect(), mid.iter().map(|v| v - coef[c]).collect())
        }
        BranchMode::Single | BranchMode::Free => {
            let (hc, cc) = structure.branches.expand(coef, c);
            (nodes(&hc), nodes(&cc))
        }
    }
}

/// The creep gain and the play weight (0 for a slot the structure leaves out), the
/// coefficients after the curves' `nb` unknowns.
fn extension_weights(structure: &StaticStructure, coef: &[f64], nb: usize) -> (f32, f32) {
    let mut k = nb;
    let creep_gain = if structure.creep_tau_s.is_some() {
        k += 1;
        coef[k - 1] as f32
    } else {
        0.0
    };
    let play_weight = if structure.play_half_width_c.is_some() { coef[k] as f32 } else { 0.0 };
    (creep_gain, play_weight)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A cubic with a constant heating/cooling step is fitted back with that step at every
    /// node (a step added to the cubic's coefficients instead vanished at the bottom node and
    /// was 4× too large at the top).
    #[test]
    fn cubic_with_a_branch_step_keeps_the_step_at_every_node() {
        // 0 → 60 → 0 °C at 1 °C/min, 1-s rows, 1/16-°C readings; the step is ±0.1 mg.
        let n = 7200;
        let time_s: Vec<f64> = (0..n).map(f64::from).collect();
        let temp_c: Vec<f64> = time_s
            .iter()
            .map(|t| {
                let c = if *t < 3600.0 { t / 60.0 } else { (7200.0 - t) / 60.0 };
                (c * 16.0).round() / 16.0
            })
            .collect();
        let curve = |t: f64| 1e-4 * (t - 30.0) + 2e-7 * (t - 30.0).powi(3) / 10.0;
        let accel_g: Vec<f64> =
            time_s.iter().zip(&temp_c).map(|(s, t)| curve(*t) + if *s < 3600.0 { 1e-4 } else { -1e-4 }).collect();
        let view = StaticSeries::view_of(&time_s, &temp_c, 0.05);
        let series = StaticSeries { view: &view, accel_g: &accel_g };
        let structure = StaticStructure {
            shape: CurveShape::Cubic,
            branches: BranchMode::Offset,
            lag_tau_s: None,
            creep_tau_s: None,
            play_half_width_c: None,
        };
        let fit = fit_static_axis(&series, &vec![true; n as usize], &structure, 16, 0.05, 10).unwrap();
        let b = &fit.axis.bias;
        for (h, c) in b.heating_g.iter().zip(&b.cooling_g) {
            let split = f64::from(h - c);
            assert!((split - 2e-4).abs() < 1e-5, "split {split} at a node, want 2e-4");
        }
    }
}
