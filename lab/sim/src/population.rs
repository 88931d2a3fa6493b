//! Production batches: many static three-axis units (samples in g, each with its own
//! temperature sensor) through one chamber program on one fixture, drawn around a nominal
//! unit with a stated spread, a few of them deliberately bad, with every unit's truth.
//!
//! What a unit is here: a board at one orientation (level: `az` ≈ −1 g) whose bias on each
//! axis is a cubic in the temperature of its case, plus half a constant step up on heating
//! and down on cooling (the branch the firmware's model holds), plus white noise. The case
//! follows the chamber air through a first-order lag of the unit's own time constant; the
//! unit's sensor reads the case with its own offset, quantised to 1/16 °C.
//!
//! The nominal unit and its spread (`NOMINAL`, [`SPREAD`]) are MEMS-grade figures of the
//! size the lab's real chamber log shows (a few tenths of a mg per °C, a split of tenths of
//! a mg), not the paper's quartz units: the paper's three are pulse-count units calibrated
//! by a four-position cycling program of many hours each, which a production line of
//! sample-output boards does not run.
//!
//! The bad units ([`Defect`]) are the three a production engineer must catch: a damaged
//! unit (a shock shifts its bias part-way through the run), a drifting temperature sensor,
//! and a unit whose heating/cooling split is three times the others'.

use std::fmt::Write as _;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::thermal::Lag;
use qfa_log::replay::Motion;
use qfa_rng::{normal, seeded, stream_seed, uniform, Stream};

/// Where the defects and truncations fall.
const PLACES: Stream = Stream::named("population: places");
/// Each unit's curve, lags and sensor (index: the unit's place).
const UNITS: Stream = Stream::named("population: units");
/// Each unit's rows: noise and sensor quantisation (index: the unit's place).
const ROWS: Stream = Stream::named("population: rows");

/// The chamber program: (target °C, rate °C/min, hold at the target s) legs from 25 °C.
/// 25 → −20 → 70 → 40 °C at 2 °C/min with 15-min holds: 8 550 one-second rows, the size
/// and shape of the lab's real chamber log (8 400 rows, 51.6 → −17.6 → 74.0 → 36.3 °C), so
/// `--holdout auto` holds out the last cooling leg as it does there.
pub(crate) const PROGRAM: [(f64, f64, f64); 3] = [(-20.0, 2.0, 900.0), (70.0, 2.0, 900.0), (40.0, 2.0, 900.0)];
/// Hold at 25 °C before the first leg, s.
pub(crate) const FIRST_HOLD_S: f64 = 900.0;
/// Temperature the curves are written about, °C.
pub(crate) const T_REF_C: f64 = 25.0;
/// Branch deadband of the truth, °C/min: the case rate must pass it to change branch.
pub(crate) const TRUTH_DEADBAND_C_PER_MIN: f64 = 0.05;

/// One axis's bias curve, g: `level + c1·d + c2·d² + c3·d³ ± split/2` with `d = T − 25 °C`,
/// `+` on the heating branch.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AxisCurve {
    /// Output at 25 °C between the branches, g (gravity's share on this axis included).
    pub level_g: f64,
    /// g/°C.
    pub c1: f64,
    /// g/°C².
    pub c2: f64,
    /// g/°C³.
    pub c3: f64,
    /// Heating minus cooling, g.
    pub split_g: f64,
}

impl AxisCurve {
    /// The output at `t_c` on the branch `heating` (true) or cooling, g.
    #[must_use]
    pub fn at(&self, t_c: f64, heating: bool) -> f64 {
        let d = t_c - T_REF_C;
        let half = if heating { 0.5 } else { -0.5 };
        self.level_g + d * (self.c1 + d * (self.c2 + d * self.c3)) + half * self.split_g
    }
}

