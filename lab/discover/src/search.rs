//! The search of a candidate's nonlinear parameters (τ, r, creep τ_ref and E) on a
//! fold's training bins, its limits, and the flag for an estimate pinned at one.

use super::*;

/// Search limits of the sensor-lag τ, s.
pub(super) const LAG_LIMITS: (f64, f64) = (30.0, 3840.0);
/// Search limits of the play half-width, °C.
pub(super) const PLAY_LIMITS: (f64, f64) = (0.15, 20.0);
/// Search limits of the creep τ_ref, s.
pub(super) const CREEP_TAU_LIMITS: (f64, f64) = (1.0, 1e6);
/// Upper search limit of the creep activation, K.
pub(super) const CREEP_E_MAX: f64 = 20_000.0;

/// Search the nonlinear parameters `e` adds, on the `train` bins.
pub(super) fn search(setup: &Setup, s: &Structure, nl: &Nonlinear, e: Effect, train: &[bool]) -> Nonlinear {
    let obj = |n: &Nonlinear| setup.train_score(s, n, train);
    let grid_1d = |pts: &[f64], set: &dyn Fn(f64) -> Nonlinear| -> Nonlinear {
        let vals: Vec<f64> = pts.iter().map(|&p| obj(&set(p))).collect();
        let b = (0..pts.len()).min_by(|&i, &j| vals[i].total_cmp(&vals[j])).unwrap_or(0);
        let lo = pts[b.saturating_sub(1)].ln();
        let hi = pts[(b + 1).min(pts.len() - 1)].ln();
        let (x, fx) = golden(|x| obj(&set(x.exp())), lo, hi, 20);
        if fx < vals[b] {
            set(x.exp())
        } else {
            set(pts[b])
        }
    };
    match e {
        Effect::SensorLag => grid_1d(&[30.0, 60.0, 120.0, 240.0, 480.0, 960.0, 1920.0, 3840.0], &|t| Nonlinear {
            lag_tau_s: Some(t as f32),
            ..*nl
        }),
        Effect::BiasBranchHysteresis => {
            grid_1d(&[0.15, 0.3, 0.6, 1.2, 2.5, 5.0, 10.0, 20.0], &|r| Nonlinear { play_r_c: Some(r as f32), ..*nl })
        }
        Effect::BiasCreep => {
            let set = |x: [f64; 2]| Nonlinear {
                creep: Some((
                    x[0].exp().clamp(CREEP_TAU_LIMITS.0, CREEP_TAU_LIMITS.1) as f32,
                    (x[1] * 1000.0).clamp(0.0, CREEP_E_MAX) as f32,
                )),
                ..*nl
            };
            let mut best = ([0.0, 0.0], f64::INFINITY);
            for &tau in &[150.0f64, 450.0, 1350.0, 4000.0, 12_000.0, 36_000.0] {
                for &ek in &[0.0, 2.5, 5.0] {
                    let x = [tau.ln(), ek];
                    let v = obj(&set(x));
                    if v < best.1 {
                        best = (x, v);
                    }
                }
            }
            let (x, v) = nelder_mead2(|x| obj(&set(x)), best.0, [0.5, 1.0], 40);
            set(if v < best.1 { x } else { best.0 })
        }
        _ => *nl,
    }
}

/// Search limits of the nonlinear parameters (the grids in [`search`]); an estimate
/// within 2 % of one is "at bound". The creep activation's lower limit 0 is physical (no
/// thermal activation), not a search limit, so it is not flagged.
pub(super) fn at_bound(e: Effect, nl: &Nonlinear) -> Vec<String> {
    let near = |x: f64, b: f64| (x / b).ln().abs() < 0.02;
    let mut v = Vec::new();
    match e {
        Effect::SensorLag => {
            if let Some(t) = nl.lag_tau_s.map(f64::from) {
                if near(t, LAG_LIMITS.0) || near(t, LAG_LIMITS.1) {
                    v.push(format!("tau_s={t:.0}"));
                }
            }
        }
        Effect::BiasBranchHysteresis => {
            if let Some(r) = nl.play_r_c.map(f64::from) {
                if near(r, PLAY_LIMITS.0) || near(r, PLAY_LIMITS.1) {
                    v.push(format!("half_width_c={r:.2}"));
                }
            }
        }
        Effect::BiasCreep => {
            if let Some((t, ek)) = nl.creep {
                let (t, ek) = (f64::from(t), f64::from(ek));
                if near(t, CREEP_TAU_LIMITS.0) || near(t, CREEP_TAU_LIMITS.1) {
                    v.push(format!("tau_ref_s={t:.0}"));
                }
                if ek >= 0.98 * CREEP_E_MAX {
                    v.push(format!("activation_k={ek:.0}"));
                }
            }
        }
        _ => {}
    }
    v
}
