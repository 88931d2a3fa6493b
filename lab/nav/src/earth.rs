//! WGS84 Earth model: normal gravity, radii of curvature, Earth and transport rates.
//!
//! The `nav-types` crate was considered: it converts between WGS84 geodetic, ECEF and
//! local frames, but it provides neither normal gravity nor the meridian / prime-vertical
//! radii of curvature, which are the only geodesy a local-level NED mechanisation needs
//! (position is carried as latitude, longitude and height, never as ECEF). The few
//! closed-form expressions below are therefore written out, each with its source.

use nalgebra::Vector3;

/// WGS84 semi-major axis a, m.
pub const A: f64 = 6_378_137.0;
/// WGS84 flattening f.
pub const F: f64 = 1.0 / 298.257_223_563;
/// First eccentricity squared e² = f(2 − f).
pub const E2: f64 = F * (2.0 - F);
/// WGS84 Earth rotation rate Ω, rad/s.
pub const OMEGA_IE: f64 = 7.292_115e-5;
/// Normal gravity at the equator γₑ, m/s² (NIMA TR8350.2, Eq. 4-1).
pub const GAMMA_E: f64 = 9.780_325_335_9;
/// Somigliana constant k = (b·γₚ)/(a·γₑ) − 1 (TR8350.2).
pub const SOMIGLIANA_K: f64 = 0.001_931_852_652_41;
/// m = Ω²a²b/GM (TR8350.2).
pub const M_RATIO: f64 = 0.003_449_786_506_84;
/// Standard gravity, m/s² (the g of accelerometer specifications).
pub const G0: f64 = 9.806_65;
/// Metres per international nautical mile.
pub const NMI_M: f64 = 1852.0;

/// Meridian radius R_M and prime-vertical radius R_N at geodetic latitude `lat` (rad), m.
///
/// `R_N = a/√(1 − e² sin²φ)`, `R_M = a(1 − e²)/(1 − e² sin²φ)^{3/2}`.
#[must_use]
pub fn radii(lat: f64) -> (f64, f64) {
    let s = lat.sin();
    let w2 = 1.0 - E2 * s * s;
    let w = w2.sqrt();
    let rn = A / w;
    let rm = A * (1.0 - E2) / (w2 * w);
    (rm, rn)
}

/// Normal gravity magnitude (gravitation plus centrifugal, along the ellipsoid normal)
/// at latitude `lat` (rad) and ellipsoidal height `h` (m), m/s².
///
/// Somigliana's closed formula on the ellipsoid,
/// `γ₀ = γₑ(1 + k sin²φ)/√(1 − e² sin²φ)`, and the second-order free-air correction
/// `γ(h) = γ₀[1 − 2/a·(1 + f + m − 2f sin²φ)·h + 3h²/a²]` (TR8350.2, Eq. 4-3).
/// The deflection of the normal-gravity vector with height (< 1e-7 g below 10 km)
/// is neglected: gravity is taken along the local down axis.
#[must_use]
pub fn gravity(lat: f64, h: f64) -> f64 {
    let s2 = lat.sin().powi(2);
    let g0 = GAMMA_E * (1.0 + SOMIGLIANA_K * s2) / (1.0 - E2 * s2).sqrt();
    g0 * (1.0 - 2.0 / A * (1.0 + F + M_RATIO - 2.0 * F * s2) * h + 3.0 * h * h / (A * A))
}

/// Earth-frame quantities the mechanisation needs at one state, in NED.
#[derive(Clone, Copy, Debug)]
pub struct Local {
    /// Meridian radius of curvature, m.
    pub rm: f64,
    /// Prime-vertical radius of curvature, m.
    pub rn: f64,
    /// Earth rate in NED, `ω_ie^n = Ω(cos φ, 0, −sin φ)`, rad/s.
    pub w_ie: Vector3<f64>,
    /// Transport rate, `ω_en^n = (v_E/(R_N+h), −v_N/(R_M+h), −v_E tan φ/(R_N+h))`, rad/s.
    pub w_en: Vector3<f64>,
    /// Normal gravity in NED, `(0, 0, γ(φ, h))`, m/s².
    pub g: Vector3<f64>,
}

impl Local {
    /// Evaluate at latitude `lat` (rad), height `h` (m) and NED velocity `v` (m/s).
    #[must_use]
    pub fn at(lat: f64, h: f64, v: &Vector3<f64>) -> Self {
        let (rm, rn) = radii(lat);
        let (s, c) = lat.sin_cos();
        let rnh = rn + h;
        let rmh = rm + h;
        Self {
            rm,
            rn,
            w_ie: Vector3::new(OMEGA_IE * c, 0.0, -OMEGA_IE * s),
            w_en: Vector3::new(v.y / rnh, -v.x / rmh, -v.y * s / c / rnh),
            g: Vector3::new(0.0, 0.0, gravity(lat, h)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gravity_matches_published_values() {
        // TR8350.2: γ at the equator 9.7803253359, at the poles 9.8321849378 m/s².
        assert!((gravity(0.0, 0.0) - 9.780_325_335_9).abs() < 1e-9);
        assert!((gravity(std::f64::consts::FRAC_PI_2, 0.0) - 9.832_184_937_8).abs() < 1e-8);
        // Free-air gradient ≈ −3.086e-6 s⁻² at mid latitude.
        let grad = (gravity(0.7, 1000.0) - gravity(0.7, 0.0)) / 1000.0;
        assert!((grad + 3.086e-6).abs() < 0.01e-6, "{grad}");
    }

    #[test]
    fn radii_at_equator_and_pole() {
        let (rm, rn) = radii(0.0);
        assert!((rn - A).abs() < 1e-6);
        assert!((rm - A * (1.0 - E2)).abs() < 1e-6);
        let (rm, rn) = radii(std::f64::consts::FRAC_PI_2);
        assert!((rm - rn).abs() < 1e-6, "at the pole R_M = R_N = a²/b");
    }
}
