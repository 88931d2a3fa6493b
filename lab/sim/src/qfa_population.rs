//! Production batches of the paper's own units: many quartz-flexure accelerometers (pulse
//! counts, each with its own DS18B20) through the paper's four-position cycling test, drawn
//! around JB-KT8 #1 with a stated spread, a few of them deliberately bad, with every unit's
//! truth.
//!
//! Each unit is a [`Truth`] (the one simulator's unit: Eq. 11 scale factor, cubic bias,
//! DS18B20, noise) whose coefficients are JB-KT8 #1's, each moved by its own spread
//! ([`QFA_SPREAD`]); its log is [`crate::simulate_paper`]'s, one unit per log, in the
//! cycling CSV `qfa-lab calibrate` reads. The paper calibrates its three units on one index
//! head in one chamber; here every unit runs the same program, and the manifest names
//! one log per serial.
//!
//! The bad units ([`QfaDefect`]) are the three the batch must catch on a QFA line: three
//! times the fleet's thermal hysteresis of the scale factor (Eq. 11's heating/cooling terms
//! ε and η at three times JB-KT8 #1's), a unit whose bias ages (0.3 µg/h of powered time,
//! 110 µg over the test's 376 h), and five times the fleet's temperature coefficient μ.
//! "The fleet's" is the nominal unit's: three times a unit's own drawn ε would leave a unit
//! drawn low at twice the fleet's, which a production engineer would not call 3×.

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::population::{serial, PopulationError, Truncation};
use crate::profile::{Program, PAPER_RATES};
use crate::truth::Truth;
use qfa_rng::{normal, seeded, stream_seed, Stream};

/// Where the defects fall.
const PLACES: Stream = Stream::named("qfa population: places");
/// Each unit's coefficients, sensor and ageing (index: the unit's place).
const UNITS: Stream = Stream::named("qfa population: units");
/// Each unit's noise seed (index: the unit's place).
const NOISE: Stream = Stream::named("qfa population: noise");

/// Row (counting interval) of the simulated logs, s.
pub const QFA_ROW_S: u32 = 10;

/// The population's spread (one standard deviation) about JB-KT8 #1, each figure's own.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QfaSpread {
    /// γ, relative.
    pub gamma: f64,
    /// μ, β, ε, η and α, each relative to its own nominal.
    pub coefficients: f64,
    /// K0 at T0, g.
    pub k0_g: f64,
    /// The bias's slope, g/°C.
    pub b1_g_per_c: f64,
    /// The bias's curvature, g/°C².
    pub b2_g_per_c2: f64,
    /// The DS18B20's offset, °C (inside its ±0.5 °C specification).
    pub sensor_offset_c: f64,
    /// Bias ageing of a good unit, µg/h.
    pub ageing_ug_per_h: f64,
}

/// The spread the batch is drawn with: γ 0.3 %, the other Eq. 11 coefficients 15 % of
/// their own value, K0 50 µg, its slope 3 µg/°C and curvature 0.01 µg/°C², the sensor's
/// offset 0.2 °C, a good unit's ageing 0.01 µg/h. Ours: the paper gives three units, whose
/// μ, ε and α differ by far more than this (μ −32.8 to −49.8, ε 21 to 88), so a fleet of
/// one part number is taken as tighter than three hand-picked units.
pub const QFA_SPREAD: QfaSpread = QfaSpread {
    gamma: 3e-3,
    coefficients: 0.15,
    k0_g: 50e-6,
    b1_g_per_c: 3e-6,
    b2_g_per_c2: 0.01e-6,
    sensor_offset_c: 0.2,
    ageing_ug_per_h: 0.01,
};

/// The bad unit's ageing, µg/h.
pub const AGEING_UG_PER_H: f64 = 0.3;

/// A deliberately bad QFA unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum QfaDefect {
    /// ε and η, the scale factor's heating/cooling terms, three times the nominal unit's.
    Hysteresis3x,
    /// The bias ages [`AGEING_UG_PER_H`].
    Ageing,
    /// μ, the scale factor's temperature coefficient, five times the nominal unit's.
    TempCoefficient5x,
}

