//! The fleet: every unit's figures side by side, which units sit outside the population and
//! why, process capability against each limit, and each unit's decision.
//!
//! # Outside the population
//! Each figure (`features`) is compared with the fleet by a robust distance:
//! `z = (x − median) / (1.4826 · MAD)` over the reference units (calibrated, both branches,
//! a span at least `FULL_SPAN_SHARE` of the fleet's median span), so the bad units
//! themselves cannot widen the yardstick the way a standard deviation would let them. The
//! scale never goes below the figure's stated floor ([`Feature::floor`]: a resolution far
//! under any population's spread, so it acts only when most units agree to the last digit).
//! A unit is flagged when a figure sits more than `Z_FLAG` scales out (held-out RMS:
//! above only; everything else: either side), with the figure, its value, the median and
//! the distance. A unit with partial coverage is compared on its sensor only: its curve's
//! shape outside its rows is an extrapolation, and its held-out figure comes from another
//! scheme (blocks, not the later leg); its limits still apply, and its table comes from
//! the population prior ([`super::prior`]).
//!
//! # The sensor against the fleet
//! Units in one chamber see one air temperature. Per minute of the shared clock the fleet's
//! median reading is formed; on the minutes where that median moves less than
//! `STEADY_C_PER_MIN` (the holds, where the units' different lags have died out) each
//! unit's difference from it gives its offset (median) and its drift (the least-squares
//! slope over time). A sensor that drifts shows there and nowhere else: its unit's own log
//! only shows a bias curve that does not repeat. A cycling log's clock restarts with each
//! run, so its minutes are a run's (`PROGRAM/RUN`, which every unit ran through alike) and
//! its drift is over the runs taken back to back ([`super::unit::SensorLeg`]).
//!
//! # Decision
//! FAIL: not calibrated, or a limit failed. REVIEW: every limit met but flagged outside the
//! population (a person looks before it ships). PASS: neither.
//!
//! # Capability
//! Per limit and axis, over the calibrated units: `Cpk = (USL − mean) / 3s` for a maximum,
//! `(mean − LSL) / 3s` for a minimum, with `s` the batch's standard deviation (so in AIAG
//! terms it is Ppk: one batch, no subgroups). Every limit here is one-sided, so Cp (which
//! needs both) is not computed, and says why.

use serde::{Deserialize, Serialize};

mod coverage;
mod fits;
mod sensor;
mod yardstick;

pub use self::coverage::Coverage;
use self::coverage::{full_coverage, partial_units};
use self::fits::InputFaults;
use self::sensor::sensors;
use self::yardstick::{feature_stats, Yardstick};
use super::unit::{Calibrated, UnitOutcome, UnitResult};
use qfa_log::robust::median;
use qfa_report::verdict::{Limits, Measured, Outcome};

