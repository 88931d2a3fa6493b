//! The drawn unit: its coefficients, its catalog and out-of-catalog effects, and the draw.

use super::*;

/// The drawn unit: scale factor K1 (pulses/(g·s)) and bias K0 (g) at the element
/// temperature Te (°C), ΔT = Te − 22 °C, r = the case temperature's rate (°C/min):
///
/// - K1 = k10 + mu·ΔT + beta·ΔT² + eps·r + eta·r·ΔT + alpha·r² (+ the out-of-catalog
///   scale-factor hysteresis);
/// - K0 = b0 + b1·ΔT + b2·ΔT² + play + creep + drift (+ out-of-catalog bias terms), with
///   play = w·(Te − p)/h, p the play operator of half-width h on Te; creep = g_c·(Te − x),
///   x relaxing to Te with τ(Te) = τ_ref·exp(E·(1/(Te + 273.15) − 1/295.15)); drift = d·t_h,
///   t_h the hours since the run's power-on.
#[derive(Clone, Debug, PartialEq)]
pub struct Unit {
    /// K1 at 22 °C, pulses/(g·s).
    pub k10: f64,
    /// Linear temperature coefficient of K1, pulses/(g·s·°C).
    pub mu: f64,
    /// Quadratic temperature coefficient of K1 (temp_quadratic, scale factor), pulses/(g·s·°C²).
    pub beta: f64,
    /// Rate coefficient (rate_hysteresis), pulses/(g·s) per °C/min.
    pub eps: f64,
    /// Rate × ΔT coefficient (rate_temp_coupling), pulses/(g·s) per (°C/min·°C).
    pub eta: f64,
    /// Rate² coefficient (rate_squared), pulses/(g·s) per (°C/min)².
    pub alpha: f64,
    /// Bias at 22 °C, g.
    pub b0_g: f64,
    /// Linear bias coefficient, g/°C.
    pub b1_g_per_c: f64,
    /// Quadratic bias coefficient (temp_quadratic, bias), g/°C².
    pub b2_g_per_c2: f64,
    /// Element lag behind the case (sensor_lag), s.
    pub lag_tau_s: Option<f64>,
    /// Play operator (bias_branch_hysteresis): half-width °C, weight g.
    pub play: Option<(f64, f64)>,
    /// Creep (bias_creep): gain g/°C, τ_ref s, activation K.
    pub creep: Option<(f64, f64, f64)>,
    /// Drift since power-on (bias_drift), g/h.
    pub drift_g_per_h: f64,
}

impl Unit {
    /// K1 without the out-of-catalog hysteresis, pulses/(g·s).
    pub fn k1(&self, te_c: f64, rate_c_per_min: f64) -> f64 {
        let d = te_c - T_REF_C;
        let r = rate_c_per_min;
        self.k10 + self.mu * d + self.beta * d * d + self.eps * r + self.eta * r * d + self.alpha * r * r
    }

    /// The static part of K0, g.
    pub fn k0_static(&self, te_c: f64) -> f64 {
        let d = te_c - T_REF_C;
        self.b0_g + self.b1_g_per_c * d + self.b2_g_per_c2 * d * d
    }

    /// Creep time constant at `te_c`, s (None when there is no creep).
    pub fn creep_tau_s(&self, te_c: f64) -> Option<f64> {
        self.creep.map(|(_, tau_ref, e)| tau_ref * (e * (1.0 / (te_c + 273.15) - 1.0 / (T_REF_C + 273.15))).exp())
    }
}

/// A catalog effect the unit can carry (the names the discovery may give).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum CatalogEffect {
    /// β·ΔT² on K1, pulses/(g·s·°C²).
    TempQuadSf {
        /// β.
        beta: f64,
    },
    /// b2·ΔT² on K0.
    TempQuadBias {
        /// b2, g/°C².
        b2_g_per_c2: f64,
    },
    /// ε·r on K1.
    RateHysteresis {
        /// ε, pulses/(g·s) per °C/min.
        eps: f64,
    },
    /// α·r² on K1.
    RateSquared {
        /// α, pulses/(g·s) per (°C/min)².
        alpha: f64,
    },
    /// η·r·ΔT on K1.
    RateTempCoupling {
        /// η, pulses/(g·s) per (°C/min·°C).
        eta: f64,
    },
    /// The element follows the case (the DS18B20) through a lag of τ in a steady ramp.
    SensorLag {
        /// τ, s.
        tau_s: f64,
    },
    /// A play operator on Te; the bias adds w·(Te − p)/h.
    BiasBranchHysteresis {
        /// h, °C.
        half_width_c: f64,
        /// w, g.
        weight_g: f64,
    },
    /// The bias adds g_c·(Te − x), x relaxing to Te with a thermally activated τ.
    BiasCreep {
        /// g_c, g/°C.
        gain_g_per_c: f64,
        /// τ at 22 °C, s.
        tau_ref_s: f64,
        /// Activation E, K.
        activation_k: f64,
    },
    /// The bias adds d·t_h since the run's power-on.
    BiasDrift {
        /// d, g/h.
        g_per_h: f64,
    },
}