impl QfaDefect {
    /// Every defect, in the order units are given them.
    pub const ALL: [Self; 3] = [Self::Hysteresis3x, Self::Ageing, Self::TempCoefficient5x];
}

/// One unit's truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QfaUnitTruth {
    /// Serial number.
    pub serial: String,
    /// Its defect, if it was made bad.
    pub defect: Option<QfaDefect>,
    /// The seed of its log's noise.
    pub noise_seed: u64,
    /// Its log's truncation, if any (every run cut alike).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub truncation: Option<Truncation>,
    /// The unit.
    pub truth: Truth,
}

/// The batch's truth, as written beside its logs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct QfaPopulationTruth {
    /// Seed it was drawn from.
    pub seed: u64,
    /// Every unit, in serial order.
    pub unit: Vec<QfaUnitTruth>,
}

/// What to draw.
#[derive(Clone, Copy, Debug)]
pub struct QfaPopulationSpec {
    /// Units.
    pub units: usize,
    /// Seed.
    pub seed: u64,
    /// Bad units: one of each [`QfaDefect`] per started 50 units, at places drawn from the
    /// seed; `false` for none.
    pub bad: bool,
    /// Good units whose log is truncated, alternating [`Truncation`]s (every run of the
    /// unit's log cut alike).
    pub truncated: usize,
}

/// Draw a population of QFA units.
#[must_use]
pub fn draw_qfa(spec: &QfaPopulationSpec) -> QfaPopulationTruth {
    // Streams of their own: a QFA batch and a static batch of one seed share no draw.
    let mut rng = seeded(stream_seed(spec.seed, PLACES, 0));
    let n = spec.units;
    let (defect, order, k) = crate::population::place_defects(&mut rng, n, &QfaDefect::ALL, spec.bad);
    let mut truncation = vec![None; n];
    for (j, &i) in order[k..].iter().take(spec.truncated).enumerate() {
        truncation[i] = Some(if j % 2 == 0 { Truncation::HeatingOnly } else { Truncation::FirstHalf });
    }
    let s = QFA_SPREAD;
    let nominal = Truth::jb_kt8(1).scale;
    let unit = (0..n)
        .map(|i| {
            let mut r = seeded(stream_seed(spec.seed, UNITS, i as u64));
            let mut t = Truth::jb_kt8(1);
            t.name = serial(i);
            let rel = |r: &mut qfa_rng::LabRng, x: f32, sd: f64| (f64::from(x) * (1.0 + sd * normal(r))) as f32;
            t.scale.gamma = rel(&mut r, t.scale.gamma, s.gamma);
            t.scale.mu = rel(&mut r, t.scale.mu, s.coefficients);
            t.scale.beta = rel(&mut r, t.scale.beta, s.coefficients);
            t.scale.epsilon = rel(&mut r, t.scale.epsilon, s.coefficients);
            t.scale.eta = rel(&mut r, t.scale.eta, s.coefficients);
            t.scale.alpha = rel(&mut r, t.scale.alpha, s.coefficients);
            t.bias.k0_g += s.k0_g * normal(&mut r);
            t.bias.b1_g_per_c += s.b1_g_per_c * normal(&mut r);
            t.bias.b2_g_per_c2 += s.b2_g_per_c2 * normal(&mut r);
            t.sensor.offset_c = s.sensor_offset_c * normal(&mut r);
            t.ageing_ug_per_h = s.ageing_ug_per_h * normal(&mut r);
            match defect[i] {
                Some(QfaDefect::Hysteresis3x) => {
                    t.scale.epsilon = 3.0 * nominal.epsilon;
                    t.scale.eta = 3.0 * nominal.eta;
                }
                Some(QfaDefect::Ageing) => t.ageing_ug_per_h = AGEING_UG_PER_H,
                Some(QfaDefect::TempCoefficient5x) => t.scale.mu = 5.0 * nominal.mu,
                None => {}
            }
            QfaUnitTruth {
                serial: serial(i),
                defect: defect[i],
                noise_seed: stream_seed(spec.seed, NOISE, i as u64),
                truncation: truncation[i],
                truth: t,
            }
        })
        .collect();
    QfaPopulationTruth { seed: spec.seed, unit }
}