/// The nominal unit's axes (`ax`, `ay`, `az`).
pub(crate) const NOMINAL: [AxisCurve; 3] = [
    AxisCurve { level_g: 0.0, c1: 1.0e-4, c2: 2.0e-7, c3: 0.0, split_g: 2.0e-4 },
    AxisCurve { level_g: 0.0, c1: -5.0e-5, c2: -1.0e-7, c3: 0.0, split_g: 6.0e-5 },
    AxisCurve { level_g: -1.0, c1: 3.0e-5, c2: 0.0, c3: 2.0e-9, split_g: 1.0e-4 },
];

/// The population's spread (one standard deviation) about `NOMINAL`: the level by an
/// absolute 2 mg (mounting and bias), every other coefficient by its own scale below, so a
/// coefficient whose nominal is 0 still varies.
pub const SPREAD: AxisCurve = AxisCurve { level_g: 2.0e-3, c1: 2.0e-5, c2: 5.0e-8, c3: 5.0e-10, split_g: 2.0e-5 };

/// A deliberately bad unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Defect {
    /// A shock at 60 % of the run shifts the bias by 6 mg (a different sign per axis).
    Damaged,
    /// The temperature sensor drifts +5 °C over the run.
    DriftingSensor,
    /// The heating/cooling split is three times the unit's drawn one on every axis.
    Hysteresis3x,
}

impl Defect {
    /// Every defect, in the order units are given them.
    pub(crate) const ALL: [Self; 3] = [Self::Damaged, Self::DriftingSensor, Self::Hysteresis3x];
}

/// Rows a unit's own log keeps (manifest runs only: one chamber log shares its rows).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Truncation {
    /// The heating leg alone: from the end of the cold hold to the top.
    HeatingOnly,
    /// The first half of the run's rows.
    FirstHalf,
}

/// One unit's truth.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnitTruth {
    /// Serial number.
    pub serial: String,
    /// Its defect, if it was made bad.
    pub defect: Option<Defect>,
    /// Its log's truncation, if any.
    pub truncation: Option<Truncation>,
    /// Air → case time constant, s.
    pub case_tau_s: f64,
    /// Sensor offset, °C.
    pub sensor_offset_c: f64,
    /// Sensor drift over the whole run, °C.
    pub sensor_drift_c: f64,
    /// White noise per sample, g.
    pub noise_g: f64,
    /// Bias shift after the shock, g per axis (zero without one).
    pub shock_g: [f64; 3],
    /// Axes `ax`, `ay`, `az`.
    pub axes: [AxisCurve; 3],
    /// The die's lag behind the case the sensor reads, s: the output follows the die, so
    /// a unit whose die lags shows an apparent heating/cooling split of its slope × rate ×
    /// lag on top of its own (0: none, the die at the case's temperature).
    #[serde(default)]
    pub die_lag_s: f64,
}

/// The batch's truth, as written beside its logs.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PopulationTruth {
    /// Seed it was drawn from.
    pub seed: u64,
    /// Every unit, in serial order.
    pub unit: Vec<UnitTruth>,
}

/// What to draw.
#[derive(Clone, Debug)]
pub struct PopulationSpec {
    /// Units.
    pub units: usize,
    /// Seed.
    pub seed: u64,
    /// Bad units: one of each [`Defect`] per started 50 units (100 units: 6), at places drawn
    /// from the seed; `false` for none.
    pub bad: bool,
    /// Good units whose own log is truncated (manifest runs), alternating [`Truncation`]s.
    pub truncated: usize,
    /// Each unit's die lags its case by its own time constant, uniform in 0..[`MAX_DIE_LAG_S`]
    /// (`false`: none, the populations drawn before this option existed).
    pub die_lags: bool,
}

/// The longest die lag a population with [`PopulationSpec::die_lags`] draws, s.
pub const MAX_DIE_LAG_S: f64 = 240.0;

/// Serial of unit `i`.
#[must_use]
pub(crate) fn serial(i: usize) -> String {
    format!("SN{:04}", i + 1)
}