impl CatalogEffect {
    /// The catalog name.
    pub fn name(&self) -> &'static str {
        match self {
            Self::TempQuadSf { .. } | Self::TempQuadBias { .. } => "temp_quadratic",
            Self::RateHysteresis { .. } => "rate_hysteresis",
            Self::RateSquared { .. } => "rate_squared",
            Self::RateTempCoupling { .. } => "rate_temp_coupling",
            Self::SensorLag { .. } => "sensor_lag",
            Self::BiasBranchHysteresis { .. } => "bias_branch_hysteresis",
            Self::BiasCreep { .. } => "bias_creep",
            Self::BiasDrift { .. } => "bias_drift",
        }
    }

    /// The channel it shows in: "scale_factor", "bias" or "both".
    pub fn channel(&self) -> &'static str {
        match self {
            Self::TempQuadSf { .. }
            | Self::RateHysteresis { .. }
            | Self::RateSquared { .. }
            | Self::RateTempCoupling { .. } => "scale_factor",
            Self::SensorLag { .. } => "both",
            _ => "bias",
        }
    }

    /// Index 0..9 of the variant (for counting draws).
    pub fn kind(&self) -> usize {
        match self {
            Self::TempQuadSf { .. } => 0,
            Self::TempQuadBias { .. } => 1,
            Self::RateHysteresis { .. } => 2,
            Self::RateSquared { .. } => 3,
            Self::RateTempCoupling { .. } => 4,
            Self::SensorLag { .. } => 5,
            Self::BiasBranchHysteresis { .. } => 6,
            Self::BiasCreep { .. } => 7,
            Self::BiasDrift { .. } => 8,
        }
    }
}

/// Effects no catalog name fits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OutOfCatalog {
    /// A bias step in ONE run, from `at_fraction` of that run's length on.
    BiasStep {
        /// Program 0..4 (in [`RATES`] order).
        program_index: usize,
        /// 0 = pos0, 1 = pos2.
        run_index: usize,
        /// Where in the run, 0..1.
        at_fraction: f64,
        /// Step, g.
        size_g: f64,
    },
    /// K1 adds ±ppm·K10 by the sign of the last ramp direction of the element (kept
    /// through holds; 0 before the first ramp).
    SfHysteresis {
        /// Half the branch gap, ppm.
        ppm: f64,
    },
    /// White-noise SD growing linearly 3× from the cold to the hot end of the span.
    TempDependentNoise,
    /// Bias adds a·t on the campaign clock (a level that steps from program to program).
    CampaignAgeing {
        /// a, g/h.
        g_per_h: f64,
    },
    /// One run's white noise 5× and a slow wander (Gauss–Markov, 10 µg, τ 1 h).
    BadRun {
        /// Program 0..4.
        program_index: usize,
        /// 0 = pos0, 1 = pos2.
        run_index: usize,
    },
}

impl OutOfCatalog {
    /// Index 0..5 of the variant.
    pub fn kind(&self) -> usize {
        match self {
            Self::BiasStep { .. } => 0,
            Self::SfHysteresis { .. } => 1,
            Self::TempDependentNoise => 2,
            Self::CampaignAgeing { .. } => 3,
            Self::BadRun { .. } => 4,
        }
    }
}

/// Which instant of the counting interval the row's temperature reading belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stamp {
    /// Taken at the interval's start.
    Start,
    /// Taken at the interval's centre.
    Centre,
    /// Taken at the interval's end.
    End,
}

/// How the pulse rate is integrated over each 0.25-s step.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Counting {
    /// The rate at the step's start held over the step.
    ZeroOrderHold,
    /// Trapezoid between the step's ends.
    FirstOrderHold,
}