/// Write one cycling log per unit (`units/SN0001.csv`, …: the paper's four rates × four
/// positions at [`QFA_ROW_S`]-s rows), the manifest naming them (`batch.toml`), and the
/// truth (`truth.toml`), into `dir`; each unit's runs on `threads` threads.
///
/// # Errors
/// [`PopulationError`]: a file not written, or the truth not serialized.
pub fn write_qfa_manifest(dir: &Path, truth: &QfaPopulationTruth, threads: usize) -> Result<(), PopulationError> {
    let mut manifest = String::from(
        "# One cycling log per QFA unit (the paper's four-position program); each [[unit]] names its serial and \
         log (relative to this file).\n",
    );
    let io = |path: &Path, e: std::io::Error| PopulationError::Io(qfa_log::IoFault::new(path, &e));
    let units = dir.join("units");
    std::fs::create_dir_all(&units).map_err(|e| io(&units, e))?;
    for u in &truth.unit {
        let mut log = crate::simulate_paper(&u.truth, QFA_ROW_S, u.noise_seed, threads, None);
        truncate(&mut log, u.truncation);
        let path = units.join(format!("{}.csv", u.serial));
        qfa_log::cycling::write_log(&path, &log).map_err(|e| io(&path, e))?;
        let _ = write!(manifest, "\n[[unit]]\nserial = \"{}\"\nlog = \"units/{}.csv\"\n", u.serial, u.serial);
    }
    let path = dir.join("batch.toml");
    std::fs::write(&path, manifest).map_err(|e| io(&path, e))?;
    let text = toml::to_string(truth).map_err(PopulationError::Toml)?;
    let path = dir.join("truth.toml");
    std::fs::write(&path, text).map_err(|e| io(&path, e))
}

/// Cut every run of `log` as `truncation` says, on its program's air temperature (the
/// static population's rule, [`crate::population::kept_rows`]).
fn truncate(log: &mut qfa_log::cycling::Log, truncation: Option<Truncation>) {
    if truncation.is_none() {
        return;
    }
    for run in &mut log.runs {
        let Some(program) = PAPER_RATES.iter().map(|&r| Program::paper(r)).find(|p| p.id == run.program) else {
            continue;
        };
        let air: Vec<f64> = run.samples.iter().map(|s| program.temp_at(s.time_s)).collect();
        let keep = crate::population::kept_rows(truncation, &air);
        run.samples = run.samples[keep].to_vec();
    }
}

