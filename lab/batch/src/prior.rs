//! The population prior: a unit whose log is partial (one branch, or a short span) gets a
//! table that borrows what its own rows cannot show from the fleet, by empirical Bayes.
//!
//! # The model
//! Per axis, every unit's bias is `θ · x(T, branch)` with
//! `x = [1, u, u², u³, ±½]`, `u = (T − 25 °C) / 50 °C` (a cubic and a constant split,
//! scaled so the basis's columns are of one size; `±½` is the heating/cooling split: the
//! form a partial log can borrow, whatever structure each unit's own table took). The fleet's units are draws `θ ~ N(μ, Σ)`; `μ` and `Σ` are
//! the mean and covariance of the full-coverage, unflagged units' own least-squares `θ` (a unit that FAILs its limits is left out: the units that ship define the population)
//! (their sampling error is small beside the spread: `lab/tests/batch.rs` checks the units'
//! slopes to a tenth of it), the covariance's correlations shrunk toward none
//! (`shrunk_covariance`: a few units' sample correlations are mostly noise). A unit's rows give `A θ ≈ y` with the
//! noise variance `σ²` measured on its own residuals: the variance of their 60-s means,
//! times the rows per mean, so slow residuals count as what they are, not as white noise.
//! The posterior mean is `(AᵀA/σ² + Σ⁻¹)⁻¹ (Aᵀy/σ² + Σ⁻¹μ)` (solved as stacked least squares by
//! the lab's one solver, never formed): where the rows determine a
//! direction of `θ` the data win, where they cannot (the split on a heating-only log, the
//! curvature beyond a short span) the fleet does.
//!
//! The unit's stage stores its sufficient statistics (the rows reduced by the lab's solver
//! to `R` and `Qᵀy`, `σ²`, covered bins) in `unit.json`, so the prior needs no rows at the fleet stage and a merged sharded run
//! forms it as one run would.
//!
//! A QFA unit's statistics are of the same form on its cycling fit's equations
//! ([`crate::qfa::QfaNormal`]: Eq. 11's scale factor, axis `k1`, and the bias in this
//! basis, axis `k0`), and its prior table is [`crate::qfa::qfa_prior_table`].
//!
//! # What is written, and when
//! For each unit with partial coverage: `table_prior.bin` / `table_prior.toml`, a grid over
//! the fleet's median span, the posterior curve ± half its split; the certificate names it
//! as the table to flash. The share of the fleet's span × both branches the unit's own rows
//! cover (1-°C bins with at least a 10-row equation on that branch) is stated; under a half,
//! the certificate says the prior, not the unit's data, decided most of the table.

use std::fmt;

use nalgebra::{DMatrix, DVector};
use serde::{Deserialize, Serialize};

use qfa_thermal::model::Branch;

use qfa_calibrate::compensate::STATIC_LSB_PER_G;
use qfa_calibrate::fit::FitError;

/// Basis scale, °C.
pub(crate) const U_SCALE_C: f64 = 50.0;
/// Length of the residual means that measure a unit's noise, s.
pub(crate) const NOISE_MEAN_S: f64 = 60.0;
/// Rows a 1-°C bin needs on a branch to count as covered (one averaged equation).
pub(crate) const BIN_ROWS: usize = 10;
/// The rate limit of a static unit's prior table, °C/min (a static table is fitted on no
/// rate term, so no rate is beyond it).
const STATIC_RATE_LIMIT_C_PER_MIN: f32 = 20.0;
/// Below this covered share the prior decided most of the table.
pub(crate) const MOSTLY_PRIOR: f64 = 0.5;

/// The basis at temperature `t_c` on `branch` (heating `+½`, cooling `−½`, unknown 0).
#[must_use]
pub(crate) fn basis(t_c: f64, branch: Branch) -> [f64; 5] {
    let u = (t_c - super::unit::DESCRIPTOR_T_C) / U_SCALE_C;
    let s = match branch {
        Branch::Heating => 0.5,
        Branch::Cooling => -0.5,
        Branch::Unknown => 0.0,
    };
    [1.0, u, u * u, u * u * u, s]
}

