//! Strapdown inertial mechanisation in the local-level NED frame, and its exact inverse.
//!
//! One step `k−1 → k` of length `dt` with gyro increment Δθₖ and accelerometer increment
//! Δvₖ (body frame, rad and m/s):
//!
//! 1. **Earth quantities** at the previous state (`earth::Local`): ω_ie^n, ω_en^n,
//!    normal gravity g^n, R_M, R_N. At 200 Hz these change by < 1e-9 relative per step,
//!    so evaluating them at k−1 instead of k−½ costs nothing measurable.
//! 2. **Attitude** (quaternion `q` = C_b^n): body rotation vector with the two-sample
//!    coning correction `φ = Δθₖ + (1/12)·Δθₖ₋₁ × Δθₖ`, navigation-frame rotation
//!    `ζ = (ω_ie^n + ω_en^n)·dt`, then `qₖ = q(−ζ) ⊗ qₖ₋₁ ⊗ q(φ)`.
//! 3. **Velocity**: rotation and two-sample sculling corrections
//!    `u = Δvₖ + ½Δθₖ×Δvₖ + (1/12)(Δθₖ₋₁×Δvₖ + Δvₖ₋₁×Δθₖ)`, projected with the half-step
//!    frame rotation `Δv_sf^n = (I − ½[ζ×])·C_b^n(k−1)·u`, then
//!    `vₖ = vₖ₋₁ + Δv_sf^n + (g^n − (2ω_ie^n + ω_en^n) × vₖ₋₁)·dt` (gravity and Coriolis).
//! 4. **Altitude** is held by an external reference (barometric / truth height and its
//!    rate): `hₖ` and `v_D,k` are overwritten, as is usual for pure-inertial horizontal
//!    tests (the free inertial vertical channel diverges).
//! 5. **Position** by the trapezoidal rule: `Δφ = ½(v_N,k−1 + v_N,k)·dt/(R_M + h̄)`,
//!    `Δλ = ½(v_E,k−1 + v_E,k)·dt/((R_N + h̄)·cos φₖ₋₁)`.
//!
//! [`inverse`] solves steps 2–3 for Δθₖ and Δvₖ given two consecutive true states (both
//! corrections are linear in the unknowns, so this is a 3×3 solve each, no iteration):
//! the trajectory generator uses it, so a perfect IMU reproduces the trajectory to
//! rounding error. The physics of the forward equations is checked independently by the
//! Schuler test and by the stationary increments test (Earth rate and gravity).

use nalgebra::{Matrix3, UnitQuaternion, Vector3};

use super::earth::Local;

/// Navigation state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NavState {
    /// Attitude C_b^n as a unit quaternion.
    pub q: UnitQuaternion<f64>,
    /// Velocity in NED, m/s.
    pub v: Vector3<f64>,
    /// Geodetic latitude, rad.
    pub lat: f64,
    /// Longitude, rad.
    pub lon: f64,
    /// Ellipsoidal height, m.
    pub h: f64,
}

/// IMU increments over one cycle, body frame.
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct Increments {
    /// Angle increment Δθ, rad.
    pub dtheta: Vector3<f64>,
    /// Velocity increment Δv, m/s.
    pub dv: Vector3<f64>,
}

/// External altitude reference for one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AltRef {
    /// Height at the end of the step, m.
    pub h: f64,
    /// Down velocity at the end of the step, m/s.
    pub vd: f64,
}

fn skew(a: &Vector3<f64>) -> Matrix3<f64> {
    Matrix3::new(0.0, -a.z, a.y, a.z, 0.0, -a.x, -a.y, a.x, 0.0)
}

/// Trapezoidal position update shared by the mechanisation and the trajectory generator.
/// `prev` is the state at k−1 (`local` evaluated there); returns (latitude, longitude) at k.
#[must_use]
pub fn advance_position(prev: &NavState, h_next: f64, v_next: &Vector3<f64>, local: &Local, dt: f64) -> (f64, f64) {
    let hm = 0.5 * (prev.h + h_next);
    let lat_n = prev.lat + 0.5 * (prev.v.x + v_next.x) * dt / (local.rm + hm);
    let lon_n = prev.lon + 0.5 * (prev.v.y + v_next.y) * dt / ((local.rn + hm) * prev.lat.cos());
    (lat_n, lon_n)
}

