//! The simulator's channel stage: the same program ([`Program::staircase`]: hold at 22 °C,
//! ramp down, up and back to 22 °C at a given rate with a dwell at each integer °C, then a
//! final hold), thermal chain, truth model ([`TruthModel`]), DS18B20 ([`SensorTruth`]) and
//! random streams as [`crate::simulate_run`], written straight to discovery's
//! channels or to a cycling / single-channel log, with white noise per row in place of
//! the I/F converter, the DS18B20's conversion timing and the bias instability. Fast: the
//! discovery tests and benchmark run on it; the discovery's FDR runs on the pulse stage.
//!
//! Chamber → case (first-order lag, the DS18B20 is on the case) → 12-bit reading with
//! noise. The truth is evaluated on the true case temperature and its exact derivative at
//! every sub-step and averaged over each row's interval, as a physical unit and an I/F
//! counter would give it: never on the firmware's own estimate, whose window artefacts
//! would then be part of the truth and invisible to the tests.

use std::fmt::Write as _;

use qfa_thermal::model::{Extensions, ScaleFactor};

use crate::profile::Program;
use crate::truth::{BiasTruth, SensorTruth, Truth, TruthModel};
use crate::IfConverter;
use qfa_log::channels::{Channels, LogKind, Trace};
use qfa_log::cycling::{write_log_to, Log, Run, Sample};
use qfa_rng::{normal, seeded, LabRng};

/// Test-program and noise configuration.
#[derive(Clone, Debug)]
pub struct SynthConfig {
    /// Ramp rates of the programs, °C/min (one program each).
    pub rates: Vec<f64>,
    /// Lowest and highest temperature, °C.
    pub t_lo: f64,
    /// Highest temperature, °C.
    pub t_hi: f64,
    /// Initial hold at 22 °C, min.
    pub hold_start_min: f64,
    /// Final hold at 22 °C, min.
    pub hold_end_min: f64,
    /// Dwell at each integer °C, min.
    pub dwell_min: f64,
    /// Row interval, s.
    pub dt_s: f64,
    /// Case time constant behind the chamber air, s.
    pub case_tau_s: f64,
    /// DS18B20 noise, °C.
    pub temp_noise_c: f64,
    /// Scale-factor noise per row, ppm.
    pub sf_noise_ppm: f64,
    /// Bias noise per row, µg (or value units × 1e-6 for single-channel).
    pub bias_noise_ug: f64,
    /// Seed.
    pub seed: u64,
}

impl Default for SynthConfig {
    fn default() -> Self {
        Self {
            rates: vec![0.3, 0.5, 0.7, 0.9],
            t_lo: 0.0,
            t_hi: 45.0,
            hold_start_min: 40.0,
            hold_end_min: 60.0,
            dwell_min: 3.0,
            dt_s: 10.0,
            case_tau_s: 120.0,
            temp_noise_c: 0.02,
            sf_noise_ppm: 5.0,
            bias_noise_ug: 5.0,
            seed: 1,
        }
    }
}

impl SynthConfig {
    /// The paper's full program (−60..70 °C, 120-min hold, four rates) at 10-s rows.
    #[must_use]
    pub fn paper_full(seed: u64) -> Self {
        Self { t_lo: -60.0, t_hi: 70.0, hold_start_min: 120.0, hold_end_min: 60.0, seed, ..Self::default() }
    }
}

/// JB-KT8 #1 scale factor (paper Eq. 15): the simulator's preset, written once in
/// [`crate::truth::Truth::jb_kt8`].
#[must_use]
pub fn kt8_1_scale() -> ScaleFactor {
    crate::truth::Truth::jb_kt8(1).scale
}

/// A truth: `scale`, bias `b0 + b1·ΔT + b2·ΔT²` (g, ΔT from the scale factor's 22 °C)
/// and `ext`, on JB-KT8 #1's thermal chain; its noise is the [`SynthConfig`]'s.
#[must_use]
pub fn truth(scale: ScaleFactor, b: [f32; 3], ext: Extensions) -> Truth {
    let bias = BiasTruth {
        k0_g: f64::from(b[0]),
        b1_g_per_c: f64::from(b[1]),
        b2_g_per_c2: f64::from(b[2]),
        b3_g_per_c3: 0.0,
    };
    Truth { name: "synth".into(), scale, bias, ext, ..Truth::jb_kt8(1).noiseless() }
}

/// The chamber program: the simulator's paper staircase ([`Program::staircase`]) between
/// `t_lo` and `t_hi` (rounded to whole °C: the program steps 1 °C), then a final hold.
fn program(c: &SynthConfig, rate: f64) -> Program {
    let mut p =
        Program::staircase("synth", rate, c.hold_start_min, c.dwell_min, c.t_lo.round() as i32, c.t_hi.round() as i32);
    let end = p.duration_s();
    p.points.push((end + c.hold_end_min * 60.0, 22.0));
    p
}

