//! Stationary alignment before take-off: coarse leveling and gyrocompassing, then a fine
//! alignment by an eight-state Kalman filter on zero velocity.
//!
//! The vehicle stands still at the scenario's start point for `[alignment] duration_s`
//! with the IMU bay at `ground_temp_c`, on the same simulated sensors and the same
//! accelerometer compensation as the flight that follows. Each variant aligns on its own
//! compensated output, so leveling absorbs whatever accelerometer error that variant has
//! at the ground temperature (bias at the alignment temperature, turn-on bias), as on a
//! real INS; only the change after alignment acts as an error in flight.
//!
//! 1. **Coarse** (the first `coarse_s`): mean specific force f̄ᵇ and angular rate ω̄ᵇ.
//!    Roll `atan2(−f_y, −f_z)`, pitch `atan2(f_x, √(f_y² + f_z²))`; ω̄ᵇ rotated into the
//!    level frame gives heading `ψ = atan2(−ω_y, ω_x)` (the horizontal Earth rate points
//!    north).
//! 2. **Fine** (the rest): the strapdown mechanisation runs from the coarse attitude with
//!    zero velocity, altitude held; once a second a Kalman filter with state
//!    `x = [δv_N, δv_E, φ_N, φ_E, φ_D, ε_N, ε_E, ε_D]` updates on the mechanised
//!    horizontal velocity (the truth is zero); the velocity and attitude estimates are fed
//!    back (closed loop) into the mechanisation, the gyro-bias estimates stay in the
//!    filter. The error model is the stationary φ-angle model in NED, with
//!    `C̃ = (I − [φ×])·C` and f^n = (0, 0, −g):
//!    `δv̇ = f^n × φ − 2ω_ie × δv` (so `δv̇_N = g·φ_E`, `δv̇_E = −g·φ_N`),
//!    `φ̇ = −ω_ie × φ − ε`, ε a random constant (prior σ: the scenario's turn-on gyro
//!    bias). Without ε the north gyro bias makes φ_N a ramp the filter tracks with a lag
//!    (seen: 2 arcsec of tilt left). Discretized at T = 1 s by `Φ = I + F·T + (F·T)²/2`.
//!    Process noise: the gyro ARW on φ, the accelerometer white noise on δv; measurement
//!    noise 1e-4 m/s (the I/F quantum is ≈ 3e-5 m/s).
//!
//! What no stationary alignment can separate stays as the alignment error: the tilt
//! absorbs the horizontal accelerometer error (`φ_N ≈ b_E/g`, `φ_E ≈ −b_N/g`), the heading
//! absorbs the east gyro bias (`δψ ≈ ε_E/(Ω cos L)`, ≈ 0.8 mrad per 0.01 °/h at 34° N).

use nalgebra::{Matrix2, SMatrix, SVector, UnitQuaternion, Vector2, Vector3};
use serde::{Deserialize, Serialize};

use super::earth::{self, OMEGA_IE};
use super::strapdown::{AltRef, Increments, NavState, Strapdown};

/// The scenario's `[alignment]` table.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct AlignConfig {
    /// Align before take-off; `false` starts every variant at the true attitude.
    pub enabled: bool,
    /// Total alignment time, s.
    pub duration_s: f64,
    /// Coarse phase, s (the rest is fine alignment).
    pub coarse_s: f64,
    /// Bay temperature on the ground during alignment, °C; the drive profile's first
    /// value when absent.
    pub ground_temp_c: Option<f64>,
}

impl Default for AlignConfig {
    fn default() -> Self {
        Self { enabled: true, duration_s: 600.0, coarse_s: 60.0, ground_temp_c: None }
    }
}

/// Alignment errors left (aligned minus true attitude).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct AlignErrors {
    /// Roll error, arcsec.
    pub roll_arcsec: f64,
    /// Pitch error, arcsec.
    pub pitch_arcsec: f64,
    /// Heading error, mrad.
    pub heading_mrad: f64,
}

