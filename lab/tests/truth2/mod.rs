//! The second independent truth generator for cycling logs (an oracle).
//!
//! It shares no code with the project: nothing from the lab (`lab/src`), nothing from the
//! firmware (`src/`), nothing from the first independent generator (`tests/truth/`). It is
//! written from the physical definitions of the unit (scale factor K1, bias K0 and the
//! catalog's effects, stated on [`Unit`] and [`CatalogEffect`]), not from the fitter's code,
//! and it writes the four-position test's CSV
//! (`program,run,time_s,input_g,temp_c,pulses,interval_s`) that the lab's reader accepts.
//!
//! How it differs from `tests/truth/` on purpose, so that agreement between the two is not a
//! shared mistake:
//!
//! | | `truth/` | `truth2/` (this module) |
//! |---|---|---|
//! | thermal chain | case τ 300 s (+ optional element lag), one exact first-order step per second | two coupled nodes (air → case τ 400 s, case ↔ element, element weakly coupled to the air), RK4 at 0.25 s |
//! | programs | 1-°C steps with 3-min dwells | continuous linear ramps, holds 30/40/40/30 min, span configurable, heating-only option |
//! | counting | trapezoid per 1 s, rounded | 0.25-s steps, zero-order or first-order hold ([`Counting`]), floor with the remainder carried |
//! | temperature stamp | latest 1-Hz reading at the row's end | start, centre or end of the row ([`Stamp`]) plus a conversion delay |
//! | noise | Gaussian white + Gauss–Markov | white (Gaussian or Student-t, 3 dof), glitches, Gauss–Markov (τ 0 allowed), temperature-dependent, bad runs |
//! | RNG | xorshift64* with Box–Muller | PCG32 (XSH-RR) seeded through SplitMix64, one stream per purpose, Marsaglia's polar method |
//! | unit | fixed coefficients | drawn per seed (±20 %), catalog rate terms, hysteresis, creep, drift, out-of-catalog effects |
//!
//! Streams: the unit's coefficients, each run's white noise, glitches, Gauss–Markov bias, bad
//! run wander and DS18B20 noise each draw from their own PCG32 stream, so switching one
//! option (a stamp, glitches) leaves every other random sequence of the log unchanged.
//!
//! Time base: every run of a program is its own power-on at t = 0 of the program's chamber
//! schedule; the runs follow one another (program by program, `pos0` then `pos2`) on a
//! campaign clock that only the out-of-catalog campaign ageing sees.

#![allow(dead_code)]

// ---------------------------------------------------------------------------------------
// RNG: PCG32 (O'Neill's XSH-RR, 64-bit state) seeded through SplitMix64; normals by the
// Marsaglia polar method (the second value of each accepted pair is kept for the next call).
// ---------------------------------------------------------------------------------------

/// SplitMix64 step: a well-mixed 64-bit value from a counter (used only for seeding).
pub fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// PCG32 (XSH-RR) with a cached polar-method normal.
#[derive(Clone, Debug)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
    spare: Option<f64>,
}

impl Pcg32 {
    const MUL: u64 = 6_364_136_223_846_793_005;

    /// A stream for `seed` and purpose `stream`: both mixed through SplitMix64.
    pub fn new(seed: u64, stream: u64) -> Self {
        let mut s = seed ^ stream.rotate_left(32);
        let init = splitmix64(&mut s);
        let seq = splitmix64(&mut s);
        let mut r = Self { state: 0, inc: (seq << 1) | 1, spare: None };
        r.next_u32();
        r.state = r.state.wrapping_add(init);
        r.next_u32();
        r
    }