/// Robust scales out that flag a unit. Set to 6 when this was written, after one 20-unit
/// simulated batch whose good units reached 4.3; measured afterwards on three 100-unit
/// chamber runs (seeds 1–3, 6 bad units each): the largest |z| of any good unit on any
/// figure was 3.38, the smallest strongest-flag distance of a bad unit 11.0
/// (`cargo test --release -p qfa-lab --test batch -- --ignored flag_study --nocapture`).
/// The simulator's population is Gaussian; a real fleet's clusters (published batch
/// studies find a few, not one family curve) would widen the tails, which is why the
/// threshold keeps this margin. `a_chamber_run_flags_each_bad_unit_for_its_defect_and_passes_the_rest`
/// fails when it is set so that a good unit is flagged or a bad one passes.
pub(crate) const Z_FLAG: f64 = 6.0;
/// The smallest robust scale of a heating/cooling split, mg: what one chamber cycle
/// resolves. A unit's split is read from its own model, whose search ties the branches
/// when the split is within its cross-validation's noise: on the simulator's population
/// about half the units with a true split of 0.06 mg read 0 and the rest read the split,
/// so the fleet's median absolute deviation collapses to 0 and, at the old floor of
/// 0.01 mg, a good unit that kept its 0.07-mg split stood 6.9 robust SDs out. Set after
/// that run, so checked by the die-lag study (lab guide, "Production batches").
pub(crate) const SPLIT_RESOLUTION_MG: f64 = 0.05;
/// Units of full coverage a fleet (or a lot) needs before units are compared with it:
/// below, the median and MAD of a handful of units are too unsteady a yardstick, and good
/// units land beyond `Z_FLAG` of it. Measured on fleets of good QFA units only (eight seeds
/// per size, `cargo test --release -p qfa-lab --test batch_qfa -- --ignored
/// fleet_size_study --nocapture`), good units beyond the line: 10/40 at 5 units, 2/64 at 8,
/// 5/80 at 10, 2/96 at 12, 2/120 at 15, 2/160 at 20, 1/240 at 30. Set to 15 after that run
/// (it was 10, from a run whose seeds drew overlapping fleets), the smallest size under the
/// goal of one good unit in 50 (redrawn with each run's own noise stream: 3/80 at 10,
/// 1/120 at 15; with every draw a named stream: 4/80 and 1/120); on normal figures the rate is 2.7 % at 10 units and 1.0 %
/// at 15 (`a_fleet_of_min_fleet_units_flags_under_one_good_unit_in_50`, which fails at 10).
/// Below it the fleet says so and judges its units by their limits alone
/// (`a_fleet_too_small_to_compare_says_so_and_flags_no_unit` fails when it is 0).
pub(crate) const MIN_FLEET: usize = 15;
/// A unit whose span is under this share of the fleet's median span has partial coverage.
pub(crate) const FULL_SPAN_SHARE: f64 = 0.8;

/// Which way a figure is bad.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Side {
    /// Too far either way.
    Both,
    /// Only too high.
    High,
}

/// A figure the fleet compares.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Feature {
    /// Name (`ax.slope_ug_per_c`).
    pub name: String,
    /// Unit (`µg/°C`).
    pub unit: String,
    /// Smallest robust scale, in the figure's unit.
    pub floor: f64,
    /// Which way it is bad.
    pub side: Side,
    /// Compared only on units with full coverage: the curve's shape (beyond a partial
    /// log's rows it is an extrapolation) and the held-out figure (a partial log is held
    /// out by another scheme, blocks instead of the later leg, so its figure measures
    /// something else).
    pub full_coverage_only: bool,
    /// Part of a lot's signature ([`super::lots`]): what the unit's curve and sensor are,
    /// not how well it was measured or how it is failing.
    #[serde(default)]
    pub signature: bool,
}

/// The distribution of one figure over the fleet.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FeatureStats {
    /// The figure.
    pub feature: Feature,
    /// Units with a value.
    pub n: usize,
    /// Of those, the units the median and scale are formed from: full coverage, a log that
    /// fits the batch (the yardstick; the others are measured against it).
    #[serde(default)]
    pub yardstick_n: usize,
    /// Reference units' median.
    pub median: f64,
    /// Robust scale (1.4826 · MAD, at least the floor).
    pub scale: f64,
    /// Every unit's value, by serial (units without one left out).
    pub values: Vec<(String, f64)>,
    /// Per lot when the fleet has two ([`Fleet::lots`]): its median and robust scale, the
    /// yardstick of its units.
    #[serde(default)]
    pub lots: Vec<[f64; 2]>,
}

impl Fleet {
    /// The lot whose yardstick the unit `serial` is compared with ([`FeatureStats::distance`]):
    /// its lot when the fleet holds two, each of `MIN_FLEET` (15) units, and the unit has full
    /// coverage; else `None`, the whole fleet's.
    #[must_use]
    pub fn lot_of(&self, serial: &str) -> Option<usize> {
        self.unit.iter().find(|u| u.serial == serial).and_then(|u| u.lot).filter(|l| l.compared_within).map(|l| l.lot)
    }
}