impl AlignErrors {
    /// Euler-angle differences of `aligned` from `truth`.
    #[must_use]
    pub fn of(aligned: &UnitQuaternion<f64>, truth: &UnitQuaternion<f64>) -> Self {
        let (r1, p1, y1) = aligned.euler_angles();
        let (r0, p0, y0) = truth.euler_angles();
        let as_arcsec = 180.0 / std::f64::consts::PI * 3600.0;
        let dy = (y1 - y0 + std::f64::consts::PI).rem_euclid(2.0 * std::f64::consts::PI) - std::f64::consts::PI;
        Self { roll_arcsec: (r1 - r0) * as_arcsec, pitch_arcsec: (p1 - p0) * as_arcsec, heading_mrad: dy * 1e3 }
    }
}

type M5 = SMatrix<f64, 8, 8>;
type V5 = SVector<f64, 8>;

/// The analytic coarse alignment from mean specific force `f` and angular rate `w` (body).
#[must_use]
pub fn coarse(f: &Vector3<f64>, w: &Vector3<f64>) -> UnitQuaternion<f64> {
    let roll = (-f.y).atan2(-f.z);
    let pitch = f.x.atan2(f.y.hypot(f.z));
    let level = UnitQuaternion::from_euler_angles(roll, pitch, 0.0);
    let wl = level * w;
    let heading = (-wl.y).atan2(wl.x);
    UnitQuaternion::from_euler_angles(roll, pitch, heading)
}

/// Noise levels the fine filter assumes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FilterNoise {
    /// Gyro angle random walk, rad/√s.
    pub arw_rad_rs: f64,
    /// Accelerometer white noise, m/s²/√Hz.
    pub accel_white_mps2_rhz: f64,
    /// Prior σ of each gyro bias, rad/s.
    pub gyro_bias_rad_s: f64,
}

/// One variant's alignment, fed every IMU cycle.
#[derive(Clone, Debug)]
pub struct Aligner {
    start: NavState,
    dt: f64,
    coarse_steps: u64,
    update_steps: u64,
    k: u64,
    sum_dth: Vector3<f64>,
    sum_dv: Vector3<f64>,
    nav: Option<Strapdown>,
    x: V5,
    p: M5,
    phi: M5,
    q: M5,
    r: f64,
}

impl Aligner {
    /// Stationary at `start` (position used, attitude ignored), IMU cycle `dt`, one Kalman
    /// update per `update_steps` cycles; `noise` sets the filter's noise levels.
    #[must_use]
    pub fn new(cfg: &AlignConfig, start: NavState, dt: f64, update_steps: u64, noise: FilterNoise) -> Self {
        let coarse_steps = ((cfg.coarse_s / dt).round() as u64).max(1);
        let t = dt * update_steps as f64;
        let (s, c) = start.lat.sin_cos();
        let (wn, wd) = (OMEGA_IE * c, -OMEGA_IE * s);
        let g = earth::gravity(start.lat, start.h);
        let mut f = M5::zeros();
        // δv̇ = f^n × φ − 2 ω_ie × δv
        f[(0, 3)] = g;
        f[(1, 2)] = -g;
        f[(0, 1)] = 2.0 * wd;
        f[(1, 0)] = -2.0 * wd;
        // φ̇ = −ω_ie × φ
        f[(2, 3)] = wd;
        f[(3, 2)] = -wd;
        f[(3, 4)] = wn;
        f[(4, 3)] = -wn;
        // − ε
        f[(2, 5)] = -1.0;
        f[(3, 6)] = -1.0;
        f[(4, 7)] = -1.0;
        let ft = f * t;
        let phi = M5::identity() + ft + ft * ft * 0.5;
        let qv = noise.accel_white_mps2_rhz.powi(2).max(1e-12) * t;
        let qp = noise.arw_rad_rs.powi(2).max(1e-16) * t;
        let qe = 1e-24 * t;
        let q = M5::from_diagonal(&V5::from_column_slice(&[qv, qv, qp, qp, qp, qe, qe, qe]));
        let pe = noise.gyro_bias_rad_s.powi(2).max(1e-20);
        let p = M5::from_diagonal(&V5::from_column_slice(&[1e-6, 1e-6, 1e-6, 1e-6, 1e-4, pe, pe, pe]));
        Self {
            start,
            dt,
            coarse_steps,
            update_steps: update_steps.max(1),
            k: 0,
            sum_dth: Vector3::zeros(),
            sum_dv: Vector3::zeros(),
            nav: None,
            x: V5::zeros(),
            p,
            phi,
            q,
            r: 1e-4f64.powi(2),
        }
    }