    /// Next 32 random bits.
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(Self::MUL).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        xorshifted.rotate_right((old >> 59) as u32)
    }

    /// Uniform in the open interval (0, 1), 53 bits.
    pub fn uniform(&mut self) -> f64 {
        let hi = u64::from(self.next_u32() >> 5); // 27 bits
        let lo = u64::from(self.next_u32() >> 6); // 26 bits
        (((hi << 26) | lo) as f64 + 0.5) / 9_007_199_254_740_992.0
    }

    /// Uniform in [a, b).
    pub fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.uniform()
    }

    /// Log-uniform in [a, b] (a, b > 0).
    pub fn log_range(&mut self, a: f64, b: f64) -> f64 {
        (a.ln() + (b.ln() - a.ln()) * self.uniform()).exp()
    }

    /// +1 or −1 with equal probability.
    pub fn sign(&mut self) -> f64 {
        if self.next_u32() & 1 == 0 {
            1.0
        } else {
            -1.0
        }
    }

    /// An integer in 0..n.
    pub fn below(&mut self, n: usize) -> usize {
        ((self.uniform() * n as f64) as usize).min(n - 1)
    }

    /// Standard normal (Marsaglia polar method).
    pub fn normal(&mut self) -> f64 {
        if let Some(z) = self.spare.take() {
            return z;
        }
        loop {
            let u = 2.0 * self.uniform() - 1.0;
            let v = 2.0 * self.uniform() - 1.0;
            let s = u * u + v * v;
            if s > 0.0 && s < 1.0 {
                let f = (-2.0 * s.ln() / s).sqrt();
                self.spare = Some(v * f);
                return u * f;
            }
        }
    }

    /// Student-t with 3 degrees of freedom scaled to unit SD (its variance is 3).
    pub fn student3(&mut self) -> f64 {
        let z = self.normal();
        let (a, b, c) = (self.normal(), self.normal(), self.normal());
        z / ((a * a + b * b + c * c) / 3.0).sqrt() / 3f64.sqrt()
    }
}

// Stream purposes (combined with the seed and the run).
const S_UNIT: u64 = 0x0001;
const S_WHITE: u64 = 0x0100;
const S_GLITCH: u64 = 0x0200;
const S_GM: u64 = 0x0300;
const S_WANDER: u64 = 0x0400;
const S_SENSOR: u64 = 0x0500;
const S_DRAW: u64 = 0x0600;

fn run_stream(seed: u64, purpose: u64, program: usize, run: usize) -> Pcg32 {
    Pcg32::new(seed, purpose + 16 * program as u64 + run as u64)
}

// ---------------------------------------------------------------------------------------
// The unit, the catalog and the draw.
// ---------------------------------------------------------------------------------------

/// Reference temperature of ΔT, °C.
pub const T_REF_C: f64 = 22.0;
/// Integration and counting step, s.
pub const DT_S: f64 = 0.25;
/// Chamber air → case time constant, s.
pub const TAU_CASE_S: f64 = 400.0;
/// Ramp rates of the four programs, °C/min.
pub const RATES: [f64; 4] = [0.3, 0.5, 0.7, 0.9];
/// Glitch probability per second and its size, pulses/s.
pub const GLITCH_PER_S: f64 = 1.0 / 5000.0;
/// Glitch size, pulses/s over one second.
pub const GLITCH_PULSES_PER_S: f64 = 200.0;

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
    /// About one second in 5 000 carries a ±200 pulses/s spike.
    pub glitches: bool,
    /// Gauss–Markov bias instability: (SD g, τ s); τ 0 = independent each step.
    pub bias_instability: (f64, f64),
    /// Cold and hot ends of the programs, °C.
    pub span_c: (f64, f64),
    /// Heating-only programs (40-min hold at the cold end, ramp to the hot end, 40-min hold).
    pub heating_only: bool,
    /// DS18B20 reading noise before the 1/16-°C quantisation, °C RMS (an addition to the
    /// brief's fields; 0.01 °C by default).
    pub sensor_noise_c: f64,
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
            bias_instability: (1e-6, 1200.0),
            span_c: (-10.0, 50.0),
            heating_only: false,
            sensor_noise_c: 0.01,
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