impl FeatureStats {
    /// The median and robust scale a unit of `lot` is compared with: its lot's, or the
    /// fleet's for a fleet of one lot and a unit in none (partial coverage).
    #[must_use]
    pub fn yardstick(&self, lot: Option<usize>) -> [f64; 2] {
        lot.and_then(|k| self.lots.get(k).copied()).unwrap_or([self.median, self.scale])
    }

    /// The robust distance of `value` for a unit of `lot`, scales.
    #[must_use]
    pub fn distance(&self, value: f64, lot: Option<usize>) -> f64 {
        let [median, scale] = self.yardstick(lot);
        (value - median) / scale
    }
}

/// One figure outside the population.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Flag {
    /// The figure.
    pub feature: String,
    /// The unit's value.
    pub value: f64,
    /// The fleet's median.
    pub median: f64,
    /// Robust distance, scales.
    pub z: f64,
    /// In words.
    pub text: String,
}

/// What happens to a unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Decision {
    /// Meets every limit, inside the population: ship.
    Pass,
    /// Meets every limit, outside the population: a person looks first.
    Review,
    /// Not calibrated, or a limit failed.
    Fail,
}

impl Fleet {
    /// Why no unit was compared with the fleet, in words; `None` when they were.
    #[must_use]
    pub fn not_compared(&self) -> Option<String> {
        (!self.compared).then(|| {
            format!(
                "only {} unit(s) of full coverage: a fleet needs {MIN_FLEET} before a unit is compared with it (with \
                 fewer, good units sit far outside so unsteady a yardstick); each unit is judged by its limits alone",
                self.reference_units
            )
        })
    }
}

impl std::fmt::Display for Decision {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Pass => "PASS",
            Self::Review => "REVIEW",
            Self::Fail => "FAIL",
        })
    }
}

/// One unit in the fleet.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct FleetUnit {
    /// Serial.
    pub serial: String,
    /// Decision.
    pub decision: Decision,
    /// The unit got a table (else it FAILs, `reasons` saying why): what a command's exit
    /// status is decided by, never the reasons' text.
    pub calibrated: bool,
    /// Why, one line each (empty on PASS).
    pub reasons: Vec<String>,
    /// Figures outside the population.
    pub flags: Vec<Flag>,
    /// Partial coverage (shape not compared): `coverage.partial()`.
    pub partial: bool,
    /// Whether its rows cover the fleet's, and if not, why.
    #[serde(default = "full_coverage")]
    pub coverage: Coverage,
    /// Sensor offset from the fleet's median reading, °C.
    pub sensor_offset_c: Measured,
    /// Sensor drift against the fleet's median reading, °C/h.
    pub sensor_drift_c_per_h: Measured,
    /// The population prior's table, for a unit with partial coverage.
    pub prior: Option<super::prior::PriorUse>,
    /// Its lot, when the fleet holds two ([`Fleet::lots`]).
    #[serde(default)]
    pub lot: Option<UnitLot>,
    /// Its log does not fit the batch (an axis the batch's units hold is missing, or it
    /// holds another unit's readings): a fault of the input, which FAILs the unit and the
    /// command's exit status whatever the limits, as a unit not calibrated does.
    #[serde(default)]
    pub input_fault: bool,
    /// What the checks of its log warned of ([`super::unit::Calibrated::log_warnings`]):
    /// not a reason, shown so the logger is looked at.
    #[serde(default)]
    pub log_warnings: Vec<String>,
}

impl FleetUnit {
    /// Whether a table of the unit may be flashed: it was calibrated and does not FAIL (a
    /// FAIL holds its tables back, the prior's included). Every page and the console name
    /// a table to flash by this alone.
    #[must_use]
    pub fn flashable(&self) -> bool {
        self.calibrated && self.decision != Decision::Fail
    }
}

