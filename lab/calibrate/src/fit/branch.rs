//! The cycling fit's bias-grid branch tie and curve shape, chosen by blocked
//! cross-validation with the one-SE rule.

use serde::Serialize;

use super::{
    bias_design, block_average, block_ranges, lstsq, BranchMode, CurveShape, CvFault, FitError, GridSpec, Row,
};

/// Contiguous cross-validation folds over the cycling fit's paired rows. Chosen before any
/// result, for a standard error from ten fold MSEs; on the paper's two fit programs
/// (0.3 and 0.9 °C/min, about 49 h of rows) a fold is some 5 h of contiguous time, far
/// beyond the 30-min correlation time of the simulated bias instability.
pub(crate) const CYCLING_CV_FOLDS: usize = 10;

/// Cross-validation figures of one branch mode on one curve shape, µg.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct BranchCv {
    /// The mode.
    pub mode: BranchMode,
    /// The curves' shape.
    pub shape: CurveShape,
    /// Its linear unknowns.
    pub unknowns: usize,
    /// √(CV MSE), µg.
    pub cv_rms_ug: f64,
    /// CV MSE (mean of the fold MSEs), µg².
    pub cv_mse_ug2: f64,
    /// Its standard error, µg².
    pub cv_se_ug2: f64,
}

/// The branch tie of a cycling fit's bias grid and how it was chosen.
#[derive(Clone, Debug, Serialize)]
pub struct BranchChoice {
    /// The chosen mode.
    pub mode: BranchMode,
    /// The chosen curves' shape: free nodes, or nodes on a cubic (the stacks' own shape,
    /// which the grid holds too).
    pub shape: CurveShape,
    /// Every candidate's figures (Single, Offset, Free, each on free nodes and on a cubic).
    pub candidates: Vec<BranchCv>,
    /// The limit the chosen mode had to meet: best CV MSE + its SE, µg².
    pub limit_ug2: f64,
    /// Folds.
    pub folds: usize,
    /// The rule, in words.
    pub rule: String,
}

/// Choose the bias grid's branch tie for the paired rows `rows` (targets `y`, K0 minus the
/// extension slots) by blocked cross-validation with the one-SE rule
/// ([`crate::select`]): the rows (programs in order, each in time order) are
/// cut into [`CYCLING_CV_FOLDS`] contiguous equal chunks; for each chunk, every mode is
/// fitted (same grid, blocks and weak regularisers as the final fit) on the other chunks
/// and scored by the MSE of its residual on the held-out chunk's `block`-row K0 means.
///
/// # Errors
/// Too few rows for the folds, a failed solve, or a figure that cannot be formed.
pub(super) fn choose_branch_mode(
    rows: &[Row],
    y: &[f64],
    starts: &[usize],
    gs: GridSpec,
    block: usize,
) -> Result<BranchChoice, FitError> {
    let n = y.len();
    let k = CYCLING_CV_FOLDS;
    // Fold boundaries join the program starts, so no averaged block straddles a fold.
    let mut st: Vec<usize> =
        starts.iter().copied().chain((0..k).map(|f| (f * n).div_ceil(k))).filter(|&i| i < n).collect();
    st.sort_unstable();
    st.dedup();
    let ranges = block_ranges(n, block, &st);
    let fold_of: Vec<usize> = ranges.iter().map(|&(s, _)| s * k / n.max(1)).collect();
    let mut cands = Vec::new();
    let shapes_and_modes = [CurveShape::Nodes, CurveShape::Cubic]
        .into_iter()
        .flat_map(|s| [BranchMode::Single, BranchMode::Offset, BranchMode::Free].map(|m| (s, m)));
    for (shape, mode) in shapes_and_modes {
        let (x, p) = bias_design(rows, shape, mode, gs);
        let (xb, yb) = block_average(&x, y, p, block, &st);
        drop(x);
        let mut fold_mse = Vec::with_capacity(k);
        for f in 0..k {
            let (mut xt, mut yt) = (Vec::new(), Vec::new());
            for (b, &fb) in fold_of.iter().enumerate() {
                if fb != f {
                    xt.extend_from_slice(&xb[b * p..(b + 1) * p]);
                    yt.push(yb[b]);
                }
            }
            mode.push_shaped_regularisers(shape, &mut xt, &mut yt, p, gs.g);
            let c = lstsq(&xt, p, &yt)?.coef;
            let (mut sse, mut m) = (0.0, 0usize);
            for (b, &fb) in fold_of.iter().enumerate() {
                if fb == f {
                    let pred: f64 = xb[b * p..(b + 1) * p].iter().zip(&c).map(|(a, ci)| a * ci).sum();
                    sse += (yb[b] - pred).powi(2);
                    m += 1;
                }
            }
            if m == 0 {
                return Err(FitError::Cv(CvFault::EmptyFold { fold: f, folds: k, block, rows: n }));
            }
            fold_mse.push(sse / m as f64 * 1e12);
        }
        cands.push((shape, mode, p, crate::select::CvFigure::of_folds(&fold_mse)?));
    }
    let figs: Vec<(usize, crate::select::CvFigure)> = cands.iter().map(|&(_, _, p, f)| (p, f)).collect();
    let rule: Vec<crate::select::Candidate> =
        figs.iter().map(|&(unknowns, f)| crate::select::Candidate { unknowns, loss: f.mse, se: f.se }).collect();
    let chosen = crate::select::one_se_rule(&rule).ok_or(FitError::Cv(CvFault::NoCandidate))?.0;
    let best = figs
        .iter()
        .map(|(_, f)| *f)
        .min_by(|a, b| a.mse.total_cmp(&b.mse))
        .ok_or(FitError::Cv(CvFault::NoCandidate))?;
    Ok(BranchChoice {
        shape: cands[chosen].0,
        mode: cands[chosen].1,
        candidates: cands
            .iter()
            .map(|&(shape, mode, unknowns, f)| BranchCv {
                mode,
                shape,
                unknowns,
                cv_rms_ug: f.mse.sqrt(),
                cv_mse_ug2: f.mse,
                cv_se_ug2: f.se,
            })
            .collect(),
        limit_ug2: best.mse + best.se,
        folds: k,
        rule: format!(
            "bias-grid branch tie (Single: one curve; Offset: one curve ± a constant half-step; Free: a curve per branch), \
             each curve free nodes or nodes on a cubic in temperature (the stacks' own shape), by {k}-fold blocked \
             cross-validation over the paired rows of every program fitted (contiguous equal chunks in time), \
             scored on the held-out chunk's {block}-row K0 means; the candidate with the fewest unknowns whose CV MSE is \
             within one standard error of the best's (one-SE rule)"
        ),
    })
}
