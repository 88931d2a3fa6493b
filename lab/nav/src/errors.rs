//! Non-thermal IMU errors: the gyro error model and the accelerometer errors that sit
//! beside the thermal ones, both from the scenario (`[imu.gyro]`, `[imu.accel]`).
//!
//! Defaults are a 0.01 °/h-class navigation-grade IMU, the class of the paper's Table 5
//! (gyro bias stability 0.01 °/h, accelerometer bias stability 50 µg). The split of that
//! class into the terms below is ours:
//!
//! | term | gyro default | accelerometer default |
//! |---|---|---|
//! | turn-on bias, σ per axis, constant over a run | 0.01 °/h | 50 µg |
//! | bias instability, first-order Gauss–Markov σ, τ | 0.005 °/h, 3600 s | (the truth model's own: 10 µg, 1800 s) |
//! | white noise | ARW 0.002 °/√h | (the truth model's own: 10 µg/√Hz) |
//! | scale-factor error, σ per axis | 10 ppm | 20 ppm (on top of the thermal K1) |
//! | misalignment, σ per off-diagonal term (non-orthogonal) | 10 arcsec | 10 arcsec |
//! | known triad misalignment (the same every run; the tables carry its inverse) | | 20–45 arcsec per term ([`AccelErrors::triad_arcsec`]) |
//!
//! Every random term is drawn once per run from the run's seed ([`ImuDraw::draw`]); none is
//! known to any compensation variant, the oracle included, so these errors are common to
//! every variant and cancel in the thermal-only error (variant − oracle). The one known
//! term is the accelerometer triad's non-orthogonality `I + K`: a multi-position
//! calibration measures it, and every table variant (and the oracle) carries
//! `(I + K)⁻¹` as the table's misalignment matrix ([`AccelErrors::carried_misalignment`]).

use nalgebra::{Matrix3, Vector3};
use qfa_rng::GaussMarkov;
use rand::Rng;
use serde::{Deserialize, Serialize};

use super::earth::G0;

const ARCSEC: f64 = std::f64::consts::PI / 180.0 / 3600.0;
const DPH: f64 = std::f64::consts::PI / 180.0 / 3600.0;

/// Gyro error model, per axis.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct GyroErrors {
    /// σ of the turn-on bias drawn per axis and run, °/h.
    pub bias_dph: f64,
    /// Bias instability: σ of a first-order Gauss–Markov process, °/h.
    pub bias_instability_dph: f64,
    /// Its correlation time, s.
    pub bias_instability_tau_s: f64,
    /// Angle random walk, °/√h.
    pub arw_dprh: f64,
    /// σ of the scale-factor error per axis, ppm.
    pub scale_factor_ppm: f64,
    /// σ of each of the six off-diagonal misalignment terms, arcsec.
    pub misalignment_arcsec: f64,
}

impl Default for GyroErrors {
    fn default() -> Self {
        Self {
            bias_dph: 0.01,
            bias_instability_dph: 0.005,
            bias_instability_tau_s: 3600.0,
            arw_dprh: 0.002,
            scale_factor_ppm: 10.0,
            misalignment_arcsec: 10.0,
        }
    }
}

impl GyroErrors {
    /// No gyro error.
    #[must_use]
    pub const fn none() -> Self {
        Self {
            bias_dph: 0.0,
            bias_instability_dph: 0.0,
            bias_instability_tau_s: 3600.0,
            arw_dprh: 0.0,
            scale_factor_ppm: 0.0,
            misalignment_arcsec: 0.0,
        }
    }
}