/// A unit's lot.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UnitLot {
    /// 0 for lot 1 (the larger), 1 for lot 2.
    pub lot: usize,
    /// The mixture's probability of it.
    pub probability: f64,
    /// The unit was compared with its own lot (both lots hold `MIN_FLEET` units), not the
    /// whole fleet.
    pub compared_within: bool,
}

/// Process capability of one limit on one axis.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Capability {
    /// Limit key.
    pub limit: String,
    /// Axis (`all` for the span).
    pub axis: String,
    /// `max` or `min`.
    pub sense: String,
    /// The limit.
    pub bound: f64,
    /// Units with the figure.
    pub n: usize,
    /// Mean.
    pub mean: Measured,
    /// Standard deviation.
    pub sd: Measured,
    /// Cpk (Ppk: one batch).
    pub cpk: Measured,
    /// Cp.
    pub cp: Measured,
}

/// The fleet's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Fleet {
    /// Units in the batch.
    pub units: usize,
    /// Counts per decision: pass, review, fail.
    pub counts: [usize; 3],
    /// The flag threshold, scales.
    pub z_flag: f64,
    /// Per figure.
    pub stats: Vec<FeatureStats>,
    /// Per limit and axis.
    pub capability: Vec<Capability>,
    /// Per unit, in serial order of the batch.
    pub unit: Vec<FleetUnit>,
    /// The population prior per axis (from the full-coverage, unflagged units that do not FAIL).
    pub population: Vec<super::prior::Population>,
    /// The fleet's span: the median of those units' lowest and highest readings, °C.
    pub span_c: [f64; 2],
    /// Units of full coverage, the yardstick of every figure.
    pub reference_units: usize,
    /// The units were compared with the fleet: it has at least 15 (`MIN_FLEET`) units of full
    /// coverage. When not, no unit is flagged outside the population and the page says so.
    pub compared: bool,
    /// Two production lots, when the fleet holds them ([`super::lots`]): each unit of full
    /// coverage is then compared with its own lot.
    #[serde(default)]
    pub lots: Option<super::lots::Lots>,
}

/// The figures compared, for the static units' axes `axes`, and a QFA unit's figures
/// when `qfa` (a batch of cycling logs).
#[must_use]
pub(crate) fn features(axes: &[String], qfa: bool, drift_floor_c_per_h: f64) -> Vec<Feature> {
    // The signature of a lot: every figure either side of the fleet but the sensor's drift
    // and the unit's ageing, which say a unit is failing.
    let f = |name: String, unit: &str, floor: f64, side: Side, full_coverage_only: bool| Feature {
        signature: side == Side::Both && !name.ends_with("drift_c_per_h") && !name.ends_with("ageing_ug_per_h"),
        name,
        unit: unit.to_string(),
        floor,
        side,
        full_coverage_only,
    };
    let mut out = Vec::new();
    for a in axes {
        out.push(f(format!("{a}.level_mg"), "mg", 0.05, Side::Both, true));
        out.push(f(format!("{a}.slope_ug_per_c"), "µg/°C", 0.5, Side::Both, true));
        out.push(f(format!("{a}.curvature_ug_per_c2"), "µg/°C²", 0.01, Side::Both, true));
        // A split below 0.05 mg is below what one chamber cycle resolves: the search ties
        // the branches of about half the units whose true split is 0.06 mg, so the fleet
        // reads 0 or the split itself (set after the die-lag study, lab guide).
        out.push(f(format!("{a}.split_mg"), "mg", SPLIT_RESOLUTION_MG, Side::Both, true));
        out.push(f(format!("{a}.ramp_split_mg"), "mg", 0.01, Side::Both, true));
        out.push(f(format!("{a}.held_out_mg"), "mg", 0.02, Side::High, true));
    }
    if qfa {
        for (name, unit, floor, high, _) in super::qfa::FLEET_FIGURES {
            let side = if high { Side::High } else { Side::Both };
            // The held-out figures and the model's shape need the fleet's span, as a static
            // unit's do.
            out.push(f(format!("qfa.{name}"), unit, floor, side, true));
        }
    }
    out.push(f("sensor.offset_c".into(), "°C", 0.05, Side::Both, false));
    // What a sensor's drift is told from none by depends on how long the log ran
    // (`sensor::DRIFT_RESOLUTION_C`).
    out.push(f("sensor.drift_c_per_h".into(), "°C/h", drift_floor_c_per_h, Side::Both, false));
    // One glitch row an hour is the scale's floor: a fleet with none has no spread.
    out.push(f("log.glitches_per_h".into(), "rows/h", 1.0, Side::High, false));
    out
}