    /// One IMU cycle's increments (compensated Δv).
    pub fn step(&mut self, inc: &Increments) {
        self.k += 1;
        if self.k <= self.coarse_steps {
            self.sum_dth += inc.dtheta;
            self.sum_dv += inc.dv;
            if self.k == self.coarse_steps {
                let t = self.k as f64 * self.dt;
                let q = coarse(&(self.sum_dv / t), &(self.sum_dth / t));
                self.nav = Some(Strapdown::new(NavState { q, v: Vector3::zeros(), ..self.start }));
            }
            return;
        }
        let Some(nav) = self.nav.as_mut() else { return };
        nav.step(inc, self.dt, AltRef { h: self.start.h, vd: 0.0 });
        if (self.k - self.coarse_steps).is_multiple_of(self.update_steps) {
            // Predict.
            self.x = self.phi * self.x;
            self.p = self.phi * self.p * self.phi.transpose() + self.q;
            // Update on z = (v_N, v_E) − 0, H = [I₂ 0].
            let z = Vector2::new(nav.state.v.x, nav.state.v.y);
            let h = SMatrix::<f64, 2, 8>::from_fn(|i, j| if i == j { 1.0 } else { 0.0 });
            let s = h * self.p * h.transpose() + Matrix2::identity() * self.r;
            let Some(si) = s.try_inverse() else { return };
            let kg = self.p * h.transpose() * si;
            self.x += kg * (z - h * self.x);
            let ikh = M5::identity() - kg * h;
            self.p = ikh * self.p * ikh.transpose() + kg * kg.transpose() * self.r;
            // Feed back: C = (I + [φ×])·C̃, v = ṽ − δv; the filter's state restarts at zero.
            let phi = Vector3::new(self.x[2], self.x[3], self.x[4]);
            nav.state.q = UnitQuaternion::from_scaled_axis(phi) * nav.state.q;
            nav.state.v.x -= self.x[0];
            nav.state.v.y -= self.x[1];
            for i in 0..5 {
                self.x[i] = 0.0;
            }
        }
    }

    /// The aligned attitude: the fine alignment's, or the coarse one if the fine phase
    /// never ran; `None` before the coarse phase ended.
    #[must_use]
    pub fn attitude(&self) -> Option<UnitQuaternion<f64>> {
        self.nav.as_ref().map(|n| n.state.q)
    }

    /// 1σ of the filter's heading estimate, mrad.
    #[must_use]
    pub fn heading_sigma_mrad(&self) -> f64 {
        self.p[(4, 4)].sqrt() * 1e3
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn coarse_recovers_attitude_from_exact_gravity_and_earth_rate() {
        let lat = 0.6f64;
        let truth = UnitQuaternion::from_euler_angles(0.02, -0.03, 2.5);
        let fn_ = Vector3::new(0.0, 0.0, -9.8);
        let wn = Vector3::new(OMEGA_IE * lat.cos(), 0.0, -OMEGA_IE * lat.sin());
        let q = coarse(&(truth.inverse() * fn_), &(truth.inverse() * wn));
        let e = AlignErrors::of(&q, &truth);
        assert!(e.roll_arcsec.abs() < 1e-6 && e.pitch_arcsec.abs() < 1e-6 && e.heading_mrad.abs() < 1e-6, "{e:?}");
    }
}