/// The mechanisation: a state plus the previous increments (for coning and sculling).
#[derive(Clone, Debug)]
pub struct Strapdown {
    /// Current state.
    pub state: NavState,
    prev: Increments,
    steps: u32,
}

impl Strapdown {
    /// Start at `state`, with zero previous increments.
    #[must_use]
    pub fn new(state: NavState) -> Self {
        Self { state, prev: Increments::default(), steps: 0 }
    }

    /// Advance one step of `dt` seconds with increments `inc`.
    pub fn step(&mut self, inc: &Increments, dt: f64, alt: AltRef) {
        let s = &self.state;
        let loc = Local::at(s.lat, s.h, &s.v);
        let zeta = (loc.w_ie + loc.w_en) * dt;
        let (dth, dv) = (&inc.dtheta, &inc.dv);
        let phi = dth + self.prev.dtheta.cross(dth) / 12.0;
        let u = dv + 0.5 * dth.cross(dv) + (self.prev.dtheta.cross(dv) + self.prev.dv.cross(dth)) / 12.0;
        let dv_n = s.q * u;
        let dv_n = dv_n - 0.5 * zeta.cross(&dv_n);
        let coriolis = (2.0 * loc.w_ie + loc.w_en).cross(&s.v);
        let mut v = s.v + dv_n + (loc.g - coriolis) * dt;
        v.z = alt.vd;
        let mut q = UnitQuaternion::from_scaled_axis(-zeta) * s.q * UnitQuaternion::from_scaled_axis(phi);
        self.steps = self.steps.wrapping_add(1);
        if self.steps.is_multiple_of(1024) {
            q.renormalize();
        }
        let (lat, lon) = advance_position(s, alt.h, &v, &loc, dt);
        self.state = NavState { q, v, lat, lon, h: alt.h };
        self.prev = *inc;
    }
}

/// Increments that take [`Strapdown::step`] exactly from `a` to `b` (up to rounding),
/// given the previous step's increments `prev`.
///
/// `b`'s position must come from [`advance_position`] with `a`, `b`'s velocity and the
/// same `dt`, as the trajectory generator does.
#[must_use]
pub fn inverse(a: &NavState, b: &NavState, prev: &Increments, dt: f64) -> Increments {
    let loc = Local::at(a.lat, a.h, &a.v);
    let zeta = (loc.w_ie + loc.w_en) * dt;
    // q(φ) = qₐ⁻¹ ⊗ q(ζ) ⊗ q_b, then φ = (I + [Δθₖ₋₁×]/12)·Δθ.
    let rb = a.q.inverse() * UnitQuaternion::from_scaled_axis(zeta) * b.q;
    let phi = rb.scaled_axis();
    let m_phi = Matrix3::identity() + skew(&prev.dtheta) / 12.0;
    let dtheta = m_phi.lu().solve(&phi).unwrap_or(phi);
    // Δv_sf^n from the velocity equation, then u, then Δv.
    let coriolis = (2.0 * loc.w_ie + loc.w_en).cross(&a.v);
    let dv_n = b.v - a.v - (loc.g - coriolis) * dt;
    let m_zeta = Matrix3::identity() - 0.5 * skew(&zeta);
    let dv_n = m_zeta.lu().solve(&dv_n).unwrap_or(dv_n);
    let u = a.q.inverse() * dv_n;
    // u = (I + ½[Δθ×] + [Δθₖ₋₁×]/12)·Δv + Δvₖ₋₁×Δθ/12
    let m_u = Matrix3::identity() + 0.5 * skew(&dtheta) + skew(&prev.dtheta) / 12.0;
    let rhs = u - prev.dv.cross(&dtheta) / 12.0;
    let dv = m_u.lu().solve(&rhs).unwrap_or(rhs);
    Increments { dtheta, dv }
}
