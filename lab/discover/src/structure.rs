//! What a discovery round adds or removes: the effects ([`Effect`]), the linear terms a
//! structure fits ([`Structure`]) and the nonlinear parameters of its slots ([`Nonlinear`]).

use super::Start;
use qfa_log::channels::LogKind;

/// A catalog effect (with the channel it acts on for `temp_quadratic`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub(crate) enum Effect {
    /// β·ΔT² on the scale factor.
    TempQuadSf,
    /// β_b·ΔT² on the bias (simple start only; the paper start's bias grid already curves).
    TempQuadBias,
    /// ε·Ṫ on the scale factor.
    RateHysteresis,
    /// α·Ṫ² on the scale factor.
    RateSquared,
    /// η·Ṫ·ΔT on the scale factor.
    RateTempCoupling,
    /// Element temperature lags the DS18B20 (both channels).
    SensorLag,
    /// Play operator on the bias.
    BiasBranchHysteresis,
    /// Arrhenius creep on the bias.
    BiasCreep,
    /// Slow drift of the bias with time since the start of the program (ageing, turn-on
    /// settling): `d·t`. Signature: follows time, not temperature or its history, so it
    /// shows on holds as much as on ramps. Lab-only: the root crate has no time slot yet,
    /// so a discovered drift is reported but cannot go into the flashed table.
    BiasDrift,
}

impl Effect {
    /// Every effect, in catalog order.
    pub(crate) const ALL: [Effect; 9] = [
        Effect::TempQuadSf,
        Effect::TempQuadBias,
        Effect::RateHysteresis,
        Effect::RateSquared,
        Effect::RateTempCoupling,
        Effect::SensorLag,
        Effect::BiasBranchHysteresis,
        Effect::BiasCreep,
        Effect::BiasDrift,
    ];

    /// Catalog name.
    #[must_use]
    pub(crate) fn name(self) -> &'static str {
        match self {
            Effect::TempQuadSf | Effect::TempQuadBias => "temp_quadratic",
            Effect::RateHysteresis => "rate_hysteresis",
            Effect::RateSquared => "rate_squared",
            Effect::RateTempCoupling => "rate_temp_coupling",
            Effect::SensorLag => "sensor_lag",
            Effect::BiasBranchHysteresis => "bias_branch_hysteresis",
            Effect::BiasCreep => "bias_creep",
            Effect::BiasDrift => "bias_drift",
        }
    }

    /// Channel it acts on: `scale_factor`, `bias` or `both`.
    #[must_use]
    pub(crate) fn channel(self) -> &'static str {
        match self {
            Effect::TempQuadSf | Effect::RateHysteresis | Effect::RateSquared | Effect::RateTempCoupling => {
                "scale_factor"
            }
            Effect::TempQuadBias | Effect::BiasBranchHysteresis | Effect::BiasCreep | Effect::BiasDrift => "bias",
            Effect::SensorLag => "both",
        }
    }

    /// Parameters it adds (for the selection penalty).
    #[must_use]
    pub(crate) fn n_params(self) -> usize {
        match self {
            Effect::BiasBranchHysteresis => 2,
            Effect::BiasCreep => 3,
            _ => 1,
        }
    }

    /// Whether the root crate's `AxisModel` can run it (so it goes into the table).
    #[must_use]
    pub(crate) fn in_firmware(self) -> bool {
        self != Effect::BiasDrift
    }

    /// Whether it acts on the scale-factor channel.
    #[must_use]
    pub(crate) fn touches_sf(self) -> bool {
        self.channel() != "bias"
    }

    /// Whether it acts on the bias channel.
    #[must_use]
    pub(crate) fn touches_bias(self) -> bool {
        self.channel() != "scale_factor"
    }
}

/// Nonlinear parameters of the slots that are on.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Nonlinear {
    /// sensor_lag τ, s.
    pub lag_tau_s: Option<f32>,
    /// bias_branch_hysteresis half-width, °C.
    pub play_r_c: Option<f32>,
    /// bias_creep (τ_ref s, activation K).
    pub creep: Option<(f32, f32)>,
}

impl Nonlinear {
    /// The parameters with `e`'s slot off.
    #[must_use]
    pub(crate) fn without(mut self, e: Effect) -> Self {
        match e {
            Effect::SensorLag => self.lag_tau_s = None,
            Effect::BiasBranchHysteresis => self.play_r_c = None,
            Effect::BiasCreep => self.creep = None,
            _ => {}
        }
        self
    }
}

/// Linear structure: which terms are in the model.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Structure {
    /// Start model.
    pub start: Start,
    /// β on the scale factor.
    pub sf_quad: bool,
    /// ε.
    pub sf_eps: bool,
    /// α.
    pub sf_alpha: bool,
    /// η.
    pub sf_eta: bool,
    /// ΔT² on a linear bias (simple start).
    pub bias_quad: bool,
    /// Bias drift with time (lab-only term).
    pub bias_drift: bool,
}

impl Structure {
    /// The start model's structure.
    #[must_use]
    pub(crate) fn start(start: Start) -> Self {
        let p = start == Start::Paper;
        Self { start, sf_quad: p, sf_eps: p, sf_alpha: p, sf_eta: p, bias_quad: false, bias_drift: false }
    }

    /// Whether `e` can still be added.
    #[must_use]
    pub(crate) fn can_add(&self, e: Effect, nl: &Nonlinear, kind: LogKind) -> bool {
        let cyc = kind == LogKind::Cycling;
        match e {
            Effect::TempQuadSf => cyc && !self.sf_quad,
            Effect::RateHysteresis => cyc && !self.sf_eps,
            Effect::RateSquared => cyc && !self.sf_alpha,
            Effect::RateTempCoupling => cyc && !self.sf_eta,
            Effect::TempQuadBias => self.start == Start::Simple && !self.bias_quad,
            Effect::SensorLag => nl.lag_tau_s.is_none(),
            Effect::BiasBranchHysteresis => nl.play_r_c.is_none(),
            Effect::BiasCreep => nl.creep.is_none(),
            Effect::BiasDrift => !self.bias_drift,
        }
    }

    /// The structure with the linear part of `e` switched off (the start model's own
    /// terms stay).
    #[must_use]
    pub(crate) fn without(self, e: Effect) -> Self {
        let base = Structure::start(self.start);
        let mut s = self;
        match e {
            Effect::TempQuadSf => s.sf_quad = base.sf_quad,
            Effect::TempQuadBias => s.bias_quad = base.bias_quad,
            Effect::RateHysteresis => s.sf_eps = base.sf_eps,
            Effect::RateSquared => s.sf_alpha = base.sf_alpha,
            Effect::RateTempCoupling => s.sf_eta = base.sf_eta,
            Effect::BiasDrift => s.bias_drift = false,
            _ => {}
        }
        s
    }

    /// The structure with the linear part of `e` switched on.
    #[must_use]
    pub(crate) fn with(mut self, e: Effect) -> Self {
        match e {
            Effect::TempQuadSf => self.sf_quad = true,
            Effect::TempQuadBias => self.bias_quad = true,
            Effect::RateHysteresis => self.sf_eps = true,
            Effect::RateSquared => self.sf_alpha = true,
            Effect::RateTempCoupling => self.sf_eta = true,
            Effect::BiasDrift => self.bias_drift = true,
            _ => {}
        }
        self
    }
}