/// What a figure is, in a production engineer's words (the flag's text starts with it).
fn words(name: &str) -> Option<&'static str> {
    let (scope, what) = name.split_once('.')?;
    if scope == "qfa" {
        return super::qfa::FLEET_FIGURES.iter().find(|f| f.0 == what).map(|f| f.4);
    }
    Some(match what {
        "level_mg" => "output at 25 °C",
        "slope_ug_per_c" => "temperature slope",
        "curvature_ug_per_c2" => "temperature curvature",
        "split_mg" => "heating/cooling split",
        "ramp_split_mg" => "heating/cooling split on the program's ramps (the die's lag fitted out)",
        "held_out_mg" => "held-out bias RMS",
        "offset_c" => "temperature sensor's offset from the fleet",
        "drift_c_per_h" => "temperature sensor's drift against the fleet",
        "glitches_per_h" => "spikes skipped per hour",
        _ => return None,
    })
}

fn value_of(c: &Calibrated, sensor: (&Measured, &Measured), name: &str) -> Option<f64> {
    let num = |m: &Measured| match m {
        Measured::Value(v) => Some(*v),
        Measured::NotComputed { .. } => None,
    };
    match name {
        "sensor.offset_c" => return num(sensor.0),
        "sensor.drift_c_per_h" => return num(sensor.1),
        "log.glitches_per_h" => return Some(c.glitches_per_h),
        _ => {}
    }
    let (axis, what) = name.split_once('.')?;
    if axis == "qfa" {
        return c.qfa.as_ref()?.value(what);
    }
    if what == "held_out_mg" {
        return c.held_out_mg.iter().find(|(a, _)| a == axis).and_then(|(_, m)| num(m));
    }
    let d = c.descriptor.iter().find(|d| d.axis == axis)?;
    match what {
        "level_mg" => Some(d.level_mg),
        "slope_ug_per_c" => Some(d.slope_ug_per_c),
        "curvature_ug_per_c2" => Some(d.curvature_ug_per_c2),
        "split_mg" => num(&d.split_mg),
        "ramp_split_mg" => num(&d.ramp_split_mg),
        _ => None,
    }
}