/// Write one multi-unit cycling log (`chamber.csv`: the cycling log's shared columns, then
/// `SERIAL.temp_c` and `SERIAL.pulses` per unit, every unit through the same program and
/// positions, as on one index head) and the truth (`truth.toml`) into `dir`.
///
/// # Errors
/// [`PopulationError`]: a file not written, or the truth not serialized.
pub fn write_qfa_chamber(dir: &Path, truth: &QfaPopulationTruth, threads: usize) -> Result<(), PopulationError> {
    let io = |path: &Path, e: std::io::Error| PopulationError::Io(qfa_log::IoFault::new(path, &e));
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let logs: Vec<qfa_log::cycling::Log> =
        truth.unit.iter().map(|u| crate::simulate_paper(&u.truth, QFA_ROW_S, u.noise_seed, threads, None)).collect();
    let mut s = String::from("program,run,time_s,input_g,interval_s");
    for u in &truth.unit {
        let _ = write!(s, ",{0}.temp_c,{0}.pulses", u.serial);
    }
    s.push('\n');
    if let Some(first) = logs.first() {
        for (k, run) in first.runs.iter().enumerate() {
            for (i, row) in run.samples.iter().enumerate() {
                let _ = write!(s, "{},{},{},{},{}", run.program, run.run, row.time_s, run.input_g, row.interval_s);
                for log in &logs {
                    let r = &log.runs[k].samples[i];
                    match r.temp_c {
                        Some(t) => write!(s, ",{t},{}", r.pulses),
                        None => write!(s, ",,{}", r.pulses),
                    }
                    .unwrap_or(());
                }
                s.push('\n');
            }
        }
    }
    let path = dir.join("chamber.csv");
    std::fs::write(&path, s).map_err(|e| io(&path, e))?;
    let text = toml::to_string(truth).map_err(PopulationError::Toml)?;
    let path = dir.join("truth.toml");
    std::fs::write(&path, text).map_err(|e| io(&path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each defect goes to `ceil(n/50)` units, never two to one unit, and moves exactly the
    /// coefficient its name says; the draw is the same for the same seed.
    #[test]
    fn defects_are_placed_and_made_as_documented() {
        let spec = QfaPopulationSpec { units: 60, seed: 3, bad: true, truncated: 0 };
        let p = draw_qfa(&spec);
        for d in QfaDefect::ALL {
            assert_eq!(p.unit.iter().filter(|u| u.defect == Some(d)).count(), 2, "{d:?}");
        }
        assert_eq!(p, draw_qfa(&spec));
        let good = draw_qfa(&QfaPopulationSpec { bad: false, ..spec });
        let n = Truth::jb_kt8(1).scale;
        for (u, g) in p.unit.iter().zip(&good.unit) {
            let (a, b) = (&u.truth.scale, &g.truth.scale);
            match u.defect {
                Some(QfaDefect::Hysteresis3x) => {
                    assert_eq!((a.epsilon, a.eta), (3.0 * n.epsilon, 3.0 * n.eta));
                    assert_eq!(a.mu, b.mu);
                }
                Some(QfaDefect::TempCoefficient5x) => assert_eq!((a.mu, a.epsilon), (5.0 * n.mu, b.epsilon)),
                Some(QfaDefect::Ageing) => assert_eq!(u.truth.ageing_ug_per_h, AGEING_UG_PER_H),
                None => assert_eq!(u.truth, g.truth),
            }
        }
    }

    /// The ageing term moves the bias by its rate times the powered time since the log's
    /// first run started: a noiseless unit at 0 g with a constant temperature reads
    /// `ageing × t` in its last run's pulses, the runs back to back.
    #[test]
    fn ageing_reads_on_the_logs_clock() {
        use crate::profile::{Position, Program};
        let mut t = Truth::jb_kt8(1).noiseless();
        t.ageing_ug_per_h = 10.0;
        let p = Program { id: "flat".into(), points: vec![(0.0, 22.0), (3600.0, 22.0)] };
        let positions = [Position { run: 0, input_g: 0.0 }, Position { run: 1, input_g: 0.0 }];
        let log = crate::simulate(&t, std::slice::from_ref(&p), &positions, 10, 1, 1, None);
        let len = crate::run_length_s(&p, 10);
        let without = crate::simulate(&Truth { ageing_ug_per_h: 0.0, ..t.clone() }, &[p], &positions, 10, 1, 1, None);
        for (k, (run, base)) in log.runs.iter().zip(&without.runs).enumerate() {
            let last = run.samples.len() - 1;
            let (s, b) = (&run.samples[last], &base.samples[last]);
            let mid_h = (k as f64 * len + s.time_s - 5.0) / 3600.0;
            let got_ug = (s.pulses - b.pulses) as f64 / (f64::from(t.scale.gamma) * 10.0) * 1e6;
            let want_ug = 10.0 * mid_h;
            // One pulse in 10 s is 0.31 µg.
            assert!((got_ug - want_ug).abs() < 0.7, "run {k}: {got_ug} µg against {want_ug}");
        }
    }
}