/// Everything a log is generated from.
#[derive(Clone, Debug, PartialEq)]
pub struct Draw {
    /// Catalog effects present (absent effects are zero).
    pub catalog: Vec<CatalogEffect>,
    /// Out-of-catalog effects present.
    pub other: Vec<OutOfCatalog>,
    /// Stamp of the temperature reading.
    pub stamp: Stamp,
    /// The reading reflects the case temperature this many seconds before its stamp.
    pub conversion_delay_s: f64,
    /// Counting integration.
    pub counting: Counting,
    /// Row (counting interval) length, s (rounded to a multiple of 0.25 s).
    pub row_s: f64,
    /// White acceleration noise, µg RMS over 10 s of counting.
    pub white_ug_per_10s: f64,
    /// White noise Student-t (3 dof) instead of Gaussian, same SD.
    pub heavy_tails: bool,
    /// About one second in 5 000 carries a spike of ±`glitch_pulses_per_s`.
    pub glitches: bool,
    /// A glitch's size, pulses/s over its one second ([`super::GLITCH_PULSES_PER_S`] by
    /// default).
    pub glitch_pulses_per_s: f64,
    /// Gauss–Markov bias instability: (SD g, τ s); τ 0 = independent each step.
    pub bias_instability: (f64, f64),
    /// Cold and hot ends of the programs, °C.
    pub span_c: (f64, f64),
    /// Heating-only programs (40-min hold at the cold end, ramp to the hot end, 40-min hold).
    pub heating_only: bool,
    /// DS18B20 reading noise before the 1/16-°C quantisation, °C RMS (an addition to the
    /// brief's fields; 0.01 °C by default).
    pub sensor_noise_c: f64,
    /// μ, after its draw, times this: a unit with that many times its own temperature
    /// coefficient (1 by default; an addition for the batch tests' defects).
    pub mu_factor: f64,
    /// Seed of the unit's coefficients and every noise stream.
    pub seed: u64,
}

impl Draw {
    /// A unit with nothing missing from a `simple` start model (K1 and K0 linear in ΔT) and
    /// the default log: end stamp with a 0.75-s conversion delay, first-order hold, 10-s
    /// rows, 3 µg per 10 s white, 1 µg Gauss–Markov (τ 20 min), −10…50 °C.
    pub fn clean(seed: u64) -> Self {
        Self {
            catalog: Vec::new(),
            other: Vec::new(),
            stamp: Stamp::End,
            conversion_delay_s: 0.75,
            counting: Counting::FirstOrderHold,
            row_s: 10.0,
            white_ug_per_10s: 3.0,
            heavy_tails: false,
            glitches: false,
            glitch_pulses_per_s: super::GLITCH_PULSES_PER_S,
            bias_instability: (1e-6, 1200.0),
            span_c: (-10.0, 50.0),
            heating_only: false,
            sensor_noise_c: 0.01,
            mu_factor: 1.0,
            seed,
        }
    }

    /// The same draw with no random part at all (no white, glitch, Gauss–Markov or
    /// DS18B20 noise); the quantisation to 1/16 °C and integer pulses stay.
    pub fn noise_free(mut self) -> Self {
        self.white_ug_per_10s = 0.0;
        self.heavy_tails = false;
        self.glitches = false;
        self.bias_instability = (0.0, 0.0);
        self.sensor_noise_c = 0.0;
        self
    }
}

/// The unit drawn for `d`: K10, μ, b0, b1 randomised ±20 % around 320 000 pulses/(g·s),
/// −30 pulses/(g·s·°C), 120 µg and 3 µg/°C, then the catalog effects of `d` (a later entry
/// of the same kind replaces an earlier one).
pub fn unit(d: &Draw) -> Unit {
    let mut r = Pcg32::new(d.seed, S_UNIT);
    let mut jitter = |x: f64| x * (1.0 + 0.2 * (2.0 * r.uniform() - 1.0));
    let mut u = Unit {
        k10: jitter(320_000.0),
        mu: jitter(-30.0),
        beta: 0.0,
        eps: 0.0,
        eta: 0.0,
        alpha: 0.0,
        b0_g: jitter(120e-6),
        b1_g_per_c: jitter(3e-6),
        b2_g_per_c2: 0.0,
        lag_tau_s: None,
        play: None,
        creep: None,
        drift_g_per_h: 0.0,
    };
    u.mu *= d.mu_factor;
    for e in &d.catalog {
        match *e {
            CatalogEffect::TempQuadSf { beta } => u.beta = beta,
            CatalogEffect::TempQuadBias { b2_g_per_c2 } => u.b2_g_per_c2 = b2_g_per_c2,
            CatalogEffect::RateHysteresis { eps } => u.eps = eps,
            CatalogEffect::RateSquared { alpha } => u.alpha = alpha,
            CatalogEffect::RateTempCoupling { eta } => u.eta = eta,
            CatalogEffect::SensorLag { tau_s } => u.lag_tau_s = Some(tau_s),
            CatalogEffect::BiasBranchHysteresis { half_width_c, weight_g } => u.play = Some((half_width_c, weight_g)),
            CatalogEffect::BiasCreep { gain_g_per_c, tau_ref_s, activation_k } => {
                u.creep = Some((gain_g_per_c, tau_ref_s, activation_k))
            }
            CatalogEffect::BiasDrift { g_per_h } => u.drift_g_per_h = g_per_h,
        }
    }
    u
}