/// One axis's sufficient statistics.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisNormal {
    /// Axis (for a QFA unit: `k1`, the scale factor, or `k0`, the bias).
    pub axis: String,
    /// The axis's mean over the unit's rows, g: the constant its tables are measured from
    /// (0 for a QFA unit, whose bias is absolute).
    pub mean_g: f64,
    /// `Qᵀy`'s first `p` entries for the unit's `R` ([`UnitNormal::r`]).
    pub qty: Vec<f64>,
    /// The unit's own least-squares `θ` (minimum norm, in the column-scaled basis, where its
    /// rows leave a direction undetermined).
    pub theta: Vec<f64>,
    /// Noise variance per row (see the module docs).
    pub sigma2: f64,
}

/// A unit's sufficient statistics for the prior: its rows reduced by the lab's solver
/// (`‖A·θ − y‖² = ‖R·θ − Qᵀy‖² + const`), so the fleet stage solves without the rows.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnitNormal {
    /// Rows the statistics were formed from.
    pub rows: usize,
    /// `R` of the QR of the rows' basis (rows × `p`), row-major, upper triangular; the same
    /// for every axis.
    pub r: Vec<f64>,
    /// Per axis.
    pub axes: Vec<AxisNormal>,
    /// 1-°C bins covered: `(bin, heating)`, bin = floor(T).
    pub covered: Vec<(i32, bool)>,
}

/// The statistics of one unit's rows: readings `temp_c`, the branch in force per row
/// (the firmware's), each axis `(name, g)`, row times `time_s`.
#[must_use]
pub(crate) fn normal_of(time_s: &[f64], temp_c: &[f64], branch: &[Branch], axes: &[(&str, &[f64])]) -> UnitNormal {
    let n = temp_c.len();
    let xs: Vec<[f64; 5]> = (0..n).map(|i| basis(temp_c[i], branch[i])).collect();
    let temps = temp_c.iter().copied().zip(branch.iter().copied());
    reduced_normal(&xs, axes, temps, |resid| {
        // Residual means over NOISE_MEAN_S: their variance × rows per mean.
        let means = qfa_calibrate::metrics::time_bin_means(resid.iter().copied(), time_s, NOISE_MEAN_S);
        let m = means.len().max(1) as f64;
        let mean_rows = means.iter().map(|b| b.2).sum::<usize>() as f64 / m;
        means.iter().map(|b| b.1 * b.1).sum::<f64>() / m * mean_rows
    })
}

/// The statistics of rows `xs` (`p` columns) and each axis `(name, y)` on them, with the
/// noise variance per row `sigma2` makes of an axis's residuals, and the bins `temps`
/// (every row's reading and branch) cover.
pub(crate) fn reduced_normal<const P: usize>(
    xs: &[[f64; P]],
    axes: &[(&str, &[f64])],
    temps: impl Iterator<Item = (f64, Branch)>,
    sigma2: impl Fn(&[f64]) -> f64,
) -> UnitNormal {
    let n = xs.len();
    let ys: Vec<DVector<f64>> = axes.iter().map(|(_, y)| DVector::from_column_slice(&y[..n])).collect();
    let reduced = qfa_calibrate::solver::reduce(DMatrix::from_fn(n, P, |i, j| xs[i][j]), &ys);
    let out_axes = axes
        .iter()
        .zip(&reduced.qty)
        .map(|((name, y), qty)| {
            let theta: Vec<f64> = qfa_calibrate::solver::lstsq_matrix(reduced.r.clone(), qty)
                .ok()
                .map(|ls| ls.coef)
                .filter(|c| c.len() == P)
                .unwrap_or_else(|| vec![0.0; P]);
            let resid: Vec<f64> = xs
                .iter()
                .zip(y.iter())
                .map(|(x, v)| v - x.iter().zip(&theta).map(|(a, c)| a * c).sum::<f64>())
                .collect();
            let mean_g = y.iter().take(n).sum::<f64>() / n.max(1) as f64;
            AxisNormal {
                axis: (*name).to_string(),
                mean_g,
                qty: qty.iter().take(P).copied().collect(),
                theta,
                sigma2: sigma2(&resid),
            }
        })
        .collect();
    let mut count: std::collections::BTreeMap<(i32, bool), usize> = std::collections::BTreeMap::new();
    for (t, b) in temps {
        if b != Branch::Unknown {
            *count.entry((t.floor() as i32, b == Branch::Heating)).or_default() += 1;
        }
    }
    UnitNormal {
        rows: n,
        r: reduced.r.transpose().as_slice().to_vec(),
        axes: out_axes,
        covered: count.into_iter().filter(|(_, c)| *c >= BIN_ROWS).map(|(k, _)| k).collect(),
    }
}

