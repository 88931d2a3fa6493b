//! What users pick today, fitted on the same training rows as the project's model and
//! scored on the same held-out rows, and the cubic exported in the formats those stacks load
//! (the exports refitted on every row of the log, as the flashed table is).
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

use std::fmt::Write as _;

use serde::Serialize;

use crate::calibrate::fit::{lstsq, FitError};
use crate::data::static_log::G0_MPS2;

/// ArduPilot's fixed reference temperature, °C.
pub const ARDUPILOT_TREF_C: f64 = 35.0;

/// ArduPilot stores coefficients × 10⁶.
pub const ARDUPILOT_SCALE: f64 = 1.0e6;

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
    pub fn fit(t: &[f64], y: &[f64], deg: usize, tref_c: f64, tmin_c: f64, tmax_c: f64) -> Result<Self, FitError> {
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
    /// (reference removed), as [`fit_peers`] does.
    ///
    /// # Errors
    /// Too few training rows, or (ArduPilot) fewer than 4 learner points.
    pub fn fit(self, t: &[f64], y: &[f64]) -> Result<Poly, FitError> {
        let tmin = t.iter().copied().fold(f64::INFINITY, f64::min);
        let tmax = t.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        match self {
            PeerKind::Cubic => Poly::fit(t, y, 3, 0.5 * (tmin + tmax), tmin, tmax),
            PeerKind::Simple => Poly::fit(t, y, 1, crate::calibrate::fit::T0_C, -60.0, 130.0),
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

/// Fit every peer to training temperatures `t` (°C) and outputs `y` (g, reference removed).
///
/// # Errors
/// Too few training rows, or fewer than 4 ArduPilot points (the learner needs a rise of
/// 2 °C or more after the coldest row).
pub fn fit_peers(t: &[f64], y: &[f64]) -> Result<Peers, FitError> {
    let cubic = PeerKind::Cubic.fit(t, y)?;
    let simple = PeerKind::Simple.fit(t, y)?;
    let ardupilot = PeerKind::Ardupilot.fit(t, y)?;
    Ok(Peers { cubic, ardupilot, ardupilot_points: ardupilot_points(t, y).0.len(), simple })
}

/// A PX4 parameter file (QGroundControl `.params` format: vehicle, component, name, value,
/// type 9 = float, 6 = int32) with `TC_A_ENABLE` and `TC_A0_*` from the cubics of axes x, y,
/// z (m/s²). `X0` is 0 as PX4's own calibration writes it ("zero at the reference
/// temperature"): the ordinary accelerometer calibration holds the offset.
#[must_use]
pub fn px4_params(cubics: &[(String, Poly)]) -> String {
    let mut s = String::from(
        "# Onboard parameters for Vehicle 1\n# qfa-lab: cubic thermal compensation fitted on every row of the log\n\
         # Vehicle-Id\tComponent-Id\tName\tValue\tType\n",
    );
    let _ = writeln!(s, "1\t1\tTC_A_ENABLE\t1\t6");
    let Some((_, first)) = cubics.first() else { return s };
    for (name, v) in [("TREF", first.tref_c), ("TMIN", first.tmin_c), ("TMAX", first.tmax_c)] {
        let _ = writeln!(s, "1\t1\tTC_A0_{name}\t{v:.6}\t9");
    }
    for (axis_name, p) in cubics {
        let i = match axis_name.as_str() {
            "ax" => 0,
            "ay" => 1,
            _ => 2,
        };
        for k in 0..4 {
            let v = if k == 0 { 0.0 } else { p.coef[k] * G0_MPS2 };
            let _ = writeln!(s, "1\t1\tTC_A0_X{k}_{i}\t{v:.9e}\t9");
        }
    }
    s
}

/// ArduPilot `INS_TCAL1_*` parameters (Mission Planner `name,value` lines): coefficients of
/// dT¹..dT³ about 35 °C in m/s² × 10⁶, and the range.
#[must_use]
pub fn ardupilot_params(cubics: &[(String, Poly)]) -> String {
    let mut s = String::from("# qfa-lab: ArduPilot TCAL fitted on every row of the log\nINS_TCAL1_ENABLE,1\n");
    let Some((_, first)) = cubics.first() else { return s };
    let _ = writeln!(s, "INS_TCAL1_TMIN,{:.2}", first.tmin_c);
    let _ = writeln!(s, "INS_TCAL1_TMAX,{:.2}", first.tmax_c);
    for k in 1..4 {
        for (axis_name, p) in cubics {
            let a = match axis_name.as_str() {
                "ax" => "X",
                "ay" => "Y",
                _ => "Z",
            };
            let _ = writeln!(s, "INS_TCAL1_ACC{k}_{a},{:.6}", p.coef[k] * G0_MPS2 * ARDUPILOT_SCALE);
        }
    }
    s
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