/// Where a population's bad units go: a shuffle of its `n` places drawn from `rng`, whose
/// first places take the defects, one of each of `kinds` (in that order) per started 50
/// units when `bad`. Returns each place's defect, the shuffle, and how many of its first
/// places the defects took (the places after them may take other roles).
pub(crate) fn place_defects<D: Copy>(
    rng: &mut qfa_rng::LabRng,
    n: usize,
    kinds: &[D],
    bad: bool,
) -> (Vec<Option<D>>, Vec<usize>, usize) {
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        let j = (uniform(rng) * (i + 1) as f64) as usize;
        order.swap(i, j.min(i));
    }
    let per_kind = if bad { n.div_ceil(50) } else { 0 };
    let mut defect = vec![None; n];
    let mut k = 0;
    for &d in kinds {
        for _ in 0..per_kind {
            if k < n {
                defect[order[k]] = Some(d);
                k += 1;
            }
        }
    }
    (defect, order, k)
}

/// Draw a population.
#[must_use]
pub fn draw(spec: &PopulationSpec) -> PopulationTruth {
    let mut rng = seeded(stream_seed(spec.seed, PLACES, 0));
    let n = spec.units;
    let (defect, order, k) = place_defects(&mut rng, n, &Defect::ALL, spec.bad);
    let mut truncation = vec![None; n];
    for (j, &i) in order[k..].iter().take(spec.truncated).enumerate() {
        truncation[i] = Some(if j % 2 == 0 { Truncation::HeatingOnly } else { Truncation::FirstHalf });
    }
    let unit = (0..n)
        .map(|i| {
            let mut r = seeded(stream_seed(spec.seed, UNITS, i as u64));
            let mut axes = NOMINAL;
            for a in &mut axes {
                a.level_g += SPREAD.level_g * normal(&mut r);
                a.c1 += SPREAD.c1 * normal(&mut r);
                a.c2 += SPREAD.c2 * normal(&mut r);
                a.c3 += SPREAD.c3 * normal(&mut r);
                a.split_g = (a.split_g + SPREAD.split_g * normal(&mut r)).max(0.0);
            }
            let d = defect[i];
            if d == Some(Defect::Hysteresis3x) {
                for a in &mut axes {
                    a.split_g *= 3.0;
                }
            }
            UnitTruth {
                serial: serial(i),
                defect: d,
                truncation: truncation[i],
                case_tau_s: 60.0 + 120.0 * uniform(&mut r),
                sensor_offset_c: 0.5 * normal(&mut r),
                sensor_drift_c: if d == Some(Defect::DriftingSensor) { 5.0 } else { 0.0 },
                noise_g: 2.0e-4 * (0.8 + 0.45 * uniform(&mut r)),
                shock_g: if d == Some(Defect::Damaged) { [6.0e-3, -6.0e-3, 6.0e-3] } else { [0.0; 3] },
                axes,
                // Drawn last, and only when asked for: the draws before it stay as they were.
                die_lag_s: if spec.die_lags { MAX_DIE_LAG_S * uniform(&mut r) } else { 0.0 },
            }
        })
        .collect();
    PopulationTruth { seed: spec.seed, unit }
}

/// The chamber air temperature at every row (1-s rows from 0 s).
#[must_use]
pub fn chamber_air() -> Vec<f64> {
    let mut out = vec![T_REF_C; FIRST_HOLD_S as usize];
    let mut t = T_REF_C;
    for (target, rate, hold) in PROGRAM {
        let step = rate / 60.0 * (target - t).signum();
        let rows = ((target - t).abs() / (rate / 60.0)).round() as usize;
        for _ in 0..rows {
            t += step;
            out.push(t);
        }
        t = target;
        out.extend(std::iter::repeat_n(t, hold as usize));
    }
    out
}