/// The chamber schedule of one program: (s, °C) knots joined by straight lines, and the
/// times at which each ramp ends.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    /// Ramp rate, °C/min.
    pub rate_c_per_min: f64,
    /// (time s, chamber °C) knots.
    pub knots: Vec<(f64, f64)>,
    /// End of each ramp, s.
    pub ramp_ends_s: Vec<f64>,
    /// Length, s.
    pub duration_s: f64,
}

/// The program at `rate` °C/min: hold 30 min at 22 °C, ramp to the cold end, hold 40 min,
/// ramp to the hot end, hold 40 min, ramp to 22 °C, hold 30 min; heating-only: hold 40 min
/// at the cold end (where the unit has soaked), ramp to the hot end, hold 40 min.
pub fn program(rate: f64, span_c: (f64, f64), heating_only: bool) -> Program {
    let (lo, hi) = span_c;
    let (start, holds_targets): (f64, Vec<(f64, f64)>) =
        if heating_only { (lo, vec![(hi, 40.0)]) } else { (T_REF_C, vec![(lo, 40.0), (hi, 40.0), (T_REF_C, 30.0)]) };
    let first_hold_min = if heating_only { 40.0 } else { 30.0 };
    let mut t = first_hold_min * 60.0;
    let mut knots = vec![(0.0, start), (t, start)];
    let mut ramp_ends_s = Vec::new();
    let mut temp = start;
    for (target, hold_min) in holds_targets {
        t += (target - temp).abs() / rate * 60.0;
        knots.push((t, target));
        ramp_ends_s.push(t);
        t += hold_min * 60.0;
        knots.push((t, target));
        temp = target;
    }
    Program { rate_c_per_min: rate, knots, ramp_ends_s, duration_s: t }
}

fn air(knots: &[(f64, f64)], t: f64) -> f64 {
    let i = knots.partition_point(|k| k.0 <= t);
    if i == 0 {
        return knots[0].1;
    }
    if i == knots.len() {
        return knots[knots.len() - 1].1;
    }
    let (a, b) = (knots[i - 1], knots[i]);
    a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
}

/// The thermal chain's couplings (1/s). Case: dTc/dt = (Ta − Tc)/400 s + c·(Te − Tc);
/// element: dTe/dt = k_ce·(Tc − Te) + k_ae·(Ta − Te). k_ae (weak) and c (the element's
/// small heat capacity loading the case) are fixed fractions; k_ce is chosen so that in a
/// steady ramp at rate R the element lags the case by exactly τ·R (the catalog's
/// sensor_lag τ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain {
    /// Element → case back-coupling c.
    pub c_back: f64,
    /// Case → element k_ce.
    pub k_ce: f64,
    /// Air → element k_ae.
    pub k_ae: f64,
}

impl Chain {
    /// The couplings for a lag τ (s).
    pub fn for_lag(tau_s: f64) -> Self {
        let k_ae = 0.02 / tau_s.max(60.0);
        let c_back = 0.1 / tau_s.max(60.0);
        // Steady ramp R: Ta − Tc = 400·(R + c·L), R = k_ce·L + k_ae·(Ta − Tc + L) with L = τR.
        let k_ce = (1.0 - TAU_CASE_S * k_ae) / tau_s - k_ae * (1.0 + TAU_CASE_S * c_back);
        Self { c_back, k_ce, k_ae }
    }
}

/// The thermal state at every 0.25-s grid point of one program (identical for both runs:
/// the chamber, not the unit's attitude, drives it).
#[derive(Clone, Debug, Default)]
pub struct Thermal {
    /// Case temperature (where the DS18B20 sits), °C.
    pub tc: Vec<f64>,
    /// Element temperature, °C.
    pub te: Vec<f64>,
    /// Case temperature rate, °C/min (the model's derivative, not a difference).
    pub rc: Vec<f64>,
    /// Element temperature rate, °C/min.
    pub re: Vec<f64>,
    /// Creep state x, °C.
    pub x: Vec<f64>,
    /// Play operator output p, °C.
    pub p: Vec<f64>,
}

