//! What users pick today, fitted on the same training rows as the project's model and
//! scored on the same held-out rows ([`crate::export`] writes the cubic in the formats those
//! stacks load, refitted on every row of the log, as the flashed table is).
//!
//! * **Cubic** (PX4 thermal compensation, the tofupilot template): bias =
//!   `X0 + X1·dT + X2·dT² + X3·dT³`, `dT = clamp(T, TMIN, TMAX) − TREF`, least squares over
//!   every training row (the tofupilot way; PX4's on-board learner uses only the heating
//!   part). `TREF` is the middle of the training range, `TMIN`/`TMAX` its ends.
//! * **ArduPilot TCAL**: the same cubic about a fixed 35 °C, fitted the way the
//!   `INS_TCALn` learner does it (`AP_InertialSensor_tempcal.cpp`): one averaged point per
//!   0.5 °C *rise* of the temperature, from the learner's start; here the learner starts at
//!   the coldest training row, as a user would start it on a cold-soaked board. Powers 1..3
//!   are the parameters; the constant is what ArduPilot's ordinary accelerometer
//!   calibration takes up at its calibration temperature.
//! * **Paper simple**: bias linear in T (the paper's Eq. 4).
//!
//! Every peer is scored with its constant fitted on the training rows (for PX4 and
//! ArduPilot the constant is the job of the ordinary accelerometer calibration, which is
//! given the benefit of the doubt here). The peers see the raw temperature reading, as
//! those stacks do.

use serde::Serialize;

use crate::fit::{lstsq, FitError};

/// ArduPilot's fixed reference temperature, °C.
pub(crate) const ARDUPILOT_TREF_C: f64 = 35.0;

/// ArduPilot stores coefficients × 10⁶.
pub(crate) const ARDUPILOT_SCALE: f64 = 1.0e6;

/// A polynomial of bias (g) in temperature, clamped to its range.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Poly {
    /// Reference temperature, °C.
    pub tref_c: f64,
    /// Clamp range, °C.
    pub tmin_c: f64,
    /// Clamp range, °C.
    pub tmax_c: f64,
    /// Coefficients of dT⁰, dT¹, … (g/°Cᵏ).
    pub coef: Vec<f64>,
}

impl Poly {
    /// Bias at temperature `t_c`, g.
    #[must_use]
    pub fn eval(&self, t_c: f64) -> f64 {
        let d = t_c.clamp(self.tmin_c, self.tmax_c) - self.tref_c;
        self.coef.iter().rev().fold(0.0, |acc, c| acc * d + c)
    }

    /// Least-squares fit of degree `deg` to `(t, y)`.
    ///
    /// # Errors
    /// Too few points.
    pub(crate) fn fit(
        t: &[f64],
        y: &[f64],
        deg: usize,
        tref_c: f64,
        tmin_c: f64,
        tmax_c: f64,
    ) -> Result<Self, FitError> {
        let p = deg + 1;
        let x: Vec<f64> = t.iter().flat_map(|&ti| (0..p).map(move |k| (ti - tref_c).powi(k as i32))).collect();
        let ls = lstsq(&x, p, y)?;
        Ok(Self { tref_c, tmin_c, tmax_c, coef: ls.coef })
    }
}

/// The peers of one axis.
#[derive(Clone, Debug, Serialize)]
pub struct Peers {
    /// PX4 / tofupilot cubic.
    pub cubic: Poly,
    /// ArduPilot TCAL cubic (about 35 °C).
    pub ardupilot: Poly,
    /// Points the ArduPilot learner formed.
    pub ardupilot_points: usize,
    /// The paper's simple model (linear).
    pub simple: Poly,
}

/// The ArduPilot learner's points: mean output and mid temperature of each 0.5 °C rise.
fn ardupilot_points(t: &[f64], y: &[f64]) -> (Vec<f64>, Vec<f64>) {
    let (mut pt, mut py) = (Vec::new(), Vec::new());
    let Some(start) = (0..t.len()).min_by(|&a, &b| t[a].total_cmp(&t[b])) else { return (pt, py) };
    let mut last = t[start];
    let (mut sum, mut n) = (0.0, 0usize);
    for i in start..t.len() {
        sum += y[i];
        n += 1;
        if t[i] - last >= 0.5 {
            pt.push(0.5 * (t[i] + last));
            py.push(sum / n as f64);
            last = t[i];
            sum = 0.0;
            n = 0;
        }
    }
    (pt, py)
}

/// One peer, for callers that fit them one at a time (discovery's held-out folds).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PeerKind {
    /// PX4 / tofupilot cubic.
    Cubic,
    /// ArduPilot TCAL cubic about 35 °C.
    Ardupilot,
    /// The paper's simple model (linear in T).
    Simple,
}

impl PeerKind {
    /// Every peer, in report order.
    pub const ALL: [PeerKind; 3] = [PeerKind::Cubic, PeerKind::Ardupilot, PeerKind::Simple];