/// One unit's rows: (sensor reading °C, [ax, ay, az] g), one per row of `air` (the air
/// about the unit, 1-s rows: the chamber's, [`chamber_air`], or any other, such as a
/// vehicle's warm-up and flight), drawn from the stream of unit `index` under `seed`.
#[must_use]
pub fn unit_rows(u: &UnitTruth, air: &[f64], seed: u64, index: usize) -> Vec<(f64, [f64; 3])> {
    let mut r = seeded(stream_seed(seed, ROWS, index as u64));
    let mut lag = Lag::new(u.case_tau_s, 1.0, air[0]);
    let mut die_lag = (u.die_lag_s > 0.0).then(|| Lag::new(u.die_lag_s, 1.0, air[0]));
    let n = air.len();
    let shock_row = n * 6 / 10;
    // The unit was brought down to 25 °C: it starts on the cooling branch.
    let mut heating = false;
    let (mut prev, mut prev_case) = (air[0], air[0]);
    let mut out = Vec::with_capacity(n);
    for (i, &a) in air.iter().enumerate() {
        let case = if i == 0 { a } else { lag.step(air[i - 1], a) };
        // The output's temperature: the die's, which follows the case through its own lag.
        let die = match die_lag.as_mut() {
            Some(d) if i > 0 => d.step(prev_case, case),
            _ => case,
        };
        prev_case = case;
        let rate = (die - prev) * 60.0;
        prev = die;
        // The lab's one branch classifier, with the truth's own deadband.
        match Motion::against(rate, TRUTH_DEADBAND_C_PER_MIN) {
            Motion::Heating => heating = true,
            Motion::Cooling => heating = false,
            Motion::Holding => {}
        }
        let drift = u.sensor_drift_c * i as f64 / n as f64;
        let reading = ((case + u.sensor_offset_c + drift + 0.02 * normal(&mut r)) * 16.0).round() / 16.0;
        let mut acc = [0.0; 3];
        for (k, c) in u.axes.iter().enumerate() {
            let shock = if i >= shock_row { u.shock_g[k] } else { 0.0 };
            acc[k] = c.at(die, heating) + shock + u.noise_g * normal(&mut r);
        }
        out.push((reading, acc));
    }
    out
}

/// The rows a truncated log keeps.
#[must_use]
pub fn kept_rows(t: Option<Truncation>, air: &[f64]) -> std::ops::Range<usize> {
    match t {
        None => 0..air.len(),
        Some(Truncation::HeatingOnly) => {
            // From the end of the cold hold (the last row at the minimum) to the first row
            // at the top: a cold-soaked unit warming up, as PX4 and ArduPilot record it. (The
            // ramps sum their steps, so the extremes are compared within 1e-6 °C.)
            let (lo, hi) = air.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)));
            let top = air.iter().position(|&a| a >= hi - 1e-6).unwrap_or(air.len() - 1);
            let start = air[..top].iter().rposition(|&a| a <= lo + 1e-6).unwrap_or(0);
            start..top + 1
        }
        Some(Truncation::FirstHalf) => 0..air.len() / 2,
    }
}

/// Column header names of one unit in a chamber log: `SN0001.temp`, `SN0001.ax`, ….
#[must_use]
pub(crate) fn unit_columns(serial: &str) -> [String; 4] {
    [format!("{serial}.temp"), format!("{serial}.ax"), format!("{serial}.ay"), format!("{serial}.az")]
}

/// Write one chamber log holding every unit (`chamber.tsv`: `time` then each unit's four
/// columns; every unit's full run), and the truth (`truth.toml`), into `dir`.
///
/// # Errors
/// [`PopulationError`]: a file not written, or the truth not serialized.
pub fn write_chamber(dir: &Path, truth: &PopulationTruth) -> Result<(), PopulationError> {
    let air = chamber_air();
    let rows: Vec<Vec<(f64, [f64; 3])>> =
        truth.unit.iter().enumerate().map(|(i, u)| unit_rows(u, &air, truth.seed, i)).collect();
    let mut s = String::from("time");
    for u in &truth.unit {
        for c in unit_columns(&u.serial) {
            s.push('\t');
            s.push_str(&c);
        }
    }
    s.push('\n');
    for i in 0..air.len() {
        let _ = write!(s, "{i}");
        for r in &rows {
            let (t, a) = r[i];
            let _ = write!(s, "\t{t:.4}\t{:.7}\t{:.7}\t{:.7}", a[0], a[1], a[2]);
        }
        s.push('\n');
    }
    write(dir, "chamber.tsv", &s)?;
    write_truth(dir, truth)
}