/// Integrates the chain with RK4 at 0.25 s over `prog` for `u`.
pub fn thermal(prog: &Program, u: &Unit) -> Thermal {
    let n = (prog.duration_s / DT_S).round() as usize;
    let chain = u.lag_tau_s.map(Chain::for_lag);
    let knots = &prog.knots;
    // State [Tc, Te, x]; without a lag Te is Tc.
    let rhs = |t: f64, s: [f64; 3]| -> [f64; 3] {
        let ta = air(knots, t);
        let (tc, te_state, x) = (s[0], s[1], s[2]);
        let (dtc, te, dte) = match chain {
            Some(ch) => {
                let dtc = (ta - tc) / TAU_CASE_S + ch.c_back * (te_state - tc);
                (dtc, te_state, ch.k_ce * (tc - te_state) + ch.k_ae * (ta - te_state))
            }
            None => {
                let dtc = (ta - tc) / TAU_CASE_S;
                (dtc, tc, dtc)
            }
        };
        let dx = match u.creep_tau_s(te) {
            Some(tau) => (te - x) / tau,
            None => 0.0,
        };
        [dtc, dte, dx]
    };
    let t0 = knots[0].1;
    let mut s = [t0, t0, t0];
    let mut th = Thermal::default();
    let mut p = t0;
    for k in 0..=n {
        let t = k as f64 * DT_S;
        if chain.is_none() {
            s[1] = s[0];
        }
        let f = rhs(t, s);
        if let Some((h, _)) = u.play {
            p = p.clamp(s[1] - h, s[1] + h);
        }
        th.tc.push(s[0]);
        th.te.push(s[1]);
        th.rc.push(60.0 * f[0]);
        th.re.push(60.0 * f[1]);
        th.x.push(s[2]);
        th.p.push(p);
        if k == n {
            break;
        }
        let add = |a: [f64; 3], b: [f64; 3], w: f64| [a[0] + w * b[0], a[1] + w * b[1], a[2] + w * b[2]];
        let k1 = f;
        let k2 = rhs(t + 0.5 * DT_S, add(s, k1, 0.5 * DT_S));
        let k3 = rhs(t + 0.5 * DT_S, add(s, k2, 0.5 * DT_S));
        let k4 = rhs(t + DT_S, add(s, k3, DT_S));
        for i in 0..3 {
            s[i] += DT_S / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    th
}

fn interp(v: &[f64], t: f64) -> f64 {
    let x = (t / DT_S).clamp(0.0, (v.len() - 1) as f64);
    let i = (x.floor() as usize).min(v.len() - 2);
    let f = x - i as f64;
    v[i] + f * (v[i + 1] - v[i])
}

// ---------------------------------------------------------------------------------------
// The log.
// ---------------------------------------------------------------------------------------

/// The truth behind one row, at the centre of its counting interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowTruth {
    /// Program index (in [`RATES`] order).
    pub program: usize,
    /// 0 = pos0, 1 = pos2.
    pub run: usize,
    /// The row's `time_s` (end of its interval), s.
    pub time_s: f64,
    /// Element temperature at the centre, °C.
    pub te_c: f64,
    /// Case temperature at the centre, °C.
    pub tc_c: f64,
    /// Case rate at the centre, °C/min.
    pub rate_c_per_min: f64,
    /// K1 at the centre, all terms, pulses/(g·s).
    pub k1: f64,
    /// K0 at the centre, all deterministic terms (no noise, no Gauss–Markov, no wander), g.
    pub k0_g: f64,
}

/// What [`cycling_traced`] returns besides the CSV.
#[derive(Clone, Debug)]
pub struct Trace {
    /// The unit.
    pub unit: Unit,
    /// The programs, in log order.
    pub programs: Vec<Program>,
    /// One entry per CSV row, in log order.
    pub rows: Vec<RowTruth>,
    /// Seconds that carried a glitch.
    pub glitch_seconds: usize,
    /// Seconds counted in the whole log.
    pub counted_seconds: usize,
}

/// The CSV text of the draw's cycling log.
pub fn cycling(d: &Draw) -> String {
    cycling_traced(d).0
}

/// The CSV text and the truth behind it.
pub fn cycling_traced(d: &Draw) -> (String, Trace) {
    let u = unit(d);
    let (lo, hi) = d.span_c;
    let sub = ((d.row_s / DT_S).round() as usize).max(1);
    let row = sub as f64 * DT_S;
    let sf_hyst_ppm: f64 =
        d.other.iter().map(|o| if let OutOfCatalog::SfHysteresis { ppm } = o { *ppm } else { 0.0 }).sum();
    let campaign_g_per_h: f64 =
        d.other.iter().map(|o| if let OutOfCatalog::CampaignAgeing { g_per_h } = o { *g_per_h } else { 0.0 }).sum();
    let temp_noise = d.other.contains(&OutOfCatalog::TempDependentNoise);
    let white_step = d.white_ug_per_10s * 1e-6 * (10.0 / DT_S).sqrt();
    let (gm_sd, gm_tau) = d.bias_instability;
    let gm_phi = if gm_tau > 0.0 { (-DT_S / gm_tau).exp() } else { 0.0 };
    let wander_phi = (-DT_S / 3600.0f64).exp();
    let prefix = if d.heating_only { "heat" } else { "ramp" };

    let mut out = String::from("program,run,time_s,input_g,temp_c,pulses,interval_s\n");
    let mut trace =
        Trace { unit: u.clone(), programs: Vec::new(), rows: Vec::new(), glitch_seconds: 0, counted_seconds: 0 };
    let mut campaign_s = 0.0;
    for (pi, &rate) in RATES.iter().enumerate() {
        let prog = program(rate, d.span_c, d.heating_only);
        let th = thermal(&prog, &u);
        let n = th.tc.len() - 1;
        let rows = n / sub;
        // Scale factor at every grid point, with the direction of the last ramp.
        let mut dir = 0.0f64;
        let k1: Vec<f64> = (0..=n)
            .map(|k| {
                if th.re[k].abs() > 0.05 {
                    dir = th.re[k].signum();
                }
                u.k1(th.te[k], th.rc[k]) + dir * sf_hyst_ppm * 1e-6 * u.k10
            })
            .collect();
        // Bias terms common to both runs.
        let k0_thermal: Vec<f64> = (0..=n)
            .map(|k| {
                let mut b = u.k0_static(th.te[k]);
                if let Some((h, w)) = u.play {
                    b += w * (th.te[k] - th.p[k]) / h;
                }
                if let Some((g, _, _)) = u.creep {
                    b += g * (th.te[k] - th.x[k]);
                }
                b
            })
            .collect();
        for (ri, (run, g)) in [("pos0", 1.0f64), ("pos2", -1.0f64)].into_iter().enumerate() {
            let mut white = run_stream(d.seed, S_WHITE, pi, ri);
            let mut glitch = run_stream(d.seed, S_GLITCH, pi, ri);
            let mut gmr = run_stream(d.seed, S_GM, pi, ri);
            let mut wanr = run_stream(d.seed, S_WANDER, pi, ri);
            let mut sensor = run_stream(d.seed, S_SENSOR, pi, ri);
            let bad = d.other.contains(&OutOfCatalog::BadRun { program_index: pi, run_index: ri });
            let step_at: Vec<(f64, f64)> = d
                .other
                .iter()
                .filter_map(|o| match *o {
                    OutOfCatalog::BiasStep { program_index, run_index, at_fraction, size_g }
                        if program_index == pi && run_index == ri =>
                    {
                        Some((at_fraction * prog.duration_s, size_g))
                    }
                    _ => None,
                })
                .collect();
            // Deterministic bias of this run at grid point k.
            let k0_at = |k: usize| -> f64 {
                let t = k as f64 * DT_S;
                let mut b = k0_thermal[k] + u.drift_g_per_h * t / 3600.0 + campaign_g_per_h * (campaign_s + t) / 3600.0;
                for &(ts, size) in &step_at {
                    if t >= ts {
                        b += size;
                    }
                }
                b
            };
            let mut gm = gm_sd * gmr.normal();
            let mut wander = if bad { 10e-6 * wanr.normal() } else { 0.0 };
            let rate_of = |k: usize, gm: f64, wander: f64| k1[k] * (g + k0_at(k) + gm + wander);
            let mut prev_rate = rate_of(0, gm, wander);
            let (mut acc, mut row_i) = (0.0f64, 0usize);
            let mut spike = 0.0f64;
            for k in 0..rows * sub {
                if k % 4 == 0 {
                    // A new second: a glitch for the next four steps, or none.
                    spike = 0.0;
                    if d.glitches && glitch.uniform() < GLITCH_PER_S {
                        spike = glitch.sign() * GLITCH_PULSES_PER_S;
                        trace.glitch_seconds += 1;
                    }
                    trace.counted_seconds += 1;
                }
                // Noise over the step.
                let mut sd = white_step;
                if temp_noise {
                    sd *= 1.0 + 2.0 * ((th.te[k] - lo) / (hi - lo)).clamp(0.0, 1.0);
                }
                if bad {
                    sd *= 5.0;
                }
                let z = if sd > 0.0 {
                    if d.heavy_tails {
                        white.student3()
                    } else {
                        white.normal()
                    }
                } else {
                    0.0
                };
                let gm_next =
                    if gm_sd > 0.0 { gm_phi * gm + gm_sd * (1.0 - gm_phi * gm_phi).sqrt() * gmr.normal() } else { 0.0 };
                let wander_next = if bad {
                    wander_phi * wander + 10e-6 * (1.0 - wander_phi * wander_phi).sqrt() * wanr.normal()
                } else {
                    0.0
                };
                let next_rate = rate_of(k + 1, gm_next, wander_next);
                let signal = match d.counting {
                    Counting::ZeroOrderHold => prev_rate * DT_S,
                    Counting::FirstOrderHold => 0.5 * (prev_rate + next_rate) * DT_S,
                };
                acc += signal + k1[k] * sd * z * DT_S + spike * DT_S;
                prev_rate = next_rate;
                gm = gm_next;
                wander = wander_next;
                if (k + 1) % sub == 0 {
                    row_i += 1;
                    let t_end = row_i as f64 * row;
                    let pulses = acc.floor();
                    acc -= pulses;
                    let t_stamp = match d.stamp {
                        Stamp::Start => t_end - row,
                        Stamp::Centre => t_end - 0.5 * row,
                        Stamp::End => t_end,
                    };
                    let seen = interp(&th.tc, (t_stamp - d.conversion_delay_s).max(0.0));
                    let noise = if d.sensor_noise_c > 0.0 { d.sensor_noise_c * sensor.normal() } else { 0.0 };
                    let reading = ((seen + noise) * 16.0).round() / 16.0;
                    out.push_str(&format!(
                        "{prefix}-{rate:.1},{run},{t_end:.2},{g},{reading:.4},{pulses:.0},{row:.2}\n"
                    ));
                    let t_mid = t_end - 0.5 * row;
                    let x = t_mid / DT_S;
                    let kf = (x.floor() as usize).min(n - 1);
                    let frac = x - kf as f64;
                    let k0_mid = k0_at(kf) + frac * (k0_at(kf + 1) - k0_at(kf));
                    trace.rows.push(RowTruth {
                        program: pi,
                        run: ri,
                        time_s: t_end,
                        te_c: interp(&th.te, t_mid),
                        tc_c: interp(&th.tc, t_mid),
                        rate_c_per_min: interp(&th.rc, t_mid),
                        k1: interp(&k1, t_mid),
                        k0_g: k0_mid,
                    });
                }
            }
            campaign_s += prog.duration_s;
        }
        trace.programs.push(prog);
    }
    (out, trace)
}