/// The fleet's figures, flags and decisions over `results` (in batch order).
#[must_use]
pub(crate) fn fleet(results: &[UnitResult], limits: &Limits) -> Fleet {
    let cal: Vec<Option<&Calibrated>> = results
        .iter()
        .map(|r| match &r.outcome {
            UnitOutcome::Calibrated(c) => Some(c.as_ref()),
            UnitOutcome::Failed { .. } => None,
        })
        .collect();
    let faults = InputFaults::of(results);
    // A unit whose log does not fit the batch (an axis missing, or another serial's
    // readings) FAILs; its figures are shown but measure no yardstick: a log named for two
    // serials would count one unit twice, a unit without an axis would shift the others.
    let input_fault: Vec<bool> = (0..results.len()).map(|i| faults.any(i)).collect();
    let fitting: Vec<Option<&Calibrated>> =
        cal.iter().zip(&input_fault).map(|(c, &fault)| if fault { None } else { *c }).collect();
    let axes = fleet_axes(&cal);
    let sensors = sensors(&cal, &input_fault);
    let sensor = &sensors.unit;
    let coverage = partial_units(&cal, &input_fault);
    let partial: Vec<bool> = coverage.iter().map(Coverage::partial).collect();
    let reference_unit: Vec<bool> = (0..results.len()).map(|i| !partial[i] && fitting[i].is_some()).collect();
    let qfa = cal.iter().flatten().any(|c| c.qfa.is_some());
    let mut flags: Vec<Vec<Flag>> = vec![Vec::new(); results.len()];
    let all_stats = |lots: Option<&super::lots::Lots>, flags: &mut [Vec<Flag>]| -> Vec<FeatureStats> {
        let yard = Yardstick { results, cal: &cal, sensor, partial: &partial, reference: &reference_unit, lots };
        features(&axes, qfa, sensors.drift_floor_c_per_h)
            .into_iter()
            .filter_map(|feat| feature_stats(feat, &yard, flags))
            .collect()
    };
    let mut stats = all_stats(None, &mut flags);
    let reference_idx: Vec<usize> = (0..results.len()).filter(|&i| reference_unit[i]).collect();
    let serials: Vec<String> = results.iter().map(|r| r.serial.clone()).collect();
    // Two lots: every figure again, each unit of full coverage against its own lot.
    let lots = super::lots::find(&stats, &serials, &reference_idx);
    if lots.is_some() {
        flags.iter_mut().for_each(Vec::clear);
        stats = all_stats(lots.as_ref(), &mut flags);
    }
    // Too few units for a yardstick: the figures are shown, no unit is flagged by them.
    let reference_units = reference_idx.len();
    let compared = reference_units >= MIN_FLEET;
    if !compared {
        flags.iter_mut().for_each(Vec::clear);
    }
    // The strongest first: a reader's first reason is the figure furthest out.
    for f in &mut flags {
        f.sort_by(|a, b| b.z.abs().total_cmp(&a.z.abs()));
    }
    let mut counts = [0; 3];
    let mut unit = fleet_units(results, &faults, &flags, &coverage, sensor, &mut counts);
    for (i, u) in unit.iter_mut().enumerate() {
        u.lot = lots.as_ref().and_then(|l| {
            l.unit[i].map(|(lot, probability)| UnitLot { lot, probability, compared_within: l.compared_within })
        });
    }
    // The units that ship define the population: full coverage, no flag, and not a FAIL (a
    // unit held back by its own limits, a damaged one in a fleet too small to flag it, or
    // one whose figures are in-sample, would move the prior's mean and covariance).
    let reference: Vec<&Calibrated> = (0..results.len())
        .filter(|&i| !partial[i] && flags[i].is_empty() && unit[i].decision != Decision::Fail)
        .filter_map(|i| cal[i])
        .collect();
    let lo: Vec<f64> = reference.iter().map(|c| c.temp_c[0]).collect();
    let hi: Vec<f64> = reference.iter().map(|c| c.temp_c[1]).collect();
    let span_c = [median(&lo).unwrap_or(0.0), median(&hi).unwrap_or(0.0)];
    // A static unit's axes, or a QFA unit's scale factor and bias (`k1`, `k0`).
    let of = |f: fn(&Calibrated) -> Option<&super::prior::UnitNormal>| {
        super::prior::population(&reference.iter().filter_map(|c| f(c)).collect::<Vec<_>>())
    };
    let mut population = of(|c| c.normal.as_ref());
    population.extend(of(|c| c.qfa_normal.as_ref().map(|q| &q.scale)));
    population.extend(of(|c| c.qfa_normal.as_ref().map(|q| &q.bias)));
    Fleet {
        units: results.len(),
        counts,
        z_flag: Z_FLAG,
        stats,
        capability: capability(&fitting, &axes, limits),
        unit,
        population,
        span_c,
        reference_units,
        compared,
        lots,
    }
}