/// Write one log per unit (`units/SN0001.tsv`, …, truncated as the truth says), the
/// manifest naming them (`batch.toml`), and the truth (`truth.toml`), into `dir`.
///
/// # Errors
/// [`PopulationError`]: a file not written, or the truth not serialized.
pub fn write_manifest_run(dir: &Path, truth: &PopulationTruth) -> Result<(), PopulationError> {
    let air = chamber_air();
    let mut manifest = String::from(
        "# One log per unit; each [[unit]] names its serial and log (relative to this file).\n\
         time_unit = \"s\"\naccel_unit = \"g\"\ntemp_unit = \"C\"\ncolumns = \"time=time,temp=temp,ax=ax,ay=ay,az=az\"\n",
    );
    for (i, u) in truth.unit.iter().enumerate() {
        let rows = unit_rows(u, &air, truth.seed, i);
        let mut s = String::from("time\ttemp\tax\tay\taz\n");
        for k in kept_rows(u.truncation, &air) {
            let (t, a) = rows[k];
            let _ = writeln!(s, "{k}\t{t:.4}\t{:.7}\t{:.7}\t{:.7}", a[0], a[1], a[2]);
        }
        write(dir, &format!("units/{}.tsv", u.serial), &s)?;
        let _ = write!(manifest, "\n[[unit]]\nserial = \"{}\"\nlog = \"units/{}.tsv\"\n", u.serial, u.serial);
    }
    write(dir, "batch.toml", &manifest)?;
    write_truth(dir, truth)
}

fn write_truth(dir: &Path, truth: &PopulationTruth) -> Result<(), PopulationError> {
    let text = toml::to_string(truth).map_err(PopulationError::Toml)?;
    write(dir, "truth.toml", &text)
}

fn write(dir: &Path, name: &str, text: &str) -> Result<(), PopulationError> {
    let p = dir.join(name);
    let io = |path: &Path, e: std::io::Error| PopulationError::Io(qfa_log::IoFault::new(path, &e));
    if let Some(parent) = p.parent() {
        std::fs::create_dir_all(parent).map_err(|e| io(parent, e))?;
    }
    std::fs::write(&p, text).map_err(|e| io(&p, e))
}

/// Why a simulated population could not be written.
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum PopulationError {
    /// A file or folder that could not be written.
    Io(qfa_log::IoFault),
    /// The truth did not serialize.
    Toml(toml::ser::Error),
}

impl std::fmt::Display for PopulationError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::Toml(e) => write!(f, "{e}"),
        }
    }
}

impl std::error::Error for PopulationError {}

#[cfg(test)]
mod tests {
    use super::*;

    /// The program is what its docs say: 8 250 rows, 25 → 70 → −20 → 40 °C.
    #[test]
    fn chamber_program_matches_its_docs() {
        let air = chamber_air();
        assert_eq!(air.len(), 8_550);
        let max = air.iter().copied().fold(f64::NEG_INFINITY, f64::max);
        let min = air.iter().copied().fold(f64::INFINITY, f64::min);
        assert!((max - 70.0).abs() < 1e-9 && (min + 20.0).abs() < 1e-9, "{min} {max}");
        assert!(air.iter().position(|&a| a <= -20.0) < air.iter().position(|&a| a >= 70.0), "cold first");
        let h = kept_rows(Some(Truncation::HeatingOnly), &air);
        assert!((air[h.start] + 20.0).abs() < 1e-9 && (air[h.end - 1] - 70.0).abs() < 1e-9, "{h:?}");
        assert!(air[h.clone()].windows(2).all(|w| w[1] >= w[0]), "heating only");
        assert!(h.start > 2249 + 800, "the cold hold is before it: {h:?}");
        assert!((air[air.len() - 1] - 40.0).abs() < 1e-9);
    }

