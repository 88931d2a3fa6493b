//! Model choice by the one-standard-error rule, the lab's one rule for "the simplest
//! candidate the data cannot tell from the best": the cycling fit's bias-grid branch tie
//! ([`crate::fit::fit`], on blocked cross-validation's MSE) and discovery's pick among its
//! significant effects (on their held-out gain, as a loss of −gain).
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

/// A candidate of the one-SE rule: its unknowns, its loss (lower is better) and the
/// loss's standard error.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Candidate {
    /// Unknowns (parameters) of the candidate.
    pub unknowns: usize,
    /// Its loss: a CV MSE, or a held-out gain's negative.
    pub loss: f64,
    /// The loss's standard error.
    pub se: f64,
}

/// The one-SE choice: the index of the candidate with the fewest unknowns whose loss is
/// at most the best's plus the best's standard error (among equal unknowns, the lower
/// loss; among equal losses, the first), and the indices of every candidate within that
/// limit. `None` for no candidates.
#[must_use]
pub fn one_se_rule(cands: &[Candidate]) -> Option<(usize, Vec<usize>)> {
    let best = (0..cands.len()).min_by(|&a, &b| cands[a].loss.total_cmp(&cands[b].loss))?;
    let limit = cands[best].loss + cands[best].se;
    let within: Vec<usize> = (0..cands.len()).filter(|&i| cands[i].loss <= limit).collect();
    let pick = within
        .iter()
        .copied()
        .min_by(|&a, &b| cands[a].unknowns.cmp(&cands[b].unknowns).then(cands[a].loss.total_cmp(&cands[b].loss)))?;
    Some((pick, within))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pick(c: &[(usize, f64, f64)]) -> Option<usize> {
        let c: Vec<Candidate> = c.iter().map(|&(unknowns, loss, se)| Candidate { unknowns, loss, se }).collect();
        one_se_rule(&c).map(|p| p.0)
    }

    #[test]
    fn simpler_within_one_se_wins_and_beyond_it_loses() {
        // Best (32 unknowns) 1.0 ± 0.2: the 16-unknown candidate at 1.19 is within, at 1.21 not.
        assert_eq!(pick(&[(16, 1.19, 0.1), (17, 1.1, 0.1), (32, 1.0, 0.2)]), Some(0));
        assert_eq!(pick(&[(16, 1.21, 0.1), (17, 1.1, 0.1), (32, 1.0, 0.2)]), Some(1));
        assert_eq!(pick(&[(16, 1.21, 0.1), (17, 1.25, 0.1), (32, 1.0, 0.2)]), Some(2));
        assert_eq!(pick(&[]), None);
        // A gain as a loss: gains 5 ± 1 (3 unknowns), 4.5 (1), 3.9 (1): the 1-unknown one
        // within one SE of the best is picked, and the best and it are within.
        let gains = [(3, -5.0, 1.0), (1, -4.5, 0.3), (1, -3.9, 0.2)];
        let c: Vec<Candidate> = gains.iter().map(|&(unknowns, loss, se)| Candidate { unknowns, loss, se }).collect();
        assert_eq!(one_se_rule(&c), Some((1, vec![0, 1])));
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