/// The fleet's population per axis: mean and covariance of `θ`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Population {
    /// Axis.
    pub axis: String,
    /// Units it was formed from.
    pub units: usize,
    /// Mean `θ`.
    pub mean: Vec<f64>,
    /// Covariance of `θ`, row-major.
    pub cov: Vec<f64>,
}

/// The population of each axis from the reference units' statistics.
#[must_use]
pub(crate) fn population(reference: &[&UnitNormal]) -> Vec<Population> {
    let Some(first) = reference.first() else { return Vec::new() };
    first
        .axes
        .iter()
        .filter_map(|a| {
            let p = a.theta.len();
            // Each unit's axis of the same name: units whose logs hold different axes line
            // up by name, never by position.
            let thetas: Vec<DVector<f64>> = reference
                .iter()
                .filter_map(|u| u.axes.iter().find(|x| x.axis == a.axis))
                .filter(|x| x.theta.len() == p)
                .map(|x| DVector::from_column_slice(&x.theta))
                .collect();
            let n = thetas.len();
            if n < 3 {
                return None;
            }
            let mean = thetas.iter().fold(DVector::zeros(p), |s, t| s + t) / n as f64;
            let cov = shrunk_covariance(&thetas, &mean);
            Some(Population {
                axis: a.axis.clone(),
                units: n,
                mean: mean.as_slice().to_vec(),
                cov: cov.transpose().as_slice().to_vec(),
            })
        })
        .collect()
}

/// The covariance of `thetas` about `mean`, its correlations shrunk toward none by
/// Schäfer and Strimmer's estimate of the best weight (*A shrinkage approach to large-scale
/// covariance matrix estimation*, Stat. Appl. Genet. Mol. Biol. 4, 2005, target "D": the
/// variances kept, each correlation `r` taken as `(1 − λ)·r`, `λ` the sum of the
/// correlations' sampling variances over the sum of their squares, within 0 and 1).
///
/// Why: a fleet's few reference units estimate a 5- or 6-coefficient covariance, and a
/// sample correlation of 8 units is mostly noise. Unshrunk, the posterior of a unit whose
/// rows leave a direction open followed those correlations: a simulated heating-only QFA
/// unit's ε went 2.4 fleet SDs from the fleet's mean, and its table's scale-factor error
/// against the truth grew from 11 to 40 ppm (`the_qfa_prior_helps_units_with_cut_logs`, on the
/// simulator's earlier noise streams).
fn shrunk_covariance(thetas: &[DVector<f64>], mean: &DVector<f64>) -> DMatrix<f64> {
    let (n, p) = (thetas.len() as f64, mean.len());
    let d: Vec<DVector<f64>> = thetas.iter().map(|t| t - mean).collect();
    let mut cov = DMatrix::<f64>::zeros(p, p);
    for x in &d {
        cov += x * x.transpose();
    }
    cov /= n - 1.0;
    let sd: Vec<f64> = (0..p).map(|i| cov[(i, i)].sqrt()).collect();
    if sd.iter().any(|s| s.is_nan() || *s <= 0.0) {
        // A coefficient the fleet never varied: no correlation to shrink (the posterior's
        // floor keeps the matrix positive definite).
        return cov;
    }
    // Standardized products w_kij = z_ki·z_kj: their mean is the sample correlation (times
    // (n−1)/n), their spread its sampling variance.
    let (mut sum_var, mut sum_sq) = (0.0, 0.0);
    for i in 0..p {
        for j in 0..p {
            if i == j {
                continue;
            }
            let w: Vec<f64> = d.iter().map(|x| x[i] / sd[i] * (x[j] / sd[j])).collect();
            let w_mean = w.iter().sum::<f64>() / n;
            sum_var += n / (n - 1.0).powi(3) * w.iter().map(|v| (v - w_mean).powi(2)).sum::<f64>();
            sum_sq += (cov[(i, j)] / (sd[i] * sd[j])).powi(2);
        }
    }
    let lambda = if sum_sq > 0.0 { (sum_var / sum_sq).clamp(0.0, 1.0) } else { 1.0 };
    for i in 0..p {
        for j in 0..p {
            if i != j {
                cov[(i, j)] *= 1.0 - lambda;
            }
        }
    }
    cov
}