/// The axes the calibrated units describe, in order of first appearance.
fn fleet_axes(cal: &[Option<&Calibrated>]) -> Vec<String> {
    let mut a: Vec<String> = Vec::new();
    for c in cal.iter().flatten() {
        for d in &c.descriptor {
            if !a.contains(&d.axis) {
                a.push(d.axis.clone());
            }
        }
    }
    a
}

/// What a flagged axis's residual says in the engineer's words: a step part-way through
/// the run that the temperature did not make ([`super::unit::ResidualStep`]), on each axis
/// the unit is flagged on.
fn step_reasons(r: &UnitResult, flags: &[Flag]) -> Vec<String> {
    let UnitOutcome::Calibrated(c) = &r.outcome else { return Vec::new() };
    c.steps
        .iter()
        .filter(|s| s.thermal_share < super::unit::NOT_THERMAL_SHARE)
        .filter(|s| flags.iter().any(|f| f.feature.split('.').next() == Some(s.axis.as_str())))
        .map(super::unit::ResidualStep::words)
        .collect()
}

/// Each unit's decision and reasons (a failure, then what a flagged axis's residual says,
/// then its flags), counted in `counts`.
fn fleet_units(
    results: &[UnitResult],
    faults: &InputFaults,
    flags: &[Vec<Flag>],
    coverage: &[Coverage],
    sensor: &[(Measured, Measured)],
    counts: &mut [usize; 3],
) -> Vec<FleetUnit> {
    results
        .iter()
        .enumerate()
        .map(|(i, r)| {
            let (mut decision, mut reasons) = match &r.outcome {
                UnitOutcome::Failed { reason } => (Decision::Fail, vec![format!("not calibrated: {reason}")]),
                UnitOutcome::Calibrated(c) if c.outcome == Outcome::Fail => {
                    (Decision::Fail, c.failed_limits.iter().map(|l| format!("limit: {l}")).collect())
                }
                UnitOutcome::Calibrated(_) if !flags[i].is_empty() => (Decision::Review, Vec::new()),
                UnitOutcome::Calibrated(_) => (Decision::Pass, Vec::new()),
            };
            let input_fault = faults.any(i);
            if let Some((lacks, fleet)) = &faults.missing[i] {
                decision = Decision::Fail;
                reasons.push(format!(
                    "its log holds no {lacks} where most of the batch's units hold {fleet}: its table leaves {lacks} \
                     uncompensated (a column missing or misnamed in its log)"
                ));
            }
            if !faults.same[i].is_empty() {
                decision = Decision::Fail;
                reasons.push(format!(
                    "its table.bin is {}'s, byte for byte: their logs hold the same readings (one log named for two \
                     serials, a log copied under another serial's name, or a column logged twice), so no table here \
                     can be told to be this unit's",
                    faults.same[i].join(", ")
                ));
            }
            reasons.extend(step_reasons(r, &flags[i]));
            reasons.extend(flags[i].iter().map(|f| format!("outside the population: {}", f.text)));
            counts[decision as usize] += 1;
            FleetUnit {
                serial: r.serial.clone(),
                decision,
                calibrated: matches!(r.outcome, UnitOutcome::Calibrated(_)),
                reasons,
                flags: flags[i].clone(),
                partial: coverage[i].partial(),
                coverage: coverage[i].clone(),
                sensor_offset_c: sensor[i].0.clone(),
                sensor_drift_c_per_h: sensor[i].1.clone(),
                prior: None,
                lot: None,
                input_fault,
                log_warnings: match &r.outcome {
                    UnitOutcome::Calibrated(c) => c.log_warnings.clone(),
                    UnitOutcome::Failed { .. } => Vec::new(),
                },
            }
        })
        .collect()
}