/// Accelerometer errors that are not thermal (on top of the truth model's own noise).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AccelErrors {
    /// σ of the turn-on bias drawn per axis and run, µg.
    pub bias_ug: f64,
    /// σ of the scale-factor error per axis, ppm.
    pub scale_factor_ppm: f64,
    /// σ of each of the six off-diagonal misalignment terms, arcsec (the residual the
    /// calibration leaves: unknown to every variant).
    pub misalignment_arcsec: f64,
    /// The triad's known non-orthogonality K, arcsec, off-diagonal terms in the order
    /// xy, xz, yx, yz, zx, zy (row: the sensing axis, column: the body axis it picks up),
    /// the same every run. The tables carry `(I + K)⁻¹`.
    pub triad_arcsec: [f64; 6],
}

impl Default for AccelErrors {
    fn default() -> Self {
        Self { bias_ug: 50.0, scale_factor_ppm: 20.0, misalignment_arcsec: 10.0, triad_arcsec: TRIAD_ARCSEC }
    }
}

/// Default known triad misalignment, arcsec (xy, xz, yx, yz, zx, zy): 0.1–0.2 mrad per
/// term, a mechanically aligned triad before its misalignment calibration. The vertical
/// axis's terms (zx, zy) and the horizontal axes' z terms couple 1 g into the horizontal
/// channel, 100–220 µg, twice the 50 µg turn-on bias.
pub const TRIAD_ARCSEC: [f64; 6] = [30.0, -45.0, 20.0, 40.0, -25.0, 35.0];

impl AccelErrors {
    /// No non-thermal accelerometer error.
    #[must_use]
    pub const fn none() -> Self {
        Self { bias_ug: 0.0, scale_factor_ppm: 0.0, misalignment_arcsec: 0.0, triad_arcsec: [0.0; 6] }
    }

    /// `I + K`: what the triad senses of a body-axis Δv.
    #[must_use]
    pub fn triad(&self) -> Matrix3<f64> {
        let k = self.triad_arcsec.map(|a| a * ARCSEC);
        Matrix3::new(1.0, k[0], k[1], k[2], 1.0, k[3], k[4], k[5], 1.0)
    }

    /// `(I + K)⁻¹` (f64), or `None` when the triad is orthogonal.
    #[must_use]
    pub fn triad_inverse(&self) -> Option<Matrix3<f64>> {
        if self.triad_arcsec.iter().all(|a| *a == 0.0) {
            return None;
        }
        self.triad().try_inverse()
    }

    /// The table's misalignment matrix, row-major f32: `(I + K)⁻¹`, or `None` when the
    /// triad is orthogonal.
    #[must_use]
    pub fn carried_misalignment(&self) -> Option<[f32; 9]> {
        self.triad_inverse().map(|m| core::array::from_fn(|i| m[(i / 3, i % 3)] as f32))
    }
}

/// The scenario's `[imu]` table.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct ImuErrors {
    /// Gyros.
    pub gyro: GyroErrors,
    /// Accelerometers (non-thermal).
    pub accel: AccelErrors,
}

impl ImuErrors {
    /// No non-thermal error at all (tests).
    #[must_use]
    pub const fn none() -> Self {
        Self { gyro: GyroErrors::none(), accel: AccelErrors::none() }
    }
}

/// One run's draw of [`ImuErrors`], and the gyro's Gauss–Markov state.
#[derive(Clone, Debug, PartialEq)]
pub struct ImuDraw {
    /// Gyro turn-on bias, rad/s.
    pub gyro_bias: Vector3<f64>,
    /// Gyro `I + S + M` (scale factor and misalignment), applied to the true Δθ.
    pub gyro_m: Matrix3<f64>,
    /// Accelerometer turn-on bias, m/s².
    pub accel_bias: Vector3<f64>,
    /// Accelerometer `(I + S + M)·(I + K)` (random, then the known triad term), applied
    /// to the true Δv before the thermal truth model.
    pub accel_m: Matrix3<f64>,
    gm: [GaussMarkov; 3],
    gm_sigma: f64,
    gm_tau_s: f64,
    arw: f64,
}

fn z<R: Rng + ?Sized>(rng: &mut R) -> f64 {
    qfa_rng::normal(rng)
}