    /// Each defect goes to `ceil(n/50)` units, never two to one unit, and the draw is the
    /// same for the same seed.
    #[test]
    fn defects_are_placed_as_documented() {
        let spec = PopulationSpec { units: 100, seed: 5, bad: true, truncated: 4, die_lags: false };
        let p = draw(&spec);
        for d in Defect::ALL {
            assert_eq!(p.unit.iter().filter(|u| u.defect == Some(d)).count(), 2, "{d:?}");
        }
        assert_eq!(p.unit.iter().filter(|u| u.truncation.is_some()).count(), 4);
        assert!(p.unit.iter().all(|u| u.defect.is_none() || u.truncation.is_none()));
        assert_eq!(p, draw(&spec));
        assert_ne!(p, draw(&PopulationSpec { seed: 6, ..spec }));
    }

    /// Two seeds draw two populations: no unit of seed 2 has the curves of any unit of
    /// seed 1, and no unit's rows repeat another's noise (the studies that run seeds 1–3
    /// count them as independent fleets). Before the seeds were mixed, seed 2's unit `i`
    /// was seed 1's unit `i + 1`.
    #[test]
    fn consecutive_seeds_share_no_unit() {
        let spec = PopulationSpec { units: 30, seed: 1, bad: false, truncated: 0, die_lags: false };
        let (a, b) = (draw(&spec), draw(&PopulationSpec { seed: 2, ..spec }));
        for u in &b.unit {
            assert!(a.unit.iter().all(|v| v.axes != u.axes), "{} repeats a unit of seed 1", u.serial);
        }
        let air = &chamber_air()[..200];
        let rows = |p: &PopulationTruth, i: usize| unit_rows(&p.unit[i], air, p.seed, i);
        let noise = |r: Vec<(f64, [f64; 3])>| r.windows(2).map(|w| w[1].1[0] - w[0].1[0]).collect::<Vec<f64>>();
        for i in 0..5 {
            for j in 0..5 {
                assert_ne!(noise(rows(&b, i)), noise(rows(&a, j)), "rows of seed 2's {i} and seed 1's {j}");
            }
        }
    }

    /// The rows follow the truth: over the last 300 s of the hold at 70 °C, an axis reads
    /// its heating curve at the sensor's reading less its offset, to within the noise.
    #[test]
    fn rows_follow_the_truth_curve() {
        let spec = PopulationSpec { units: 3, seed: 1, bad: false, truncated: 0, die_lags: false };
        let p = draw(&spec);
        let air = chamber_air();
        let u = &p.unit[1];
        let rows = unit_rows(u, &air, p.seed, 1);
        let top = air.iter().position(|&a| a >= 70.0).unwrap() + 900;
        let seg = &rows[top - 300..top];
        for k in 0..3 {
            let mean = seg.iter().map(|r| r.1[k]).sum::<f64>() / 300.0;
            let want = seg.iter().map(|r| u.axes[k].at(r.0 - u.sensor_offset_c, true)).sum::<f64>() / 300.0;
            // 5 standard errors of the mean, plus the 1/16-°C reading's share (1/32 °C × 0.2 mg/°C).
            let tol = 5.0 * u.noise_g / 300f64.sqrt() + 7e-6;
            assert!((mean - want).abs() < tol, "axis {k}: {mean} vs {want}");
        }
        let t = seg.iter().map(|r| r.0).sum::<f64>() / 300.0 - u.sensor_offset_c;
        assert!((t - 70.0).abs() < 0.1, "the case settles at 70 °C: {t}");
    }
}