/// Record each partial unit's prior table on the fleet: a unit for which the prior decided
/// most of the table is held for REVIEW with that reason, and the counts follow.
pub(crate) fn apply_priors(fleet: &mut Fleet, uses: Vec<Option<super::prior::PriorUse>>) {
    for (u, p) in fleet.unit.iter_mut().zip(uses) {
        if let Some(p) = &p {
            if p.mostly_prior {
                u.reasons.push(format!(
                    "the population prior, not the unit's rows, decided most of {} (its rows cover {:.0} % of the \
                     fleet's span × both branches; under {:.0} %)",
                    p.table,
                    100.0 * p.covered_share,
                    100.0 * super::prior::MOSTLY_PRIOR
                ));
                if u.decision == Decision::Pass {
                    u.decision = Decision::Review;
                }
            }
        }
        u.prior = p;
    }
    fleet.counts = count(&fleet.unit);
}

/// Units per decision: PASS, REVIEW, FAIL.
#[must_use]
pub(crate) fn count(units: &[FleetUnit]) -> [usize; 3] {
    let mut counts = [0; 3];
    for u in units {
        counts[u.decision as usize] += 1;
    }
    counts
}

fn capability(cal: &[Option<&Calibrated>], axes: &[String], limits: &Limits) -> Vec<Capability> {
    let not = |why: &str| Measured::NotComputed { not_computed: why.to_string() };
    let one = |limit: &str, axis: &str, sense: &str, bound: f64, v: Vec<f64>| {
        let n = v.len();
        let (mean, sd, cpk) = if n < 2 {
            (not("fewer than 2 units"), not("fewer than 2 units"), not("fewer than 2 units"))
        } else {
            let m = v.iter().sum::<f64>() / n as f64;
            let s = (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / (n - 1) as f64).sqrt();
            let cpk = if s > 0.0 {
                Measured::Value(if sense == "max" { (bound - m) / (3.0 * s) } else { (m - bound) / (3.0 * s) })
            } else {
                not("no spread: every unit gave the same figure")
            };
            (Measured::Value(m), Measured::Value(s), cpk)
        };
        Capability {
            limit: limit.into(),
            axis: axis.into(),
            sense: sense.into(),
            bound,
            n,
            mean,
            sd,
            cpk,
            cp: not("one-sided limit: Cp needs a lower and an upper limit"),
        }
    };
    let mut out = Vec::new();
    for a in axes {
        let v: Vec<f64> = cal
            .iter()
            .flatten()
            .filter_map(|c| c.held_out_mg.iter().find(|(x, _)| x == a))
            .filter_map(|(_, m)| match m {
                Measured::Value(v) => Some(*v),
                Measured::NotComputed { .. } => None,
            })
            .collect();
        out.push(one("held_out_bias_mg", a, "max", limits.held_out_bias_mg, v));
    }
    let qfa: Vec<&super::qfa::QfaFigures> = cal.iter().flatten().filter_map(|c| c.qfa.as_ref()).collect();
    if !qfa.is_empty() {
        let values = |f: fn(&super::qfa::QfaFigures) -> &Measured| -> Vec<f64> {
            qfa.iter()
                .filter_map(|q| match f(q) {
                    Measured::Value(v) => Some(*v),
                    Measured::NotComputed { .. } => None,
                })
                .collect()
        };
        let v = values(|q| &q.held_out_bias_ug);
        out.push(one("held_out_bias_ug", "qfa", "max", limits.held_out_bias_ug, v));
        let v = values(|q| &q.held_out_sensitivity_ppm_per_c);
        out.push(one("held_out_sensitivity_ppm_per_c", "qfa", "max", limits.held_out_sensitivity_ppm_per_c, v));
    }
    let spans: Vec<f64> = cal.iter().flatten().map(|c| c.temp_c[1] - c.temp_c[0]).collect();
    out.push(one("min_span_c", "all", "min", limits.min_span_c, spans));
    out
}