    /// Name as in the reports.
    #[must_use]
    pub fn label(self) -> &'static str {
        match self {
            PeerKind::Cubic => "PX4/tofupilot cubic",
            PeerKind::Ardupilot => "ArduPilot TCAL",
            PeerKind::Simple => "paper simple (linear in T)",
        }
    }

    /// Fit this peer to training temperatures `t` (°C, the raw reading) and outputs `y`
    /// (reference removed), as `fit_peers` does.
    ///
    /// # Errors
    /// Too few training rows, or (ArduPilot) fewer than 4 learner points.
    pub fn fit(self, t: &[f64], y: &[f64]) -> Result<Poly, FitError> {
        let tmin = t.iter().copied().fold(f64::INFINITY, f64::min);
        let tmax = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        match self {
            PeerKind::Cubic => Poly::fit(t, y, 3, 0.5 * (tmin + tmax), tmin, tmax),
            PeerKind::Simple => Poly::fit(t, y, 1, crate::fit::T0_C, -60.0, 130.0),
            PeerKind::Ardupilot => {
                let (pt, py) = ardupilot_points(t, y);
                let mut ardupilot = Poly::fit(&pt, &py, 3, ARDUPILOT_TREF_C, tmin, tmax)?;
                // The learner's own constant is not a parameter: the ordinary calibration
                // sets the offset, here the training mean of what remains.
                ardupilot.coef[0] = 0.0;
                let rest: f64 = t.iter().zip(y).map(|(&ti, &yi)| yi - ardupilot.eval(ti)).sum::<f64>() / t.len() as f64;
                ardupilot.coef[0] = rest;
                Ok(ardupilot)
            }
        }
    }
}

/// Why the ArduPilot learner formed no fit, in its own terms.
#[must_use]
pub(crate) fn ardupilot_reason(e: &FitError) -> String {
    match e {
        FitError::TooFewRows { rows, .. } => format!(
            "the ArduPilot learner formed {rows} point(s) (one per 0.5 °C rise after the coldest row) and its cubic \
             needs 4: it learns only while the temperature rises"
        ),
        e => e.to_string(),
    }
}

/// Fit every peer to training temperatures `t` (°C) and outputs `y` (g, reference removed).
///
/// # Errors
/// Too few training rows, or fewer than 4 ArduPilot points (the learner needs a rise of
/// 2 °C or more after the coldest row).
pub(crate) fn fit_peers(t: &[f64], y: &[f64]) -> Result<Peers, FitError> {
    let cubic = PeerKind::Cubic.fit(t, y)?;
    let simple = PeerKind::Simple.fit(t, y)?;
    let ardupilot = PeerKind::Ardupilot.fit(t, y)?;
    Ok(Peers { cubic, ardupilot, ardupilot_points: ardupilot_points(t, y).0.len(), simple })
}

impl Poly {
    /// The same polynomial about `tref_c`, clamped to `tmin_c..tmax_c`: the coefficients
    /// of `Σ cₖ (T − r₀)ᵏ` re-expanded in powers of `T − r₁` (binomial theorem), so inside
    /// the clamp range it is the same function.
    #[must_use]
    pub(crate) fn about(&self, tref_c: f64, tmin_c: f64, tmax_c: f64) -> Self {
        let h = tref_c - self.tref_c;
        let binom = |n: usize, k: usize| -> f64 { (0..k).fold(1.0, |acc, i| acc * (n - i) as f64 / (i + 1) as f64) };
        let coef = (0..self.coef.len())
            .map(|j| (j..self.coef.len()).map(|k| self.coef[k] * binom(k, j) * h.powi((k - j) as i32)).sum())
            .collect();
        Self { tref_c, tmin_c, tmax_c, coef }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_recovers_a_cubic_and_clamps() {
        let t: Vec<f64> = (0..50).map(|i| -10.0 + f64::from(i)).collect();
        let f = |x: f64| 1e-3 + 2e-5 * (x - 15.0) - 3e-7 * (x - 15.0).powi(2) + 4e-9 * (x - 15.0).powi(3);
        let y: Vec<f64> = t.iter().map(|&x| f(x)).collect();
        let p = Poly::fit(&t, &y, 3, 15.0, -10.0, 39.0).unwrap();
        for (k, want) in [1e-3, 2e-5, -3e-7, 4e-9].iter().enumerate() {
            assert!((p.coef[k] - want).abs() < 1e-12 + 1e-6 * want.abs(), "{k}: {}", p.coef[k]);
        }
        assert!((p.eval(100.0) - f(39.0)).abs() < 1e-12);
    }

    #[test]
    fn re_expansion_keeps_the_function() {
        let p = Poly { tref_c: 28.2, tmin_c: -17.6, tmax_c: 74.0, coef: vec![1e-3, 2e-5, -3e-7, 4e-9] };
        let q = p.about(10.0, -5.0, 55.0);
        assert_eq!((q.tref_c, q.tmin_c, q.tmax_c), (10.0, -5.0, 55.0));
        for t in [-5.0, 0.0, 10.0, 33.3, 55.0] {
            // The direct sum, not Poly::eval, on both sides.
            let direct = |c: &[f64], r: f64| c.iter().enumerate().map(|(k, c)| c * (t - r).powi(k as i32)).sum::<f64>();
            assert!((direct(&q.coef, 10.0) - direct(&p.coef, 28.2)).abs() < 1e-15, "{t}");
        }
        // Clamped at the new range.
        assert_eq!(q.eval(70.0), q.eval(55.0));
    }

    #[test]
    fn ardupilot_learner_takes_only_rises() {
        // Down from 10 to 0 °C, then up to 5 °C: points only on the way up, each 0.5 °C.
        // Quarter degrees: exact in binary, so each rise is exactly 0.5 °C.
        let mut t: Vec<f64> = (0..=40).map(|i| 10.0 - 0.25 * f64::from(i)).collect();
        t.extend((1..=20).map(|i| 0.25 * f64::from(i)));
        let y: Vec<f64> = t.iter().map(|x| x * 1e-4).collect();
        let (pt, py) = ardupilot_points(&t, &y);
        assert_eq!(pt.len(), 10, "{pt:?}");
        assert!((pt[0] - 0.25).abs() < 1e-9 && (py[0] - 0.25e-4).abs() < 1e-12, "{pt:?} {py:?}");
    }
}
