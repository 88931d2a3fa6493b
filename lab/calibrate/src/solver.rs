//! The lab's one least-squares solver: a Householder QR of the column-scaled design matrix
//! (each column divided by its norm), then the SVD of its small triangular factor; the
//! condition number reported is the scaled matrix's.

use nalgebra::{DMatrix, DVector};
use serde::Serialize;

use super::fit::FitError;

/// A least-squares solution.
#[derive(Clone, Debug, Serialize)]
pub struct LsResult {
    /// Coefficients.
    pub coef: Vec<f64>,
    /// Condition number of the column-scaled design matrix.
    pub cond: f64,
    /// RMS residual of the (block-averaged) equations.
    pub rms: f64,
    /// Equations.
    pub rows: usize,
}

/// Solve `min ‖X·c − y‖` with `X` row-major (`p` columns), as [`lstsq_matrix`].
///
/// # Errors
/// [`FitError::TooFewRows`].
pub fn lstsq(x: &[f64], p: usize, y: &[f64]) -> Result<LsResult, FitError> {
    let n = y.len();
    if n < p || p == 0 {
        return Err(FitError::TooFewRows { rows: n, unknowns: p });
    }
    lstsq_matrix(DMatrix::from_row_slice(n, p, x), &DVector::from_column_slice(y))
}

/// The lab's one least-squares solver: `min ‖A·c − y‖` with each column of `A` divided by
/// its norm, by a Householder QR of `A` and the SVD of its `p × p` factor (singular values below 10⁻¹² of the largest are cut).
/// Never the normal equations, which square the condition number.
///
/// # Errors
/// [`FitError::TooFewRows`] when `A` has fewer rows than columns or none.
pub fn lstsq_matrix(m: DMatrix<f64>, y: &DVector<f64>) -> Result<LsResult, FitError> {
    Factored::new(m)?.solve(y)
}

/// A design matrix factored once, for several right-hand sides (a static log's axes share
/// their rows, so their fits share the design): [`lstsq_matrix`] is [`Factored::new`] then
/// [`Factored::solve`], so one right-hand side solved either way gives the same bits.
pub struct Factored {
    /// `A` with each column divided by its norm.
    scaled: DMatrix<f64>,
    /// The column norms.
    norms: Vec<f64>,
    qr: nalgebra::linalg::QR<f64, nalgebra::Dyn, nalgebra::Dyn>,
    svd: nalgebra::linalg::SVD<f64, nalgebra::Dyn, nalgebra::Dyn>,
}

impl Factored {
    /// Scale `m`'s columns, then its Householder QR and the SVD of the `p × p` factor.
    ///
    /// # Errors
    /// [`FitError::TooFewRows`] when `m` has fewer rows than columns or none.
    pub fn new(mut m: DMatrix<f64>) -> Result<Self, FitError> {
        let (n, p) = m.shape();
        if n < p || p == 0 {
            return Err(FitError::TooFewRows { rows: n, unknowns: p });
        }
        let norms: Vec<f64> = (0..p).map(|j| m.column(j).norm().max(f64::MIN_POSITIVE)).collect();
        for (j, nj) in norms.iter().enumerate() {
            m.column_mut(j).scale_mut(1.0 / nj);
        }
        // Householder QR first, then the SVD of the small `p × p` factor: `A = Q·R` has the
        // singular values of `R`, and `Qᵀ·y` carries everything of `y` the fit can reach. The
        // SVD of the tall `A` itself (with its `n × p` left vectors) cost 40 % of a static
        // calibration; this costs one Householder pass over `A`.
        let qr = m.clone().qr();
        let svd = qr.r().svd(true, true);
        Ok(Self { scaled: m, norms, qr, svd })
    }

    /// The solution for the right-hand side `y` (one value per row of `A`).
    ///
    /// # Errors
    /// [`FitError::TooFewRows`] when the SVD cannot solve it.
    pub fn solve(&self, y: &DVector<f64>) -> Result<LsResult, FitError> {
        let (n, p) = self.scaled.shape();
        let mut qty = y.clone();
        self.qr.q_tr_mul(&mut qty);
        let qty = qty.rows(0, p).into_owned();
        let svd = &self.svd;
        let cond = svd.singular_values.max() / svd.singular_values.min();
        let c = svd
            .solve(&qty, 1e-12 * svd.singular_values.max())
            .map_err(|_| FitError::TooFewRows { rows: n, unknowns: p })?;
        let resid = &self.scaled * &c - y;
        let rms = (resid.norm_squared() / n as f64).sqrt();
        let coef = c.iter().zip(&self.norms).map(|(ci, nj)| ci / nj).collect();
        Ok(LsResult { coef, cond, rms, rows: n })
    }
}

