//! Model choice by blocked cross-validation with the one-standard-error rule, shared by the
//! calibration fits that choose a structure from the data (the cycling fit's bias-grid
//! branch tie, [`crate::fit::fit`]).
//!
//! The rule (Hastie, Tibshirani & Friedman, *Elements of Statistical Learning*, §7.10):
//! each candidate's CV error is the mean of its per-fold held-out mean squared errors, with
//! standard error `sd(fold MSEs) / √folds`; the best candidate is the one with the lowest
//! CV error, and the one chosen is the candidate with the **fewest unknowns** whose CV
//! error is at most the best's plus the best's standard error. It prefers the simpler model
//! unless the data say, beyond the scatter between folds, that the richer one predicts
//! better. Folds must be long against the residual autocorrelation (contiguous blocks of
//! time), otherwise the folds are not close to independent and the SE is too small.
//! No threshold is tuned: one standard error is the rule.

use serde::Serialize;

use crate::fit::{CvFault, FitError};

/// Cross-validation figures of one candidate (units of the squared residual).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub(crate) struct CvFigure {
    /// Mean over folds of the held-out mean squared error.
    pub mse: f64,
    /// Standard error of `mse`: sample SD of the fold MSEs over √folds.
    pub se: f64,
    /// Folds.
    pub folds: usize,
}

impl CvFigure {
    /// The figure of per-fold held-out MSEs.
    ///
    /// # Errors
    /// [`FitError::Cv`] with fewer than two folds (no standard error) or a non-finite MSE:
    /// a figure that cannot be computed is an error, not a number.
    pub(crate) fn of_folds(fold_mse: &[f64]) -> Result<Self, FitError> {
        let k = fold_mse.len();
        if k < 2 {
            return Err(FitError::Cv(CvFault::TooFewFolds(k)));
        }
        if let Some(x) = fold_mse.iter().find(|x| !x.is_finite()) {
            return Err(FitError::Cv(CvFault::NonFiniteMse(*x)));
        }
        let mse = fold_mse.iter().sum::<f64>() / k as f64;
        let var = fold_mse.iter().map(|x| (x - mse).powi(2)).sum::<f64>() / (k - 1) as f64;
        Ok(Self { mse, se: (var / k as f64).sqrt(), folds: k })
    }
}

/// The one-SE choice among `(unknowns, figure)` candidates: the index of the candidate with
/// the fewest unknowns whose `mse` ≤ best `mse` + best `se` (among equal unknowns, the
/// lower `mse`). `None` for no candidates.
#[must_use]
pub(crate) fn one_se_rule(cands: &[(usize, CvFigure)]) -> Option<usize> {
    let best = (0..cands.len()).min_by(|&a, &b| cands[a].1.mse.total_cmp(&cands[b].1.mse))?;
    let limit = cands[best].1.mse + cands[best].1.se;
    (0..cands.len())
        .filter(|&i| cands[i].1.mse <= limit)
        .min_by(|&a, &b| cands[a].0.cmp(&cands[b].0).then(cands[a].1.mse.total_cmp(&cands[b].1.mse)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fig(mse: f64, se: f64) -> CvFigure {
        CvFigure { mse, se, folds: 10 }
    }

    #[test]
    fn simpler_within_one_se_wins_and_beyond_it_loses() {
        // Best (30 unknowns) 1.0 ± 0.2: the 16-unknown candidate at 1.19 is within, at 1.21 not.
        assert_eq!(one_se_rule(&[(16, fig(1.19, 0.1)), (17, fig(1.1, 0.1)), (32, fig(1.0, 0.2))]), Some(0));
        assert_eq!(one_se_rule(&[(16, fig(1.21, 0.1)), (17, fig(1.1, 0.1)), (32, fig(1.0, 0.2))]), Some(1));
        assert_eq!(one_se_rule(&[(16, fig(1.21, 0.1)), (17, fig(1.25, 0.1)), (32, fig(1.0, 0.2))]), Some(2));
        assert_eq!(one_se_rule(&[]), None);
    }

    #[test]
    fn figure_of_folds() {
        let f = CvFigure::of_folds(&[1.0, 3.0]).unwrap();
        assert_eq!((f.mse, f.folds), (2.0, 2));
        assert!((f.se - 1.0).abs() < 1e-12, "{}", f.se);
        assert!(CvFigure::of_folds(&[1.0]).is_err());
        assert!(CvFigure::of_folds(&[1.0, f64::NAN]).is_err());
    }
}