/// The posterior mean `θ` of one axis of a unit (module docs); `None` when the
/// population's covariance is not positive definite, or its size is not the unit's.
///
/// Solved by the lab's one solver as stacked least squares: the unit's reduced rows
/// `R·θ ≈ Qᵀy` over `σ`, and the population's `L⁻¹·θ ≈ L⁻¹·μ` with `Σ = L·Lᵀ`, whose
/// normal equations are the module docs' posterior.
#[must_use]
pub(crate) fn posterior(unit: &UnitNormal, axis: usize, pop: &Population) -> Option<Vec<f64>> {
    let a = unit.axes.get(axis)?;
    let p = a.theta.len();
    if pop.mean.len() != p || pop.cov.len() != p * p || unit.r.len() != p * p || a.qty.len() != p {
        return None;
    }
    let cov = DMatrix::from_row_slice(p, p, &pop.cov);
    // A floor on the prior's variance per direction (1e-9 of its largest) keeps Σ
    // positive definite when the fleet never varied a coefficient (a split of zero everywhere).
    let floor = 1e-9 * cov.diagonal().max().max(f64::MIN_POSITIVE);
    let l_inv = qfa_calibrate::solver::prior_rows(cov + DMatrix::from_diagonal_element(p, p, floor))?;
    let s = a.sigma2.max(f64::MIN_POSITIVE).sqrt();
    let mut m = DMatrix::zeros(2 * p, p);
    m.rows_mut(0, p).copy_from(&(DMatrix::from_row_slice(p, p, &unit.r) / s));
    m.rows_mut(p, p).copy_from(&l_inv);
    let mut rhs = DVector::zeros(2 * p);
    rhs.rows_mut(0, p).copy_from(&(DVector::from_column_slice(&a.qty) / s));
    rhs.rows_mut(p, p).copy_from(&(&l_inv * DVector::from_column_slice(&pop.mean)));
    let theta = qfa_calibrate::solver::lstsq_matrix(m, &rhs).ok()?.coef;
    (theta.len() == p && theta.iter().all(|v| v.is_finite())).then_some(theta)
}

/// The share of the fleet's `span` (°C, both branches) a unit's covered bins hold.
#[must_use]
pub(crate) fn covered_share(unit: &UnitNormal, span: (f64, f64)) -> f64 {
    let (lo, hi) = (span.0.floor() as i32, span.1.ceil() as i32 - 1);
    let total = (2 * (hi - lo + 1)).max(1) as f64;
    let inside = unit.covered.iter().filter(|(b, _)| (lo..=hi).contains(b)).count() as f64;
    inside / total
}