fn matrix<R: Rng + ?Sized>(sf_ppm: f64, mis_arcsec: f64, rng: &mut R) -> Matrix3<f64> {
    Matrix3::from_fn(|i, j| if i == j { 1.0 + sf_ppm * 1e-6 * z(rng) } else { mis_arcsec * ARCSEC * z(rng) })
}

impl ImuDraw {
    /// Draw every constant term of `e` from `rng`; the Gauss–Markov state starts from its
    /// stationary law.
    pub fn draw<R: Rng + ?Sized>(e: &ImuErrors, rng: &mut R) -> Self {
        let g = e.gyro;
        let gyro_bias = Vector3::from_fn(|_, _| g.bias_dph * DPH * z(rng));
        let gyro_m = matrix(g.scale_factor_ppm, g.misalignment_arcsec, rng);
        let a = e.accel;
        let accel_bias = Vector3::from_fn(|_, _| a.bias_ug * 1e-6 * G0 * z(rng));
        let accel_m = matrix(a.scale_factor_ppm, a.misalignment_arcsec, rng) * a.triad();
        let gm_sigma = g.bias_instability_dph * DPH;
        let gm = core::array::from_fn(|_| GaussMarkov::stationary(gm_sigma, rng));
        Self {
            gyro_bias,
            gyro_m,
            accel_bias,
            accel_m,
            gm,
            gm_sigma,
            gm_tau_s: g.bias_instability_tau_s.max(1e-3),
            arw: g.arw_dprh.to_radians() / 60.0,
        }
    }

    /// Gyro turn-on bias drawn, °/h.
    #[must_use]
    pub fn gyro_bias_dph(&self) -> [f64; 3] {
        let b = self.gyro_bias / DPH;
        [b.x, b.y, b.z]
    }

    /// Measured Δθ over `dt` for the true `dtheta`: misalignment and scale factor, turn-on
    /// bias, Gauss–Markov bias and angle random walk.
    pub fn gyro<R: Rng + ?Sized>(&mut self, dtheta: &Vector3<f64>, dt: f64, rng: &mut R) -> Vector3<f64> {
        if self.gm_sigma > 0.0 {
            let phi = (-dt / self.gm_tau_s).exp();
            for g in &mut self.gm {
                g.step(phi, rng);
            }
        }
        let gm = Vector3::from_fn(|i, _| self.gm[i].value());
        let mut out = self.gyro_m * dtheta + (self.gyro_bias + gm) * dt;
        if self.arw > 0.0 {
            let s = self.arw * dt.sqrt();
            for i in 0..3 {
                out[i] += s * z(rng);
            }
        }
        out
    }

    /// The Δv the accelerometer axes sense over `dt` for the true `dv` (before the thermal
    /// truth model turns it into pulses): misalignment, scale factor and turn-on bias.
    #[must_use]
    pub fn accel(&self, dv: &Vector3<f64>, dt: f64) -> Vector3<f64> {
        self.accel_m * dv + self.accel_bias * dt
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn none_is_the_identity_and_defaults_are_the_documented_class() {
        let mut rng = qfa_rng::seeded(1);
        let mut d = ImuDraw::draw(&ImuErrors::none(), &mut rng);
        let v = Vector3::new(1e-3, -2e-3, 3e-3);
        assert_eq!(d.gyro(&v, 0.005, &mut rng), v);
        assert_eq!(d.accel(&v, 0.005), v);
        // Over many draws the turn-on gyro bias has σ ≈ 0.01 °/h (within 10 % for 3000 samples).
        let mut s2 = 0.0;
        for _ in 0..1000 {
            let d = ImuDraw::draw(&ImuErrors::default(), &mut rng);
            s2 += d.gyro_bias_dph().iter().map(|b| b * b).sum::<f64>();
        }
        let sigma = (s2 / 3000.0).sqrt();
        assert!((sigma - 0.01).abs() < 0.001, "{sigma}");
    }
}