/// A random draw: with probability about 0.35 nothing hidden, else 1–3 distinct effects,
/// each from the catalog (probability 0.7) or out of it (0.3), sizes log-uniform from barely
/// detectable to clear, signs random; random stamp, conversion delay 0 or 0.75 s, counting,
/// glitches and heavy tails each on half the time, bias instability 0–2 µg with τ 10–60 min.
/// Deterministic for a seed.
pub fn random_draw(seed: u64) -> Draw {
    let mut r = Pcg32::new(seed, S_DRAW);
    let mut mix = seed ^ 0xA5A5_5A5A_0F0F_F0F0;
    let mut d = Draw::clean(splitmix64(&mut mix));
    d.stamp = [Stamp::Start, Stamp::Centre, Stamp::End][r.below(3)];
    d.conversion_delay_s = if r.uniform() < 0.5 { 0.0 } else { 0.75 };
    d.counting = if r.uniform() < 0.5 { Counting::ZeroOrderHold } else { Counting::FirstOrderHold };
    d.glitches = r.uniform() < 0.5;
    d.heavy_tails = r.uniform() < 0.5;
    d.bias_instability = (r.range(0.0, 2e-6), r.range(600.0, 3600.0));
    if r.uniform() < 0.35 {
        return d;
    }
    let n = 1 + r.below(3);
    let mut tries = 0;
    while d.catalog.len() + d.other.len() < n && tries < 100 {
        tries += 1;
        if r.uniform() < 0.7 {
            let e = match r.below(9) {
                0 => CatalogEffect::TempQuadSf { beta: r.sign() * r.log_range(0.02, 0.3) },
                1 => CatalogEffect::TempQuadBias { b2_g_per_c2: r.sign() * r.log_range(0.01e-6, 0.2e-6) },
                2 => CatalogEffect::RateHysteresis { eps: r.sign() * r.log_range(0.5, 20.0) },
                3 => CatalogEffect::RateSquared { alpha: r.sign() * r.log_range(0.5, 10.0) },
                4 => CatalogEffect::RateTempCoupling { eta: r.sign() * r.log_range(0.02, 0.5) },
                5 => CatalogEffect::SensorLag { tau_s: r.log_range(60.0, 900.0) },
                6 => CatalogEffect::BiasBranchHysteresis {
                    half_width_c: r.log_range(0.5, 5.0),
                    weight_g: r.sign() * r.log_range(1e-6, 20e-6),
                },
                7 => CatalogEffect::BiasCreep {
                    gain_g_per_c: r.sign() * r.log_range(0.1e-6, 2e-6),
                    tau_ref_s: r.log_range(300.0, 5000.0),
                    activation_k: r.range(0.0, 6000.0),
                },
                _ => CatalogEffect::BiasDrift { g_per_h: r.sign() * r.log_range(0.3e-6, 5e-6) },
            };
            if d.catalog.iter().all(|c| c.kind() != e.kind()) {
                d.catalog.push(e);
            }
        } else {
            let e = match r.below(5) {
                0 => OutOfCatalog::BiasStep {
                    program_index: r.below(RATES.len()),
                    run_index: r.below(2),
                    at_fraction: r.range(0.2, 0.8),
                    size_g: r.sign() * r.log_range(5e-6, 60e-6),
                },
                1 => OutOfCatalog::SfHysteresis { ppm: r.log_range(1.0, 20.0) },
                2 => OutOfCatalog::TempDependentNoise,
                3 => OutOfCatalog::CampaignAgeing { g_per_h: r.log_range(0.1e-6, 1e-6) },
                _ => OutOfCatalog::BadRun { program_index: r.below(RATES.len()), run_index: r.below(2) },
            };
            if d.other.iter().all(|o| o.kind() != e.kind()) {
                d.other.push(e);
            }
        }
    }
    d
}

// ---------------------------------------------------------------------------------------
// Chamber programs and the thermal chain.
// ---------------------------------------------------------------------------------------