/// A flashable axis model for bias curve `theta` over `span` (°C): 16 nodes, heating = the
/// curve + half the split, cooling − half, the bias measured from `reference_g`; `scale`
/// and `rate_limit` (°C/min) as given.
#[must_use]
pub(crate) fn axis_model(
    theta: &[f64],
    span: (f64, f64),
    reference_g: f64,
    deadband: f32,
    scale: qfa_thermal::ScaleFactor,
    rate_limit_c_per_min: f32,
) -> qfa_thermal::AxisModel {
    let g = qfa_thermal::model::MAX_BIAS_POINTS;
    let start = span.0.floor();
    let end = span.1.ceil().max(start + 2.0);
    let step = (end - start) / (g - 1) as f64;
    let node = |j: usize, b: Branch| {
        let x = basis(start + step * j as f64, b);
        (x.iter().zip(theta).map(|(a, c)| a * c).sum::<f64>() - reference_g) as f32
    };
    let heating: heapless::Vec<f32, { qfa_thermal::model::MAX_BIAS_POINTS }> =
        (0..g).map(|j| node(j, Branch::Heating)).collect();
    let cooling: heapless::Vec<f32, { qfa_thermal::model::MAX_BIAS_POINTS }> =
        (0..g).map(|j| node(j, Branch::Cooling)).collect();
    qfa_thermal::AxisModel {
        scale,
        bias: qfa_thermal::BiasGrid {
            t_start_c: start as f32,
            t_step_c: step as f32,
            deadband_c_per_min: deadband,
            heating_g: heating,
            cooling_g: cooling,
            // The prior's curve comes from the fleet, not from a fit to this unit's rows: no
            // residual of its own, so the threshold a hand-written grid has.
            residual_rms_g: qfa_thermal::BiasGrid::DEFAULT_RESIDUAL_RMS_G,
        },
        rate_limit_c_per_min,
        ext: qfa_thermal::Extensions::default(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With a population far tighter than the noise the posterior is the population's
    /// mean; with a vague population it is the unit's own fit; a direction the rows do not
    /// reach (the split, on one branch) comes from the population either way.
    #[test]
    fn the_posterior_leans_on_whichever_knows_more() {
        let temps: Vec<f64> = (0..600).map(|i| 20.0 + 0.05 * f64::from(i)).collect();
        let time: Vec<f64> = (0..600).map(f64::from).collect();
        let branch = vec![Branch::Heating; 600];
        let own = [0.01, 0.002, 0.0, 0.0, 0.0];
        let y: Vec<f64> =
            temps.iter().map(|&t| basis(t, Branch::Heating).iter().zip(&own).map(|(a, b)| a * b).sum()).collect();
        let u = normal_of(&time, &temps, &branch, &[("ax", &y)]);
        // A noise floor for the exact data: a tenth of a mg.
        let mut u = u;
        u.axes[0].sigma2 = 1e-8;
        let mean = vec![0.0, 0.001, 0.0, 0.0, 4e-4];
        let pop = |var: f64| Population {
            axis: "ax".into(),
            units: 10,
            mean: mean.clone(),
            cov: DMatrix::from_diagonal_element(5, 5, var).as_slice().to_vec(),
        };
        let tight = posterior(&u, 0, &pop(1e-16)).unwrap();
        let vague = posterior(&u, 0, &pop(1.0)).unwrap();
        for k in 0..4 {
            assert!((tight[k] - mean[k]).abs() < 1e-6, "tight {k}: {tight:?}");
        }
        // Vague: the unit's own curve, in what its rows determine (on one branch, the
        // constant and the split only as `constant + split/2`).
        for k in 1..4 {
            assert!((vague[k] - own[k]).abs() < 1e-5, "vague {k}: {vague:?}");
        }
        assert!((vague[0] + 0.5 * vague[4] - own[0]).abs() < 1e-5, "vague: {vague:?}");
        // The split is collinear with the constant on one branch: the rows fix only
        // constant + split/2, and with a tight prior on the split the fleet's value stands.
        let split = posterior(
            &u,
            0,
            &Population {
                cov: {
                    let mut c = vec![0.0; 25];
                    for k in 0..4 {
                        c[k * 6] = 1.0;
                    }
                    c[24] = 1e-16;
                    c
                },
                ..pop(1.0)
            },
        )
        .unwrap();
        assert!((split[4] - 4e-4).abs() < 1e-8, "{split:?}");
        assert!((split[0] + 0.5 * split[4] - own[0]).abs() < 1e-5, "{split:?}");
    }

    /// A unit logged over a narrow span (here 0.4 °C, u within 0.008): the cubic's columns
    /// are nearly collinear, cond(A) about 10⁷, so `AᵀA` (cond 10¹⁴) keeps no digit of the
    /// cubic term. The rows reduced by QR keep cond(A): exact data are fitted to their rounding.
    #[test]
    fn a_narrow_span_is_fitted_without_squaring_its_condition() {
        let n = 400;
        let temps: Vec<f64> = (0..n).map(|i| 30.0 + 0.001 * f64::from(i)).collect();
        let time: Vec<f64> = (0..n).map(f64::from).collect();
        let own = [0.01, 0.02, -0.3, 5.0, 0.0];
        let y: Vec<f64> =
            temps.iter().map(|&t| basis(t, Branch::Heating).iter().zip(&own).map(|(a, b)| a * b).sum()).collect();
        let u = normal_of(&time, &temps, &[Branch::Heating; 400], &[("ax", &y)]);
        let theta = u.axes[0].theta.clone();
        let worst = temps
            .iter()
            .zip(&y)
            .map(|(&t, v)| (basis(t, Branch::Heating).iter().zip(&theta).map(|(a, b)| a * b).sum::<f64>() - v).abs())
            .fold(0.0, f64::max);
        // Independent check: the residual of an exact cubic is rounding, far below 1 ng.
        assert!(worst < 1e-12, "worst residual {worst:e} g, theta {theta:?}");
    }

    /// Against draws whose covariance is known: among 8 units of independent coefficients
    /// the shrunk correlations are nearer the truth (none) than the sample's, RMS over 200
    /// fleets; among 60 units with a true correlation of 0.9, most of it is kept. The
    /// variances are the sample's either way.
    #[test]
    fn the_population_shrinks_noise_correlations_and_keeps_real_ones() {
        let mut rng = qfa_rng::seeded(7);
        let draw = |rng: &mut qfa_rng::LabRng, n: usize, rho: f64| -> Vec<DVector<f64>> {
            (0..n)
                .map(|_| {
                    let (a, b, c) = (qfa_rng::normal(rng), qfa_rng::normal(rng), qfa_rng::normal(rng));
                    DVector::from_vec(vec![a, rho * a + (1.0 - rho * rho).sqrt() * b, 3.0 * c])
                })
                .collect()
        };
        let corr = |c: &DMatrix<f64>, i: usize, j: usize| c[(i, j)] / (c[(i, i)] * c[(j, j)]).sqrt();
        let mean_of = |t: &[DVector<f64>]| t.iter().fold(DVector::zeros(3), |s, x| s + x) / t.len() as f64;
        let sample = |t: &[DVector<f64>], m: &DVector<f64>| {
            t.iter().fold(DMatrix::zeros(3, 3), |s, x| s + (x - m) * (x - m).transpose()) / (t.len() - 1) as f64
        };
        let (mut shrunk_sq, mut sample_sq, mut kept) = (0.0, 0.0, 0.0);
        for _ in 0..200 {
            let t = draw(&mut rng, 8, 0.0);
            let m = mean_of(&t);
            let (c, s) = (shrunk_covariance(&t, &m), sample(&t, &m));
            for (i, j) in [(0, 1), (0, 2), (1, 2)] {
                shrunk_sq += corr(&c, i, j).powi(2);
                sample_sq += corr(&s, i, j).powi(2);
            }
            assert!((c[(0, 0)] - s[(0, 0)]).abs() < 1e-12 * s[(0, 0)], "the variances are the sample's");
            let t = draw(&mut rng, 60, 0.9);
            kept += corr(&shrunk_covariance(&t, &mean_of(&t)), 0, 1) / 200.0;
        }
        let (shrunk, sample) = ((shrunk_sq / 600.0).sqrt(), (sample_sq / 600.0).sqrt());
        assert!(
            shrunk < 0.7 * sample,
            "RMS correlation among independent draws: shrunk {shrunk:.3}, sample {sample:.3}"
        );
        assert!(kept > 0.8, "mean correlation kept of a true 0.9 among 60: {kept:.2}");
    }

    #[test]
    fn a_unit_without_a_population_gets_no_prior_table_and_is_told_which_axis() {
        let temps: Vec<f64> = (0..100).map(|i| 20.0 + 0.1 * f64::from(i)).collect();
        let time: Vec<f64> = (0..100).map(f64::from).collect();
        let u = normal_of(&time, &temps, &[Branch::Heating; 100], &[("ay", &temps)]);
        let e = prior_table(&u, &[], (20.0, 30.0), 0.1).unwrap_err();
        assert!(matches!(&e, PriorError::NoPopulation(axis) if axis == "ay"), "{e:?}");
        assert_eq!(e.to_string(), "ay: no population");
    }
}

/// How a unit's table came from the prior.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PriorUse {
    /// The file written (`table_prior.bin`, with its `.toml`).
    pub table: String,
    /// The CRC-32 in its header.
    pub table_crc32: String,
    /// Share of the fleet's span × both branches the unit's own rows cover.
    pub covered_share: f64,
    /// The prior decided most of the table (`covered_share` under `MOSTLY_PRIOR`).
    pub mostly_prior: bool,
}

/// Why a unit's prior table could not be formed (the unit keeps its own table, and its
/// certificate says why).
#[derive(Clone, Debug, PartialEq)]
#[non_exhaustive]
pub enum PriorError {
    /// The fleet has no population for this axis of the unit.
    NoPopulation(String),
    /// The posterior of this axis cannot be formed: the population's covariance is not
    /// positive definite, or the stacked solve failed.
    NotInvertible(String),
    /// The table of the posterior curves was refused.
    Table(FitError),
}

impl fmt::Display for PriorError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoPopulation(axis) => write!(f, "{axis}: no population"),
            Self::NotInvertible(axis) => write!(f, "{axis}: the population cannot be inverted"),
            Self::Table(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for PriorError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // The message is the fit's own: the chain goes on from its source.
            Self::Table(e) => e.source(),
            Self::NoPopulation(_) | Self::NotInvertible(_) => None,
        }
    }
}

/// The table of one unit's posterior over `span`, or why there is none.
///
/// # Errors
/// No population for an axis, a posterior that cannot be formed, or a table the root
/// crate refuses ([`PriorError`]).
pub fn prior_table(
    unit: &UnitNormal,
    pops: &[Population],
    span: (f64, f64),
    deadband: f32,
) -> Result<qfa_thermal::Table, PriorError> {
    let mut axes = Vec::new();
    for (k, a) in unit.axes.iter().enumerate() {
        let pop = pops.iter().find(|p| p.axis == a.axis).ok_or_else(|| PriorError::NoPopulation(a.axis.clone()))?;
        let theta = posterior(unit, k, pop).ok_or_else(|| PriorError::NotInvertible(a.axis.clone()))?;
        // The bias is measured from the unit's own mean over its rows, as its own table's.
        let scale = qfa_thermal::ScaleFactor::simple(super::unit::DESCRIPTOR_T_C as f32, STATIC_LSB_PER_G, 0.0);
        axes.push(axis_model(&theta, span, a.mean_g, deadband, scale, STATIC_RATE_LIMIT_C_PER_MIN));
    }
    qfa_calibrate::fit::table_of_axes(qfa_thermal::Input::Samples, axes).map_err(PriorError::Table)
}
