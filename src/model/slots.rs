//! The extension slots the discovery workflow switches on: the sensor lag, the bias
//! branch's play and the bias creep, each off (`None`) by default.

use serde::{Deserialize, Serialize};

/// `sensor_lag`: the sensing element follows the DS18B20 reading through a first-order lag.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct SensorLag {
    /// Time constant τ, s.
    pub tau_s: f32,
}

/// `bias_branch_hysteresis`: a play operator of half-width r on temperature.
///
/// The play output p follows T but stays within `[T − r, T + r]`; the bias gains
/// `weight·(T − p)/r`, which is +weight after sustained heating, −weight after sustained
/// cooling, holds its value through holds, and switches over 2r after a turnaround.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct BranchHysteresis {
    /// Half-width r, °C.
    pub half_width_c: f32,
    /// Weight, g.
    pub weight_g: f32,
}

/// `bias_creep`: viscoelastic relaxation of the bias toward equilibrium.
///
/// A state x relaxes toward T with `τ(T) = τ_ref·exp(E·(1/(T+273.15) − 1/(T_ref+273.15)))`
/// (Arrhenius: faster when hot for E > 0); the bias gains `gain·(T − x)`, which grows
/// with ramp rate (≈ gain·τ·Ṫ on a ramp) and decays to zero over τ during a hold.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Creep {
    /// Gain, g per °C.
    pub gain_g_per_c: f32,
    /// τ at `t_ref_c`, s.
    pub tau_ref_s: f32,
    /// Reference temperature of τ, °C.
    pub t_ref_c: f32,
    /// Activation temperature E (activation energy / Boltzmann), K.
    pub activation_k: f32,
}

impl Creep {
    /// τ(T), s.
    #[must_use]
    pub fn tau_s(&self, t_c: f32) -> f32 {
        let inv = 1.0 / (t_c + 273.15) - 1.0 / (self.t_ref_c + 273.15);
        self.tau_ref_s * libm::expf(self.activation_k * inv)
    }
}

/// The extension slots the discovery workflow switches on; each is off (`None`) by default.
#[derive(Clone, Copy, Debug, PartialEq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Extensions {
    /// Element temperature lags the sensor.
    pub sensor_lag: Option<SensorLag>,
    /// Rate-independent bias branch hysteresis.
    pub bias_branch_hysteresis: Option<BranchHysteresis>,
    /// Temperature-dependent bias creep.
    pub bias_creep: Option<Creep>,
}

impl Extensions {
    /// Every slot off: [`Extensions::default`] in a `const`.
    pub const NONE: Self = Self { sensor_lag: None, bias_branch_hysteresis: None, bias_creep: None };
}