/// A least-squares problem `min ‖A·c − y‖` reduced to `p` equations by the Householder QR
/// that [`lstsq_matrix`] also starts with: `A = Q·R`, so `‖A·c − y‖² = ‖R·c − Qᵀy‖² + const`
/// over the first `p` entries of `Qᵀy`. A caller that must keep a problem's statistics
/// without its rows (a batch unit's, for the fleet's prior) keeps `R` and `Qᵀy`, and solves
/// later by stacking them with other equations into [`lstsq_matrix`]: never `AᵀA`, which
/// squares the condition number.
#[derive(Clone, Debug, PartialEq)]
pub struct Reduced {
    /// `R`, `p × p` upper triangular (zero rows where `A` had fewer than `p`).
    pub r: DMatrix<f64>,
    /// `Qᵀy`'s first `p` entries, one vector per right-hand side.
    pub qty: Vec<DVector<f64>>,
}

/// [`Reduced`] of `A` for each right-hand side in `ys` (each of `A`'s row count).
#[must_use]
pub fn reduce(a: DMatrix<f64>, ys: &[DVector<f64>]) -> Reduced {
    let (n, p) = a.shape();
    let k = n.min(p);
    let qr = a.qr();
    let mut r = DMatrix::zeros(p, p);
    r.rows_mut(0, k).copy_from(&qr.r());
    let qty = ys
        .iter()
        .map(|y| {
            let mut v = y.clone();
            qr.q_tr_mul(&mut v);
            let mut z = DVector::zeros(p);
            z.rows_mut(0, k).copy_from(&v.rows(0, k));
            z
        })
        .collect();
    Reduced { r, qty }
}

/// Rows `W` with `Wᵀ·W = Σ⁻¹` for a positive definite covariance `Σ` (`W = L⁻¹`, `Σ = L·Lᵀ`):
/// a Gaussian prior `c ~ N(μ, Σ)` enters [`lstsq_matrix`] as the equations `W·c ≈ W·μ`,
/// so a posterior is one stacked solve. `None` when `Σ` is not positive definite.
#[must_use]
pub fn prior_rows(cov: DMatrix<f64>) -> Option<DMatrix<f64>> {
    let p = cov.nrows();
    cov.cholesky()?.l().solve_lower_triangular(&DMatrix::identity(p, p))
}

/// The lab's one smoothness regulariser of a bias grid, for every fitter that has one
/// (the cycling and static fits, discovery): one row per interior node,
/// `weight·(c[off+i−1] − 2·c[off+i] + c[off+i+1]) = 0`, over the `g` nodes at column `off`
/// of a `p`-column design. The weight is the caller's: 1 against unit-weight rows in the
/// calibration fits, scaled to the column norms in discovery's bin-averaged problem.
pub fn second_difference_rows(p: usize, off: usize, g: usize, weight: f64) -> impl Iterator<Item = Vec<f64>> {
    (1..g.saturating_sub(1)).map(move |i| {
        let mut row = vec![0.0; p];
        for (d, c) in [1.0, -2.0, 1.0].into_iter().enumerate() {
            row[off + i - 1 + d] = weight * c;
        }
        row
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows vanish on a straight grid and measure a bend: second differences of
    /// `c = i²` are 2 at every interior node, times the weight.
    #[test]
    fn second_differences_vanish_on_lines_and_measure_curvature() {
        let (p, off, g) = (9, 2, 6);
        let rows: Vec<Vec<f64>> = second_difference_rows(p, off, g, 0.5).collect();
        assert_eq!(rows.len(), g - 2);
        let apply = |c: &dyn Fn(usize) -> f64| -> Vec<f64> {
            rows.iter()
                .map(|r| (0..p).map(|j| r[j] * if (off..off + g).contains(&j) { c(j - off) } else { 7.0 }).sum())
                .collect()
        };
        assert!(apply(&|i| 3.0 - 0.25 * i as f64).iter().all(|v| v.abs() < 1e-12));
        assert_eq!(apply(&|i| (i * i) as f64), vec![1.0; g - 2]);
    }
}