/// One program's rows: (time s, DS18B20 °C, true K1, true K0). The case follows the
/// chamber through the simulator's thermal chain with the config's case τ (exact for the
/// piecewise-linear program, 10 sub-steps per row so the knots fall close to step edges).
fn program_rows(c: &SynthConfig, rate: f64, truth: &Truth, rng: &mut LabRng) -> Vec<(f64, f32, f64, f64)> {
    let prog = program(c, rate);
    let end = prog.duration_s();
    let sub = 10usize;
    let h = c.dt_s / sub as f64;
    let thermal = crate::thermal::ThermalChain { case_tau_s: c.case_tau_s, ..truth.thermal };
    let mut chain = thermal.start(prog.temp_at(0.0), h, truth.element_tau_s());
    let mut model: TruthModel = truth.model();
    // The simulator's one DS18B20, on the case, without offset, read at every row.
    let sensor = SensorTruth { offset_c: 0.0, noise_c: c.temp_noise_c, period_s: c.dt_s, first_s: 0.0 };
    let mut out = Vec::new();
    let mut t = 0.0;
    // The truth at the end of the previous sub-step (K1, K0).
    let mut prev = (0.0f64, 0.0f64);
    while t <= end {
        // The truth over the row's interval: the model on the true case temperature and its
        // exact derivative at every sub-step, averaged (a row's pulses are counted over the
        // interval that ends at `t`, as the cycling log's format says).
        // Trapezoids over the sub-steps: the interval's mean, centred on its middle.
        let (mut k1, mut k0) = (0.0f64, 0.0f64);
        if t > 0.0 {
            for k in 0..sub {
                let t0 = t - c.dt_s + h * k as f64;
                let temps = chain.step(prog.temp_at(t0 + h));
                let e = model.step(temps.case_c, temps.case_rate_c_per_min, h);
                k1 += 0.5 * (prev.0 + e.k1) / sub as f64;
                k0 += 0.5 * (prev.1 + e.k0) / sub as f64;
                prev = (e.k1, e.k0);
            }
        } else {
            let e = model.step(chain.case.y, 0.0, 0.0);
            (k1, k0) = (e.k1, e.k0);
            prev = (k1, k0);
        }
        let reading = sensor.read(rng, chain.case.y) as f32;
        out.push((t, reading, k1, k0));
        t += c.dt_s;
    }
    out
}

/// Channels of a simulated cycling test (K1, K0 per row with noise, binned to `bin_s`).
#[must_use]
pub fn cycling_channels(c: &SynthConfig, truth: &Truth, bin_s: f64) -> Channels {
    let mut rng = seeded(c.seed);
    let mut traces = Vec::new();
    for &rate in &c.rates {
        let rows = program_rows(c, rate, truth, &mut rng);
        let temps: Vec<(f64, f32)> = rows.iter().map(|r| (r.0, r.1)).collect();
        let sf: Vec<f64> = rows.iter().map(|r| r.2 * (1.0 + c.sf_noise_ppm * 1e-6 * normal(&mut rng))).collect();
        let bias: Vec<f64> = rows.iter().map(|r| r.3 + c.bias_noise_ug * 1e-6 * normal(&mut rng)).collect();
        traces.push(Trace::new(format!("paper-{rate:.1}"), &temps, Some(&sf), &bias, bin_s));
    }
    Channels { kind: LogKind::Cycling, bias_unit: qfa_log::channels::BiasUnit::G, traces, skipped_glitches: Vec::new() }
}

/// A single-channel log (`time_s,temp_c,value`) of the first program: value = K0 in µg.
#[must_use]
pub fn single_csv(c: &SynthConfig, truth: &Truth) -> String {
    let mut rng = seeded(c.seed);
    let mut s = String::from("time_s,temp_c,value\n");
    if let Some(&rate) = c.rates.first() {
        let rows = program_rows(c, rate, truth, &mut rng);
        for r in rows {
            let v = r.3 * 1e6 + c.bias_noise_ug * normal(&mut rng);
            let _ = writeln!(s, "{:.1},{:.4},{:.4}", r.0, r.1, v);
        }
    }
    s
}

/// A cycling log in the lab's CSV format (written by [`qfa_log::cycling::write_log_to`],
/// the one cycling writer): per program four runs (+1, 0, −1, 0 g), pulses from the one
/// [`crate::IfConverter`]; `accel_noise_ug` is white noise per row.
#[must_use]
pub fn cycling_csv(c: &SynthConfig, truth: &Truth, accel_noise_ug: f64) -> String {
    let mut rng = seeded(c.seed);
    let mut log = Log::default();
    for &rate in &c.rates {
        let rows = program_rows(c, rate, truth, &mut rng);
        for (run, g) in [1.0f64, 0.0, -1.0, 0.0].into_iter().enumerate() {
            let mut counter = IfConverter::default();
            let mut samples = Vec::with_capacity(rows.len());
            for w in rows.windows(2) {
                let (p0, r) = (w[0].0, &w[1]);
                let iv = r.0 - p0;
                let a = r.2 * (r.3 + g + accel_noise_ug * 1e-6 * normal(&mut rng));
                let pulses = counter.count(a * iv);
                // The time is written to 0.1 s, as a chamber logger would stamp it.
                let time_s = (r.0 * 10.0).round() / 10.0;
                samples.push(Sample { time_s, temp_c: Some(f64::from(r.1)), pulses, interval_s: iv });
            }
            log.runs.push(Run { program: format!("paper-{rate:.1}"), run: run.to_string(), input_g: g, samples });
        }
    }
    let mut bytes = Vec::with_capacity(1 << 20);
    // Into memory, in UTF-8 (the program and run names above are ASCII): neither can fail.
    let _ = write_log_to(&mut bytes, &log);
    String::from_utf8(bytes).expect("the cycling writer writes UTF-8")
}
