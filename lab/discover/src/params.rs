//! An effect's parameters by report name, and the name of the weight its weight test is on.

use super::*;

/// Report name of the weight an effect is tested on ([`WeightZ`]); `None` for a lag and a
/// creep, which answer to the held-out test alone.
pub(super) fn weight_key(e: Effect, unit: BiasUnit) -> Option<String> {
    Some(match e {
        Effect::TempQuadSf => "beta".into(),
        Effect::TempQuadBias => unit.param("beta", "_per_c2"),
        Effect::RateHysteresis => "epsilon".into(),
        Effect::RateSquared => "alpha".into(),
        Effect::RateTempCoupling => "eta".into(),
        Effect::BiasBranchHysteresis => unit.param("weight", ""),
        // The creep's gain trades off against its τ (a long τ with a large gain looks like a
        // short one with a small gain; its interval was [0.5, 43] µg/°C on a two-τ creep
        // log), so the gain is not a weight to test; like the lag, the creep answers to
        // the held-out test alone.
        Effect::SensorLag | Effect::BiasCreep => return None,
        Effect::BiasDrift => unit.param("drift", "_per_h"),
    })
}

/// An effect's parameters by report name, bias terms in the report's unit
/// ([`BiasUnit::param`]: µg for a cycling log, whose model holds g).
pub(super) fn effect_params(e: Effect, f: &Fitted, unit: BiasUnit) -> std::collections::BTreeMap<String, f64> {
    let mut p = std::collections::BTreeMap::new();
    let m = &f.model;
    let s = &m.scale;
    let k = unit.to_report();
    match e {
        Effect::TempQuadSf => {
            p.insert("beta".into(), f64::from(s.beta));
        }
        Effect::TempQuadBias => {
            // Curvature of the grid: second difference / step².
            let g = &m.bias.heating_g;
            let h = f64::from(m.bias.t_step_c);
            let n = g.len();
            let c: f64 =
                (1..n - 1).map(|i| f64::from(g[i + 1] - 2.0 * g[i] + g[i - 1])).sum::<f64>() / ((n - 2) as f64 * h * h);
            p.insert(unit.param("beta", "_per_c2"), k * c / 2.0);
        }
        Effect::RateHysteresis => {
            p.insert("epsilon".into(), f64::from(s.epsilon));
        }
        Effect::RateSquared => {
            p.insert("alpha".into(), f64::from(s.alpha));
        }
        Effect::RateTempCoupling => {
            p.insert("eta".into(), f64::from(s.eta));
        }
        Effect::SensorLag => {
            if let Some(l) = m.ext.sensor_lag {
                p.insert("tau_s".into(), f64::from(l.tau_s));
            }
        }
        Effect::BiasBranchHysteresis => {
            if let Some(h) = m.ext.bias_branch_hysteresis {
                p.insert("half_width_c".into(), f64::from(h.half_width_c));
                p.insert(unit.param("weight", ""), k * f64::from(h.weight_g));
            }
        }
        Effect::BiasCreep => {
            if let Some(c) = m.ext.bias_creep {
                p.insert(unit.param("gain", "_per_c"), k * f64::from(c.gain_g_per_c));
                p.insert("tau_ref_s".into(), f64::from(c.tau_ref_s));
                p.insert("t_ref_c".into(), f64::from(c.t_ref_c));
                p.insert("activation_k".into(), f64::from(c.activation_k));
            }
        }
        Effect::BiasDrift => {
            if let Some(d) = f.drift_per_h {
                p.insert(unit.param("drift", "_per_h"), k * d);
            }
        }
    }
    p
}
