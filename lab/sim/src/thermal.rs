//! Thermal chain: chamber air → accelerometer case (DS18B20 on it) → sensing element.
//!
//! Each link is a first-order lag `dy/dt = (u − y)/τ`. Chosen time constants:
//! * **case** τ = 600 s (10 min): a JB-KT8-size steel case in an index-head fixture in
//!   forced chamber air. With the paper's 3-min dwell per 1 °C step this smooths the
//!   chamber staircase to a ripple of about ±0.05 °C/min on the case rate.
//! * **element** τ = 180 s (3 min): the quartz proof mass and torquer inside the case,
//!   coupled through the epoxy and the gas gap. Only used by the truth model when the
//!   `sensor_lag` effect is on (then its τ is the effect's τ), and for plots otherwise.
//!
//! The step is exact for an input linear over the step: with `u(s) = u0 + k·s`,
//! `y(dt) = u(dt) − k·τ + (y0 − u0 + k·τ)·e^{−dt/τ}`.

use serde::{Deserialize, Serialize};

/// Time constants of the chain.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ThermalChain {
    /// Air → case, s.
    pub case_tau_s: f64,
    /// Case → element, s (used when `sensor_lag` is off; otherwise `sensor_lag.tau_s`).
    pub element_tau_s: f64,
}

impl Default for ThermalChain {
    fn default() -> Self {
        Self { case_tau_s: 600.0, element_tau_s: 180.0 }
    }
}

/// One first-order lag with a cached step weight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lag {
    tau_s: f64,
    dt_s: f64,
    decay: f64,
    /// Output.
    pub y: f64,
}

impl Lag {
    /// A lag at rest at `y0`, stepping by `dt_s`.
    #[must_use]
    pub(crate) fn new(tau_s: f64, dt_s: f64, y0: f64) -> Self {
        Self { tau_s, dt_s, decay: (-dt_s / tau_s).exp(), y: y0 }
    }

    /// Advance one step with the input going linearly from `u0` to `u1`; returns the output.
    pub(crate) fn step(&mut self, u0: f64, u1: f64) -> f64 {
        let k_tau = (u1 - u0) / self.dt_s * self.tau_s;
        self.y = u1 - k_tau + (self.y - u0 + k_tau) * self.decay;
        self.y
    }

    /// Step length, s.
    #[must_use]
    pub(crate) fn dt_s(&self) -> f64 {
        self.dt_s
    }

    /// Current rate of change for input `u`, per second.
    #[must_use]
    pub(crate) fn rate_per_s(&self, u: f64) -> f64 {
        (u - self.y) / self.tau_s
    }
}

/// State of the chain.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ChainState {
    /// Case lag.
    pub case: Lag,
    /// Element lag.
    pub element: Lag,
    air_c: f64,
}

/// Temperatures after a step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Temps {
    /// Chamber air, °C.
    pub air_c: f64,
    /// Case (DS18B20), °C.
    pub case_c: f64,
    /// Case rate, °C/min (exact, from the lag equation).
    pub case_rate_c_per_min: f64,
    /// Sensing element, °C.
    pub element_c: f64,
}

impl ThermalChain {
    /// Everything at rest at `t0_c`, stepping by `dt_s`; the element uses `element_tau_s`.
    #[must_use]
    pub fn start(&self, t0_c: f64, dt_s: f64, element_tau_s: f64) -> ChainState {
        ChainState {
            case: Lag::new(self.case_tau_s, dt_s, t0_c),
            element: Lag::new(element_tau_s, dt_s, t0_c),
            air_c: t0_c,
        }
    }
}

impl ChainState {
    /// Advance one step to air temperature `air_c` (linear from the previous one).
    pub fn step(&mut self, air_c: f64) -> Temps {
        let c0 = self.case.y;
        let c1 = self.case.step(self.air_c, air_c);
        let e = self.element.step(c0, c1);
        self.air_c = air_c;
        Temps { air_c, case_c: c1, case_rate_c_per_min: self.case.rate_per_s(air_c) * 60.0, element_c: e }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ramp_response_lags_by_tau() {
        // A steady ramp k through a lag settles at u − k·τ.
        let mut l = Lag::new(600.0, 1.0, 0.0);
        let k = 0.01;
        for i in 0..20_000 {
            l.step(k * f64::from(i), k * f64::from(i + 1));
        }
        let u = k * 20_000.0;
        assert!((l.y - (u - k * 600.0)).abs() < 1e-6, "{}", l.y);
        // Step response after one τ: 1 − 1/e.
        let mut s = Lag::new(180.0, 1.0, 0.0);
        for _ in 0..180 {
            s.step(1.0, 1.0);
        }
        assert!((s.y - (1.0 - (-1.0f64).exp())).abs() < 1e-9);
    }
}
